"""Why something failed in flight, as one enum: the values of the language's ACTION_FAILURE
parameter, the reasons a vehicle gives for a request it did not carry out
(:class:`tml.vehicle.RequestResult`), and the engine's own."""

from __future__ import annotations

from enum import StrEnum


class FailureReason(StrEnum):
    """Why an action, a pick or a vehicle failed.

    The first five are the values of the ACTION_FAILURE parameter (docs/language.md) and the
    reasons a vehicle gives; the others fail a task without being an action's failure.
    """

    REJECTED = "rejected"  # the vehicle refused a request
    TIMEOUT = "timeout"  # a time limit ran out
    UNSUPPORTED = "unsupported"  # the vehicle cannot do it (no gripper, no FLIP mode)
    INFEASIBLE = "infeasible"  # refused before it started (the vehicle's kind, the profile)
    GENERAL = "general"  # anything else
    PICK = "pick"  # no vehicle qualified for a role in time
    LINK = "link"  # the vehicle's link was lost
    TAKEN = "taken"  # someone else (the autopilot, a pilot, another ground station) took it


ACTION_FAILURES = (FailureReason.REJECTED, FailureReason.TIMEOUT, FailureReason.UNSUPPORTED,
                   FailureReason.INFEASIBLE, FailureReason.GENERAL)
"""The values the ACTION_FAILURE parameter takes."""
