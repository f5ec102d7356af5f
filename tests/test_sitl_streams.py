"""Stream scheduling: default rates, SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM."""

from __future__ import annotations

from collections import Counter

from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.streams import Streams

TICK = 0.05


def count(streams: Streams, start: float, seconds: float) -> Counter:
    seen: Counter = Counter()
    for step in range(round(seconds / TICK)):
        seen.update(streams.due(start + step * TICK))
    return seen


def test_default_streams_run_unasked_at_their_rates():
    seen = count(Streams(), 0.0, 10.0)
    assert seen[M.MAVLINK_MSG_ID_HEARTBEAT] == 10
    assert seen[M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT] == 40
    assert seen[M.MAVLINK_MSG_ID_HOME_POSITION] == 0  # on change and on request only


def test_message_interval_sets_stops_and_restores_a_rate():
    s = Streams()
    assert s.set_interval(M.MAVLINK_MSG_ID_ATTITUDE, 50_000, 0.0)  # 20 Hz
    assert count(s, 0.0, 2.0)[M.MAVLINK_MSG_ID_ATTITUDE] == 40
    s.set_interval(M.MAVLINK_MSG_ID_ATTITUDE, -1, 2.0)
    assert count(s, 2.0, 2.0)[M.MAVLINK_MSG_ID_ATTITUDE] == 0
    s.set_interval(M.MAVLINK_MSG_ID_ATTITUDE, 0, 4.0)
    assert count(s, 4.0, 2.0)[M.MAVLINK_MSG_ID_ATTITUDE] == 8  # back to the default 4 Hz
    assert not s.set_interval(M.MAVLINK_MSG_ID_PARAM_VALUE, 1000, 0.0)


def test_data_stream_groups_switch_their_messages_together():
    s = Streams()
    s.request_data_stream(M.MAV_DATA_STREAM_POSITION, 10, True, 0.0)
    seen = count(s, 0.0, 1.0)
    assert seen[M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT] == seen[
        M.MAVLINK_MSG_ID_LOCAL_POSITION_NED] == 10
    s.request_data_stream(M.MAV_DATA_STREAM_ALL, 0, False, 1.0)
    assert set(count(s, 1.0, 3.0)) == {M.MAVLINK_MSG_ID_HEARTBEAT}


def test_a_late_step_never_sends_a_message_twice():
    s = Streams()
    s.due(0.0)
    assert s.due(5.0).count(M.MAVLINK_MSG_ID_HEARTBEAT) == 1
    assert count(s, 5.05, 0.9)[M.MAVLINK_MSG_ID_HEARTBEAT] == 0  # next one a second later
    assert M.MAVLINK_MSG_ID_HEARTBEAT in s.due(6.0)
