"""Dynamic verification and routing for the interpreter, from live telemetry.

:func:`pre_check` binds a vehicle profile and a world into the interpreter's ``pre_check``
hook (:class:`tml.engine.Options`): before an action starts, the live position, heading and
battery become the verifier's variables, the action's category constraints are checked
(:func:`tml.verify.constraints.check_before_action`), and each violated constraint comes
back as text. A non-empty answer makes the action fail with ACTION_FAILURE = infeasible,
which event handlers can react to; unhandled, the mission ends in its safe state.

:func:`router` gives the interpreter the planner's collision-free paths, so that a move the
verifier judged around an obstacle is flown around it too.

The live check judges the action as the connected vehicle's kind (:mod:`tml.language.kinds`): when
the vehicle is of another kind than the profile (a fixed-wing flown with the default
quadcopter profile), the shipped profile of its kind is used, so that a plane is never
asked to hover and a rover never to take off. :func:`preflight` does the same for the
whole mission before the first task: every action a connected vehicle will fly is checked
against what that vehicle can do (:func:`tml.language.kinds.refusal`), so that a mission it cannot
fly is refused before it leaves the ground.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from functools import cache

from tml.geo import Point
from tml.language import actions
from tml.language.actions import BoundAction
from tml.language.kinds import kind_of, refusal, role_kinds
from tml.language.model import Mission
from tml.vehicle import VehicleState
from tml.verify.constraints import Constraint, Violation, check_before_action
from tml.verify.motion import PredictedState
from tml.verify.planner import Planner
from tml.verify.profile import SHIPPED_FOR_KIND, VehicleProfile, load_profile
from tml.world import World

PreCheck = Callable[[BoundAction, VehicleState, dict[str, Point], float], list[str]]
Route = Callable[[Point, Point], list[Point] | None]


def live_variables(state: VehicleState, mission_time: float) -> PredictedState | None:
    """The verifier's variables from a live state; None while position or battery is unknown."""
    if state.position is None or state.battery is None:
        return None
    return PredictedState(position=state.position, battery=state.battery, time=mission_time,
                          heading=state.heading, flying=state.flying)


@cache
def _shipped(name: str) -> VehicleProfile:
    return load_profile(name)


def profile_for(profile: VehicleProfile, vehicle_type: str) -> VehicleProfile:
    """``profile``, or the shipped profile of the vehicle's kind when ``vehicle_type`` (as
    the vehicle reports it; "" while unknown) is of another kind."""
    kind = kind_of(vehicle_type)
    if not vehicle_type or kind is profile.kind:
        return profile
    return _shipped(SHIPPED_FOR_KIND[kind])


def cruise(profile: VehicleProfile) -> Callable[[str], tuple[float, float]]:
    """The interpreter's hook (:class:`tml.engine.Limits`): how a vehicle of a type moves
    until SET_SPEED, as its profile (:func:`profile_for`) says: its cruise speed (m/s) and
    acceleration (m/s²). Its time limits are set on them."""

    def of(vehicle_type: str) -> tuple[float, float]:
        mine = profile_for(profile, vehicle_type)
        return mine.cruise_speed, mine.acceleration

    return of


def pre_check(profile: VehicleProfile, world: World | None = None) -> PreCheck:
    """The interpreter's hook: the constraints an action would break if started now."""

    def check(bound: BoundAction, state: VehicleState, labels: dict[str, Point],
              mission_time: float) -> list[str]:
        cannot = refusal(bound, kind_of(state.vehicle_type), state.vehicle_type)
        if state.vehicle_type and cannot is not None:
            return [f"{Constraint.VEHICLE.value}: {bound.name}: {cannot}"]
        variables = live_variables(state, mission_time)
        if variables is None:
            return []  # nothing to judge yet: the action's own checks wait for a position
        mine = profile_for(profile, state.vehicle_type)
        return [str(v) for v in check_before_action(bound, variables, mine, world, labels)]

    return check


def preflight(mission: Mission, vehicle_types: Mapping[int, str]) -> list[Violation]:
    """What the connected vehicles cannot do of ``mission``, before it starts.

    ``vehicle_types`` maps each vehicle's id to its type. Without roles every vehicle flies
    every action; with roles, each role's actions are held against the vehicles its type
    admits (a role no connected vehicle can fly is left to its pick, which names why).
    Each violation names the vehicle in ``vehicles`` and the role, if any.
    """
    found: list[Violation] = []
    flown = [(t.action, t.role) for t in mission.walk() if t.action is not None]
    flown += [(a, e.role) for e in mission.events for a in e.actions]
    roles = {role.name: role for role in mission.roles}
    for vehicle_id, vehicle_type in sorted(vehicle_types.items()):
        if not vehicle_type:
            continue
        kind = kind_of(vehicle_type)
        for action, role in flown:
            assert action is not None
            if role in roles and kind not in role_kinds(roles[role].vehicle_type):
                continue  # this vehicle is never picked for that role
            bound = actions.bind(action)
            cannot = refusal(bound, kind, vehicle_type)
            if cannot is not None:
                found.append(Violation(Constraint.VEHICLE, cannot, math.nan, "", math.nan, "",
                                       bound.name, action.location, role=role or "",
                                       vehicles=(vehicle_id,)))
    return found


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
