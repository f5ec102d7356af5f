"""Why something failed in flight, as one enum, and a failure as it climbs the task tree."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from tml.engine.records import Status


class FailureReason(StrEnum):
    """Why an action, a pick or a vehicle failed.

    The first five are the values of the ACTION_FAILURE parameter (docs/language.md); the
    others fail a task without being an action's failure.
    """

    REJECTED = "rejected"  # the vehicle refused a request
    TIMEOUT = "timeout"  # a time limit ran out
    UNSUPPORTED = "unsupported"  # the vehicle cannot do it (no gripper, no FLIP mode)
    INFEASIBLE = "infeasible"  # refused before it started (the vehicle's kind, the profile)
    GENERAL = "general"  # anything else
    PICK = "pick"  # no vehicle qualified for a role in time
    LINK = "link"  # the vehicle's link was lost
    TAKEN = "taken"  # someone else (the autopilot, a pilot, another ground station) took it

    @classmethod
    def of(cls, said: str) -> FailureReason:
        """The reason a vehicle gave for refusing a request (no reason: it was refused)."""
        if not said:
            return cls.REJECTED
        try:
            return cls(said)
        except ValueError:
            return cls.GENERAL


ACTION_FAILURES = (FailureReason.REJECTED, FailureReason.TIMEOUT, FailureReason.UNSUPPORTED,
                   FailureReason.INFEASIBLE, FailureReason.GENERAL)
"""The values the ACTION_FAILURE parameter takes."""


@dataclass(frozen=True)
class Failure:
    """A failure on its way up the task tree to the nearest ``on_error``."""

    reason: FailureReason
    message: str  # said in full: the mission's reason when nothing handles it
    vehicle_id: int | None = None  # the vehicle it happened on, when there is one

    @property
    def status(self) -> Status:
        """How the mission ends when nothing handles it: an infeasible action aborts it."""
        return Status.ABORTED if self.reason is FailureReason.INFEASIBLE else Status.FAILED
