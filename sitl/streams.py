"""Which telemetry messages are due when: the port's default rates, and the ways to change them.

As on an ArduPilot serial port, a new link gets nothing streamed but HEARTBEAT (1 Hz): the
ports' stream rates (ArduPilot's ``SRx_*`` parameters) are zero, so a ground station asks
for what it needs, per message with MAV_CMD_SET_MESSAGE_INTERVAL (interval in
microseconds; 0 restores the default, i.e. off, -1 stops it) or per group with the older
REQUEST_DATA_STREAM (groups as ArduCopter maps them; a message that is in no group, such
as EXTENDED_SYS_STATE, HOME_POSITION or POSITION_TARGET_*, only by interval). HOME_POSITION and
GPS_GLOBAL_ORIGIN are also sent once, unasked, when the EKF origin is set, and
HOME_POSITION whenever home moves (the model does that, not this schedule).

The rates belong to the vehicle's port, not to one connection: as ArduPilot keeps a
serial port's rates when its client reconnects, a client that connects later gets what an
earlier one asked for. A message falls due at most once per control step, keeping its
average rate; after a step late by a whole interval or more its schedule restarts from
that step, so a late step never causes a burst of copies.
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import ardupilotmega as mavlink

M = mavlink
# The messages that can stream, with the rate (Hz) a port sends them at unasked.
DEFAULT_RATES = {
    M.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    M.MAVLINK_MSG_ID_SYS_STATUS: 0.0,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: 0.0,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: 0.0,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 0.0,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 0.0,
    M.MAVLINK_MSG_ID_ATTITUDE: 0.0,
    M.MAVLINK_MSG_ID_VFR_HUD: 0.0,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 0.0,
    M.MAVLINK_MSG_ID_MISSION_CURRENT: 0.0,
    M.MAVLINK_MSG_ID_EKF_STATUS_REPORT: 0.0,
    M.MAVLINK_MSG_ID_SYSTEM_TIME: 0.0,
    M.MAVLINK_MSG_ID_HOME_POSITION: 0.0,  # sent when home changes and on request
    M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: 0.0,  # sent when the origin is set and on request
    M.MAVLINK_MSG_ID_POSITION_TARGET_GLOBAL_INT: 0.0,  # GUIDED's target, by interval only
    M.MAVLINK_MSG_ID_POSITION_TARGET_LOCAL_NED: 0.0,
}
# REQUEST_DATA_STREAM groups (MAV_DATA_STREAM) as ArduCopter 4.7 fills them (the messages
# this simulator builds; RAW_SENSORS and RC_CHANNELS hold only messages it does not).
DATA_STREAMS = {
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
        M.MAVLINK_MSG_ID_SYSTEM_TIME,
    ),
}


def _interval(rate: float) -> float | None:
    return 1.0 / rate if rate > 0 else None


class Streams:
    """The interval (s, or None when off) and next due time of every streamed message."""

    def __init__(self) -> None:
        self._intervals = {msg_id: _interval(rate) for msg_id, rate in DEFAULT_RATES.items()}
        self._next_due = dict.fromkeys(self._intervals, 0.0)
        # The earliest time anything streaming falls due: most control steps send nothing,
        # and they learn it from this one comparison (the model's step makes it without
        # calling :meth:`due`).
        self.earliest = 0.0

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
        self.earliest = now
        return True

    def request_data_stream(self, stream_id: int, rate: float, start: bool, now: float) -> None:
        """REQUEST_DATA_STREAM: ``rate`` Hz for a group (or all), or stop it."""
        groups = list(DATA_STREAMS) if stream_id == M.MAV_DATA_STREAM_ALL else [stream_id]
        for group in groups:
            for msg_id in DATA_STREAMS.get(group, ()):
                self._intervals[msg_id] = 1.0 / rate if start and rate > 0 else None
                self._next_due[msg_id] = now
                self.earliest = now

    def due(self, now: float) -> list[int]:
        """The ids of the messages due at ``now``, each scheduled for its next time."""
        soon = now + 1e-9
        if soon < self.earliest:
            return []
        out = []
        earliest = math.inf
        next_due = self._next_due
        for msg_id, interval in self._intervals.items():
            if interval is None:
                continue
            at = next_due[msg_id]
            if soon >= at:
                following = at + interval
                # Late by a whole interval (a long step): restart from now, never burst.
                at = next_due[msg_id] = following if following > soon else now + interval
                out.append(msg_id)
            if at < earliest:
                earliest = at
        self.earliest = earliest
        return out
