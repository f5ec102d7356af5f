"""Settings and memory: SET_SPEED, SET_HOME and MEMORIZE_POINT."""

from __future__ import annotations

from dataclasses import replace

from tml.actions import guided, items, mav, reading, timing
from tml.actions.definition import ActionDef, NotApplicable, spec
from tml.actions.guided import Context, Script, Send
from tml.actions.motion import Labels, Motion, PredictedState, Step
from tml.language.actions import BoundAction
from tml.vehicle import SetHome, SetSpeed


def set_speed(ctx: Context, bound: BoundAction) -> Script:
    """Change the speed of the following moves."""
    speed = bound.number("speed")
    kind = bound.choice("speed_type")
    yield Send(SetSpeed(ctx.vehicle_id, speed, kind, bound.number("throttle", -1.0)))
    if kind in ("airspeed", "ground"):
        ctx.limits.speed = speed
    elif kind == "climb":
        ctx.limits.climb_rate = speed
    else:
        ctx.limits.descent_rate = speed


def set_home(ctx: Context, bound: BoundAction) -> Script:
    """Home at the current position, or at a WGS84 position."""
    position = None
    if "latitude" in bound.values:
        position = (bound.number("latitude"), bound.number("longitude"),
                    bound.number("altitude"))
    yield Send(SetHome(ctx.vehicle_id, position))


def memorize_point(ctx: Context, bound: BoundAction) -> Script:
    """Store the current position under a label."""
    label = bound.labels["coordinates"]
    ctx.labels[label] = guided.current_position(ctx)
    ctx.note(f"memorized {label!r}", label=label, point=list(ctx.labels[label]))
    yield from ()


# --- mission items (dispatch="mission") ----------------------------------------

def set_speed_items(b: items.Builder, action: BoundAction) -> None:
    kind = items.SPEED_TYPES[action.choice("speed_type")]
    b.add(mav.DO_CHANGE_SPEED, params=(kind, action.number("speed"),
                                       action.number("throttle", -1.0), 0.0))


def set_home_items(b: items.Builder, action: BoundAction) -> None:
    if "latitude" not in action.values:
        b.add(mav.DO_SET_HOME, params=(1.0, 0.0, 0.0, 0.0))
        return
    b.add(mav.DO_SET_HOME, frame=mav.FRAME_GLOBAL_INT,
          raw=(round(action.number("latitude") * 1e7),
               round(action.number("longitude") * 1e7), action.number("altitude")))


# --- motion models (tml verify) -------------------------------------------------------------

def memorize_point_motion(model: Motion, bound: BoundAction, state: PredictedState,
                          labels: Labels) -> Step:
    label = bound.labels.get("coordinates")
    if label:
        labels[label] = state.position
    return Step(state, state, labels=labels)


def set_speed_motion(model: Motion, bound: BoundAction, state: PredictedState,
                     labels: Labels) -> Step:
    kind, value = bound.choice("speed_type"), bound.number("speed")
    if kind == "climb":
        after = replace(state, climb_rate=min(value, model.profile.climb_rate))
    elif kind == "descent":
        after = replace(state, descent_rate=min(value, model.profile.descent_rate))
    else:
        after = replace(state, speed=value)
    return Step(state, after, labels=labels, requested_speed=(kind, value))


def set_home_motion(model: Motion, bound: BoundAction, state: PredictedState,
                    labels: Labels) -> Step:
    if "latitude" not in bound.values:
        home = state.position
    else:
        home = model.local(bound.number("latitude"), bound.number("longitude"),
                           bound.number("altitude"), "amsl")
    return Step(state, replace(state, home=home), labels=labels)


# --- reading mission items back (tml import) ------------------------------------------------

def set_speed_read(item: reading.ItemFields) -> reading.Arguments:
    """DO_CHANGE_SPEED: the speed and which one, the throttle when it changes it, and the
    frame a file wrote."""
    kinds = {number: name for name, number in items.SPEED_TYPES.items()}
    arguments = {"speed": reading.value(item.param2),
                 "speed_type": kinds.get(int(item.param1), "airspeed")}
    if item.param3 != -1:
        arguments["throttle"] = reading.value(item.param3)
    return reading.frame(arguments, item)


def set_home_read(item: reading.ItemFields) -> reading.Arguments:
    """DO_SET_HOME: here, or a position."""
    if item.param1 == 1 or not (item.x or item.y):
        return {}
    return reading.encoding({"latitude": reading.value(item.x / 1e7),
                             "longitude": reading.value(item.y / 1e7),
                             "altitude": reading.value(item.z)}, item)


_NO_ITEM = NotApplicable("remembers a position in tml, which no mission item "
                         "can do")
"""Why MEMORIZE_POINT has no mission item (nor an item time)."""


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("SET_SPEED"), guided=set_speed, items=set_speed_items, motion=set_speed_motion,
              item_time=timing.nominal,
              imports=reading.Reading({mav.DO_CHANGE_SPEED: set_speed_read})),
    ActionDef(spec("SET_HOME"), guided=set_home, items=set_home_items, motion=set_home_motion,
              item_time=timing.nominal, imports=reading.Reading({mav.DO_SET_HOME: set_home_read})),
    ActionDef(spec("MEMORIZE_POINT"), guided=memorize_point, items=_NO_ITEM,
              motion=memorize_point_motion, item_time=_NO_ITEM, imports=_NO_ITEM),
)
