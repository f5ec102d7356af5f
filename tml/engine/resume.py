"""Where an interrupted run stood, read back from its own records, to go on from there.

Theory of operation
-------------------
Everything the engine decides is a record (:class:`~tml.engine.records.Record`), and the
flight log keeps them in order (typed: :mod:`tml.engine.flightlog`). :class:`Fold` is the
one fold of a log's records into task state: what resume, the service's task board and
its page read. :func:`progress` folds one vehicle's records into a :class:`Progress`: the
tasks that had ended, the tasks whose body was running and since when, the round each
repeat or loop was in, the points memorized, the mission time reached, and the highest
request or plan id used. The interpreter starts from it
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

The task board (:meth:`Fold.board`) is the last state said of each task, forgotten
below a task by the same rounds: a repeat's next round shows its tasks pending again, so
the board shows what a resumed run would still fly.

Time: the mission clock is read from the records' times, per run (each ``mission`` record
that starts or resumes the mission sets the base; a pause is taken out), so the time spent
without a ground station is not counted: a time limit continues where it stood.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from tml.engine.flightlog import (
    ControlLine,
    DecisionLine,
    Line,
    MissionLine,
    RequestLine,
    TaskLine,
    UnknownKind,
    get,
    parse,
)
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


@dataclass
class _Course:
    """What the fold keeps of one vehicle's mission (or of the tasks no vehicle flies)."""

    ended: dict[str, TaskState] = field(default_factory=dict)
    running: dict[str, float] = field(default_factory=dict)
    rounds: dict[str, int] = field(default_factory=dict)
    labels: dict[str, Point] = field(default_factory=dict)
    plans: dict[str, tuple[int, Point]] = field(default_factory=dict)
    recovering: set[str] = field(default_factory=set)
    states: dict[str, TaskState] = field(default_factory=dict)  # the board: the last said
    planning: str = ""  # the task whose plan the next FlyMission request sends
    base: float = 0.0
    offset: float = 0.0
    elapsed: float = 0.0
    started: bool = False
    status: str = ""
    paused_at: float | None = None

    def forget_below(self, path: str) -> None:
        """A task begins (again): what ended below it belongs to its last run."""
        prefix = path + "/"
        for found in (self.ended, self.rounds, self.states):
            for below in [p for p in found if p.startswith(prefix)]:
                del found[below]


class Fold:
    """The one fold of a flight log's records into where each vehicle's mission stands:
    what :func:`progress` gives a resumed run, and the task board the service, its page
    and the reports show (:meth:`board`). Fed record by record, in the log's order
    (:meth:`see`); see the module docstring for the rules (rounds, jumps, pauses,
    resumes)."""

    def __init__(self) -> None:
        self.courses: dict[int | None, _Course] = {}
        self.last_id = 0  # the highest request or plan id used
        self.changes = 0  # counts the changes of the board: a reader redraws when it moves

    def course(self, vehicle_id: int | None) -> _Course:
        """What the fold keeps of ``vehicle_id`` (None: the tasks no vehicle flies)."""
        found = self.courses.get(vehicle_id)
        if found is None:
            found = self.courses[vehicle_id] = _Course()
        return found

    def see(self, record: Line | Mapping[str, Any]) -> None:
        """Take the next record (typed, or a parsed line of a kind this version knows)."""
        if not isinstance(record, Line):
            try:
                record = parse(record)
            except (UnknownKind, KeyError, TypeError):
                return
        for value in (get(record, "request_id"), get(record, "plan_id")):
            if isinstance(value, int) and not isinstance(value, bool):
                self.last_id = max(self.last_id, value)
        course = self.course(record.vehicle)
        if isinstance(record, TaskLine):
            self._board(course, record)
        elif isinstance(record, MissionLine) and record.ended:
            # A continued run (tml serve): the tasks its interrupted run had ended.
            for path, state in record.ended.items():
                with contextlib.suppress(ValueError):
                    course.states[str(path)] = TaskState(state)
            self.changes += 1
        self._progress(course, record)

    def _board(self, course: _Course, record: TaskLine) -> None:
        with contextlib.suppress(ValueError):
            state = TaskState(record.state)
            if state is TaskState.RUNNING and not record.resumed:
                course.forget_below(record.task)
            course.states[record.task] = state
            self.changes += 1

    def _progress(self, course: _Course, record: Line) -> None:
        t = float(record.t)
        if isinstance(record, MissionLine):
            if record.elapsed is not None:  # resumed: the clock goes on
                course.base, course.offset, course.started = t, float(record.elapsed), True
                course.paused_at = None
            elif record.status is not None:
                course.status = record.status
            else:
                course.base, course.offset, course.started = t, 0.0, True
                course.status, course.paused_at = "", None
        if not course.started:
            return
        if isinstance(record, ControlLine) and record.control == "pause":
            course.paused_at = t
        elif isinstance(record, ControlLine) and record.control == "resume":
            course.offset -= float(record.paused or 0.0)
            course.paused_at = None
        now = course.offset + ((t if course.paused_at is None else course.paused_at)
                               - course.base)
        course.elapsed = max(course.elapsed, now)
        if isinstance(record, TaskLine):
            path = record.task
            if record.state == TaskState.RUNNING.value:
                if not record.resumed:
                    course.forget_below(path)
                    course.recovering.discard(path)
                    course.running[path] = now
                course.ended.pop(path, None)
            elif record.state in ENDED:
                course.ended[path] = TaskState(record.state)
                course.running.pop(path, None)
        elif isinstance(record, DecisionLine) and isinstance(record.task, str):
            path = record.task
            if record.recover:
                course.recovering.add(path)
            elif record.actions is not None:
                course.planning = path  # "flown as a mission": its FlyMission follows
            else:
                number = record.iteration if record.iteration is not None else record.round
                if isinstance(number, int) and not record.resumed:
                    course.rounds[path] = number
                    course.forget_below(path)
                    self.changes += 1
        elif isinstance(record, RequestLine) and get(record, "message") == "FlyMission" \
                and course.planning and record.plan_id is not None:
            x, y, z = (float(v) for v in record.start or (0.0, 0.0, 0.0))
            course.plans[course.planning] = (int(record.plan_id), (x, y, z))
        label, point = get(record, "label"), get(record, "point")
        if isinstance(label, str) and isinstance(point, list):
            x, y, z = (float(v) for v in point)
            course.labels[label] = (x, y, z)

    def progress(self, vehicle_id: int) -> Progress:
        """Where ``vehicle_id``'s mission stood at the last record seen."""
        course = self.course(vehicle_id)
        return Progress(dict(course.ended), dict(course.running), dict(course.rounds),
                        dict(course.labels), course.elapsed, self.last_id, course.started,
                        course.status, dict(course.plans), frozenset(course.recovering))

    def tasks(self, vehicle_id: int | None) -> dict[str, TaskState]:
        """Every task's state said for ``vehicle_id`` (None: the tasks no vehicle flies),
        as they stand: a task of a round before the one flown now is not there (pending)."""
        return dict(self.course(vehicle_id).states)

    def board(self, paths: Sequence[str], vehicles: Iterable[int]
              ) -> dict[str, dict[str, str]]:
        """Per vehicle (by id, as text; "" for tasks no vehicle flies, when there are
        any) the state of each of ``paths``, ``pending`` for a task not reached."""
        whose: list[int | None] = list(vehicles)
        whose += [v for v in self.courses if v not in whose and self.courses[v].states]
        return {("" if v is None else str(v)): {
                    path: self.course(v).states.get(path, TaskState.PENDING).value
                    for path in paths}
                for v in whose}


def progress(records: Iterable[Line | Mapping[str, Any]], vehicle_id: int) -> Progress:
    """Fold the records of a flight log (typed, or its parsed lines, in order) into where
    the mission of ``vehicle_id`` stood (:class:`Fold`); see the module docstring."""
    fold = Fold()
    for record in records:
        fold.see(record)
    return fold.progress(vehicle_id)


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
