"""Covering an area: SURVEY_AREA's lawnmower and EXPLORE_SPACE's expanding square
(the points from :mod:`tml.patterns`)."""

from __future__ import annotations

import math
from itertools import pairwise

from tml.actions import guided, items, timing
from tml.actions.definition import ActionDef, NotApplicable, spec
from tml.actions.guided import Context, Limits, Script, fly_to
from tml.actions.motion import Labels, Motion, PredictedState, Step
from tml.geo import Point
from tml.language.actions import BoundAction
from tml.patterns import expanding_square, survey


def survey_area(ctx: Context, bound: BoundAction) -> Script:
    """Lawnmower passes over the area, each along its length, ``spacing`` apart, the last
    on the far edge (:func:`tml.patterns.survey`)."""
    here = guided.require_flying(ctx, "SURVEY_AREA")
    base = guided_base(ctx, bound, here)
    altitude = bound.number("altitude", here[2])
    for point in survey((base[0], base[1], altitude), bound.number("length"),
                        bound.number("width"), bound.number("spacing"),
                        bound.choice("direction")):
        yield from fly_to(ctx, point, "SURVEY_AREA")


def guided_base(ctx: Context, bound: BoundAction, here: Point) -> Point:
    """Where a survey's rectangle starts (SURVEY_AREA, SURVEY_PHOTOS): its ``coordinates``,
    ``latitude`` and ``longitude``, or ``here``."""
    base = guided.point_argument(ctx, bound, "coordinates")
    if base is None and "latitude" in bound.values:
        base = guided.local(ctx, bound)
    return base or here


def explore_space(ctx: Context, bound: BoundAction) -> Script:
    """An expanding square around the start out to ``radius``, passes ``spacing`` apart,
    then back to the start (:func:`tml.patterns.expanding_square`)."""
    here = guided.require_flying(ctx, "EXPLORE_SPACE")
    for point in expanding_square(here, bound.number("radius"), bound.number("spacing")):
        yield from fly_to(ctx, point, "EXPLORE_SPACE")


# --- mission items (dispatch="mission") ----------------------------------------

def items_base(b: items.Builder, action: BoundAction) -> Point:
    """Where a survey's rectangle starts, as its mission items place it."""
    if "latitude" in action.values:
        return items.global_point(b, action)[0]
    return action.point("coordinates", b.cursor.position)


def survey_area_items(b: items.Builder, action: BoundAction) -> None:
    base = items_base(b, action)
    altitude = action.number("altitude", b.cursor.position[2])
    for point in survey((base[0], base[1], altitude), action.number("length"),
                        action.number("width"), action.number("spacing"),
                        action.choice("direction")):
        b.waypoint(point)


def explore_space_items(b: items.Builder, action: BoundAction) -> None:
    for point in expanding_square(b.cursor.position, action.number("radius"),
                                  action.number("spacing")):
        b.waypoint(point)


# --- motion models (tml verify) -------------------------------------------------------------

def motion_base(model: Motion, bound: BoundAction, state: PredictedState,
                labels: Labels) -> tuple[Point, str]:
    """Where a survey's rectangle starts, as ``tml verify`` predicts it, and the label read
    that holds no point ("" when none)."""
    base, unknown = model.point_of(bound, labels)
    if base is None and "latitude" in bound.values:
        base = model.local(bound.number("latitude"), bound.number("longitude"), 0.0,
                           "relative")
    return base or state.position, unknown


def survey_area_motion(model: Motion, bound: BoundAction, state: PredictedState,
                       labels: Labels) -> Step:
    base, unknown = motion_base(model, bound, state, labels)
    if unknown:
        return model.unknown(state, labels, unknown)
    altitude = bound.number("altitude", None) or state.position[2]
    targets = survey((base[0], base[1], altitude), bound.number("length"),
                     bound.number("width"), bound.number("spacing"),
                     bound.choice("direction"))
    return model.go(bound, state, labels, targets)


def explore_space_motion(model: Motion, bound: BoundAction, state: PredictedState,
                         labels: Labels) -> Step:
    targets = expanding_square(state.position, bound.number("radius"),
                               bound.number("spacing"))
    return model.go(bound, state, labels, targets)


# --- time of the mission items (the interpreter's watch) ------------------------------------

def survey_area_time(limits: Limits, vehicle_type: str, here: Point,
                     bound: BoundAction) -> float:
    """The lawnmower flown (:func:`tml.patterns.survey`), from its base."""
    return lawnmower_time(limits, vehicle_type, here, bound, bound.number("spacing"))


def lawnmower_time(limits: Limits, vehicle_type: str, here: Point, bound: BoundAction,
                   spacing: float) -> float:
    """To the base of a survey's rectangle, then its passes ``spacing`` apart."""
    passes = survey((0.0, 0.0, 0.0), bound.number("length"), bound.number("width"),
                    spacing, bound.choice("direction"))
    return timing.nominal(limits, vehicle_type, here, bound) + sum(
        limits.leg_seconds(vehicle_type, math.dist(a, b)) for a, b in pairwise(passes))


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("SURVEY_AREA"), guided=survey_area, drives=True, items=survey_area_items,
              motion=survey_area_motion, item_time=survey_area_time,
              imports=NotApplicable("its passes read back as GO_TO_POSITION "
                                    "waypoints")),
    ActionDef(spec("EXPLORE_SPACE"), guided=explore_space, drives=True, items=explore_space_items,
              motion=explore_space_motion, item_time=timing.nominal,
              imports=NotApplicable("its square reads back as GO_TO_POSITION "
                                    "waypoints")),
)
