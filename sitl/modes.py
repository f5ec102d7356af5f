"""ArduCopter's flight modes as the simulated vehicle knows them, and what each allows.

HEARTBEAT ``custom_mode`` carries the number; a ground station names it from the table
for a QUADROTOR with the ArduPilot autopilot (pymavlink's ``mode_mapping_acm``), so the
numbers here must be ArduCopter's. The simulator implements the subset below; the sets
say where the vehicle may arm, which modes need a position estimate to be entered, which
show the GUIDED flag in HEARTBEAT ``base_mode``, and where a FLIP may start.
"""

from __future__ import annotations

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
