"""Flight modes by name for ArduPilot Copter, Plane, Rover and PX4."""

from __future__ import annotations

import pytest

from tml.errors import VehicleError
from tml.mavlink.codec import mavlink
from tml.mavlink.modes import mode_name, mode_names, set_mode_command

ARDUPILOT = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
PX4 = mavlink.MAV_AUTOPILOT_PX4
QUAD, PLANE, ROVER = (mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_TYPE_FIXED_WING,
                      mavlink.MAV_TYPE_GROUND_ROVER)
CUSTOM = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


@pytest.mark.parametrize(("vehicle_type", "name", "number"), [
    (QUAD, "GUIDED", 4), (QUAD, "AUTO", 3), (QUAD, "LAND", 9), (QUAD, "RTL", 6),
    (QUAD, "LOITER", 5), (PLANE, "GUIDED", 15), (PLANE, "AUTO", 10), (PLANE, "FBWA", 5),
    (ROVER, "HOLD", 4), (ROVER, "GUIDED", 15), (ROVER, "AUTO", 10),
])
def test_ardupilot_modes_use_the_vehicle_kinds_custom_mode_numbers(
        vehicle_type: int, name: str, number: int) -> None:
    command = set_mode_command(vehicle_type, ARDUPILOT, name.lower())
    assert (command.command, command.param1, command.param2) == (176, CUSTOM, number)
    assert mode_name(vehicle_type, ARDUPILOT, CUSTOM, number) == name


@pytest.mark.parametrize(("name", "main", "sub"), [("MISSION", 4, 4), ("OFFBOARD", 6, 0),
                                                   ("POSCTL", 3, 0), ("RTL", 4, 5)])
def test_px4_modes_use_main_and_sub_modes(name: str, main: int, sub: int) -> None:
    command = set_mode_command(QUAD, PX4, name)
    assert (command.param2, command.param3) == (main, sub)
    assert command.param1 == command.param1 // 1 and int(command.param1) & CUSTOM
    assert mode_name(QUAD, PX4, int(command.param1), (main << 16) | (sub << 24)) == name


def test_unknown_mode_names_the_modes_there_are() -> None:
    with pytest.raises(VehicleError, match=r"'HOVER'.*GUIDED") as caught:
        set_mode_command(QUAD, ARDUPILOT, "HOVER", system_id=2)
    assert caught.value.system_id == 2
    with pytest.raises(VehicleError, match="STABILIZE"):
        set_mode_command(QUAD, PX4, "STABILIZE")


def test_mode_lists_differ_between_vehicle_kinds() -> None:
    assert "FBWA" in mode_names(PLANE, ARDUPILOT) and "FBWA" not in mode_names(QUAD, ARDUPILOT)
    assert "OFFBOARD" in mode_names(QUAD, PX4)
    assert mode_name(QUAD, ARDUPILOT, CUSTOM, 99) == "Mode(99)"
