"""Dynamic verification and routing for the interpreter, from live telemetry.

:func:`pre_check` binds a vehicle profile and a world into the interpreter's ``pre_check``
hook (:class:`tml.engine.Options`): before an action starts, the live position, heading and
battery become the verifier's variables, the action's category constraints are checked
(:func:`tml.verify.constraints.check_before_action`), and each violated constraint comes
back as text. A non-empty answer makes the action fail with ACTION_FAILURE = infeasible,
which event handlers can react to; unhandled, the mission ends in its safe state.

:func:`router` gives the interpreter the planner's collision-free paths, so that a move the
verifier judged around an obstacle is flown around it too.
"""

from __future__ import annotations

from collections.abc import Callable

from tml.actions import BoundAction
from tml.vehicle import Point
from tml.vehicle import VehicleState as LiveState
from tml.verify.constraints import check_before_action
from tml.verify.motion import VehicleState
from tml.verify.planner import Planner
from tml.verify.profile import VehicleProfile
from tml.world import World

PreCheck = Callable[[BoundAction, LiveState, dict[str, Point], float], list[str]]
Route = Callable[[Point, Point], list[Point] | None]


def live_variables(state: LiveState, mission_time: float) -> VehicleState | None:
    """The verifier's variables from a live state; None while position or battery is unknown."""
    if state.position is None or state.battery is None:
        return None
    return VehicleState(position=state.position, battery=state.battery, time=mission_time,
                        heading=state.heading, flying=state.flying)


def pre_check(profile: VehicleProfile, world: World | None = None) -> PreCheck:
    """The interpreter's hook: the constraints an action would break if started now."""

    def check(bound: BoundAction, state: LiveState, labels: dict[str, Point],
              mission_time: float) -> list[str]:
        variables = live_variables(state, mission_time)
        if variables is None:
            return []  # nothing to judge yet: the action's own checks wait for a position
        return [str(v) for v in check_before_action(bound, variables, profile, world, labels)]

    return check


def router(profile: VehicleProfile, world: World | None) -> Route | None:
    """The interpreter's router: the verifier's collision-free paths around the world's
    obstacles with the profile's clearance (None when the world has no obstacles)."""
    if world is None or not world.obstacles:
        return None
    planner = Planner(world.obstacles, profile.min_clearance)

    def route(start: Point, end: Point) -> list[Point] | None:
        trajectory = planner.trajectory(start, end)
        return None if trajectory is None else list(trajectory.points)

    return route
