"""The messages a simulated vehicle sends, built from its present state.

Each builder reads a :class:`Source` (the vehicle model, or any object with the same
attributes) and returns one pymavlink message; :data:`BUILDERS` maps the message ids that
stream or can be requested to their builders, so the model builds what
:mod:`sitl.streams` says is due with :func:`build`. A builder is written as the
arguments of its message's constructor (:class:`Builder`), so that :func:`fields` gives
the streamed telemetry as :class:`sitl.wire.Fields`, which the server encodes without
building a pymavlink message: the same bytes at a fraction of the cost. What the values mean follows
ArduCopter: GLOBAL_POSITION_INT has lat = lon = 0 until the GPS has a fix,
HOME_POSITION and GPS_GLOBAL_ORIGIN do not exist before the EKF sets its origin,
EXTENDED_SYS_STATE tells taking off from landing, MISSION_CURRENT carries the mission state.

A message built by the model is addressed with its sender (system, component) in its
header (:func:`stamp`), so that the server encodes each with the right source ids without
knowing which part of the vehicle produced it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.arming import ATTITUDE_AT
from sitl.modes import ModeTable
from sitl.physics import Battery
from sitl.wire import Fields
from tml.world import Home

M = mavlink
AUTOPILOT = M.MAV_COMP_ID_AUTOPILOT1  # 1
COMPANION = M.MAV_COMP_ID_ONBOARD_COMPUTER  # 191

EKF_STARTING = 0x400  # EKF_UNINITIALIZED, before the attitude is known
EKF_BEFORE_GPS = 0xA7  # attitude, velocities, vertical position, constant-position mode
EKF_WITH_GPS = 0x33F  # ... plus horizontal position, relative and absolute, and predicted
FLIGHT_SW_VERSION = (4 << 24) | (6 << 16) | (0 << 8) | 255  # 4.6.0 official
CAPABILITIES = (
    M.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | M.MAV_PROTOCOL_CAPABILITY_MISSION_INT | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
    | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | M.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
    | M.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
)
SENSORS = (
    M.MAV_SYS_STATUS_SENSOR_3D_GYRO | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | M.MAV_SYS_STATUS_SENSOR_3D_MAG | M.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | M.MAV_SYS_STATUS_SENSOR_GPS | M.MAV_SYS_STATUS_SENSOR_BATTERY
    | M.MAV_SYS_STATUS_PREARM_CHECK
)

Vector = tuple[float, float, float]
Arguments = tuple[Any, ...]


class Source(Protocol):
    """What the builders read from a vehicle (positions in metres north/east/up of origin)."""

    system_id: int
    mav_type: int  # HEARTBEAT type: QUADROTOR, FIXED_WING, GROUND_ROVER
    mode_table: ModeTable
    reports_landed_state: bool  # False: EXTENDED_SYS_STATE says UNDEFINED (Rover)
    time: float
    mode: str
    armed: bool
    landed: bool
    origin: Home
    home: Home
    battery: Battery
    roll: float  # radians
    pitch: float  # radians
    booted: bool  # past ArduCopter's boot ("ArduPilot Ready")
    origin_set: bool

    # Read-only: the model derives them from its state.
    @property
    def position(self) -> Vector: ...
    @property
    def velocity(self) -> Vector: ...
    @property
    def heading(self) -> float: ...  # degrees
    @property
    def gps_fixed(self) -> bool: ...
    @property
    def position_ok(self) -> bool: ...
    @property
    def prearm_ok(self) -> bool: ...  # the pre-arm checks pass (always when armed)
    @property
    def landing(self) -> bool: ...  # descending to touch down
    @property
    def in_failsafe(self) -> bool: ...

    def global_position(self) -> Vector: ...  # latitude, longitude, altitude (AMSL)
    def home_local(self) -> Vector: ...
    def gps_noise(self) -> float: ...  # degrees of receiver noise for this fix
    def mission_status(self) -> tuple[int, int, int]: ...  # seq, total, MISSION_STATE
    # GUIDED's target: (local position, global position) or (velocity, None), or None.
    def guided_target(self) -> tuple[Vector, Vector | None] | None: ...


class Builder:
    """A message built from a vehicle: its pymavlink class and the function giving the
    constructor's arguments (None when the message does not exist yet)."""

    def __init__(self, kind: Any, arguments: Callable[[Source], Arguments | None]) -> None:
        self.kind = kind
        self.arguments = arguments
        self.__doc__ = arguments.__doc__
        self.__name__ = arguments.__name__

    def __call__(self, v: Source) -> Any | None:
        """The message describing ``v`` now, or None."""
        args = self.arguments(v)
        return None if args is None else self.kind(*args)

    def fields(self, v: Source) -> Fields | None:
        """The message describing ``v`` now as its arguments, not built, or None."""
        args = self.arguments(v)
        return None if args is None else Fields(self.kind, args)


def builds(kind: Any) -> Callable[[Callable[[Source], Arguments | None]], Builder]:
    """Make a function giving the arguments of ``kind``'s constructor its builder."""
    def wrap(arguments: Callable[[Source], Arguments | None]) -> Builder:
        return Builder(kind, arguments)
    return wrap


def stamp(msg: Any, system_id: int, component_id: int) -> Any:
    """Set ``msg``'s source ids and return it."""
    msg._header.srcSystem = system_id
    msg._header.srcComponent = component_id
    return msg


def statustext(severity: int, text: str) -> Any:
    """A STATUSTEXT, cut to the 50 characters the field holds."""
    return M.MAVLink_statustext_message(severity, text.encode()[:50])


def targets(msg: Any, system_id: int, component_id: int) -> bool:
    """True when ``msg`` is for this system and component (or broadcast, or untargeted)."""
    system = getattr(msg, "target_system", 0)
    component = getattr(msg, "target_component", 0)
    return system in (0, system_id) and component in (0, component_id)


def _quaternion(heading: float) -> list[float]:
    yaw = math.radians(heading)
    return [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]


@builds(M.MAVLink_heartbeat_message)
def heartbeat(v: Source) -> Arguments:
    """HEARTBEAT: the vehicle's type, ArduPilot, the mode number; CRITICAL during a
    failsafe."""
    base = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
    if v.mode in v.mode_table.guided_flag:
        base |= M.MAV_MODE_FLAG_GUIDED_ENABLED
    if v.armed:
        base |= M.MAV_MODE_FLAG_SAFETY_ARMED
    state = M.MAV_STATE_BOOT if not v.booted else M.MAV_STATE_CRITICAL if v.in_failsafe else (
        M.MAV_STATE_ACTIVE if v.armed else M.MAV_STATE_STANDBY)
    return (v.mav_type, M.MAV_AUTOPILOT_ARDUPILOTMEGA, base, v.mode_table.numbers[v.mode],
            state, 3)


@builds(M.MAVLink_sys_status_message)
def sys_status(v: Source) -> Arguments:
    """SYS_STATUS: sensors (GPS unhealthy without a fix), the pre-arm checks (healthy when
    they pass, as ArduPilot reports them) and the battery."""
    healthy = SENSORS if v.gps_fixed else SENSORS & ~M.MAV_SYS_STATUS_SENSOR_GPS
    if not v.prearm_ok:
        healthy &= ~M.MAV_SYS_STATUS_PREARM_CHECK
    b = v.battery
    return (
        SENSORS, SENSORS, healthy, 200, round(b.voltage * 1000), round(b.current * 100),
        b.remaining, 0, 0, 0, 0, 0, 0)


@builds(M.MAVLink_battery_status_message)
def battery_status(v: Source) -> Arguments:
    """BATTERY_STATUS: voltage, current, consumed charge and percent left."""
    b = v.battery
    cells = [round(b.voltage * 1000)] + [65535] * 9
    return (
        0, M.MAV_BATTERY_FUNCTION_ALL, M.MAV_BATTERY_TYPE_LIPO, 32767, cells,
        round(b.current * 100), round(b.consumed_mah), -1, b.remaining)


@builds(M.MAVLink_gps_raw_int_message)
def gps_raw_int(v: Source) -> Arguments:
    """GPS_RAW_INT: no fix until the GPS locks, then a 3D fix with a little noise."""
    if not v.gps_fixed:  # ArduCopter SITL reports no GPS (fix type 0) before it locks
        return (int(v.time * 1e6), 0, 0, 0, 0, 9999, 9999, 0, 0, 0)
    lat, lon, alt = v.global_position()
    noise = v.gps_noise()
    vn, ve, _ = v.velocity
    return (
        int(v.time * 1e6), 3, round((lat + noise) * 1e7), round((lon + noise) * 1e7),
        round(alt * 1000), 121, 200, round(math.hypot(vn, ve) * 100),
        round(math.degrees(math.atan2(ve, vn)) % 360 * 100), 10)


@builds(M.MAVLink_global_position_int_message)
def global_position_int(v: Source) -> Arguments:
    """GLOBAL_POSITION_INT: lat = lon = 0 before the GPS fix, as ArduCopter."""
    u = v.position[2]
    vn, ve, vu = v.velocity
    lat = lon = 0
    alt = round((v.origin.altitude + u) * 1000)
    if v.gps_fixed:
        la, lo, al = v.global_position()
        lat, lon, alt = round(la * 1e7), round(lo * 1e7), round(al * 1000)
    home_up = v.home_local()[2]
    return (
        int(v.time * 1000), lat, lon, alt, round((u - home_up) * 1000),
        round(vn * 100), round(ve * 100), round(-vu * 100), round(v.heading * 100) % 36000)


@builds(M.MAVLink_local_position_ned_message)
def local_position_ned(v: Source) -> Arguments:
    """LOCAL_POSITION_NED from the boot position (the EKF origin)."""
    (n, e, u), (vn, ve, vu) = v.position, v.velocity
    return (int(v.time * 1000), n, e, -u, vn, ve, -vu)


@builds(M.MAVLink_attitude_message)
def attitude(v: Source) -> Arguments:
    """ATTITUDE: roll and pitch (non-zero only in a flip), yaw in (-pi, pi]."""
    yaw = math.radians(v.heading)
    yaw = yaw - 2 * math.pi if yaw > math.pi else yaw
    return (int(v.time * 1000), v.roll, v.pitch, yaw, 0.0, 0.0, 0.0)


@builds(M.MAVLink_vfr_hud_message)
def vfr_hud(v: Source) -> Arguments:
    """VFR_HUD: speeds, heading, throttle, altitude and climb."""
    vn, ve, vu = v.velocity
    ground = math.hypot(vn, ve)
    throttle = 0 if not v.armed else (15 if v.landed else 50)
    return (ground, ground, round(v.heading) % 360, throttle,
            v.origin.altitude + v.position[2], vu)


@builds(M.MAVLink_extended_sys_state_message)
def extended_sys_state(v: Source) -> Arguments:
    """EXTENDED_SYS_STATE: on the ground, taking off, in the air or landing (undefined for
    a vehicle that never leaves the ground, as Rover says)."""
    if not v.reports_landed_state:
        state = M.MAV_LANDED_STATE_UNDEFINED
    elif v.landed:
        state = M.MAV_LANDED_STATE_ON_GROUND
    elif v.landing:
        state = M.MAV_LANDED_STATE_LANDING
    elif v.velocity[2] > 0.2 and v.position[2] < 2.0:
        state = M.MAV_LANDED_STATE_TAKEOFF
    else:
        state = M.MAV_LANDED_STATE_IN_AIR
    return (M.MAV_VTOL_STATE_UNDEFINED, state)


@builds(M.MAVLink_mission_current_message)
def mission_current(v: Source) -> Arguments:
    """MISSION_CURRENT: the item in progress, the item count (home excluded), the state."""
    seq, total, state = v.mission_status()
    return (seq, total, state, 0)


@builds(M.MAVLink_ekf_status_report_message)
def ekf_status_report(v: Source) -> Arguments:
    """EKF_STATUS_REPORT: the horizontal position flags only once the EKF uses GPS."""
    flags = EKF_WITH_GPS if v.position_ok else EKF_BEFORE_GPS if v.origin_set or (
        v.time >= ATTITUDE_AT[0]) else EKF_STARTING
    return (flags, 0.01, 0.01, 0.01, 0.01, 0.0, 0.0)


@builds(M.MAVLink_home_position_message)
def home_position(v: Source) -> Arguments | None:
    """HOME_POSITION, or None before the EKF origin (ArduCopter has no home yet)."""
    if not v.origin_set:
        return None
    h = v.home
    x, y, z = v.home_local()
    return (
        round(h.latitude * 1e7), round(h.longitude * 1e7), round(h.altitude * 1000),
        x, y, -z, _quaternion(h.heading), 0.0, 0.0, 0.0, int(v.time * 1e6))


@builds(M.MAVLink_gps_global_origin_message)
def gps_global_origin(v: Source) -> Arguments | None:
    """GPS_GLOBAL_ORIGIN: the EKF origin (the boot position), None before it is set."""
    if not v.origin_set:
        return None
    o = v.origin
    return (
        round(o.latitude * 1e7), round(o.longitude * 1e7), round(o.altitude * 1000),
        int(v.time * 1e6))


# POSITION_TARGET_* type_masks as ArduCopter sends them (GCS_MAVLINK_Copter): the position
# alone (global, local) or the velocity alone (local); yaw and yaw rate always ignored.
TARGET_GLOBAL_POSITION = 65016
TARGET_LOCAL_POSITION = 3576
TARGET_LOCAL_VELOCITY = 3079


@builds(M.MAVLink_position_target_global_int_message)
def position_target_global_int(v: Source) -> Arguments | None:
    """POSITION_TARGET_GLOBAL_INT: GUIDED's point (frame GLOBAL, altitude AMSL), None
    under a velocity target, without a target or outside GUIDED."""
    target = v.guided_target()
    if target is None or target[1] is None:
        return None
    lat, lon, alt = target[1]
    return (int(v.time * 1000), M.MAV_FRAME_GLOBAL, TARGET_GLOBAL_POSITION,
            round(lat * 1e7), round(lon * 1e7), alt, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@builds(M.MAVLink_position_target_local_ned_message)
def position_target_local_ned(v: Source) -> Arguments | None:
    """POSITION_TARGET_LOCAL_NED: GUIDED's point (NED metres from the EKF origin) or its
    velocity target, None without a target or outside GUIDED."""
    target = v.guided_target()
    if target is None:
        return None
    (a, b, c), point = target
    if point is not None:
        mask, position, velocity = TARGET_LOCAL_POSITION, (a, b, -c), (0.0, 0.0, 0.0)
    else:
        mask, position, velocity = TARGET_LOCAL_VELOCITY, (0.0, 0.0, 0.0), (a, b, -c)
    return (int(v.time * 1000), M.MAV_FRAME_LOCAL_NED, mask, *position, *velocity,
            0.0, 0.0, 0.0, 0.0, 0.0)


@builds(M.MAVLink_system_time_message)
def system_time(v: Source) -> Arguments:
    """SYSTEM_TIME: time since boot (no UNIX time: the simulated GPS gives none)."""
    return (0, int(v.time * 1000))


@builds(M.MAVLink_autopilot_version_message)
def autopilot_version(v: Source) -> Arguments:
    """AUTOPILOT_VERSION: ArduPilot 4.6.0 with the mission, fence and rally capabilities."""
    return (
        CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0x1209, 0x5740,
        v.system_id)


def camera_feedback(v: Source, index: int) -> Any:
    """CAMERA_FEEDBACK for picture ``index`` (the first is 1) taken here and now, as
    ArduPilot's AP_Camera sends it for a camera without a feedback pin: camera 0, the
    vehicle's position (altitude AMSL and above home) and attitude in degrees, flags
    CAMERA_FEEDBACK_PHOTO, no completed captures counted; no UNIX time (0)."""
    lat, lon, alt = v.global_position()
    yaw = v.heading % 360.0
    return M.MAVLink_camera_feedback_message(
        0, 0, 0, index, round(lat * 1e7), round(lon * 1e7), alt, v.position[2] - v.home_local()[2],
        math.degrees(v.roll), math.degrees(v.pitch), yaw, 0.0, M.CAMERA_FEEDBACK_PHOTO, 0)


BUILDERS: dict[int, Builder] = {
    M.MAVLINK_MSG_ID_HEARTBEAT: heartbeat,
    M.MAVLINK_MSG_ID_SYS_STATUS: sys_status,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: battery_status,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: gps_raw_int,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: global_position_int,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: local_position_ned,
    M.MAVLINK_MSG_ID_ATTITUDE: attitude,
    M.MAVLINK_MSG_ID_VFR_HUD: vfr_hud,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: extended_sys_state,
    M.MAVLINK_MSG_ID_MISSION_CURRENT: mission_current,
    M.MAVLINK_MSG_ID_EKF_STATUS_REPORT: ekf_status_report,
    M.MAVLINK_MSG_ID_HOME_POSITION: home_position,
    M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: gps_global_origin,
    M.MAVLINK_MSG_ID_SYSTEM_TIME: system_time,
    M.MAVLINK_MSG_ID_POSITION_TARGET_GLOBAL_INT: position_target_global_int,
    M.MAVLINK_MSG_ID_POSITION_TARGET_LOCAL_NED: position_target_local_ned,
    M.MAVLINK_MSG_ID_AUTOPILOT_VERSION: autopilot_version,
}


def build(msg_id: int, v: Source) -> Any | None:
    """Message ``msg_id`` describing ``v`` now (None when unknown or not available yet)."""
    builder = BUILDERS.get(msg_id)
    return builder(v) if builder is not None else None


def fields(msg_id: int, v: Source) -> Fields | None:
    """Message ``msg_id`` describing ``v`` now as its arguments, not built (None when
    unknown or not available yet): what the server encodes for a stream."""
    builder = BUILDERS.get(msg_id)
    return builder.fields(v) if builder is not None else None
