"""How ArduCopter stores mission, fence and rally items, and so what it reads back.

ArduPilot keeps a mission item in 15 bytes (``AP_Mission::Mission_Command``): the command,
a 16-bit ``p1``, and either a *location* (latitude and longitude in degrees * 1e7, the
altitude in whole centimetres, and flags: relative or terrain altitude, counter-clockwise,
exit on the tangent, two bits of the command's own) or a record of C fields of the
command's own. An upload converts the MISSION_ITEM_INT into that form
(``AP_Mission::mavlink_int_to_mission_cmd``) and a download converts it back
(``mission_cmd_to_mavlink_int``); what does not fit is lost. :func:`store` does both in
one go: it returns the item as the vehicle will read it back, or the MAV_MISSION_RESULT
that refuses it. The simulator stores that form, so its downloads are ArduCopter's and its
AUTO executor flies what ArduCopter flies (a hold of 2.5 s is held 2 s, a loiter radius of
8.4 m is circled at 8 m).

What is kept, for the commands the simulator knows (ArduCopter's build):

- a position command keeps x, y, the altitude in whole centimetres (float32 arithmetic:
  12.345 m reads back as 12.34 m) and its frame as GLOBAL (0; MAV_FRAME_MISSION and
  GLOBAL_INT too), GLOBAL_RELATIVE_ALT (3) or GLOBAL_TERRAIN_ALT (10); any other frame is
  UNSUPPORTED_FRAME. A command without a position reads back frame 0 and x = y = z = 0;
- NAV_WAYPOINT, NAV_TAKEOFF, NAV_LAND, NAV_SPLINE_WAYPOINT, DO_SET_HOME, DO_SET_ROI ... keep
  param1 in ``p1`` (a whole number 0..65535) and nothing else, except NAV_LAND's param4,
  kept as its sign (-1 or 1, NaN reading 1);
- NAV_LOITER_TURNS keeps whole turns up to 255 (below 1, in 256ths of a turn) and the
  radius in whole metres up to 255 m, then in tens of metres up to 2550 m, its sign being
  the direction; NAV_LOITER_TIME keeps the seconds and only the radius's sign (reading back
  1 or -1); NAV_LOITER_UNLIM keeps the radius in whole metres;
- the other commands keep their params in the C types of their records (CONDITION_YAW:
  float angle and rate, int8 direction, uint8 relative; DO_CHANGE_SPEED: uint8 type, float
  speed and throttle; IMAGE_START_CAPTURE: uint8, float, uint16, uint16 ...);
- ``autocontinue`` always reads back 1.

Refused as ArduPilot refuses them: an unknown command (UNSUPPORTED), a NaN param where the
command takes none (only param4 of NAV_WAYPOINT, NAV_LOITER_UNLIM, NAV_LAND, NAV_TAKEOFF and
NAV_VTOL_TAKEOFF may be NaN) or an infinite one (INVALID_PARAMn), a latitude or longitude
out of range (INVALID_PARAM5_X / 6_Y), an altitude of 83 km or more (INVALID_PARAM7).

Fences (AC_PolyFence_loader) keep x, y and param1 (a polygon's vertex count as a uint8, a
circle's radius as a float) and read back frame 0 without altitude; rally points (AP_Rally)
keep x, y, the frame's family and the altitude in whole metres. Neither keeps
``autocontinue`` (reads 0).

Float-to-integer conversions are C's as ArduPilot SITL does them on x86-64: truncated toward
zero to a 32-bit integer, then cut to the field's width (a hold of -1.5 s becomes 65535). A
value beyond 32 bits stops ArduPilot SITL with a floating-point exception; here it becomes
x86's "integer indefinite", 0x80000000, cut likewise.

This is the simulator's own reading of ArduPilot, kept apart from tml's read-back rules
(tml.mavlink.mission) on purpose: the simulator plays the vehicle against which tml's rules
are tested, and a mistake shared by both would go unseen.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.results import MissionResult

MISSION, FENCE, RALLY = 0, 1, 2

Params = tuple[float, float, float, float]


@dataclass(frozen=True)
class Stored:
    """An item as the vehicle reads it back (the fields that storage changes)."""

    frame: int
    params: Params
    x: int
    y: int
    z: float
    autocontinue: int


def f32(value: float) -> float:
    """``value`` rounded to a C float, as MAVLink carries and ArduPilot computes it."""
    rounded: float = struct.unpack("<f", struct.pack("<f", value))[0]
    return rounded


def c_integer(value: float, bits: int, signed: bool = False) -> int:
    """A float assigned to a C integer field of ``bits`` bits, as x86-64 does it."""
    whole = math.trunc(value) if math.isfinite(value) else -2**31
    if not -2**31 <= whole < 2**31:
        whole = -2**31  # the "integer indefinite" of cvttss2si
    whole &= (1 << bits) - 1
    if signed and whole >= 1 << (bits - 1):
        whole -= 1 << bits
    return whole


# --- the 15-byte command ------------------------------------------------------------------


@dataclass
class _Command:
    """The parts of AP_Mission::Mission_Command the conversions fill in."""

    id: int
    p1: int = 0
    content: dict[int | str, float] = field(default_factory=dict)  # param index, "x", "y"
    lat: int = 0
    lng: int = 0
    alt: int = 0  # cm
    relative: bool = False
    terrain: bool = False
    ccw: bool = False
    xtrack: bool = False
    turns_in_256ths: bool = False  # type-specific bit 1 of NAV_LOITER_TURNS
    radius_in_tens: bool = False  # type-specific bit 0 of NAV_LOITER_TURNS


def _p1(value: float) -> int:
    return c_integer(value, 16)


# Each command's conversion: (into the command, back to params 1-4). The commands with a
# position also keep the location (POSITION below).
Into = Callable[[_Command, Params], None]
Back = Callable[[_Command], Params]


def _param1_in_p1() -> tuple[Into, Back]:
    def into(cmd: _Command, p: Params) -> None:
        cmd.p1 = _p1(p[0])

    return into, lambda cmd: (float(cmd.p1), 0.0, 0.0, 0.0)


def _nothing() -> tuple[Into, Back]:
    return (lambda cmd, p: None), (lambda cmd: (0.0, 0.0, 0.0, 0.0))


def _record(*fields: tuple[int, Callable[[float], float]]) -> tuple[Into, Back]:
    """A record of C fields, each from a param (0-3)."""
    def into(cmd: _Command, p: Params) -> None:
        for index, convert in fields:
            cmd.content[index] = convert(p[index])

    def back(cmd: _Command) -> Params:
        params = [cmd.content.get(i, 0.0) for i in range(4)]
        return params[0], params[1], params[2], params[3]

    return into, back


def _float(value: float) -> float:
    return f32(value)


def _int(bits: int, signed: bool = False) -> Callable[[float], float]:
    return lambda value: float(c_integer(value, bits, signed))


_U8, _I8, _U16, _I16 = _int(8), _int(8, True), _int(16), _int(16, True)


def _loiter_unlimited() -> tuple[Into, Back]:
    def into(cmd: _Command, p: Params) -> None:
        cmd.p1 = _p1(abs(p[2]))
        cmd.ccw = p[2] < 0

    return into, lambda cmd: (0.0, 0.0, -float(cmd.p1) if cmd.ccw else float(cmd.p1), 0.0)


def _loiter_turns() -> tuple[Into, Back]:
    def into(cmd: _Command, p: Params) -> None:
        turns = p[0]
        if 0 < turns < 1:
            turns *= 256.0
            cmd.turns_in_256ths = True
        radius = abs(p[2])
        if radius <= 255:
            metres = c_integer(radius, 8)
        else:
            metres = c_integer(min(255.0, radius * 0.1), 8)
            cmd.radius_in_tens = True
        cmd.p1 = _p1(min(255.0, turns)) | (metres << 8)
        cmd.ccw, cmd.xtrack = p[2] < 0, p[3] > 0

    def back(cmd: _Command) -> Params:
        turns, radius = float(cmd.p1 & 0xFF), float(cmd.p1 >> 8)
        if cmd.ccw:
            radius = -radius
        if cmd.radius_in_tens:
            radius *= 10
        if cmd.turns_in_256ths:
            turns /= 256.0
        return turns, 0.0, radius, float(cmd.xtrack)

    return into, back


def _loiter_time() -> tuple[Into, Back]:
    def into(cmd: _Command, p: Params) -> None:
        cmd.p1 = _p1(p[0])
        cmd.ccw, cmd.xtrack = p[2] < 0, p[3] > 0

    return into, lambda cmd: (float(cmd.p1), 0.0, -1.0 if cmd.ccw else 1.0, float(cmd.xtrack))


def _land() -> tuple[Into, Back]:
    def into(cmd: _Command, p: Params) -> None:
        cmd.p1 = _p1(p[0])
        if not math.isnan(p[3]):
            cmd.ccw = p[3] <= -1.1920929e-07  # is_negative(): below -FLT_EPSILON

    return into, lambda cmd: (float(cmd.p1), 0.0, 0.0, -1.0 if cmd.ccw else 1.0)


def _loiter_to_altitude() -> tuple[Into, Back]:
    def into(cmd: _Command, p: Params) -> None:
        cmd.p1 = _p1(abs(p[1]))
        cmd.ccw, cmd.xtrack = p[1] < 0, p[3] > 0

    return into, lambda cmd: (0.0, -float(cmd.p1) if cmd.ccw else float(cmd.p1), 0.0,
                              float(cmd.xtrack))


M = mavlink
CONVERSIONS: dict[int, tuple[Into, Back]] = {
    M.MAV_CMD_NAV_WAYPOINT: _param1_in_p1(),  # hold s (Copter)
    M.MAV_CMD_NAV_LOITER_UNLIM: _loiter_unlimited(),
    M.MAV_CMD_NAV_LOITER_TURNS: _loiter_turns(),
    M.MAV_CMD_NAV_LOITER_TIME: _loiter_time(),
    M.MAV_CMD_NAV_RETURN_TO_LAUNCH: _nothing(),
    M.MAV_CMD_NAV_LAND: _land(),
    M.MAV_CMD_NAV_TAKEOFF: _param1_in_p1(),
    M.MAV_CMD_NAV_CONTINUE_AND_CHANGE_ALT: _param1_in_p1(),
    M.MAV_CMD_NAV_LOITER_TO_ALT: _loiter_to_altitude(),
    M.MAV_CMD_NAV_SPLINE_WAYPOINT: _param1_in_p1(),
    M.MAV_CMD_NAV_VTOL_TAKEOFF: _nothing(),
    M.MAV_CMD_NAV_VTOL_LAND: _param1_in_p1(),
    M.MAV_CMD_NAV_GUIDED_ENABLE: _param1_in_p1(),
    M.MAV_CMD_NAV_DELAY: _record((0, _float), (1, _I8), (2, _I8), (3, _I8)),
    M.MAV_CMD_CONDITION_DELAY: _record((0, _float)),
    M.MAV_CMD_CONDITION_DISTANCE: _record((0, _float)),
    M.MAV_CMD_CONDITION_YAW: _record((0, _float), (1, _float), (2, _I8), (3, _U8)),
    M.MAV_CMD_DO_JUMP: _record((0, _U16), (1, _I16)),
    M.MAV_CMD_DO_CHANGE_SPEED: _record((0, _U8), (1, _float), (2, _float)),
    M.MAV_CMD_DO_SET_HOME: _param1_in_p1(),
    M.MAV_CMD_DO_SET_RELAY: _record((0, _U8), (1, _U8)),
    M.MAV_CMD_DO_SET_SERVO: _record((0, _U8), (1, _U16)),
    M.MAV_CMD_DO_LAND_START: _nothing(),
    M.MAV_CMD_DO_SET_ROI_LOCATION: _param1_in_p1(),
    M.MAV_CMD_DO_SET_ROI_NONE: _param1_in_p1(),
    M.MAV_CMD_DO_SET_ROI: _param1_in_p1(),
    M.MAV_CMD_DO_DIGICAM_CONTROL: _record((0, _U8), (1, _U8), (2, _I8), (3, _U8)),
    M.MAV_CMD_DO_MOUNT_CONTROL: _record((0, _float), (1, _float), (2, _float)),
    M.MAV_CMD_DO_SET_CAM_TRIGG_DIST: _record((0, _float), (2, _U8)),
    M.MAV_CMD_DO_GRIPPER: _record((0, _U8), (1, _U8)),
    M.MAV_CMD_IMAGE_START_CAPTURE: _record((0, _U8), (1, _float), (2, _U16), (3, _U16)),
    M.MAV_CMD_IMAGE_STOP_CAPTURE: _param1_in_p1(),
}
POSITION = frozenset({
    M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LOITER_UNLIM, M.MAV_CMD_NAV_LOITER_TURNS,
    M.MAV_CMD_NAV_LOITER_TIME, M.MAV_CMD_NAV_LAND, M.MAV_CMD_NAV_TAKEOFF,
    M.MAV_CMD_NAV_CONTINUE_AND_CHANGE_ALT, M.MAV_CMD_NAV_LOITER_TO_ALT,
    M.MAV_CMD_NAV_SPLINE_WAYPOINT, M.MAV_CMD_NAV_GUIDED_ENABLE, M.MAV_CMD_DO_SET_HOME,
    M.MAV_CMD_DO_LAND_START, M.MAV_CMD_DO_SET_ROI_LOCATION, M.MAV_CMD_DO_SET_ROI,
    M.MAV_CMD_NAV_VTOL_TAKEOFF, M.MAV_CMD_NAV_VTOL_LAND,
})
"""The commands ArduPilot stores with a location (AP_Mission::stored_in_location)."""
NAN_PARAM4 = frozenset({M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LOITER_UNLIM, M.MAV_CMD_NAV_LAND,
                        M.MAV_CMD_NAV_TAKEOFF, M.MAV_CMD_NAV_VTOL_TAKEOFF})
# Frames of a position: relative altitude, terrain altitude.
_POSITION_FRAMES = {
    M.MAV_FRAME_MISSION: (False, False), M.MAV_FRAME_GLOBAL: (False, False),
    M.MAV_FRAME_GLOBAL_INT: (False, False), M.MAV_FRAME_GLOBAL_RELATIVE_ALT: (True, False),
    M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: (True, False),
    M.MAV_FRAME_GLOBAL_TERRAIN_ALT: (True, True), M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: (True, True),
}
FENCE_FRAMES = frozenset({M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT,
                          M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                          M.MAV_FRAME_GLOBAL_TERRAIN_ALT, M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT})
RALLY_FRAMES = frozenset({M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT,
                          M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT})
ALTITUDE_LIMIT = 83000.0  # m: LOCATION_ALT_MAX_M, what 24 bits of centimetres hold


def _latitude_ok(lat: float) -> bool:
    return abs(lat) <= 90e7


def _longitude_ok(lng: float) -> bool:
    return abs(lng) <= 180e7


def int_coordinates(command: int, x: float, y: float) -> tuple[int, int] | MissionResult:
    """x and y of a legacy MISSION_ITEM as MISSION_ITEM_INT carries them, or the refusal.

    A position's degrees are scaled by 1e7 in float32 arithmetic, as ArduPilot does: the
    legacy message loses up to a few decimetres of position (float32 holds 24 bits).
    """
    if command not in POSITION:
        return c_integer(f32(x), 32, True), c_integer(f32(y), 32, True)
    if not _latitude_ok(f32(x) * 1e7):
        return MissionResult.INVALID_PARAM5_X
    if not _longitude_ok(f32(y) * 1e7):
        return MissionResult.INVALID_PARAM6_Y
    return (c_integer(f32(f32(x) * f32(1e7)), 32, True),
            c_integer(f32(f32(y) * f32(1e7)), 32, True))


def store(mission_type: int, command: int, frame: int, params: Params, x: int, y: int,
          z: float) -> Stored | MissionResult:
    """What the vehicle reads back of an item, or the MAV_MISSION_RESULT refusing it."""
    p: Params = (f32(params[0]), f32(params[1]), f32(params[2]), f32(params[3]))
    if mission_type == FENCE:
        return _store_fence(command, frame, p, x, y)
    if mission_type == RALLY:
        return _store_rally(command, frame, x, y, f32(z))
    return _store_mission(command, frame, p, x, y, f32(z))


def _store_mission(command: int, frame: int, p: Params, x: int, y: int, z: float
                   ) -> Stored | MissionResult:
    for index, value in enumerate(p):
        nan_allowed = (index == 3 and command in NAN_PARAM4) or (
            command == M.MAV_CMD_NAV_VTOL_LAND and index >= 2)
        if math.isinf(value) or (math.isnan(value) and not nan_allowed):
            return MissionResult.invalid_param(index)
    conversion = CONVERSIONS.get(command)
    if conversion is None:
        return MissionResult.UNSUPPORTED
    into, back = conversion
    cmd = _Command(command)
    into(cmd, p)
    if command in POSITION:
        if not _latitude_ok(x):
            return MissionResult.INVALID_PARAM5_X
        if not _longitude_ok(y):
            return MissionResult.INVALID_PARAM6_Y
        if math.isnan(z) or abs(z) >= ALTITUDE_LIMIT:
            return MissionResult.INVALID_PARAM7
        if frame not in _POSITION_FRAMES:
            return MissionResult.UNSUPPORTED_FRAME
        cmd.lat, cmd.lng = x, y
        cmd.alt = c_integer(f32(z * 100.0), 32, True)
        cmd.relative, cmd.terrain = _POSITION_FRAMES[frame]
    elif command == M.MAV_CMD_DO_DIGICAM_CONTROL:
        cmd.content["x"], cmd.content["y"] = c_integer(x, 8), c_integer(y, 8)
    return _read_back(cmd, back)


def _read_back(cmd: _Command, back: Back) -> Stored:
    params = back(cmd)
    if cmd.id in POSITION:
        frame = (M.MAV_FRAME_GLOBAL_TERRAIN_ALT if cmd.terrain else
                 M.MAV_FRAME_GLOBAL_RELATIVE_ALT if cmd.relative else M.MAV_FRAME_GLOBAL)
        return Stored(frame, params, cmd.lat, cmd.lng, f32(f32(cmd.alt) * f32(0.01)), 1)
    z = float(M.MAV_MOUNT_MODE_MAVLINK_TARGETING) if cmd.id == M.MAV_CMD_DO_MOUNT_CONTROL else 0.0
    return Stored(M.MAV_FRAME_GLOBAL, params, int(cmd.content.get("x", 0)),
                  int(cmd.content.get("y", 0)), z, 1)


def _store_fence(command: int, frame: int, p: Params, x: int, y: int) -> Stored | MissionResult:
    if frame not in FENCE_FRAMES:
        return MissionResult.UNSUPPORTED_FRAME
    if command in (M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                   M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION):
        param1 = float(c_integer(p[0], 8))  # the vertex count
    elif command in (M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, M.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION):
        param1 = p[0]  # the radius
    elif command == M.MAV_CMD_NAV_FENCE_RETURN_POINT:
        param1 = 0.0
    else:
        return MissionResult.UNSUPPORTED
    return Stored(M.MAV_FRAME_GLOBAL, (param1, 0.0, 0.0, 0.0), x, y, 0.0, 0)


def _store_rally(command: int, frame: int, x: int, y: int, z: float) -> Stored | MissionResult:
    if command != M.MAV_CMD_NAV_RALLY_POINT:
        return MissionResult.UNSUPPORTED
    if frame not in RALLY_FRAMES:
        return MissionResult.UNSUPPORTED_FRAME
    if not _latitude_ok(x):
        return MissionResult.INVALID_PARAM5_X
    if not _longitude_ok(y):
        return MissionResult.INVALID_PARAM6_Y
    if not -32768 <= z <= 32767:
        return MissionResult.INVALID_PARAM7
    relative = frame in (M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
    return Stored(M.MAV_FRAME_GLOBAL_RELATIVE_ALT if relative else M.MAV_FRAME_GLOBAL,
                  (0.0, 0.0, 0.0, 0.0), x, y, float(c_integer(z, 16, True)), 0)
