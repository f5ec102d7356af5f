"""The vehicle side of the mission protocol, driven message by message with injected time."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.missions import ITEM_TIMEOUT, RETRIES, MissionServer
from tml.mavlink.mission import MissionItem

HOME = MissionItem(0, 0, 16, x=-353632610, y=1491652300, z=584.0)


def item_int(seq: int, command: int = 16, mission_type: int = 0, frame: int = 6) -> object:
    return M.MAVLink_mission_item_int_message(
        1, 1, seq, frame, command, 0, 1, 0, 0, 0, 0, -353632610 + seq * 100, 1491652300, 10.0,
        mission_type)


def server() -> tuple[MissionServer, list[int]]:
    changes: list[int] = []
    return MissionServer(lambda: HOME, changes.append), changes


def upload(s: MissionServer, count: int, now: float = 5.0, mission_type: int = 0,
           reply=item_int) -> list:
    replies = s.handle(M.MAVLink_mission_count_message(1, 1, count, mission_type), now)
    seen = list(replies)
    while replies and replies[-1].get_type().startswith("MISSION_REQUEST"):
        replies = s.handle(reply(replies[-1].seq, mission_type=mission_type), now)
        seen += replies
    return seen


def test_upload_requests_with_legacy_mission_request_and_home_replaces_seq_0():
    s, changes = server()
    seen = upload(s, 4)
    assert [m.get_type() for m in seen] == ["MISSION_REQUEST"] * 4 + ["MISSION_ACK"]
    assert [m.seq for m in seen[:4]] == [0, 1, 2, 3]
    assert seen[-1].type == M.MAV_MISSION_ACCEPTED and changes == [0]
    items = s.items()
    assert items[0] == HOME and len(items) == 4 and items[3].x == -353632610 + 300


def test_mission_item_float_replies_are_accepted():
    s, _ = server()

    def float_item(seq: int, mission_type: int = 0):
        return M.MAVLink_mission_item_message(1, 1, seq, 3, 16, 0, 1, 0, 0, 0, 0, -35.5, 149.25,
                                              20.0, mission_type)

    assert upload(s, 2, reply=float_item)[-1].type == M.MAV_MISSION_ACCEPTED
    assert (s.items()[1].x, s.items()[1].y) == (-355000000, 1492500000)


def test_a_client_that_uses_request_int_gets_request_int():
    s, _ = server()
    upload(s, 2)
    s.handle(M.MAVLink_mission_request_int_message(1, 1, 0, 0), 5.0)
    seen = upload(s, 2)
    assert [m.get_type() for m in seen] == ["MISSION_REQUEST_INT"] * 2 + ["MISSION_ACK"]


def test_download_reads_back_home_and_items():
    s, _ = server()
    upload(s, 3)
    (count,) = s.handle(M.MAVLink_mission_request_list_message(1, 1, 0), 6.0)
    assert count.count == 3
    (zero,) = s.handle(M.MAVLink_mission_request_int_message(1, 1, 0, 0), 6.0)
    assert (zero.frame, zero.z, zero.x) == (0, 584.0, HOME.x)
    (two,) = s.handle(M.MAVLink_mission_request_message(1, 1, 2, 0), 6.0)
    assert two.get_type() == "MISSION_ITEM" and abs(two.x - (-35.363261 + 2e-5)) < 1e-6
    (bad,) = s.handle(M.MAVLink_mission_request_int_message(1, 1, 9, 0), 6.0)
    assert bad.type == M.MAV_MISSION_INVALID_SEQUENCE


def test_clear_and_zero_count():
    s, changes = server()
    upload(s, 3)
    (ack,) = s.handle(M.MAVLink_mission_clear_all_message(1, 1, 0), 6.0)
    assert ack.type == M.MAV_MISSION_ACCEPTED and s.items() == [] and changes == [0, 0]


def test_busy_after_boot_and_too_many_items():
    s, _ = server()
    (ack,) = s.handle(M.MAVLink_mission_count_message(1, 1, 3, 0), 0.5)
    assert ack.type == M.MAV_MISSION_NO_SPACE
    (ack,) = s.handle(M.MAVLink_mission_count_message(1, 1, 10_000, 0), 5.0)
    assert ack.type == M.MAV_MISSION_NO_SPACE


def test_missing_items_are_requested_again_then_the_upload_is_cancelled():
    s, _ = server()
    s.handle(M.MAVLink_mission_count_message(1, 1, 2, 0), 5.0)
    now, rerequests = 5.0, []
    for _ in range(RETRIES + 1):
        assert s.tick(now + ITEM_TIMEOUT / 2) == []
        now += ITEM_TIMEOUT
        rerequests += s.tick(now)
    assert [m.get_type() for m in rerequests] == ["MISSION_REQUEST"] * RETRIES + ["MISSION_ACK"]
    assert rerequests[-1].type == M.MAV_MISSION_OPERATION_CANCELLED
    assert s.items() == []


def test_duplicates_ignored_future_items_refused_lost_ack_resent():
    s, _ = server()
    s.handle(M.MAVLink_mission_count_message(1, 1, 2, 0), 5.0)
    assert s.handle(item_int(0), 5.0)[0].seq == 1
    assert s.handle(item_int(0), 5.0) == []  # duplicate
    (future,) = s.handle(M.MAVLink_mission_item_int_message(
        1, 1, 5, 6, 16, 0, 1, 0, 0, 0, 0, 0, 0, 0), 5.0)
    assert future.type == M.MAV_MISSION_INVALID_SEQUENCE
    assert s.handle(item_int(1), 5.0)[0].type == M.MAV_MISSION_ACCEPTED
    assert s.handle(item_int(1), 5.1)[0].type == M.MAV_MISSION_ACCEPTED  # ACK lost, item resent


def test_fence_and_rally_lists_are_separate_and_checked():
    s, changes = server()
    assert upload(s, 3, mission_type=1,
                  reply=lambda seq, mission_type: item_int(seq, 5001, 1))[-1].type == 0
    assert upload(s, 1, mission_type=2,
                  reply=lambda seq, mission_type: item_int(seq, 5100, 2))[-1].type == 0
    assert len(s.items(1)) == 3 and len(s.items(2)) == 1 and s.items(0) == []
    assert changes == [1, 2]
    refused = upload(s, 1, mission_type=1, reply=lambda seq, mission_type: item_int(seq, 16, 1))
    assert refused[-1].type == M.MAV_MISSION_UNSUPPORTED
    bad_frame = upload(s, 1, reply=lambda seq, mission_type: item_int(seq, frame=1))
    assert bad_frame[-1].type == M.MAV_MISSION_UNSUPPORTED_FRAME
