"""Moves to a point: GO_TO_POINT, MOVE, MOVE_FORWARDS, MOVE_FROM_HOME, GO_TO_POSITION,
SET_ALTITUDE, RETURN_HOME and GO_TO_RECTANGLE (IMAV 2016)."""

from __future__ import annotations

import math
from dataclasses import replace

from tml.actions import guided, items, mav, reading, timing
from tml.actions.definition import ActionDef, NotApplicable, spec
from tml.actions.guided import ActionFailed, Context, Script, Send, Sleep, fly_to
from tml.actions.motion import Labels, Motion, PredictedState, Step, add
from tml.language.actions import BoundAction
from tml.patterns import displaced
from tml.vehicle import Hold


def go_to_point(ctx: Context, bound: BoundAction) -> Script:
    """Fly to a local point, a memorized label, or a point relative to the vehicle."""
    here = guided.reference(ctx)
    target = guided.point_argument(ctx, bound, "coordinates")
    if target is None:
        dn, de, du = bound.point("relative_coordinates")
        target = (here[0] + dn, here[1] + de, here[2] + du)
    yield from fly_to(ctx, target, "GO_TO_POINT")


def move(ctx: Context, bound: BoundAction) -> Script:
    """Move by a displacement, or a distance in a direction relative to the heading."""
    here = guided.reference(ctx)
    if "coordinates" in bound.values:
        dn, de, du = bound.point("coordinates")
        target = (here[0] + dn, here[1] + de, here[2] + du)
    else:
        target = displaced(here, ctx.state.heading, bound.choice("direction"),
                           bound.number("distance"))
    yield from fly_to(ctx, target, bound.name)


def move_forwards(ctx: Context, bound: BoundAction) -> Script:
    """Move straight ahead along the heading."""
    here = guided.reference(ctx)
    target = displaced(here, ctx.state.heading, "forward", bound.number("distance"))
    yield from fly_to(ctx, target, "MOVE_FORWARDS")


def move_from_home(ctx: Context, bound: BoundAction) -> Script:
    """Fly to an offset from home (the local frame's origin)."""
    yield from fly_to(ctx, bound.point("coordinates"), "MOVE_FROM_HOME")


def go_to_position(ctx: Context, bound: BoundAction) -> Script:
    """Fly to a WGS84 position (reached within ``acceptance_radius`` when given), then face
    ``yaw`` and hover for ``hold`` seconds when given, as ArduCopter flies a NAV_WAYPOINT
    with those params."""
    radius = bound.number("acceptance_radius", 0.0)
    yield from fly_to(ctx, guided.local(ctx, bound), "GO_TO_POSITION", within=radius or None)
    yaw = bound.number("yaw", math.nan)
    if not math.isnan(yaw):
        yield from guided.face(ctx, yaw % 360.0)
    hold = bound.number("hold", 0.0)
    if hold > 0:
        yield Send(Hold(ctx.vehicle_id))
        yield Sleep(hold)


def set_altitude(ctx: Context, bound: BoundAction) -> Script:
    """Climb or descend where the vehicle is."""
    here = guided.reference(ctx)
    altitude = bound.number("altitude")
    if bound.choice("altitude_reference") == "amsl" and ctx.state.home is not None:
        altitude -= ctx.state.home.altitude
    yield from fly_to(ctx, (here[0], here[1], altitude), "SET_ALTITUDE")


def return_home(ctx: Context, bound: BoundAction) -> Script:
    """Fly back over home at the current altitude and hold."""
    here = guided.require_flying(ctx, "RETURN_HOME")
    yield from fly_to(ctx, (0.0, 0.0, here[2]), "RETURN_HOME")


def go_to_rectangle(ctx: Context, bound: BoundAction) -> Script:
    """Fly to the coloured frame known in the environment, 1 m in front of it."""
    colour = bound.text("frame_color").lower()
    frames = [o for o in (ctx.world.objects if ctx.world else ())
              if o.kind == "frame" and o.color.lower() == colour]
    if not frames:
        raise ActionFailed("infeasible", f"no {colour} frame is known in the environment")
    here = guided.current_position(ctx)
    frame = min(frames, key=lambda o: math.hypot(o.north - here[0], o.east - here[1]))
    distance = math.hypot(frame.north - here[0], frame.east - here[1])
    back = min(1.0, distance) / max(distance, 1e-6)
    target = (frame.north - (frame.north - here[0]) * back,
              frame.east - (frame.east - here[1]) * back, frame.altitude or here[2])
    yield from fly_to(ctx, target, "GO_TO_RECTANGLE")


# --- mission items (dispatch="mission") ----------------------------------------

def go_to_point_items(b: items.Builder, action: BoundAction) -> None:
    point = action.point("coordinates", None)
    if point is None:
        point = items.plus(b.cursor.position, action.point("relative_coordinates", (0.0, 0.0, 0.0)))
    b.waypoint(point)


def move_items(b: items.Builder, action: BoundAction) -> None:
    offset = action.point("coordinates", None)
    if offset is not None:
        b.waypoint(items.plus(b.cursor.position, offset))
    else:
        b.waypoint(displaced(b.cursor.position, b.cursor.heading, action.choice("direction"),
                             action.number("distance")))


def move_forwards_items(b: items.Builder, action: BoundAction) -> None:
    b.waypoint(displaced(b.cursor.position, b.cursor.heading, "forward",
                         action.number("distance")))


def move_from_home_items(b: items.Builder, action: BoundAction) -> None:
    b.waypoint(action.point("coordinates", (0.0, 0.0, b.cursor.position[2])))


def go_to_position_items(b: items.Builder, action: BoundAction) -> None:
    point, reference = items.global_point(b, action, action.choice("altitude_reference"))
    b.waypoint(point, reference, items.written_position(b, action),
               params=tuple(action.number(name, 0.0) for name in WAYPOINT_PARAMS))


def set_altitude_items(b: items.Builder, action: BoundAction) -> None:
    reference = action.choice("altitude_reference")
    altitude = action.number("altitude")
    up = altitude - b.home.altitude if reference == "amsl" else altitude
    n, e, _ = b.cursor.position
    # A waypoint above the expected position: DO_CHANGE_ALTITUDE only changes the altitude
    # of the navigation command in progress, which may already be done (and ArduCopter 4.7
    # refuses it in a mission upload as UNSUPPORTED).
    b.waypoint((n, e, up), reference)


def return_home_items(b: items.Builder, action: BoundAction) -> None:
    b.waypoint((0.0, 0.0, b.cursor.position[2]))


# --- motion models (tml verify) -------------------------------------------------------------

def go_to_point_motion(model: Motion, bound: BoundAction, state: PredictedState,
                       labels: Labels) -> Step:
    point, unknown = model.point_of(bound, labels)
    if unknown:
        return model.unknown(state, labels, unknown)
    if point is None:
        point = add(state.position, bound.point("relative_coordinates"))
    return model.go(bound, state, labels, [point])


def move_motion(model: Motion, bound: BoundAction, state: PredictedState,
                labels: Labels) -> Step:
    offset = bound.point("coordinates", None)
    if offset is not None:
        return model.go(bound, state, labels, [add(state.position, offset)])
    target = displaced(state.position, state.heading, bound.choice("direction"),
                       bound.number("distance"))
    return model.go(bound, state, labels, [target])


def move_forwards_motion(model: Motion, bound: BoundAction, state: PredictedState,
                         labels: Labels) -> Step:
    target = displaced(state.position, state.heading, "forward", bound.number("distance"))
    return model.go(bound, state, labels, [target])


def move_from_home_motion(model: Motion, bound: BoundAction, state: PredictedState,
                          labels: Labels) -> Step:
    return model.go(bound, state, labels, [add(state.home, bound.point("coordinates"))])


def go_to_position_motion(model: Motion, bound: BoundAction, state: PredictedState,
                          labels: Labels) -> Step:
    step = model.go(bound, state, labels, [model.global_point(bound)])
    hold = bound.number("hold", 0.0)
    return replace(step, after=model.hover(step.after, hold)) if hold > 0 else step


def set_altitude_motion(model: Motion, bound: BoundAction, state: PredictedState,
                        labels: Labels) -> Step:
    altitude = bound.number("altitude")
    if bound.choice("altitude_reference") == "amsl":
        altitude -= model.home.altitude
    return model.go(bound, state, labels, [(*state.position[:2], altitude)])


def return_home_motion(model: Motion, bound: BoundAction, state: PredictedState,
                       labels: Labels) -> Step:
    return model.go(bound, state, labels, [(*state.home[:2], state.position[2])])


def go_to_rectangle_motion(model: Motion, bound: BoundAction, state: PredictedState,
                           labels: Labels) -> Step:
    colour = bound.text("frame_color").lower()
    frames = [o for o in model.world.objects if o.kind == "frame" and o.color.lower() == colour]
    if not frames:
        return Step(state, state, labels=labels, notes=(
            f"no {colour} frame in the world: where it is is known only in flight",))
    frame = frames[0]
    return model.go(bound, state, labels, [(frame.north, frame.east, frame.altitude)])


# --- reading mission items back (tml import) ------------------------------------------------

WAYPOINT_PARAMS = ("hold", "acceptance_radius", "pass_radius", "yaw")
"""GO_TO_POSITION's arguments that are a NAV_WAYPOINT's param1 to param4."""


def go_to_position_read(item: reading.ItemFields) -> reading.Arguments | None:
    """NAV_WAYPOINT at a position, with its hold, acceptance and pass radius and yaw when
    not 0 (NaN kept as NaN)."""
    if not reading.placed(item):
        return None
    arguments = reading.position({}, item)
    params = (item.param1, item.param2, item.param3, item.param4)
    for name, param in zip(WAYPOINT_PARAMS, params, strict=True):
        if param != 0:  # NaN included
            arguments[name] = reading.value(param)
    return arguments


def set_altitude_read(item: reading.ItemFields) -> reading.Arguments | None:
    """NAV_WAYPOINT "here", at an altitude."""
    if reading.placed(item):
        return None
    return reading.encoding({"altitude": reading.value(item.z)}, item)


_NO_ITEM = NotApplicable("flies to a frame the camera sees in flight, which no "
                         "mission item can name")
"""Why GO_TO_RECTANGLE has no mission item (nor an item time)."""


_AS_WAYPOINT = NotApplicable("its waypoint reads back as a GO_TO_POSITION (tml import "
                             "reads positions as written, in WGS84)")
"""Why the moves to a local point are not read back."""


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("GO_TO_POINT"), guided=go_to_point, drives=True, items=go_to_point_items,
              motion=go_to_point_motion, item_time=timing.nominal, imports=_AS_WAYPOINT),
    ActionDef(spec("MOVE"), guided=move, drives=True, items=move_items, motion=move_motion,
              item_time=timing.nominal, imports=_AS_WAYPOINT),
    ActionDef(spec("MOVE_FORWARDS"), guided=move_forwards, drives=True, items=move_forwards_items,
              motion=move_forwards_motion, item_time=timing.nominal, imports=_AS_WAYPOINT),
    ActionDef(spec("MOVE_FROM_HOME"), guided=move_from_home, drives=True,
              items=move_from_home_items, motion=move_from_home_motion, item_time=timing.nominal,
              imports=_AS_WAYPOINT),
    ActionDef(spec("GO_TO_POSITION"), guided=go_to_position, drives=True,
              items=go_to_position_items, motion=go_to_position_motion, item_time=timing.nominal,
              imports=reading.Reading({mav.NAV_WAYPOINT: go_to_position_read})),
    ActionDef(spec("SET_ALTITUDE"), guided=set_altitude, drives=True, items=set_altitude_items,
              motion=set_altitude_motion, item_time=timing.nominal,
              imports=reading.Reading({mav.NAV_WAYPOINT: set_altitude_read})),
    ActionDef(spec("RETURN_HOME"), guided=return_home, drives=True, items=return_home_items,
              motion=return_home_motion, item_time=timing.nominal, imports=_AS_WAYPOINT),
    ActionDef(spec("GO_TO_RECTANGLE"), guided=go_to_rectangle, drives=True, items=_NO_ITEM,
              motion=go_to_rectangle_motion, item_time=_NO_ITEM, imports=_NO_ITEM),
)
