"""The vehicle interface's fake vehicle (tml.vehicle)."""

from __future__ import annotations

import pytest

from tml.vehicle import Arm, FakeVehicle, GoTo, Land, RequestResult, SetMode, TakeOff


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
    assert vehicle.poll() == [RequestResult(1, arm.request_id, False, "rejected")]
    assert vehicle.submitted == [arm, takeoff]


def test_not_ready_vehicle_refuses_to_arm() -> None:
    vehicle = FakeVehicle(ready=False)
    vehicle.submit(Arm(1))
    assert vehicle.poll()[0].reason == "rejected"


def test_request_ids_are_unique() -> None:
    assert len({Arm(1).request_id for _ in range(100)}) == 100
