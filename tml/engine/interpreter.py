"""The TML interpreter: depth-first stepping of the task tree, with event handling.

Theory of operation
-------------------
The interpreter is pure: each call takes the time and the vehicle's latest state (and the
results of requests) and returns the requests to send and the records to log. It never
sleeps, reads a clock or touches a link, so every rule below is tested with a fake vehicle
and an injected clock.

*Cursor.* A stack of frames walks the task tree depth-first, as the paper describes. A
task is entered when the walk reaches it: its conditions are evaluated then (all must
hold, else it is skipped and the decision is logged with the values read), its skills are
switched on, and it runs ``repeat`` times: a terminal task by running its action, a
non-terminal one by running its children in order. Leaving a task switches its skills off.
A task with ``dispatch="mission"`` under a ``command`` parent is flown whole by the
autopilot: its terminal actions go to the vehicle in one :class:`~tml.vehicle.FlyMission`
request, and the vehicle's mission progress names the task being flown.

*Actions.* A terminal task's action runs as a script (:mod:`tml.engine.scripts`): it sends
requests, waits for their results, and watches telemetry for completion within a time
limit. A failed action sets ACTION_FAILURE; if no event handler fires on it, the mission
ends (status FAILED, or ABORTED when the action was infeasible).

*Events.* On every step while the mission runs, every event handler's conditions are
evaluated (conjunctive). A handler fires on the rising edge of its conditions (or on every
step while they hold, with ``trigger="level"``), one handler per step. A handler whose
actions only memorize points runs without disturbing the running action; otherwise the
running action is stopped (the vehicle is told to hold) and the handler's actions run in
order. Then its termination applies: CONTINUE resumes the stopped action (its last request
is sent again), NEXT_TASK goes on after the current task, REPEAT_TASK starts it again,
ABORT_TASK abandons the task the handler is scoped to with ``current_task`` (else the
current task) and goes on after it, JUMP_TO_TASK continues from the named task,
END_MISSION ends the mission as completed, ABORT_MISSION ends it as aborted.

*Safety.* When the mission ends for any reason with the vehicle in the air, or when the
runner calls :meth:`Interpreter.abort`, the vehicle is commanded to the safe state (RTL by
default; land or hold by option), and disarmed if it is armed on the ground.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum

from tml.engine.conditions import Memory, evaluate, evaluate_all
from tml.engine.scripts import (
    SCRIPTS,
    ActionFailed,
    Limits,
    Script,
    Send,
    Sleep,
    Until,
    script_for,
)
from tml.language.actions import CAPABILITIES, BoundAction, Category, bind, lookup
from tml.language.kinds import Kind, kind_of
from tml.language.model import (
    Action,
    Condition,
    ConditionKind,
    Dispatch,
    Event,
    EventTrigger,
    Mission,
    Task,
    TerminationMode,
)
from tml.vehicle import (
    Disarm,
    FlyMission,
    Hold,
    Land,
    Point,
    Request,
    RequestResult,
    ReturnToLaunch,
    SetSkill,
    VehicleState,
)
from tml.world import World


class Status(StrEnum):
    """Where a mission run is."""

    RUNNING = "running"
    COMPLETED = "completed"
    ABORTED = "aborted"  # ABORT_MISSION, an infeasible action, or the runner's abort
    FAILED = "failed"  # an action failed (vehicle refusal, timeout) and nothing handled it


class TaskState(StrEnum):
    """What happened to a task, for the live view and the log."""

    PENDING = "pending"
    RUNNING = "running"
    DONE = "done"
    SKIPPED = "skipped"
    FAILED = "failed"
    ABORTED = "aborted"


@dataclass(frozen=True)
class Record:
    """One line of the flight log: what the interpreter decided or saw, and when.

    ``data`` holds plain values (numbers, text, tuples, sets); the journal writes them as JSON.
    """

    time: float
    kind: str
    data: dict[str, object]
    vehicle_id: int | None = None  # whose record it is, in a fleet


@dataclass
class Output:
    """What a step returns: requests to submit and records to log."""

    requests: list[Request] = field(default_factory=list)
    records: list[Record] = field(default_factory=list)


# Waypoints from a point to another around known obstacles (ends included), or None.
Route = Callable[[Point, Point], list[Point] | None]
# Checks an action before it starts, given the live state, the labels and the mission time;
# returns the violated constraints (empty: feasible). See tml.verify.inflight.pre_check.
PreCheck = Callable[[BoundAction, VehicleState, dict[str, Point], float], list[str]]
# The latest states of a role's vehicles (empty when the role is not picked), for
# conditions that name a role.
RoleStates = Callable[[str], Sequence[VehicleState]]


@dataclass
class Options:
    """How the interpreter flies."""

    safe_state: str = "rtl"  # rtl, land or hold: what the vehicle is told when a run ends
    limits: Limits = field(default_factory=Limits)
    world: World | None = None  # what GO_TO_RECTANGLE knows of frames
    pre_check: PreCheck | None = None  # dynamic feasibility check before each action
    route: Route | None = None  # collision-free waypoints around known obstacles
    mission_stall: float = 300.0  # s without progress in a dispatch="mission" task
    role_states: RoleStates | None = None  # for conditions with role=
    # At the end of a run the vehicle is commanded to the safe state. A fleet's branch ends
    # with end_safe=False: a completed branch leaves its vehicle where it is (the next task
    # takes over), a failed one only stops it (hold); the fleet decides what comes next.
    end_safe: bool = True


@dataclass(frozen=True)
class View:
    """A snapshot for the live display."""

    status: Status
    task_states: dict[str, TaskState]
    current_task: str
    current_action: str
    progress: float | None
    labels: dict[str, Point]
    events: tuple[tuple[float, str], ...]
    mission_time: float
    reason: str
    role: str = ""  # the role the vehicle flies, in a fleet


_INSTANT = {Category.MEMORY}


@dataclass
class _Frame:
    task: Task
    index: int = 0
    iteration: int = 1


@dataclass
class _Run:
    """A running action script and where it is waiting."""

    bound: BoundAction
    script: Script
    task: Task | None
    step: Send | Until | Sleep | None = None
    since: float = 0.0
    request_id: int = 0
    last_request: Request | None = None
    resume_at: Until | Sleep | None = None  # the wait to go back to once resent
    progress: float | None = None


@dataclass
class _Plan:
    """A dispatch="mission" task being flown by the autopilot."""

    plan_id: int
    root: Task
    tasks: list[Task]
    actions: list[BoundAction]
    index: int = -1
    since: float = 0.0
    limit: float = math.inf  # s the current item may take before the plan has stalled
    request_id: int = 0


# Plan ids are unique in the process: a vehicle reports the last plan's progress until the
# next one is uploaded, and a later interpreter on it (a fleet's next task) must not take
# that progress for its own plan's.
_plan_ids = itertools.count(1)


class Interpreter:
    """Runs one mission on one vehicle; see the module docstring."""

    def __init__(self, mission: Mission, vehicle_id: int = 1,
                 options: Options | None = None) -> None:
        self.mission = mission
        self.vehicle_id = vehicle_id
        self.options = options or Options()
        self.limits = replace(self.options.limits)
        self.world = self.options.world or mission.world
        self.labels: dict[str, Point] = {}
        self.last_target: Point | None = None
        self.route = self.options.route
        self.status = Status.RUNNING
        self.reason = ""
        self.mission_end: Status | None = None  # set when END/ABORT_MISSION ended the run
        self._root = Task("", (), mission.location, children=mission.tasks)
        self._stack: list[_Frame] = []
        self._terminal: Task | None = None
        self._terminal_left = 0
        self._run: _Run | None = None
        self._plan: _Plan | None = None
        self._handling: Event | None = None
        self._handler_actions: list[Action] = []
        self._interrupted: _Run | None = None
        self._holding: dict[str, bool] = {}
        self._failure: str | None = None
        self._failed_run: _Run | None = None
        self._skills: dict[str, int] = {}
        self._task_started: dict[tuple[str, ...], float] = {}
        self._states: dict[str, TaskState] = {t.path_name: TaskState.PENDING
                                              for t in mission.walk()}
        self._events: list[tuple[float, str]] = []
        self._start = 0.0
        self._now = 0.0
        self._state = VehicleState(vehicle_id, 0.0)
        self._out = Output()

    # --- the public API ----------------------------------------------------------------------

    @property
    def state(self) -> VehicleState:
        """The latest vehicle state the interpreter was given."""
        return self._state

    def start(self, now: float, state: VehicleState | None = None) -> Output:
        """Begin the mission: mission-level skills on, cursor at the first task."""
        self._begin(now, state)
        self._start = now
        self._note("mission", f"mission {self.mission.name!r} started", name=self.mission.name)
        lacking = self._lacking(state)
        if lacking:
            self._end(Status.FAILED, lacking)
            return self._finish()
        for skill in self.mission.skills:
            self._skill(skill.name, True)
        self._stack = [_Frame(self._root)]
        self._advance()
        return self._finish()

    def step(self, now: float, state: VehicleState,
             results: Sequence[RequestResult] = ()) -> Output:
        """Take the time, the latest state and request results; return what to do."""
        self._begin(now, state)
        if self.status is not Status.RUNNING:
            return self._finish()
        for result in results:
            self._result(result)
        self._events_tick()
        self._drive()
        return self._finish()

    def abort(self, now: float, state: VehicleState, reason: str) -> Output:
        """Stop everything and command the safe state (interpreter error, link, Ctrl-C)."""
        self._begin(now, state)
        if self.status is Status.RUNNING:
            self._end(Status.ABORTED, reason)
        else:
            self._safe_state(reason)
        return self._finish()

    def _lacking(self, state: VehicleState | None) -> str:
        """Why the vehicle cannot fly this mission, for an action that needs what it has
        not got (a FLIP mode, a gripper); "" when it can (or its state is not known)."""
        if state is None:
            return ""
        for _, action in self.mission.actions():
            spec = lookup(action.name)
            if spec is not None and spec.requires and spec.requires not in state.capabilities:
                return (f"{spec.name} (line {action.location.line}) needs "
                        f"{CAPABILITIES[spec.requires]}, and vehicle {self.vehicle_id} has none"
                        f" (refused before take-off)")
        return ""

    def stop(self, now: float, state: VehicleState, reason: str) -> Output:
        """End the run as stopped from outside (a fleet's until, time limit or sibling):
        the running action is stopped and a flying vehicle told to hold, nothing more."""
        self._begin(now, state)
        if self.status is Status.RUNNING:
            safe, self.options = self.options, replace(self.options, end_safe=False)
            self._end(Status.ABORTED, reason)
            self.options = safe
            if state.flying and not any(isinstance(r, Hold) for r in self._out.requests):
                self._send(Hold(self.vehicle_id))
        return self._finish()

    def view(self) -> View:
        """A snapshot for the display."""
        run = self._run
        task = self._terminal.path_name if self._terminal else ""
        return View(self.status, dict(self._states), task,
                    run.bound.name if run else "", run.progress if run else None,
                    dict(self.labels), tuple(self._events), self._now - self._start, self.reason)

    # --- plumbing ------------------------------------------------------------------------------

    def _begin(self, now: float, state: VehicleState | None) -> None:
        self._now = now
        if state is not None:
            self._state = state
        self._out = Output()

    def _finish(self) -> Output:
        out, self._out = self._out, Output()
        return out

    def _note(self, kind: str, message: str, /, **data: object) -> None:
        self._out.records.append(Record(self._now, kind, {"message": message, **data}))

    def _send(self, request: Request) -> None:
        self._out.requests.append(request)
        self._note("request", request.name, request_id=request.request_id,
                   **request_fields(request))

    def note(self, message: str, **data: object) -> None:
        """For scripts: log a decision."""
        self._note("decision", message, **data)

    def _memory(self) -> Memory:
        current = self._terminal.path if self._terminal else ()
        running = {current[:i] for i in range(1, len(current) + 1)}
        running |= {frame.task.path for frame in self._stack if frame.task.path}
        started = self._task_started.get(current, self._now)
        return Memory(self.labels, self._now - self._start, self._now - started, current,
                      self._run.bound.name if self._run else "", self._failure,
                      frozenset(running))

    def _evaluate(self, condition: Condition, memory: Memory) -> tuple[bool, object]:
        read_role = self.options.role_states
        if condition.role is not None and read_role is not None:
            return evaluate_all(condition, read_role(condition.role), memory)
        return evaluate(condition, self._state, memory)

    def _skill(self, name: str, enabled: bool) -> None:
        count = self._skills.get(name, 0) + (1 if enabled else -1)
        self._skills[name] = count
        if (enabled and count == 1) or (not enabled and count == 0):
            self._send(SetSkill(self.vehicle_id, name, enabled))

    def _set(self, task: Task, state: TaskState) -> None:
        if task.path:
            self._states[task.path_name] = state
            self._note("task", f"{task.path_name}: {state.value}", task=task.path_name,
                       state=state.value)

    # --- the cursor ----------------------------------------------------------------------------

    def _advance(self) -> None:
        """Move the cursor to the next terminal task and start it (or end the mission)."""
        while self.status is Status.RUNNING and self._run is None and self._plan is None:
            if self._terminal is not None and self._terminal_left > 0:
                self._start_action(self._terminal)
                return
            if self._terminal is not None:
                self._leave(self._terminal, TaskState.DONE)
                self._terminal = None
            if not self._stack:
                self._end(Status.COMPLETED, "all tasks done")
                return
            frame = self._stack[-1]
            if frame.index < len(frame.task.children):
                child = frame.task.children[frame.index]
                frame.index += 1
                self._enter(child)
            elif frame.iteration < frame.task.repeat:
                frame.iteration += 1
                frame.index = 0
                self._note("decision", f"{frame.task.path_name}: repeat "
                           f"{frame.iteration} of {frame.task.repeat}",
                           task=frame.task.path_name, iteration=frame.iteration)
            else:
                self._stack.pop()
                if frame.task is not self._root:
                    self._leave(frame.task, TaskState.DONE)

    def _enter(self, task: Task) -> None:
        memory = self._memory()
        for condition in task.conditions:
            holds, value = self._evaluate(condition, memory)
            if not holds:
                self._note("decision", f"{task.path_name}: skipped, condition false",
                           task=task.path_name, subject=condition.subject,
                           comparison=condition.comparison.value if condition.comparison
                           else None, expected=condition.value, read=value,
                           line=condition.location.line)
                self._set(task, TaskState.SKIPPED)
                return
        self._task_started[task.path] = self._now
        self._set(task, TaskState.RUNNING)
        for skill in task.skills:
            self._skill(skill.name, True)
        if task.dispatch is Dispatch.MISSION:
            self._fly_as_mission(task)
        elif task.is_terminal:
            self._terminal = task
            self._terminal_left = task.repeat
        else:
            self._stack.append(_Frame(task))

    def _leave(self, task: Task, state: TaskState) -> None:
        for skill in task.skills:
            self._skill(skill.name, False)
        self._set(task, state)

    def _unwind_to(self, target: Task | None) -> None:
        """Leave the current terminal task and frames up to (and including) ``target``."""
        if self._terminal is not None:
            self._leave(self._terminal, TaskState.ABORTED)
            self._terminal = None
        if target is None:
            return
        while self._stack and self._stack[-1].task is not self._root:
            frame = self._stack.pop()
            self._leave(frame.task, TaskState.ABORTED)
            if frame.task is target:
                return

    def _jump(self, target: Task) -> None:
        """Continue depth-first from ``target``: rebuild the stack down to its parent."""
        self._unwind_to(None)
        while self._stack and self._stack[-1].task is not self._root:
            frame = self._stack.pop()
            self._leave(frame.task, TaskState.ABORTED)
        self._stack = [_Frame(self._root)]
        node = self._root
        for depth in range(1, len(target.path)):
            child = next(c for c in node.children if c.path == target.path[:depth])
            self._stack[-1].index = node.children.index(child) + 1
            self._task_started[child.path] = self._now
            self._set(child, TaskState.RUNNING)
            for skill in child.skills:
                self._skill(skill.name, True)
            self._stack.append(_Frame(child))
            node = child
        self._stack[-1].index = node.children.index(target)

    # --- actions -------------------------------------------------------------------------------

    def _start_action(self, task: Task) -> None:
        self._terminal_left -= 1
        assert task.action is not None
        self._new_run(task.action, task)  # sets self._run (or fails, maybe firing an event)

    def _new_run(self, action: Action, task: Task | None) -> _Run | None:
        bound = bind(action)
        self._failure = None
        self._note("action", f"{bound.name} started", action=bound.name,
                   task=task.path_name if task else None, line=action.location.line,
                   arguments=dict(bound.values), labels=dict(bound.labels))
        run = _Run(bound, script_for(self, bound), task, since=self._now)
        if self.options.pre_check is not None:
            violations = self.options.pre_check(bound, self._state, self.labels,
                                                self._now - self._start)
            if violations:
                self._fail(run, "infeasible", "; ".join(violations))
                return None
        self._run = run
        self._drive()
        return self._run

    def _drive(self) -> None:
        """Run the current script until it waits; then start whatever comes next."""
        if self._plan is not None:
            self._track_plan()
        run = self._run
        while run is not None and self.status is Status.RUNNING:
            step = run.step
            if isinstance(step, Send):
                return  # waiting for the request's result
            if isinstance(step, Until):
                if step.progress is not None:
                    run.progress = step.progress(self._state)
                if not step.predicate(self._state):
                    if self._now - run.since > step.limit:
                        self._fail(run, "timeout", f"did not {step.what} within "
                                   f"{step.limit:.0f} s")
                    return
            elif isinstance(step, Sleep):
                run.progress = min(1.0, (self._now - run.since) / max(step.seconds, 1e-9))
                if self._now - run.since < step.seconds:
                    return
            try:
                run.step = next(run.script)
            except StopIteration:
                self._complete(run)
                run = self._run
                continue
            except ActionFailed as failure:
                self._fail(run, failure.reason, failure.detail)
                return
            run.since = self._now
            if isinstance(run.step, Send):
                run.request_id = run.step.request.request_id
                run.last_request = run.step.request
                self._send(run.step.request)

    def _result(self, result: RequestResult) -> None:
        plan = self._plan
        if plan is not None and result.request_id == plan.request_id and not result.ok:
            self._plan_failed(plan, result.reason or "rejected", "the vehicle refused the "
                              "mission" + (f": {result.detail}" if result.detail else ""))
            return
        run = self._run
        if run is None or not isinstance(run.step, Send) or result.request_id != run.request_id:
            if not result.ok:
                self._note("result", f"request {result.request_id} failed: {result.reason}",
                           request_id=result.request_id, ok=False, reason=result.reason,
                           detail=result.detail)
            return
        self._note("result", f"{run.step.request.name} {'done' if result.ok else 'failed'}",
                   request_id=result.request_id, ok=result.ok, reason=result.reason,
                   detail=result.detail)
        if result.ok:
            # Go on with the script at the next drive; a resumed action first goes back to
            # the wait it was stopped in (with a fresh time limit).
            run.step, run.resume_at = run.resume_at or Sleep(0.0), None
            run.since = self._now
        else:
            self._fail(run, result.reason or "rejected",
                       f"{run.step.request.name} refused" + (f": {result.detail}"
                                                              if result.detail else ""))

    def _complete(self, run: _Run) -> None:
        self._note("action", f"{run.bound.name} done", action=run.bound.name,
                   task=run.task.path_name if run.task else None)
        self._run = None
        if self._handling is not None:
            self._next_handler_action()
        else:
            self._advance()

    def _fail(self, run: _Run, reason: str, detail: str) -> None:
        self._note("action", f"{run.bound.name} failed: {reason}: {detail}",
                   action=run.bound.name, task=run.task.path_name if run.task else None,
                   reason=reason, detail=detail)
        self._run = None
        self._failure = reason
        self._failed_run = run
        if run.task is not None:
            self._states[run.task.path_name] = TaskState.FAILED
        if self._handling is not None:
            # An event handler's own action failed: the handler is over.
            self._handling = None
            self._handler_actions = []
        if not self._events_tick():
            status = Status.ABORTED if reason == "infeasible" else Status.FAILED
            self._end(status, f"{run.bound.name} failed ({reason}): {detail}")

    # --- dispatch="mission" --------------------------------------------------------------------

    def _fly_as_mission(self, task: Task) -> None:
        tasks: list[Task] = []
        self._collect(task, tasks)
        if not tasks:
            self._leave(task, TaskState.DONE)
            return
        plan = self._plan = _Plan(next(_plan_ids), task, tasks, [], since=self._now,
                                  limit=self.options.mission_stall)
        try:
            plan.actions = [self._with_labels(bind(t.action)) for t in tasks if t.action]
        except ActionFailed as failure:
            self._plan_failed(plan, failure.reason, failure.detail)
            return
        self._note("decision", f"{task.path_name}: {len(plan.actions)} actions flown as a "
                   "mission", task=task.path_name, actions=[a.name for a in plan.actions])
        self._send_plan(plan)

    def _send_plan(self, plan: _Plan) -> None:
        request = FlyMission(self.vehicle_id, plan.plan_id, tuple(plan.actions),
                             self._state.position or (0.0, 0.0, 0.0))
        plan.request_id = request.request_id
        self._send(request)

    def _with_labels(self, bound: BoundAction) -> BoundAction:
        """The action with the points of the labels it reads put in its values."""
        values = dict(bound.values)
        for name, label in bound.labels.items():
            if label not in self.labels:
                raise ActionFailed("infeasible", f"{bound.name}: label {label!r} has not "
                                   "been memorized")
            values[name] = self.labels[label]
        return replace(bound, values=values, labels={})

    def _collect(self, task: Task, into: list[Task]) -> None:
        """Terminal tasks of a mission subtree, repeats unrolled, conditions evaluated now."""
        memory = self._memory()
        for condition in task.conditions:
            if not self._evaluate(condition, memory)[0]:
                self._set(task, TaskState.SKIPPED)
                return
        for _ in range(task.repeat):
            if task.is_terminal:
                into.append(task)
            for child in task.children:
                self._collect(child, into)

    def _track_plan(self) -> None:
        plan = self._plan
        assert plan is not None
        progress = self._state.mission
        if progress is None or progress.plan_id != plan.plan_id:
            if self._now - plan.since > plan.limit:
                self._plan_failed(plan, "timeout", "the vehicle did not start the mission")
            return
        index = min(progress.action_index, len(plan.tasks) - 1)
        if index != plan.index:
            if 0 <= plan.index < len(plan.tasks):
                self._set(plan.tasks[plan.index], TaskState.DONE)
            # The autopilot runs DO items between two navigation items at once, and may
            # report the next navigation item before one of them was ever current: the
            # tasks it went past were flown all the same.
            for passed in plan.tasks[max(plan.index + 1, 0):index]:
                self._set(passed, TaskState.RUNNING)
                self._set(passed, TaskState.DONE)
            plan.index, plan.since = index, self._now
            plan.limit = self._item_limit(plan.actions[index])
            self._terminal = plan.tasks[index]
            self._task_started[self._terminal.path] = self._now
            self._set(self._terminal, TaskState.RUNNING)
        if progress.finished:
            if 0 <= plan.index < len(plan.tasks):
                self._set(plan.tasks[plan.index], TaskState.DONE)
            for task in plan.tasks[plan.index + 1:]:  # flown too, and said in the log
                self._set(task, TaskState.RUNNING)
                self._set(task, TaskState.DONE)
            for task in plan.tasks:
                self._states[task.path_name] = TaskState.DONE
            self._terminal = None
            self._plan = None
            self._leave(plan.root, TaskState.DONE)
            self._advance()
        elif self._now - plan.since > plan.limit:
            self._plan_failed(plan, "timeout", f"{plan.actions[plan.index].name} not done "
                              f"within {plan.limit:.0f} s")

    def _item_limit(self, bound: BoundAction) -> float:
        """How long one action of a mission plan may take: its nominal time, doubled, plus
        slack; an endless loiter has no limit (an event ends it)."""
        limits, values = self.limits, bound.values
        here = self._state.position or (0.0, 0.0, 0.0)
        turns, duration = values.get("turns"), values.get("duration")
        if bound.name in ("LOITER", "RETURN_HOME_AND_LOITER") and turns is None \
                and duration is None:
            return math.inf
        seconds = float(duration or 0.0)  # type: ignore[arg-type]
        if turns is not None:
            seconds += 2 * math.pi * float(values["radius"]) * float(turns) / limits.speed  # type: ignore[arg-type]
        target = values.get("coordinates")
        if isinstance(target, tuple):
            seconds += math.dist(here, target) / limits.speed
        if bound.name == "SURVEY_AREA":
            seconds += (float(values["length"]) * (float(values["width"])  # type: ignore[arg-type]
                        / float(values["spacing"]) + 1) + float(values["width"])) / limits.speed  # type: ignore[arg-type]
        if bound.name == "TAKE_OFF":
            seconds += float(values["altitude"]) / limits.climb_rate  # type: ignore[arg-type]
        if bound.spec.category is Category.TAKE_OFF_LANDING and bound.name != "TAKE_OFF":
            # Over the landing point (home when none is given), then down at LAND_SPEED.
            over = target if isinstance(target, tuple) else (0.0, 0.0, 0.0)
            if "latitude" in values or bound.name == "LAND":
                over = here
            seconds += math.hypot(here[0] - over[0], here[1] - over[1]) / limits.speed \
                + max(here[2], 15.0) / limits.land_rate
        if seconds == 0.0:
            return self.options.mission_stall
        return limits.factor * seconds + limits.slack

    def _plan_failed(self, plan: _Plan, reason: str, detail: str) -> None:
        self._plan = None
        self._terminal = None
        self._failure = reason
        self._states[plan.root.path_name] = TaskState.FAILED
        self._note("action", f"mission flight of {plan.root.path_name} failed: {detail}",
                   task=plan.root.path_name, reason=reason, detail=detail)
        if not self._events_tick():
            status = Status.ABORTED if reason == "infeasible" else Status.FAILED
            self._end(status, f"{plan.root.path_name}: {detail}")

    # --- events --------------------------------------------------------------------------------

    def _events_tick(self) -> bool:
        """Evaluate the handlers; fire the first that triggers. True if one fired."""
        if self.status is not Status.RUNNING or self._handling is not None:
            return False
        memory = self._memory()
        fired: Event | None = None
        for event in self.mission.events:
            readings = [self._evaluate(c, memory) for c in event.conditions]
            holds = all(h for h, _ in readings)
            was = self._holding.get(event.name, False)
            triggers = holds and (event.trigger is EventTrigger.LEVEL or not was)
            if triggers and fired is None:
                fired = event
                self._holding[event.name] = True
                self._note("event", f"event {event.name!r} fired", event=event.name,
                           line=event.location.line,
                           read=[{"subject": c.subject, "value": v}
                                 for c, (_, v) in zip(event.conditions, readings, strict=True)])
            elif not triggers or not holds:
                self._holding[event.name] = holds  # a rising edge left pending fires next
        if fired is None:
            return False
        self._events.append((self._now - self._start, fired.name))
        self._handle(fired)
        return True

    def _handle(self, event: Event) -> None:
        instant = all(bind(a).spec.category in _INSTANT for a in event.actions)
        if instant and event.termination.mode is TerminationMode.CONTINUE:
            for action in event.actions:  # memorizing does not disturb the running action
                bound = bind(action)
                self._note("action", f"{bound.name} (event {event.name!r})",
                           action=bound.name, line=action.location.line)
                try:
                    for _ in SCRIPTS[bound.name](self, bound):
                        pass  # memory actions finish without waiting
                except ActionFailed as failure:
                    self._failure = failure.reason
                    self._note("action", f"{bound.name} failed: {failure}",
                               action=bound.name, reason=failure.reason)
            return
        self._handling = event
        if self._run is not None or self._plan is not None:
            self._interrupted = self._run
            self._run = None
            if self._state.flying:
                self._send(Hold(self.vehicle_id))
        self._handler_actions = list(event.actions)
        self._next_handler_action()

    def _next_handler_action(self) -> None:
        while self._handler_actions and self.status is Status.RUNNING:
            action = self._handler_actions.pop(0)
            if self._new_run(action, None) is not None or self._handling is None:
                return
        if self._handling is not None and self.status is Status.RUNNING:
            event, self._handling = self._handling, None
            self._terminate(event)

    def _terminate(self, event: Event) -> None:
        mode = event.termination.mode
        interrupted, self._interrupted = self._interrupted, None
        plan, self._plan = self._plan, None
        self._note("decision", f"event {event.name!r}: {mode.value}", event=event.name,
                   termination=mode.value)
        if mode is TerminationMode.CONTINUE:
            if plan is not None:
                self._plan = plan
                self._note("decision", "the autopilot mission is resumed from its current item")
                first = max(plan.index, 0)
                plan.tasks, plan.actions = plan.tasks[first:], plan.actions[first:]
                plan.index, plan.since, plan.limit = -1, self._now, self.options.mission_stall
                self._send_plan(plan)
            elif interrupted is not None:
                self._resume(interrupted)
            else:
                self._advance()
        elif mode is TerminationMode.NEXT_TASK:
            if plan is not None:
                self._unwind_plan(plan, TaskState.ABORTED)
            elif self._terminal is not None:
                self._terminal_left = 0
                self._states[self._terminal.path_name] = TaskState.ABORTED
            self._advance()
        elif mode is TerminationMode.REPEAT_TASK:
            if plan is not None:
                self._unwind_plan(plan, TaskState.PENDING)
                self._stack[-1].index -= 1
            elif self._terminal is not None:
                self._terminal_left += 1
            self._advance()
        elif mode is TerminationMode.ABORT_TASK:
            if plan is not None:
                self._unwind_plan(plan, TaskState.ABORTED)
            else:
                self._unwind_to(self._scope(event))
            self._advance()
        elif mode is TerminationMode.JUMP_TO_TASK:
            if plan is not None:
                self._unwind_plan(plan, TaskState.ABORTED)
            target = self._find(event.termination.task or "")
            self._jump(target)
            self._advance()
        elif mode is TerminationMode.END_MISSION:
            self.mission_end = Status.COMPLETED
            self._end(Status.COMPLETED, f"event {event.name!r} ended the mission")
        else:
            self.mission_end = Status.ABORTED
            self._end(Status.ABORTED, f"event {event.name!r} aborted the mission")

    def _resume(self, run: _Run) -> None:
        """Continue a stopped action: send its last request again and restart its timer."""
        self._run = run
        run.since = self._now
        request = None
        if isinstance(run.step, Send):
            # Stopped while its request was on its way: the answer may have come while the
            # handler ran (and gone unclaimed), and the Hold overrode the request anyway.
            request = run.step.request
        elif isinstance(run.step, (Until, Sleep)) and run.last_request is not None:
            request, run.resume_at = run.last_request, run.step
        if request is not None:
            again = replace(request, request_id=_fresh_id())
            self._note("decision", f"{run.bound.name} resumed", action=run.bound.name)
            run.step = Send(again)
            run.request_id = again.request_id
            run.last_request = again
            self._send(again)
        self._drive()

    def _unwind_plan(self, plan: _Plan, state: TaskState) -> None:
        for task in plan.tasks:
            if self._states.get(task.path_name) is TaskState.RUNNING:
                self._states[task.path_name] = state
        self._terminal = None
        self._leave(plan.root, state)

    def _scope(self, event: Event) -> Task | None:
        for condition in event.conditions:
            if condition.kind is ConditionKind.CURRENT_TASK:
                return self._find(condition.subject)
        return self._terminal

    def _find(self, reference: str) -> Task:
        if "/" in reference:
            path = tuple(p.strip() for p in reference.split("/"))
            return next(t for t in self.mission.walk() if t.path == path)
        return next(t for t in self.mission.walk() if t.name == reference.strip())

    # --- the end -------------------------------------------------------------------------------

    def _end(self, status: Status, reason: str) -> None:
        self.status = status
        self.reason = reason
        self._run = None
        self._plan = None
        self._handling = None
        ended = TaskState.DONE if status is Status.COMPLETED else TaskState.ABORTED
        for path, state in self._states.items():
            if state is TaskState.RUNNING:  # the log says how each running task ended
                self._states[path] = ended
                self._note("task", f"{path}: {ended.value}", task=path, state=ended.value)
        for name, count in list(self._skills.items()):
            if count > 0:
                self._skills[name] = 1
                self._skill(name, False)
        self._note("mission", f"mission {status.value}: {reason}", status=status.value,
                   reason=reason)
        if self.options.end_safe:
            self._safe_state(reason)
        elif status is not Status.COMPLETED and self._state.flying:
            self._send(Hold(self.vehicle_id))

    def _safe_state(self, reason: str) -> None:
        safe = safe_state_request(self._state, self.options.safe_state)
        if safe is not None:
            request, why = safe
            self._note("safety", f"{why} ({reason})", request=request.name)
            self._send(request)


def safe_state_request(state: VehicleState, safe_state: str) -> tuple[Request, str] | None:
    """What puts a vehicle in the safe state, and why; None when it is disarmed on the
    ground. In the air: ``safe_state`` (rtl, land or hold); armed on the ground: disarm.
    A ground vehicle is safe stopped: an armed one is disarmed, wherever it is."""
    if state.armed and kind_of(state.vehicle_type) is Kind.GROUND:
        return Disarm(state.vehicle_id), "ground vehicle armed: disarm (it stops)"
    if state.flying:
        request: Request = {"land": Land, "hold": Hold}.get(
            safe_state, ReturnToLaunch)(state.vehicle_id)
        return request, f"vehicle in the air: {request.name}"
    if state.armed:
        return Disarm(state.vehicle_id), "vehicle armed on the ground: disarm"
    return None


def _fresh_id() -> int:
    return Hold(0).request_id


def request_fields(request: Request) -> dict[str, object]:
    data = {k: v for k, v in request.__dict__.items() if k not in ("vehicle_id", "request_id")}
    if isinstance(request, FlyMission):
        data["actions"] = [a.name for a in request.actions]
    return data
