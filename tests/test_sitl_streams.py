"""Stream scheduling: a port's defaults (HEARTBEAT only), SET_MESSAGE_INTERVAL,
REQUEST_DATA_STREAM with ArduCopter's groups."""

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


def test_a_new_link_gets_only_heartbeats_unasked():
    # ArduCopter SITL's SERIAL0 streams nothing but HEARTBEAT until a client asks.
    assert count(Streams(), 0.0, 10.0) == Counter({M.MAVLINK_MSG_ID_HEARTBEAT: 10})


def test_message_interval_sets_stops_and_restores_a_rate():
    s = Streams()
    assert s.set_interval(M.MAVLINK_MSG_ID_ATTITUDE, 50_000, 0.0)  # 20 Hz
    assert count(s, 0.0, 2.0)[M.MAVLINK_MSG_ID_ATTITUDE] == 40
    s.set_interval(M.MAVLINK_MSG_ID_ATTITUDE, -1, 2.0)
    assert count(s, 2.0, 2.0)[M.MAVLINK_MSG_ID_ATTITUDE] == 0
    s.set_interval(M.MAVLINK_MSG_ID_ATTITUDE, 50_000, 4.0)
    s.set_interval(M.MAVLINK_MSG_ID_ATTITUDE, 0, 4.0)
    assert count(s, 4.0, 2.0)[M.MAVLINK_MSG_ID_ATTITUDE] == 0  # back to the default: off
    assert s.set_interval(M.MAVLINK_MSG_ID_HOME_POSITION, 1e6, 6.0)  # streams when asked
    assert count(s, 6.0, 2.0)[M.MAVLINK_MSG_ID_HOME_POSITION] == 2
    assert not s.set_interval(M.MAVLINK_MSG_ID_PARAM_VALUE, 1000, 0.0)


def test_data_stream_groups_switch_their_messages_together():
    s = Streams()
    s.request_data_stream(M.MAV_DATA_STREAM_POSITION, 10, True, 0.0)
    seen = count(s, 0.0, 1.0)
    assert seen[M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT] == seen[
        M.MAVLINK_MSG_ID_LOCAL_POSITION_NED] == 10
    s.request_data_stream(M.MAV_DATA_STREAM_ALL, 0, False, 1.0)
    assert set(count(s, 1.0, 3.0)) == {M.MAVLINK_MSG_ID_HEARTBEAT}
    s.request_data_stream(M.MAV_DATA_STREAM_ALL, 2, True, 4.0)
    assert set(count(s, 4.0, 1.0)) == {  # what ArduCopter 4.7 sends of the simulated ones
        M.MAVLINK_MSG_ID_HEARTBEAT, M.MAVLINK_MSG_ID_SYS_STATUS, M.MAVLINK_MSG_ID_GPS_RAW_INT,
        M.MAVLINK_MSG_ID_MISSION_CURRENT, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, M.MAVLINK_MSG_ID_ATTITUDE,
        M.MAVLINK_MSG_ID_VFR_HUD, M.MAVLINK_MSG_ID_BATTERY_STATUS,
        M.MAVLINK_MSG_ID_EKF_STATUS_REPORT, M.MAVLINK_MSG_ID_SYSTEM_TIME}
    # EXTENDED_SYS_STATE is in no group: ArduCopter sends it only at an interval asked for.
    assert s.set_interval(M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 500_000, 5.0)
    assert count(s, 5.0, 1.0)[M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE] == 2


def test_a_late_step_never_sends_a_message_twice():
    s = Streams()
    s.due(0.0)
    assert s.due(5.0).count(M.MAVLINK_MSG_ID_HEARTBEAT) == 1
    assert count(s, 5.05, 0.9)[M.MAVLINK_MSG_ID_HEARTBEAT] == 0  # next one a second later
    assert M.MAVLINK_MSG_ID_HEARTBEAT in s.due(6.0)


def test_a_stream_asked_for_between_due_times_starts_at_once():
    # The schedule answers "nothing due" from its earliest due time: a stream switched on
    # while the others wait (HEARTBEAT next due at 2 s) must still start in that step.
    s = Streams()
    assert s.due(1.0) == [M.MAVLINK_MSG_ID_HEARTBEAT]
    assert s.due(1.05) == []
    s.set_interval(M.MAVLINK_MSG_ID_ATTITUDE, 250_000, 1.1)
    assert s.due(1.1) == [M.MAVLINK_MSG_ID_ATTITUDE]
    s.request_data_stream(M.MAV_DATA_STREAM_EXTRA2, 4, True, 1.15)
    assert s.due(1.15) == [M.MAVLINK_MSG_ID_VFR_HUD]
    assert s.due(1.35) == [M.MAVLINK_MSG_ID_ATTITUDE]
    assert s.due(1.4) == [M.MAVLINK_MSG_ID_VFR_HUD]
