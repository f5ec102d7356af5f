"""The flight modes of the simulated vehicles (ArduCopter, ArduPlane, Rover), and what each
allows.

HEARTBEAT ``custom_mode`` carries the number; a ground station names it from the table
for the HEARTBEAT type with the ArduPilot autopilot (pymavlink's ``mode_mapping_acm``,
``_apm``, ``_rover``), so the numbers here must be ArduPilot's. The simulator implements
the subsets below; the sets say where the vehicle may arm, which modes need a position
estimate to be entered, which show the GUIDED flag in HEARTBEAT ``base_mode``, and (for
the copter) where a FLIP may start. :class:`ModeTable` bundles one vehicle's.
"""

from __future__ import annotations

from dataclasses import dataclass

MODES = {
    "STABILIZE": 0, "ACRO": 1, "ALT_HOLD": 2, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6,
    "LAND": 9, "FLIP": 14, "BRAKE": 17,
}
MODE_NAMES = {number: name for name, number in MODES.items()}
ARMABLE = frozenset({"STABILIZE", "ACRO", "ALT_HOLD", "GUIDED", "LOITER"})
NEEDS_POSITION = frozenset({"AUTO", "GUIDED", "LOITER", "RTL", "BRAKE"})
GUIDED_FLAG_MODES = frozenset({"AUTO", "GUIDED", "RTL", "LAND", "LOITER", "BRAKE"})
# Where FLIP may be entered from, armed and flying: as ArduCopter (Mode::allows_flip), the
# modes whose throttle is the pilot's stick; never GUIDED or AUTO.
FLIP_FROM = frozenset({"ACRO", "STABILIZE", "ALT_HOLD"})
# Where the pilot's throttle must not be at zero for a FLIP (ArduCopter's ap.throttle_zero).
FLIP_NEEDS_THROTTLE = frozenset({"ACRO", "STABILIZE"})
PILOT_MODES = frozenset({"ACRO", "STABILIZE", "ALT_HOLD"})
"""Modes flown by the pilot's sticks (RC input or RC_CHANNELS_OVERRIDE), not by targets."""


@dataclass(frozen=True)
class ModeTable:
    """One vehicle kind's flight modes: ``numbers`` (name -> HEARTBEAT ``custom_mode``, as
    pymavlink's table for the kind's HEARTBEAT type), where it may arm, which modes need a
    position estimate, and which show the GUIDED flag in HEARTBEAT ``base_mode``."""

    numbers: dict[str, int]
    armable: frozenset[str]
    needs_position: frozenset[str]
    guided_flag: frozenset[str]

    @property
    def names(self) -> dict[int, str]:
        """``custom_mode`` -> name."""
        return {number: name for name, number in self.numbers.items()}


COPTER = ModeTable(MODES, ARMABLE, NEEDS_POSITION, GUIDED_FLAG_MODES)
# ArduPlane (HEARTBEAT type FIXED_WING): arms in any of these; GUIDED, AUTO, RTL, LOITER,
# CIRCLE and TAKEOFF navigate, so they need the position (Plane's base_mode sets the
# GUIDED flag for them).
_PLANE_MODES = {"MANUAL": 0, "CIRCLE": 1, "STABILIZE": 2, "FBWA": 5, "AUTO": 10, "RTL": 11,
                "LOITER": 12, "TAKEOFF": 13, "GUIDED": 15}
_PLANE_NAVIGATING = frozenset({"CIRCLE", "AUTO", "RTL", "LOITER", "TAKEOFF", "GUIDED"})
PLANE = ModeTable(_PLANE_MODES, frozenset(_PLANE_MODES), _PLANE_NAVIGATING, _PLANE_NAVIGATING)
# ArduPilot Rover (HEARTBEAT type GROUND_ROVER).
_ROVER_MODES = {"MANUAL": 0, "ACRO": 1, "STEERING": 3, "HOLD": 4, "LOITER": 5, "AUTO": 10,
                "RTL": 11, "SMART_RTL": 12, "GUIDED": 15}
_ROVER_NAVIGATING = frozenset({"LOITER", "AUTO", "RTL", "SMART_RTL", "GUIDED"})
ROVER = ModeTable(_ROVER_MODES, frozenset(_ROVER_MODES), _ROVER_NAVIGATING,
                  _ROVER_NAVIGATING | {"HOLD"})
