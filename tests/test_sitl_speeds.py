"""The navigation's limits: the parameters, DO_CHANGE_SPEED's overrides and the modes."""

from __future__ import annotations

import pytest

from sitl.params import AUTOPILOT_DEFAULTS, Params
from sitl.speeds import BRAKE_DECEL, Speeds


def test_overrides_replace_the_parameters_until_set_again():
    speeds = Speeds(Params(AUTOPILOT_DEFAULTS, {"WPNAV_SPEED": 1000}))
    assert speeds.limits("GUIDED").speed == pytest.approx(10.0)
    speeds.set(1, 4.0)
    speeds.set(2, 1.5)
    speeds.set(3, 0.7)
    limits = speeds.limits("GUIDED")
    assert (limits.speed, limits.climb, limits.descent) == (4.0, 1.5, 0.7)


def test_rtl_brake_and_the_pilot_modes_have_their_own_limits():
    params = Params(AUTOPILOT_DEFAULTS, {"RTL_SPEED": 300})
    speeds = Speeds(params)
    assert speeds.limits("RTL").speed == pytest.approx(3.0)
    assert speeds.limits("BRAKE").accel == BRAKE_DECEL
    assert speeds.limits("ALT_HOLD").climb == pytest.approx(params["PILOT_SPEED_UP"] / 100.0)


def test_the_limits_are_kept_until_a_parameter_the_mode_or_an_override_changes():
    params = Params(AUTOPILOT_DEFAULTS)
    speeds = Speeds(params)
    first = speeds.limits("GUIDED")
    assert speeds.limits("GUIDED") is first
    params.set("WPNAV_SPEED", 700)
    assert speeds.limits("GUIDED") is not first
    assert speeds.limits("GUIDED").speed == pytest.approx(7.0)
