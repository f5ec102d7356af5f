"""Vehicle commands and mission transfers over loopback against the fake autopilot."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from test_mavlink_link import FakeAutopilot, eventually

from tml.errors import CommandRejected, MissionTransferError, VehicleTimeout
from tml.mavlink.codec import mavlink
from tml.mavlink.link import Link
from tml.mavlink.mission import MissionItem, MissionType, Progress
from tml.mavlink.vehicle import Vehicle


@pytest.fixture
def fake() -> Iterator[FakeAutopilot]:
    with FakeAutopilot(system_id=1, command_results={
        mavlink.MAV_CMD_COMPONENT_ARM_DISARM: mavlink.MAV_RESULT_FAILED,
        mavlink.MAV_CMD_SET_MESSAGE_INTERVAL: mavlink.MAV_RESULT_UNSUPPORTED,
        mavlink.MAV_CMD_DO_GRIPPER: None,
    }) as ap:
        yield ap


@pytest.fixture
def vehicle(fake: FakeAutopilot) -> Iterator[Vehicle]:
    with Link(f"udpout:127.0.0.1:{fake.port}") as link:
        yield Vehicle.connect(link, 1, timeout=5)


def items(n: int) -> list[MissionItem]:
    return [MissionItem(seq=i, frame=6, command=16, x=-353632621 + 100 * i, y=1491652374,
                        z=20.0) for i in range(n)]


def test_mode_by_name_reaches_the_vehicle_and_shows_in_telemetry(
        fake: FakeAutopilot, vehicle: Vehicle) -> None:
    vehicle.set_mode("guided")
    assert fake.mode == 4
    assert eventually(lambda: vehicle.telemetry.mode == "GUIDED")


def test_refused_command_raises_command_rejected_with_names(vehicle: Vehicle) -> None:
    with pytest.raises(CommandRejected) as caught:
        vehicle.arm()
    error = caught.value
    assert (error.command, error.result, error.system_id) == (
        "MAV_CMD_COMPONENT_ARM_DISARM", "MAV_RESULT_FAILED", 1)


def test_unanswered_command_is_retransmitted_then_times_out(
        fake: FakeAutopilot, vehicle: Vehicle) -> None:
    impatient = Vehicle(vehicle.link, vehicle.info, command_timeout=0.05, command_retries=3)
    with pytest.raises(VehicleTimeout, match="MAV_CMD_DO_GRIPPER"):
        impatient.gripper(grab=True)
    sent = [m for m in fake.commands if m.command == mavlink.MAV_CMD_DO_GRIPPER]
    assert [m.confirmation for m in sent] == [0, 1, 2, 3]
    assert (sent[0].param1, sent[0].param2) == (1, mavlink.GRIPPER_ACTION_GRAB)


def test_convenience_commands_send_the_right_mav_cmds(fake: FakeAutopilot,
                                                      vehicle: Vehicle) -> None:
    vehicle.takeoff(12.0)
    vehicle.land()
    vehicle.return_to_launch()
    vehicle.change_speed(4.0)
    vehicle.yaw(90.0, relative=True)
    vehicle.reposition(-35.36, 149.16, 15.0)
    vehicle.set_home()
    vehicle.set_home(-35.0, 149.0, 600.0)
    vehicle.start_mission()
    vehicle.set_current(2)
    vehicle.take_photo()
    got = [(m.get_type(), m.command) for m in fake.commands]
    assert got == [
        ("COMMAND_LONG", 22), ("COMMAND_LONG", 21), ("COMMAND_LONG", 20),
        ("COMMAND_LONG", 178), ("COMMAND_LONG", 115), ("COMMAND_INT", 192),
        ("COMMAND_LONG", 179), ("COMMAND_INT", 179), ("COMMAND_LONG", 300),
        ("COMMAND_LONG", 224), ("COMMAND_LONG", 203)]
    takeoff, reposition = fake.commands[0], fake.commands[5]
    assert takeoff.param7 == 12.0
    assert (reposition.x, reposition.y, reposition.z) == (-353600000, 1491600000, 15.0)


def test_rates_fall_back_to_request_data_stream(fake: FakeAutopilot, vehicle: Vehicle) -> None:
    assert vehicle.request_rates({"ATTITUDE": 10.0}) is False
    assert eventually(lambda: any(m.get_type() == "REQUEST_DATA_STREAM" and
                                  m.req_message_rate == 10 for m in fake.received))


def test_mission_upload_with_home_slot_and_read_back(fake: FakeAutopilot,
                                                     vehicle: Vehicle) -> None:
    progress: list[Progress] = []
    sent = vehicle.upload(items(20), on_progress=progress.append)
    stored = fake.missions[MissionType.MISSION]
    assert len(stored) == 21 and stored[0].x == -353632621 and stored[0].frame == 0
    assert [m.seq for m in stored] == list(range(21)) and stored[1].z == 20.0
    assert sent[1:] == [MissionItem(**{**item.__dict__, "seq": item.seq + 1})
                        for item in items(20)]
    requests = [m for m in fake.received if m.get_type() == "MISSION_ITEM_INT"]
    assert len(requests) >= 21
    assert all(p.done <= p.total for p in progress)


def test_fence_upload_keeps_seq_zero_and_clear_empties_it(fake: FakeAutopilot,
                                                          vehicle: Vehicle) -> None:
    fence = [MissionItem(seq=i, frame=5, command=5001, param1=3, x=i, y=i,
                         mission_type=MissionType.FENCE) for i in range(3)]
    vehicle.upload(fence, MissionType.FENCE)
    assert [m.command for m in fake.missions[MissionType.FENCE]] == [5001] * 3
    assert vehicle.download(MissionType.FENCE) == fence
    vehicle.clear(MissionType.FENCE)
    assert fake.missions[MissionType.FENCE] == []


def test_read_back_mismatch_is_a_transfer_error(fake: FakeAutopilot, vehicle: Vehicle) -> None:
    fake.store_altitude = 99.0  # a vehicle that does not keep what it was sent
    with pytest.raises(MissionTransferError) as caught:
        vehicle.upload(items(2))
    assert caught.value.result == "MISMATCH" and "read back differs" in str(caught.value)
