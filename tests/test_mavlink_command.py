"""The command state machine: retransmission, IN_PROGRESS, and every result as an error."""

from __future__ import annotations

import pytest

from tml.errors import CommandRejected, VehicleTimeout
from tml.mavlink.command import (
    Command,
    CommandAck,
    CommandInt,
    CommandLong,
    CommandResult,
    CommandSender,
    result_name,
)

TAKEOFF = CommandLong(22, param7=10.0)


def test_accepted_on_first_ack() -> None:
    sender = CommandSender(TAKEOFF, "MAV_CMD_NAV_TAKEOFF", system_id=1)
    assert sender.start(0.0) == [TAKEOFF]
    sender.receive(CommandAck(22, CommandResult.MAV_RESULT_ACCEPTED), 0.05)
    assert sender.done and sender.accepted and sender.error is None
    assert sender.tick(100.0) == []


def test_retransmits_with_incremented_confirmation_then_times_out() -> None:
    sender = CommandSender(TAKEOFF, system_id=3, timeout=1.0, retries=5)
    sent = sender.start(0.0)
    now = 0.0
    while not sender.done:
        assert sender.tick(now + 0.5) == []  # nothing before the deadline
        now = sender.deadline
        sent += sender.tick(now)
    assert [m.confirmation for m in sent] == [0, 1, 2, 3, 4, 5]
    assert now == pytest.approx(6.0)
    assert isinstance(sender.error, VehicleTimeout)
    assert "vehicle 3" in str(sender.error) and "MAV_CMD_22" in str(sender.error)


def test_command_int_is_resent_unchanged() -> None:
    goto = CommandInt(192, frame=6, x=1, y=2, z=3.0)
    sender = CommandSender(goto)
    sender.start(0.0)
    assert sender.tick(sender.deadline) == [goto]


def test_ack_for_another_command_is_ignored() -> None:
    sender = CommandSender(TAKEOFF)
    sender.start(0.0)
    sender.receive(CommandAck(400, CommandResult.MAV_RESULT_DENIED), 0.1)
    assert not sender.done


def test_in_progress_stops_retransmission_and_waits_for_the_final_ack() -> None:
    sender = CommandSender(TAKEOFF, timeout=1.0, progress_timeout=10.0)
    sender.start(0.0)
    sender.receive(CommandAck(22, CommandResult.MAV_RESULT_IN_PROGRESS, progress=40), 0.2)
    assert sender.progress == 40 and not sender.done
    assert sender.tick(5.0) == []  # past the ACK timeout: no retransmission
    sender.receive(CommandAck(22, CommandResult.MAV_RESULT_IN_PROGRESS, progress=80), 9.0)
    assert sender.tick(18.0) == [] and not sender.done  # each IN_PROGRESS extends the wait
    sender.receive(CommandAck(22, CommandResult.MAV_RESULT_ACCEPTED), 18.5)
    assert sender.accepted


def test_in_progress_without_a_final_ack_times_out() -> None:
    sender = CommandSender(TAKEOFF, progress_timeout=10.0)
    sender.start(0.0)
    sender.receive(CommandAck(22, CommandResult.MAV_RESULT_IN_PROGRESS), 0.2)
    assert sender.tick(10.2) == []
    assert isinstance(sender.error, VehicleTimeout)


@pytest.mark.parametrize("result", [r for r in CommandResult
                                    if r not in (CommandResult.MAV_RESULT_ACCEPTED,
                                                 CommandResult.MAV_RESULT_IN_PROGRESS)],
                         ids=lambda r: r.name)
def test_every_refusal_is_command_rejected_with_command_result_and_vehicle(
        result: CommandResult) -> None:
    sender = CommandSender(TAKEOFF, "MAV_CMD_NAV_TAKEOFF", system_id=4)
    sender.start(0.0)
    sender.receive(CommandAck(22, result), 0.1)
    error = sender.error
    assert isinstance(error, CommandRejected)
    assert (error.command, error.result, error.system_id) == ("MAV_CMD_NAV_TAKEOFF",
                                                              result.name, 4)


def test_unknown_result_number_keeps_its_number() -> None:
    assert result_name(42) == "MAV_RESULT_42"


def test_result_names_are_those_of_the_mavlink_definition() -> None:
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    defined = {entry.name: value for value, entry in mavlink.enums["MAV_RESULT"].items()
               if not entry.name.endswith("_END")}
    # The table also holds results newer than pymavlink's dialect (CANCELLED, 6, and
    # COMMAND_UNSUPPORTED_MAV_FRAME, 9, from common.xml); those it has must agree.
    assert defined.items() <= {r.name: r.value for r in CommandResult}.items()
    assert len(defined) >= 8


# --- a retransmission whose first copy may have been taken (the ACK was lost) ------------------

FAILED = CommandResult.MAV_RESULT_FAILED


class Telemetry:
    """What the vehicle is seen doing: the fake behind a ``taken`` predicate."""

    def __init__(self) -> None:
        self.climbing = False
        self.looks = 0

    def taken(self) -> bool:
        self.looks += 1
        return self.climbing


def retried(sender: CommandSender) -> list[Command]:
    """Start ``sender`` and let its first ACK be lost: returns both transmissions."""
    sent = sender.start(0.0)
    sent += sender.tick(sender.deadline)
    return sent


def test_a_retry_refused_while_telemetry_shows_the_command_taken_is_accepted() -> None:
    seen = Telemetry()
    sender = CommandSender(TAKEOFF, "MAV_CMD_NAV_TAKEOFF", timeout=1.0, taken=seen.taken)
    assert [m.confirmation for m in retried(sender)] == [0, 1]
    seen.climbing = True  # ArduCopter took the first copy and refuses the second in the air
    sender.receive(CommandAck(22, FAILED), 1.1)
    assert sender.done and sender.accepted and sender.by_telemetry
    assert sender.error is None


@pytest.mark.parametrize("result", [CommandResult.MAV_RESULT_FAILED,
                                    CommandResult.MAV_RESULT_DENIED,
                                    CommandResult.MAV_RESULT_TEMPORARILY_REJECTED],
                         ids=lambda r: r.name)
def test_a_refused_retry_waits_for_telemetry_that_lags_the_ack(result: CommandResult) -> None:
    seen = Telemetry()
    sender = CommandSender(TAKEOFF, timeout=1.0, settle=1.0, taken=seen.taken)
    retried(sender)
    sender.receive(CommandAck(22, result), 1.1)
    assert not sender.done and sender.refused_retry == result
    assert sender.deadline <= 1.1 + 1.0
    assert sender.tick(sender.deadline) == []  # no retransmission while the refusal is held
    seen.climbing = True
    sender.tick(sender.deadline)
    assert sender.accepted and sender.by_telemetry


def test_a_refused_retry_that_telemetry_never_explains_is_a_refusal() -> None:
    seen = Telemetry()
    sender = CommandSender(TAKEOFF, "MAV_CMD_NAV_TAKEOFF", system_id=2, timeout=1.0,
                           settle=1.0, taken=seen.taken)
    sent = retried(sender)
    sender.receive(CommandAck(22, FAILED), 1.1)
    while not sender.done:
        sent += sender.tick(sender.deadline)
    assert len(sent) == 2 and sender.deadline == float("inf")
    assert isinstance(sender.error, CommandRejected)
    assert sender.error.result == "MAV_RESULT_FAILED" and not sender.by_telemetry
    assert seen.looks >= 2  # looked again while the refusal was held


def test_the_answer_to_the_first_transmission_is_final_whatever_the_telemetry() -> None:
    seen = Telemetry()
    seen.climbing = True
    sender = CommandSender(TAKEOFF, taken=seen.taken)
    sender.start(0.0)
    sender.receive(CommandAck(22, FAILED), 0.1)
    assert isinstance(sender.error, CommandRejected) and seen.looks == 0


def test_a_retry_answered_unsupported_is_a_refusal_without_looking() -> None:
    seen = Telemetry()
    sender = CommandSender(TAKEOFF, timeout=1.0, taken=seen.taken)
    retried(sender)
    seen.climbing = True
    looks = seen.looks
    sender.receive(CommandAck(22, CommandResult.MAV_RESULT_UNSUPPORTED), 1.1)
    assert isinstance(sender.error, CommandRejected) and seen.looks == looks


def test_a_command_telemetry_shows_taken_is_not_sent_again() -> None:
    seen = Telemetry()
    sender = CommandSender(CommandLong(176, 1, 14), timeout=1.0, taken=seen.taken)
    sender.start(0.0)
    seen.climbing = True  # the ACK was lost, but the vehicle did it (a second FLIP would flip)
    assert sender.tick(1.0) == []
    assert sender.accepted and sender.by_telemetry


def test_without_a_telemetry_judgement_a_refused_retry_is_a_refusal() -> None:
    sender = CommandSender(TAKEOFF, timeout=1.0)
    retried(sender)
    sender.receive(CommandAck(22, FAILED), 1.1)
    assert isinstance(sender.error, CommandRejected)
