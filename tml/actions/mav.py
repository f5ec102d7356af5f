"""The MAV_CMD, MAV_FRAME and gripper numbers the action modules write in mission items.

Plain numbers, so that the item compilers never import pymavlink: the MAV_CMD and MAV_FRAME
numbers are read by name from :mod:`tml.language.mavlink_tables` (which tests check against
pymavlink), the gripper actions are MAVLink's GRIPPER_ACTIONS (tests/test_action_registry.py
checks every number here against pymavlink).
"""

from __future__ import annotations

from tml.language.mavlink_tables import MAV_CMD, MAV_FRAME

_CMD = {name.removeprefix("MAV_CMD_"): number for number, name in MAV_CMD.items()}
_FRAME = {name.removeprefix("MAV_"): number for number, name in MAV_FRAME.items()}

NAV_WAYPOINT = _CMD["NAV_WAYPOINT"]
NAV_LOITER_UNLIM = _CMD["NAV_LOITER_UNLIM"]
NAV_LOITER_TURNS = _CMD["NAV_LOITER_TURNS"]
NAV_LOITER_TIME = _CMD["NAV_LOITER_TIME"]
NAV_RETURN_TO_LAUNCH = _CMD["NAV_RETURN_TO_LAUNCH"]
NAV_LAND = _CMD["NAV_LAND"]
NAV_TAKEOFF = _CMD["NAV_TAKEOFF"]
NAV_DELAY = _CMD["NAV_DELAY"]
NAV_LAST = _CMD["NAV_LAST"]
"""Commands below it navigate; DO_ and CONDITION_ commands are above."""
CONDITION_YAW = _CMD["CONDITION_YAW"]
DO_CHANGE_SPEED = _CMD["DO_CHANGE_SPEED"]
DO_SET_HOME = _CMD["DO_SET_HOME"]
DO_DIGICAM_CONTROL = _CMD["DO_DIGICAM_CONTROL"]
DO_SET_CAM_TRIGG_DIST = _CMD["DO_SET_CAM_TRIGG_DIST"]
DO_GRIPPER = _CMD["DO_GRIPPER"]
IMAGE_START_CAPTURE = _CMD["IMAGE_START_CAPTURE"]
IMAGE_STOP_CAPTURE = _CMD["IMAGE_STOP_CAPTURE"]
DO_SET_ROI_LOCATION = _CMD["DO_SET_ROI_LOCATION"]
DO_SET_ROI_NONE = _CMD["DO_SET_ROI_NONE"]

FRAME_GLOBAL = _FRAME["FRAME_GLOBAL"]
FRAME_MISSION = _FRAME["FRAME_MISSION"]
FRAME_GLOBAL_RELATIVE_ALT = _FRAME["FRAME_GLOBAL_RELATIVE_ALT"]
FRAME_GLOBAL_INT = _FRAME["FRAME_GLOBAL_INT"]
FRAME_GLOBAL_RELATIVE_ALT_INT = _FRAME["FRAME_GLOBAL_RELATIVE_ALT_INT"]
FRAME_GLOBAL_TERRAIN_ALT = _FRAME["FRAME_GLOBAL_TERRAIN_ALT"]
FRAME_GLOBAL_TERRAIN_ALT_INT = _FRAME["FRAME_GLOBAL_TERRAIN_ALT_INT"]

GRIPPER_ACTION_RELEASE = 0
GRIPPER_ACTION_GRAB = 1


def number(text: str) -> int:
    """The number of a MAV_CMD or MAV_FRAME the language checked: a number, or a name of
    :mod:`tml.language.mavlink_tables` (prefix MAV_CMD_ or MAV_FRAME_ included)."""
    if text.isdigit():
        return int(text)
    name = text.removeprefix("MAV_")
    return _FRAME[name] if name.startswith("FRAME_") else _CMD[name.removeprefix("CMD_")]

AMSL_FRAMES = frozenset({FRAME_GLOBAL, FRAME_GLOBAL_INT})
"""The global frames whose altitude is above mean sea level."""
RELATIVE_FRAMES = frozenset({FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_RELATIVE_ALT_INT})
"""The global frames whose altitude is above home."""
TERRAIN_FRAMES = frozenset({FRAME_GLOBAL_TERRAIN_ALT, FRAME_GLOBAL_TERRAIN_ALT_INT})
"""The global frames whose altitude is above the terrain."""
GLOBAL_FRAMES = AMSL_FRAMES | RELATIVE_FRAMES | TERRAIN_FRAMES
"""The frames whose x and y are latitude and longitude (degrees * 1e7)."""
FLOAT_FRAMES = frozenset({FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_TERRAIN_ALT})
"""The global frames without _INT, which frame_encoding="float" writes."""
