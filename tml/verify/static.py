"""Static verification: abstract execution of a whole mission before flight.

The task tree is walked depth-first as the interpreter will walk it, carrying a set of
*alternatives*, each a predicted :class:`VehicleState` with the labels memorized so far.
Repeats are unrolled. A task with conditions may or may not run, so after it the
alternatives of both ways are kept. Alternatives that end at the same place with the same
settings and labels are merged into one that takes the lowest battery and the latest time
(the worst of them); past :data:`MAX_ALTERNATIVES` the ones with most battery left are
dropped and the report says the result is approximate.

Event handlers can fire at any moment, so each event's actions are predicted from every
point where the vehicle is flying after an action and from the point of each action's
path farthest from home, and the worst outcome is kept.

Every action is checked against its category's constraints (:mod:`tml.verify.constraints`);
a violation found on several alternatives is reported once, with its worst numbers.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field, replace

from tml import actions
from tml.model import Comparison, ConditionKind, Event, Mission, Task
from tml.parameters import parse_boolean
from tml.verify.constraints import Constraint, Violation, check_step
from tml.verify.motion import FlightModel, Labels, Step, VehicleState
from tml.verify.profile import VehicleProfile
from tml.world import World

MAX_ALTERNATIVES = 16


@dataclass(frozen=True)
class Row:
    """One predicted execution of an action (the worst of its alternatives)."""

    task: str
    action: str
    line: int
    distance: float  # m
    duration: float  # s
    time: float  # s since the mission started, at the end of the action
    battery: float  # percent after the action
    clearance: float  # m from the path (or the destination) to the nearest obstacle
    event: str = ""  # the event handler the action belongs to, if any

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready dictionary."""
        return {"task": self.task, "event": self.event or None, "action": self.action,
                "line": self.line, "distance": round(self.distance, 3),
                "duration": round(self.duration, 3), "time": round(self.time, 3),
                "battery": round(self.battery, 3),
                "clearance": None if math.isinf(self.clearance) else round(self.clearance, 3)}


@dataclass
class Report:
    """Everything static verification found about one mission."""

    file: str
    profile: VehicleProfile
    rows: list[Row] = field(default_factory=list)
    violations: list[Violation] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    end: VehicleState | None = None  # the worst predicted state at the end
    approximate: bool = False

    @property
    def feasible(self) -> bool:
        """True when no constraint is broken on any way through the mission."""
        return not self.violations


@dataclass(frozen=True)
class _Alternative:
    state: VehicleState
    labels: tuple[tuple[str, tuple[float, float, float]], ...] = ()

    @property
    def label_map(self) -> Labels:
        return dict(self.labels)


def _alternative(state: VehicleState, labels: Labels) -> _Alternative:
    return _Alternative(state, tuple(sorted(labels.items())))


class _Walker:
    def __init__(self, model: FlightModel, event_labels: frozenset[str] = frozenset()) -> None:
        self.model = model
        # Labels an event handler may store at any time: reading one is not an error even
        # where no task has stored it yet (the IMAV 2016 mission's "item A coordinates").
        self.event_labels = event_labels
        self.found: dict[tuple[str, str], Violation] = {}
        self.rows: list[Row] = []
        self.notes: dict[str, None] = {}
        self.sources: list[tuple[str, VehicleState, Labels]] = []  # where events may fire
        self.approximate = False

    def tasks(self, tasks: Iterable[Task], alternatives: list[_Alternative],
              guarded: frozenset[str] = frozenset()) -> list[_Alternative]:
        for task in tasks:
            ran = alternatives
            inner = guarded | _guarded_labels(task)
            for iteration in range(task.repeat):
                name = task.path_name + (f" #{iteration + 1}" if task.repeat > 1 else "")
                ran = self.task(task, name, ran, inner)
            alternatives = self.merge(ran + alternatives if task.conditions else ran)
        return alternatives

    def task(self, task: Task, name: str, alternatives: list[_Alternative],
             guarded: frozenset[str] = frozenset()) -> list[_Alternative]:
        if task.action is None:
            return self.tasks(task.children, alternatives, guarded)
        bound = actions.bind(task.action)
        steps = [self.model.step(bound, a.state, a.label_map) for a in alternatives]
        for step in steps:
            self.judge(bound, step, name, guarded | self.event_labels)
            if step.after.flying:
                self.sources.append((name, step.after, step.labels))
                far = self.farthest(step)
                if far is not None:
                    self.sources.append((name, far, step.labels))
        self.row(bound, steps, name)
        return self.merge([_alternative(s.after, s.labels) for s in steps])

    def farthest(self, step: Step) -> VehicleState | None:
        points = step.waypoints()
        if not points:
            return None
        home = step.after.home
        point, battery = max(points, key=lambda p: math.hypot(p[0][0] - home[0],
                                                                p[0][1] - home[1]))
        if point == step.after.position:
            return None
        return replace(step.after, position=point, battery=battery)

    def judge(self, bound: actions.BoundAction, step: Step, where: str,
              excused: frozenset[str] = frozenset()) -> None:
        for note in step.notes:
            self.notes[f"{bound.action.location}: {bound.name}: {note}"] = None
        for violation in check_step(bound, step, self.model):
            if violation.constraint is Constraint.LABEL and step.unknown_label in excused:
                continue  # guarded by "known", or an event may have stored it
            violation = replace(violation, task=where)
            key = (violation.constraint.value, str(violation.location))
            kept = self.found.get(key)
            if kept is None or violation.excess > kept.excess:
                self.found[key] = violation

    def row(self, bound: actions.BoundAction, steps: list[Step], task: str,
            event: str = "") -> None:
        worst = min(steps, key=lambda s: s.after.battery)
        points = worst.path_points()
        if worst.destination is not None and not points:
            points = [worst.destination]
        clearance = self.model.planner.clearance_of(points) if points else math.inf
        self.rows.append(Row(task, bound.name, bound.action.location.line, worst.distance,
                             worst.duration, worst.after.time, worst.after.battery,
                             clearance, event))

    def merge(self, alternatives: list[_Alternative]) -> list[_Alternative]:
        grouped: dict[tuple[object, ...], _Alternative] = {}
        for alternative in alternatives:
            state = alternative.state
            key = (tuple(round(v, 3) for v in state.position), state.flying, state.home,
                   state.speed, state.climb_rate, state.descent_rate,
                   round(state.heading, 3), alternative.labels)
            kept = grouped.get(key)
            if kept is not None:
                state = replace(state, battery=min(state.battery, kept.state.battery),
                                time=max(state.time, kept.state.time))
            grouped[key] = replace(alternative, state=state)
        merged = sorted(grouped.values(), key=lambda a: a.state.battery)
        if len(merged) > MAX_ALTERNATIVES:
            self.approximate = True
            merged = merged[:MAX_ALTERNATIVES]
        return merged

    def event(self, event: Event) -> None:
        if not event.actions:
            return
        bounds = [actions.bind(action) for action in event.actions]
        worst: list[Step] | None = None
        for where, state, labels in self.sources:
            steps: list[Step] = []
            for bound in bounds:
                step = self.model.step(bound, state, labels)
                self.judge(bound, step, f"event {event.name} during {where}")
                steps.append(step)
                state, labels = step.after, step.labels
            if worst is None or steps[-1].after.battery < worst[-1].after.battery:
                worst = steps
        for bound, step in zip(bounds, worst or [], strict=False):
            self.row(bound, [step], "", event.name)


def _guarded_labels(task: Task) -> frozenset[str]:
    """Labels a task's conditions require to be known before it runs."""
    return frozenset(
        c.subject for c in task.conditions
        if c.kind is ConditionKind.LABEL and c.comparison is Comparison.KNOWN
        and parse_boolean(c.value or "yes") is not False)


def verify_mission(mission: Mission, profile: VehicleProfile, world: World | None = None,
                   start: VehicleState | None = None) -> Report:
    """Predict and check every action of ``mission`` (and of its event handlers).

    ``world`` is laid over the mission's own ``<environment>``; ``start`` is the state
    before the first action (default: on the ground at home, battery full, heading as
    the world's home).
    """
    merged = (mission.world or World()).merged(world)
    model = FlightModel(profile, merged)
    if start is None:
        start = VehicleState(heading=merged.home_or_default.heading)
    event_labels = frozenset(
        bound.labels["coordinates"] for event in mission.events for action in event.actions
        if (bound := actions.bind(action)).name == "MEMORIZE_POINT")
    walker = _Walker(model, event_labels)
    ends = walker.tasks(mission.tasks, [_alternative(start, {})])
    for event in mission.events:
        walker.event(event)
    violations = sorted(walker.found.values(), key=lambda v: (
        v.location.line if v.location else 0, v.constraint.value))
    end = min((a.state for a in ends), key=lambda s: s.battery, default=None)
    return Report(mission.file, profile, walker.rows, violations, list(walker.notes), end,
                  walker.approximate)
