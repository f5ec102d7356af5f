"""ArduCopter's flight modes as the simulated vehicle knows them, and what each allows.

HEARTBEAT ``custom_mode`` carries the number; a ground station names it from the table
for a QUADROTOR with the ArduPilot autopilot (pymavlink's ``mode_mapping_acm``), so the
numbers here must be ArduCopter's. The simulator implements the subset below; the sets
say where the vehicle may arm, which modes need a position estimate to be entered, and
which show the GUIDED flag in HEARTBEAT ``base_mode``.
"""

from __future__ import annotations

MODES = {"STABILIZE": 0, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9, "BRAKE": 17}
MODE_NAMES = {number: name for name, number in MODES.items()}
ARMABLE = frozenset({"STABILIZE", "GUIDED", "LOITER"})
NEEDS_POSITION = frozenset({"AUTO", "GUIDED", "LOITER", "RTL", "BRAKE"})
GUIDED_FLAG_MODES = frozenset({"AUTO", "GUIDED", "RTL", "LAND", "LOITER", "BRAKE"})
