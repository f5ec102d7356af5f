"""The mode table agrees with what ground stations decode for an ArduCopter."""

from __future__ import annotations

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.modes import ARMABLE, GUIDED_FLAG_MODES, MODE_NAMES, MODES, NEEDS_POSITION


def test_every_mode_number_means_the_same_mode_to_a_ground_station():
    table = mavutil.mode_mapping_bynumber(M.MAV_TYPE_QUADROTOR)
    assert {number: table[number] for number in MODE_NAMES} == MODE_NAMES


def test_the_sets_only_name_known_modes_and_arming_needs_a_pilot_mode():
    assert set(MODES) >= ARMABLE | NEEDS_POSITION | GUIDED_FLAG_MODES
    assert not ARMABLE & {"AUTO", "RTL", "LAND", "BRAKE"}
