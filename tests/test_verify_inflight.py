"""Dynamic verification before each action (tml.verify.inflight)."""

from __future__ import annotations

import math
from dataclasses import replace

from fake_vehicle import FakeVehicle

from tml.engine import Interpreter, Options, Status
from tml.language.actions import bind
from tml.language.validation import validate_file
from tml.vehicle import GoTo, VehicleState
from tml.verify.inflight import live_variables, pre_check, preflight
from tml.verify.profile import load_profile
from tml.world import Cylinder, World

MISSION = ('<mission name="m"><task name="up"><action name="TAKE_OFF"/></task>'
           '<task name="far"><action name="GO_TO_POINT"><argument name="coordinates" '
           'value="({north}, 0, 10)"/></action></task><task name="down">'
           '<action name="LAND"/></task>{events}</mission>')


def fly(north: float, battery: float, events: str = "", world: World | None = None):
    profile = load_profile("quadcopter")
    text = MISSION.format(north=north, events=events)
    mission = validate_file("m.xml", text.encode()).mission
    vehicle = FakeVehicle(battery=battery, drain_per_second=0.0, speed=10.0)
    interp = Interpreter(mission, [1], Options(pre_check=pre_check(profile, world)))
    out, time = interp.start(0.0, {1: vehicle.state()}), 0.0
    while interp.status is Status.RUNNING and time < 600:
        for request in out.requests:
            vehicle.submit(request)
        vehicle.advance(0.1)
        time += 0.1
        out = interp.step(time, {1: vehicle.state()}, {1: vehicle.poll()})
    return interp, vehicle


def test_feasible_action_flies() -> None:
    interp, vehicle = fly(100, 90.0)
    assert interp.status is Status.COMPLETED
    assert any(isinstance(r, GoTo) for r in vehicle.submitted)


def test_action_beyond_the_live_battery_is_refused_before_it_is_sent() -> None:
    interp, vehicle = fly(3000, 30.0)
    assert interp.status is Status.ABORTED
    assert "infeasible" in interp.reason
    assert not any(isinstance(r, GoTo) for r in vehicle.submitted)


def test_infeasible_action_can_be_handled_by_an_event() -> None:
    events = ('<event_handling><event name="cannot"><condition parameter="ACTION_FAILURE" '
              'comparison="equal" value="infeasible"/><action name="LAND"/>'
              '<termination mode="END_MISSION"/></event></event_handling>')
    interp, vehicle = fly(3000, 30.0, events)
    assert interp.status is Status.COMPLETED
    assert vehicle.position[2] == 0.0


def test_destination_inside_an_obstacle_is_refused() -> None:
    world = World(obstacles=(Cylinder("mast", 100.0, 0.0, 5.0, 0.0, 50.0),))
    interp, _ = fly(100, 90.0, world=world)
    assert interp.status is Status.ABORTED and "c1" in interp.reason


def test_unknown_position_or_battery_is_not_judged() -> None:
    state = VehicleState(1, 0.0)
    assert live_variables(state, 0.0) is None
    known = replace(state, position=(1.0, 2.0, 3.0), battery=50.0, armed=True, landed=False)
    variables = live_variables(known, 12.0)
    assert variables.position == (1.0, 2.0, 3.0) and variables.flying and variables.time == 12.0


def test_router_flies_around_a_known_obstacle() -> None:
    from tml.verify.inflight import router

    interp, vehicle, closest = closest_approach(
        MISSION.format(north=100, events=""), Cylinder("tower", 50.0, 0.0, 5.0, 0.0, 100.0))
    assert interp.status is Status.COMPLETED
    assert closest >= 5.0 + load_profile("quadcopter").min_clearance - 0.6
    assert len([r for r in vehicle.submitted if isinstance(r, GoTo)]) > 1
    assert router(load_profile("quadcopter"), World()) is None


def test_no_path_is_infeasible() -> None:
    from tml.verify.inflight import router

    # A ring of towers 100 m out, each 12 m wide, closer together than the clearance allows.
    walls = tuple(Cylinder(f"c{i}", 100.0 * math.cos(i * 0.2), 100.0 * math.sin(i * 0.2),
                           12.0, 0.0, 1000.0) for i in range(32))
    world = World(obstacles=walls)
    route = router(load_profile("quadcopter"), world)
    assert route((0.0, 0.0, 10.0), (300.0, 0.0, 10.0)) is None


def closest_approach(mission_text: str, obstacle: Cylinder) -> tuple[Interpreter,
                                                                    FakeVehicle, float]:
    """Fly with the router around ``obstacle``; the closest the vehicle came to its axis."""
    from tml.verify.inflight import router

    world = World(obstacles=(obstacle,))
    route = router(load_profile("quadcopter"), world)
    mission = validate_file("m.xml", mission_text.encode()).mission
    interp = Interpreter(mission, [1], Options(route=route))
    vehicle = FakeVehicle(drain_per_second=0.0, speed=10.0)
    out, time, closest = interp.start(0.0, {1: vehicle.state()}), 0.0, math.inf
    while interp.status is Status.RUNNING and time < 900:
        for request in out.requests:
            vehicle.submit(request)
        vehicle.advance(0.1)
        time += 0.1
        north, east, _ = vehicle.position
        closest = min(closest, math.hypot(north - obstacle.north, east - obstacle.east))
        out = interp.step(time, {1: vehicle.state()}, {1: vehicle.poll()})
    return interp, vehicle, closest


def test_loiter_around_an_obstacle_joins_the_circle_instead_of_its_centre() -> None:
    text = ('<mission name="m"><task name="up"><action name="TAKE_OFF"/></task>'
            '<task name="round"><action name="LOITER"><argument name="coordinates" '
            'value="(60, 0, 10)"/><argument name="radius" value="10"/><argument name="turns" '
            'value="1"/></action></task><task name="down"><action name="LAND"/></task>'
            '</mission>')
    interp, _, closest = closest_approach(text, Cylinder("mast", 60.0, 0.0, 2.0, 0.0, 100.0))
    assert interp.status is Status.COMPLETED
    assert closest >= 10.0 - 0.6  # never inside the circle


def test_return_home_and_land_goes_around_obstacles_before_rtl() -> None:
    from tml.vehicle import ReturnToLaunch

    text = ('<mission name="m"><task name="up"><action name="TAKE_OFF"/></task>'
            '<task name="out"><action name="GO_TO_POINT"><argument name="coordinates" '
            'value="(80, 0, 10)"/></action></task><task name="back">'
            '<action name="RETURN_HOME_AND_LAND"/></task></mission>')
    interp, vehicle, closest = closest_approach(
        text, Cylinder("tower", 40.0, 0.0, 5.0, 0.0, 100.0))
    assert interp.status is Status.COMPLETED
    assert closest >= 5.0 + 5.0 - 0.6  # radius plus the profile's clearance, less tolerance
    rtl = [i for i, r in enumerate(vehicle.submitted) if isinstance(r, ReturnToLaunch)]
    assert len(rtl) == 1 and isinstance(vehicle.submitted[rtl[0] - 1], GoTo)


def test_the_live_check_judges_the_vehicle_s_own_kind() -> None:
    # A rover flown with the default quadcopter profile: TAKE_OFF is refused as the rover's.
    check = pre_check(load_profile("quadcopter"))
    take_off = validate_file("m.xml", MISSION.format(north=10, events="").encode()).mission
    bound = bind(take_off.tasks[0].action)
    rover = VehicleState(1, 0.0, position=(0.0, 0.0, 0.0), battery=90.0, vehicle_type="rover")
    (found,) = check(bound, rover, {}, 0.0)
    assert found.startswith("vehicle: TAKE_OFF: a rover cannot take off")
    copter = replace(rover, vehicle_type="quadcopter")
    assert check(bound, copter, {}, 0.0) == []


def test_preflight_names_each_vehicle_that_cannot_fly_an_action() -> None:
    mission = validate_file("m.xml", MISSION.format(north=10, events="").encode()).mission
    found = preflight(mission, {1: "quadcopter", 2: "rover", 3: "fixed-wing"})
    assert {(v.action, v.vehicles) for v in found} == {("TAKE_OFF", (2,)), ("LAND", (2,))}
    assert preflight(mission, {1: "quadcopter", 2: ""}) == []  # unknown type: not judged


def test_preflight_holds_a_role_only_against_the_vehicles_its_type_admits() -> None:
    text = ('<mission name="m"><roles><role name="air" type="UAV"/>'
            '<role name="ground" type="rover"/></roles>'
            '<task name="fly" role="air"><action name="TAKE_OFF"/></task>'
            '<task name="drive" role="ground"><action name="LAND"/></task></mission>')
    mission = validate_file("m.xml", text.encode()).mission
    found = preflight(mission, {1: "quadcopter", 2: "rover"})
    assert [(v.action, v.role, v.vehicles) for v in found] == [("LAND", "ground", (2,))]
