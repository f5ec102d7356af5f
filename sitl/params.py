"""The parameter tables of the simulated vehicles and of their companion computer.

Names, defaults and units follow ArduCopter (centimetres and centimetres per second where
ArduCopter uses them), ArduPlane and Rover, so that a ground station that reads or writes
them sees what it expects: the plane and the rover have the parameters all three share and
their own, never ArduCopter's (:data:`COPTER_ONLY`). ``SIM_*`` parameters shape the
simulation itself: ``SIM_GPS_LOCKTIME``, ``SIM_WIND_SPD``, ``SIM_WIND_DIR``,
``SIM_BATT_VOLTAGE`` and ``SIM_BATT_CAP_AH`` (the simulated pack's capacity; 0, the
default, keeps the voltage constant as ArduPilot SITL does) are ArduPilot SITL's own
names; ``SIM_EKF_GPS_TIME`` (seconds from boot until the EKF uses GPS) is ours, with the
delay ArduCopter SITL shows, and so are ``SIM_BATT_CHARGE`` (amperes a landed, disarmed
vehicle takes from its charging pad; 0: no pad), ``SIM_BATT_START`` (the charge the battery
holds at boot, in percent of ``BATT_CAPACITY``; 100, the default, is a full battery as on
ArduPilot SITL) and ``SIM_COMPANION`` (1: the vehicle
carries the embedded companion computer, component 191; 0: it has none, and a companion
attached from outside, such as ``tml companion``, takes its place).

:class:`Params` keeps the values in table order (the order PARAM_VALUE indices refer to)
and remembers each value's MAVLink type: PARAM_SET carries a float whatever the type,
and ArduPilot answers with the value rounded to the parameter's type.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

# MAV_PARAM_TYPE values used here.
INT8, INT16, INT32, REAL32 = 2, 4, 6, 9

SAME_AS: Mapping[str, str] = MappingProxyType({
    # ArduPilot 4.7's name and the one before it, of one setting: setting either sets both
    # (a ground station of either age reads and writes the value the model uses).
    "MAV_GCS_SYSID": "SYSID_MYGCS", "SYSID_MYGCS": "MAV_GCS_SYSID",
})

AUTOPILOT_DEFAULTS: tuple[tuple[str, float, int], ...] = (
    ("MAV_SYSID", 1, INT16),
    ("SYSID_THISMAV", 1, INT16),
    ("MAV_GCS_SYSID", 255, INT16),
    ("SYSID_MYGCS", 255, INT16),
    ("FRAME_CLASS", 1, INT8),
    ("FRAME_TYPE", 1, INT8),
    ("ARMING_CHECK", 1, INT32),
    ("DISARM_DELAY", 10, INT8),
    ("WPNAV_SPEED", 1000, REAL32),
    ("WPNAV_SPEED_UP", 250, REAL32),
    ("WPNAV_SPEED_DN", 150, REAL32),
    ("WPNAV_ACCEL", 250, REAL32),
    ("WPNAV_ACCEL_Z", 100, REAL32),
    ("WPNAV_RADIUS", 200, REAL32),
    ("WPNAV_JERK", 1, REAL32),
    ("PSC_JERK_XY", 5, REAL32),
    ("PSC_JERK_Z", 5, REAL32),
    ("PSC_POSXY_P", 1, REAL32),
    ("PSC_POSZ_P", 1, REAL32),
    ("MOT_SPOOL_TIME", 0.5, REAL32),
    ("TKOFF_SLEW_TIME", 2, REAL32),
    ("LOIT_SPEED", 1250, REAL32),
    ("ATC_SLEW_YAW", 6000, REAL32),
    ("ATC_RATE_Y_MAX", 90, REAL32),
    ("ATC_INPUT_TC", 0.15, REAL32),
    ("PILOT_SPEED_UP", 250, INT16),
    ("PILOT_SPEED_DN", 0, INT16),
    ("PILOT_ACCEL_Z", 250, INT16),
    ("THR_DZ", 100, INT16),
    ("RC_OVERRIDE_TIME", 3.0, REAL32),
    ("LAND_SPEED", 50, INT16),
    ("LAND_SPEED_HIGH", 0, INT16),
    ("LAND_ALT_LOW", 1000, INT16),
    ("RTL_ALT", 1500, INT32),
    ("RTL_ALT_FINAL", 0, INT32),
    ("RTL_LOIT_TIME", 5000, INT32),
    ("RTL_SPEED", 0, INT16),
    ("RTL_CONE_SLOPE", 3, REAL32),
    ("RTL_CLIMB_MIN", 0, INT16),
    ("CIRCLE_RADIUS", 1000, REAL32),
    ("BATT_MONITOR", 4, INT8),
    ("BATT_CAPACITY", 3300, INT32),
    ("BATT_LOW_VOLT", 10.5, REAL32),
    ("BATT_LOW_MAH", 0, INT32),
    ("BATT_LOW_TIMER", 10, INT8),
    ("BATT_CRT_VOLT", 0, REAL32),
    ("BATT_FS_LOW_ACT", 0, INT8),
    ("BATT_FS_CRT_ACT", 0, INT8),
    ("FS_GCS_ENABLE", 0, INT8),
    ("FS_GCS_TIMEOUT", 5, REAL32),
    ("FS_EKF_ACTION", 1, INT8),
    ("FENCE_ENABLE", 0, INT8),
    ("FENCE_TYPE", 7, INT8),
    ("FENCE_ACTION", 1, INT8),
    ("FENCE_ALT_MAX", 100, REAL32),
    ("FENCE_ALT_MIN", -10, REAL32),
    ("FENCE_RADIUS", 300, REAL32),
    ("FENCE_MARGIN", 2, REAL32),
    ("FENCE_TOTAL", 0, INT8),
    ("RALLY_TOTAL", 0, INT8),
    ("RALLY_LIMIT_KM", 0.3, REAL32),
    ("RALLY_INCL_HOME", 1, INT8),
    ("MIS_TOTAL", 0, INT16),
    ("AVOID_ENABLE", 3, INT8),
    ("AVOID_MARGIN", 2, REAL32),
    ("GRIP_ENABLE", 1, INT8),
    ("GRIP_TYPE", 1, INT8),  # 1 servo: a gripper is fitted
    # A camera is fitted (1: a servo-triggered one, read at boot as ArduPilot does; 0: none).
    ("CAM1_TYPE", 1, INT8),
    ("CAM1_TRIGG_DIST", 0, REAL32),
    ("CAM1_DURATION", 0.1, REAL32),  # s the shutter is held: no other picture meanwhile
    ("SIM_GPS_LOCKTIME", 10, REAL32),
    ("SIM_EKF_GPS_TIME", 41, REAL32),
    ("SIM_WIND_SPD", 0, REAL32),
    ("SIM_WIND_DIR", 180, REAL32),
    ("SIM_BATT_VOLTAGE", 12.6, REAL32),
    ("SIM_BATT_CAP_AH", 0, REAL32),
    ("SIM_BATT_CHARGE", 0, REAL32),
    ("SIM_BATT_START", 100, REAL32),
    ("SIM_COMPANION", 1, INT8),
)

FAST_BOOT: tuple[tuple[str, float], ...] = (("SIM_GPS_LOCKTIME", 1.0), ("SIM_EKF_GPS_TIME", 2.0))
"""The settings that cut the start-up: the GPS locks after 1 s and the EKF uses it after 2 s
instead of ArduCopter SITL's 10 and 41 s of vehicle time (``--fast-boot``)."""

# ArduCopter's own parameters: ArduPlane and Rover have none of them.
COPTER_ONLY = frozenset({
    "FRAME_CLASS", "FRAME_TYPE", "DISARM_DELAY", "WPNAV_SPEED", "WPNAV_SPEED_UP",
    "WPNAV_SPEED_DN", "WPNAV_ACCEL", "WPNAV_ACCEL_Z", "WPNAV_RADIUS", "LOIT_SPEED",
    "ATC_SLEW_YAW", "ATC_RATE_Y_MAX", "PILOT_SPEED_UP", "LAND_SPEED", "LAND_SPEED_HIGH",
    "LAND_ALT_LOW", "RTL_ALT", "RTL_ALT_FINAL", "RTL_LOIT_TIME", "RTL_SPEED", "CIRCLE_RADIUS",
    "FS_EKF_ACTION", "WPNAV_JERK", "PSC_JERK_XY", "PSC_JERK_Z", "PSC_POSXY_P", "PSC_POSZ_P",
    "MOT_SPOOL_TIME", "TKOFF_SLEW_TIME", "RTL_CONE_SLOPE", "RTL_CLIMB_MIN", "ATC_INPUT_TC",
})


def _common(*own: tuple[str, float, int]) -> tuple[tuple[str, float, int], ...]:
    """The parameters every ArduPilot vehicle has here, then a kind's ``own`` (which may
    give a shared one another default)."""
    mine = {name for name, _, _ in own}
    return tuple(p for p in AUTOPILOT_DEFAULTS
                 if p[0] not in COPTER_ONLY and p[0] not in mine) + own


# ArduPlane with the values of ArduPilot's plane.parm (what its SITL flies with).
PLANE_DEFAULTS = _common(
    ("AIRSPEED_CRUISE", 22, REAL32),
    ("AIRSPEED_MIN", 10, INT16),
    ("AIRSPEED_MAX", 30, INT16),
    ("ROLL_LIMIT_DEG", 65, REAL32),
    ("TECS_CLMB_MAX", 5, REAL32),
    ("TECS_SINK_MAX", 5, REAL32),
    ("TKOFF_ALT", 50, REAL32),
    ("TKOFF_DIST", 200, REAL32),
    ("WP_RADIUS", 50, INT16),
    ("WP_LOITER_RAD", 80, INT16),
    ("RTL_ALTITUDE", 100, REAL32),
    ("RTL_RADIUS", 0, INT16),
    ("LAND_FLARE_ALT", 3, REAL32),
    ("LAND_DISARMDELAY", 20, INT8),
    ("GRIP_ENABLE", 0, INT8),  # no gripper fitted
)
# Rover with the values of ArduPilot's rover.parm.
ROVER_DEFAULTS = _common(
    ("FRAME_CLASS", 1, INT8),
    ("CRUISE_SPEED", 5, REAL32),
    ("WP_SPEED", 5, REAL32),
    ("WP_RADIUS", 3, REAL32),
    ("TURN_RADIUS", 0.9, REAL32),
    ("ATC_ACCEL_MAX", 1, REAL32),
    ("ATC_TURN_MAX_G", 0.6, REAL32),
    ("RTL_SPEED", 0, REAL32),
    ("MIS_DONE_BEHAVE", 0, INT8),
    ("GRIP_ENABLE", 0, INT8),  # no gripper fitted
)

# The companion computer (component 191): one switch per TML skill, and its camera.
COMPANION_DEFAULTS: tuple[tuple[str, float, int], ...] = (
    ("AVOID_OBST", 0, INT8),
    ("RECOG_MARKERS", 0, INT8),
    ("RECOG_ARUCO", 0, INT8),
    ("SELF_LOCATE", 0, INT8),
    ("RECOG_ITEMS", 0, INT8),
    ("RECOG_BUCKETS", 0, INT8),
    ("CAM_HFOV", 70, REAL32),
    ("CAM_VFOV", 55, REAL32),
    ("CAM_RANGE", 40, REAL32),
    ("DET_RATE", 2, REAL32),
)


class UnknownParameter(KeyError):
    """A parameter name the table does not hold."""


class Params(dict[str, float]):
    """An ordered table of named float values with their MAVLink types.

    A dict, so that reading a value (the model reads a score of them every control
    step) is a plain dict lookup; writing goes through :meth:`set`, which rounds to the
    parameter's type and refuses names the table does not hold.
    """

    def __init__(
        self,
        defaults: tuple[tuple[str, float, int], ...],
        overrides: Mapping[str, float] | None = None,
    ) -> None:
        super().__init__((name, float(value)) for name, value, _ in defaults)
        self._types: dict[str, int] = {name: kind for name, _, kind in defaults}
        # Counts the writes: what is derived from the values (the model's limits) is kept
        # while it stands still.
        self.version = 0
        for name, value in (overrides or {}).items():
            self.set(name, value)

    def __setitem__(self, name: str, value: float) -> None:
        self.set(name, value)

    def index(self, name: str) -> int:
        """Position of ``name`` in the table (PARAM_VALUE.param_index)."""
        return list(self).index(name)

    def name_at(self, index: int) -> str | None:
        """The name at ``index``, or None when out of range."""
        names = list(self)
        return names[index] if 0 <= index < len(names) else None

    def type_of(self, name: str) -> int:
        """The MAV_PARAM_TYPE of ``name``."""
        return self._types[name]

    def set(self, name: str, value: float) -> float:
        """Store ``value`` rounded to the parameter's type; returns what was stored."""
        if name not in self:
            raise UnknownParameter(name)
        stored = float(value) if self._types[name] == REAL32 else float(round(value))
        self.version += 1
        super().__setitem__(name, stored)
        other = SAME_AS.get(name)
        if other is not None and other in self:
            super().__setitem__(other, stored)
        return stored


def param_value(params: Params, name: str) -> Any:
    """The PARAM_VALUE that reports ``name``."""
    return mavlink.MAVLink_param_value_message(
        name.encode(), params[name], params.type_of(name), len(params), params.index(name)
    )


def param_replies(params: Params, msg: Any) -> list[Any]:
    """Answer PARAM_REQUEST_LIST, PARAM_REQUEST_READ and PARAM_SET as ArduPilot does.

    Unknown names get no answer (the client times out); a set is echoed with the stored
    value. Other messages give an empty list.
    """
    kind = msg.get_type()
    if kind == "PARAM_REQUEST_LIST":
        return [param_value(params, name) for name in params]
    if kind == "PARAM_REQUEST_READ":
        name = params.name_at(msg.param_index) if msg.param_index >= 0 else _name(msg)
        return [param_value(params, name)] if name is not None and name in params else []
    if kind == "PARAM_SET":
        name = _name(msg)
        if name not in params:
            return []
        params.set(name, msg.param_value)
        return [param_value(params, name)]
    return []


def _name(msg: Any) -> str:
    raw = msg.param_id
    text = raw.decode(errors="replace") if isinstance(raw, bytes) else str(raw)
    return text.rstrip("\x00")
