"""Which way ArduCopter turns on CONDITION_YAW, and that tml turns it the shorter way.

ArduCopter's ``AutoYaw::set_fixed_yaw`` keeps to the direction in param3 even for a heading
from north: told clockwise from heading H to H - 45, it turns 315 degrees. A plain pymavlink
client flies the same turns on ArduCopter SITL and on the simulator, which must sweep the
same way; then tml's SetYaw to H - 45 must sweep about -45 degrees on ArduCopter (it sent
param3 1, clockwise, for every heading before: a turn of 315). The heading is
unwrapped sample by sample (GLOBAL_POSITION_INT's ``hdg`` for the plain client, tml's state
for tml); the runs wait for states, with hang guards.
"""

from __future__ import annotations

import time
from typing import Any

import pytest
from ground_station import GUIDED, GroundStation, M, on_both
from vehicle_steps import do, until

from tml.mavlink.adapter import MavlinkVehicle
from tml.mavlink.link import Link
from tml.vehicle import Arm, SetMode, SetYaw, TakeOff

HANG = 120.0  # wall s: a hang guard, not a time limit of the verdict
SETTLED = 1.5  # degrees from the heading asked


def _wrap(angle: float) -> float:
    return (angle + 180.0) % 360.0 - 180.0


def _sweep(heading: Any, done: Any) -> float:
    """Degrees turned (clockwise positive) until ``done(heading)``, reading ``heading()``."""
    swept, last = 0.0, heading()
    end = time.monotonic() + HANG
    while not done(last) or abs(swept) < 1.0:
        assert time.monotonic() < end, f"hung turning: {swept:.0f} degrees so far"
        now = heading()
        swept += _wrap(now - last)
        last = now
        time.sleep(0.01)
    return swept


def _station_sweeps(address: str) -> dict[int, float]:
    """The degrees a CONDITION_YAW to 45 degrees anticlockwise of the heading sweeps, for
    param3 1 (clockwise) and 0 (the shorter way), flown by a plain pymavlink client."""
    station = GroundStation(address)
    try:
        station.connect()
        station.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                        50_000)  # 20 Hz of the vehicle's time
        station.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL)
        station.set_mode(GUIDED)
        station.arm()
        station.take_off()

        def heading() -> float:
            while station._receive(0.005) is not None:
                pass  # the latest GLOBAL_POSITION_INT
            return float(station.position.hdg) / 100.0

        swept = {}
        for direction in (1, 0):
            start = heading()
            target = (start - 45.0) % 360.0
            station.command(M.MAV_CMD_CONDITION_YAW, target, 0, direction, 0)
            swept[direction] = _sweep(heading, lambda h, t=target: abs(_wrap(h - t)) < SETTLED)
        return swept
    finally:
        station.close()


@pytest.mark.timeout(600)
def test_condition_yaw_keeps_to_its_direction_on_arducopter_and_the_simulator(
        ardupilot: Any) -> None:
    arducopter, simulator = on_both(ardupilot, _station_sweeps)  # degrees swept
    for swept in (arducopter, simulator):
        assert swept[1] == pytest.approx(315, abs=10)  # clockwise, the long way
        assert swept[0] == pytest.approx(-45, abs=10)  # the shorter way


@pytest.mark.timeout(600)
def test_tml_turns_arducopter_the_shorter_way(ardupilot: Any) -> None:
    (sitl,) = ardupilot(speedup=2)
    with Link(sitl.address) as link:
        vehicle = MavlinkVehicle(link, sitl.system_id)
        try:
            vehicle.prepare()
            until(vehicle, lambda s: s.ready and s.home is not None and s.armable,
                   "ready to arm")
            for request in (SetMode(1, "GUIDED"), Arm(1), TakeOff(1, 5.0)):
                result = do(vehicle, request)
                assert result.ok, (request, result)
            until(vehicle, lambda s: s.altitude > 4.5, "climbed")
            target = (vehicle.state().heading - 45.0) % 360.0
            assert do(vehicle, SetYaw(1, target)).ok
            swept = _sweep(lambda: vehicle.state().heading,
                           lambda h: abs(_wrap(h - target)) < SETTLED)
            assert swept == pytest.approx(-45, abs=10)
        finally:
            vehicle.close()
