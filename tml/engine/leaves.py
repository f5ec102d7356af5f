"""The leaves of the task tree: the work a vehicle does.

An :class:`ActionLeaf` flies one action with its script (:mod:`tml.engine.scripts`): it
sends the script's requests, waits for their results, watches the state for completion
within the script's time limits. A :class:`PlanLeaf` flies a ``dispatch="mission"`` task
whole: its terminal tasks' actions go to the vehicle in one
:class:`~tml.vehicle.FlyMission` request, and the vehicle's progress names the task being
flown. Each leaf's :class:`~tml.engine.context.WorkMode` moves only as
:data:`~tml.engine.context.WORK_MOVES` allows.

A leaf stopped from above tells its vehicle to hold (unless the mission is ending: the safe
state follows) and closes its script. An event handler *holds* a leaf instead (the vehicle
holds, the script is kept) and its termination gives a :class:`~tml.engine.context.Verdict`:
resume, go on, begin anew, or fail. A leaf whose action fails asks the event handlers
first (:attr:`~tml.engine.context.Run.react`); only when none fires does it fail, and the
failure goes up the tree.
"""

from __future__ import annotations

import math
from dataclasses import replace

from tml.actions.definition import NotApplicable
from tml.actions.registry import definition
from tml.engine.composites import Node, NodeStatus
from tml.engine.context import (
    WORK_MOVES,
    Duty,
    Pilot,
    Run,
    TaskOwner,
    Verdict,
    WorkMode,
    moved,
)
from tml.engine.failures import Failure
from tml.engine.records import TaskState
from tml.engine.scripts import ActionFailed, Script, Send, Sleep, Until, script_for
from tml.engine.wake import Waker
from tml.errors import EngineError
from tml.language.actions import BoundAction, bind
from tml.language.failures import FailureReason
from tml.language.model import Action, Task
from tml.vehicle import FlyMission, Hold, Request, RequestResult


class Leaf(Node):
    """What both leaves share: the vehicle, the task, the mode and the verdict to apply."""

    def __init__(self, run: Run, pilot: Pilot, task: Task | None,
                 owner: TaskOwner | None) -> None:
        super().__init__()
        self.run = run
        self.pilot = pilot
        self.task = task
        self._owner = owner
        self._mode = WorkMode.READY
        self.verdict: tuple[Verdict, Failure | None] | None = None
        self.pending: Failure | None = None  # the failure an event handler decides on
        self.outcome = NodeStatus.RUNNING  # SUCCESS or FAILURE once ended by itself
        self._held_at: float | None = None  # when an event handler took it over

    @property
    def owner(self) -> TaskOwner | None:
        """The node of the task it flies for (None: an event handler's action)."""
        return self._owner

    @property
    def mode(self) -> WorkMode:
        """Where the work is."""
        return self._mode

    def become(self, mode: WorkMode) -> None:
        """Change mode, as :data:`~tml.engine.context.WORK_MOVES` allows; entering HELD or
        AWAITING notes when (an event handler takes the work over), leaving them forgets."""
        self._mode = moved(WORK_MOVES, self._mode, mode, f"{self.action_name} work")
        if mode in (WorkMode.HELD, WorkMode.AWAITING):
            self._held_at = self.run.log.now
        elif mode is WorkMode.ACTIVE:
            self._held_at = None

    @property
    def held_at(self) -> float | None:
        """When an event handler took the work over, while it is held or awaits the
        handler's verdict (see :class:`~tml.engine.context.Work`)."""
        return self._held_at if self._mode in (WorkMode.HELD, WorkMode.AWAITING) else None

    @property
    def action_name(self) -> str:
        """The action flown now."""
        raise NotImplementedError

    @property
    def task_path(self) -> tuple[str, ...]:
        """The task flown now (() for an event handler's action)."""
        raise NotImplementedError

    @property
    def task_since(self) -> float:
        """When the task flown now began (TASK_ELAPSED_TIME)."""
        raise NotImplementedError

    def progress(self, clock: float) -> float | None:
        """How far the work is at ``clock`` (the mission's clock), 0 to 1, when it can
        tell."""
        raise NotImplementedError

    @property
    def plan(self) -> tuple[Task, ...]:
        """The tasks flown as one autopilot plan (empty for an action)."""
        return ()

    @property
    def vehicle_id(self) -> int:
        """The vehicle it flies on."""
        return self.pilot.vehicle_id

    def hold(self) -> bool:
        """Stop for an event handler; True when it was flying."""
        if self._mode is not WorkMode.ACTIVE:
            return False
        self.pilot.stir()
        self.become(WorkMode.HELD)
        return True

    def decide(self, verdict: Verdict, failure: Failure | None = None) -> None:
        """What follows, applied at the next step."""
        self.pilot.stir()
        self.verdict = (verdict, failure)

    def carry_on(self) -> None:
        """Go on after a pause of the run (the vehicle held): only active work has
        anything to send again."""
        self.pilot.stir()
        if self._mode is WorkMode.ACTIVE and self.verdict is None:
            self.resume(fresh=False)

    # --- the lifecycle ---------------------------------------------------------------------

    def start(self) -> None:
        self.pilot.work.append(self)

    def step(self) -> NodeStatus:
        if self._mode is WorkMode.READY and self.verdict is None:
            if self.pilot.duty is Duty.LOST:
                self.finish(NodeStatus.FAILURE, self.pilot.link_failure())
                return self.outcome
            if self._owner is not None and self.pilot.duty is Duty.HANDLING:
                return NodeStatus.RUNNING  # begins once its vehicle's event handler is over
            self.begin()
        self._apply_verdict()
        if self._mode is WorkMode.ACTIVE:
            self.drive()
        self._apply_verdict()  # a failure in this step may have been decided at once
        return self.outcome if self._mode is WorkMode.ENDED else NodeStatus.RUNNING

    def end(self, status: NodeStatus, why: str) -> None:
        if self._mode is not WorkMode.ENDED:  # stopped from above
            if self._mode is WorkMode.ACTIVE and not self.run.ending \
                    and self.pilot.state.possibly_flying:
                self.run.send(Hold(self.vehicle_id))
            if self._mode is not WorkMode.READY:
                # Held by an event handler whose termination stops it: it stopped flying
                # when the handler took over, and is stamped then.
                self.stopped(why, self.held_at)
            self.become(WorkMode.ENDED)
        if self in self.pilot.work:
            self.pilot.work.remove(self)

    def finish(self, outcome: NodeStatus, failure: Failure | None = None) -> None:
        """End the work by itself: done (SUCCESS) or failed."""
        self.close()
        self.outcome, self.failure = outcome, failure
        self.become(WorkMode.ENDED)

    def fail(self, failure: Failure) -> None:
        """The work failed: ACTION_FAILURE says why; an event handler may decide what follows,
        else the work fails."""
        self.pilot.failure = failure.reason
        self.close()
        if self._owner is None:  # an event handler's own action: the handler decides
            self.finish(NodeStatus.FAILURE, failure)
            return
        self.become(WorkMode.AWAITING)
        self.pending = failure
        if not self.run.react(self.pilot):
            self.finish(NodeStatus.FAILURE, failure)

    def _apply_verdict(self) -> None:
        if self.verdict is None:
            return
        (verdict, failure), self.verdict = self.verdict, None
        if verdict is Verdict.RESUME and self._mode is WorkMode.HELD:
            self.become(WorkMode.ACTIVE)
            self.resume(fresh=True)
        elif verdict is Verdict.GO_ON and self._mode is WorkMode.AWAITING:
            self.finish(NodeStatus.SUCCESS)
        elif verdict is Verdict.RESTART and self._mode in (WorkMode.HELD, WorkMode.AWAITING):
            self.close()
            self.become(WorkMode.ACTIVE)
            self.restart()
        elif verdict is Verdict.FAIL and self._mode is not WorkMode.ENDED:
            failure = failure or self.pending
            assert failure is not None
            if self._mode in (WorkMode.ACTIVE, WorkMode.HELD):
                self.stopped(failure.message, self.held_at)
            self.finish(NodeStatus.FAILURE, failure)

    # --- what each leaf does ---------------------------------------------------------------

    def begin(self) -> None:
        """Start the work (its mode becomes ACTIVE)."""
        raise NotImplementedError

    def drive(self) -> None:
        """One step of active work."""
        raise NotImplementedError

    def resume(self, fresh: bool) -> None:
        """Go on after the vehicle held: an event handler held the work (CONTINUE, with
        ``fresh`` time limits) or the run was paused (time limits go on where they
        stopped)."""
        raise NotImplementedError

    def restart(self) -> None:
        """Begin the work anew (REPEAT_TASK)."""
        self.begin()

    def close(self) -> None:
        """Let go of what the work holds (its script)."""

    def stopped(self, why: str, at: float | None = None) -> None:
        """Log that the work was stopped before its end (``at``: the runner's time it
        stopped flying, when that was earlier than now)."""
        raise NotImplementedError

    def on_result(self, result: RequestResult) -> bool:
        """Take the result of one of its requests; False when it is not its own."""
        raise NotImplementedError


class ActionLeaf(Leaf):
    """One action flown with commands; see the module docstring."""

    def __init__(self, run: Run, pilot: Pilot, action: Action, task: Task | None,
                 owner: TaskOwner | None, event: str = "") -> None:
        super().__init__(run, pilot, task, owner)
        self.action = action
        self.event = event  # the event handler it runs for
        self.bound = bind(action)
        self.script: Script | None = None
        self.wait: Send | Until | Sleep | None = None
        self.since = 0.0  # when the current wait began
        self.began = 0.0
        self.request_id = 0
        self.last_request: Request | None = None
        self.resume_at: Until | Sleep | None = None  # the wait to go back to once resent
        self.resume_since: float | None = None  # and when it began, after a pause
        self._progress: float | None = None

    @property
    def action_name(self) -> str:
        return self.bound.name

    @property
    def task_path(self) -> tuple[str, ...]:
        return self.task.path if self.task is not None else ()

    @property
    def task_since(self) -> float:
        return self._owner.since if self._owner is not None else self.began

    def progress(self, clock: float) -> float | None:
        wait = self.wait
        if isinstance(wait, Sleep) and self._mode is WorkMode.ACTIVE:
            # Time alone moves it: from the clock, not from the last step (a WAIT is
            # not stepped until it ends: tml.engine.wake).
            return max(0.0, min(1.0, (clock - self.since) / max(wait.seconds, 1e-9)))
        if isinstance(wait, Until) and wait.progress is not None \
                and self._mode is WorkMode.ACTIVE:
            # From the latest state, when asked (the display): an Until is stepped only
            # when a field its condition reads changes, not as the progress moves.
            self._progress = wait.progress(self.pilot.state)
        return self._progress

    def wake(self, waker: Waker) -> None:
        mode, wait = self._mode, self.wait
        waker.vehicle(self.vehicle_id)
        if self.verdict is not None or mode is WorkMode.READY:
            waker.anything()
        elif mode is WorkMode.ACTIVE:
            if isinstance(wait, Sleep):
                waker.by(self.since + wait.seconds)
            elif isinstance(wait, Until):
                waker.by(self.since + wait.limit)
                waker.state(self.vehicle_id, wait.reads)
            elif wait is None:
                waker.anything()
            # Send: only its answer moves a request on.
        # HELD, AWAITING: the event handler that took it over decides (its own nodes say
        # what they wait for); ENDED: nothing.

    def _data(self) -> dict[str, object]:
        return {"action": self.bound.name,
                "task": self.task.path_name if self.task is not None else None}

    def begin(self) -> None:
        self.become(WorkMode.ACTIVE)
        run, bound = self.run, self.bound
        self.pilot.failure = None
        self.began = self.since = run.now
        self.wait, self.resume_at, self.last_request, self._progress = None, None, None, None
        run.note("action", f"{bound.name} started", self.vehicle_id, **self._data(),
                 line=self.action.location.line, arguments=dict(bound.values),
                 labels=dict(bound.labels))
        restoring, task = run.restoring, self.task
        self.script = script_for(self.pilot, bound, restoring is not None and task is not None
                                 and restoring.reentering(task.path_name))
        if run.options.pre_check is not None:
            violations = run.options.pre_check(bound, self.pilot.state, self.pilot.labels,
                                               run.log.mission_time)
            if violations:
                self._failed(FailureReason.INFEASIBLE, "; ".join(violations))

    def drive(self) -> None:
        """Run the script until it waits, or ends."""
        run, state = self.run, self.pilot.state
        while self.mode is WorkMode.ACTIVE and self.script is not None:
            wait = self.wait
            if isinstance(wait, Send):
                return  # waiting for the request's result
            if isinstance(wait, Until):
                # Judged only on telemetry that arrived after the latest request.
                if not (state.current and wait.predicate(state)):
                    if run.now - self.since > wait.limit:
                        self._failed(FailureReason.TIMEOUT,
                                     f"did not {wait.what} within {wait.limit:.0f} s")
                    return
            elif isinstance(wait, Sleep) and run.now - self.since < wait.seconds:
                return
            try:
                self.wait = next(self.script)
            except StopIteration:
                run.note("action", f"{self.bound.name} done", self.vehicle_id, **self._data())
                self.finish(NodeStatus.SUCCESS)
                return
            except ActionFailed as failure:
                self._failed(failure.reason, failure.detail)
                return
            self.since = run.now
            if isinstance(self.wait, Send):
                self._send(self.wait.request)

    def _send(self, request: Request) -> None:
        sent = self.run.send(request)
        self.wait, self.request_id, self.last_request = Send(sent), sent.request_id, sent

    def on_result(self, result: RequestResult) -> bool:
        wait = self.wait
        if self.mode is not WorkMode.ACTIVE or not isinstance(wait, Send) \
                or result.request_id != self.request_id:
            return False
        self.pilot.stir()
        self.run.note("result", f"{wait.request.name} {'done' if result.ok else 'failed'}",
                      self.vehicle_id, request_id=result.request_id, ok=result.ok,
                      reason=result.reason, detail=result.detail)
        if result.ok:
            # Go on with the script at the next drive; a resumed action first goes back to
            # the wait it was stopped in (with a fresh time limit after CONTINUE, with the
            # time it had left after a pause).
            self.wait, self.resume_at = self.resume_at or Sleep(0.0), None
            self.since = self.run.now if self.resume_since is None else self.resume_since
            self.resume_since = None
        else:
            self._failed(result.reason or FailureReason.REJECTED, f"{wait.request.name} refused"
                         + (f": {result.detail}" if result.detail else ""))
        return True

    def _failed(self, reason: FailureReason, detail: str) -> None:
        name = self.bound.name
        self.run.note("action", f"{name} failed: {reason.value}: {detail}", self.vehicle_id,
                      **self._data(), reason=reason.value, detail=detail)
        self.fail(Failure(reason, f"{name} failed ({reason.value}): {detail}", self.vehicle_id))

    def resume(self, fresh: bool) -> None:
        """Continue a held action: send its last request again; after CONTINUE (``fresh``)
        its timer starts again, after a pause it goes on."""
        kept = self.since
        if fresh:
            self.since = self.run.now
        request = None
        if isinstance(self.wait, Send):
            # Held while its request was on its way: the answer may have come while the
            # handler ran (and gone unclaimed), and the Hold overrode the request anyway.
            request = self.wait.request
        elif isinstance(self.wait, (Until, Sleep)) and self.last_request is not None:
            request, self.resume_at = self.last_request, self.wait
            self.resume_since = None if fresh else kept
        if request is not None:
            self.run.note("decision", f"{self.bound.name} resumed", self.vehicle_id,
                          action=self.bound.name)
            self._send(request)

    def close(self) -> None:
        if self.script is not None:
            self.script.close()
            self.script = None

    def stopped(self, why: str, at: float | None = None) -> None:
        self.run.log.note_at(self.run.log.now if at is None else at, "action",
                             f"{self.bound.name} stopped: {why}", self.vehicle_id,
                             **self._data(), why=why)


class PlanLeaf(Leaf):
    """A ``dispatch="mission"`` task flown whole by the autopilot; see the module docstring."""

    def __init__(self, run: Run, pilot: Pilot, root: Task, owner: TaskOwner) -> None:
        super().__init__(run, pilot, root, owner)
        self.root = root
        self.tasks: list[Task] = []  # the terminal tasks flown, repeats unrolled
        self.actions: list[BoundAction] = []
        self.plan_id = 0
        self.request_id = 0
        self.index = -1  # the item being flown (-1: not started)
        self.flying: Task | None = None  # the task said to be running
        self.since = 0.0  # when the item began, or the plan was sent
        self.limit = math.inf  # s the current item may take before the plan has stalled
        self.before: set[str] = set()  # items an interrupted run said had ended

    @property
    def action_name(self) -> str:
        return self.actions[self.index].name if 0 <= self.index < len(self.actions) else ""

    @property
    def task_path(self) -> tuple[str, ...]:
        # The item's task, or the plan's before the vehicle has begun it.
        return self.flying.path if self.flying is not None else self.root.path

    @property
    def task_since(self) -> float:
        return self.since if self.flying is not None else self._started()

    def _started(self) -> float:
        return self._owner.since if self._owner is not None else self.since

    def progress(self, clock: float) -> float | None:
        # By the vehicle's items when it tells them (a survey is one action of many items).
        said = self.pilot.state.mission
        if said is not None and said.plan_id == self.plan_id and said.items > 0:
            return 1.0 if said.finished else max(said.item - 1, 0) / said.items
        return max(self.index, 0) / len(self.tasks) if self.tasks else None

    @property
    def plan(self) -> tuple[Task, ...]:
        return tuple(self.tasks)

    def begin(self) -> None:
        self.become(WorkMode.ACTIVE)
        self.tasks, self.flying, self.index = [], None, -1
        self._collect(self.root, top=True)
        if not self.tasks:
            self.finish(NodeStatus.SUCCESS)
            return
        self.since, self.limit = self.run.now, self.run.options.mission_stall
        try:
            self.actions = [self._with_labels(bind(t.action)) for t in self.tasks if t.action]
        except ActionFailed as failure:
            self._failed(failure.reason, failure.detail)
            return
        self.run.note("decision", f"{self.root.path_name}: {len(self.actions)} actions flown as "
                      "a mission", self.vehicle_id, task=self.root.path_name,
                      actions=[a.name for a in self.actions])
        if not self._follow():
            self._send_plan()

    def _follow(self) -> bool:
        """Resumed: follow the plan an interrupted run sent, if the vehicle flies it in
        AUTO (True), rather than sending it again."""
        restoring = self.run.restoring
        sent = None if restoring is None else restoring.take_plan(self.root.path_name)
        if sent is None or self.pilot.state.mode != "AUTO":
            return False
        self.plan_id, start, self.before = sent
        self.run.note("decision", f"{self.root.path_name}: the vehicle flies its plan in AUTO: "
                      "followed, not sent again", self.vehicle_id, task=self.root.path_name,
                      plan_id=self.plan_id)
        sent_now = self.run.send(FlyMission(self.vehicle_id, self.plan_id,
                                            tuple(self.actions), start, track=True))
        self.request_id = sent_now.request_id
        return True

    def _collect(self, task: Task, top: bool = False) -> None:
        """Terminal tasks of the plan, repeats unrolled, conditions evaluated now."""
        if not top:
            false = self.run.check(task.conditions, task, {task.role: self.vehicle_id})
            if false is not None:
                self.run.set_state(task, TaskState.SKIPPED, self.vehicle_id)
                return
        for _ in range(task.repeat):
            if task.is_terminal:
                self.tasks.append(task)
            for child in task.children:
                self._collect(child)

    def _with_labels(self, bound: BoundAction) -> BoundAction:
        """The action with the points of the labels it reads put in its values."""
        values = dict(bound.values)
        for name, label in bound.labels.items():
            if label not in self.pilot.labels:
                raise ActionFailed(FailureReason.INFEASIBLE,
                                   f"{bound.name}: label {label!r} has not been memorized")
            values[name] = self.pilot.labels[label]
        return replace(bound, values=values, labels={})

    def _send_plan(self) -> None:
        self.plan_id = self.run.ids.take()
        sent = self.run.send(FlyMission(self.vehicle_id, self.plan_id, tuple(self.actions),
                                        self.pilot.state.position or (0.0, 0.0, 0.0)))
        self.request_id = sent.request_id

    def drive(self) -> None:
        """Follow the vehicle's progress through the plan."""
        run, tasks = self.run, self.tasks
        progress = self.pilot.state.mission
        if progress is None or progress.plan_id != self.plan_id:
            if run.now - self.since > self.limit:
                self._failed(FailureReason.TIMEOUT, "the vehicle did not start the mission")
            return
        index = min(progress.action_index, len(tasks) - 1)
        if index != self.index:
            # The autopilot runs DO items between two navigation items at once, and may
            # report the next navigation item before one of them was ever current: the
            # tasks it went past were flown all the same.
            self._flown(index)
            self.index, self.since = index, run.now
            self.limit = item_limit(self.actions[index], self.pilot, run.options.mission_stall)
            self._say(tasks[index])
        if progress.finished:
            self._flown(len(tasks))
            self.finish(NodeStatus.SUCCESS)
        elif run.now - self.since > self.limit:
            self._failed(FailureReason.TIMEOUT, f"{self.actions[self.index].name} not done "
                         f"within {self.limit:.0f} s")

    def _flown(self, upto: int) -> None:
        """The tasks before item ``upto`` are done (each said running first)."""
        for task in self.tasks[max(self.index, 0):upto]:
            self._say(task)
            if task.path_name in self.before:  # said by the interrupted run
                self.before.discard(task.path_name)
            else:
                self.run.set_state(task, TaskState.DONE, self.vehicle_id)
            self.flying = None

    def _say(self, task: Task) -> None:
        if self.flying is not task:
            self.flying = task
            if task.path_name not in self.before:
                self.run.set_state(task, TaskState.RUNNING, self.vehicle_id)

    def on_result(self, result: RequestResult) -> bool:
        if result.request_id != self.request_id or self.mode is not WorkMode.ACTIVE:
            return False
        if not result.ok:
            self._failed(result.reason or FailureReason.REJECTED, "the vehicle refused the mission"
                         + (f": {result.detail}" if result.detail else ""))
        return True

    def _failed(self, reason: FailureReason, detail: str) -> None:
        path = self.root.path_name
        self.run.note("action", f"mission flight of {path} failed: {detail}", self.vehicle_id,
                      task=path, reason=reason.value, detail=detail)
        self._end_item(TaskState.FAILED)
        self.fail(Failure(reason, f"{path}: {detail}", self.vehicle_id))

    def _end_item(self, state: TaskState, at: float | None = None) -> None:
        if self.flying is not None:
            self.run.set_state(self.flying, state, self.vehicle_id, at=at)
            self.flying = None

    def resume(self, fresh: bool) -> None:
        """Fly on from the current item: the rest of the plan is sent again (a new upload,
        with the time limits of one, after CONTINUE or a pause alike)."""
        first = max(self.index, 0)
        self.tasks, self.actions = self.tasks[first:], self.actions[first:]
        self.index, self.since, self.limit = -1, self.run.now, self.run.options.mission_stall
        self.run.note("decision", "the autopilot mission is resumed from its current item",
                      self.vehicle_id, task=self.root.path_name)
        self._send_plan()

    def restart(self) -> None:
        self._end_item(TaskState.ABORTED)
        self.begin()

    def stopped(self, why: str, at: float | None = None) -> None:
        self._end_item(TaskState.ABORTED, at)
        self.run.log.note_at(self.run.log.now if at is None else at, "action",
                             f"mission flight of {self.root.path_name} stopped: {why}",
                             self.vehicle_id, task=self.root.path_name, why=why)


def item_limit(bound: BoundAction, pilot: Pilot, stall: float) -> float:
    """How long one action of a mission plan may take: its nominal time (the ``item_time``
    of its definition, :mod:`tml.actions.timing`), doubled, plus slack; an endless loiter
    has no limit (an event ends it). ``stall`` when the action gives no time of its own."""
    limits, here = pilot.limits, pilot.state.position or (0.0, 0.0, 0.0)
    item_time = definition(bound).item_time
    if isinstance(item_time, NotApplicable):  # compile_mission refused it before
        raise EngineError(f"{bound.name} has no mission item: {item_time.reason}")
    seconds = item_time(limits, pilot.state.vehicle_type, here, bound)
    if math.isinf(seconds):
        return math.inf
    if seconds == 0.0:
        return stall
    return limits.factor * seconds + limits.slack
