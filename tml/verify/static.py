"""Static verification: abstract execution of a whole mission before flight.

The task tree is walked depth-first as the interpreter will walk it, carrying a set of
*alternatives*, each a predicted :class:`PredictedState` with the labels memorized so far.
Repeats are unrolled. A task with conditions may or may not run, so after it the
alternatives of both ways are kept -- except where a condition on the battery is false at
the battery predicted there even :data:`BATTERY_MARGIN` points above it: that alternative
skips the task (a sortie guarded by "battery at least 60 %" is not flown after one that
used half the battery). Alternatives that end at the same place with the same
settings and labels are merged into one that takes the lowest battery and the latest time
(the worst of them); past :data:`MAX_ALTERNATIVES` the ones with most battery left are
dropped and the report says the result is approximate.

Event handlers can fire at any moment, so each event's actions are predicted from every
point where the vehicle is flying after an action and from the point of each action's
path farthest from home, and the worst outcome is kept.

Every action is checked against its category's constraints (:mod:`tml.verify.constraints`);
a violation found on several alternatives is reported once, with its worst numbers.

Fleets. A mission that declares roles is verified role by role: each role is one vehicle
(all its ``count`` vehicles fly the same tasks from the same start, so one prediction
covers them), starting from ``start``, flying the terminal tasks whose effective role is
that role in document order; the tasks of other roles leave it as it is, so parallel and
first compositions fly each role's branch independently (a role in several branches of one
composition flies them one after the other, which costs at least as much battery). A
choice is abstracted like a condition: each branch is walked from the state before it and
the alternatives of all branches are kept. An on_error handler is walked from the state at
the start of the task it guards and from the state at its end (the failure may come at
once or at the last action), and the ways that ran it join those that did not. A loop is
walked for one round (a loop forever cannot be bounded); until and time_limit can only
shorten a task, so the whole task is walked; wait_for leaves the vehicle as it is (a
recharge while waiting is not counted). After a task that releases a role, the role's
next pick may be another vehicle: its next task starts from ``start`` again (with the
labels kept), and its findings name the next vehicle of the role. A role is verified with
the profile given when its ``type`` admits that profile's vehicle type, else with the
shipped profile of the role's kind (a rover role with the rover profile), which the notes
say.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from tml.errors import Location
from tml.language import actions
from tml.language.kinds import Kind, role_kinds
from tml.language.model import Comparison, Composition, ConditionKind, Event, Mission, Role, Task
from tml.language.parameters import ORDERINGS, compare_numbers, lookup, parse_boolean
from tml.language.skills import mission_vehicle_skills
from tml.verify.constraints import Constraint, Violation, check_step
from tml.verify.motion import FlightModel, Labels, PredictedState, Step
from tml.verify.planner import Point3
from tml.verify.profile import SHIPPED_FOR_KIND, VehicleProfile, load_profile
from tml.verify.terrain import GroundCheck, ground_check
from tml.world import World

if TYPE_CHECKING:
    from tml.terrain import Terrain

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
    role: str = ""  # the role flying it, in a mission that declares roles
    vehicles: tuple[int, ...] = ()  # which of the role's vehicles (1, 2 ... in pick order)
    path: tuple[Point3, ...] = ()  # the points flown through, ending where the action ends
    # m above the ground at the lowest point of the path (terrain data given; NaN where it
    # does not cover the path, None where nothing is judged: an action that does not move,
    # a landing from where it is)
    terrain_clearance: float | None = None
    photos: tuple[Point3, ...] = ()  # where the camera is predicted to take photos

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready dictionary (``role`` and ``vehicles`` only when there are roles)."""
        found: dict[str, object] = {
            "task": self.task, "event": self.event or None, "action": self.action,
            "line": self.line, "distance": round(self.distance, 3),
            "duration": round(self.duration, 3), "time": round(self.time, 3),
            "battery": round(max(self.battery, 0.0), 3),  # 0: empty, never negative
            "clearance": None if math.isinf(self.clearance) else round(self.clearance, 3),
            "path": [[round(v, 2) for v in point] for point in self.path]}
        if self.photos:
            found["photos"] = [[round(v, 2) for v in point] for point in self.photos]
        if self.role:
            found |= {"role": self.role, "vehicles": list(self.vehicles)}
        return found


@dataclass
class Report:
    """Everything static verification found about one mission."""

    file: str
    profile: VehicleProfile
    rows: list[Row] = field(default_factory=list)
    violations: list[Violation] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    end: PredictedState | None = None  # the worst predicted state at the end
    approximate: bool = False
    roles: tuple[str, ...] = ()  # the roles verified, each as its own vehicle
    ends: dict[str, PredictedState] = field(default_factory=dict)  # role -> worst end
    warnings: list[str] = field(default_factory=list)  # not violations: the mission may fly
    skills: tuple[str, ...] = ()
    """The skills the mission switches on the vehicle (catalogue names, the ground ones left
    out): the vehicle must provide them (a companion computer), tml run waits for them."""
    terrain: str = ""
    """The terrain data the paths were judged over (a file or directory), if any."""

    @property
    def feasible(self) -> bool:
        """True when no constraint is broken on any way through the mission."""
        return not self.violations


def vehicles_text(vehicles: tuple[int, ...]) -> str:
    """``vehicle 1`` or ``vehicles 3, 4``: which of a role's vehicles a finding is about."""
    numbers = ", ".join(str(v) for v in vehicles)
    return f"vehicle {numbers}" if len(vehicles) == 1 else f"vehicles {numbers}"


@dataclass(frozen=True)
class _Alternative:
    state: PredictedState
    labels: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    pick: int = 0  # releases of the role so far: which of its vehicles flies now
    released: bool = False  # the role was released: its next task is flown by a fresh pick

    @property
    def label_map(self) -> Labels:
        return dict(self.labels)


def _alternative(state: PredictedState, labels: Labels, pick: int = 0) -> _Alternative:
    return _Alternative(state, tuple(sorted(labels.items())), pick)


class _Walker:
    """Walks the task tree for one vehicle: every terminal task, or a role's only."""

    def __init__(self, model: FlightModel, start: PredictedState,
                 event_labels: frozenset[str] = frozenset(), role: Role | None = None,
                 ground: GroundCheck | None = None) -> None:
        self.model = model
        self.ground = ground  # the paths' clearance over terrain data, when given
        self.start = start  # also the state of a fresh vehicle picked after a release
        self.role = role
        # Labels an event handler may store at any time: reading one is not an error even
        # where no task has stored it yet (the IMAV 2016 mission's "item A coordinates").
        self.event_labels = event_labels
        self.found: dict[tuple[str, str], Violation] = {}
        self.rows: list[Row] = []
        self.notes: dict[str, None] = {}
        # Notes of the flight model on actions, by (action, note): where each was said. A
        # note said of several actions (every CAPTURE_PHOTO) is printed once with its lines.
        self.action_notes: dict[tuple[str, str], dict[Location, None]] = {}
        # Where events may fire: (task, state, labels, pick).
        self.sources: list[tuple[str, PredictedState, Labels, int]] = []
        self.approximate = False

    @property
    def role_name(self) -> str:
        return self.role.name if self.role is not None else ""

    def vehicles(self, pick: int) -> tuple[int, ...]:
        """The role's vehicles flying after ``pick`` releases (none without roles)."""
        if self.role is None:
            return ()
        first = pick * self.role.count + 1
        return tuple(range(first, first + self.role.count))

    def tasks(self, tasks: Iterable[Task], alternatives: list[_Alternative],
              guarded: frozenset[str] = frozenset()) -> list[_Alternative]:
        for task in tasks:
            alternatives = self.entry(task, alternatives, guarded)
        return alternatives

    def entry(self, task: Task, alternatives: list[_Alternative], guarded: frozenset[str],
              optional: bool = True) -> list[_Alternative]:
        """``task`` as its parent runs it: rounds, error handler, release; ``optional``
        when its conditions may skip it (not so for the branch a choice picked)."""
        self.explain(task)
        inner = guarded | _guarded_labels(task)
        ran = [a for a in alternatives if not _battery_rules_out(task, a.state.battery)]
        if len(ran) < len(alternatives):
            self.notes[f"{task.location}: task {task.path_name}: skipped where its battery "
                       f"condition is false at the predicted battery + "
                       f"{BATTERY_MARGIN:g} points"] = None
        for iteration in range(task.repeat if ran else 0):  # a loop: for one round
            name = task.path_name + (f" #{iteration + 1}" if task.repeat > 1 else "")
            ran = self.task(task, name, ran, inner)
        if task.on_error:
            # The failure may come at once or at the last action.
            ran = ran + self.tasks(task.on_error, self.merge(alternatives + ran), inner)
        ran = self.released(task, ran)
        skippable = bool(task.conditions) or (task.loop is not None and bool(task.loop.conditions))
        return self.merge(ran + alternatives if optional and skippable else ran)

    def explain(self, task: Task) -> None:
        """Notes on what the walk assumes of the task's orchestration."""
        where = f"{task.location}: task {task.path_name}"
        if task.loop is not None:
            self.notes[f"{where}: loop verified for one round"] = None
        if task.until or task.time_limit is not None:
            self.notes[f"{where}: until and time_limit can only shorten the task; the "
                       "whole task is verified"] = None
        if any(_reads_battery(c.subject) for c in task.wait_for):
            self.notes[f"{where}: wait_for on the battery: the vehicle is taken as it was "
                       "(a recharge while waiting is not counted)"] = None

    def released(self, task: Task, alternatives: list[_Alternative]) -> list[_Alternative]:
        """After a task that releases the role, its next pick may be a fresh vehicle (the
        released one stays the end state until the role flies again)."""
        if self.role is None or self.role.name not in task.release:
            return alternatives
        return [replace(a, released=True) for a in alternatives]

    def picked(self, alternative: _Alternative) -> _Alternative:
        """The alternative as the role's next task finds it: a fresh vehicle if released."""
        if not alternative.released:
            return alternative
        fresh = replace(self.start, time=alternative.state.time)
        return _Alternative(fresh, alternative.labels, alternative.pick + 1)

    def task(self, task: Task, name: str, alternatives: list[_Alternative],
             guarded: frozenset[str] = frozenset()) -> list[_Alternative]:
        if task.action is None:
            if task.composition is Composition.CHOICE:
                # Which branch runs is known only in flight: each from the same state.
                return self.merge([a for child in task.children
                                   for a in self.entry(child, alternatives, guarded, False)])
            # Parallel and first branches of other roles leave this vehicle as it is.
            return self.tasks(task.children, alternatives, guarded)
        if self.role is not None and task.role != self.role.name:
            return alternatives
        bound = actions.bind(task.action)
        alternatives = [self.picked(a) for a in alternatives]
        steps = [(a.pick, self.model.step(bound, a.state, a.label_map)) for a in alternatives]
        for pick, step in steps:
            self.judge(bound, step, name, guarded | self.event_labels, pick)
            if step.after.flying:
                self.sources.append((name, step.after, step.labels, pick))
                far = self.farthest(step)
                if far is not None:
                    self.sources.append((name, far, step.labels, pick))
        self.row(bound, steps, name)
        return self.merge([_alternative(s.after, s.labels, pick) for pick, s in steps])

    def farthest(self, step: Step) -> PredictedState | None:
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
              excused: frozenset[str] = frozenset(), pick: int = 0) -> None:
        for note in step.notes:
            self.action_notes.setdefault((bound.name, note), {})[bound.action.location] = None
        unasked: frozenset[Constraint] = frozenset()
        if step.before.battery < 0:
            unasked = _ON_BATTERY  # it ran out before this action: said once, where it did
        elif step.after.battery < 0:
            # It runs out in this action (c2): no way home to judge.
            unasked = frozenset({Constraint.RETURN_RESERVE})
        found = check_step(bound, step, self.model, unasked=unasked)
        above = self.ground.violation(step, bound.name, bound.action.location) \
            if self.ground is not None else None
        for violation in found + ([above] if above is not None else []):
            if violation.constraint is Constraint.LABEL and step.unknown_label in excused:
                continue  # guarded by "known", or an event may have stored it
            violation = replace(violation, task=where, role=self.role_name,
                                vehicles=self.vehicles(pick))
            key = (violation.constraint.value, str(violation.location))
            kept = self.found.get(key)
            if kept is None or violation.excess > kept.excess:
                self.found[key] = violation

    def said(self) -> dict[str, None]:
        """The notes, those on actions once per (action, note) with every line it is
        said of."""
        notes = dict(self.notes)
        for (name, note), places in self.action_notes.items():
            first, *more = places
            lines = f" ({1 + len(more)} actions, lines {_lines(list(places))})" if more else ""
            notes[f"{first}: {name}: {note}{lines}"] = None
        return notes

    def row(self, bound: actions.BoundAction, steps: list[tuple[int, Step]], task: str,
            event: str = "") -> None:
        pick, worst = min(steps, key=lambda s: s[1].after.battery)
        points = worst.path_points()
        if worst.destination is not None and not points:
            points = [worst.destination]
        clearance = self.model.planner.clearance_of(points) if points else math.inf
        terrain = self.ground.table_value([s for _, s in steps]) \
            if self.ground is not None else None
        self.rows.append(Row(task, bound.name, bound.action.location.line, worst.distance,
                             worst.duration, worst.after.time, worst.after.battery,
                             clearance, event, self.role_name, self.vehicles(pick),
                             (*points, worst.after.position), terrain, worst.photos))

    def merge(self, alternatives: list[_Alternative]) -> list[_Alternative]:
        grouped: dict[tuple[object, ...], _Alternative] = {}
        for alternative in alternatives:
            state = alternative.state
            key = (tuple(round(v, 3) for v in state.position), state.flying, state.home,
                   state.speed, state.climb_rate, state.descent_rate,
                   round(state.heading, 3), alternative.labels, alternative.pick,
                   alternative.released)
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
        worst: list[tuple[int, Step]] | None = None
        for where, state, labels, pick in self.sources:
            steps: list[tuple[int, Step]] = []
            for bound in bounds:
                step = self.model.step(bound, state, labels)
                self.judge(bound, step, f"event {event.name} during {where}", pick=pick)
                steps.append((pick, step))
                state, labels = step.after, step.labels
            if worst is None or steps[-1][1].after.battery < worst[-1][1].after.battery:
                worst = steps
        for bound, picked in zip(bounds, worst or [], strict=False):
            self.row(bound, [picked], "", event.name)


_ON_BATTERY = frozenset({Constraint.C2, Constraint.RETURN_RESERVE})
"""The constraints on the battery left. The action where it runs out breaks c2, which says
so; past it there is no charge to judge, and each later action would only repeat the
finding with a negative charge."""

LINES_SHOWN = 10
"""Lines listed for a note said of many actions before the rest are counted."""


def _lines(places: list[Location]) -> str:
    """``4, 6, 8`` (and ``and 12 more`` past :data:`LINES_SHOWN`)."""
    shown = ", ".join(str(place.line) for place in places[:LINES_SHOWN])
    more = len(places) - LINES_SHOWN
    return f"{shown} and {more} more" if more > 0 else shown


def _guarded_labels(task: Task) -> frozenset[str]:
    """Labels a task's conditions require to be known before it runs."""
    return frozenset(
        c.subject for c in task.conditions
        if c.kind is ConditionKind.LABEL and c.comparison is Comparison.KNOWN
        and parse_boolean(c.value or "yes") is not False)


BATTERY_MARGIN = 10.0
"""Percentage points by which the real battery may be above the predicted one when a
battery condition is judged (the prediction is a worst case, and a close one: see
docs/verify.md)."""


def _battery_rules_out(task: Task, battery: float) -> bool:
    """True when a condition of ``task`` on its own vehicle's battery (an ordering
    comparison with a number) is false for every charge from ``battery`` to ``battery +
    BATTERY_MARGIN``."""
    for condition in task.conditions:
        if condition.kind is not ConditionKind.PARAMETER or condition.role is not None \
                or not _reads_battery(condition.subject) \
                or condition.comparison not in ORDERINGS:
            continue
        try:
            target = float(condition.value or "")
        except ValueError:
            continue
        if not any(compare_numbers(charge, condition.comparison, target)
                   for charge in (battery, battery + BATTERY_MARGIN)):
            return True
    return False


def _reads_battery(parameter: str) -> bool:
    spec = lookup(parameter)
    return spec is not None and spec.name == "BATTERY_CHARGE_PERCENTAGE"


def _lands_by_event(mission: Mission, walker: _Walker) -> bool:
    """Whether an event handler of the walker's vehicle lands it (an endless LOITER that
    an event ends with RETURN_HOME_AND_LAND does not end the mission in the air)."""
    role = walker.role.name if walker.role is not None else None
    return any(spec is not None and spec.category is actions.Category.TAKE_OFF_LANDING
               and spec.name != "TAKE_OFF"
               for event in mission.events if role is None or event.role in (None, role)
               for action in event.actions for spec in [actions.lookup(action.name)])


def verify_mission(mission: Mission, profile: VehicleProfile, world: World | None = None,
                   start: PredictedState | None = None,
                   terrain: Terrain | None = None) -> Report:
    """Predict and check every action of ``mission`` (and of its event handlers).

    ``world`` is laid over the mission's own ``<environment>``; ``start`` is the state
    before the first action (default: on the ground at home, battery full, heading as
    the world's home), and with roles the state of every vehicle when it is picked.
    ``terrain``: the ground's heights, over which every path is judged
    (:mod:`tml.verify.terrain`; the caller reads the data the world names).
    """
    merged = (mission.world or World()).merged(world)
    model = FlightModel(profile, merged)
    if start is None:
        start = PredictedState(heading=merged.home_or_default.heading)
    event_labels = frozenset(
        bound.labels["coordinates"] for event in mission.events for action in event.actions
        if (bound := actions.bind(action)).name == "MEMORIZE_POINT")
    notes: dict[str, None] = {}
    models = {profile.name: model}

    def role_model(role: Role) -> FlightModel:
        kinds = role_kinds(role.vehicle_type)
        if profile.kind in kinds:
            return model
        name = SHIPPED_FOR_KIND[next(kind for kind in Kind if kind in kinds)]
        notes[f"{role.location}: role {role.name} (type {role.vehicle_type}) verified with "
              f"the {name} profile"] = None
        if name not in models:
            models[name] = FlightModel(load_profile(name), merged)
        return models[name]

    def walking(flight: FlightModel, role: Role | None = None) -> _Walker:
        return _Walker(flight, start, event_labels, role, ground_check(flight, terrain))

    walkers = [walking(role_model(role), role) for role in mission.roles] or [walking(model)]
    if mission.roles:
        names = {role.name for role in mission.roles}
        notes |= {f"{task.location}: task {task.path_name}: flown by no declared role; not "
                  "verified": None
                  for task in mission.walk() if task.action is not None and task.role not in names}
    violations: list[Violation] = []
    ends: dict[str, PredictedState] = {}
    warnings: list[str] = []
    checks = [w.ground for w in walkers if w.ground is not None]
    if checks and (said := checks[0].home_warning()):
        warnings.append(said)
    for walker in walkers:
        finals = walker.tasks(mission.tasks, [_alternative(start, {})])
        # A ground vehicle is never in the air, and LAND is refused to it: where its mission
        # ends, the run's safe state stops it (disarm, tml.engine.safety).
        aloft = [a.state for a in finals if a.state.flying] \
            if walker.model.profile.kind is not Kind.GROUND else []
        if aloft and (walker.role is None or walker.rows) and not _lands_by_event(mission,
                                                                                   walker):
            whose = f"role {walker.role_name}: " if walker.role is not None else ""
            up = max(state.position[2] for state in aloft)
            warnings.append(f"{whose}the mission ends with the vehicle in the air (up to "
                            f"{up:.0f} m) on {len(aloft)} of {len(finals)} way(s) through it: "
                            "it hovers there until its battery fails; end with LAND or "
                            "RETURN_HOME_AND_LAND")
        for event in mission.events:
            if walker.role is None or event.role in (None, walker.role.name):
                walker.event(event)
        violations += walker.found.values()
        notes |= walker.said()
        end = min((a.state for a in finals), key=lambda s: s.battery, default=None)
        if end is not None and (walker.role is None or walker.rows):
            ends[walker.role_name] = end
    violations.sort(key=lambda v: (v.location.line if v.location else 0, v.constraint.value,
                                   v.role))
    rows = [row for walker in walkers for row in walker.rows]
    end = min(ends.values(), key=lambda s: s.battery, default=None)
    roles = tuple(role.name for role in mission.roles)
    skills = mission_vehicle_skills(mission)
    return Report(mission.file, profile, rows, violations, list(notes), end,
                  any(w.approximate for w in walkers), roles,
                  ends if mission.roles else {}, warnings, tuple(sorted(skills)),
                  terrain.source if terrain is not None else "")
