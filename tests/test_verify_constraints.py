"""Each constraint, table-driven: cases that hold and cases that fail, with the numbers on
both sides; the grouping by action category; the dynamic API."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import pytest

from tml.errors import Location
from tml.language.actions import BoundAction, bind
from tml.language.model import Action, Argument
from tml.verify.constraints import (
    BY_CATEGORY,
    Constraint,
    assess_action,
    check_before_action,
    check_step,
)
from tml.verify.motion import FlightModel, PredictedState
from tml.verify.profile import load_profile
from tml.world import Cylinder, Geofence, Prism, World

# Round numbers: 5 m/s cruise, 10 m/s max, 0.1 %/m, 0.1 %/s, reserve 20 %, clearance 5 m;
# moves start and stop at once, landings at the descent rate, no wait over home.
PROFILE = replace(load_profile("quadcopter"), cruise_speed=5.0, max_speed=10.0,
                  climb_rate=2.0, descent_rate=1.0, battery_per_metre=0.1,
                  battery_per_second=0.1, battery_reserve=20.0, min_clearance=5.0,
                  min_altitude=0.0, max_altitude=100.0, max_range=500.0,
                  return_altitude=10.0, min_turn_radius=0.0, max_flight_time=0.0,
                  acceleration=0.0, land_speed=0.0, land_altitude=0.0, return_hover=0.0)
ROVER = replace(load_profile("rover"), max_range=500.0)
FIXED_WING = load_profile("fixed-wing")
NAN = math.nan
HERE = Location("mission.xml", 42)
AT_10 = PredictedState(position=(0.0, 0.0, 10.0), flying=True)
MAST = World(obstacles=(Cylinder("mast", 0.0, 20.0, 2.0),))
FENCE = World(geofence=Geofence(((-100.0, -100.0), (100.0, -100.0), (100.0, 100.0),
                                 (-100.0, 100.0)), max_altitude=50.0))
WALLS = World(obstacles=(
    Prism("n", ((120, -20), (122, -20), (122, 22), (120, 22)), top=20),
    Prism("s", ((80, -22), (82, -22), (82, 20), (80, 20)), top=20),
    Prism("e", ((80, 20), (122, 20), (122, 22), (80, 22)), top=20),
    Prism("w", ((80, -22), (122, -22), (122, -20), (80, -20)), top=20)))


def action(name: str, labels: dict[str, str] | None = None, **values: str) -> BoundAction:
    arguments = [Argument(k, v, None, HERE) for k, v in values.items()]
    arguments += [Argument(k, None, v, HERE) for k, v in (labels or {}).items()]
    return bind(Action(name, tuple(arguments), HERE))


def go(north: float, east: float, up: float) -> BoundAction:
    return action("GO_TO_POINT", coordinates=f"({north}, {east}, {up})")


@dataclass
class Case:
    name: str
    bound: BoundAction
    state: PredictedState = AT_10
    world: World | None = None
    profile: object = PROFILE
    labels: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    deadline: float | None = None
    fails: tuple[float, float] | None = None  # (value, limit) when the constraint fails


CASES: dict[Constraint, list[Case]] = {
    Constraint.C1: [
        Case("8 m from the mast", go(0, 10, 10), world=MAST),
        Case("3 m from the mast", go(0, 15, 10), world=MAST, fails=(3.0, 5.0)),
        Case("over the mast's top", go(0, 15, 30),
             world=World(obstacles=(Cylinder("mast", 0.0, 20.0, 2.0, top=20.0),))),
        Case("loiter circle grazes the mast", action(
            "LOITER", coordinates="(0, 0, 10)", radius="16", turns="1"), world=MAST,
             fails=(2.0, 5.0)),
    ],
    Constraint.C2: [
        Case("200 m on 30 %", go(200, 0, 10), state=replace(AT_10, battery=30.0)),
        Case("400 m on 30 %", go(400, 0, 10), state=replace(AT_10, battery=30.0),
             fails=(400.0, 300.0)),
        Case("hover 100 s on 5 %", action("WAIT", duration="100"),
             state=replace(AT_10, battery=5.0), fails=(10.0, 5.0)),
        Case("home on 12 %, below the reserve", action("RETURN_HOME_AND_LAND"),
             state=replace(AT_10, position=(100.0, 0.0, 10.0), battery=12.0)),
    ],
    Constraint.C3: [
        Case("8 m/s asked", action("SET_SPEED", speed="8")),
        Case("12 m/s asked", action("SET_SPEED", speed="12"), fails=(12.0, 10.0)),
        Case("climb 3 m/s asked", action("SET_SPEED", speed="3", speed_type="climb"),
             fails=(3.0, 2.0)),
        Case("100 m in 20 s", go(100, 0, 10), deadline=20.0),
        Case("100 m in 5 s", go(100, 0, 10), deadline=5.0, fails=(20.0, 10.0)),
    ],
    Constraint.PATH: [
        Case("over the courtyard walls", go(100, 0, 30), world=WALLS,
             state=replace(AT_10, position=(0.0, 0.0, 30.0))),
        # Climbing from 10 m, the leg is judged at every altitude it passes: blocked.
        Case("climbing over the walls", go(100, 0, 30), world=WALLS, fails=(0.0, 5.0)),
        Case("into the walled courtyard", go(100, 0, 10), world=WALLS, fails=(0.0, 5.0)),
    ],
    Constraint.GEOFENCE: [
        Case("inside", go(50, 0, 10), world=FENCE),
        Case("30 m out", go(130, 0, 10), world=FENCE, fails=(30.0, 0.0)),
        Case("loiter circle 10 m out", action(
            "LOITER", coordinates="(80, 0, 10)", radius="30", turns="1"), world=FENCE,
             fails=(10.0, 0.0)),
    ],
    Constraint.ALTITUDE: [
        Case("at 90 m", go(0, 0, 90)),
        Case("at 120 m", go(0, 0, 120), fails=(120.0, 100.0)),
        Case("at 60 m under a 50 m fence", go(0, 0, 60), world=FENCE, fails=(60.0, 50.0)),
        Case("cruise at 10 m, floor 20 m", go(50, 0, 10),
             profile=replace(PROFILE, min_altitude=20.0), fails=(10.0, 20.0)),
    ],
    Constraint.RANGE: [
        Case("400 m out", go(400, 0, 10)),
        Case("600 m out", go(600, 0, 10), fails=(600.0, 500.0)),
    ],
    Constraint.RETURN_RESERVE: [
        # 50 m out costs 5 %, coming back 50 m plus 10 m down costs 6 %: 40-5-6 = 29.
        Case("50 m out on 40 %", go(50, 0, 10), state=replace(AT_10, battery=40.0)),
        # 100 m out costs 10 %, coming back 11 %: 40-10-11 = 19.
        Case("100 m out on 40 %", go(100, 0, 10), state=replace(AT_10, battery=40.0),
             fails=(19.0, 20.0)),
        # Going home is what the reserve is for: not held to it.
        Case("home on 25 %", action("RETURN_HOME_AND_LAND"),
             state=replace(AT_10, position=(100.0, 0.0, 10.0), battery=25.0)),
    ],
    Constraint.TIME: [
        Case("wait 30 s at 60 s", action("WAIT", duration="30"), state=replace(AT_10, time=60.0),
             profile=replace(PROFILE, max_flight_time=100.0)),
        Case("wait 50 s at 60 s", action("WAIT", duration="50"), state=replace(AT_10, time=60.0),
             profile=replace(PROFILE, max_flight_time=100.0), fails=(110.0, 100.0)),
    ],
    Constraint.AIRBORNE: [
        Case("flying", go(10, 0, 10)),
        Case("on the ground", go(10, 0, 10), state=PredictedState(), fails=(0.0, 0.0)),
        # A NAV_DELAY after a landing: the vehicle waits where it stands.
        Case("wait on the ground", action("WAIT", duration="5"), state=PredictedState()),
        Case("turn on the ground", action("ROTATE_YAW", angle="90"), state=PredictedState(),
             fails=(0.0, 0.0)),
    ],
    Constraint.TURN_RADIUS: [
        Case("50 m circle", action("LOITER", radius="50", turns="1"),
             profile=replace(PROFILE, min_turn_radius=40.0, max_range=5000.0)),
        Case("30 m circle", action("LOITER", radius="30", turns="1"),
             profile=replace(PROFILE, min_turn_radius=40.0), fails=(30.0, 40.0)),
    ],
    Constraint.LABEL: [
        Case("memorized", action("GO_TO_POINT", labels={"coordinates": "spot"}),
             labels={"spot": (10.0, 0.0, 10.0)}),
        Case("never memorized", action("GO_TO_POINT", labels={"coordinates": "spot"}),
             fails=(0.0, 1.0)),
    ],
    # No numbers: the vehicle cannot do the action at all (value and limit are nan).
    Constraint.VEHICLE: [
        Case("quadcopter takes off", action("TAKE_OFF"), state=PredictedState()),
        Case("rover takes off", action("TAKE_OFF"), state=PredictedState(), profile=ROVER,
             fails=(NAN, NAN)),
        Case("rover drives to a point", go(10, 0, 0), state=PredictedState(), profile=ROVER),
        Case("rover moves up", action("MOVE", direction="up", distance="3"),
             profile=ROVER, fails=(NAN, NAN)),
        Case("fixed-wing turns in place", action("ROTATE_YAW", angle="90"),
             profile=FIXED_WING, fails=(NAN, NAN)),
    ],
}


@pytest.mark.parametrize(("constraint", "case"), [
    (constraint, case) for constraint, cases in CASES.items() for case in cases],
    ids=lambda x: x.name if isinstance(x, Case) else x.value)
def test_constraint(constraint: Constraint, case: Case) -> None:
    found = check_before_action(case.bound, case.state, case.profile, case.world, case.labels,
                                case.deadline)
    mine = [v for v in found if v.constraint is constraint]
    if case.fails is None:
        assert mine == []
        return
    assert len(mine) == 1, found
    violation = mine[0]
    assert (violation.value, violation.limit) == pytest.approx(case.fails, abs=0.05,
                                                               nan_ok=True)
    assert violation.location == HERE
    assert violation.action == case.bound.name
    assert str(violation).startswith(f"mission.xml:42: {constraint.value}: {case.bound.name}: ")


def test_every_constraint_has_cases_that_hold_and_fail() -> None:
    for constraint in Constraint:
        if constraint is Constraint.TERRAIN:
            continue  # judged over terrain data, apart: tests/test_verify_terrain.py
        cases = CASES[constraint]
        assert any(c.fails is None for c in cases), constraint
        assert any(c.fails is not None for c in cases), constraint


def test_actions_are_checked_only_against_their_category() -> None:
    outside = PredictedState(position=(300.0, 0.0, 80.0), flying=True, battery=21.0)
    photo = action("CAPTURE_PHOTO")
    assert Constraint.GEOFENCE not in BY_CATEGORY[photo.spec.category]
    assert check_before_action(photo, outside, PROFILE, FENCE) == []
    # The same place fails the fence for a move.
    moved = check_before_action(go(300, 10, 80), outside, PROFILE, FENCE)
    assert Constraint.GEOFENCE in {v.constraint for v in moved}


def test_take_off_from_the_ground_is_not_an_airborne_violation() -> None:
    assert check_before_action(action("TAKE_OFF"), PredictedState(), PROFILE) == []


def test_a_vehicle_violation_says_what_the_vehicle_cannot_do() -> None:
    violation, = check_before_action(action("TAKE_OFF"), PredictedState(), ROVER)
    assert str(violation) == ("mission.xml:42: vehicle: TAKE_OFF: a rover cannot take off "
                              "(it stays on the ground and arms itself for its first move)")
    assert violation.to_dict()["value"] is None and violation.to_dict()["relation"] is None


def test_a_ground_vehicle_needs_no_take_off_to_move() -> None:
    # Its first move arms it: not an airborne violation, and it drives at 0 m.
    assessment = assess_action(go(30, 0, 10), PredictedState(), ROVER)
    assert assessment.feasible
    assert assessment.step.after.position == (30.0, 0.0, 0.0)
    assert assessment.step.after.flying


def test_assessment_carries_the_prediction() -> None:
    assessment = assess_action(go(100, 0, 10), AT_10, PROFILE)
    assert assessment.feasible
    assert assessment.step.after.position == (100.0, 0.0, 10.0)
    assert assessment.step.after.battery == pytest.approx(90.0)


def test_a_constraint_not_asked_for_is_not_judged_nor_its_ways_home_planned() -> None:
    # 100 m out on 40 % breaks the reserve; unasked, the reserve is neither reported nor its
    # way home planned (the planner keeps every leg it was asked for, straight or not).
    bound, state = go(100, 0, 10), replace(AT_10, position=(0.0, 40.0, 10.0), battery=40.0)
    asked, unasked = FlightModel(PROFILE, MAST), FlightModel(PROFILE, MAST)
    step = asked.step(bound, state)
    assert Constraint.RETURN_RESERVE in {v.constraint for v in check_step(bound, step, asked)}
    legs = set(asked.planner._cache)
    found = check_step(bound, unasked.step(bound, state), unasked,
                       unasked=frozenset({Constraint.RETURN_RESERVE}))
    assert Constraint.RETURN_RESERVE not in {v.constraint for v in found}
    assert set(unasked.planner._cache) < legs


def test_violation_json_has_both_sides() -> None:
    violation = check_before_action(go(0, 15, 10), AT_10, PROFILE, MAST)[0]
    data = violation.to_dict()
    assert data["constraint"] == "c1"
    assert (data["file"], data["line"]) == ("mission.xml", 42)
    assert data["value"] == pytest.approx(3.0)
    assert (data["relation"], data["limit"], data["unit"]) == (">=", 5.0, "m")
