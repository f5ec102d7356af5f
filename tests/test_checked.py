"""The options of a checked flight (tml.run.checked)."""

from __future__ import annotations

import pytest

from tml.run.checked import checked_options
from tml.verify.profile import load_profile
from tml.world import World


@pytest.mark.parametrize(("profile", "vehicle_type", "speed", "acceleration"), [
    ("quadcopter", "", 10.0, 2.5), ("quadcopter", "quadcopter", 10.0, 2.5),
    ("quadcopter", "rover", 5.0, 0.6), ("fixed-wing", "fixed-wing", 18.0, 0.0),
    ("rover", "rover", 5.0, 0.6)])
def test_a_checked_flight_times_moves_as_its_profile_says(
        profile: str, vehicle_type: str, speed: float, acceleration: float) -> None:
    limits = checked_options(load_profile(profile), World()).engine.limits
    assert limits.move_speed(vehicle_type) == speed
    own = load_profile(profile if vehicle_type in ("", profile) else vehicle_type)
    assert (own.cruise_speed, own.acceleration) == (speed, acceleration)
    # 100 m from a stop to a stop: 100 / speed, plus speed / acceleration to speed up and
    # brake (40 m of a quadcopter's 100 reach 10 m/s at 2.5 m/s²).
    assert limits.leg_seconds(vehicle_type, 100.0) == pytest.approx(
        100 / speed + (speed / acceleration if acceleration else 0.0))
    limits.speed = 2.0  # SET_SPEED
    assert limits.move_speed(vehicle_type) == 2.0
