"""ORBIT: circle a point of interest at a radius, facing it, for turns or a time.

ArduPilot has no MAV_CMD_DO_ORBIT, so ORBIT is made of what it has:

- with commands (GUIDED), a multicopter is sent round the circle target after target
  (:func:`tml.actions.guided.circle`), each position target carrying the heading from that
  target toward the point of interest; a fixed-wing circles the point natively and heads
  along its circle (it cannot face a point); a ground vehicle is refused
  (:mod:`tml.language.kinds`);
- as mission items (AUTO), DO_SET_ROI_LOCATION at the point of interest, NAV_LOITER_TURNS
  around it at the flight altitude, a NAV_WAYPOINT where the circle ends, and
  DO_SET_ROI_NONE: ArduCopter faces the ROI while it circles, and keeps facing it after the
  circle unless the ROI is cleared. ArduPilot runs the DO items that follow a navigation
  item while that item flies (AP_Mission), so the ROI is set during the item before the
  circle, and the ROI is cleared only once the circle is over, during the waypoint where it
  ends (it ends where it began: ArduCopter joins the circle at its point nearest the
  vehicle and flies whole turns). A time becomes the whole turns it takes at ArduCopter's
  default CIRCLE_RATE (20 deg/s), since ArduPilot circles only by turns;
- ``tml import`` reads those four items back as one ORBIT when they compile back exactly.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from tml.actions import guided, items, mav, reading, timing
from tml.actions.definition import ActionDef, spec
from tml.actions.guided import Context, Limits, Script
from tml.actions.motion import Labels, Motion, PredictedState, Step
from tml.geo import Point, to_local
from tml.language.actions import BoundAction
from tml.patterns import circle_entry, circle_point

TURN_SECONDS = 360.0 / 20.0
"""Seconds ArduCopter takes for one turn of NAV_LOITER_TURNS at its default CIRCLE_RATE
(20 deg/s)."""


def turns_of(bound: BoundAction) -> int:
    """The turns an ORBIT flies as mission items: its ``turns``, or the whole turns its
    ``duration`` takes at :data:`TURN_SECONDS` a turn (at least one)."""
    turns = bound.integer("turns", None)
    if turns is not None:
        return turns
    return max(1, math.ceil(bound.number("duration") / TURN_SECONDS - 1e-9))


# --- GUIDED (dispatch="command") ----------------------------------------------------------

def orbit(ctx: Context, bound: BoundAction) -> Script:
    """Fly to the circle's nearest point and go round it facing the point of interest."""
    here = guided.require_flying(ctx, "ORBIT")
    target = guided.point_argument(ctx, bound, "coordinates")
    if target is None:
        target = guided.local(ctx, bound, "target_altitude")
    centre = (target[0], target[1], bound.number("altitude", here[2]))
    yield from guided.circle(ctx, centre, bound.number("radius"), bound.integer("turns", None),
                             bound.number("duration", None), facing=target)


# --- mission items (dispatch="mission") ---------------------------------------------------

def orbit_items(b: items.Builder, action: BoundAction) -> None:
    altitude = action.number("altitude", b.cursor.position[2])
    if "latitude" in action.values:
        latitude, longitude = action.number("latitude"), action.number("longitude")
        north, east, _ = to_local(latitude, longitude, b.home.altitude, b.home.latitude,
                                  b.home.longitude, b.home.altitude)
        target: Point = (north, east, action.number("target_altitude"))
        x, y = round(latitude * 1e7), round(longitude * 1e7)
        roi_exact: tuple[int, int, float] | None = (x, y, target[2])
        circle_exact: tuple[int, int, float] | None = (x, y, altitude)
    else:
        target = action.point("coordinates")
        roi_exact = circle_exact = None
    centre = (target[0], target[1], altitude)
    radius = action.number("radius")
    b.add(mav.DO_SET_ROI_LOCATION, point=target, raw=roi_exact)
    # Where the circle ends, from the centre as the items carry it (1e-7 degrees), so that
    # the same items imported back compile to the same end.
    roi = b.items[-1]
    north, east, _ = to_local(roi.x / 1e7, roi.y / 1e7, b.home.altitude, b.home.latitude,
                              b.home.longitude, b.home.altitude)
    end = circle_point((north, east, altitude), radius,
                       circle_entry((north, east, altitude), b.cursor.position), 0)
    items.loiter_at(b, centre, "relative", radius, turns_of(action), exact=circle_exact)
    b.waypoint(end)
    b.add(mav.DO_SET_ROI_NONE)


def orbit_time(limits: Limits, vehicle_type: str, here: Point, bound: BoundAction) -> float:
    """To the circle, then each turn at the speed in force, or at CIRCLE_RATE when that is
    slower (a small circle)."""
    radius = bound.number("radius")
    turn = max(2 * math.pi * radius / limits.move_speed(vehicle_type), TURN_SECONDS)
    target = timing.target(bound)
    leg = 0.0 if target is None else limits.leg_seconds(
        vehicle_type, max(0.0, math.hypot(here[0] - target[0], here[1] - target[1]) - radius))
    return leg + turns_of(bound) * turn


# --- motion model (tml verify) ------------------------------------------------------------

def orbit_motion(model: Motion, bound: BoundAction, state: PredictedState,
                 labels: Labels) -> Step:
    target, unknown = model.point_of(bound, labels)
    if unknown:
        return model.unknown(state, labels, unknown)
    if target is None:
        target = model.local(bound.number("latitude"), bound.number("longitude"),
                             bound.number("target_altitude"), "relative")
    centre = (target[0], target[1], bound.number("altitude", state.position[2]))
    return model.circle(bound, state, labels, centre, bound.number("radius"),
                        bound.integer("turns", None), bound.number("duration", None))


# --- reading mission items back (tml import) ----------------------------------------------

_ROI = "roi"
"""The argument an ORBIT being read keeps its ROI item's position in until its circle is
read (never written: an ORBIT with it does not validate, so a lone ROI item stays a
MISSION_ITEM)."""
_CIRCLE = "circle"
"""The same for its NAV_LOITER_TURNS, until its DO_SET_ROI_NONE is read."""
_END = "end"
"""The same for the NAV_WAYPOINT where its circle ends."""
_CLEAR = "clear"
"""The same for its DO_SET_ROI_NONE (alone, it is no ORBIT)."""


def _roi_read(item: reading.ItemFields) -> reading.Arguments | None:
    if item.frame not in mav.RELATIVE_FRAMES or not reading.placed(item) \
            or item.param1 or item.param2 or item.param3 or item.param4:
        return None
    return reading.encoding({_ROI: "yes", "latitude": reading.value(item.x / 1e7),
                             "longitude": reading.value(item.y / 1e7),
                             "target_altitude": reading.value(item.z)}, item)


def _circle_read(item: reading.ItemFields) -> reading.Arguments | None:
    if item.frame not in mav.RELATIVE_FRAMES or not reading.placed(item):
        return None
    return {_CIRCLE: "yes", "latitude": reading.value(item.x / 1e7),
            "longitude": reading.value(item.y / 1e7), "altitude": reading.value(item.z),
            "turns": reading.value(item.param1), "radius": reading.value(abs(item.param3))}


def _end_read(item: reading.ItemFields) -> reading.Arguments | None:
    if item.frame not in mav.RELATIVE_FRAMES or not reading.placed(item) \
            or item.param1 or item.param2 or item.param3 or item.param4:
        return None
    return {_END: "yes", "altitude": reading.value(item.z)}


def _none_read(item: reading.ItemFields) -> reading.Arguments | None:
    return {_CLEAR: "yes"} if item.frame == mav.FRAME_MISSION and not any(
        (item.param1, item.param2, item.param3, item.param4, item.x, item.y, item.z)) else None


def orbit_join(before: str, before_arguments: Mapping[str, str],
               arguments: Mapping[str, str]) -> reading.Arguments | None:
    """The ROI item, then its circle around the same point, then the ROI cleared: one
    ORBIT."""
    if before != "ORBIT":
        return None
    if _CIRCLE in arguments and _ROI in before_arguments and _CIRCLE not in before_arguments \
            and all(before_arguments[k] == arguments[k] for k in ("latitude", "longitude")):
        return {**before_arguments, **arguments}
    if _END in arguments and _CIRCLE in before_arguments and _END not in before_arguments \
            and before_arguments["altitude"] == arguments["altitude"]:
        return {**before_arguments, _END: "yes"}  # the compiler writes where it ends
    if _CLEAR in arguments and _END in before_arguments:
        return {k: v for k, v in before_arguments.items() if k not in (_ROI, _CIRCLE, _END)}
    return None


ORBIT_READING = reading.Reading({
    mav.DO_SET_ROI_LOCATION: _roi_read,
    mav.NAV_LOITER_TURNS: _circle_read,
    mav.NAV_WAYPOINT: _end_read,
    mav.DO_SET_ROI_NONE: _none_read,
}, join=orbit_join)
"""ORBIT from its four items (the circle alone reads back as a LOITER, the waypoint as a
GO_TO_POSITION)."""


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("ORBIT"), guided=orbit, drives=False, items=orbit_items,
              item_time=orbit_time, motion=orbit_motion, imports=ORBIT_READING),
)
