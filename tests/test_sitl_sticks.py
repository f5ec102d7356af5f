"""The pilot's sticks: SITL's idle radio, a ground station's override and how it reads."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.params import AUTOPILOT_DEFAULTS, Params
from sitl.sticks import Sticks


def override(source: int, *channels: int) -> M.MAVLink_rc_channels_override_message:
    values = [*channels, *[65535] * (8 - len(channels))]
    msg = M.MAVLink_rc_channels_override_message(1, 1, *values)
    msg._header.srcSystem = source
    return msg


def test_only_the_ground_station_of_mav_gcs_sysid_holds_the_sticks_while_fresh():
    sticks = Sticks(Params(AUTOPILOT_DEFAULTS, {"RC_OVERRIDE_TIME": 3}))
    assert [sticks.rc(channel, 0.0) for channel in (1, 2, 3, 4)] == [1500, 1500, 1000, 1500]
    sticks.override(override(42, 1900), 0.0)  # not the ground station: ignored
    assert sticks.rc(1, 0.0) == 1500 and not sticks.overridden
    sticks.override(override(255, 1900, 65535, 1600), 1.0)
    assert (sticks.rc(1, 2.0), sticks.rc(2, 2.0), sticks.rc(3, 2.0)) == (1900, 1500, 1600)
    assert sticks.overridden == {1, 3}
    assert sticks.rc(1, 4.5) == 1500  # older than RC_OVERRIDE_TIME: the radio again
    sticks.override(override(255, 0), 5.0)  # 0 gives the channel back
    assert sticks.overridden == {3}


def test_sticks_read_as_arducopters_control_in_and_climb_rate():
    sticks = Sticks(Params(AUTOPILOT_DEFAULTS, {"RC_OVERRIDE_TIME": -1}))
    sticks.override(override(255, 1510, 2000, 1500), 0.0)
    assert sticks.stick(1, 0.0) == 0.0  # inside the dead zone
    assert sticks.stick(2, 0.0) == pytest.approx(4500.0)
    assert sticks.climb_rate(0.0) == 0.0  # mid-stick holds the altitude
    sticks.override(override(255, 65535, 65535, 2000), 1.0)
    assert sticks.climb_rate(1.0) == pytest.approx(sticks.params["PILOT_SPEED_UP"] / 100.0)
