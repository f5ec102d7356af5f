"""Vehicle commands and mission transfers over loopback against the fake autopilot."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import pytest
from test_mavlink_link import FakeAutopilot, eventually

from sitl.faults import Faults
from sitl.server import Simulator
from tml.errors import CommandRejected, LinkLost, MissionTransferError, VehicleTimeout
from tml.mavlink.autopilot import TAKEN, Autopilot
from tml.mavlink.codec import mavlink
from tml.mavlink.command import CommandLong
from tml.mavlink.link import Link
from tml.mavlink.mission import MissionItem, MissionType, Progress
from tml.mavlink.telemetry import COMPANION_COMPONENT, Telemetry
from tml.timebase import Lockstep
from tml.world import World, WorldObject


@pytest.fixture
def fake() -> Iterator[FakeAutopilot]:
    with FakeAutopilot(system_id=1, command_results={
        mavlink.MAV_CMD_COMPONENT_ARM_DISARM: mavlink.MAV_RESULT_FAILED,
        mavlink.MAV_CMD_SET_MESSAGE_INTERVAL: mavlink.MAV_RESULT_UNSUPPORTED,
        mavlink.MAV_CMD_DO_GRIPPER: None,
    }) as ap:
        yield ap


@pytest.fixture
def vehicle(fake: FakeAutopilot) -> Iterator[Autopilot]:
    with Link(f"udpout:127.0.0.1:{fake.port}") as link:
        yield Autopilot.connect(link, 1, timeout=5)


class ForgetfulCopter(FakeAutopilot):
    """Carries out the first copy of each command but loses its ACK; answers the copies
    after it as ArduCopter does once the first was taken (FAILED, a FLIP: flips again).

    ``climbs``: a NAV_TAKEOFF makes it report itself in the air and climbing (else it
    stays on the ground and refuses the repeat all the same). A FLIP rolls it over
    (ATTITUDE) without a HEARTBEAT showing it, as when the HEARTBEATs of a short flip are
    lost, and leaves it in ALT_HOLD, where it started.
    """

    def __init__(self, climbs: bool = True) -> None:
        super().__init__(system_id=1)
        self.climbs = climbs
        self.modes[1] = 2  # ALT_HOLD
        self.flips = 0

    def heartbeat(self, system_id: int | None = None, **ids: Any) -> None:
        armed = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        self.send(mavlink.MAVLink_heartbeat_message(
            mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, armed,
            self.modes[1], 4, 3), **ids)

    def _answer(self, msg: Any) -> None:
        if msg.get_type() != "COMMAND_LONG":
            return super()._answer(msg)
        self.commands.append(msg)
        b = mavlink.MAVLink(None)
        if msg.command == mavlink.MAV_CMD_DO_SET_MODE and int(msg.param2) == 14:
            self.flips += 1
            for roll in (0.5, 1.6, 3.0, -1.4, 0.1):
                self.send(b.attitude_encode(0, roll, 0.0, 0.0, 0.0, 0.0, 0.0))
        if msg.confirmation == 0:
            if msg.command == mavlink.MAV_CMD_NAV_TAKEOFF and self.climbs:
                self.send(b.extended_sys_state_encode(0, mavlink.MAV_LANDED_STATE_IN_AIR))
                self.send(b.global_position_int_encode(0, -353632621, 1491652374, 586000,
                                                       2000, 0, 0, -150, 0))
            return  # taken, and its ACK lost
        self.send(b.command_ack_encode(msg.command, mavlink.MAV_RESULT_FAILED, 0, 0, 255, 190))


@pytest.fixture
def forgetful(request: pytest.FixtureRequest) -> Iterator[tuple[ForgetfulCopter, Autopilot]]:
    with ForgetfulCopter(climbs=getattr(request, "param", True)) as ap, \
            Link(f"udpout:127.0.0.1:{ap.port}") as link:
        yield ap, Autopilot(link, link.wait_vehicle(1, timeout=5), command_timeout=0.3)


def test_a_take_off_whose_ack_was_lost_is_judged_by_the_climb_not_by_the_refused_repeat(
        forgetful: tuple[ForgetfulCopter, Autopilot]) -> None:
    ap, vehicle = forgetful
    vehicle.takeoff(10.0)  # no ACK, but the vehicle is seen climbing before the timeout
    assert [c.confirmation for c in ap.commands] == [0]  # so it is not sent again


@pytest.mark.parametrize("forgetful", [False], indirect=True)
def test_a_refused_repeat_of_a_take_off_the_telemetry_does_not_show_is_a_refusal(
        forgetful: tuple[ForgetfulCopter, Autopilot]) -> None:
    ap, vehicle = forgetful
    with pytest.raises(CommandRejected) as caught:
        vehicle.takeoff(10.0)
    assert caught.value.result == "MAV_RESULT_FAILED"
    assert [c.confirmation for c in ap.commands] == [0, 1]


def test_a_flip_whose_ack_was_lost_is_not_sent_again_once_the_vehicle_rolled(
        forgetful: tuple[ForgetfulCopter, Autopilot]) -> None:
    ap, vehicle = forgetful
    vehicle.set_mode("FLIP")  # no ACK and no HEARTBEAT in FLIP: the roll shows it
    assert ap.flips == 1
    assert vehicle.telemetry.mode == "ALT_HOLD"


def test_every_command_judged_by_telemetry_has_a_rule_that_can_say_no() -> None:
    empty = Telemetry(1)
    for command, rule in TAKEN.items():
        assert not rule(CommandLong(command, 1.0, 99.0), empty, empty), command


def items(n: int) -> list[MissionItem]:
    return [MissionItem(seq=i, frame=6, command=16, x=-353632621 + 100 * i, y=1491652374,
                        z=20.0) for i in range(n)]


def test_mode_by_name_reaches_the_vehicle_and_shows_in_telemetry(
        fake: FakeAutopilot, vehicle: Autopilot) -> None:
    vehicle.set_mode("guided")
    assert fake.mode == 4
    assert vehicle.telemetry.mode == "GUIDED"  # set_mode waited for the HEARTBEAT


def test_a_vehicle_that_accepts_a_mode_but_keeps_its_own_is_caught() -> None:
    with FakeAutopilot(system_id=1, obey_modes=False) as stubborn, \
            Link(f"udpout:127.0.0.1:{stubborn.port}") as link:
        vehicle = Autopilot.connect(link, 1, timeout=5)
        with pytest.raises(CommandRejected) as caught:
            vehicle.set_mode("GUIDED")
        assert caught.value.command == "MAV_CMD_DO_SET_MODE"
        assert "ACCEPTED, but the next HEARTBEAT shows STABILIZE, not GUIDED" in str(caught.value)
        assert [c.command for c in stubborn.commands] == [mavlink.MAV_CMD_DO_SET_MODE]


def test_a_mode_change_without_a_heartbeat_after_the_ack_times_out() -> None:
    with FakeAutopilot(system_id=1, silent_after=mavlink.MAV_CMD_DO_SET_MODE) as mute, \
            Link(f"udpout:127.0.0.1:{mute.port}", lost_after=30.0) as link:
        vehicle = Autopilot(link, link.wait_vehicle(1, timeout=5), mode_timeout=0.3)
        with pytest.raises(VehicleTimeout, match="GUIDED accepted, but no HEARTBEAT"):
            vehicle.set_mode("GUIDED")
        assert mute.mode == 4  # it did switch: only the proof is missing


def test_refused_command_raises_command_rejected_with_names(vehicle: Autopilot) -> None:
    with pytest.raises(CommandRejected) as caught:
        vehicle.arm()
    error = caught.value
    assert (error.command, error.result, error.system_id) == (
        "MAV_CMD_COMPONENT_ARM_DISARM", "MAV_RESULT_FAILED", 1)


def test_unanswered_command_is_retransmitted_then_times_out(
        fake: FakeAutopilot, vehicle: Autopilot) -> None:
    impatient = Autopilot(vehicle.link, vehicle.info, command_timeout=0.05, command_retries=3)
    with pytest.raises(VehicleTimeout, match="MAV_CMD_DO_GRIPPER"):
        impatient.gripper(grab=True)
    sent = [m for m in fake.commands if m.command == mavlink.MAV_CMD_DO_GRIPPER]
    assert [m.confirmation for m in sent] == [0, 1, 2, 3]
    assert (sent[0].param1, sent[0].param2) == (1, mavlink.GRIPPER_ACTION_GRAB)


def test_convenience_commands_send_the_right_mav_cmds(fake: FakeAutopilot,
                                                      vehicle: Autopilot) -> None:
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


def test_rates_fall_back_to_request_data_stream(fake: FakeAutopilot, vehicle: Autopilot) -> None:
    assert vehicle.request_rates({"ATTITUDE": 10.0}) is False
    assert eventually(lambda: any(m.get_type() == "REQUEST_DATA_STREAM" and
                                  m.req_message_rate == 10 for m in fake.received))


def test_mission_upload_with_home_slot_and_read_back(fake: FakeAutopilot,
                                                     vehicle: Autopilot) -> None:
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
                                                          vehicle: Autopilot) -> None:
    fence = [MissionItem(seq=i, frame=5, command=5001, param1=3, x=i, y=i,
                         mission_type=MissionType.FENCE) for i in range(3)]
    vehicle.upload(fence, MissionType.FENCE)
    assert [m.command for m in fake.missions[MissionType.FENCE]] == [5001] * 3
    assert vehicle.download(MissionType.FENCE) == fence
    vehicle.clear(MissionType.FENCE)
    assert fake.missions[MissionType.FENCE] == []


def test_read_back_mismatch_is_a_transfer_error(fake: FakeAutopilot, vehicle: Autopilot) -> None:
    fake.store_altitude = 99.0  # a vehicle that does not keep what it was sent
    with pytest.raises(MissionTransferError) as caught:
        vehicle.upload(items(2))
    assert caught.value.result == "MISMATCH"
    assert str(caught.value).endswith(
        "mission read back differs from the upload: item 1 MAV_CMD_NAV_WAYPOINT (16): z sent "
        "20, read back 99; item 2 MAV_CMD_NAV_WAYPOINT (16): z sent 20, read back 99")


def test_ardupilot_read_back_is_compared_by_its_storage_rules(fake: FakeAutopilot,
                                                             vehicle: Autopilot) -> None:
    # The fake keeps what it is sent: a hold of 2.5 s that ArduPilot would store as 2 s is
    # a difference, and a yaw that ArduPilot drops is not compared.
    hold = [replace(item, param1=2.5, param4=90.0) for item in items(5)]
    with pytest.raises(MissionTransferError) as caught:
        vehicle.upload(hold)
    assert ("item 1 MAV_CMD_NAV_WAYPOINT (16): param1 sent 2.5, read back 2.5 (expected 2); "
            "item 2 " in str(caught.value))
    assert str(caught.value).endswith("(and 2 more)")
    vehicle.upload([replace(item, param1=2.0, param4=90.0) for item in items(5)])


# -- against the simulator over loopback ------------------------------------------------


@pytest.fixture
def sim_link() -> Iterator[tuple[Simulator, Link]]:
    with Simulator(vehicles=1, tcp_base_port=0, speedup=20.0) as sim, \
            Link(f"tcp:127.0.0.1:{sim.tcp_ports[0]}") as link:
        yield sim, link


def test_simulated_copter_is_discovered_takes_off_and_reports_it(
        sim_link: tuple[Simulator, Link]) -> None:
    sim, link = sim_link
    vehicle = Autopilot.connect(link, 1, timeout=10)
    assert (vehicle.info.vehicle_type, vehicle.info.autopilot) == (
        mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA)
    assert vehicle.request_rates() is True
    with pytest.raises(CommandRejected):  # not armable before the EKF uses GPS
        vehicle.arm()
    link.wait_telemetry(1, lambda t: t.position_ready, timeout=30)
    vehicle.set_mode("GUIDED")
    vehicle.arm()
    vehicle.takeoff(10.0)
    flying = link.wait_telemetry(
        1, lambda t: t.position is not None and t.position.relative_altitude > 9.0, timeout=30)
    assert flying.armed and flying.mode == "GUIDED"
    assert sim.vehicle(1).armed and sim.vehicle(1).mode == "GUIDED"
    vehicle.land()
    link.wait_telemetry(1, lambda t: not t.armed, timeout=60)


def test_simulated_copter_mode_changes_are_confirmed_or_refused() -> None:
    # The EKF never uses GPS here, and an idle armed vehicle does not disarm by itself.
    params = {"SIM_EKF_GPS_TIME": 1000, "DISARM_DELAY": 0}
    with Simulator(vehicles=1, tcp_base_port=0, speedup=20.0, params=params) as sim, \
            Link(f"tcp:127.0.0.1:{sim.tcp_ports[0]}") as link:
        vehicle = Autopilot.connect(link, 1, timeout=10)
        vehicle.set_mode("GUIDED")  # disarmed, ArduCopter enters any mode
        vehicle.set_mode("LAND")  # returns only once a HEARTBEAT has shown LAND
        assert vehicle.telemetry.mode == "LAND" and sim.vehicle(1).mode == "LAND"
        vehicle.set_mode("stabilize")
        assert vehicle.telemetry.mode == "STABILIZE"
        assert eventually(lambda: arms(vehicle), timeout=30)  # STABILIZE: ~23 s vehicle time
        with pytest.raises(CommandRejected) as caught:  # armed, GUIDED needs the position
            vehicle.set_mode("GUIDED")
        assert caught.value.result == "MAV_RESULT_FAILED" and sim.vehicle(1).mode == "STABILIZE"


def arms(vehicle: Autopilot) -> bool:
    """One arming attempt: True when accepted."""
    try:
        vehicle.arm()
    except CommandRejected:
        return False
    return True


def test_simulated_copter_keeps_an_uploaded_mission_in_items_1_to_n(
        sim_link: tuple[Simulator, Link]) -> None:
    sim, link = sim_link
    vehicle = Autopilot.connect(link, 1, timeout=10)
    assert eventually(lambda: sim.time > 1.5)  # uploads are refused for a second after boot
    sent = vehicle.upload(items(50))  # read back and compared from item 1 on
    stored = sim.vehicle(1).mission_items
    assert len(stored) == 51
    assert [(m.x, m.y, m.z) for m in stored[1:]] == [(i.x, i.y, i.z) for i in items(50)]
    assert sent[0] != vehicle.download()[0]  # home, written by the vehicle
    vehicle.clear()
    assert len(vehicle.download()) <= 1


@pytest.mark.timeout(60)
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_upload_and_read_back_survive_30_percent_loss_each_way(seed: int) -> None:
    # In lock-step, so that the messages the seeded faults drop are the same on any machine.
    timebase = Lockstep()
    faults = Faults(seed=seed, loss_in=0.3, loss_out=0.3)
    sent = items(8)
    with timebase.taking_part(), \
            Simulator(vehicles=1, tcp_base_port=0, speedup=50.0, faults=faults,
                      lockstep=timebase) as sim, \
            Link(f"tcp:127.0.0.1:{sim.tcp_ports[0]}", timebase=timebase) as link:
        vehicle = Autopilot.connect(link, 1, timeout=20)
        timebase.sleep(1.5 - timebase.now())  # uploads are refused a second after boot
        vehicle.upload(sent)  # read back over the same lossy link and compared, or raises
        assert [(m.seq - 1, m.x, m.z) for m in sim.vehicle(1).mission_items[1:]] == [
            (i.seq, i.x, i.z) for i in sent]
        # The loss was real, and seen in the sequence gaps: 30 % of some 40 messages.
        assert 0.1 < link.telemetry(1).loss < 0.5


def test_a_simulated_outage_makes_the_vehicle_lost_until_it_ends() -> None:
    # Nothing gets through between 20 s and 60 s of vehicle time (1 s to 3 s of wall time).
    faults = Faults(outages=((20.0, 60.0),))
    with Simulator(vehicles=1, tcp_base_port=0, speedup=20.0, faults=faults) as sim, \
            Link(f"tcp:127.0.0.1:{sim.tcp_ports[0]}", lost_after=0.5) as link:
        vehicle = Autopilot.connect(link, 1, timeout=10)
        lost = link.wait_telemetry(1, lambda t: t.link_lost, timeout=20)
        assert sim.faults.in_outage(sim.time) and lost.mode == "STABILIZE"
        with pytest.raises(LinkLost):  # sent once, but its retries are not waited out
            vehicle.set_mode("LAND")
        back = link.wait_telemetry(1, lambda t: not t.link_lost, timeout=20, lost_ok=True)
        assert sim.time >= 60.0 and back.last_heartbeat is not None
        vehicle.set_mode("LAND")
        assert sim.vehicle(1).mode == "LAND"


def test_an_object_under_the_flying_vehicle_is_detected_over_the_link() -> None:
    world = World(objects=(
        WorldObject("marker", "7", north=1.0, east=-1.0),  # under the take-off point
        WorldObject("aruco", "3", north=0.0, east=1.0),  # in view, but its skill stays off
        WorldObject("marker", "8", north=200.0, east=0.0),  # far outside the footprint
    ))
    quick_fix = {"SIM_GPS_LOCKTIME": 1.0, "SIM_EKF_GPS_TIME": 2.0}
    with Simulator(vehicles=1, tcp_base_port=0, speedup=20.0, world=world,
                   params=quick_fix) as sim, \
            Link(f"tcp:127.0.0.1:{sim.tcp_ports[0]}") as link:
        vehicle = Autopilot.connect(link, 1, timeout=10)
        vehicle.request_rates()  # nothing streams until asked, as on ArduPilot
        link.send(mavlink.MAVLink_param_set_message(1, COMPANION_COMPONENT, b"RECOG_MARKERS", 1,
                                                    mavlink.MAV_PARAM_TYPE_REAL32))
        link.wait_telemetry(1, lambda t: t.position_ready, timeout=30)
        vehicle.set_mode("GUIDED")
        vehicle.arm()
        vehicle.takeoff(10.0)
        seen = link.wait_telemetry(1, lambda t: ("MARKER", 7) in t.sightings, timeout=30)
        assert seen.detections["MARKER"] == 7 and "ARUCO" not in seen.detections
        assert link.wait_telemetry(
            1, lambda t: t.sightings[("MARKER", 7)].position is not None, timeout=10
        ).sightings[("MARKER", 7)].position == (1.0, -1.0, 0.0)
        assert ("MARKER", 8) not in link.telemetry(1).sightings
        assert sim.vehicle(1).armed


def test_two_simulated_vehicles_on_two_links_are_kept_apart() -> None:
    with Simulator(vehicles=2, tcp_base_port=0, speedup=20.0) as sim, \
            Link(f"tcp:127.0.0.1:{sim.tcp_ports[0]}") as one, \
            Link(f"tcp:127.0.0.1:{sim.tcp_ports[1]}") as two:
        first, second = Autopilot.connect(one, 1, timeout=10), Autopilot.connect(two, 2, timeout=10)
        second.set_mode("LAND")
        assert eventually(lambda: second.telemetry.mode == "LAND")
        assert sim.vehicle(2).mode == "LAND" and sim.vehicle(1).mode != "LAND"
        assert first.telemetry.mode != "LAND" and sorted(one.vehicles()) == [1]
