"""The camera: CAPTURE_PHOTO, CAPTURE_PHOTOS, START_CAPTURING and STOP_CAPTURING."""

from __future__ import annotations

from tml.actions.definition import ActionDef, spec
from tml.actions.guided import Context, Script, Send, Sleep
from tml.language.actions import BoundAction
from tml.vehicle import Camera


def capture_photo(ctx: Context, bound: BoundAction) -> Script:
    """One photo."""
    yield Send(Camera(ctx.vehicle_id, "photo", 1))


def capture_photos(ctx: Context, bound: BoundAction) -> Script:
    """A number of photos at an interval; done when the last is due."""
    count = bound.integer("count")
    interval = bound.number("interval")
    yield Send(Camera(ctx.vehicle_id, "photo", count, interval))
    yield Sleep(interval * (count - 1))


def start_capturing(ctx: Context, bound: BoundAction) -> Script:
    """Photos at an interval until STOP_CAPTURING."""
    yield Send(Camera(ctx.vehicle_id, "start", 0, bound.number("interval")))


def stop_capturing(ctx: Context, bound: BoundAction) -> Script:
    """Stop the photos START_CAPTURING began."""
    yield Send(Camera(ctx.vehicle_id, "stop"))


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("CAPTURE_PHOTO"), guided=capture_photo),
    ActionDef(spec("CAPTURE_PHOTOS"), guided=capture_photos),
    ActionDef(spec("START_CAPTURING"), guided=start_capturing),
    ActionDef(spec("STOP_CAPTURING"), guided=stop_capturing),
)
