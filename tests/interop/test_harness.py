"""The suite's own harness: ArduPilot SITL starts, is found at its address, and stops."""

from __future__ import annotations

from ardupilot_sitl import SitlVehicle

from tml.mavlink.codec import mavlink
from tml.mavlink.link import Link


def test_two_copters_answer_at_their_own_ports_with_their_own_system_ids(ardupilot) -> None:
    first, second = ardupilot(count=2, params={"BATT_CAPACITY": 800})
    assert second.port != first.port
    for sitl in (first, second):
        with Link(sitl.address) as link:
            info = link.wait_vehicle(None, 30)
            assert info.system_id == sitl.system_id
            assert info.vehicle_type == mavlink.MAV_TYPE_QUADROTOR
            assert info.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA


def test_a_stopped_vehicle_is_gone(ardupilot) -> None:
    (sitl,) = ardupilot()
    sitl.stop()
    assert sitl.process.poll() is not None
    assert isinstance(sitl, SitlVehicle)
