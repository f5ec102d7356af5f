"""The options of a checked flight (tml.run.checked)."""

from __future__ import annotations

import pytest

from tml.run.checked import checked_options
from tml.verify.profile import load_profile
from tml.world import World


@pytest.mark.parametrize(("profile", "vehicle_type", "speed"), [
    ("quadcopter", "", 10.0), ("quadcopter", "quadcopter", 10.0), ("quadcopter", "rover", 5.0),
    ("fixed-wing", "fixed-wing", 18.0), ("rover", "rover", 5.0)])
def test_a_checked_flight_times_moves_at_its_profile_s_cruise_speed(
        profile: str, vehicle_type: str, speed: float) -> None:
    limits = checked_options(load_profile(profile), World()).engine.limits
    assert limits.move_speed(vehicle_type) == speed
    assert speed == load_profile(profile if vehicle_type in ("", profile) else vehicle_type
                                 ).cruise_speed
