"""The independent pymavlink ground station flies ArduCopter SITL (the simulator's twin test
is tests/test_ground_station.py): GUIDED, arm with retries, take off, upload, read back,
AUTO, land."""

from __future__ import annotations

from ground_station import fly, same_mission


def test_an_independent_ground_station_flies_arducopter(ardupilot) -> None:
    (sitl,) = ardupilot()
    flight = fly(sitl.address, timeout=120.0)
    assert "Arm: Need Position Estimate" in flight.arm_refusals
    assert flight.takeoff_result == 0
    assert same_mission(flight.uploaded, flight.read_back)
    assert flight.reached[:3] == [1, 2, 3]
    assert flight.landed_disarmed
