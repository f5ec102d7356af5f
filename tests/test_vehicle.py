"""The vehicle interface's fake vehicle (tml.vehicle)."""

from __future__ import annotations

import dataclasses

import pytest
from fake_vehicle import FakeVehicle

from tml.language.failures import FailureReason
from tml.language.kinds import VEHICLE_TYPE_CLASSES, VEHICLE_TYPES, vehicle_type_matches
from tml.vehicle import (
    Arm,
    AutopilotMessage,
    GoTo,
    IdSource,
    Land,
    RequestResult,
    SetMode,
    TakeOff,
    VehicleState,
    awaiting,
    shown_severity,
)
from tml.world import DEFAULT_HOME


def test_fake_vehicle_flies_and_answers_requests() -> None:
    vehicle = FakeVehicle(speed=10.0)
    for request in (SetMode(1, "GUIDED"), Arm(1), TakeOff(1, 10.0)):
        vehicle.submit(request)
    assert [r.ok for r in vehicle.poll()] == [True, True, True]
    assert vehicle.poll() == []
    for _ in range(50):
        vehicle.advance(0.1)
    assert vehicle.state().altitude == pytest.approx(10.0)
    assert vehicle.state().flying
    vehicle.submit(GoTo(1, (30.0, 40.0, 10.0)))
    for _ in range(60):
        vehicle.advance(0.1)
    assert vehicle.state().position == pytest.approx((30.0, 40.0, 10.0))
    vehicle.submit(Land(1))
    for _ in range(60):
        vehicle.advance(0.1)
    state = vehicle.state()
    assert state.landed and not state.armed and state.battery < 100


def test_scripted_refusals_and_silence() -> None:
    vehicle = FakeVehicle(reject={"Arm": "rejected"}, ignore={"TakeOff"}, ready=True)
    arm, takeoff = Arm(1), TakeOff(1, 5.0)
    vehicle.submit(arm)
    vehicle.submit(takeoff)
    assert vehicle.poll() == [RequestResult(1, arm.request_id, False, FailureReason.REJECTED)]
    assert vehicle.submitted == [arm, takeoff]


def test_not_ready_vehicle_refuses_to_arm() -> None:
    vehicle = FakeVehicle(ready=False)
    vehicle.submit(Arm(1))
    assert vehicle.poll()[0].reason == "rejected"


def test_an_id_source_gives_each_id_once_and_counts_on_its_own() -> None:
    ids = IdSource()
    taken = [ids.take() for _ in range(100)]
    assert len(set(taken)) == 100 and taken[0] == 1
    assert IdSource().take() == 1  # nothing is numbered process-wide
    assert Arm(1).request_id == 0  # numbered when sent


def test_the_fake_vehicle_reports_its_type() -> None:
    assert FakeVehicle().state().vehicle_type == "quadcopter"
    assert FakeVehicle(vehicle_type="rover").state().vehicle_type == "rover"
    assert VehicleState(1, 0.0).vehicle_type == ""  # unknown until the vehicle says


@pytest.mark.parametrize(("wanted", "actual", "matches"), [
    ("quadcopter", "quadcopter", True),
    ("quadcopter", "hexacopter", False),
    ("fixed-wing", "fixed-wing", True),
    ("rover", "boat", False),
    ("multicopter", "quadcopter", True),
    ("multicopter", "hexacopter", True),
    ("multicopter", "octocopter", True),
    ("multicopter", "tricopter", True),
    ("multicopter", "coaxial", True),
    ("multicopter", "helicopter", False),
    ("multicopter", "fixed-wing", False),
    ("UAV", "quadcopter", True),
    ("uav", "helicopter", True),
    ("Uav", "fixed-wing", True),
    ("UAV", "vtol", True),
    ("UAV", "airship", True),
    ("UAV", "rover", False),
    ("UAV", "boat", False),
    ("UAV", "submarine", False),
    ("Quadcopter", "quadcopter", False),  # only the class word "UAV" ignores case
    ("quadcopter", "", False),
    ("UAV", "", False),
    ("multicopter", "", False),
])
def test_vehicle_type_matches(wanted: str, actual: str, matches: bool) -> None:
    assert vehicle_type_matches(wanted, actual) is matches


def test_the_type_words_a_role_may_use() -> None:
    assert {"quadcopter", "fixed-wing", "vtol", "rover"} <= VEHICLE_TYPES
    assert "" not in VEHICLE_TYPES
    assert {"multicopter", "uav"} == VEHICLE_TYPE_CLASSES
    assert not VEHICLE_TYPES & VEHICLE_TYPE_CLASSES
    for word in VEHICLE_TYPES:
        assert vehicle_type_matches(word, word)


READY = VehicleState(vehicle_id=1, time=0.0, position=(0.0, 0.0, 0.0), home=DEFAULT_HOME,
                     battery=100.0, gps_fix=3)


def test_a_vehicle_that_reported_everything_and_can_arm_is_awaited_for_nothing() -> None:
    assert awaiting(READY) == ()
    assert awaiting(FakeVehicle().state()) == ()


def test_what_has_not_arrived_is_awaited_never_taken_as_zero() -> None:
    booting = VehicleState(vehicle_id=1, time=0.0, ready=False, armable=None,
                           heading_known=False)
    assert awaiting(booting) == ("GPS status", "position", "attitude", "home position",
                                 "battery status", "GPS fix")
    assert awaiting(VehicleState(vehicle_id=1, time=0.0, link="lost")) == ("heartbeat",)


def test_an_unarmable_vehicle_is_awaited_with_the_autopilots_words() -> None:
    no_ekf = VehicleState(**{**READY.__dict__, "ready": False, "armable": False,
                             "prearm": "PreArm: Need Position Estimate"})
    assert awaiting(no_ekf) == ("position estimate", "pre-arm checks",
                                "autopilot: PreArm: Need Position Estimate")
    no_fix = VehicleState(**{**no_ekf.__dict__, "gps_fix": 1, "armable": None})
    assert awaiting(no_fix)[0] == "GPS fix"
    # A stale text alone does not hold a vehicle that can arm.
    assert awaiting(VehicleState(**{**READY.__dict__, "prearm": "PreArm: old news"})) == ()


def test_a_vehicle_already_armed_is_taken_as_it_is() -> None:
    flying = VehicleState(**{**READY.__dict__, "armed": True, "landed": False,
                             "ready": False, "armable": False})
    assert awaiting(flying) == ()


def test_a_reason_not_to_arm_is_shown_as_info() -> None:
    # ArduCopter says "PreArm: Mode not armable" (critical) after every landing in RTL,
    # and says such reasons only while disarmed.
    assert shown_severity(2, "PreArm: Mode not armable") == 6
    assert shown_severity(2, "Arm: Throttle too high") == 6
    assert shown_severity(2, "EKF variance") == 2
    assert shown_severity(4, "Mode not armable, PreArm: after") == 4  # only as it begins
    assert shown_severity(7, "PreArm: debug") == 7  # never made worse
    assert AutopilotMessage(1, 2, "PreArm: Mode not armable").shown_severity == 6


def test_the_fake_vehicle_reports_what_an_operator_reads() -> None:
    vehicle = FakeVehicle()
    for request in (Arm(1), TakeOff(1, 10.0)):
        vehicle.submit(request)
    vehicle.advance(1.0)
    state = vehicle.state()
    assert state.climb == pytest.approx(2.5) and state.satellites == 10
    assert state.voltage is not None and 10.5 < state.voltage <= 12.6
    assert state.home_distance == 0.0
    assert VehicleState(1, 0.0).home_distance is None
    assert VehicleState(1, 0.0, position=(3.0, -4.0, 9.0)).home_distance == 5.0
    # What only an operator reads is no change of state for the rules.
    assert VehicleState(1, 0.0, voltage=12.0) == VehicleState(1, 0.0, voltage=11.0)



def test_a_vehicle_is_not_ready_while_a_skill_of_the_mission_cannot_be_switched() -> None:
    from types import MappingProxyType

    from tml.vehicle import VehicleState, awaiting, unprovided

    state = VehicleState(1, 0.0, position=(0.0, 0.0, 0.0), home=None, battery=100.0,
                         gps_fix=3, skills=MappingProxyType({
                             "AVOID_OBSTACLES": "needs a companion computer (component 191), "
                                                "not heard yet",
                             "RECOGNIZE_ITEMS": ""}))
    wanted = {"AVOID_OBSTACLES", "RECOGNIZE_ITEMS", "RECOGNIZE_BUCKETS"}
    assert [m for m in awaiting(state, wanted) if m.startswith("skill")] == [
        "skill AVOID_OBSTACLES (needs a companion computer (component 191), not heard yet)",
        "skill RECOGNIZE_BUCKETS (nothing on this vehicle switches it)"]
    assert unprovided(state, wanted) == ("RECOGNIZE_BUCKETS",)
    assert not [m for m in awaiting(state, {"RECOGNIZE_ITEMS"}) if m.startswith("skill")]
    flying = dataclasses.replace(state, armed=True, landed=False)  # a resumed run waits too
    assert "skill AVOID_OBSTACLES (needs a companion computer (component 191), not heard " \
           "yet)" in awaiting(flying, wanted)
    said_nothing = VehicleState(1, 0.0, skills=None)
    assert not [m for m in awaiting(said_nothing, {"AVOID_OBSTACLES"}) if m.startswith("skill")]
    assert unprovided(said_nothing, wanted) == ()
