"""Geometry and limits of the action scripts (tml.engine.scripts)."""

from __future__ import annotations

import math

import pytest
from fake_vehicle import FakeVehicle
from test_engine_interpreter import Flight

from tml.engine import Limits, Options, Status
from tml.errors import Location
from tml.vehicle import Circle, Disarm, GoTo, Land, ReturnToLaunch

HERE = Location("m.xml", 1, 1)
TAKE_OFF_30 = '<task name="Up"><action name="TAKE_OFF"><argument name="altitude" ' \
              'value="30"/></action></task>'


# --- each kind of vehicle, flown on the FakeVehicle ------------------------------------------

def _plane(**kw: object) -> FakeVehicle:
    return FakeVehicle(vehicle_type="fixed-wing", speed=20.0, climb_rate=5.0, **kw)  # type: ignore[arg-type]


def _rover(**kw: object) -> FakeVehicle:
    return FakeVehicle(vehicle_type="rover", **kw)  # type: ignore[arg-type]


def _kinds_of(flight: Flight) -> list[str]:
    return [type(r).__name__ for r in flight.requests]


def test_a_fixed_wing_takes_off_with_one_request_that_arms_it() -> None:
    flight = Flight(TAKE_OFF_30, vehicle=_plane()).run(120)
    assert flight.interp.status is Status.COMPLETED
    assert _kinds_of(flight)[0] == "TakeOff"  # no GUIDED, no separate Arm
    assert flight.vehicle.armed and flight.vehicle.position[2] >= 25


def test_a_fixed_wing_circles_natively_and_counts_its_turns() -> None:
    body = TAKE_OFF_30 + ('<task name="Circle"><action name="LOITER"><argument name="radius" '
                          'value="60"/><argument name="turns" value="2"/></action></task>')
    flight = Flight(body, vehicle=_plane()).run(300)
    assert flight.interp.status is Status.COMPLETED
    circles = [r for r in flight.requests if isinstance(r, Circle)]
    assert len(circles) == 1 and circles[0].radius == 60
    # Two turns of a 60 m circle at 20 m/s: about 38 s once on the circle.
    started, done = (r.time for r in flight.records if r.kind == "action"
                     and r.data.get("action") == "LOITER"
                     and r.data["message"].split()[-1] in ("started", "done"))
    assert done - started >= 2 * 2 * math.pi * 60 / 20


@pytest.mark.parametrize(("action", "touchdown"), [("LAND", None),
                                                   ("RETURN_HOME_AND_LAND", (0, 0, 0))])
def test_a_fixed_wing_lands_with_one_landing_request(action: str, touchdown) -> None:
    body = TAKE_OFF_30 + f'<task name="Down"><action name="{action}"/></task>'
    flight = Flight(body, vehicle=_plane()).run(300)
    assert flight.interp.status is Status.COMPLETED
    (land,) = [r for r in flight.requests if isinstance(r, Land)]
    assert land.touchdown == touchdown
    assert not [r for r in flight.requests if isinstance(r, ReturnToLaunch)]
    assert not flight.vehicle.armed


def test_a_fixed_wing_cannot_stop_its_stabilize_is_a_hold_without_waiting() -> None:
    body = TAKE_OFF_30 + '<task name="Hold"><action name="STABILIZE"/></task>'
    flight = Flight(body, vehicle=_plane()).run(120)
    assert flight.interp.status is Status.COMPLETED
    # Hold, done at once; then the end of the mission sends the flying plane home (RTL).
    assert _kinds_of(flight)[-2:] == ["Hold", "ReturnToLaunch"]
    assert any("cannot stop" in r.data["message"] for r in flight.records)


@pytest.mark.parametrize(("vehicle", "action", "why"), [
    (_plane, '<action name="ROTATE_YAW"><argument name="angle" value="90"/></action>',
     "a fixed-wing cannot turn in place"),
    (_rover, '<action name="TAKE_OFF"/>', "a rover cannot take off"),
    (_rover, '<action name="LAND"/>', "a rover cannot land"),
    (_rover, '<action name="MOVE"><argument name="direction" value="up"/>'
             '<argument name="distance" value="3"/></action>', "a rover cannot move up"),
])
def test_what_a_kind_cannot_do_fails_infeasible_before_anything_is_sent(
        vehicle, action: str, why: str) -> None:
    flight = Flight(f'<task name="T">{action}</task>', vehicle=vehicle()).run(30)
    assert flight.interp.status is Status.ABORTED
    assert "infeasible" in flight.interp.reason and why in flight.interp.reason
    assert flight.requests == []


def test_a_rover_arms_itself_for_its_first_move_and_drives_at_ground_level() -> None:
    body = '<task name="Out"><action name="GO_TO_POINT"><argument name="coordinates" ' \
           'value="(20, 5, 7)"/></action></task>'
    flight = Flight(body, vehicle=_rover(), options=Options(safe_state="hold")).run(60)
    assert flight.interp.status is Status.COMPLETED
    assert _kinds_of(flight)[:3] == ["SetMode", "Arm", "GoTo"]
    goto = next(r for r in flight.requests if isinstance(r, GoTo))
    assert goto.target == (20.0, 5.0, 0.0)
    # At the end a ground vehicle is stopped by disarming it, whatever the safe state.
    assert isinstance(flight.requests[-1], Disarm) and not flight.vehicle.armed


def test_a_rover_returns_home_stops_and_disarms() -> None:
    body = '<task name="Out"><action name="GO_TO_POINT"><argument name="coordinates" ' \
           'value="(20, 0, 0)"/></action></task><task name="Back">' \
           '<action name="RETURN_HOME_AND_LAND"/></task>'
    flight = Flight(body, vehicle=_rover()).run(120)
    assert flight.interp.status is Status.COMPLETED
    assert _kinds_of(flight)[-2:] == ["ReturnToLaunch", "Disarm"]
    assert math.dist(flight.vehicle.position, (0, 0, 0)) < 3.0


# --- time limits at the speed in force ----------------------------------------------------

GO_FAR = ('<task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/>'
          '</action></task><task name="Far"><action name="GO_TO_POINT"><argument '
          'name="coordinates" value="(100, 0, 10)"/></action></task>')


def _cruising(speed: float, acceleration: float = 0.0) -> Options:
    return Options(limits=Limits(cruise=lambda vehicle_type: (speed, acceleration)))


def _said(flight: Flight) -> str:
    return " ".join(str(r.data.get("message", "")) for r in flight.records)


def test_a_move_s_time_limit_is_twice_its_time_at_the_cruise_speed_plus_15_s() -> None:
    # 100 m at 2 m/s take 50 s; at a cruise speed of 10 m/s the limit is 2 x 10 + 15 = 35 s.
    fast = Flight(GO_FAR, vehicle=FakeVehicle(speed=2.0), options=_cruising(10.0)).run(300)
    assert fast.interp.status is not Status.COMPLETED
    assert "within 35 s" in _said(fast)
    # At a cruise speed of 2 m/s: 2 x 50 + 15 = 115 s, time enough.
    slow = Flight(GO_FAR, vehicle=FakeVehicle(speed=2.0), options=_cruising(2.0)).run(300)
    assert slow.interp.status is Status.COMPLETED
    # Speeding up and braking at 0.5 m/s², a 100 m leg never reaches 10 m/s (that takes
    # 200 m): 2 x sqrt(100 / 0.5) = 28.3 s, so the limit is 2 x 28.3 + 15 = 72 s, enough.
    braking = Flight(GO_FAR, vehicle=FakeVehicle(speed=2.0), options=_cruising(10.0, 0.5))
    assert braking.run(300).interp.status is Status.COMPLETED
    assert "within" not in _said(braking)


def test_set_speed_puts_its_speed_in_force_for_the_time_limit() -> None:
    slowly = GO_FAR.replace('<task name="Far">', '<task name="Slowly"><action name="SET_SPEED">'
                            '<argument name="speed" value="2"/></action></task>'
                            '<task name="Far">')
    flight = Flight(slowly, vehicle=FakeVehicle(speed=10.0), options=_cruising(10.0)).run(300)
    assert flight.interp.status is Status.COMPLETED, _said(flight)
    assert flight.vehicle.speed == 2.0
