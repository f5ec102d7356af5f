"""Translation between tml's plain MAVLink data and pymavlink messages.

The only module of tml that builds or parses pymavlink message objects; the protocol state
machines (``mission``, ``command``) and the telemetry tracker work on plain dataclasses or
read attributes. MAVLink 2 is set before pymavlink's ``mavutil`` is first imported, and the
ardupilotmega dialect (a superset of common) is used throughout.
"""

from __future__ import annotations

import os

# mavutil picks the protocol version when first imported: MAVLink 2, explicitly.
os.environ.setdefault("MAVLINK20", "1")

import importlib.util
import logging
import sys


def _imported_on_first_use(name: str) -> None:
    """Put module ``name`` in place to be executed when an attribute of it is first read
    (:class:`importlib.util.LazyLoader`), not when it is imported."""
    spec = importlib.util.find_spec(name)
    if name in sys.modules or spec is None or spec.loader is None:
        return
    spec.loader = importlib.util.LazyLoader(spec.loader)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    # Bound in its package as an import binds it: ``from package import name`` then takes
    # it as it is (looked up in sys.modules, its __spec__ would be read, which loads it).
    package, _, child = name.rpartition(".")
    setattr(sys.modules[package], child, module)


# mavutil imports mavexpression (its log-expression evaluator, which tml never calls) and,
# through it, numpy: a third of the start-up of every tml process that flies or commands.
_imported_on_first_use("pymavlink.mavexpression")

from pymavlink import mavutil  # noqa: E402 (after the lazy module is in place)
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

from tml.mavlink.command import (  # noqa: E402
    Command,
    CommandAck,
    CommandInt,
    CommandLong,
    Heartbeat,
)
from tml.mavlink.mission import (  # noqa: E402
    MissionAck,
    MissionClearAll,
    MissionCount,
    MissionItem,
    MissionMessage,
    MissionRequest,
    MissionRequestList,
)

__all__ = ["decode", "encode", "mavlink", "mavutil"]

GCS_SYSTEM_ID = 255
"""The system id tml uses on the wire, as ground stations customarily do."""
GCS_COMPONENT_ID = mavlink.MAV_COMP_ID_MISSIONPLANNER

PYMAVLINK_LOG = logging.getLogger("tml.mavlink.pymavlink")
"""Where pymavlink's own prints go instead of the terminal."""


def _pymavlink_print(*values: object, **_: object) -> None:
    # pymavlink prints what its sockets do ("[Errno 111] Connection refused sleeping", "EOF
    # on TCP socket", "Attempting reconnect") to standard output. tml says itself, once,
    # what it waits for and what failed; those lines go to the log for debugging.
    PYMAVLINK_LOG.debug(" ".join(str(value) for value in values))


mavutil.print = _pymavlink_print  # the module's name print, found before the builtin

# Message objects are built with the encode methods of an encoder that never writes:
# pymavlink stamps sequence numbers and signatures when the link's own encoder sends them.
_BUILD = mavlink.MAVLink(None)

Plain = MissionMessage | Command | CommandAck | Heartbeat


def encode(msg: Plain, target_system: int, target_component: int) -> mavlink.MAVLink_message:
    """The pymavlink message for plain ``msg`` addressed to one system and component."""
    ts, tc = target_system, target_component
    match msg:
        case MissionItem():
            return _BUILD.mission_item_int_encode(
                ts, tc, msg.seq, msg.frame, msg.command, msg.current, msg.autocontinue,
                msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z,
                msg.mission_type)
        case MissionCount():
            return _BUILD.mission_count_encode(ts, tc, msg.count, msg.mission_type)
        case MissionRequest(legacy=True):
            return _BUILD.mission_request_encode(ts, tc, msg.seq, msg.mission_type)
        case MissionRequest():
            return _BUILD.mission_request_int_encode(ts, tc, msg.seq, msg.mission_type)
        case MissionRequestList():
            return _BUILD.mission_request_list_encode(ts, tc, msg.mission_type)
        case MissionClearAll():
            return _BUILD.mission_clear_all_encode(ts, tc, msg.mission_type)
        case MissionAck():
            return _BUILD.mission_ack_encode(ts, tc, msg.result, msg.mission_type)
        case CommandLong():
            return _BUILD.command_long_encode(
                ts, tc, msg.command, msg.confirmation, msg.param1, msg.param2, msg.param3,
                msg.param4, msg.param5, msg.param6, msg.param7)
        case CommandInt():
            return _BUILD.command_int_encode(
                ts, tc, msg.frame, msg.command, msg.current, msg.autocontinue, msg.param1,
                msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z)
        case CommandAck():
            return _BUILD.command_ack_encode(msg.command, msg.result, msg.progress, 0, ts, tc)
    raise TypeError(f"cannot encode {msg!r}")


def decode(msg: mavlink.MAVLink_message) -> Plain | None:
    """The plain form of a mission-protocol message, COMMAND_ACK or HEARTBEAT; else None."""
    kind = msg.get_type()
    if kind == "HEARTBEAT":
        return Heartbeat(msg.type, msg.autopilot, msg.base_mode, msg.custom_mode, msg.get_seq())
    if kind == "MISSION_ITEM_INT":
        return _item(msg, msg.x, msg.y)
    if kind == "MISSION_ITEM":
        # The legacy float form: global coordinates come as degrees.
        scale = 1e7 if msg.frame in _GLOBAL_FRAMES else 1
        return _item(msg, round(msg.x * scale), round(msg.y * scale))
    if kind == "MISSION_COUNT":
        return MissionCount(msg.count, msg.mission_type)
    if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
        return MissionRequest(msg.seq, msg.mission_type, legacy=kind == "MISSION_REQUEST")
    if kind == "MISSION_REQUEST_LIST":
        return MissionRequestList(msg.mission_type)
    if kind == "MISSION_CLEAR_ALL":
        return MissionClearAll(msg.mission_type)
    if kind == "MISSION_ACK":
        return MissionAck(msg.type, msg.mission_type)
    if kind == "COMMAND_ACK":
        return CommandAck(msg.command, msg.result, msg.progress, msg.get_seq())
    return None


_GLOBAL_FRAMES = frozenset({
    mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_INT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT, mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
})


def _item(msg: mavlink.MAVLink_message, x: int, y: int) -> MissionItem:
    return MissionItem(
        seq=msg.seq, frame=msg.frame, command=msg.command, current=msg.current,
        autocontinue=msg.autocontinue, param1=msg.param1, param2=msg.param2,
        param3=msg.param3, param4=msg.param4, x=int(x), y=int(y), z=msg.z,
        mission_type=msg.mission_type)


def enum_name(enum: str, value: int) -> str:
    """The name of ``value`` in MAVLink enum ``enum`` (``<enum>_<value>`` if undefined)."""
    entry = mavlink.enums.get(enum, {}).get(value)
    return entry.name if entry is not None else f"{enum}_{value}"


def command_name(command: int) -> str:
    """The MAV_CMD name of a command number, e.g. 22 -> ``MAV_CMD_NAV_TAKEOFF``."""
    return enum_name("MAV_CMD", command)


def command_text(command: int) -> str:
    """A command number as a person reads it: its name and number,
    ``MAV_CMD_CONDITION_DISTANCE (114)``; ``MAV_CMD 116 (unknown)`` for a number no
    MAV_CMD of ArduPilot's dialect has."""
    entry = mavlink.enums["MAV_CMD"].get(command)
    return f"{entry.name} ({command})" if entry is not None else f"MAV_CMD {command} (unknown)"


def gcs_heartbeat() -> mavlink.MAVLink_message:
    """The HEARTBEAT a ground station sends (type GCS, no autopilot)."""
    return _BUILD.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                   mavlink.MAV_STATE_ACTIVE)


def request_data_stream(target_system: int, target_component: int, rate_hz: int
                        ) -> mavlink.MAVLink_message:
    """REQUEST_DATA_STREAM for all streams, the fallback for SET_MESSAGE_INTERVAL."""
    return _BUILD.request_data_stream_encode(target_system, target_component,
                                             mavlink.MAV_DATA_STREAM_ALL, rate_hz, 1)


def position_target(target_system: int, target_component: int, lat_e7: int, lon_e7: int,
                    alt: float, yaw: float | None = None) -> mavlink.MAVLink_message:
    """SET_POSITION_TARGET_GLOBAL_INT for a position (relative altitude), GUIDED mode."""
    return _BUILD.set_position_target_global_int_encode(
        0, target_system, target_component, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        _target_mask(_IGNORE_VELOCITY, yaw),
        lat_e7, lon_e7, alt, 0, 0, 0, 0, 0, 0, yaw or 0.0, 0)


def stop_target(target_system: int, target_component: int, yaw: float | None = None
                ) -> mavlink.MAVLink_message:
    """SET_POSITION_TARGET_LOCAL_NED for a velocity of zero, GUIDED mode: brake and hold.

    ArduCopter starts its velocity controller from the velocity the vehicle has and shapes
    it to zero within its acceleration and jerk limits, then holds where that ends, as its
    own ``ModeGuided::hold_position`` does (a position target at the point where it was
    would be flown past and back to)."""
    return _BUILD.set_position_target_local_ned_encode(
        0, target_system, target_component, mavlink.MAV_FRAME_LOCAL_NED,
        _target_mask(_IGNORE_POSITION, yaw), 0, 0, 0, 0, 0, 0, 0, 0, 0, yaw or 0.0, 0)


_IGNORE_POSITION = (mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE
                    | mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE
                    | mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE)
_IGNORE_VELOCITY = (mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE
                    | mavlink.POSITION_TARGET_TYPEMASK_VY_IGNORE
                    | mavlink.POSITION_TARGET_TYPEMASK_VZ_IGNORE)


def _target_mask(ignored: int, yaw: float | None) -> int:
    """A position target's type mask: ``ignored`` besides the acceleration and the yaw
    rate, and the yaw when there is none."""
    mask: int = (ignored | mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
                 | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE
                 | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE
                 | mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE)
    if yaw is None:
        mask |= mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
    return mask


RC_IGNORE = 65535
"""RC_CHANNELS_OVERRIDE channels 1-8: leave the channel as it is (UINT16_MAX)."""
RC_RELEASE = 0
"""RC_CHANNELS_OVERRIDE channels 1-8: give the channel back to the radio."""


def rc_override(target_system: int, target_component: int, sticks: tuple[int, int, int, int]
                ) -> mavlink.MAVLink_message:
    """RC_CHANNELS_OVERRIDE of channels 1-4 (roll, pitch, throttle, yaw: PWM microseconds, or
    RC_RELEASE each); channels 5-8 are left alone, 9-18 ignored (0, as MAVLink says)."""
    return _BUILD.rc_channels_override_encode(target_system, target_component, *sticks,
                                              RC_IGNORE, RC_IGNORE, RC_IGNORE, RC_IGNORE)
