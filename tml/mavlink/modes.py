"""Flight modes by name, chosen from what a vehicle says in its HEARTBEAT.

ArduPilot numbers its modes per vehicle kind (Copter, Plane, Rover, ...) and sends the
number as ``custom_mode``; PX4 packs a main mode and a sub mode into ``custom_mode``. The
tables are pymavlink's (``mavutil.mode_mapping_*`` and ``px4_map``), so they follow upstream.
A mode is set with MAV_CMD_DO_SET_MODE: param1 the base mode flags, param2 the custom (or
PX4 main) mode, param3 the PX4 sub mode.
"""

from __future__ import annotations

from tml.errors import VehicleError
from tml.mavlink.codec import mavlink, mavutil
from tml.mavlink.command import CommandLong

PX4 = mavlink.MAV_AUTOPILOT_PX4


def mode_names(vehicle_type: int, autopilot: int) -> list[str]:
    """The mode names a vehicle of this HEARTBEAT type and autopilot understands."""
    if autopilot == PX4:
        return list(mavutil.px4_map)
    table = mavutil.mode_mapping_bynumber(vehicle_type) or {}
    return list(table.values())


def mode_name(vehicle_type: int, autopilot: int, base_mode: int, custom_mode: int) -> str:
    """The name of the mode a HEARTBEAT reports (``Mode(<n>)`` when unknown)."""
    if autopilot == PX4:
        return mavutil.interpret_px4_mode(base_mode, custom_mode)
    table = mavutil.mode_mapping_bynumber(vehicle_type) or {}
    return table.get(custom_mode, f"Mode({custom_mode})")


def set_mode_command(vehicle_type: int, autopilot: int, name: str,
                     system_id: int | None = None) -> CommandLong:
    """The DO_SET_MODE command that selects mode ``name`` (case-insensitive)."""
    wanted = name.upper()
    if autopilot == PX4:
        if wanted in mavutil.px4_map:
            base, main, sub = mavutil.px4_map[wanted]
            return CommandLong(mavlink.MAV_CMD_DO_SET_MODE, base, main, sub)
    else:
        table = mavutil.mode_mapping_byname(vehicle_type) or {}
        if wanted in table:
            return CommandLong(mavlink.MAV_CMD_DO_SET_MODE,
                               mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, table[wanted])
    known = ", ".join(mode_names(vehicle_type, autopilot)) or "none known"
    raise VehicleError(f"no flight mode {name!r} for this vehicle (modes: {known})", system_id)
