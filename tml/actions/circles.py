"""Circling a point: LOITER and RETURN_HOME_AND_LOITER."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from tml.actions import guided, items, mav, reading, timing
from tml.actions.definition import ActionDef, NotApplicable, spec
from tml.actions.guided import Context, Script
from tml.actions.motion import Labels, Motion, PredictedState, Step, add
from tml.geo import Point
from tml.language.actions import BoundAction


def loiter(ctx: Context, bound: BoundAction) -> Script:
    """Fly to the centre and circle it: turns, a time, or until an event stops it."""
    here = guided.require_flying(ctx, "LOITER")
    centre = guided.point_argument(ctx, bound, "coordinates")
    relative = bound.point("relative_coordinates", None)
    if centre is None and relative is not None:
        dn, de, du = relative
        centre = (here[0] + dn, here[1] + de, here[2] + du)
    if centre is None:
        centre = bound.point("from_home", None)
    if centre is None and "latitude" in bound.values:
        centre = guided.local(ctx, bound)
    centre = centre or here
    yield from guided.circle(ctx, centre, bound.number("radius"), bound.number("turns", None),
                             bound.number("duration", None))


def return_home_and_loiter(ctx: Context, bound: BoundAction) -> Script:
    """Fly back over home and circle it until an event stops it."""
    here = guided.require_flying(ctx, "RETURN_HOME_AND_LOITER")
    yield from guided.circle(ctx, (0.0, 0.0, here[2]), bound.number("radius"), None, None)


# --- mission items (dispatch="mission") ----------------------------------------

def _loiter_centre(b: items.Builder, action: BoundAction) -> tuple[Point, str]:
    if "latitude" in action.values:
        return items.global_point(b, action, action.choice("altitude_reference"))
    return _local_centre(b, action), "relative"


def _local_centre(b: items.Builder, action: BoundAction) -> Point:
    point = action.point("coordinates", None)
    if point is not None:
        return point
    relative = action.point("relative_coordinates", None)
    if relative is not None:
        return items.plus(b.cursor.position, relative)
    return action.point("from_home", b.cursor.position)


def loiter_items(b: items.Builder, action: BoundAction) -> None:
    exact = items.written_position(b, action) if "latitude" in action.values else None
    items.loiter_at(b, *_loiter_centre(b, action), action.number("radius"),
                    action.number("turns", None), action.number("duration", None), exact)


def return_home_and_loiter_items(b: items.Builder, action: BoundAction) -> None:
    items.loiter_at(b, (0.0, 0.0, b.cursor.position[2]), "relative", action.number("radius"))


# --- motion models (tml verify) -------------------------------------------------------------

def loiter_motion(model: Motion, bound: BoundAction, state: PredictedState,
                  labels: Labels) -> Step:
    centre, unknown = model.point_of(bound, labels)
    if unknown:
        return model.unknown(state, labels, unknown)
    relative = bound.point("relative_coordinates", None)
    from_home = bound.point("from_home", None)
    if centre is None and relative is not None:
        centre = add(state.position, relative)
    elif centre is None and from_home is not None:
        centre = add(state.home, from_home)
    elif centre is None and "latitude" in bound.values:
        centre = model.global_point(bound)
    return model.circle(bound, state, labels, centre or state.position,
                        bound.number("radius"), bound.integer("turns", None),
                        bound.number("duration", None))


def return_home_and_loiter_motion(model: Motion, bound: BoundAction, state: PredictedState,
                                  labels: Labels) -> Step:
    step = model.circle(bound, state, labels, (*state.home[:2], state.position[2]),
                        bound.number("radius"))
    return replace(step, notes=(
        "circles home until an event ends it; no time counted for it",))


# --- reading mission items back (tml import) ------------------------------------------------

def _circle_read(item: reading.ItemFields, param1: str | None) -> reading.Arguments:
    """A loiter item: its centre when it has one, ``param1`` (turns or duration), its
    radius."""
    arguments = reading.position({}, item) if reading.placed(item) else {}
    if param1 is not None:
        arguments[param1] = reading.value(item.param1)
    if item.param3:
        arguments["radius"] = reading.value(abs(item.param3))
    return arguments


def loiter_join(before: str, before_arguments: Mapping[str, str],
                arguments: Mapping[str, str]) -> reading.Arguments | None:
    """Turns beyond what one NAV_LOITER_TURNS keeps, written as several over one circle."""
    same_circle = all(before_arguments.get(k) == arguments.get(k)
                      for k in ("latitude", "longitude", "altitude", "radius"))
    if before == "LOITER" and "turns" in arguments \
            and before_arguments.get("turns") == str(items.LOITER_TURNS_MAX) and same_circle:
        joined = dict(before_arguments)
        joined["turns"] = str(items.LOITER_TURNS_MAX + int(arguments["turns"]))
        return joined
    return None


LOITER_READING = reading.Reading({
    mav.NAV_LOITER_UNLIM: lambda item: _circle_read(item, None),
    mav.NAV_LOITER_TURNS: lambda item: _circle_read(item, "turns"),
    mav.NAV_LOITER_TIME: lambda item: _circle_read(item, "duration"),
}, join=loiter_join)
"""LOITER from each loiter item."""


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("LOITER"), guided=loiter, drives=True, items=loiter_items, motion=loiter_motion,
              item_time=timing.until_stopped, imports=LOITER_READING),
    ActionDef(spec("RETURN_HOME_AND_LOITER"), guided=return_home_and_loiter, drives=True,
              items=return_home_and_loiter_items, motion=return_home_and_loiter_motion,
              item_time=timing.until_stopped,
              imports=NotApplicable("its circle reads back as a LOITER around "
                                    "home's position")),
)
