"""The camera: CAPTURE_PHOTO, CAPTURE_PHOTOS, START_CAPTURING and STOP_CAPTURING."""

from __future__ import annotations

from tml.actions import items, mav, reading, timing
from tml.actions.definition import ActionDef, spec
from tml.actions.guided import Context, Script, Send, Sleep
from tml.actions.motion import Labels, Motion, PredictedState, Step, instant
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


# --- mission items (dispatch="mission") ----------------------------------------

def capture_photo_items(b: items.Builder, action: BoundAction) -> None:
    # param5 (shoot) travels in the item's x field.
    b.add(mav.DO_DIGICAM_CONTROL, raw=(1, 0, 0.0))


def capture_photos_items(b: items.Builder, action: BoundAction) -> None:
    b.add(mav.IMAGE_START_CAPTURE,
          params=(0.0, action.number("interval"), action.number("count"), 0.0))


def start_capturing_items(b: items.Builder, action: BoundAction) -> None:
    b.add(mav.IMAGE_START_CAPTURE,
          params=(0.0, action.number("interval"), 0.0, 0.0))


def stop_capturing_items(b: items.Builder, action: BoundAction) -> None:
    b.add(mav.IMAGE_STOP_CAPTURE)


# --- motion models (tml verify) -------------------------------------------------------------

def capture_photos_motion(model: Motion, bound: BoundAction, state: PredictedState,
                          labels: Labels) -> Step:
    seconds = (bound.integer("count") - 1) * bound.number("interval")
    return Step(state, model.hover(state, seconds), labels=labels)


# --- reading mission items back (tml import) ------------------------------------------------

def capture_photos_read(item: reading.ItemFields) -> reading.Arguments | None:
    """IMAGE_START_CAPTURE of a number of photos."""
    if item.param3 > 0:
        return {"count": reading.value(item.param3), "interval": reading.value(item.param2)}
    return None


def start_capturing_read(item: reading.ItemFields) -> reading.Arguments | None:
    """IMAGE_START_CAPTURE until stopped."""
    return None if item.param3 > 0 else {"interval": reading.value(item.param2)}


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("CAPTURE_PHOTO"), guided=capture_photo, items=capture_photo_items,
              motion=instant, item_time=timing.nominal,
              imports=reading.Reading({mav.DO_DIGICAM_CONTROL: lambda item: {}})),
    ActionDef(spec("CAPTURE_PHOTOS"), guided=capture_photos, items=capture_photos_items,
              motion=capture_photos_motion, item_time=timing.nominal,
              imports=reading.Reading({mav.IMAGE_START_CAPTURE: capture_photos_read})),
    ActionDef(spec("START_CAPTURING"), guided=start_capturing, items=start_capturing_items,
              motion=instant, item_time=timing.nominal,
              imports=reading.Reading({mav.IMAGE_START_CAPTURE: start_capturing_read})),
    ActionDef(spec("STOP_CAPTURING"), guided=stop_capturing, items=stop_capturing_items,
              motion=instant, item_time=timing.nominal,
              imports=reading.Reading({mav.IMAGE_STOP_CAPTURE: lambda item: {}})),
)
