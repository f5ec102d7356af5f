"""SURVEY_PHOTOS: photograph a rectangle, the passes and the photos spaced for a camera.

A camera looking straight down from ``altitude`` sees a footprint on the ground of
``altitude x sensor / focal_length`` in each direction (the sensor's width across the
passes, its height along them). Photos that overlap by ``side_overlap`` percent from one
pass to the next need passes ``(1 - side_overlap / 100) x`` the footprint's width apart;
photos that overlap by ``front_overlap`` along a pass need one each ``(1 - front_overlap /
100) x`` its length flown. A ``ground_resolution`` (cm a pixel) sets the altitude instead:
``altitude = ground_resolution / 100 x focal_length x image_width / sensor_width``.

The rectangle is flown as SURVEY_AREA flies it (:func:`tml.patterns.survey`), and the
autopilot takes the photos by distance, as ArduPilot's camera library does: once
DO_SET_CAM_TRIGG_DIST sets a distance (its "trigger once" taking the first photo at once),
a photo each time the vehicle is that far (horizontally, in a straight line) from where it
took the last one, until a distance of 0 stops it:

- with commands (GUIDED), the vehicle flies to the base point, the distance is sent as
  COMMAND_LONG DO_SET_CAM_TRIGG_DIST, the passes are flown target after target, and a
  distance of 0 is sent at the end;
- as mission items (AUTO), a NAV_WAYPOINT at the base point, DO_SET_CAM_TRIGG_DIST, the
  passes' waypoints, the last waypoint again, then DO_SET_CAM_TRIGG_DIST 0. ArduPilot runs
  the DO items after a navigation item while that item flies (AP_Mission), so the first is
  run once the base point is reached, and the stop only once the last point is: run right
  after the last pass's waypoint, it would stop the photos as that pass begins;
- ``tml verify`` predicts the photos by the same rule along the passes
  (:func:`photo_points`): their count in a note and their positions in the JSON report.
  CAMERA_FEEDBACK from the vehicle says where it took them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from itertools import pairwise

from tml.actions import guided, items, mav
from tml.actions.areas import guided_base, items_base, lawnmower_time, motion_base
from tml.actions.definition import ActionDef, NotApplicable, spec
from tml.actions.guided import ActionFailed, Context, Limits, Script, Send, fly_to
from tml.actions.motion import Labels, Motion, PredictedState, Step
from tml.geo import Point
from tml.language.actions import BoundAction
from tml.language.quantities import RANGES, Quantity
from tml.patterns import survey
from tml.vehicle import Camera

MIN_ALTITUDE = 1.0
"""m above home a survey is photographed from, at the lowest: below it the footprint, the
passes and the trigger distance shrink toward nothing."""


@dataclass(frozen=True)
class PhotoPlan:
    """How a SURVEY_PHOTOS is flown and photographed."""

    altitude: float  # m above home
    footprint: tuple[float, float]  # m on the ground: (across the passes, along them)
    spacing: float  # m between passes
    trigger_distance: float  # m flown between photos


def photo_plan(bound: BoundAction, current_altitude: float) -> PhotoPlan:
    """The plan of a SURVEY_PHOTOS flown from ``current_altitude`` (used when neither
    ``altitude`` nor ``ground_resolution`` is given); ValueError, saying why, when the
    altitude is below :data:`MIN_ALTITUDE`."""
    focal = bound.number("focal_length")
    sensor_width, sensor_height = bound.number("sensor_width"), bound.number("sensor_height")
    altitude = bound.number("altitude", None)
    if altitude is None and "ground_resolution" in bound.values:
        altitude = bound.number("ground_resolution") / 100 * focal \
            * bound.integer("image_width") / sensor_width
    if altitude is None:
        altitude = current_altitude
    if altitude < MIN_ALTITUDE:
        raise ValueError(f"SURVEY_PHOTOS would photograph from {altitude:.1f} m, below "
                         f"{MIN_ALTITUDE:g} m: give its altitude or ground_resolution, or "
                         f"fly it once in the air")
    across = altitude * sensor_width / focal
    along = altitude * sensor_height / focal
    plan = PhotoPlan(altitude, (across, along),
                     across * (1 - bound.number("side_overlap") / 100),
                     along * (1 - bound.number("front_overlap") / 100))
    # The passes and the photos are as far apart as SURVEY_AREA's passes may be: closer,
    # a survey is a cloud of points and photos (a sensor of 1e-320 mm, an overlap of 100 %).
    limits = RANGES[Quantity.SPACING]
    for name, value in (("passes", plan.spacing), ("photos", plan.trigger_distance)):
        if not limits.low <= value <= limits.high:
            raise ValueError(f"SURVEY_PHOTOS would take its {name} {value:.3g} m apart, "
                             f"outside {limits.low:g} to {limits.high:g} m: check the "
                             "camera's sensor, focal length, overlaps and the altitude")
    return plan


def passes(base: Point, bound: BoundAction, plan: PhotoPlan) -> list[Point]:
    """The points of the lawnmower, from the base point."""
    return survey((base[0], base[1], plan.altitude), bound.number("length"),
                  bound.number("width"), plan.spacing, bound.choice("direction"))


def photo_points(path: list[Point], distance: float) -> list[Point]:
    """Where a camera triggered by ``distance`` takes photos along ``path`` (straight legs
    from its first point): one at the first point, then one each time the vehicle is
    ``distance`` metres from the last photo, measured horizontally in a straight line, as
    ArduPilot's AP_Camera judges it."""
    if not path or distance <= 0:
        return []
    photos = [path[0]]
    last = path[0]
    for a, b in pairwise(path):
        start = 0.0  # the fraction of the leg already flown past the last photo
        while True:
            t = _reach(last, a, b, distance, start)
            if t is None:
                break
            last = (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]),
                    a[2] + t * (b[2] - a[2]))
            photos.append(last)
            start = t
    return photos


def _reach(centre: Point, a: Point, b: Point, distance: float, start: float) -> float | None:
    """The first fraction ``t`` >= ``start`` of the leg from ``a`` to ``b`` at which the
    vehicle is ``distance`` horizontally from ``centre``, or None."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    fx, fy = a[0] - centre[0], a[1] - centre[1]
    qa, qb, qc = dx * dx + dy * dy, 2 * (fx * dx + fy * dy), fx * fx + fy * fy
    if qa == 0:
        return None
    disc = qb * qb - 4 * qa * (qc - distance * distance)
    if disc < 0:
        return None
    for t in sorted(((-qb - math.sqrt(disc)) / (2 * qa), (-qb + math.sqrt(disc)) / (2 * qa))):
        # Leaving the circle (the distance growing): a photo is due there.
        if start + 1e-9 < t <= 1 + 1e-12 and 2 * qa * t + qb > 0:
            return min(t, 1.0)
    return None


# --- GUIDED (dispatch="command") ----------------------------------------------------------

def survey_photos(ctx: Context, bound: BoundAction) -> Script:
    """To the base point, the trigger distance on, the passes, the trigger off."""
    here = guided.require_flying(ctx, "SURVEY_PHOTOS")
    try:
        plan = photo_plan(bound, here[2])
    except ValueError as error:
        raise ActionFailed("infeasible", str(error)) from None
    first, *rest = passes(guided_base(ctx, bound, here), bound, plan)
    yield from fly_to(ctx, first, "SURVEY_PHOTOS")
    yield Send(Camera(ctx.vehicle_id, "distance", distance=plan.trigger_distance))
    for point in rest:
        yield from fly_to(ctx, point, "SURVEY_PHOTOS")
    yield Send(Camera(ctx.vehicle_id, "distance", distance=0.0))


# --- mission items (dispatch="mission") ---------------------------------------------------

def survey_photos_items(b: items.Builder, action: BoundAction) -> None:
    plan = photo_plan(action, b.cursor.position[2])
    first, *rest = passes(items_base(b, action), action, plan)
    b.waypoint(first)
    # param3 = 1: the first photo at once ("trigger once").
    b.add(mav.DO_SET_CAM_TRIGG_DIST, params=(plan.trigger_distance, 0.0, 1.0, 0.0))
    for point in rest:
        b.waypoint(point)
    b.waypoint(rest[-1])  # the stop runs only once the last point is reached
    b.add(mav.DO_SET_CAM_TRIGG_DIST)


def survey_photos_time(limits: Limits, vehicle_type: str, here: Point,
                       bound: BoundAction) -> float:
    """The lawnmower flown, its passes as far apart as the plan lays them."""
    return lawnmower_time(limits, vehicle_type, here, bound,
                          photo_plan(bound, here[2]).spacing)


# --- motion model (tml verify) ------------------------------------------------------------

def survey_photos_motion(model: Motion, bound: BoundAction, state: PredictedState,
                         labels: Labels) -> Step:
    base, unknown = motion_base(model, bound, state, labels)
    if unknown:
        return model.unknown(state, labels, unknown)
    try:
        plan = photo_plan(bound, state.position[2])
    except ValueError as error:
        return Step(state, state, labels=labels, notes=(f"{error}; not predicted",))
    targets = passes(base, bound, plan)
    photos = photo_points(targets, plan.trigger_distance)
    step = model.go(bound, state, labels, targets)
    note = (f"{len(photos)} photos predicted, one every "
            f"{plan.trigger_distance:.1f} m, passes {plan.spacing:.1f} m apart at "
            f"{plan.altitude:.1f} m (a photo covers {plan.footprint[0]:.1f} x "
            f"{plan.footprint[1]:.1f} m)")
    return replace(step, photos=tuple(photos), notes=(*step.notes, note))


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("SURVEY_PHOTOS"), guided=survey_photos, drives=True,
              items=survey_photos_items, item_time=survey_photos_time,
              motion=survey_photos_motion,
              imports=NotApplicable("its passes read back as GO_TO_POSITION waypoints and "
                                    "its camera items as MISSION_ITEMs")),
)
