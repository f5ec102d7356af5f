"""What the vehicle answers: a MAV_RESULT to a command, a MAV_MISSION_RESULT to a transfer.

pymavlink's constants carry no types; these enums give the answers one, so that a handler
is checked to return an answer and not some other number. Their values are MAVLink's.
"""

from __future__ import annotations

from enum import IntEnum

from pymavlink.dialects.v20 import ardupilotmega as mavlink


class Result(IntEnum):
    """MAV_RESULT: the answer in a COMMAND_ACK."""

    ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
    DENIED = mavlink.MAV_RESULT_DENIED
    UNSUPPORTED = mavlink.MAV_RESULT_UNSUPPORTED
    FAILED = mavlink.MAV_RESULT_FAILED


class MissionResult(IntEnum):
    """MAV_MISSION_RESULT: the answer in a MISSION_ACK."""

    ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
    ERROR = mavlink.MAV_MISSION_ERROR
    UNSUPPORTED_FRAME = mavlink.MAV_MISSION_UNSUPPORTED_FRAME
    UNSUPPORTED = mavlink.MAV_MISSION_UNSUPPORTED
    NO_SPACE = mavlink.MAV_MISSION_NO_SPACE
    INVALID_PARAM1 = mavlink.MAV_MISSION_INVALID_PARAM1
    INVALID_PARAM2 = mavlink.MAV_MISSION_INVALID_PARAM2
    INVALID_PARAM3 = mavlink.MAV_MISSION_INVALID_PARAM3
    INVALID_PARAM4 = mavlink.MAV_MISSION_INVALID_PARAM4
    INVALID_PARAM5_X = mavlink.MAV_MISSION_INVALID_PARAM5_X
    INVALID_PARAM6_Y = mavlink.MAV_MISSION_INVALID_PARAM6_Y
    INVALID_PARAM7 = mavlink.MAV_MISSION_INVALID_PARAM7
    INVALID_SEQUENCE = mavlink.MAV_MISSION_INVALID_SEQUENCE
    DENIED = mavlink.MAV_MISSION_DENIED
    OPERATION_CANCELLED = mavlink.MAV_MISSION_OPERATION_CANCELLED

    @classmethod
    def invalid_param(cls, index: int) -> MissionResult:
        """The refusal of param ``index`` (0 for param1, ... 3 for param4)."""
        return (cls.INVALID_PARAM1, cls.INVALID_PARAM2, cls.INVALID_PARAM3,
                cls.INVALID_PARAM4)[index]
