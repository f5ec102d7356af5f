"""Vehicle profiles: the parameters (the paper's k_i) of the feasibility model.

A profile is a flat TOML table of numbers in fixed units (metres, m/s, deg/s, percent of a
full battery, seconds) and the ``vehicle_type`` it describes (a word of
:data:`tml.language.kinds.VEHICLE_TYPES`), which says what the vehicle can do at all
(:mod:`tml.language.kinds`). Three profiles ship with tml (``quadcopter``, ``fixed-wing`` and
``rover``); a file may name one of them as ``base`` and give only the keys it changes.
The same numbers can be read from a connected ArduPilot vehicle's parameters
(:func:`profile_from_parameters`), which convert the autopilot's units (cm/s, cm, mAh)
into the profile's.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, fields, replace
from importlib import resources
from pathlib import Path

from tml.errors import TmlError
from tml.language.kinds import VEHICLE_TYPES, Kind, kind_of

SHIPPED = ("quadcopter", "fixed-wing", "rover")
DEFAULT_VEHICLE_TYPE = "quadcopter"
"""The vehicle type of a profile that does not say."""
SHIPPED_FOR_KIND = {Kind.MULTICOPTER: "quadcopter", Kind.FIXED_WING: "fixed-wing",
                    Kind.GROUND: "rover"}
"""The shipped profile that describes a vehicle of each kind."""


@dataclass(frozen=True)
class VehicleProfile:
    """The vehicle-specific parameters of the feasibility model (units in the comments)."""

    name: str
    cruise_speed: float  # m/s, speed of moves until SET_SPEED changes it
    max_speed: float  # m/s, the paper's k3
    climb_rate: float  # m/s
    descent_rate: float  # m/s
    land_speed: float  # m/s of the last land_altitude metres of a landing; 0: descent_rate
    land_altitude: float  # m above the ground where a landing slows to land_speed
    yaw_rate: float  # deg/s
    acceleration: float  # m/s², speeding up and braking at each waypoint; 0: at once
    battery_capacity: float  # mAh the consumption figures below are measured with
    battery_per_metre: float  # percent per metre flown, the paper's k1
    battery_per_second: float  # percent per second hovering (loitering for a fixed-wing)
    battery_reserve: float  # percent that must be left when back home
    min_clearance: float  # m, the paper's k2
    min_altitude: float  # m above home, lowest altitude of a cruise leg
    max_altitude: float  # m above home
    max_range: float  # m, farthest horizontal distance from home
    takeoff_altitude: float  # m, used by TAKE_OFF when no altitude is written
    return_altitude: float  # m, RETURN_HOME_AND_LAND climbs to it first (ArduPilot RTL_ALT)
    return_hover: float  # s RETURN_HOME_AND_LAND hovers over home before it descends
    min_turn_radius: float  # m, smallest loiter circle (0 for a multicopter)
    max_flight_time: float  # s from the start of the mission to its end; 0: no limit
    vehicle_type: str = DEFAULT_VEHICLE_TYPE  # a word of tml.language.kinds.VEHICLE_TYPES
    min_terrain_clearance: float = 10.0  # m above the ground (terrain data), when given

    @property
    def kind(self) -> Kind:
        """What the vehicle can do at all (see :mod:`tml.language.kinds`)."""
        return kind_of(self.vehicle_type)


# Keys that may be zero; every other number must be strictly positive.
_MAY_BE_ZERO = frozenset({"min_altitude", "min_turn_radius", "max_flight_time",
                          "battery_reserve", "min_clearance", "battery_per_second",
                          "acceleration", "land_speed", "land_altitude", "return_hover",
                          "min_terrain_clearance"})
# Keys a profile file may leave out, and the value they then take (files written before
# the key existed keep their meaning).
_OPTIONAL = {"acceleration": 0.0, "land_speed": 0.0, "land_altitude": 0.0,
             "return_hover": 0.0, "min_terrain_clearance": 10.0}
TEXT_KEYS = ("name", "vehicle_type")
NUMBER_KEYS = tuple(f.name for f in fields(VehicleProfile) if f.name not in TEXT_KEYS)


def _numbers(profile: VehicleProfile) -> dict[str, float]:
    numbers: dict[str, float] = {key: getattr(profile, key) for key in NUMBER_KEYS}
    return numbers


def _profile(name: str, vehicle_type: str, numbers: Mapping[str, float]) -> VehicleProfile:
    return VehicleProfile(name=name, vehicle_type=vehicle_type, **numbers)


def _problem(file: str, key: str, why: str) -> TmlError:
    return TmlError(f"{file}: key {key!r}: {why}")


def profile_from_mapping(data: Mapping[str, object], file: str,
                         base: VehicleProfile | None = None) -> VehicleProfile:
    """A profile from a parsed TOML table; keys missing here come from ``base``.

    Raises :class:`TmlError` naming the file and the key on an unknown key, a missing key,
    a value that is not a number, or a number out of range.
    """
    name = None if base is None else base.name
    vehicle_type = DEFAULT_VEHICLE_TYPE if base is None else base.vehicle_type
    values = {} if base is None else _numbers(base)
    for key, value in data.items():
        if key == "base":
            continue
        if key == "name":
            if not isinstance(value, str) or not value.strip():
                raise _problem(file, key, "expected a non-empty string")
            name = value
            continue
        if key == "vehicle_type":
            if not isinstance(value, str) or value not in VEHICLE_TYPES:
                raise _problem(file, key, f"expected one of {', '.join(sorted(VEHICLE_TYPES))}"
                                          f", got {value!r}")
            vehicle_type = value
            continue
        if key not in NUMBER_KEYS:
            raise _problem(file, key, "unknown key; known keys: " + ", ".join(NUMBER_KEYS))
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise _problem(file, key, f"expected a number, got {value!r}")
        number = float(value)
        if not math.isfinite(number) or number < 0 or (number == 0 and key not in _MAY_BE_ZERO):
            bound = "at least 0" if key in _MAY_BE_ZERO else "greater than 0"
            raise _problem(file, key, f"must be a finite number {bound}, got {value!r}")
        values[key] = number
    for key, default in _OPTIONAL.items():
        values.setdefault(key, default)
    for key in NUMBER_KEYS:
        if key not in values:
            raise _problem(file, key, "missing (or name a shipped profile with base = "
                                      f"\"{SHIPPED[0]}\" to take the rest from it)")
    profile = _profile(Path(file).stem if name is None else name, vehicle_type, values)
    if profile.cruise_speed > profile.max_speed:
        raise _problem(file, "cruise_speed", f"{profile.cruise_speed:g} m/s is above "
                                             f"max_speed {profile.max_speed:g} m/s")
    if profile.min_altitude >= profile.max_altitude:
        raise _problem(file, "min_altitude", f"{profile.min_altitude:g} m is not below "
                                             f"max_altitude {profile.max_altitude:g} m")
    if profile.battery_reserve >= 100:
        raise _problem(file, "battery_reserve", "must be below 100 percent")
    return profile


def load_profile(source: str | Path) -> VehicleProfile:
    """A shipped profile by name (``quadcopter``, ``fixed-wing``, ``rover``) or a file.

    Raises :class:`TmlError` on bad TOML or bad keys (naming the file and the key), or on a
    bare name that is neither a shipped profile nor a file (listing the profiles), and
    OSError when the file cannot be read.
    """
    text_source = str(source)
    if text_source in SHIPPED:
        shipped = resources.files("tml.verify").joinpath(f"profiles/{text_source}.toml")
        return profile_from_mapping(tomllib.loads(shipped.read_text("utf-8")), text_source)
    path = Path(source)
    if len(path.parts) == 1 and not path.suffix and not path.exists():
        # A bare word is a profile's name mistyped more likely than a file gone: the names.
        raise TmlError(f"profile {text_source!r}: no such profile or file; the profiles are "
                       f"{', '.join(SHIPPED)}, vehicle (filled in from the vehicle's own "
                       "parameters) or a TOML file")
    try:
        data = tomllib.loads(path.read_text("utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise TmlError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise TmlError(f"{path}: not a UTF-8 text file") from None
    base = None
    if "base" in data:
        if data["base"] not in SHIPPED:
            raise _problem(str(path), "base", f"{data['base']!r} is not a shipped profile "
                                              f"({', '.join(SHIPPED)})")
        base = load_profile(str(data["base"]))
    return profile_from_mapping(data, str(path), base)


def _positive(params: Mapping[str, float], name: str) -> float | None:
    value = params.get(name)
    if value is None or not math.isfinite(value) or value <= 0:
        return None
    return float(value)


COPTER_PARAMETERS = ("WPNAV_SPEED", "WPNAV_SPEED_UP", "WPNAV_SPEED_DN", "WPNAV_ACCEL",
                     "LAND_SPEED", "LAND_ALT_LOW", "RTL_ALT", "RTL_LOIT_TIME",
                     "FENCE_ALT_MAX", "FENCE_ALT_MIN", "FENCE_RADIUS", "ATC_RATE_Y_MAX",
                     "BATT_CAPACITY", "BATT_LOW_MAH")
"""The ArduCopter parameters :func:`profile_from_parameters` reads (all exist on Copter)."""
PARAMETERS: dict[Kind, tuple[str, ...]] = {
    Kind.MULTICOPTER: COPTER_PARAMETERS,
    Kind.FIXED_WING: ("AIRSPEED_CRUISE", "AIRSPEED_MAX", "TKOFF_ALT", "RTL_ALTITUDE",
                      "FENCE_ALT_MAX", "FENCE_ALT_MIN", "FENCE_RADIUS", "BATT_CAPACITY",
                      "BATT_LOW_MAH"),
    Kind.GROUND: ("WP_SPEED", "FENCE_RADIUS", "BATT_CAPACITY", "BATT_LOW_MAH"),
}
"""The parameters to read from a vehicle of each kind (ArduCopter's, ArduPlane's, Rover's)."""


def shipped_for(vehicle_type: str) -> VehicleProfile:
    """The shipped profile of a vehicle type's kind (the quadcopter's while unknown)."""
    return load_profile(SHIPPED_FOR_KIND[kind_of(vehicle_type)])


def profile_from_parameters(params: Mapping[str, float], base: VehicleProfile) -> VehicleProfile:
    """``base`` with the values an ArduPilot vehicle's parameters give, in profile units.

    Pure: takes the parameter table as read from the vehicle (names as ArduPilot spells
    them, values as it sends them) and returns a new profile. Parameters absent, zero or
    negative (ArduPilot's "not set" / "disabled") leave the base value. Read:
    WPNAV_SPEED, WPNAV_SPEED_UP, WPNAV_SPEED_DN, LAND_SPEED, LAND_ALT_LOW, RTL_ALT,
    ALT_HOLD_RTL, TRIM_ARSPD_CM (cm/s or cm); WPNAV_ACCEL (cm/s²); RTL_LOIT_TIME (ms);
    AIRSPEED_CRUISE, AIRSPEED_MAX, ARSPD_FBW_MAX, FENCE_ALT_MAX, FENCE_ALT_MIN,
    FENCE_RADIUS, TKOFF_ALT, RTL_ALTITUDE (m); WP_SPEED (m/s, Rover's); ATC_RATE_Y_MAX
    (deg/s); BATT_CAPACITY and BATT_LOW_MAH (mAh).

    The battery calibration: the base's ``battery_per_metre`` and ``battery_per_second``
    are percent of ``battery_capacity`` mAh, that is a current drawn (the shipped
    quadcopter's were measured on ArduCopter SITL, docs/verify.md); the same current takes
    a smaller share of a larger battery, so BATT_CAPACITY scales both by
    ``battery_capacity / BATT_CAPACITY``.
    """
    changes: dict[str, float] = {}
    centimetres = {"WPNAV_SPEED": "cruise_speed", "TRIM_ARSPD_CM": "cruise_speed",
                   "WPNAV_SPEED_UP": "climb_rate", "WPNAV_SPEED_DN": "descent_rate",
                   "WPNAV_ACCEL": "acceleration", "LAND_SPEED": "land_speed",
                   "LAND_ALT_LOW": "land_altitude", "RTL_ALT": "return_altitude",
                   "ALT_HOLD_RTL": "return_altitude"}
    metres = {"AIRSPEED_CRUISE": "cruise_speed", "ARSPD_FBW_MAX": "max_speed",
              "AIRSPEED_MAX": "max_speed", "FENCE_ALT_MAX": "max_altitude",
              "FENCE_RADIUS": "max_range", "TKOFF_ALT": "takeoff_altitude",
              "RTL_ALTITUDE": "return_altitude", "WP_SPEED": "cruise_speed",
              "ATC_RATE_Y_MAX": "yaw_rate"}
    for name, key in centimetres.items():
        value = _positive(params, name)
        if value is not None:
            changes[key] = value / 100.0
    for name, key in metres.items():
        value = _positive(params, name)
        if value is not None:
            changes[key] = value
    hover = _positive(params, "RTL_LOIT_TIME")
    if hover is not None:
        changes["return_hover"] = hover / 1000.0
    fence_min = _positive(params, "FENCE_ALT_MIN")
    if fence_min is not None:
        changes["min_altitude"] = fence_min
    capacity = _positive(params, "BATT_CAPACITY")
    if capacity is not None:
        scale = base.battery_capacity / capacity
        changes.update(battery_capacity=capacity,
                       battery_per_metre=base.battery_per_metre * scale,
                       battery_per_second=base.battery_per_second * scale)
        low = _positive(params, "BATT_LOW_MAH")
        if low is not None and low < capacity:
            changes["battery_reserve"] = 100.0 * low / capacity
    profile = _profile(base.name, base.vehicle_type, _numbers(base) | changes)
    if profile.max_speed < profile.cruise_speed:
        profile = replace(profile, max_speed=profile.cruise_speed)
    return profile


def profile_from_vehicle(read_parameters: Callable[[Iterable[str]], Mapping[str, float]],
                         base: VehicleProfile) -> tuple[VehicleProfile, dict[str, float]]:
    """``base`` filled in from a connected vehicle: ``read_parameters(names)`` returns the
    values of those of :data:`PARAMETERS` of the base's kind the vehicle has (give the
    vehicle's own kind: :func:`shipped_for`). Returns the profile and the parameters read
    (to tell the user what was used)."""
    params = dict(read_parameters(PARAMETERS[base.kind]))
    return profile_from_parameters(params, base), params


def describe_parameters(params: Mapping[str, float]) -> str:
    """``NAME=value, ...`` in name order, for messages."""
    return ", ".join(f"{name}={value:g}" for name, value in sorted(params.items()))
