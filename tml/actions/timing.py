"""The time toolkit: how long an action flown as mission items (``dispatch="mission"``) is
expected to take, for the interpreter's watch on each item (:func:`tml.engine.leaves.item_limit`).

An item time (the ``item_time`` part of an :class:`~tml.actions.definition.ActionDef`) gives
the nominal seconds of one action from where the vehicle is, at the speeds the
:class:`~tml.actions.guided.Limits` hold: 0 when the action gives no time of its own (the
interpreter then allows its stall time), infinite for an action that lasts until an event
ends it. The interpreter doubles it and adds slack.
"""

from __future__ import annotations

import math

from tml.actions.guided import Limits
from tml.geo import Point
from tml.language.actions import BoundAction


def _number(bound: BoundAction, name: str) -> float | None:
    """A number argument of the action, None when it has no such argument or it is
    absent."""
    return bound.number(name, None) if bound.takes(name) else None


def target(bound: BoundAction) -> Point | None:
    """The point the action's ``coordinates`` give, if it takes them and they are given."""
    return bound.point("coordinates", None) if bound.takes("coordinates") else None


def nominal(limits: Limits, vehicle_type: str, here: Point, bound: BoundAction) -> float:
    """What any action's arguments say: its ``duration``, its ``turns`` of its ``radius``,
    the leg to its ``coordinates``."""
    turns, duration = _number(bound, "turns"), _number(bound, "duration")
    seconds = duration or 0.0
    if turns is not None:
        seconds += 2 * math.pi * (_number(bound, "radius") or 0.0) * turns \
            / limits.move_speed(vehicle_type)
    point = target(bound)
    if point is not None:
        seconds += limits.leg_seconds(vehicle_type, math.dist(here, point))
    return seconds


def until_stopped(limits: Limits, vehicle_type: str, here: Point, bound: BoundAction) -> float:
    """A circle: endless without ``turns`` or a ``duration`` (an event ends it)."""
    if _number(bound, "turns") is None and _number(bound, "duration") is None:
        return math.inf
    return nominal(limits, vehicle_type, here, bound)


def landing(limits: Limits, vehicle_type: str, here: Point, over: Point) -> float:
    """Over the landing point ``over``, then down at LAND_SPEED."""
    return limits.leg_seconds(vehicle_type, math.hypot(here[0] - over[0], here[1] - over[1])) \
        + max(here[2], 15.0) / limits.land_rate
