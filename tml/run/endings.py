"""How a run ends: one table for ``tml run``, ``tml serve``, resume and the cluster.

Every way a run can end is one :class:`Ending`: the status word ``tml serve`` stores and
shows for it (``tml run`` says it in its last line), the exit code ``tml run`` ends with
(and ``tml serve`` keeps in the run's record), and what it means. The runner
(:mod:`tml.run.runner`) says which ending a run had (:meth:`Ending.of`, from what ended
each vehicle's work); ``tml run`` exits with its code, the service stores its status and
code. An ending that comes before any run exists (an invalid mission, a usage error, a
refused clearance) has no status: ``tml serve`` refuses the request instead (4xx), and
stores nothing. docs/run.md, "How a run ends", is this table in words, each row with the
tests that show it; tests/test_endings.py keeps the two alike.
"""

from __future__ import annotations

from collections.abc import Iterable
from enum import Enum

from tml.errors import ExitCode


class Ending(Enum):
    """One way a run ends: ``(status, exit code, cause, meaning)``.

    ``cause`` is the runner's word for what ended a vehicle's work in this way (the
    ``cause`` of each vehicle's outcome; "" where the mission itself decided, or no
    vehicle flew); ``status`` None: no run is stored (``tml serve`` refuses the request);
    ``exit_code`` None: no tml process gives one (the process died).
    """

    COMPLETED = ("completed", ExitCode.OK, "", "the mission completed on every vehicle")
    ABORTED = ("aborted", ExitCode.ABORTED, "",
               "the mission aborted itself; every vehicle to its safe state")
    STOPPED = ("aborted", ExitCode.ABORTED, "stop",
               "stopped by the operator or the service; every vehicle to its safe state")
    OPERATOR = ("taken", ExitCode.FAILURE, "operator",
                "taken over by an operator's command, carried out through the run")
    TAKEN = ("taken", ExitCode.FAILURE, "taken",
             "taken over outside tml (a failsafe, the pilot, another ground station)")
    FAILED = ("failed", ExitCode.FAILURE, "", "an action failed and nothing handled it")
    LINK_LOST = ("failed", ExitCode.FAILURE, "link",
                 "a vehicle's link was lost for longer than the link-lost limit")
    REBOOTED = ("failed", ExitCode.FAILURE, "rebooted",
                "a vehicle's autopilot rebooted during the run")
    NOT_READY = ("failed", ExitCode.FAILURE, "ready",
                 "a vehicle was not ready for the mission in time: nothing flew")
    ERROR = ("failed", ExitCode.FAILURE, "error",
             "tml itself failed; every vehicle to its safe state")
    INTERRUPTED = ("interrupted", None, "",
                   "the process flying the run died: the run can be gone on with")
    INVALID = (None, ExitCode.INVALID, "",
               "an invalid mission, or an infeasible one without force: not flown")
    USAGE = (None, ExitCode.USAGE, "", "a usage error, or a resume refused: not flown")
    NOT_CLEARED = (None, ExitCode.FAILURE, "",
                   "no vehicle answered, or one was refused before the flight: not flown")

    def __init__(self, status: str | None, exit_code: ExitCode | None, cause: str,
                 meaning: str) -> None:
        self.status = status
        self.exit_code = exit_code
        self.cause = cause
        self.meaning = meaning

    @property
    def code(self) -> ExitCode:
        """The exit code of an ending a tml process gives (all but ``INTERRUPTED``)."""
        if self.exit_code is None:
            raise ValueError(f"{self.name}: no process gives an exit code")
        return self.exit_code

    @classmethod
    def of(cls, ended: Iterable[tuple[str, str]]) -> Ending:
        """The ending of a run whose vehicles ended with these (mission status, cause):
        the first in :data:`WORST_FIRST` that one of them had (with several vehicles the
        worst decides; a vehicle whose work a cause ended is judged by the cause, one the
        mission ended by its status). ``COMPLETED`` only when every vehicle completed;
        anything else the table does not know (a mission still running) is ``ABORTED``."""
        ended = list(ended)
        causes = {cause for _, cause in ended if cause}
        statuses = {status for status, cause in ended if not cause}
        for ending in WORST_FIRST[:-1]:
            if ending.cause in causes if ending.cause else ending.status in statuses:
                return ending
        if causes or statuses - {cls.COMPLETED.status}:
            return cls.ABORTED
        return cls.COMPLETED


WORST_FIRST = (Ending.ERROR, Ending.LINK_LOST, Ending.REBOOTED, Ending.NOT_READY,
               Ending.FAILED, Ending.TAKEN, Ending.OPERATOR, Ending.STOPPED, Ending.ABORTED,
               Ending.COMPLETED)
"""The endings a run's vehicles decide, the worst first."""

CAUSES = {ending.cause: ending for ending in WORST_FIRST if ending.cause}
"""The ending of each cause the runner gives a vehicle's outcome."""
