"""Vehicle profiles: shipped ones load, bad files name the file and the key, ArduPilot
parameters convert to profile units."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from tml.errors import TmlError
from tml.language.kinds import Kind
from tml.verify.profile import (
    COPTER_PARAMETERS,
    NUMBER_KEYS,
    PARAMETERS,
    SHIPPED,
    SHIPPED_FOR_KIND,
    load_profile,
    profile_from_parameters,
    profile_from_vehicle,
    shipped_for,
)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_profiles_load(name: str) -> None:
    profile = load_profile(name)
    assert profile.name == name
    assert 0 < profile.cruise_speed <= profile.max_speed
    assert profile.min_altitude < profile.max_altitude


def test_a_name_that_is_no_profile_and_no_file_is_told_the_profiles(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(TmlError) as raised:
        load_profile("helicopter")
    message = str(raised.value)
    assert message.startswith("profile 'helicopter': no such profile or file; the profiles ")
    assert all(name in message for name in SHIPPED)
    (tmp_path / "helicopter").mkdir()  # there, but not a file: the system's reason
    with pytest.raises(IsADirectoryError):
        load_profile("helicopter")


@pytest.mark.parametrize(("name", "kind"), [("quadcopter", Kind.MULTICOPTER),
                                            ("fixed-wing", Kind.FIXED_WING),
                                            ("rover", Kind.GROUND)])
def test_each_shipped_profile_says_what_vehicle_it_describes(name: str, kind: Kind) -> None:
    assert load_profile(name).kind is kind
    assert SHIPPED_FOR_KIND[kind] == name


def test_a_profile_file_may_name_its_vehicle_type(tmp_path: Path) -> None:
    path = tmp_path / "boat.toml"
    path.write_text('base = "rover"\nvehicle_type = "boat"\n')
    assert load_profile(path).kind is Kind.GROUND
    path.write_text('base = "quadcopter"\nmax_speed = 12\n')
    assert load_profile(path).vehicle_type == "quadcopter"  # the base's


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
    ('base = "quadcopter"\nvehicle_type = "blimp"\n', "vehicle_type", "expected one of"),
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
    # The same current drawn from a larger battery: a smaller percent per metre and second.
    scale = base.battery_capacity / 10000.0
    assert profile.battery_capacity == 10000.0
    assert profile.battery_per_metre == pytest.approx(base.battery_per_metre * scale)
    assert profile.battery_per_second == pytest.approx(base.battery_per_second * scale)
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


def test_arducopters_defaults_give_the_shipped_quadcopter() -> None:
    """The shipped profile is ArduCopter SITL with copter.parm: its parameters change
    nothing (the battery figures were measured with BATT_CAPACITY 3300)."""
    arducopter = {"WPNAV_SPEED": 1000.0, "WPNAV_SPEED_UP": 250.0, "WPNAV_SPEED_DN": 150.0,
                  "WPNAV_ACCEL": 250.0, "LAND_SPEED": 50.0, "LAND_ALT_LOW": 1000.0,
                  "RTL_ALT": 1500.0, "RTL_LOIT_TIME": 5000.0, "ATC_RATE_Y_MAX": 0.0,
                  "BATT_CAPACITY": 3300.0, "BATT_LOW_MAH": 0.0}
    base = load_profile("quadcopter")
    assert profile_from_parameters(arducopter, base) == base


def test_acceleration_landing_and_rtl_wait_convert_from_ardupilot_units() -> None:
    params = {"WPNAV_ACCEL": 100.0, "LAND_SPEED": 30.0, "LAND_ALT_LOW": 500.0,
              "RTL_LOIT_TIME": 2000.0}
    profile = profile_from_parameters(params, load_profile("quadcopter"))
    assert (profile.acceleration, profile.land_speed, profile.land_altitude,
            profile.return_hover) == pytest.approx((1.0, 0.3, 5.0, 2.0))


def test_battery_calibration_follows_the_vehicles_capacity() -> None:
    """The figures are a current: a smaller battery loses it faster, in percent."""
    base = load_profile("quadcopter")
    small = profile_from_parameters({"BATT_CAPACITY": base.battery_capacity / 4}, base)
    assert small.battery_per_second == pytest.approx(4 * base.battery_per_second)
    assert small.battery_per_metre == pytest.approx(4 * base.battery_per_metre)
    amperes = base.battery_per_second / 100 * base.battery_capacity * 3.6
    assert 25 < amperes < 32  # ArduCopter SITL hovers on about 28 A


def test_profile_from_a_vehicle_reads_the_copter_parameters() -> None:
    asked: list[str] = []

    def read(names):  # a vehicle that has only some of them
        asked.extend(names)
        return {"BATT_CAPACITY": 6600.0, "WPNAV_SPEED": 500.0}

    base = load_profile("quadcopter")
    profile, params = profile_from_vehicle(read, base)
    assert asked == list(COPTER_PARAMETERS)
    assert params == {"BATT_CAPACITY": 6600.0, "WPNAV_SPEED": 500.0}
    assert profile.cruise_speed == 5.0
    assert profile.battery_per_second == pytest.approx(base.battery_per_second / 2)


def test_new_keys_may_be_left_out_of_a_full_profile(tmp_path: Path) -> None:
    path = tmp_path / "old.toml"
    keys = {f: getattr(load_profile("quadcopter"), f) for f in NUMBER_KEYS
            if f not in ("acceleration", "land_speed", "land_altitude", "return_hover")}
    path.write_text("".join(f"{key} = {value!r}\n" for key, value in keys.items()))
    profile = load_profile(path)
    assert (profile.acceleration, profile.land_speed, profile.return_hover) == (0, 0, 0)


def test_arduplane_and_rover_parameters_fill_in_their_own_profiles() -> None:
    plane = profile_from_parameters({"AIRSPEED_CRUISE": 22, "RTL_ALTITUDE": 100,
                                     "TKOFF_ALT": 50}, load_profile("fixed-wing"))
    assert (plane.cruise_speed, plane.return_altitude, plane.takeoff_altitude) == (22, 100, 50)
    rover = profile_from_parameters({"WP_SPEED": 3}, load_profile("rover"))
    assert rover.cruise_speed == 3 and rover.kind is Kind.GROUND
    assert set(PARAMETERS) == set(Kind)


def test_a_vehicle_s_parameters_are_read_for_its_own_kind() -> None:
    asked: list[str] = []

    def read(names):
        asked.extend(names)
        return {"WP_SPEED": 3.0}

    assert shipped_for("boat").name == "rover" and shipped_for("").name == "quadcopter"
    profile, _ = profile_from_vehicle(read, shipped_for("rover"))
    assert asked == list(PARAMETERS[Kind.GROUND]) and profile.cruise_speed == 3.0
