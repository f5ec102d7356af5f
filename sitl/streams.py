"""Which telemetry messages are due when: default rates, and the two ways to change them.

A ground station changes a message's rate with MAV_CMD_SET_MESSAGE_INTERVAL (interval in
microseconds; 0 restores the default, -1 stops it) or a whole group's with the older
REQUEST_DATA_STREAM (groups as ArduPilot maps them). Unlike a bare ArduPilot serial port,
the default streams run without being asked for, so a client that never sets rates still
sees telemetry. A message falls due at most once per control step, keeping its average
rate; after a step late by a whole interval or more its schedule restarts from that step,
so a late step never causes a burst of copies.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

M = mavlink
# Default stream rates in Hz (message id -> rate).
DEFAULT_RATES = {
    M.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    M.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: 1.0,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: 1.0,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 4.0,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 4.0,
    M.MAVLINK_MSG_ID_ATTITUDE: 4.0,
    M.MAVLINK_MSG_ID_VFR_HUD: 4.0,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0,
    M.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
    M.MAVLINK_MSG_ID_EKF_STATUS_REPORT: 1.0,
    M.MAVLINK_MSG_ID_HOME_POSITION: 0.0,  # sent when home changes and on request
}
# REQUEST_DATA_STREAM groups (MAV_DATA_STREAM) as ArduPilot maps them.
DATA_STREAMS = {
    M.MAV_DATA_STREAM_RAW_SENSORS: (M.MAVLINK_MSG_ID_GPS_RAW_INT,),
    M.MAV_DATA_STREAM_EXTENDED_STATUS: (
        M.MAVLINK_MSG_ID_SYS_STATUS, M.MAVLINK_MSG_ID_GPS_RAW_INT,
        M.MAVLINK_MSG_ID_MISSION_CURRENT,
    ),
    M.MAV_DATA_STREAM_POSITION: (
        M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, M.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    ),
    M.MAV_DATA_STREAM_EXTRA1: (M.MAVLINK_MSG_ID_ATTITUDE,),
    M.MAV_DATA_STREAM_EXTRA2: (M.MAVLINK_MSG_ID_VFR_HUD,),
    M.MAV_DATA_STREAM_EXTRA3: (
        M.MAVLINK_MSG_ID_BATTERY_STATUS, M.MAVLINK_MSG_ID_EKF_STATUS_REPORT,
        M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
    ),
}


def _interval(rate: float) -> float | None:
    return 1.0 / rate if rate > 0 else None


class Streams:
    """The interval (s, or None when off) and next due time of every streamed message."""

    def __init__(self) -> None:
        self._intervals = {msg_id: _interval(rate) for msg_id, rate in DEFAULT_RATES.items()}
        self._next_due = dict.fromkeys(self._intervals, 0.0)

    def set_interval(self, msg_id: int, interval_us: float, now: float) -> bool:
        """SET_MESSAGE_INTERVAL; False for a message that cannot stream."""
        if msg_id not in self._intervals:
            return False
        if interval_us < 0:
            self._intervals[msg_id] = None
        elif interval_us == 0:
            self._intervals[msg_id] = _interval(DEFAULT_RATES[msg_id])
        else:
            self._intervals[msg_id] = interval_us / 1e6
        self._next_due[msg_id] = now
        return True

    def request_data_stream(self, stream_id: int, rate: float, start: bool, now: float) -> None:
        """REQUEST_DATA_STREAM: ``rate`` Hz for a group (or all), or stop it."""
        groups = list(DATA_STREAMS) if stream_id == M.MAV_DATA_STREAM_ALL else [stream_id]
        for group in groups:
            for msg_id in DATA_STREAMS.get(group, ()):
                self._intervals[msg_id] = 1.0 / rate if start and rate > 0 else None
                self._next_due[msg_id] = now

    def due(self, now: float) -> list[int]:
        """The ids of the messages due at ``now``, each scheduled for its next time."""
        out = []
        for msg_id, interval in self._intervals.items():
            if interval is None or now + 1e-9 < self._next_due[msg_id]:
                continue
            following = self._next_due[msg_id] + interval
            # Late by a whole interval (a long step): restart from now rather than burst.
            self._next_due[msg_id] = following if following > now + 1e-9 else now + interval
            out.append(msg_id)
        return out
