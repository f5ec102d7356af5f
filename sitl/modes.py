"""ArduCopter's flight modes as the simulated vehicle knows them, and what each allows.

HEARTBEAT ``custom_mode`` carries the number; a ground station names it from the table
for a QUADROTOR with the ArduPilot autopilot (pymavlink's ``mode_mapping_acm``), so the
numbers here must be ArduCopter's. The simulator implements the subset below; the sets
say where the vehicle may arm, which modes need a position estimate to be entered, which
show the GUIDED flag in HEARTBEAT ``base_mode``, and where a FLIP may start.
"""

from __future__ import annotations

MODES = {
    "STABILIZE": 0, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9, "FLIP": 14,
    "BRAKE": 17,
}
MODE_NAMES = {number: name for name, number in MODES.items()}
ARMABLE = frozenset({"STABILIZE", "GUIDED", "LOITER"})
NEEDS_POSITION = frozenset({"AUTO", "GUIDED", "LOITER", "RTL", "BRAKE"})
GUIDED_FLAG_MODES = frozenset({"AUTO", "GUIDED", "RTL", "LAND", "LOITER", "BRAKE"})
# Where FLIP may be entered from, armed and flying. ArduCopter allows ACRO, STABILIZE and
# ALT_HOLD, whose pilot sticks hold the throttle; this simulator has neither ACRO nor
# ALT_HOLD, and accepts GUIDED instead so that a mission can flip without a pilot.
FLIP_FROM = frozenset({"STABILIZE", "GUIDED"})
