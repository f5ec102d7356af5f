"""Vehicle profiles: shipped ones load, bad files name the file and the key, ArduPilot
parameters convert to profile units."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from tml.errors import TmlError
from tml.verify.profile import SHIPPED, load_profile, profile_from_parameters


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_profiles_load(name: str) -> None:
    profile = load_profile(name)
    assert profile.name == name
    assert 0 < profile.cruise_speed <= profile.max_speed
    assert profile.min_altitude < profile.max_altitude


def test_fixed_wing_cannot_circle_as_tightly_as_a_quadcopter() -> None:
    assert load_profile("fixed-wing").min_turn_radius > load_profile("quadcopter").min_turn_radius


def test_file_with_base_overrides_only_what_it_gives(tmp_path: Path) -> None:
    path = tmp_path / "heavy.toml"
    path.write_text('base = "quadcopter"\nname = "heavy"\nbattery_per_metre = 0.05\n')
    profile = load_profile(path)
    assert profile == replace(load_profile("quadcopter"), name="heavy", battery_per_metre=0.05)


@pytest.mark.parametrize(("text", "key", "why"), [
    ('base = "quadcopter"\ncruise_speed = "fast"\n', "cruise_speed", "expected a number"),
    ('base = "quadcopter"\ncruise_sped = 4\n', "cruise_sped", "unknown key"),
    ('base = "quadcopter"\nmax_speed = -1\n', "max_speed", "greater than 0"),
    ('base = "quadcopter"\ncruise_speed = 40\n', "cruise_speed", "above max_speed"),
    ('base = "quadcopter"\nmin_altitude = 500\n', "min_altitude", "not below max_altitude"),
    ('base = "helicopter"\n', "base", "not a shipped profile"),
    ('cruise_speed = 4\n', "max_speed", "missing"),
])
def test_bad_profile_names_file_and_key(tmp_path: Path, text: str, key: str, why: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(TmlError) as caught:
        load_profile(path)
    assert str(path) in str(caught.value)
    assert f"key {key!r}" in str(caught.value)
    assert why in str(caught.value)


def test_not_toml_is_an_error_with_the_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("cruise_speed = = 3\n")
    with pytest.raises(TmlError, match=r"bad\.toml: not valid TOML"):
        load_profile(path)


def test_missing_file_is_an_os_error(tmp_path: Path) -> None:
    with pytest.raises(OSError):
        load_profile(tmp_path / "nowhere.toml")


def test_parameters_convert_from_ardupilot_units() -> None:
    base = load_profile("quadcopter")
    params = {"WPNAV_SPEED": 800.0, "WPNAV_SPEED_UP": 300.0, "WPNAV_SPEED_DN": 120.0,
              "RTL_ALT": 2500.0, "FENCE_ALT_MAX": 80.0, "FENCE_RADIUS": 600.0,
              "BATT_CAPACITY": 10000.0, "BATT_LOW_MAH": 2500.0, "ATC_RATE_Y_MAX": 0.0}
    profile = profile_from_parameters(params, base)
    assert profile.cruise_speed == pytest.approx(8.0)
    assert profile.climb_rate == pytest.approx(3.0)
    assert profile.descent_rate == pytest.approx(1.2)
    assert profile.return_altitude == pytest.approx(25.0)
    assert profile.max_altitude == 80.0
    assert profile.max_range == 600.0
    assert profile.yaw_rate == base.yaw_rate  # 0 means "not set" in ArduPilot
    # Twice the reference capacity: half the percent per metre and per second.
    assert profile.battery_per_metre == pytest.approx(base.battery_per_metre / 2)
    assert profile.battery_per_second == pytest.approx(base.battery_per_second / 2)
    assert profile.battery_reserve == pytest.approx(25.0)


def test_parameters_raise_max_speed_to_a_faster_cruise() -> None:
    base = load_profile("quadcopter")
    profile = profile_from_parameters({"WPNAV_SPEED": 2000.0}, base)
    assert profile.cruise_speed == 20.0
    assert profile.max_speed == 20.0


def test_no_parameters_change_nothing() -> None:
    base = load_profile("fixed-wing")
    assert profile_from_parameters({}, base) == base


def test_every_copter_parameter_read_from_a_vehicle_changes_the_profile() -> None:
    from tml.verify.profile import COPTER_PARAMETERS, profile_from_parameters

    base = load_profile("quadcopter")
    for name in COPTER_PARAMETERS:
        value = 7777.0 if name != "BATT_LOW_MAH" else 500.0
        params = {name: value, "BATT_CAPACITY": 9000.0} if name == "BATT_LOW_MAH" \
            else {name: value}
        assert profile_from_parameters(params, base) != base, name
