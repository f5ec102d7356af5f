"""The vehicle side of the mission protocol: message by message with injected time, through
the vehicle model, and over a lossy link against tml's own uploader."""

from __future__ import annotations

import json
import math
import random
import struct
import time
from dataclasses import astuple, replace
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.faults import Faults
from sitl.missions import REQUEST_INTERVAL, UPLOAD_TIMEOUT, MissionServer
from sitl.model import VehicleModel
from sitl.server import Simulator
from tml.geo import to_local
from tml.mavlink.autopilot import Autopilot
from tml.mavlink.link import Link
from tml.mavlink.mission import (
    MissionItem,
    ardupilot_form,
    read_back_differences,
    with_home_placeholder,
)
from tml.world import DEFAULT_HOME

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
    # Degrees are scaled by 1e7 in float32, as ArduPilot does: 149.25 loses 32e-7 degrees.
    assert (s.items()[1].x, s.items()[1].y) == (-355000000, 1492499968)


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
    # Back to degrees in float32 arithmetic, as ArduPilot does: within float32's 4e-6.
    assert two.get_type() == "MISSION_ITEM" and abs(two.x - (-35.363261 + 2e-5)) < 4e-6
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


def test_the_awaited_item_is_requested_again_every_second_until_it_comes():
    s, _ = server()
    (first,) = s.handle(M.MAVLink_mission_count_message(1, 1, 3, 0), 5.0)
    assert first.seq == 0
    assert s.tick(5.0 + REQUEST_INTERVAL) == []  # not yet: ArduPilot waits more than 1 s
    (again,) = s.tick(5.0 + REQUEST_INTERVAL + 0.05)
    assert (again.get_type(), again.seq) == ("MISSION_REQUEST", 0)
    assert s.tick(5.0 + REQUEST_INTERVAL + 0.5) == []  # the clock restarts at each request
    (next_request,) = s.handle(item_int(0), 6.8)
    assert next_request.seq == 1
    (again,) = s.tick(6.8 + REQUEST_INTERVAL + 0.05)
    assert again.seq == 1


def test_an_upload_that_gets_no_item_for_eight_seconds_is_cancelled():
    s, changes = server()
    upload(s, 2)
    s.handle(M.MAVLink_mission_count_message(1, 1, 3, 0), 10.0)
    s.handle(item_int(0), 10.0)
    sent, now = [], 10.0
    while now < 10.0 + UPLOAD_TIMEOUT + 1.0:
        now = round(now + 0.05, 2)
        sent += [(now, m) for m in s.tick(now)]
    kinds = [m.get_type() for _, m in sent]
    assert kinds == ["MISSION_REQUEST"] * 7 + ["MISSION_ACK"]  # once a second, then give up
    assert {m.seq for _, m in sent[:-1]} == {1}
    cancelled_at, ack = sent[-1]
    assert ack.type == M.MAV_MISSION_OPERATION_CANCELLED and cancelled_at > 10.0 + UPLOAD_TIMEOUT
    (late,) = s.handle(item_int(1), now)  # too late: ArduPilot is no longer receiving
    assert late.type == M.MAV_MISSION_ERROR
    assert len(s.items()) == 2 and changes == [0]  # the earlier mission is kept


def test_items_other_than_the_awaited_one_get_invalid_sequence_and_change_nothing():
    s, _ = server()
    s.handle(M.MAVLink_mission_count_message(1, 1, 2, 0), 5.0)
    assert s.handle(item_int(0), 5.0)[0].seq == 1
    repeat = M.MAVLink_mission_item_int_message(1, 1, 0, 6, 16, 0, 1, 0, 0, 0, 0, 1, 2, 99.0)
    (ack,) = s.handle(repeat, 5.1)
    assert (ack.get_type(), ack.type) == ("MISSION_ACK", M.MAV_MISSION_INVALID_SEQUENCE)
    (future,) = s.handle(M.MAVLink_mission_item_int_message(
        1, 1, 5, 6, 16, 0, 1, 0, 0, 0, 0, 0, 0, 0), 5.1)
    assert future.type == M.MAV_MISSION_INVALID_SEQUENCE
    assert s.handle(item_int(1), 5.2)[0].type == M.MAV_MISSION_ACCEPTED
    assert s.items()[1].z == 10.0 and len(s.items()) == 2  # the repeat was not stored
    # A repeat after the final ACK (lost): ArduPilot does not repeat the ACK, it answers
    # MAV_MISSION_ERROR as to any item that comes when it is not receiving.
    assert s.handle(item_int(1), 5.3)[0].type == M.MAV_MISSION_ERROR


def test_a_list_being_uploaded_is_not_read_cleared_or_taken_over():
    s, _ = server()
    s.handle(M.MAVLink_mission_count_message(1, 1, 3, 0), 5.0)
    other = M.MAVLink_mission_count_message(1, 1, 2, 0)
    other._header.srcSystem = 42
    assert s.handle(other, 5.1)[0].type == M.MAV_MISSION_DENIED
    assert s.handle(M.MAVLink_mission_request_list_message(1, 1, 0), 5.1)[0].type == (
        M.MAV_MISSION_DENIED)
    assert s.handle(M.MAVLink_mission_clear_all_message(1, 1, 0), 5.1)[0].type == (
        M.MAV_MISSION_ERROR)
    (count,) = s.handle(M.MAVLink_mission_request_list_message(1, 1, 1), 5.1)
    assert count.get_type() == "MISSION_COUNT"  # the fence list is not being written
    (restart,) = s.handle(M.MAVLink_mission_count_message(1, 1, 1, 0), 5.2)
    assert restart.seq == 0  # the uploading client may start again
    assert s.handle(item_int(0), 5.3)[0].type == M.MAV_MISSION_ACCEPTED


def test_the_vehicle_runs_the_timeouts_on_its_own_clock():
    v = VehicleModel(1, DEFAULT_HOME)
    v.step(2.0)
    (request,) = v.handle(M.MAVLink_mission_count_message(1, 1, 2, 0))
    assert request.seq == 0
    out = [m for m in v.step(UPLOAD_TIMEOUT + 0.5) if m.get_type().startswith("MISSION_")
           and m.get_type() != "MISSION_CURRENT"]
    assert [m.get_type() for m in out] == ["MISSION_REQUEST"] * 7 + ["MISSION_ACK"]
    assert out[-1].type == M.MAV_MISSION_OPERATION_CANCELLED
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in out} == {(1, 1)}


def mission(n: int) -> list[MissionItem]:
    return [MissionItem(seq=i, frame=6, command=16, param1=i % 3, x=-353632621 + 100 * i,
                        y=1491652374 - 50 * i, z=10.0 + i) for i in range(n)]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_tmls_uploader_gets_a_mission_through_30_percent_loss_each_way(seed):
    faults = Faults(seed=seed, loss_in=0.3, loss_out=0.3)
    sent = mission(6)
    with Simulator(tcp_base_port=0, speedup=5.0, faults=faults) as sim, \
            Link(f"tcp:127.0.0.1:{sim.tcp_ports[0]}") as link:
        vehicle = Autopilot.connect(link, 1, timeout=20)
        deadline = time.monotonic() + 10
        while sim.time < 1.5:  # uploads get NO_SPACE for a second after boot
            assert time.monotonic() < deadline
            time.sleep(0.02)
        # upload() reads the mission back over the same lossy link, and raises a
        # MissionTransferError unless it is what was sent.
        assert vehicle.upload(sent) == with_home_placeholder(sent)
        stored = sim.vehicle(1).mission_items[1:]
        # Stored as ArduPilot stores them: frame 6 (INT) as its float twin 3.
        # (the simulator keeps its own record of an item: compared field by field)
        assert [astuple(replace(item, seq=item.seq - 1)) for item in stored] == [
            astuple(replace(item, frame=3)) for item in sent]
        assert link.telemetry(1).lost > 0  # the loss was real


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


# --- items stored as ArduCopter stores them ----------------------------------------------

ARDUCOPTER = json.loads((Path(__file__).parent / "data" / "arducopter_read_back.json")
                        .read_text())


def case_id(case: dict) -> str:
    return "-".join(f"{v:g}" for v in case["sent"][:6])


def store_and_read(sent: list, mission_type: int = 0) -> object:
    """Upload home and one item as MISSION_ITEM_INT; the item read back, or the refusal."""
    command, frame, *params, x, y, z = sent
    s, _ = server()

    def reply(seq: int, mission_type: int = 0) -> object:
        if seq == 0 and mission_type == 0:
            return item_int(0)
        return M.MAVLink_mission_item_int_message(1, 1, seq, frame, command, 0, 1, *params,
                                                  x, y, z, mission_type)

    count = 2 if mission_type == 0 else 1
    last = upload(s, count, mission_type=mission_type, reply=reply)[-1]
    if last.type != M.MAV_MISSION_ACCEPTED:
        return last.type
    (item,) = s.handle(M.MAVLink_mission_request_int_message(1, 1, count - 1, mission_type),
                       6.0)
    return item


def f32(value: float) -> float:
    return struct.unpack("<f", struct.pack("<f", value))[0]


@pytest.mark.parametrize("case", ARDUCOPTER["kept"] + ARDUCOPTER["wrapped"], ids=case_id)
def test_an_item_reads_back_as_it_did_from_arducopter(case: dict) -> None:
    back = store_and_read(case["sent"])
    frame, *params, x, y, z = case["read"]
    assert (back.frame, back.param1, back.param2, back.param3, back.param4, back.x, back.y,
            back.z, back.autocontinue) == (frame, *map(f32, params), x, y, f32(z), 1)


@pytest.mark.parametrize("case", ARDUCOPTER["refused"], ids=case_id)
def test_an_item_arducopter_refuses_ends_the_upload_with_its_result(case: dict) -> None:
    assert store_and_read(case["sent"]) == getattr(M, case["result"])


def test_fences_and_rally_points_keep_what_arducopter_keeps() -> None:
    lat, lon = -353632610, 1491652300
    vertex = store_and_read([5001, 6, 3.7, 1, 2, 3, lat, lon, 10.0], mission_type=1)
    assert (vertex.frame, vertex.param1, vertex.param2, vertex.z, vertex.autocontinue) == (
        0, 3.0, 0.0, 0.0, 0)
    circle = store_and_read([5003, 0, 50.5, 1, 2, 3, lat, lon, 7.0], mission_type=1)
    assert (circle.param1, circle.param2, circle.x, circle.y) == (50.5, 0.0, lat, lon)
    rally = store_and_read([5100, 6, 1, 2, 3, 4, lat, lon, 12.7], mission_type=2)
    assert (rally.frame, rally.param1, rally.z, rally.autocontinue) == (3, 0.0, 12.0, 0)
    assert store_and_read([5100, 0, 0, 0, 0, 0, lat, lon, -5.6], mission_type=2).z == -5.0
    assert store_and_read([5100, 6, 0, 0, 0, 0, lat, lon, 40000.0], mission_type=2) == (
        M.MAV_MISSION_INVALID_PARAM7)


def test_the_simulators_storage_and_tmls_read_back_rules_agree() -> None:
    # Two readings of ArduPilot written apart: what the simulator stores must be what tml's
    # rules expect, for any value the fields can hold.
    rng = random.Random(11)
    commands = sorted({case["sent"][0] for case in ARDUCOPTER["kept"]})
    unstorable = 0
    for _ in range(2000):
        command = rng.choice(commands)
        frame = rng.choice([0, 2, 3, 5, 6, 10, 11])
        params = [rng.choice([0.0, 1.0, -1.0, round(rng.uniform(-120, 250), rng.randint(0, 3)),
                              round(rng.uniform(0, 3), 2)]) for _ in range(4)]
        x, y = -353632610 + rng.randint(-9999, 9999), 1491652300 + rng.randint(-9999, 9999)
        sent = MissionItem(1, frame, command, 0, 1, *params, x, y,
                           round(rng.uniform(-50, 3000), rng.randint(0, 4)))
        back = store_and_read([command, frame, *params, x, y, sent.z])
        if isinstance(back, int):  # a value ArduPilot refuses (a NaN-free sample: none)
            pytest.fail(f"{sent} refused with {back}")
        read = MissionItem(1, back.frame, back.command, 0, back.autocontinue, back.param1,
                           back.param2, back.param3, back.param4, back.x, back.y, back.z)
        differences = read_back_differences([sent], [read], ardupilot_form)
        # Only a value that cannot be stored (which may spoil its neighbours) differs.
        assert not differences or any(d.why for d in differences), (sent, read, differences)
        unstorable += bool(differences)
    assert 0 < unstorable < 1000  # the sample holds both kinds


def test_the_auto_executor_flies_the_stored_values() -> None:
    # A loiter radius of 8.9 m is stored, and so circled, as 8 m, as ArduCopter does.
    v = VehicleModel(1, DEFAULT_HOME, params={"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2})
    v.step(3)
    lat, lon = -353632610, 1491652300
    mission = [(16, 0, (0, 0, 0, 0), 0, 0, 0.0), (22, 6, (0, 0, 0, 0), 0, 0, 10.0),
               (18, 6, (1, 0, 8.9, 0), lat, lon, 10.0), (20, 6, (0, 0, 0, 0), 0, 0, 0.0)]
    replies = v.handle(M.MAVLink_mission_count_message(1, 1, len(mission), 0))
    while replies[-1].get_type() == "MISSION_REQUEST":
        command, frame, params, x, y, z = mission[replies[-1].seq]
        replies = v.handle(M.MAVLink_mission_item_int_message(
            1, 1, replies[-1].seq, frame, command, 0, 1, *params, x, y, z, 0))
    assert v.mission_items[2].param3 == 8.0
    assert v.set_mode("GUIDED")
    v.handle(M.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    assert v.set_mode("AUTO")
    h = DEFAULT_HOME
    centre = to_local(lat / 1e7, lon / 1e7, h.altitude, h.latitude, h.longitude, h.altitude)
    distances = []
    while v.armed and v.time < 300:
        v.step(0.1)
        if v.auto is not None and v.auto.nav is not None and v.auto.nav.phase == "circle":
            distances.append(math.dist(v.position[:2], centre[:2]))
    on_circle = sorted(distances[len(distances) // 4:])
    assert on_circle[len(on_circle) // 2] == pytest.approx(8.0, abs=0.3)
