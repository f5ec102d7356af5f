"""The nodes of the task tree and how sub-tasks are composed: the lifecycle every node has,
and ``sequence``, ``parallel``, ``first``, ``choice`` and ``repeat``/``loop``.

Theory of operation
-------------------
A node has an explicit :class:`NodeStatus` and three hooks, as in py_trees: :meth:`Node.start`
when it is first ticked, :meth:`Node.step` on every tick while it runs (returning RUNNING,
SUCCESS or FAILURE), and :meth:`Node.end`, called exactly once however it ends: done,
failed, or *stopped* from above (status INVALID) when a higher node pre-empts it -- an
``until`` or ``time_limit``, a ``first`` sibling that finished, a sibling's failure, an
event's termination, the end of the mission. A composite stops its running children in
its own ``end``, so a stop goes down the tree depth first and every running node below is
told: nothing is left running unseen, and a child's end is recorded before its parent's.

A node finishes as soon as it can: a sequence starts its next child in the tick in which
the previous one ended, so one tick may run many instant children. A node that fails
carries a :class:`~tml.engine.failures.Failure`; composites hand it up unchanged, and the
task nodes (:mod:`tml.engine.tasks`) decide where it is handled.

Children are built when they start, by a ``build`` function the task node gives (each
round of a repeat, each vehicle of a team gets fresh nodes). A sequence can be told to
*jump* (JUMP_TO_TASK): it stops its running child, unless the target lies inside it, and
goes on from the child on the way to the target.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from enum import Enum

from tml.engine.context import Pilot, Roles, Run
from tml.engine.failures import Failure
from tml.engine.records import TaskState
from tml.engine.wake import Waker, fields_read
from tml.language.model import Task
from tml.vehicle import VehicleState, same_state


class NodeStatus(Enum):
    """Where a node is."""

    INVALID = "invalid"  # not started yet, or stopped
    RUNNING = "running"
    SUCCESS = "success"
    FAILURE = "failure"


class Node:
    """A node of the task tree; see the module docstring."""

    def __init__(self) -> None:
        self.status = NodeStatus.INVALID
        self.failure: Failure | None = None  # why it failed, when it did

    def tick(self) -> NodeStatus:
        """Start the node if it is not running, step it, and end it when it is over."""
        if self.status is not NodeStatus.RUNNING:
            self.status = NodeStatus.RUNNING
            self.failure = None
            self.start()
        status = self.step()
        if status is not NodeStatus.RUNNING:
            self.status = status
            self.end(status, "")
        return status

    def stop(self, why: str) -> None:
        """Pre-empt a running node (and so everything running below it)."""
        if self.status is NodeStatus.RUNNING:
            self.status = NodeStatus.INVALID
            self.end(NodeStatus.INVALID, why)

    def start(self) -> None:
        """Called when the node starts."""

    def step(self) -> NodeStatus:
        """One tick of work; RUNNING until the node is done (SUCCESS) or has failed."""
        raise NotImplementedError

    def end(self, status: NodeStatus, why: str) -> None:
        """Called once when the node ends: done, failed, or stopped (INVALID) for ``why``."""

    def jump(self, path: tuple[str, ...]) -> bool:
        """Go on from the task at ``path`` (JUMP_TO_TASK); False when it is not below."""
        return False

    def wake(self, waker: Waker) -> None:
        """Tell ``waker`` what this running node waits for (:mod:`tml.engine.wake`); by
        default anything: it is stepped at every tick and on every change."""
        waker.anything()


# Builds the node of a sub-task; ``entry`` is the path of a jump's target below it, if any.
Build = Callable[[Task, tuple[str, ...] | None], Node]


class SequenceNode(Node):
    """Parts one after the other, each built when it starts; fails as soon as one fails."""

    def __init__(self, run: Run, count: int, part: Callable[[int], Node]) -> None:
        super().__init__()
        self.run = run
        self.count = count
        self.part = part  # builds part i
        self.index = 0
        self.current: Node | None = None

    def start(self) -> None:
        self.index, self.current = 0, None

    def step(self) -> NodeStatus:
        while not self.run.halted:
            if self.current is None:
                if self.index >= self.count:
                    return NodeStatus.SUCCESS
                self.current = self.part(self.index)
            status = self.current.tick()
            if status is NodeStatus.RUNNING:
                return status
            if status is NodeStatus.FAILURE:
                self.failure = self.current.failure
                return status
            self.current = None
            self.index += 1
        return NodeStatus.RUNNING

    def end(self, status: NodeStatus, why: str) -> None:
        if self.current is not None:
            self.current.stop(why)

    def wake(self, waker: Waker) -> None:
        if self.current is None or self.run.halted:
            waker.anything()
        else:
            self.current.wake(waker)


class TasksNode(SequenceNode):
    """Sub-tasks one after the other, in document order (``composition="sequence"``)."""

    def __init__(self, run: Run, tasks: Sequence[Task], build: Build,
                 entry: tuple[str, ...] | None = None) -> None:
        super().__init__(run, len(tasks), lambda i: build(tasks[i], None))
        self.tasks = tasks
        self.build = build
        self.entry = entry  # a jump's target below: start from the sub-task on its way

    def start(self) -> None:
        super().start()
        entry, self.entry = self.entry, None
        if entry is not None:
            self._go_to(entry)

    def jump(self, path: tuple[str, ...]) -> bool:
        current = self.current
        if current is not None and current.jump(path):
            return True
        if not any(_leads_to(t, path) for t in self.tasks):
            return False
        if current is not None:
            current.stop(f"JUMP_TO_TASK {'/'.join(path)}")
        self._go_to(path)
        return True

    def _go_to(self, path: tuple[str, ...]) -> None:
        self.index = next(i for i, t in enumerate(self.tasks) if _leads_to(t, path))
        self.current = self.build(self.tasks[self.index], path)


def _leads_to(task: Task, path: tuple[str, ...]) -> bool:
    return path[:len(task.path)] == task.path


class ParallelNode(Node):
    """Sub-tasks side by side: done when all are done, or with ``first`` when the first is
    (the others are stopped); a failure stops the others and fails the node.

    *Asleep.* After its tick, each branch says what it waits for (:mod:`tml.engine.wake`);
    until then it is not ticked: not before the time it named, nor while the states it
    reads show the same in the fields it reads and nothing was done to its vehicles' work
    from outside (:meth:`~tml.engine.context.Pilot.stir`). So of a team of hundreds of
    vehicles flying a WAIT or waiting for their requests, a step ticks only those whose
    turn it is."""

    def __init__(self, run: Run, children: Callable[[], list[Node]], first: bool = False) -> None:
        super().__init__()
        self.run = run
        self.children = children
        self.first = first
        self.running: list[Node] = []
        self._asleep: dict[Node, Asleep] = {}

    def start(self) -> None:
        self.running = self.children()
        self._asleep = {}

    def step(self) -> NodeStatus:
        for child in list(self.running):
            asleep = self._asleep.get(child)
            if asleep is not None and asleep.sleeps(self.run):
                continue
            status = child.tick()
            if status is NodeStatus.SUCCESS:
                self.running.remove(child)
                if self.first:
                    self._stop_all("another branch finished first")
                    return status
            elif status is NodeStatus.FAILURE:
                self.running.remove(child)
                self.failure = child.failure
                self._stop_all("a sibling branch failed")
                return status
            else:
                self._rest(child)
            if self.run.halted:
                return NodeStatus.RUNNING
        return NodeStatus.RUNNING if self.running else NodeStatus.SUCCESS

    def _rest(self, child: Node) -> None:
        """Note what a branch still running waits for (nothing it can sleep on: none)."""
        waker = Waker()
        child.wake(waker)
        asleep = Asleep.after(self.run, waker)
        if asleep is None:
            self._asleep.pop(child, None)
        else:
            self._asleep[child] = asleep

    def end(self, status: NodeStatus, why: str) -> None:
        self._stop_all(why)

    def wake(self, waker: Waker) -> None:
        if not self.running:
            waker.anything()
        for child in self.running:
            asleep = self._asleep.get(child)
            if asleep is not None and asleep.still():
                asleep.told.tell(waker)  # what it said at its last tick still holds
            else:
                child.wake(waker)
            if waker.reads is None:
                return  # anything: nothing more to learn

    def _stop_all(self, why: str) -> None:
        running, self.running = self.running, []
        self._asleep = {}
        for child in running:
            child.stop(why)


class Asleep:
    """A node that is not ticked until the time it ``told`` (the mission's clock), unless
    one of its vehicles is stirred or shows another value in a field it reads (a branch of
    a :class:`ParallelNode`, an event's handler: :class:`tml.engine.events.Events`);
    ``seen``: (pilot, its stirs, its state, the fields read) at its last tick."""

    __slots__ = ("seen", "told")

    def __init__(self, told: Waker,
                 seen: list[tuple[Pilot, int, VehicleState, Iterable[str]]]) -> None:
        self.told = told
        self.seen = seen

    @classmethod
    def after(cls, run: Run, waker: Waker) -> Asleep | None:
        """What a node that has just told ``waker`` what it waits for sleeps on; None when
        it cannot sleep: it waits for anything, or for nothing any vehicle does."""
        reads = waker.reads
        if reads is None or not (reads or waker.vehicles):
            return None
        pilots = run.pilots
        return cls(waker, [
            (pilots[vid], pilots[vid].stirs, pilots[vid].state, fields_read(reads, vid))
            for vid in waker.vehicles | reads.keys()])

    def sleeps(self, run: Run) -> bool:
        """Whether the branch may stay unticked in this step."""
        return run.now < self.told.at and not run.halted and self.still()

    def still(self) -> bool:
        """Whether what it told still holds: nothing stirred its vehicles, and they show
        the same in the fields it reads."""
        for pilot, stirs, state, names in self.seen:  # a loop: asked of every branch
            if pilot.stirs != stirs or not same_state(state, pilot.state, names):
                return False
        return True


class ChoiceNode(Node):
    """Dolphin's ``oneOf``: the first sub-task whose own conditions hold runs, the others are
    skipped; while none holds, it waits."""

    def __init__(self, run: Run, task: Task, roles: Roles, build: Build,
                 vehicle_id: int | None) -> None:
        super().__init__()
        self.run = run
        self.task = task
        self.roles = roles
        self.build = build
        self.vehicle_id = vehicle_id
        self.chosen: Node | None = None

    def step(self) -> NodeStatus:
        if self.chosen is None:
            child = next((c for c in self.task.children
                          if self.run.holds(c.conditions, c, self.roles)), None)
            if child is None:
                return NodeStatus.RUNNING
            for other in self.task.children:
                if other is not child:
                    self.run.set_state(other, TaskState.SKIPPED, self.vehicle_id)
            self.run.note("decision", f"{self.task.path_name}: {child.name} chosen",
                          self.vehicle_id, task=self.task.path_name, chosen=child.path_name)
            self.chosen = self.build(child, None)
        status = self.chosen.tick()
        self.failure = self.chosen.failure
        return status

    def end(self, status: NodeStatus, why: str) -> None:
        if self.chosen is not None:
            self.chosen.stop(why)

    def wake(self, waker: Waker) -> None:
        if self.chosen is None:  # waiting for a sub-task's conditions to hold
            waker.anything()
        else:
            self.chosen.wake(waker)


class RepeatNode(Node):
    """A task's body ``repeat`` times, or round after round as long as its ``loop``'s
    conditions hold (read before each round). The next repeat starts at once; the next
    loop round at the next step, so that a loop over instant work still lets time pass."""

    def __init__(self, run: Run, task: Task, roles: Roles, body: Callable[[bool], Node],
                 vehicle_id: int | None, since: float) -> None:
        super().__init__()
        self.run = run
        self.task = task
        self.roles = roles
        self.body = body  # builds a round's body; True: the first round (a jump enters it)
        self.vehicle_id = vehicle_id
        self.since = since  # when the task began to run
        self.round = 0
        self.current: Node | None = None
        self.resumed = False  # the round going on is an interrupted run's: said already

    def start(self) -> None:
        self.round, self.current = 0, None
        if self.run.restoring is not None:
            self.round = max(0, self.run.restoring.take_round(self.task.path_name) - 1)
            self.resumed = self.round > 0

    def step(self) -> NodeStatus:
        task, note = self.task, self.run.note
        while not self.run.halted:
            if self.current is None:
                if task.loop is not None and not self.run.holds(task.loop.conditions, task,
                                                                self.roles, self.since):
                    note("decision", f"{task.path_name}: loop ends after {self.round} rounds",
                         self.vehicle_id, task=task.path_name, rounds=self.round)
                    return NodeStatus.SUCCESS
                if task.loop is None and self.round >= task.repeat:
                    return NodeStatus.SUCCESS
                self.round += 1
                # A resumed round was said by the interrupted run.
                fresh, self.resumed = not self.resumed, False
                if fresh and self.round > 1 and task.loop is not None:
                    note("decision", f"{task.path_name}: round {self.round}", self.vehicle_id,
                         task=task.path_name, round=self.round)
                elif fresh and self.round > 1:
                    note("decision", f"{task.path_name}: repeat {self.round} of {task.repeat}",
                         self.vehicle_id, task=task.path_name, iteration=self.round)
                self.current = self.body(self.round == 1)
            status = self.current.tick()
            if status is not NodeStatus.SUCCESS:
                self.failure = self.current.failure
                return status
            self.current = None
            if task.loop is not None:
                return NodeStatus.RUNNING
        return NodeStatus.RUNNING

    def end(self, status: NodeStatus, why: str) -> None:
        if self.current is not None:
            self.current.stop(why)

    def jump(self, path: tuple[str, ...]) -> bool:
        return self.current is not None and self.current.jump(path)

    def wake(self, waker: Waker) -> None:
        if self.current is None:  # a loop's next round: its conditions are read then
            waker.anything()
        else:
            self.current.wake(waker)
