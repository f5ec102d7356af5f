"""Flight modes by name for ArduPilot Copter, Plane, Rover and PX4, and confirming a change."""

from __future__ import annotations

import pytest

from tml.errors import CommandRejected, VehicleError, VehicleTimeout
from tml.mavlink.codec import mavlink
from tml.mavlink.command import CommandAck, Heartbeat
from tml.mavlink.modes import (
    CONFIRM_TIMEOUT,
    ModeChange,
    mode_name,
    mode_names,
    set_mode_command,
)

ARDUPILOT = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
PX4 = mavlink.MAV_AUTOPILOT_PX4
QUAD, PLANE, ROVER = (mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_TYPE_FIXED_WING,
                      mavlink.MAV_TYPE_GROUND_ROVER)
CUSTOM = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


@pytest.mark.parametrize(("vehicle_type", "name", "number"), [
    (QUAD, "GUIDED", 4), (QUAD, "AUTO", 3), (QUAD, "LAND", 9), (QUAD, "RTL", 6),
    (QUAD, "LOITER", 5), (PLANE, "GUIDED", 15), (PLANE, "AUTO", 10), (PLANE, "FBWA", 5),
    (ROVER, "HOLD", 4), (ROVER, "GUIDED", 15), (ROVER, "AUTO", 10),
])
def test_ardupilot_modes_use_the_vehicle_kinds_custom_mode_numbers(
        vehicle_type: int, name: str, number: int) -> None:
    command = set_mode_command(vehicle_type, ARDUPILOT, name.lower())
    assert (command.command, command.param1, command.param2) == (176, CUSTOM, number)
    assert mode_name(vehicle_type, ARDUPILOT, CUSTOM, number) == name


@pytest.mark.parametrize(("name", "main", "sub"), [("MISSION", 4, 4), ("OFFBOARD", 6, 0),
                                                   ("POSCTL", 3, 0), ("RTL", 4, 5)])
def test_px4_modes_use_main_and_sub_modes(name: str, main: int, sub: int) -> None:
    command = set_mode_command(QUAD, PX4, name)
    assert (command.param2, command.param3) == (main, sub)
    assert command.param1 == command.param1 // 1 and int(command.param1) & CUSTOM
    assert mode_name(QUAD, PX4, int(command.param1), (main << 16) | (sub << 24)) == name


def test_unknown_mode_names_the_modes_there_are() -> None:
    with pytest.raises(VehicleError, match=r"'HOVER'.*GUIDED") as caught:
        set_mode_command(QUAD, ARDUPILOT, "HOVER", system_id=2)
    assert caught.value.system_id == 2
    with pytest.raises(VehicleError, match="STABILIZE"):
        set_mode_command(QUAD, PX4, "STABILIZE")


def test_mode_lists_differ_between_vehicle_kinds() -> None:
    assert "FBWA" in mode_names(PLANE, ARDUPILOT) and "FBWA" not in mode_names(QUAD, ARDUPILOT)
    assert "OFFBOARD" in mode_names(QUAD, PX4)
    assert mode_name(QUAD, ARDUPILOT, CUSTOM, 99) == "Mode(99)"


# -- confirming a mode change (sans-IO, time injected) --------------------------------------

ACCEPTED = mavlink.MAV_RESULT_ACCEPTED


def beat(custom_mode: int, seq: int | None = None) -> Heartbeat:
    return Heartbeat(QUAD, ARDUPILOT, CUSTOM, custom_mode, seq)


def guided_change(**options: float) -> ModeChange:
    change = ModeChange(set_mode_command(QUAD, ARDUPILOT, "GUIDED"), "guided", system_id=1,
                        **options)
    assert [m.command for m in change.start(0.0)] == [mavlink.MAV_CMD_DO_SET_MODE]
    return change


def test_a_mode_change_is_done_when_the_heartbeat_after_the_ack_shows_it() -> None:
    change = guided_change()
    change.receive(beat(4, seq=10), 0.1)  # before the ACK: proves nothing
    assert not change.done
    change.receive(CommandAck(mavlink.MAV_CMD_DO_SET_MODE, ACCEPTED, packet_seq=11), 0.2)
    assert not change.done and change.deadline == pytest.approx(0.2 + CONFIRM_TIMEOUT)
    change.receive(beat(4, seq=12), 0.9)
    assert change.done and change.error is None and change.shown == "GUIDED"


def test_a_heartbeat_showing_another_mode_after_the_ack_is_a_rejection() -> None:
    change = guided_change()
    change.receive(CommandAck(mavlink.MAV_CMD_DO_SET_MODE, ACCEPTED, packet_seq=250), 0.1)
    change.receive(beat(0, seq=3), 0.8)  # after the ACK, across the sequence wrap
    assert change.done and isinstance(change.error, CommandRejected)
    assert change.error.command == "MAV_CMD_DO_SET_MODE" and change.error.system_id == 1
    assert "shows STABILIZE, not GUIDED" in change.error.result


def test_a_heartbeat_sent_before_the_ack_but_arriving_after_it_is_not_the_answer() -> None:
    change = guided_change()
    change.receive(CommandAck(mavlink.MAV_CMD_DO_SET_MODE, ACCEPTED, packet_seq=2), 0.1)
    change.receive(beat(0, seq=250), 0.11)  # overtaken on the way (UDP reorders)
    assert not change.done
    change.receive(beat(4, seq=9), 1.1)
    assert change.done and change.error is None


def test_no_heartbeat_within_the_limit_after_the_ack_is_a_timeout() -> None:
    change = guided_change(confirm_timeout=2.0)
    change.receive(CommandAck(mavlink.MAV_CMD_DO_SET_MODE, ACCEPTED), 0.1)
    assert change.tick(2.0) == [] and not change.done
    change.tick(2.1)
    assert change.done and isinstance(change.error, VehicleTimeout)
    assert "GUIDED accepted, but no HEARTBEAT within 2 s" in str(change.error)
    change.receive(beat(4), 2.2)
    assert isinstance(change.error, VehicleTimeout)  # too late to change the outcome


def test_a_refused_or_unanswered_mode_command_fails_as_a_command() -> None:
    refused = guided_change()
    refused.receive(CommandAck(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_RESULT_FAILED), 0.1)
    assert refused.done and isinstance(refused.error, CommandRejected)
    assert refused.error.result == "MAV_RESULT_FAILED"
    silent = guided_change(timeout=1.0, retries=1)
    assert [m.confirmation for m in silent.tick(1.0)] == [1]  # retransmitted, confirmation 1
    silent.tick(2.0)
    assert silent.done and isinstance(silent.error, VehicleTimeout)


def test_a_flip_is_confirmed_by_its_ack_alone_as_it_may_end_before_the_next_heartbeat() -> None:
    flip = ModeChange(set_mode_command(QUAD, ARDUPILOT, "FLIP"), "flip", system_id=1)
    flip.start(0.0)
    flip.receive(beat(14, seq=1), 0.1)
    assert not flip.done
    flip.receive(CommandAck(mavlink.MAV_CMD_DO_SET_MODE, ACCEPTED, packet_seq=2), 0.2)
    assert flip.done and flip.error is None
    refused = ModeChange(set_mode_command(QUAD, ARDUPILOT, "FLIP"), "FLIP", system_id=1)
    refused.start(0.0)
    refused.receive(CommandAck(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_RESULT_FAILED), 0.1)
    assert isinstance(refused.error, CommandRejected)


def test_the_mode_watch_tells_a_mode_nobody_here_asked_for() -> None:
    from tml.mavlink.modes import ModeWatch

    watch = ModeWatch()
    assert not watch.seen("STABILIZE", armed=False, now=0.0)  # its own mode before an ask
    watch.ask("GUIDED")
    assert not watch.seen("STABILIZE", armed=True, now=1.0)  # the old one, until GUIDED shows
    assert not watch.seen("GUIDED", armed=True, now=2.0)
    watch.ask("AUTO")
    watch.refused()  # AUTO refused: GUIDED is still expected
    assert not watch.seen("GUIDED", armed=True, now=3.0)
    watch.ask("FLIP")
    assert not watch.seen("ALT_HOLD", armed=True, now=4.0)  # where a flip ends by itself
    watch.ask("GUIDED")
    assert not watch.seen("GUIDED", armed=True, now=5.0) and watch.taken == ""
    assert not watch.seen("LAND", armed=True, now=6.0)  # one HEARTBEAT says nothing yet
    assert watch.seen("LAND", armed=True, now=7.0) and watch.taken == "LAND"
    assert not watch.seen("RTL", armed=True, now=8.0) and watch.taken == "LAND"  # said once


def test_one_forged_heartbeat_between_the_real_ones_takes_nothing() -> None:
    from tml.mavlink.modes import ModeWatch

    watch = ModeWatch()
    watch.ask("GUIDED")
    assert not watch.seen("GUIDED", armed=True, now=10.0)
    for t in (10.5, 11.5, 12.5):  # a spoofer says LAND between the autopilot's GUIDEDs
        assert not watch.seen("LAND", armed=True, now=t)
        assert not watch.seen("GUIDED", armed=True, now=t + 0.5)
    assert watch.taken == ""


def test_a_mode_adopted_as_the_vehicle_flies_in_it_makes_another_a_take_over() -> None:
    """A resumed or continued run finds the vehicle flying in GUIDED and asks no switch:
    GUIDED is adopted, and an operator's RTL after it is told as a take-over."""
    from tml.mavlink.modes import ModeWatch

    watch = ModeWatch()
    assert not watch.seen("RTL", armed=True, now=0.0)
    assert not watch.seen("RTL", armed=True, now=2.0)  # nothing asked: its own mode
    watch.adopt("GUIDED")
    assert not watch.seen("GUIDED", armed=True, now=3.0)
    assert not watch.seen("RTL", armed=True, now=4.0)
    assert watch.seen("RTL", armed=True, now=5.0) and watch.taken == "RTL"
    asked = ModeWatch()
    asked.ask("AUTO")
    asked.adopt("GUIDED")  # a mode asked already is kept
    assert asked.asked == "AUTO"


def test_a_mode_change_on_the_ground_disarmed_is_not_taken() -> None:
    from tml.mavlink.modes import ModeWatch

    watch = ModeWatch()
    watch.ask("LAND")
    assert not watch.seen("LAND", armed=True, now=0.0)
    assert not watch.seen("STABILIZE", armed=False, now=1.0)
    assert not watch.seen("STABILIZE", armed=False, now=2.0) and watch.taken == ""


def test_auto_to_rtl_is_a_take_over_on_a_copter_and_the_end_of_a_planes_mission() -> None:
    from tml.mavlink.modes import ModeWatch

    copter, plane = ModeWatch(), ModeWatch(fixed_wing=True)
    for watch in (copter, plane):
        watch.ask("AUTO")
        watch.seen("AUTO", armed=True, now=0.0)
        watch.seen("RTL", armed=True, now=1.0)  # ArduCopter's fence breached: AUTO -> RTL
        watch.seen("RTL", armed=True, now=2.0)
    assert (copter.taken, plane.taken) == ("RTL", "")
