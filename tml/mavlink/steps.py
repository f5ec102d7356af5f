"""What a procedure with a vehicle waits for, one step at a time: :class:`Exchange`, :class:`Until`.

A request to a vehicle (a take-off: GUIDED, then arm, then NAV_TAKEOFF, arming again when
the vehicle disarmed by itself meanwhile) is a sequence of exchanges, each of which takes
round trips, and of waits for the telemetry to show something. Written as a generator that
*yields* each :data:`Step` and is sent back its outcome, the sequence is a state machine
that does no I/O and keeps no thread: whoever drives it decides when to resume it.

- :meth:`tml.mavlink.link.Link.drive` drives one on the calling thread, which waits
  (a command-line tool, a pre-flight check);
- :meth:`tml.mavlink.link.Link.begin` drives one from the link's reactor, which resumes it
  when the exchange's answer arrives, when the awaited telemetry shows, or when its time is
  up: a fleet's requests are carried out by the one thread that reads every link;
- a test drives one by hand, feeding it the outcomes it wants to try (tests/test_steps.py).

The outcome sent back for an :class:`Exchange` is nothing: the machine is done, and says how
(``error``); for an :class:`Until`, nothing either. What fails is thrown into the generator
where it waits: :class:`~tml.errors.VehicleTimeout` when an Until's time is up,
:class:`~tml.errors.LinkLost` when the vehicle is lost during either step.
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

T = TypeVar("T")


class Machine(Protocol):
    """A sans-IO exchange with one vehicle: a transfer, a command sender, a mode change."""

    inputs: Any
    """The plain message type(s) (a type or a union) the machine is fed."""

    @property
    def deadline(self) -> float: ...

    @property
    def done(self) -> bool: ...

    def start(self, now: float) -> list[Any]: ...

    def receive(self, msg: Any, now: float) -> list[Any]: ...

    def tick(self, now: float) -> list[Any]: ...


@dataclass(frozen=True, eq=False)
class Exchange:
    """Run ``machine`` with the vehicle until it is done (its ``error`` says how);
    ``on_progress(machine)`` is called now and then meanwhile (a long transfer's progress)."""

    machine: Machine
    on_progress: Callable[[Machine], None] | None = None


@dataclass(frozen=True, eq=False)
class Until:
    """Wait until ``holds()`` is true, for at most ``timeout`` seconds of the link's time
    base. ``holds`` is asked again after each message from the vehicle (and at once), from
    whichever thread drives the step: it must be quick and read only what is safe to read
    there. ``what`` names the wait in the VehicleTimeout; ``lost_ok`` keeps waiting while
    the vehicle is lost (to see it come back)."""

    holds: Callable[[], bool]
    timeout: float
    what: str = "condition"
    lost_ok: bool = False


Step = Exchange | Until
Steps = Generator[Step, None, T]
"""A procedure: yields steps, is resumed when each is over, returns its outcome."""
