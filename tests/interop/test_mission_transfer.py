"""Mission upload and read-back against ArduCopter SITL, compared by ArduPilot's rules.

ArduCopter stores items in its own form (tml.mavlink.mission.ardupilot_form): these tests
upload the kinds of item tml compiles, read them back and find no difference, show that a
real difference (an item changed on the vehicle behind tml's back) is named, measure again
the read-backs recorded in tests/data/arducopter_read_back.json (which the pure tests and
the simulator's tests are built on), and fly missions/mission_dispatch.xml.
"""

from __future__ import annotations

import json
import math
import random
import re
import struct
import time
from pathlib import Path

import pytest
from pymavlink import mavutil

from tml.commands.cli import main
from tml.errors import MissionTransferError
from tml.mavlink.autopilot import Autopilot
from tml.mavlink.codec import mavlink
from tml.mavlink.link import Link
from tml.mavlink.mission import (
    MissionItem,
    MissionResult,
    ardupilot_form,
    exact_form,
    read_back_differences,
)
from tml.run.journal import read

ROOT = Path(__file__).resolve().parents[2]
RECORDED = json.loads((ROOT / "tests" / "data" / "arducopter_read_back.json").read_text())
LAT, LON = -353632610, 1491652300


def connect(link: Link) -> Autopilot:
    return Autopilot.connect(link, None, timeout=30)


def upload_when_ready(vehicle: Autopilot, items: list[MissionItem]) -> list[MissionItem]:
    """Upload, retrying while ArduCopter answers NO_SPACE (about a second after boot)."""
    deadline = time.monotonic() + 30
    while True:
        try:
            return vehicle.upload(items)
        except MissionTransferError as error:
            if error.result != MissionResult.MAV_MISSION_NO_SPACE.name or (
                    time.monotonic() > deadline):
                raise
            time.sleep(0.5)


def compiled_mix(n: int, seed: int) -> list[MissionItem]:
    """``n`` items of the kinds tml.mavlink.compile emits, with values ArduPilot rounds."""
    rng = random.Random(seed)
    m = mavlink

    def point() -> tuple[int, int]:
        return LAT + rng.randint(-5000, 5000), LON + rng.randint(-5000, 5000)

    kinds = [
        lambda: (m.MAV_CMD_NAV_WAYPOINT, 6, (0, 0, 0, 0), *point(), rng.uniform(5, 60)),
        lambda: (m.MAV_CMD_NAV_WAYPOINT, 5, (0, 0, 0, 0), *point(), 584 + rng.uniform(5, 60)),
        lambda: (m.MAV_CMD_NAV_WAYPOINT, 11, (0, 0, 0, 0), *point(), rng.uniform(5, 60)),
        lambda: (m.MAV_CMD_NAV_TAKEOFF, 6, (15, 0, 0, 0), 0, 0, rng.uniform(5, 30)),
        lambda: (m.MAV_CMD_NAV_LOITER_TURNS, 6, (rng.randint(1, 5), 0,
                                                 rng.uniform(-300, 300), 0), *point(), 20.0),
        lambda: (m.MAV_CMD_NAV_LOITER_TIME, 6, (rng.uniform(1, 90), 0, rng.uniform(1, 30), 0),
                 *point(), 20.0),
        lambda: (m.MAV_CMD_NAV_LOITER_UNLIM, 6, (0, 0, rng.uniform(1, 30), 0), *point(), 20.0),
        lambda: (m.MAV_CMD_NAV_LAND, 6, (0, rng.choice([0, 1, 2]), 0, rng.uniform(-360, 360)),
                 *point(), 20.0),
        lambda: (m.MAV_CMD_NAV_DELAY, 2, (rng.uniform(0, 30), -1, -1, -1), 0, 0, 0.0),
        lambda: (m.MAV_CMD_CONDITION_YAW, 2, (rng.uniform(0, 360), 0, rng.choice([-1, 1]),
                                              rng.choice([0, 1])), 0, 0, 0.0),
        lambda: (m.MAV_CMD_DO_CHANGE_SPEED, 2, (rng.randint(0, 3), rng.uniform(0.5, 12), -1, 0),
                 0, 0, 0.0),
        lambda: (m.MAV_CMD_DO_DIGICAM_CONTROL, 2, (0, 0, 0, 0), 1, 0, 0.0),
        lambda: (m.MAV_CMD_IMAGE_START_CAPTURE, 2, (0, rng.uniform(0.5, 5), rng.randint(0, 9),
                                                    0), 0, 0, 0.0),
        lambda: (m.MAV_CMD_IMAGE_STOP_CAPTURE, 2, (0, 0, 0, 0), 0, 0, 0.0),
        lambda: (m.MAV_CMD_DO_GRIPPER, 2, (1, rng.choice([0, 1]), 0, 0), 0, 0, 0.0),
        lambda: (m.MAV_CMD_DO_SET_HOME, 2, (1, 0, 0, 0), 0, 0, 0.0),
        lambda: (m.MAV_CMD_NAV_RETURN_TO_LAUNCH, 2, (0, 0, 0, 0), 0, 0, 0.0),
    ]
    items = []
    for seq in range(n):
        command, frame, params, x, y, z = rng.choice(kinds)()
        items.append(MissionItem(seq, frame, command, 0, 1, *map(float, params), x, y, z))
    return items


@pytest.mark.parametrize("count", [10, 100, 500])
def test_items_tml_compiles_read_back_with_no_difference_by_ardupilots_rules(
        ardupilot, count: int) -> None:
    (sitl,) = ardupilot()
    with Link(sitl.address) as link:
        vehicle = connect(link)
        sent = upload_when_ready(vehicle, compiled_mix(count, seed=count))  # and reads back
        back = vehicle.download()
    assert len(back) == count + 1  # behind ArduPilot's home
    assert read_back_differences(sent, back, ardupilot_form, skip_home=True) == []
    # Byte for byte, ArduCopter's read-back differs all over: the rules are what make it pass.
    assert len(read_back_differences(sent, back, exact_form, skip_home=True)) > count / 2


def test_an_item_changed_behind_tmls_back_is_named(ardupilot) -> None:
    (sitl,) = ardupilot()
    with Link(sitl.address) as link:
        vehicle = connect(link)
        sent = upload_when_ready(vehicle, compiled_mix(20, seed=7))
        vehicle.check_read_back(sent)  # as uploaded: no difference
        changed = next(item for item in sent[1:] if item.command == mavlink.MAV_CMD_NAV_WAYPOINT)
        replace_item(sitl.companion_address, changed, param1=7.0, z=changed.z + 3.0)
        with pytest.raises(MissionTransferError) as caught:
            vehicle.check_read_back(sent)
    assert caught.value.result == "MISMATCH"
    assert (f"item {changed.seq} MAV_CMD_NAV_WAYPOINT (16): param1 sent 0, read back 7"
            in str(caught.value))
    assert re.search(rf"item {changed.seq} MAV_CMD_NAV_WAYPOINT \(16\): z sent [\d.]+, "
                     r"read back [\d.]+ \(expected [\d.]+\)", str(caught.value))


def replace_item(address: str, item: MissionItem, **changes: float) -> None:
    """Write one item over with MISSION_WRITE_PARTIAL_LIST, as another ground station would."""
    conn = mavutil.mavlink_connection(address, source_system=251, source_component=190)
    try:
        conn.wait_heartbeat(timeout=30)
        target = (conn.target_system, conn.target_component)
        conn.mav.mission_write_partial_list_send(*target, item.seq, item.seq)
        request = conn.recv_match(type=["MISSION_REQUEST", "MISSION_REQUEST_INT"],
                                  blocking=True, timeout=10)
        assert request is not None and request.seq == item.seq
        values = {**item.__dict__, **changes}
        conn.mav.mission_item_int_send(
            *target, item.seq, values["frame"], values["command"], 0, 1, values["param1"],
            values["param2"], values["param3"], values["param4"], values["x"], values["y"],
            values["z"], 0)
        ack = conn.recv_match(type="MISSION_ACK", blocking=True, timeout=10)
        assert ack is not None and ack.type == mavlink.MAV_MISSION_ACCEPTED
    finally:
        conn.close()


def _f32(value: float) -> float:
    return struct.unpack("<f", struct.pack("<f", value))[0]


def test_the_recorded_read_backs_are_what_arducopter_reads_back(ardupilot) -> None:
    (sitl,) = ardupilot()
    cases = RECORDED["kept"] + RECORDED["wrapped"]
    items = [MissionItem(seq, frame, command, 0, 1, *params, x, y, z)
             for seq, case in enumerate(cases)
             for command, frame, *params, x, y, z in [case["sent"]]]
    with Link(sitl.address) as link:
        vehicle = connect(link)
        deadline = time.monotonic() + 30
        while True:  # NO_SPACE for a second after boot
            try:
                vehicle.upload(items, verify=False)
                break
            except MissionTransferError:
                assert time.monotonic() < deadline
                time.sleep(0.5)
        back = vehicle.download()[1:]
        for case, item in zip(cases, back, strict=True):
            frame, *params, x, y, z = case["read"]
            assert (item.frame, item.param1, item.param2, item.param3, item.param4, item.x,
                    item.y, item.z) == (frame, *map(_f32, params), x, y, _f32(z)), case
        for case in RECORDED["refused"]:
            command, frame, *params, x, y, z = case["sent"]
            with pytest.raises(MissionTransferError) as caught:
                vehicle.upload([MissionItem(0, frame, command, 0, 1, *params, x, y, z)],
                               verify=False)
            assert caught.value.result == case["result"], case
    assert not any(math.isnan(v) for case in cases for v in case["read"])


def test_mission_dispatch_flies_its_plan_on_arducopter(ardupilot, tmp_path: Path) -> None:
    (sitl,) = ardupilot()
    log = tmp_path / "mission_dispatch.jsonl"
    code = main(["run", str(ROOT / "missions" / "mission_dispatch.xml"), "--connect",
                 sitl.address, "-q", "--log", str(log)])
    lines = read(str(log))
    ended = [line for line in lines if line["kind"] == "run" and "outcomes" in line]
    reason = ended[-1]["outcomes"][0]["reason"] if ended else ""
    assert (code, reason) == (0, "all tasks done"), [
        line["message"] for line in lines if line["kind"] in ("action", "result", "error")][-8:]
    (plan,) = [line for line in lines if line["kind"] == "decision"
               and line["message"].endswith("actions flown as a mission")]
    assert plan["task"] == "Photo flight" and len(plan["actions"]) == 13
    # MISSION_CURRENT walked the plan through every task that holds a navigation item.
    running = {line["task"] for line in lines if line["kind"] == "task"
               and line["state"] == "running"}
    assert {f"Photo flight/{name}" for name in (
        "Fly to the first field", "Circle the first field twice", "Climb",
        "Hold over the second field", "Settle", "Settle again", "Land on the pad")} <= running
    states = {line["task"]: line["state"] for line in lines if line["kind"] == "task"}
    assert states["Photo flight"] == "done"
    last = [line for line in lines if line["kind"] == "telemetry"][-1]
    assert last["landed"] and not last["armed"]
