"""Stream scheduling: a port's defaults (HEARTBEAT only), SET_MESSAGE_INTERVAL,
REQUEST_DATA_STREAM with ArduCopter's groups."""

from __future__ import annotations

from collections import Counter

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M
from test_sitl_model import command, flying

from sitl.streams import Streams
from tml.geo import to_global
from tml.world import DEFAULT_HOME

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


# The GUIDED target, through the model: as ArduCopter 4.7 (tml/mavlink/targets.py), asked
# for by interval, reported in GUIDED only -- a point as both messages (the position
# alone), a velocity target as POSITION_TARGET_LOCAL_NED alone (the velocity alone).
GLOBAL = "POSITION_TARGET_GLOBAL_INT"
LOCAL = "POSITION_TARGET_LOCAL_NED"


def asking_for_targets(v) -> None:
    for msg_id in (M.MAVLINK_MSG_ID_POSITION_TARGET_GLOBAL_INT,
                   M.MAVLINK_MSG_ID_POSITION_TARGET_LOCAL_NED):
        command(v, M.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 500_000)
    v.step(0.25)  # a stream asked for starts at once: count from the next due time


def targets_sent(v, seconds: float = 1.0) -> dict[str, list]:
    sent: dict[str, list] = {GLOBAL: [], LOCAL: []}
    for m in v.step(seconds):
        if m.get_type() in sent:
            sent[m.get_type()].append(m)
    return sent


def test_guided_flying_to_a_point_reports_it_in_both_target_messages():
    v = flying()
    asking_for_targets(v)
    v.handle(M.MAVLink_set_position_target_local_ned_message(
        0, 1, 1, M.MAV_FRAME_LOCAL_NED, 0b110111111000, 40.0, -25.0, -12.0,
        0, 0, 0, 0, 0, 0, 0, 0))
    sent = targets_sent(v)
    assert len(sent[GLOBAL]) == len(sent[LOCAL]) == 2  # 2 Hz, as asked
    local, glob = sent[LOCAL][-1], sent[GLOBAL][-1]
    assert (local.coordinate_frame, local.type_mask) == (M.MAV_FRAME_LOCAL_NED, 3576)
    assert (local.x, local.y, local.z) == pytest.approx((40.0, -25.0, -12.0), abs=1e-4)
    assert (glob.coordinate_frame, glob.type_mask) == (M.MAV_FRAME_GLOBAL, 65016)
    lat, lon, alt = to_global(40.0, -25.0, 12.0, DEFAULT_HOME.latitude,
                              DEFAULT_HOME.longitude, DEFAULT_HOME.altitude)
    assert (glob.lat_int, glob.lon_int) == (round(lat * 1e7), round(lon * 1e7))
    assert glob.alt == pytest.approx(alt, abs=1e-3)  # AMSL (frame GLOBAL)


def test_a_guided_velocity_target_is_reported_in_local_ned_alone():
    v = flying()
    asking_for_targets(v)
    v.handle(M.MAVLink_set_position_target_local_ned_message(
        0, 1, 1, M.MAV_FRAME_LOCAL_NED, 0b110111000111, 0, 0, 0,
        2.0, -1.0, 0.5, 0, 0, 0, 0, 0))
    sent = targets_sent(v)
    assert sent[GLOBAL] == [] and len(sent[LOCAL]) == 2
    local = sent[LOCAL][-1]
    assert local.type_mask == 3079
    assert (local.vx, local.vy, local.vz) == pytest.approx((2.0, -1.0, 0.5))


@pytest.mark.parametrize("mode", ["BRAKE", "LOITER"])
def test_no_target_is_reported_outside_guided(mode):
    v = flying()
    asking_for_targets(v)
    assert targets_sent(v)[LOCAL]  # the take-off's point, in GUIDED
    assert v.set_mode(mode)
    assert targets_sent(v, 2.0) == {GLOBAL: [], LOCAL: []}


def test_no_target_is_reported_unasked():
    v = flying()
    v.handle(M.MAVLink_request_data_stream_message(1, 1, M.MAV_DATA_STREAM_ALL, 10, 1))
    assert targets_sent(v, 2.0) == {GLOBAL: [], LOCAL: []}  # in no data stream group
