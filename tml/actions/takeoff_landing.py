"""Taking off and landing: TAKE_OFF, LAND, LANDING_POINT, RETURN_HOME_AND_LAND."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

from tml.actions import guided, items, mav, reading, timing
from tml.actions.definition import ActionDef, spec
from tml.actions.guided import LANDED_READS, Context, Limits, Script, Send, Until, fly_to
from tml.actions.motion import Labels, Motion, PredictedState, Step
from tml.geo import Point
from tml.language.actions import BoundAction
from tml.language.kinds import Kind
from tml.patterns import displaced
from tml.vehicle import Arm, Disarm, Land, ReturnToLaunch, SetMode, SetYaw, TakeOff


def take_off(ctx: Context, bound: BoundAction) -> Script:
    """Arm in GUIDED and climb; ignored (as the paper says) when already flying.

    A fixed-wing cannot take off in GUIDED: its TakeOff request is ArduPlane's TAKEOFF mode
    (a climb along its heading to the altitude, then a circle), which arms it too.
    """
    altitude = bound.number("altitude")
    if ctx.state.flying:
        ctx.note("TAKE_OFF ignored: the vehicle is already flying", altitude=ctx.state.altitude)
        return
    yield Until(lambda s: s.ready, ctx.limits.ready_timeout,
                "a position estimate to arm with (EKF using GPS)")
    if guided.vehicle_kind(ctx) is not Kind.FIXED_WING:
        yield Send(SetMode(ctx.vehicle_id, "GUIDED"))
        yield Send(Arm(ctx.vehicle_id))
    yield Send(TakeOff(ctx.vehicle_id, altitude))
    tolerance = guided.tolerances(ctx)[1]
    yield Until(lambda s: s.altitude >= altitude - tolerance,
                ctx.limits.factor * altitude / ctx.limits.climb_rate + ctx.limits.slack,
                f"climb to {altitude:g} m", lambda s: max(0.0, min(1.0, s.altitude / altitude)),
                frozenset(("position", "current")))
    yaw = bound.number("yaw", math.nan)
    if not math.isnan(yaw) and guided.vehicle_kind(ctx) is not Kind.FIXED_WING:
        yield from guided.face(ctx, yaw % 360.0)


def _climb_on(ctx: Context, bound: BoundAction) -> Script:
    """A TAKE_OFF the interrupted run began, resumed with the vehicle in the air: it is not
    ignored as a fresh one would be (the next action's hold would stop the climb short of
    the altitude it was given), the climb goes on to that altitude -- a position target
    there, above where the vehicle is (a fixed-wing's TAKEOFF mode climbs on by itself) --
    and is done when the telemetry shows it."""
    altitude = bound.number("altitude")
    here = guided.current_position(ctx)
    tolerance = guided.tolerances(ctx)[1]
    if here[2] >= altitude - tolerance:
        ctx.note(f"TAKE_OFF resumed: the vehicle is at its altitude ({altitude:g} m) already",
                 altitude=ctx.state.altitude)
        return
    ctx.note(f"TAKE_OFF resumed in the air at {here[2]:.1f} m: climbing on to {altitude:g} m",
             altitude=ctx.state.altitude)
    if guided.vehicle_kind(ctx) is not Kind.FIXED_WING:
        yield from fly_to(ctx, (here[0], here[1], altitude), "TAKE_OFF")
        return
    yield Until(lambda s: s.altitude >= altitude - tolerance,
                ctx.limits.factor * (altitude - here[2]) / ctx.limits.climb_rate
                + ctx.limits.slack, f"climb to {altitude:g} m",
                lambda s: max(0.0, min(1.0, s.altitude / altitude)),
                frozenset(("position", "current")))


def land(ctx: Context, bound: BoundAction) -> Script:
    """Land where the vehicle is and wait until it is down and disarmed (a fixed-wing:
    along an approach straight ahead)."""
    if not ctx.state.possibly_flying:  # seen on the ground since it was last asked to fly
        ctx.note("LAND: the vehicle is already on the ground")
        return
    if guided.vehicle_kind(ctx) is Kind.FIXED_WING:
        yield from guided.glide(ctx, None, "LAND")
        return
    start = ctx.state.altitude
    yield Send(Land(ctx.vehicle_id))
    yield Until(guided.landed_and_disarmed,
                ctx.limits.factor * start / ctx.limits.land_rate + ctx.limits.slack,
                "land and disarm", lambda s: max(0.0, min(1.0, 1 - s.altitude / max(start, 1))),
                LANDED_READS)


def landing_point(ctx: Context, bound: BoundAction) -> Script:
    """Fly over the landing point, face the yaw if given, and land; nothing when the
    vehicle is down there already (a run resumed after it landed, as LAND)."""
    point = guided.point_argument(ctx, bound, "coordinates")
    if point is None:
        point = guided.local(ctx, bound)
    if not ctx.state.flying and guided.vehicle_kind(ctx) is not Kind.GROUND and \
            math.dist(guided.current_position(ctx)[:2], point[:2]) <= 2 * guided.tolerances(ctx)[0]:
        ctx.note("LANDING_POINT: the vehicle is already down at the landing point")
        return
    here = guided.require_flying(ctx, "LANDING_POINT")
    yaw = bound.number("yaw", None)
    precision = bound.choice("precision_mode") != "disabled"
    if guided.vehicle_kind(ctx) is Kind.FIXED_WING:
        if yaw is not None or precision:
            ctx.note("LANDING_POINT: a fixed-wing lands along its approach; yaw and "
                     "precision landing are not applied")
        yield from guided.glide(ctx, (point[0], point[1], 0.0), "LANDING_POINT")
        return
    yield from fly_to(ctx, (point[0], point[1], max(here[2], point[2])), "LANDING_POINT")
    if yaw is not None:
        yield Send(SetYaw(ctx.vehicle_id, yaw % 360))
    if precision:
        ctx.note("precision landing is applied only to dispatch=\"mission\" (NAV_LAND)")
    yield from land(ctx, bound)


def return_home_and_land(ctx: Context, bound: BoundAction) -> Script:
    """ArduPilot RTL: return, descend and land at home; done when disarmed.

    RTL flies a straight line home. When known obstacles stand on that line, the vehicle
    first flies the planned path home in GUIDED, and RTL then only descends.
    """
    here = guided.require_flying(ctx, "RETURN_HOME_AND_LAND")
    kind = guided.vehicle_kind(ctx)
    if kind is Kind.FIXED_WING:
        yield from guided.glide(ctx, (0.0, 0.0, 0.0), "RETURN_HOME_AND_LAND")
        return
    if kind is Kind.GROUND and not ctx.state.armed:
        ctx.note("RETURN_HOME_AND_LAND: the vehicle is already stopped and disarmed")
        return
    above_home = (0.0, 0.0, here[2])
    if ctx.route is not None:
        path = ctx.route(here, above_home)
        if path is not None and len(path) > 2:
            yield from fly_to(ctx, above_home, "RETURN_HOME_AND_LAND")
            here = guided.current_position(ctx)
    yield Send(ReturnToLaunch(ctx.vehicle_id))
    if kind is Kind.GROUND:
        # Rover's RTL drives home and stops there, armed: then tml disarms it.
        home = guided.arrived(ctx, (0.0, 0.0, 0.0))
        yield Until(lambda s: home(s) and s.ground_speed <= 0.3,
                    guided.travel_time(ctx, here, (0.0, 0.0, 0.0)), "drive home and stop",
                    lambda s: 1.0 - min(1.0, math.dist(s.position or here, (0, 0, 0))
                                        / max(math.dist(here, (0, 0, 0)), 1.0)))
        yield Send(Disarm(ctx.vehicle_id))
        yield Until(lambda s: not s.armed, ctx.limits.slack, "disarm")
        return
    limit = guided.travel_time(ctx, here, (0.0, 0.0, 0.0)) + ctx.limits.factor * max(
        here[2], 15.0) / ctx.limits.land_rate
    yield Until(guided.landed_and_disarmed, limit, "return home and land",
                lambda s: 1.0 - min(1.0, math.dist(s.position or here, (0, 0, 0))
                                    / max(math.dist(here, (0, 0, 0)), 1.0)), LANDED_READS)


# --- mission items (dispatch="mission") ----------------------------------------

def take_off_items(b: items.Builder, action: BoundAction) -> None:
    altitude = action.number("altitude")
    n, e, _ = b.cursor.position
    params = (action.number("pitch"), 0.0, 0.0, action.number("yaw", 0.0))
    if "latitude" in action.values:  # the position the item carries, as written
        b.add(mav.NAV_TAKEOFF, point=(n, e, altitude), params=params,
              raw=(round(action.number("latitude") * 1e7),
                   round(action.number("longitude") * 1e7), altitude))
    else:
        b.add(mav.NAV_TAKEOFF, altitude=altitude, params=params)
    b.cursor.position = (n, e, altitude)


def land_items(b: items.Builder, action: BoundAction) -> None:
    if b.kind is Kind.FIXED_WING:
        items.glide(b, None)
        return
    b.add(mav.NAV_LAND, point=b.cursor.position)
    b.cursor.position = (*b.cursor.position[:2], 0.0)


def landing_point_items(b: items.Builder, action: BoundAction) -> None:
    exact = None
    if "latitude" in action.values:
        point, reference = items.global_point(b, action, action.choice("altitude_reference"))
        exact = items.written_position(b, action)
    else:
        point, reference = action.point("coordinates", b.cursor.position), "relative"
    if b.kind is Kind.FIXED_WING:
        items.glide(b, (point[0], point[1], 0.0))
        return
    items.land_at(b, action, point, reference, exact)


def return_home_and_land_items(b: items.Builder, action: BoundAction) -> None:
    if b.kind is Kind.FIXED_WING:
        items.glide(b, (0.0, 0.0, 0.0))
        return
    if action.number("yaw", None) is None and action.choice("precision_mode") == "disabled":
        b.add(mav.NAV_RETURN_TO_LAUNCH)
        b.cursor.position = (0.0, 0.0, 0.0)
        return
    # RTL carries neither a heading nor a precision-landing mode: fly home, then land.
    b.waypoint((0.0, 0.0, b.cursor.position[2]))
    items.land_at(b, action, b.cursor.position, "relative")


# --- motion models (tml verify) -------------------------------------------------------------

def take_off_motion(model: Motion, bound: BoundAction, state: PredictedState,
                    labels: Labels) -> Step:
    if state.flying:
        return Step(state, state, labels=labels, notes=("already flying: ignored",))
    if model.profile.kind is Kind.GROUND:
        return Step(state, state, labels=labels)  # refused: see the vehicle constraint
    written = bound.action.argument("altitude", "height") is not None
    altitude = bound.number("altitude") if written else model.profile.takeoff_altitude
    target = (state.position[0], state.position[1], altitude)
    if model.profile.kind is Kind.FIXED_WING:  # a climb along the heading
        run = altitude / model.profile.climb_rate * model.profile.cruise_speed
        target = (*displaced(state.position, state.heading, "forward", run)[:2], altitude)
    step = model.go(bound, replace(state, flying=True), labels, [target], cruise=False)
    return replace(step, before=state)


def land_motion(model: Motion, bound: BoundAction, state: PredictedState,
                labels: Labels) -> Step:
    if model.profile.kind is Kind.FIXED_WING:
        return model.landing(bound, state, labels, None)
    if model.profile.kind is Kind.GROUND:
        return Step(state, state, labels=labels)  # refused: see the vehicle constraint
    target = (state.position[0], state.position[1], 0.0)
    step = model.go(bound, state, labels, [target], landing=True, cruise=False)
    return replace(step, after=replace(step.after, flying=False))


def landing_point_motion(model: Motion, bound: BoundAction, state: PredictedState,
                         labels: Labels) -> Step:
    point, unknown = model.point_of(bound, labels)
    if unknown:
        return model.unknown(state, labels, unknown)
    if point is None:
        point = model.global_point(bound)
    if model.profile.kind is Kind.FIXED_WING:
        return model.landing(bound, state, labels, (point[0], point[1], 0.0))
    targets = [(point[0], point[1], state.position[2]), (point[0], point[1], 0.0)]
    step = model.go(bound, state, labels, targets, landing=True, cruise=False)
    return replace(step, after=replace(step.after, flying=False))


def return_home_and_land_motion(model: Motion, bound: BoundAction, state: PredictedState,
                                labels: Labels) -> Step:
    if model.profile.kind is Kind.FIXED_WING:
        return model.landing(bound, state, labels, state.home)
    after, legs, blocked = model.fly_home_and_land(state, state.home)
    return Step(state, replace(after, flying=False), tuple(legs), tuple(blocked),
                labels=labels, destination=state.home)


# --- time of the mission items (the interpreter's watch) ------------------------------------

def take_off_time(limits: Limits, vehicle_type: str, here: Point, bound: BoundAction) -> float:
    """The climb to the take-off altitude."""
    return timing.nominal(limits, vehicle_type, here, bound) \
        + bound.number("altitude") / limits.climb_rate


def land_time(limits: Limits, vehicle_type: str, here: Point, bound: BoundAction) -> float:
    """Down where the vehicle is."""
    return timing.nominal(limits, vehicle_type, here, bound) \
        + timing.landing(limits, vehicle_type, here, here)


def landing_point_time(limits: Limits, vehicle_type: str, here: Point,
                       bound: BoundAction) -> float:
    """Over the landing point (taken as where the vehicle is for a WGS84 one), then down."""
    over = here if "latitude" in bound.values else timing.target(bound) or (0.0, 0.0, 0.0)
    return timing.nominal(limits, vehicle_type, here, bound) \
        + timing.landing(limits, vehicle_type, here, over)


def return_home_and_land_time(limits: Limits, vehicle_type: str, here: Point,
                              bound: BoundAction) -> float:
    """Home, then down."""
    return timing.nominal(limits, vehicle_type, here, bound) \
        + timing.landing(limits, vehicle_type, here, (0.0, 0.0, 0.0))


# --- reading mission items back (tml import) ------------------------------------------------

def take_off_read(item: reading.ItemFields) -> reading.Arguments:
    """NAV_TAKEOFF: its altitude and pitch, and the position and yaw it carries when it has
    them."""
    arguments = {"altitude": reading.value(item.z), "pitch": reading.value(item.param1)}
    if reading.placed(item):
        arguments["latitude"] = reading.value(item.x / 1e7)
        arguments["longitude"] = reading.value(item.y / 1e7)
    if item.param4 != 0:  # NaN included
        arguments["yaw"] = reading.value(item.param4)
    return reading.encoding(arguments, item)


def land_read(item: reading.ItemFields) -> reading.Arguments | None:
    """NAV_LAND where the vehicle is (no position)."""
    return None if reading.placed(item) else {}


def landing_point_read(item: reading.ItemFields) -> reading.Arguments | None:
    """NAV_LAND at a position, with its precision landing mode and heading (1 or -1: the
    direction ArduPilot writes back, unless a turn to it comes before: see the join), and
    the altitude it carries when 0 in a frame above home."""
    if not reading.placed(item):
        return None
    arguments = reading.position({}, item)
    precision = {number: name for name, number in items.PRECISION_MODES.items()}
    if int(item.param2) in precision:
        arguments["precision_mode"] = precision[int(item.param2)]
    if item.param4 in (1, -1):
        arguments["loiter_direction"] = "clockwise" if item.param4 > 0 else "counter-clockwise"
    elif item.param4:
        arguments["yaw"] = reading.value(item.param4)
    if item.z == 0 and item.frame in (mav.FRAME_GLOBAL_RELATIVE_ALT,
                                      mav.FRAME_GLOBAL_RELATIVE_ALT_INT):
        arguments["keep_altitude"] = "yes"
    return arguments


def landing_point_join(before: str, before_arguments: Mapping[str, str],
                       arguments: Mapping[str, str]) -> reading.Arguments | None:
    """The CONDITION_YAW to the heading it lands with, then its NAV_LAND: one action (a
    heading of 1 or -1 read as a direction is the yaw again)."""
    joined = dict(arguments)
    direction = joined.pop("loiter_direction", None)
    if direction is not None:
        joined["yaw"] = "1" if direction == "clockwise" else "-1"
    if before == "ROTATE_YAW" and "yaw" in joined and before_arguments.get(
            "orientation_angle") == reading.value(float(joined["yaw"]) % 360.0):
        return joined
    return None


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("TAKE_OFF"), guided=take_off, resumed=_climb_on, items=take_off_items,
              motion=take_off_motion, item_time=take_off_time,
              imports=reading.Reading({mav.NAV_TAKEOFF: take_off_read})),
    ActionDef(spec("LAND"), guided=land, items=land_items, motion=land_motion, item_time=land_time,
              imports=reading.Reading({mav.NAV_LAND: land_read})),
    ActionDef(spec("LANDING_POINT"), guided=landing_point, items=landing_point_items,
              motion=landing_point_motion, item_time=landing_point_time,
              imports=reading.Reading({mav.NAV_LAND: landing_point_read}, join=landing_point_join)),
    ActionDef(spec("RETURN_HOME_AND_LAND"), guided=return_home_and_land,
              items=return_home_and_land_items, motion=return_home_and_land_motion,
              item_time=return_home_and_land_time,
              imports=reading.Reading({mav.NAV_RETURN_TO_LAUNCH:
                                       lambda item: reading.frame({}, item)})),
)
