"""The simulator's record of one stored mission, fence or rally item.

The simulator is an autopilot of its own, so it keeps its own record of what it stored
rather than borrowing the ground station's (tml's); the two meet only on the wire, as
MISSION_ITEM_INT messages.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class MissionItem:
    """One stored item, with the fields of MISSION_ITEM_INT.

    ``x``/``y`` are latitude/longitude in degrees * 1e7 for global frames; ``z`` is the
    altitude in metres.
    """

    seq: int
    frame: int
    command: int
    current: int = 0
    autocontinue: int = 1
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    mission_type: int = 0  # MAV_MISSION_TYPE_MISSION
