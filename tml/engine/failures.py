"""A failure as it climbs the task tree (why: :class:`tml.language.failures.FailureReason`)."""

from __future__ import annotations

from dataclasses import dataclass

from tml.engine.records import Status
from tml.language.failures import FailureReason


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
