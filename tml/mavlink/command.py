"""The MAVLink command protocol as a pure state machine (no sockets, no clock).

A :class:`CommandSender` carries one COMMAND_LONG or COMMAND_INT to one vehicle. Like the
mission transfer it is driven by its caller: ``start(now)`` returns the message to send,
``receive(ack, now)`` takes each COMMAND_ACK from that vehicle, ``tick(now)`` (due at
``deadline``) returns retransmissions. A COMMAND_LONG is retransmitted with its confirmation
field incremented, so the vehicle can tell a retry from a new command; COMMAND_INT has no
such field and goes out unchanged.

An ACK with MAV_RESULT_IN_PROGRESS stops the retransmissions (the vehicle has the command)
and extends the wait to ``progress_timeout`` after each such ACK; the final ACK ends it.

*A retransmitted command whose first ACK was lost.* The vehicle may have taken the first
copy, and then answer the retry by what it is doing now: ArduCopter refuses NAV_TAKEOFF
with FAILED once it is off the ground, so the ACK of a retry cannot say whether the command
was carried out. The sender does not know the vehicle's state; its caller may inject
``taken``, a function saying whether telemetry shows the command carried out (the rules
are in :data:`tml.mavlink.autopilot.TAKEN`). Then a retry answered FAILED, DENIED or
TEMPORARILY_REJECTED is held for up to ``settle`` seconds while the telemetry may still
show the command taken (it counts as accepted, ``by_telemetry``), and a retransmission is
not sent at all once the telemetry shows it taken: a repeated FLIP would flip twice. The
answer to the first transmission is always final.
``error`` is the one place where an outcome becomes an exception: every result other than
ACCEPTED becomes :class:`~tml.errors.CommandRejected` with the command's name, the result's
name and the vehicle; silence becomes :class:`~tml.errors.VehicleTimeout`.
"""

from __future__ import annotations

import enum
import types
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from tml.errors import CommandRejected, VehicleError, VehicleTimeout

TIMEOUT = 1.5
"""Seconds to wait for a COMMAND_ACK before retransmitting."""
RETRIES = 5
"""Retransmissions before giving up."""
PROGRESS_TIMEOUT = 10.0
"""Seconds to wait for the final ACK after an IN_PROGRESS one."""
SETTLE = 1.0
"""Seconds a refused retransmission waits for telemetry showing the command taken."""
SETTLE_POLL = 0.1
"""Seconds between looks at the telemetry while a refusal is held."""


class CommandResult(enum.IntEnum):
    """MAV_RESULT, the result field of COMMAND_ACK (names as in the MAVLink XML)."""

    MAV_RESULT_ACCEPTED = 0
    MAV_RESULT_TEMPORARILY_REJECTED = 1
    MAV_RESULT_DENIED = 2
    MAV_RESULT_UNSUPPORTED = 3
    MAV_RESULT_FAILED = 4
    MAV_RESULT_IN_PROGRESS = 5
    MAV_RESULT_CANCELLED = 6
    MAV_RESULT_COMMAND_LONG_ONLY = 7
    MAV_RESULT_COMMAND_INT_ONLY = 8
    MAV_RESULT_COMMAND_UNSUPPORTED_MAV_FRAME = 9


def result_name(result: int) -> str:
    """The MAV_RESULT name of ``result`` (``MAV_RESULT_<n>`` if unknown)."""
    try:
        return CommandResult(result).name
    except ValueError:
        return f"MAV_RESULT_{result}"


@dataclass(frozen=True)
class CommandLong:
    """COMMAND_LONG: a command with seven float parameters."""

    command: int
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    param5: float = 0.0
    param6: float = 0.0
    param7: float = 0.0
    confirmation: int = 0


@dataclass(frozen=True)
class CommandInt:
    """COMMAND_INT: a command with a frame and integer position (degrees * 1e7)."""

    command: int
    frame: int = 0
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    current: int = 0
    autocontinue: int = 0


@dataclass(frozen=True)
class CommandAck:
    """COMMAND_ACK: the vehicle's answer to a command.

    ``packet_seq`` is the MAVLink packet sequence number it came with (None when unknown):
    it orders the ACK against the HEARTBEATs of the same component (see
    :class:`~tml.mavlink.modes.ModeChange`).
    """

    command: int
    result: int
    progress: int = 0
    packet_seq: int | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Heartbeat:
    """HEARTBEAT: what a component is and which mode it is in.

    The command protocol reads it to confirm a mode change; ``packet_seq`` as in
    :class:`CommandAck`.
    """

    vehicle_type: int
    autopilot: int
    base_mode: int
    custom_mode: int
    packet_seq: int | None = field(default=None, compare=False)


Command = CommandLong | CommandInt
"""A command as plain data, ready for the codec."""

RETRY_REFUSALS = frozenset({CommandResult.MAV_RESULT_TEMPORARILY_REJECTED,
                            CommandResult.MAV_RESULT_DENIED, CommandResult.MAV_RESULT_FAILED})
"""Answers to a retransmission that may only mean the first copy was taken."""


class CommandSender:
    """Send one command until it is acknowledged, refused, or the vehicle stays silent."""

    inputs: type | types.UnionType = CommandAck
    """The plain messages the sender takes (what a link feeds it)."""

    def __init__(self, command: Command, name: str = "", *, system_id: int | None = None,
                 timeout: float = TIMEOUT, retries: int = RETRIES,
                 progress_timeout: float = PROGRESS_TIMEOUT,
                 taken: Callable[[], bool] | None = None, settle: float = SETTLE) -> None:
        self.command = command
        self.name = name or f"MAV_CMD_{command.command}"
        self.system_id = system_id
        self.timeout = timeout
        self.retries = retries
        self.progress_timeout = progress_timeout
        self.taken = taken
        self.settle = settle
        self.deadline = float("inf")
        self.result: int | None = None
        self.progress: int | None = None
        self.timed_out = False
        self.attempts = 0
        self.by_telemetry = False
        """True when telemetry, not an ACK, showed the command taken."""
        self.refused_retry: int | None = None
        """The refusal of a retransmission, while it is held (see the module docstring)."""
        self._settle_by = float("inf")

    @property
    def done(self) -> bool:
        """True once a final ACK arrived or the sender gave up."""
        return self.result is not None or self.timed_out

    @property
    def accepted(self) -> bool:
        """True if the vehicle accepted the command."""
        return self.result == CommandResult.MAV_RESULT_ACCEPTED

    @property
    def error(self) -> VehicleError | None:
        """The exception this outcome amounts to, or None if accepted or still running."""
        if self.timed_out:
            return VehicleTimeout(f"{self.name}: no COMMAND_ACK after {self.attempts} attempts",
                                  self.system_id)
        if self.result is None or self.accepted:
            return None
        return CommandRejected(self.name, result_name(self.result), self.system_id)

    def start(self, now: float) -> list[Command]:
        """The first transmission."""
        return self._transmit(now)

    def receive(self, ack: CommandAck, now: float) -> list[Command]:
        """Feed a COMMAND_ACK from the vehicle (ACKs for other commands are ignored)."""
        if self.done or ack.command != self.command.command:
            return []
        if ack.result == CommandResult.MAV_RESULT_IN_PROGRESS:
            self.progress = ack.progress
            self.deadline = now + self.progress_timeout
            return []
        if ack.result in RETRY_REFUSALS and self.attempts > 1 and self.taken is not None:
            if self.taken():
                self._taken()
            elif self.refused_retry is None:
                self.refused_retry = ack.result
                self._settle_by = now + self.settle
                self.deadline = min(now + SETTLE_POLL, self._settle_by)
            return []
        self.result = ack.result
        self.deadline = float("inf")
        return []

    def tick(self, now: float) -> list[Command]:
        """Retransmit or give up once the deadline has passed."""
        if self.done or now < self.deadline:
            return []
        if self.refused_retry is not None:
            if self.taken is not None and self.taken():
                self._taken()
            elif now >= self._settle_by:
                self.result = self.refused_retry
                self.deadline = float("inf")
            else:
                self.deadline = min(now + SETTLE_POLL, self._settle_by)
            return []
        if self.progress is None and self.taken is not None and self.taken():
            self._taken()  # the ACK was lost, the vehicle did it: do not send it twice
            return []
        if self.progress is not None or self.attempts > self.retries:
            self.timed_out = True
            self.deadline = float("inf")
            return []
        return self._transmit(now)

    def _taken(self) -> None:
        self.result = CommandResult.MAV_RESULT_ACCEPTED
        self.by_telemetry = True
        self.deadline = float("inf")

    def _transmit(self, now: float) -> list[Command]:
        message = self.command
        if isinstance(message, CommandLong):
            message = replace(message, confirmation=min(self.attempts, 255))
        self.attempts += 1
        self.deadline = now + self.timeout
        return [message]
