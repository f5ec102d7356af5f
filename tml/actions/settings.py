"""Settings and memory: SET_SPEED, SET_HOME and MEMORIZE_POINT."""

from __future__ import annotations

from tml.actions import guided
from tml.actions.definition import ActionDef, spec
from tml.actions.guided import Context, Script, Send
from tml.language.actions import BoundAction
from tml.vehicle import SetHome, SetSpeed


def set_speed(ctx: Context, bound: BoundAction) -> Script:
    """Change the speed of the following moves."""
    speed = bound.number("speed")
    kind = bound.choice("speed_type")
    yield Send(SetSpeed(ctx.vehicle_id, speed, kind))
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


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("SET_SPEED"), guided=set_speed),
    ActionDef(spec("SET_HOME"), guided=set_home),
    ActionDef(spec("MEMORIZE_POINT"), guided=memorize_point),
)
