"""Procedures (tml.mavlink.steps): driven by hand without a link, by the calling thread
(Link.drive), and by the link's reactor (Link.begin) against the fake autopilot of
test_mavlink_link over loopback UDP."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import pytest
from test_mavlink_link import FakeAutopilot, eventually

from tml.errors import CommandRejected, LinkLost, VehicleError, VehicleTimeout
from tml.mavlink.autopilot import Autopilot, arm_command, takeoff_command
from tml.mavlink.codec import mavlink
from tml.mavlink.command import CommandAck, CommandLong, CommandResult, CommandSender
from tml.mavlink.link import Link, VehicleInfo
from tml.mavlink.reactor import THREAD_NAME
from tml.mavlink.steps import Exchange, Steps, Until
from tml.mavlink.telemetry import Telemetry

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
    assert ended.wait() == (2, None, THREAD_NAME)
    assert seen == [THREAD_NAME] * 3, "every part of it ran on the reactor's thread"
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
        autopilot.arm()  # would wait for the reactor, on the reactor
        yield from ()

    ended = Ended()
    link.begin(blocking(), 1, 1, ended)
    _outcome, error, _ = ended.wait()
    assert isinstance(error, VehicleError) and "reactor's own thread" in str(error)
