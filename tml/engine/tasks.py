"""The node of one task: everything a task does around its action or sub-tasks.

A :class:`TaskNode` moves through its :class:`Phase`\\ s: it picks its role's vehicles (a
role of several vehicles makes it a *team*: one node per vehicle, side by side), waits
for ``<wait_for>``, evaluates its ``<condition>``\\ s (skipped when one is false), then runs
its *body* -- the action, the sub-tasks composed as its ``composition`` says, or the
autopilot plan of a ``dispatch="mission"`` task -- ``repeat`` times or as its ``<loop>``
allows, bounded by ``<until>`` and ``time_limit``. While the body runs the task's skills
are on. A failure in the body runs the task's ``<on_error>`` tasks in its place, or goes on
up. However the task ends, the roles of its ``release`` are freed.

The task's state goes to the log once per change, after its sub-tasks': RUNNING when the
body starts, then DONE (also when stopped by ``until`` or ``time_limit``), SKIPPED,
FAILED, or ABORTED when it is stopped from above or abandoned by an event's termination
(NEXT_TASK, ABORT_TASK: the mission goes on after it). A task cut by the termination of
an event handler that held its vehicle's work is stamped when the handler took over --
the moment it stopped flying -- not when the handler's actions ended.
"""

from __future__ import annotations

from enum import Enum

from tml.engine.composites import (
    ChoiceNode,
    Node,
    NodeStatus,
    ParallelNode,
    RepeatNode,
    TasksNode,
)
from tml.engine.context import Pilot, Roles, Run
from tml.engine.failures import Failure
from tml.engine.leaves import ActionLeaf, PlanLeaf
from tml.engine.records import TaskState
from tml.engine.wake import Waker
from tml.language.model import Composition, Dispatch, Task
from tml.vehicle import Hold


class Phase(Enum):
    """Where a task node is."""

    PICK = "pick"  # binding its role's vehicles
    TEAM = "team"  # flown by each vehicle of its role, side by side
    WAIT = "wait"  # waiting for <wait_for>, then reading its conditions
    BODY = "body"  # running: its action, sub-tasks or plan
    RECOVER = "recover"  # failed: its <on_error> tasks run in its place


class TaskNode(Node):
    """One task of the tree; see the module docstring.

    ``roles`` are the vehicles standing for the roles in this branch; ``entry`` the path of
    a jump's target inside the task (it is then entered as the walk passes through: no
    wait, no conditions); ``member``: one vehicle's part of a team (the team releases).
    """

    def __init__(self, run: Run, task: Task, roles: Roles, owner: TaskNode | None,
                 entry: tuple[str, ...] | None = None, member: bool = False) -> None:
        super().__init__()
        self.run = run
        self._task = task
        self._owner = owner
        self.base = dict(roles)
        self.roles: dict[str | None, int] = dict(roles)
        self.entry = entry if entry != task.path else None
        self.member = member
        self.phase = Phase.PICK
        self.inner: Node | None = None  # the team, the body or the on_error tasks
        self.vehicle_id: int | None = None
        self.running = False  # said RUNNING, not yet said how it ended
        self.abandoned: str | None = None  # why an event's termination abandons it
        self._since = 0.0

    @property
    def task(self) -> Task:
        """The task."""
        return self._task

    @property
    def owner(self) -> TaskNode | None:
        """The node of the task around it."""
        return self._owner

    @property
    def since(self) -> float:
        """When the task began: its body started (before: when the node started)."""
        return self._since

    def abandon(self, why: str) -> None:
        """End the task unfinished (ABORTED) at its next step; the mission goes on after it."""
        self.abandoned = why
        for pilot in ([self.run.pilots[self.vehicle_id]] if self.vehicle_id is not None
                      else self.run.pilots.values()):
            pilot.stir()

    def build(self, task: Task, entry: tuple[str, ...] | None) -> Node:
        """The node of a sub-task (or an on_error task)."""
        return TaskNode(self.run, task, self.roles, self, entry)

    # --- the lifecycle ---------------------------------------------------------------------

    def start(self) -> None:
        self.phase, self.inner, self.roles = Phase.PICK, None, dict(self.base)
        self.running, self.abandoned, self._since = False, None, self.run.now

    def step(self) -> NodeStatus:
        restoring = self.run.restoring
        if self.phase is Phase.PICK and restoring is not None \
                and self.task.path_name not in restoring.recovering \
                and restoring.take_ended(self.task.path_name) is not None:
            return NodeStatus.SUCCESS  # it had ended before the run was interrupted
        if self.abandoned is None:
            status = self._advance()
            if status is not NodeStatus.RUNNING or self.abandoned is None:
                return status
        why, self.abandoned = self.abandoned, None
        at = self._interrupted_at()
        if self.inner is not None:
            self.inner.stop(why)
        self._ended(TaskState.ABORTED, at)
        return NodeStatus.SUCCESS

    def end(self, status: NodeStatus, why: str) -> None:
        if status is NodeStatus.INVALID:  # stopped from above
            at = self._interrupted_at()
            if self.inner is not None:
                self.inner.stop(why)
            self._ended(TaskState.ABORTED, at)
        if not self.member:
            for name in self.task.release:
                self.run.release(name, f"released by {self.task.path_name}")

    def jump(self, path: tuple[str, ...]) -> bool:
        return self.phase is Phase.BODY and self.inner is not None and self.inner.jump(path)

    def wake(self, waker: Waker) -> None:
        inner, task = self.inner, self.task
        if self.abandoned is not None or inner is None or self.phase in (Phase.PICK,
                                                                        Phase.WAIT):
            waker.anything()
        elif self.phase is not Phase.BODY:  # TEAM, RECOVER
            inner.wake(waker)
        elif task.until:  # conditions read at every step
            waker.anything()
        else:
            if task.time_limit is not None:
                waker.by(self.since + task.time_limit)
            inner.wake(waker)

    # --- the phases ------------------------------------------------------------------------

    def _advance(self) -> NodeStatus:
        while True:
            if self.phase is Phase.PICK:
                status = self._pick()
            elif self.phase is Phase.WAIT:
                status = self._wait()
            elif self.phase is Phase.BODY:
                status = self._body()
            else:  # TEAM, RECOVER: the inner node's outcome is the task's
                assert self.inner is not None
                status = self.inner.tick()
                self.failure = self.inner.failure
            if status is not None:
                return status

    def _pick(self) -> NodeStatus | None:
        run, task = self.run, self.task
        role = task.role
        needs_vehicle = role is not None or task.is_terminal or None in run.bound
        if needs_vehicle and self.roles.get(role) not in run.bound.get(role, ()):
            # A role released since this branch bound it (a loop round that ends with
            # release) is picked again, as on first use.
            vehicles = run.bound.get(role) or run.pick(task, role, self.since)
            if vehicles is None:
                return NodeStatus.RUNNING
            if isinstance(vehicles, Failure):
                run.set_state(task, TaskState.FAILED, None)
                return self._failed(vehicles)
            if len(vehicles) > 1:  # a team: every vehicle flies the task
                self.inner = ParallelNode(run, lambda: [
                    TaskNode(run, task, {**self.roles, role: v}, self._owner, self.entry, True)
                    for v in vehicles])
                self.phase = Phase.TEAM
                return None
            self.roles[role] = vehicles[0]
        self.vehicle_id = self.roles.get(role)
        self.phase = Phase.WAIT
        if task.wait_for and self.entry is None:
            run.note("decision", f"{task.path_name}: waiting for its conditions",
                     self.vehicle_id, task=task.path_name)
        return None

    def _wait(self) -> NodeStatus | None:
        run, task = self.run, self.task
        if run.restoring is not None and run.restoring.take_recovering(task.path_name):
            # It had failed, and its on_error tasks were running: they go on.
            self.inner = TasksNode(run, task.on_error, self.build)
            self.phase = Phase.RECOVER
            return None
        begun = None if run.restoring is None else run.restoring.take_running(task.path_name)
        if begun is not None:  # running when the run was interrupted: it goes on
            self._begin_body(begun, resumed=True)
            return None
        if self.entry is None:
            if task.wait_for:
                read = run.readings(task.wait_for, task, self.roles)
                if not all(holds for _, holds, _ in read):
                    return NodeStatus.RUNNING
                # What was read is logged: the reason the task starts now (a role's
                # altitude, a label), which the telemetry samples show only between them.
                run.note("decision", f"{task.path_name}: its conditions are met",
                         self.vehicle_id, task=task.path_name,
                         read=[{"subject": c.subject, "value": value} for c, _, value in read])
            false = run.check(task.conditions, task, self.roles)
            if false is not None:
                condition, value = false
                run.note("decision", f"{task.path_name}: skipped, condition false",
                         self.vehicle_id, task=task.path_name, subject=condition.subject,
                         comparison=condition.comparison.value if condition.comparison
                         else None, expected=condition.value, read=value,
                         line=condition.location.line)
                run.set_state(task, TaskState.SKIPPED, self.vehicle_id)
                return NodeStatus.SUCCESS
        self._begin_body(run.now)
        return None

    def _begin_body(self, since: float, resumed: bool = False) -> None:
        """The body starts (``since``: when it began, earlier for a resumed task)."""
        run, task = self.run, self.task
        self._since = since
        run.set_state(task, TaskState.RUNNING, self.vehicle_id, resumed)
        self.running = True
        pilot = self._pilot()
        if pilot is not None:
            for skill in task.skills:
                run.skill(pilot, skill.name, True)
        self.inner = self._make_body()
        self.phase = Phase.BODY

    def _body(self) -> NodeStatus | None:
        run, task, body = self.run, self.task, self.inner
        assert body is not None
        why = ""
        read: dict[str, object] = {}
        until = run.readings(task.until, task, self.roles, self.since) if task.until else []
        if until and all(holds for _, holds, _ in until):
            why = "its until conditions hold"
            read = {"read": [{"subject": c.subject, "value": value} for c, _, value in until]}
        elif task.time_limit is not None and run.now - self.since >= task.time_limit:
            why = f"its time limit of {task.time_limit:g} s is reached"
        if why:
            run.note("decision", f"{task.path_name}: stopped, {why}", self.vehicle_id,
                     task=task.path_name, **read)
            body.stop(f"{task.path_name}: {why}")
            self._ended(TaskState.DONE)
            return NodeStatus.SUCCESS
        status = body.tick()
        if status is NodeStatus.SUCCESS:
            self._ended(TaskState.DONE)
        elif status is NodeStatus.FAILURE:
            assert body.failure is not None
            self._ended(TaskState.FAILED)
            return self._failed(body.failure)
        return status

    def _failed(self, failure: Failure) -> NodeStatus | None:
        """The task failed: its on_error tasks run in its place, else the failure goes up."""
        run, task = self.run, self.task
        if not task.on_error:
            self.failure = failure
            return NodeStatus.FAILURE
        run.note("decision", f"{task.path_name}: failed ({failure.message}); its on_error "
                 "tasks run", self.vehicle_id, task=task.path_name,
                 reason=failure.reason.value, detail=failure.message, recover=True)
        vid = failure.vehicle_id
        if vid is not None and run.pilots[vid].state.possibly_flying:
            run.send(Hold(vid))  # it stops where it is while the handler takes over
        self.inner = TasksNode(run, task.on_error, self.build)
        self.phase = Phase.RECOVER
        return None

    def _interrupted_at(self) -> float | None:
        """When an event handler took over its vehicle's work in the task, if it holds
        any: a task the handler's termination cuts stopped flying then."""
        pilot = self._pilot()
        return None if pilot is None else pilot.interrupted_at(self.task.path)

    def _ended(self, state: TaskState, at: float | None = None) -> None:
        """Say how the task ended (stamped ``at`` that runner's time, when earlier than
        now), and switch its skills off."""
        if not self.running:
            return
        self.running = False
        self.run.set_state(self.task, state, self.vehicle_id, at=at)
        pilot = self._pilot()
        if pilot is not None:
            for skill in self.task.skills:
                self.run.skill(pilot, skill.name, False)

    def _pilot(self) -> Pilot | None:
        return None if self.vehicle_id is None else self.run.pilots[self.vehicle_id]

    # --- the body --------------------------------------------------------------------------

    def _make_body(self) -> Node:
        run, task = self.run, self.task
        pilot = None if self.vehicle_id is None else run.pilots[self.vehicle_id]
        if task.dispatch is Dispatch.MISSION and pilot is not None:
            return PlanLeaf(run, pilot, task, self)
        entry = self.entry

        def round_body(first: bool) -> Node:
            if task.action is not None:
                assert pilot is not None, f"{task.path_name}: an action needs a vehicle"
                return ActionLeaf(run, pilot, task.action, task, self)
            if task.composition is Composition.CHOICE:
                return ChoiceNode(run, task, self.roles, self.build, self.vehicle_id)
            if task.composition is Composition.SEQUENCE:
                return TasksNode(run, task.children, self.build, entry if first else None)
            return ParallelNode(run, lambda: [self.build(c, None) for c in task.children],
                                first=task.composition is Composition.FIRST)

        if task.repeat == 1 and task.loop is None:
            return round_body(True)
        return RepeatNode(run, task, self.roles, round_body, self.vehicle_id, self.since)
