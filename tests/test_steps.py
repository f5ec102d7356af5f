"""Procedures (tml.mavlink.steps): driven by hand without a link, by the calling thread
(Link.drive), and by the link's reactor (Link.begin) against the fake autopilot of
test_mavlink_link over loopback UDP."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import pytest
from test_mavlink_link import FakeAutopilot, eventually

from tml.errors import CommandRejected, LinkLost, VehicleError, VehicleTimeout
from tml.mavlink import codec
from tml.mavlink.adapter import MavlinkVehicle
from tml.mavlink.autopilot import Autopilot, arm_command, takeoff_command
from tml.mavlink.codec import mavlink
from tml.mavlink.command import CommandAck, CommandLong, CommandResult, CommandSender
from tml.mavlink.link import Link, VehicleInfo
from tml.mavlink.modes import ModeChange
from tml.mavlink.reactor import THREAD_NAME
from tml.mavlink.steps import Exchange, Steps, Until
from tml.mavlink.telemetry import Telemetry
from tml.timebase import SYSTEM
from tml.vehicle import Flip, RequestResult, TakeOff

GRIPPER = mavlink.MAV_CMD_DO_GRIPPER
COPTER = VehicleInfo(1, 1, mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                     frozenset({1}))


class NoLink:
    """All an Autopilot's procedures read of a link: the vehicle's snapshot."""

    def telemetry(self, system_id: int) -> Telemetry:
        return Telemetry(system_id=system_id)


def by_hand() -> Autopilot:
    return Autopilot(NoLink(), COPTER)  # type: ignore[arg-type]


# -- by hand: a procedure is a state machine that does no I/O ---------------------------------


def test_a_command_is_one_exchange_over_when_its_ack_comes() -> None:
    steps = by_hand().commanding(arm_command())
    step = next(steps)
    assert isinstance(step, Exchange) and isinstance(step.machine, CommandSender)
    [sent] = step.machine.start(0.0)
    assert (sent.command, sent.param1) == (mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    step.machine.receive(CommandAck(sent.command, CommandResult.MAV_RESULT_ACCEPTED), 0.1)
    with pytest.raises(StopIteration):
        steps.send(None)


def test_a_refusal_is_raised_where_the_procedure_waited() -> None:
    def take_off(autopilot: Autopilot) -> Steps[str]:
        try:
            yield from autopilot.commanding(takeoff_command(5.0))
        except CommandRejected as refused:
            return f"refused: {refused.result}"
        return "flying"

    steps = take_off(by_hand())
    step = next(steps)
    assert isinstance(step, Exchange)
    [sent] = step.machine.start(0.0)
    step.machine.receive(CommandAck(sent.command, CommandResult.MAV_RESULT_FAILED), 0.1)
    with pytest.raises(StopIteration) as over:
        steps.send(None)
    assert over.value.value == "refused: MAV_RESULT_FAILED"


def test_silence_is_the_machines_own_deadline_and_retries() -> None:
    autopilot = by_hand()
    steps = autopilot.commanding(CommandLong(GRIPPER))
    step = next(steps)
    assert isinstance(step, Exchange)
    machine = step.machine
    sends = len(machine.start(0.0))
    while not machine.done:
        sends += len(machine.tick(machine.deadline))
    assert sends == 1 + autopilot.command_retries  # sent, retried, then given up
    with pytest.raises(VehicleTimeout):
        steps.send(None)


# -- by the link ------------------------------------------------------------------------------


def two_commands(autopilot: Autopilot, seen: list[str]) -> Steps[int]:
    """Arms, then asks for the gripper; notes the thread each part ran on."""
    seen.append(threading.current_thread().name)
    yield from autopilot.commanding(arm_command())
    seen.append(threading.current_thread().name)
    yield from autopilot.commanding(CommandLong(GRIPPER))
    seen.append(threading.current_thread().name)
    return 2


@pytest.fixture
def rig() -> Iterator[tuple[FakeAutopilot, Link, Autopilot]]:
    with FakeAutopilot(system_id=1) as fake, \
            Link(f"udpout:127.0.0.1:{fake.port}", lost_after=0.5) as link:
        yield fake, link, Autopilot.connect(link, 1, timeout=5)


def fake_heard(fake: FakeAutopilot, command: int) -> bool:
    """Whether ``command`` reached the fake (bounded wait: the socket may lag the send)."""
    return eventually(lambda: any(c.command == command for c in fake.commands))


class Ended:
    """Collects what Link.begin reports when a procedure is over."""

    def __init__(self) -> None:
        self.calls: list[tuple[Any, BaseException | None, str]] = []

    def __call__(self, outcome: Any, error: BaseException | None) -> None:
        self.calls.append((outcome, error, threading.current_thread().name))

    def wait(self) -> tuple[Any, BaseException | None, str]:
        assert eventually(lambda: bool(self.calls), 10.0), "the procedure never ended"
        [call] = self.calls
        return call


def test_the_calling_thread_drives_a_procedure_and_waits(
        rig: tuple[FakeAutopilot, Link, Autopilot]) -> None:
    fake, _link, autopilot = rig
    seen: list[str] = []
    assert autopilot.do(two_commands(autopilot, seen)) == 2
    assert set(seen) == {threading.current_thread().name}
    assert [c.command for c in fake.commands] == [mavlink.MAV_CMD_COMPONENT_ARM_DISARM, GRIPPER]


def test_the_reactor_drives_a_procedure_without_a_thread_of_its_own(
        rig: tuple[FakeAutopilot, Link, Autopilot]) -> None:
    fake, link, autopilot = rig
    threads = {t.name for t in threading.enumerate()}
    seen: list[str] = []
    ended = Ended()
    link.begin(two_commands(autopilot, seen), 1, 1, ended)
    # (The reactor may resume it before this line: only the first entry is known yet.)
    assert seen[0] == threading.current_thread().name, "begun here, up to its first step"
    assert fake_heard(fake, mavlink.MAV_CMD_COMPONENT_ARM_DISARM), "whose command went out"
    assert ended.wait() == (2, None, THREAD_NAME)
    assert seen[1:] == [THREAD_NAME] * 2, "the rest of it ran on the reactor's thread"
    assert {t.name for t in threading.enumerate()} <= threads
    assert [c.command for c in fake.commands] == [mavlink.MAV_CMD_COMPONENT_ARM_DISARM, GRIPPER]


def test_a_refusal_ends_the_procedure_with_it(
        rig: tuple[FakeAutopilot, Link, Autopilot]) -> None:
    fake, link, autopilot = rig
    fake.command_results[GRIPPER] = mavlink.MAV_RESULT_DENIED
    ended = Ended()
    link.begin(two_commands(autopilot, []), 1, 1, ended)
    outcome, error, _ = ended.wait()
    assert outcome is None and isinstance(error, CommandRejected)
    assert error.result == "MAV_RESULT_DENIED"


def test_an_until_resumes_at_the_message_that_makes_it_hold(
        rig: tuple[FakeAutopilot, Link, Autopilot]) -> None:
    _fake, link, autopilot = rig

    def guided_then_seen() -> Steps[str]:
        yield from autopilot.switching("GUIDED")  # the fake obeys: its HEARTBEAT shows it
        yield Until(lambda: link.telemetry(1).mode == "GUIDED", 5.0, "GUIDED shown")
        return link.telemetry(1).mode

    ended = Ended()
    link.begin(guided_then_seen(), 1, 1, ended)
    assert ended.wait()[:2] == ("GUIDED", None)


def test_an_until_that_never_holds_times_out(
        rig: tuple[FakeAutopilot, Link, Autopilot]) -> None:
    _fake, link, _autopilot = rig

    def never() -> Steps[None]:
        yield Until(lambda: False, 0.3, "nothing")

    ended = Ended()
    link.begin(never(), 1, 1, ended)
    _outcome, error, _ = ended.wait()
    assert isinstance(error, VehicleTimeout)
    assert str(error) == "vehicle 1: nothing not reached within 0.3 s"


def test_a_vehicle_lost_during_a_step_ends_it_with_link_lost(
        rig: tuple[FakeAutopilot, Link, Autopilot]) -> None:
    fake, link, autopilot = rig
    fake.command_results[GRIPPER] = None  # never answered: 7.5 s of retries
    fake.silent_after = GRIPPER
    ended = Ended()
    link.begin(two_commands(autopilot, []), 1, 1, ended)
    _outcome, error, _ = ended.wait()
    assert isinstance(error, LinkLost) and "during CommandSender" in str(error)


def test_a_procedure_waiting_when_the_link_closes_ends_with_link_lost() -> None:
    with FakeAutopilot(system_id=1, command_results={GRIPPER: None}) as fake:
        link = Link(f"udpout:127.0.0.1:{fake.port}").start()
        autopilot = Autopilot.connect(link, 1, timeout=5)
        ended = Ended()
        link.begin(autopilot.commanding(CommandLong(GRIPPER)), 1, 1, ended)
        assert eventually(lambda: bool(fake.commands)), "the command went out"
        link.close()
        _outcome, error, _ = ended.wait()
        assert isinstance(error, LinkLost) and "closed" in str(error)
        again = Ended()
        link.begin(autopilot.commanding(CommandLong(GRIPPER)), 1, 1, again)
        assert isinstance(again.wait()[1], LinkLost), "a closed link begins nothing"


def test_a_wait_on_the_reactors_own_thread_is_refused(
        rig: tuple[FakeAutopilot, Link, Autopilot]) -> None:
    _fake, link, autopilot = rig

    def blocking() -> Steps[None]:
        yield from autopilot.commanding(arm_command())
        autopilot.arm()  # would wait for the reactor, on the reactor

    ended = Ended()
    link.begin(blocking(), 1, 1, ended)
    _outcome, error, _ = ended.wait()
    assert isinstance(error, VehicleError) and "reactor's own thread" in str(error)


def test_a_repeated_message_goes_from_the_reactor_until_stopped(
        rig: tuple[FakeAutopilot, Link, Autopilot]) -> None:
    _fake, link, _autopilot = rig
    calls: list[str] = []
    stop = link.repeat(lambda: calls.append(threading.current_thread().name), 0.02)
    assert eventually(lambda: len(calls) >= 3), "repeated"
    stop()
    stopped_at = len(calls)
    time.sleep(0.2)  # ten periods: a repeat not stopped would have gone on
    assert len(calls) <= stopped_at + 1  # (one may have been under way)
    assert set(calls) == {THREAD_NAME}


# -- a request's procedure, by hand: MavlinkVehicle without a link -------------------------------


class ScriptedLink:
    """What MavlinkVehicle reads of a link, with a snapshot the test sets and nothing on
    the wire: the request's procedure is driven by the test alone."""

    timebase = SYSTEM
    source_system = 255

    def __init__(self) -> None:
        self.snapshot = Telemetry(system_id=1, vehicle_type=mavlink.MAV_TYPE_QUADROTOR,
                                  autopilot=mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                  mode="GUIDED")
        self.sent: list[Any] = []

    def wait_vehicle(self, system_id: int | None, timeout: float) -> VehicleInfo:
        return COPTER

    def telemetry(self, system_id: int) -> Telemetry:
        return self.snapshot

    def listen(self, listener: Any) -> None:
        pass

    def on_change(self, listener: Any) -> None:
        pass

    def send(self, msg: Any, system_id: int = 0, component_id: int = 0) -> None:
        self.sent.append(msg)

    def repeat(self, send: Any, period: float) -> Any:
        self.repeating = True

        def stop() -> None:
            self.repeating = False
        return stop


def answer(step: object, result: CommandResult, now: float = 0.0) -> int:
    """Start the Exchange ``step`` and answer its command with ``result``; the command."""
    assert isinstance(step, Exchange) and isinstance(step.machine, CommandSender)
    [sent] = step.machine.start(now)
    step.machine.receive(CommandAck(sent.command, result), now + 0.05)
    command: int = sent.command
    return command


def test_a_take_off_refused_because_the_vehicle_disarmed_meanwhile_arms_and_tries_again() -> None:
    link = ScriptedLink()
    vehicle = MavlinkVehicle(link, 1)  # type: ignore[arg-type]
    steps = vehicle._carry_out(TakeOff(1, 5.0))
    # ArduCopter disarms on the ground DISARM_DELAY after arming: the take-off is refused.
    assert answer(next(steps), CommandResult.MAV_RESULT_FAILED) == mavlink.MAV_CMD_NAV_TAKEOFF
    assert answer(steps.send(None), CommandResult.MAV_RESULT_ACCEPTED) \
        == mavlink.MAV_CMD_COMPONENT_ARM_DISARM
    assert answer(steps.send(None), CommandResult.MAV_RESULT_ACCEPTED) \
        == mavlink.MAV_CMD_NAV_TAKEOFF
    with pytest.raises(StopIteration) as over:
        steps.send(None)
    assert over.value.value == RequestResult(1, 0, True)


def test_a_take_off_refused_while_armed_is_the_refusal() -> None:
    link = ScriptedLink()
    link.snapshot = replace(link.snapshot, armed=True)
    steps = MavlinkVehicle(link, 1)._carry_out(TakeOff(1, 5.0))  # type: ignore[arg-type]
    answer(next(steps), CommandResult.MAV_RESULT_FAILED)
    with pytest.raises(StopIteration) as over:
        steps.send(None)
    result = over.value.value
    assert (result.ok, result.reason, result.detail) == (
        False, "rejected", "MAV_CMD_NAV_TAKEOFF: MAV_RESULT_FAILED")


def test_a_flip_that_fails_midway_puts_the_vehicle_back_in_guided_before_the_sticks_go() -> None:
    link = ScriptedLink()
    steps = MavlinkVehicle(link, 1)._carry_out(Flip(1, "left"))  # type: ignore[arg-type]
    hold = next(steps)  # ALT_HOLD asked, with the sticks held (every STICK_PERIOD after)
    assert isinstance(hold, Exchange) and isinstance(hold.machine, ModeChange)
    assert hold.machine.mode == "ALT_HOLD" and link.repeating
    hold.machine.start(0.0)
    link.snapshot = replace(link.snapshot, mode="ALT_HOLD", mode_changes=((0.1, "ALT_HOLD"),))
    while not hold.machine.done:  # its ACK lost, the HEARTBEAT shows it taken
        hold.machine.tick(hold.machine.deadline)
    flip = steps.send(None)
    assert isinstance(flip, Exchange) and isinstance(flip.machine, ModeChange)
    assert flip.machine.mode == "FLIP"
    flip.machine.start(1.0)
    while not flip.machine.done:  # never answered, never seen
        flip.machine.tick(flip.machine.deadline)
    # The flip is given up: the vehicle is put back in GUIDED before the sticks are let go
    # (in ALT_HOLD a released throttle stick is a throttle at zero).
    back = steps.send(None)
    assert isinstance(back, Exchange) and isinstance(back.machine, ModeChange)
    assert back.machine.mode == "GUIDED"
    assert link.repeating
    assert not [m for m in link.sent if getattr(m, "chan1_raw", None) == codec.RC_RELEASE]
    back.machine.start(20.0)
    while not back.machine.done:
        back.machine.tick(back.machine.deadline)
    with pytest.raises(StopIteration) as over:
        steps.send(None)
    assert over.value.value.reason == "timeout"
    assert not link.repeating
    assert [m.chan1_raw for m in link.sent[-3:]] == [codec.RC_RELEASE] * 3


def test_a_flip_abandoned_unfinished_lets_go_of_the_sticks_and_asks_nothing_more() -> None:
    link = ScriptedLink()
    link.snapshot = replace(link.snapshot, mode="ALT_HOLD")
    steps = MavlinkVehicle(link, 1)._carry_out(Flip(1, "left"))  # type: ignore[arg-type]
    next(steps)
    steps.close()  # as the garbage collector closes a generator nobody resumes
    assert not link.repeating
    assert [m.chan1_raw for m in link.sent[-3:]] == [codec.RC_RELEASE] * 3


def test_a_failure_of_whoever_is_told_the_end_is_reported_and_the_link_goes_on(
        rig: tuple[FakeAutopilot, Link, Autopilot],
        monkeypatch: pytest.MonkeyPatch) -> None:
    _fake, link, autopilot = rig
    reported: list[Any] = []
    monkeypatch.setattr(threading, "excepthook", reported.append)

    def told(outcome: Any, error: BaseException | None) -> None:
        raise RuntimeError("a bug in the one told")

    link.begin(autopilot.commanding(arm_command()), 1, 1, told)
    assert eventually(lambda: bool(reported)), "reported"
    assert isinstance(reported[0].exc_value, RuntimeError)
    ended = Ended()
    link.begin(two_commands(autopilot, []), 1, 1, ended)
    assert ended.wait()[:2] == (2, None), "the reactor still serves the link"
