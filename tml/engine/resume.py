"""Where an interrupted run stood, read back from its own records, to go on from there.

Theory of operation
-------------------
Everything the engine decides is a record (:class:`~tml.engine.records.Record`), and the
flight log keeps them in order. :func:`progress` folds one vehicle's records into a
:class:`Progress`: the tasks that had ended, the tasks whose body was running and since
when, the round each repeat or loop was in, the points memorized, the mission time
reached, and the highest request or plan id used. The interpreter starts from it
(:meth:`tml.engine.Interpreter.start` with ``progress``) through the same nodes as a fresh
start, with these differences, each consumed once: a task that had ended is passed over
without running or being recorded again; a task that was running is entered as a jump
enters its target -- no wait, no conditions read again -- with the time it had already
run, so that its time limit goes on; a repeat or loop goes on from the round it was in;
a task that had failed while its ``on_error`` tasks ran goes on with them.
The work of the running task is started again, and its scripts judge from the vehicle's
state what is left: TAKE_OFF is ignored by a vehicle already flying, LAND by one already
down (LANDING_POINT by one down at its point), a GO_TO flies to its target from where
the vehicle is. A ``dispatch="mission"`` task whose plan was sent and that the vehicle
still flies in AUTO is followed where the autopilot is (its plan is not sent again), the
items already flown not said again.

Rounds: a repeat's round record (``repeat N of M``) and a task that starts running again
(a later round, a jump back) forget what ended below it in the round before. A record the
resumed run writes for a task it re-enters carries ``resumed`` and forgets nothing, so a
run resumed and interrupted again folds to the same place.

Time: the mission clock is read from the records' times, per run (each ``mission`` record
that starts or resumes the mission sets the base; a pause is taken out), so the time spent
without a ground station is not counted: a time limit continues where it stood.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from tml.engine.records import TaskState
from tml.vehicle import Point

ENDED = frozenset(s.value for s in (TaskState.DONE, TaskState.SKIPPED, TaskState.FAILED,
                                    TaskState.ABORTED))


@dataclass(frozen=True)
class Progress:
    """Where one vehicle's mission stood when its run was interrupted."""

    ended: Mapping[str, TaskState] = field(default_factory=dict)  # path -> how it ended
    running: Mapping[str, float] = field(default_factory=dict)  # path -> mission time begun
    rounds: Mapping[str, int] = field(default_factory=dict)  # repeat/loop -> its round
    labels: Mapping[str, Point] = field(default_factory=dict)  # memorized points
    elapsed: float = 0.0  # mission time at the last record
    last_id: int = 0  # the highest request or plan id used
    started: bool = False  # the mission had started
    status: str = ""  # how the mission ended ("" while it ran)
    # A dispatch="mission" task's plan sent to the vehicle: its id and start.
    plans: Mapping[str, tuple[int, Point]] = field(default_factory=dict)
    recovering: frozenset[str] = frozenset()  # failed tasks whose on_error tasks ran


def progress(records: Iterable[Mapping[str, Any]], vehicle_id: int) -> Progress:
    """Fold the engine's records of ``vehicle_id`` (a flight log's lines, in order) into
    where its mission stood; see the module docstring."""
    ended: dict[str, TaskState] = {}
    running: dict[str, float] = {}
    rounds: dict[str, int] = {}
    labels: dict[str, Point] = {}
    plans: dict[str, tuple[int, Point]] = {}
    recovering: set[str] = set()
    planning = ""  # the task whose plan the next FlyMission request sends
    base = offset = elapsed = 0.0
    last_id, started, status = 0, False, ""
    paused_at: float | None = None
    for record in records:
        for key in ("request_id", "plan_id"):
            if isinstance(record.get(key), int):
                last_id = max(last_id, record[key])
        if record.get("vehicle") != vehicle_id:
            continue
        kind, t = record.get("kind"), float(record.get("t", 0.0))
        if kind == "mission" and "elapsed" in record:  # resumed: the clock goes on
            base, offset, started, paused_at = t, float(record["elapsed"]), True, None
        elif kind == "mission" and "status" in record:
            status = str(record["status"])
        elif kind == "mission":
            base, offset, started, status, paused_at = t, 0.0, True, "", None
        if not started:
            continue
        if kind == "control" and record.get("control") == "pause":
            paused_at = t
        elif kind == "control" and record.get("control") == "resume":
            offset -= float(record.get("paused", 0.0))
            paused_at = None
        now = offset + ((t if paused_at is None else paused_at) - base)
        elapsed = max(elapsed, now)
        path = record.get("task")
        if kind == "task" and isinstance(path, str):
            state = record.get("state")
            if state == TaskState.RUNNING.value:
                if not record.get("resumed"):
                    _forget_below(ended, rounds, path)
                    recovering.discard(path)
                    running[path] = now
                ended.pop(path, None)
            elif state in ENDED:
                ended[path] = TaskState(state)
                running.pop(path, None)
        elif kind == "decision" and isinstance(path, str) and record.get("recover"):
            recovering.add(path)
        elif kind == "decision" and isinstance(path, str) and "actions" in record:
            planning = path  # "flown as a mission": its FlyMission request follows
        elif kind == "request" and record.get("message") == "FlyMission" and planning:
            x, y, z = (float(v) for v in record.get("start") or (0.0, 0.0, 0.0))
            plans[planning] = (int(record["plan_id"]), (x, y, z))
        elif kind == "decision" and isinstance(path, str):
            number = record.get("iteration", record.get("round"))
            if isinstance(number, int) and not record.get("resumed"):
                rounds[path] = number
                _forget_below(ended, rounds, path)
        if isinstance(record.get("label"), str) and isinstance(record.get("point"), list):
            x, y, z = (float(v) for v in record["point"])
            labels[record["label"]] = (x, y, z)
    return Progress(ended, running, rounds, labels, elapsed, last_id, started, status, plans,
                    frozenset(recovering))


def _forget_below(ended: dict[str, TaskState], rounds: dict[str, int], path: str) -> None:
    """A task begins (again): what ended below it belongs to its last run."""
    prefix = path + "/"
    for done in [p for p in ended if p.startswith(prefix)]:
        del ended[done]
    for counted in [p for p in rounds if p.startswith(prefix)]:
        del rounds[counted]


class Restoring:
    """What a resumed run has still to take from its :class:`Progress`: each entry is
    taken once, by the node it is for, so that later rounds and jumps run as usual."""

    def __init__(self, progress: Progress, clock: float) -> None:
        self.ended = dict(progress.ended)
        # The running tasks' start on this run's mission clock.
        self.running = {path: clock - (progress.elapsed - begun)
                        for path, begun in progress.running.items()}
        self.rounds = dict(progress.rounds)
        self.plans = dict(progress.plans)
        self.recovering = set(progress.recovering)
        self.reentered: set[str] = set()  # the running tasks taken so far

    def take_ended(self, path: str) -> TaskState | None:
        """How the task had ended, if it had (then it is passed over)."""
        return self.ended.pop(path, None)

    def take_running(self, path: str) -> float | None:
        """When the task had begun running, if it was running (then it is re-entered)."""
        begun = self.running.pop(path, None)
        if begun is not None:
            self.reentered.add(path)
        return begun

    def reentering(self, path: str) -> bool:
        """Whether the task was running when the run was interrupted, and is re-entered
        now (its action goes on with what is left of it: a TAKE_OFF climbs on)."""
        return path in self.reentered

    def take_round(self, path: str) -> int:
        """The round the repeat or loop was in (0: it had not begun)."""
        return self.rounds.pop(path, 0)

    def take_recovering(self, path: str) -> bool:
        """Whether the task had failed and its on_error tasks were running (then they
        go on in its place)."""
        if path not in self.recovering:
            return False
        self.recovering.discard(path)
        self.ended.pop(path, None)
        return True

    def take_plan(self, path: str) -> tuple[int, Point, set[str]] | None:
        """The plan the task had sent (its id and start) and the tasks of it that had
        ended, if it had sent one (then it is followed, not sent again)."""
        plan = self.plans.pop(path, None)
        if plan is None:
            return None
        prefix = path + "/"
        flown = {p for p in self.ended if p.startswith(prefix)}
        for done in flown:
            del self.ended[done]
        return plan[0], plan[1], flown
