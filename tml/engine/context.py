"""What every node of a running mission shares, and the rules that read and change it.

A :class:`Run` holds the time, the flight log being written, one :class:`Pilot` per vehicle
and the roles' bindings; its methods are the rules every node applies the same way:
evaluating conditions, counting skill uses, numbering and logging requests, recording task
states, picking and releasing vehicles, and the safe state. The nodes
(:mod:`tml.engine.composites`, :mod:`tml.engine.tasks`, :mod:`tml.engine.leaves`) and the
event handlers (:mod:`tml.engine.events`) change nothing else. See
:mod:`tml.engine.interpreter` for the theory of operation.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import Protocol, TypeVar

from tml.engine.conditions import Memory, evaluate, evaluate_all
from tml.engine.failures import Failure
from tml.engine.records import Change, Output, Record, Status, TaskState, View, request_fields
from tml.engine.resume import Restoring
from tml.engine.roles import Candidate, candidates
from tml.engine.safety import left_to_itself, safe_state_request
from tml.engine.scripts import Limits
from tml.errors import EngineError
from tml.language import skills
from tml.language.actions import BoundAction
from tml.language.failures import FailureReason
from tml.language.model import Condition, Mission, Task
from tml.vehicle import IdSource, Point, Request, RequestResult, SetSkill, VehicleState
from tml.world import World

# Waypoints from a point to another around known obstacles (ends included), or None.
Route = Callable[[Point, Point], list[Point] | None]
# Checks an action before it starts, given the live state, the labels and the mission time;
# returns the violated constraints (empty: feasible). See tml.verify.inflight.pre_check.
PreCheck = Callable[[BoundAction, VehicleState, dict[str, Point], float], list[str]]
# A task's roles and the one vehicle each stands for in it (key None: the mission has no
# roles, and the vehicle flies every task).
Roles = Mapping[str | None, int]


@dataclass
class Options:
    """How the interpreter flies."""

    safe_state: str = "rtl"  # rtl, land or hold: what a vehicle is told when nobody flies it
    limits: Limits = field(default_factory=Limits)
    world: World | None = None  # what GO_TO_RECTANGLE knows of frames, and the mission's home
    pre_check: PreCheck | None = None  # dynamic feasibility check before each action
    route: Route | None = None  # collision-free waypoints around known obstacles
    mission_stall: float = 300.0  # s without progress in a dispatch="mission" task


# --- explicit states ---------------------------------------------------------------------------

State = TypeVar("State", bound=Enum)


def moved(moves: Mapping[State, frozenset[State]], current: State, to: State,
          what: str) -> State:
    """``to``, when the table ``moves`` allows ``current`` to become it."""
    if to not in moves[current]:
        raise EngineError(f"{what} cannot go from {current.value} to {to.value}")
    return to


SAY_TASKS = "SAY_OUT_LOUD_CURRENT_TASK"
"""The skill that announces each task as it starts (tml says it: a ``say`` line)."""


class Duty(Enum):
    """What a vehicle's pilot is doing about events."""

    WATCHING = "watching"  # its event handlers are checked while it flies a task
    HANDLING = "handling"  # an event handler's actions run; its tasks' work is held
    LOST = "lost"  # its link is lost: it does nothing more and is never picked again


DUTY_MOVES: dict[Duty, frozenset[Duty]] = {
    Duty.WATCHING: frozenset({Duty.HANDLING, Duty.LOST}),
    Duty.HANDLING: frozenset({Duty.WATCHING, Duty.LOST}),
    Duty.LOST: frozenset(),
}


class WorkMode(Enum):
    """Where a leaf's work on its vehicle is (an action, or an autopilot plan)."""

    READY = "ready"  # not begun: it waits while its vehicle handles an event
    ACTIVE = "active"  # flying: waiting for a request's answer, a state, a time, progress
    HELD = "held"  # stopped by an event handler (the vehicle holds); resumed by CONTINUE
    AWAITING = "awaiting"  # failed; an event handler decides what follows
    ENDED = "ended"  # done, failed or stopped


WORK_MOVES: dict[WorkMode, frozenset[WorkMode]] = {
    WorkMode.READY: frozenset({WorkMode.ACTIVE, WorkMode.ENDED}),
    WorkMode.ACTIVE: frozenset({WorkMode.ACTIVE, WorkMode.HELD, WorkMode.AWAITING,
                                WorkMode.ENDED}),  # ACTIVE again: begun anew (REPEAT_TASK)
    WorkMode.HELD: frozenset({WorkMode.ACTIVE, WorkMode.ENDED}),
    WorkMode.AWAITING: frozenset({WorkMode.ACTIVE, WorkMode.ENDED}),
    WorkMode.ENDED: frozenset(),
}


class Verdict(Enum):
    """What an event handler's termination decides for held or failed work."""

    RESUME = "resume"  # CONTINUE a held action: its last request again, a fresh time limit
    GO_ON = "go on"  # CONTINUE after a failure: the task goes on as if the action were done
    RESTART = "restart"  # REPEAT_TASK: the action (or the plan) begins anew
    FAIL = "fail"  # nothing handles a failure: the work fails with it


class TaskOwner(Protocol):
    """The node of a running task, as the work in it and the event handlers see it."""

    @property
    def task(self) -> Task:
        """The task."""
        ...

    @property
    def owner(self) -> TaskOwner | None:
        """The node of the task around it (None at the top)."""
        ...

    @property
    def since(self) -> float:
        """When the task began to run."""
        ...

    def abandon(self, why: str) -> None:
        """End the task unfinished (ABORTED), the mission going on after it."""
        ...


class Work(Protocol):
    """A leaf at work on a vehicle, as its pilot and the event handlers see it."""

    @property
    def owner(self) -> TaskOwner | None:
        """The task it flies for (None: an event handler's action)."""
        ...

    @property
    def mode(self) -> WorkMode:
        """Where it is."""
        ...

    @property
    def task_path(self) -> tuple[str, ...]:
        """The task flown now (in a plan: the item's), () for an event handler's action."""
        ...

    @property
    def task_since(self) -> float:
        """When the task flown now began (TASK_ELAPSED_TIME)."""
        ...

    @property
    def action_name(self) -> str:
        """The action flown now."""
        ...

    @property
    def held_at(self) -> float | None:
        """The runner's time an event handler took the work over (held it, or its failure
        fired one), while the handler's termination is awaited; None otherwise."""
        ...

    def progress(self, clock: float) -> float | None:
        """How far the action is at ``clock`` (the mission's clock), 0 to 1, when it can
        tell."""
        ...

    @property
    def plan(self) -> tuple[Task, ...]:
        """The tasks flown as one autopilot plan (empty for an action)."""
        ...

    def hold(self) -> bool:
        """Stop for an event handler (the caller tells the vehicle to hold); True when it
        was flying."""
        ...

    def decide(self, verdict: Verdict, failure: Failure | None = None) -> None:
        """What follows, applied when the work is next stepped."""
        ...

    def carry_on(self) -> None:
        """Go on after a pause of the run, during which its vehicle held: the work's last
        request again, as CONTINUE does, its time limits going on where they stopped."""
        ...

    def on_result(self, result: RequestResult) -> bool:
        """Take the result of one of its requests; False when it is not its own."""
        ...


# --- the log -----------------------------------------------------------------------------------


class Log:
    """The time of the step being taken, and the requests and records it produces.

    Two clocks: ``now``, the runner's time of the step, which stamps the records; and
    :attr:`clock`, the mission's own, which stands still while the run is paused, so that
    every time limit, elapsed time and wait the rules measure stops counting then. What a
    person reads (the display's task changes, events and time) is stamped :attr:`stamp`:
    the runner's time since the mission started, as the flight log's ``mission_time``.
    """

    def __init__(self, vehicle_id: int | None) -> None:
        self.vehicle_id = vehicle_id  # whose the mission's own records are (a fleet of one)
        self.now = 0.0
        self.start = 0.0  # the mission clock's reading when the mission started
        self.paused = 0.0  # s the run was paused, pauses that are over
        self.paused_at: float | None = None  # when the pause now going on began
        self.out = Output()

    @property
    def clock(self) -> float:
        """The mission's clock: the time of the step less the time spent paused."""
        return self.clock_at(self.now)

    def clock_at(self, now: float) -> float:
        """The mission's clock at the runner's time ``now`` (not before the last step)."""
        return (now if self.paused_at is None else self.paused_at) - self.paused

    @property
    def mission_time(self) -> float:
        """Seconds the mission has run (pauses not counted): MISSION_ELAPSED_TIME."""
        return self.clock - self.start

    @property
    def stamp(self) -> float:
        """The mission time of the step for a person: seconds since the mission started on
        the runner's time, pauses counted (a resumed run counts on from the interrupted
        run's time)."""
        return self.stamp_of(self.now)

    def stamp_of(self, now: float) -> float:
        """The :attr:`stamp` of the runner's time ``now``."""
        return now - self.start

    def note(self, kind: str, message: str, vehicle_id: int | None, /, **data: object) -> None:
        """Add a record."""
        self.note_at(self.now, kind, message, vehicle_id, **data)

    def note_at(self, now: float, kind: str, message: str, vehicle_id: int | None, /,
                **data: object) -> None:
        """Add a record stamped with the runner's time ``now`` (earlier than the step's for
        what is said after the moment it happened: a task an event handler cut)."""
        self.out.records.append(Record(now, kind, {"message": message, **data}, vehicle_id))

    def take(self) -> Output:
        """What was produced since the last call."""
        out, self.out = self.out, Output()
        return out


@dataclass(eq=False)
class Pilot:
    """One vehicle as the engine knows it: what it carries, what it has learnt (memorized
    points, speed limits, the last target), its work and duty now, and its share of the
    log and the display. Scripts read and change it as their
    :class:`~tml.engine.scripts.Context`."""

    vehicle_id: int
    payloads: frozenset[str]
    state: VehicleState
    limits: Limits
    world: World | None
    route: Route | None
    log: Log
    labels: dict[str, Point] = field(default_factory=dict)
    last_target: Point | None = None
    duty: Duty = Duty.WATCHING
    role: str | None = None  # the role it is bound to
    free_since: float = -math.inf  # never used: free since before the run
    lost: str = ""  # why it cannot be used any more
    failure: FailureReason | None = None  # ACTION_FAILURE: why its last action failed
    skills: dict[str, int] = field(default_factory=dict)  # uses of each skill switched on
    work: list[Work] = field(default_factory=list)  # its running leaves, oldest first
    holding: dict[str, bool] = field(default_factory=dict)  # each event's conditions held
    events: list[tuple[float, str]] = field(default_factory=list)  # (mission time, event)
    states: dict[str, TaskState] = field(default_factory=dict)  # tasks it flew
    changes: list[Change] = field(default_factory=list)
    stirs: int = 0  # counts stir()

    @property
    def now(self) -> float:
        """The mission's clock (:attr:`Log.clock`), for the scripts' own timing."""
        return self.log.clock

    def note(self, message: str, **data: object) -> None:
        """Write a decision about this vehicle to the flight log."""
        self.log.note("decision", message, self.vehicle_id, **data)

    def link_failure(self) -> Failure:
        """The failure of the work of a vehicle whose link is lost."""
        return Failure(FailureReason.LINK, f"link: vehicle {self.vehicle_id}: {self.lost}",
                       self.vehicle_id)

    def become(self, duty: Duty) -> None:
        """Change duty, as :data:`DUTY_MOVES` allows."""
        self.stir()
        self.duty = moved(DUTY_MOVES, self.duty, duty, f"vehicle {self.vehicle_id}")

    def stir(self) -> None:
        """Something was done to its work from outside the tree's tick (a result, an event
        handler, a lost link): the nodes doing it are stepped next (tml.engine.wake)."""
        self.stirs += 1

    def flying_a_task(self) -> bool:
        """Whether it flies a task now (its event handlers are checked then)."""
        # A loop is quicker than any() over a generator: asked of every vehicle at every step.
        for work in self.work:  # noqa: SIM110
            if work.owner is not None and work.mode is not WorkMode.ENDED:
                return True
        return False

    def current(self) -> Work | None:
        """The task work begun last."""
        return next((w for w in reversed(self.work) if w.task_path), None)

    def interrupted_at(self, path: tuple[str, ...]) -> float | None:
        """When an event handler took over the work it holds in the task ``path`` (or
        below), if it holds any: the moment the task stopped flying."""
        held = [w.held_at for w in self.work if w.owner is not None and w.held_at is not None
                and w.task_path[:len(path)] == path]
        return min(held) if held else None

    def memory(self, now: float, mission_time: float) -> Memory:
        """What its event handlers read besides the vehicle's state."""
        current = self.current()
        path = current.task_path if current else ()
        running = {w.task_path[:i] for w in self.work for i in range(1, len(w.task_path) + 1)}
        action = self.work[-1].action_name if self.work else ""
        return Memory(self.labels, mission_time, now - (current.task_since if current else now),
                      path, action, self.failure, frozenset(running))


# --- the run -----------------------------------------------------------------------------------


def _no_event(pilot: Pilot) -> bool:
    return False


class Run:
    """One mission being flown by its vehicles; see the module docstring."""

    def __init__(self, mission: Mission, vehicles: Sequence[int], options: Options,
                 payloads: Mapping[int, Iterable[str]], ids: IdSource) -> None:
        self.mission = mission
        self.options = options
        self.ids = ids
        alone = not mission.roles and len(vehicles) == 1
        self.log = Log(vehicles[0] if alone else None)
        world = options.world or mission.world
        self.pilots = {vid: Pilot(vid, frozenset(p.lower() for p in payloads.get(vid, ())),
                                  VehicleState(vid, 0.0), replace(options.limits), world,
                                  options.route, self.log)
                       for vid in vehicles}
        self.home = world.home if world is not None else None
        self.bound: dict[str | None, tuple[int, ...]] = {}
        self.pending = {t.path_name: TaskState.PENDING for t in mission.walk()}
        self.shared: dict[str, TaskState] = {}  # tasks no vehicle flies
        self.changes = 0  # task changes recorded: each Change's number
        self.started = False  # the mission has started (Interpreter.start)
        self.status = Status.RUNNING
        self.reason = ""
        self.ending = False  # the mission is ending: stopped work sends no hold
        self.jump_to: tuple[str, ...] | None = None  # JUMP_TO_TASK, for the next step
        self.finish: tuple[Status, str] | None = None  # END_MISSION or ABORT_MISSION
        # A resumed run's progress, taken by the nodes of its first step (tml.engine.resume).
        self.restoring: Restoring | None = None
        # An action failed on a vehicle: True when an event handler fired on it and
        # decides what follows (set by the interpreter to its event handling).
        self.react: Callable[[Pilot], bool] = _no_event

    @property
    def now(self) -> float:
        """The mission's clock (:attr:`Log.clock`): every duration the rules measure is
        measured on it."""
        return self.log.clock

    @property
    def paused(self) -> bool:
        """Whether the run is paused: nothing is stepped, the vehicles hold."""
        return self.log.paused_at is not None

    @property
    def halted(self) -> bool:
        """Whether the mission is ending: no node starts anything more."""
        return self.status is not Status.RUNNING or self.finish is not None

    def note(self, kind: str, message: str, vehicle_id: int | None = None, /,
             **data: object) -> None:
        """Add a record about ``vehicle_id`` (None: about the mission)."""
        self.log.note(kind, message, vehicle_id, **data)

    def send(self, request: Request) -> Request:
        """Number a request, send it and log it; the request as sent."""
        sent = replace(request, request_id=self.ids.take())
        self.log.out.requests.append(sent)
        self.note("request", sent.name, sent.vehicle_id, request_id=sent.request_id,
                  **request_fields(sent))
        return sent

    def set_state(self, task: Task, state: TaskState, vehicle_id: int | None,
                  resumed: bool = False, at: float | None = None) -> None:
        """Record that ``task`` (flown by ``vehicle_id``, or by none) is now in ``state``
        (``resumed``: re-entered by a resumed run, :mod:`tml.engine.resume`), stamped ``at``
        that runner's time when it is said later than it happened (the moment an event
        handler took over a task it then cut), else now."""
        path = task.path_name
        more: dict[str, object] = {"resumed": True} if resumed else {}
        now = self.log.now if at is None else at
        if at is not None:
            more["decided"] = round(self.log.stamp, 3)  # the mission time it was decided
        self.log.note_at(now, "task", f"{path}: {state.value}", vehicle_id, task=path,
                         state=state.value, **more)
        if state is TaskState.RUNNING and vehicle_id is not None \
                and self.pilots[vehicle_id].skills.get(SAY_TASKS, 0) > 0:
            self.log.note_at(now, "say", f"now: {path}", vehicle_id, task=path)
        self.changes += 1
        change = Change(self.log.stamp_of(now), path, state, vehicle_id, self.changes)
        if vehicle_id is None:
            self.shared[path] = state
            for pilot in self.pilots.values():
                pilot.changes.append(change)
        else:
            pilot = self.pilots[vehicle_id]
            pilot.states[path] = state
            pilot.changes.append(change)

    def skill(self, pilot: Pilot, name: str, on: bool) -> None:
        """Count a use of a skill on or off: the vehicle is told when the first use begins
        and when the last ends."""
        count = pilot.skills.get(name, 0) + (1 if on else -1)
        if count < 0:
            raise EngineError(f"skill {name} switched off more often than on")
        pilot.skills[name] = count
        spec = skills.lookup(name)
        if count == (1 if on else 0) and not (spec is not None and spec.ground):
            self.send(SetSkill(pilot.vehicle_id, name, on))

    def mission_skills(self, pilot: Pilot, on: bool) -> None:
        """The mission's own skills, for as long as the vehicle flies the mission."""
        for skill in self.mission.skills:
            self.skill(pilot, skill.name, on)

    def view(self, pilot: Pilot, now: float) -> View:
        """The display's snapshot of one vehicle at the runner's time ``now``."""
        current, last = pilot.current(), (pilot.work[-1] if pilot.work else None)
        log = self.log
        return View(self.status, {**self.pending, **self.shared, **pilot.states},
                    "/".join(current.task_path) if current else "",
                    last.action_name if last else "",
                    last.progress(log.clock_at(now)) if last else None,
                    dict(pilot.labels), tuple(pilot.events), log.stamp_of(now),
                    self.reason or pilot.lost, pilot.role or "", tuple(pilot.changes),
                    self.started, tuple("/".join(w.task_path) for w in pilot.work
                                        if w.owner is not None and w.held_at is not None))

    # --- conditions ----------------------------------------------------------------------------

    def vehicle(self, task: Task, roles: Roles) -> int | None:
        """The vehicle a task's conditions read: its role's in this branch, or the role's one
        vehicle."""
        vid = roles.get(task.role)
        bound = self.bound.get(task.role, ())
        return bound[0] if vid is None and len(bound) == 1 else vid

    def check(self, conditions: Sequence[Condition], task: Task, roles: Roles,
              since: float | None = None) -> tuple[Condition, object] | None:
        """The first of a task's conditions that does not hold and the value it read; None
        when they all hold. ``since``: when the task began to run (None: it has not)."""
        for condition, holds, value in self.readings(conditions, task, roles, since):
            if not holds:
                return condition, value
        return None

    def readings(self, conditions: Sequence[Condition], task: Task, roles: Roles,
                 since: float | None = None) -> list[tuple[Condition, bool, object]]:
        """Each of a task's conditions, whether it holds and the value it read."""
        vid = self.vehicle(task, roles)
        pilot = self.pilots[vid] if vid is not None else None
        memory = Memory(pilot.labels if pilot else {}, self.log.mission_time,
                        self.now - since if since is not None else 0.0, task.path, "",
                        pilot.failure if pilot else None,
                        frozenset(task.path[:i] for i in range(1, len(task.path) + 1)))
        return [(condition, *self.reading(condition, pilot, memory, roles))
                for condition in conditions]

    def holds(self, conditions: Sequence[Condition], task: Task, roles: Roles,
              since: float | None = None) -> bool:
        """Whether all of a task's conditions hold."""
        return self.check(conditions, task, roles, since) is None

    def reading(self, condition: Condition, pilot: Pilot | None, memory: Memory,
                roles: Roles) -> tuple[bool, object]:
        """Whether one condition holds and the value it read: from the role it names, else
        from ``pilot``'s vehicle; with no vehicle, only what the engine keeps itself (elapsed
        times, the current task) is known."""
        if condition.role is not None:
            return evaluate_all(condition, self.role_states(condition.role, roles), memory)
        state = pilot.state if pilot is not None else VehicleState(0, self.now)
        return evaluate(condition, state, memory)

    def role_states(self, role: str, roles: Roles) -> list[VehicleState]:
        """The states of a role's vehicles: the one standing for it in this branch, else all
        its vehicles (none when it is not picked)."""
        if role in roles:
            return [self.pilots[roles[role]].state]
        return [self.pilots[v].state for v in self.bound.get(role, ())]

    # --- roles ---------------------------------------------------------------------------------

    def pick(self, task: Task, name: str | None, since: float) -> tuple[int, ...] | Failure | None:
        """Bind a role's vehicles for ``task``: the vehicles, a failure once the role's
        ``pick_timeout`` (from ``since``) has run out, or None while it waits."""
        role = self.mission.role(name) if name is not None else None
        if role is None:
            return Failure(FailureReason.PICK, f"pick: {task.path_name}: no vehicle for it "
                           f"(role {name!r} is not declared)")
        chosen, refused = candidates(role, [
            Candidate(p.vehicle_id, p.state, p.payloads, p.free_since, p.role, p.lost)
            for p in self.pilots.values()], self.home)
        if len(chosen) >= role.count:
            picked = tuple(chosen[:role.count])
            self.bound[role.name] = picked
            for vid in picked:
                self.pilots[vid].role = role.name
                self.mission_skills(self.pilots[vid], True)
            self.note("pick", f"role {role.name!r}: vehicle{'s' if len(picked) > 1 else ''} "
                      f"{', '.join(map(str, picked))} picked", None, role=role.name,
                      vehicles=list(picked), waited=round(self.now - since, 3))
            return picked
        if self.now - since < role.pick_timeout:
            return None
        why = "; ".join(f"vehicle {vid}: {reason}" for vid, reason in refused)
        detail = (f"role {role.name!r} needs {role.count} vehicle{'s' if role.count > 1 else ''}"
                  f", {len(chosen)} qualified within {role.pick_timeout:g} s"
                  + (f" ({why})" if why else ""))
        self.note("pick", f"pick failed: {detail}", None, role=role.name, refused=dict(refused))
        return Failure(FailureReason.PICK, f"pick: {detail}")

    def release(self, name: str | None, reason: str) -> None:
        """Free a role's vehicles: their mission skills end, and each is put in the safe
        state (a flying vehicle is sent home, an armed one on the ground disarmed)."""
        for vid in self.bound.pop(name, ()):
            pilot = self.pilots[vid]
            pilot.role = None
            pilot.free_since = self.now
            if name is not None:
                self.note("release", f"role {name!r}: vehicle {vid} released ({reason})", vid,
                          role=name)
            self.mission_skills(pilot, False)
            self.safe_state(pilot, reason)

    def unbind(self, pilot: Pilot, entirely: bool = False) -> str | None:
        """Let go of a vehicle that cannot be used any more; the role it had. ``entirely``
        also lets go of a vehicle flying a mission without roles, so that the mission's end
        does not command it either (someone else took it)."""
        role = pilot.role
        if role is not None or entirely:
            rest = tuple(v for v in self.bound.get(role, ()) if v != pilot.vehicle_id)
            if rest:
                self.bound[role] = rest
            else:
                self.bound.pop(role, None)
            pilot.role = None
        return role

    def safe_state(self, pilot: Pilot, reason: str) -> None:
        """Command the safe state (:func:`~tml.engine.safety.safe_state_request`)."""
        safe = safe_state_request(pilot.state, self.options.safe_state)
        if safe is None:
            left = left_to_itself(pilot.state, self.options.safe_state)
            if left:  # a safe-state decision too: said, and confirmed like the others
                self.note("safety", f"{left} ({reason})", pilot.vehicle_id, request="")
        if safe is not None:
            request, why = safe
            self.note("safety", f"{why} ({reason})", pilot.vehicle_id, request=request.name)
            self.send(request)
