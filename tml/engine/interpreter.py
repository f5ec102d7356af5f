"""The TML interpreter: one mission flown by one vehicle or a fleet, as a tree of nodes.

Theory of operation
-------------------
The interpreter is pure: each call takes the time and the vehicles' latest states (and the
results of their requests) and returns the requests to send, each addressed to its
vehicle, and the records to log. It never sleeps, reads a clock or touches a link, so
every rule is tested with fake vehicles and an injected clock. Request and plan ids come
from the :class:`~tml.vehicle.IdSource` it is given.

*One tree.* The mission is a tree of nodes with one lifecycle (start, step, stop, an
explicit status; :mod:`tml.engine.composites`): a :class:`~tml.engine.tasks.TaskNode` per
task (role pick, ``wait_for``, conditions, skills, repeat or loop, ``until`` and
``time_limit``, ``on_error``, release, its state in the log), composites for its
sub-tasks (sequence, parallel, first, choice), and leaves for the work a vehicle does
(:mod:`tml.engine.leaves`: an action flown with commands, or a ``dispatch="mission"`` task
flown whole by the autopilot). A mission without roles is a fleet of one: every task is
flown by the one vehicle (given several vehicles, each task is flown by all of them side by
side, as a role of that many). The paper's depth-first walk is the sequence node: a task's
conditions are read when the walk reaches it, a skipped task lets the walk go on at once.

*Steps.* Each :meth:`Interpreter.step` first hands every vehicle's request results to its
work, then handles events vehicle by vehicle (:mod:`tml.engine.events`), then ticks the
tree from the root once: every running node does one step, and a node that ends lets the
next start in the same step. Nodes never run the same work twice in a step, and stop
nothing they do not own: a node is stopped only by its parent, through its ``stop``,
which goes down the tree (a stopped action tells its vehicle to hold and closes its
script).

*State.* What each vehicle has and does is its :class:`~tml.engine.context.Pilot`: its
memorized points and limits, counted skill uses, its running work, and its
:class:`~tml.engine.context.Duty` (watching for events, handling one, or lost); each
leaf's :class:`~tml.engine.context.WorkMode` says where its work is. Both change only as
their transition tables allow. The mission's :class:`~tml.engine.records.Status` is one
field: RUNNING until the tree is done (COMPLETED), a failure reaches the root (FAILED, or
ABORTED for an infeasible action), an event ends the mission, or the runner aborts it.

*Failures.* An action's failure (ACTION_FAILURE: rejected, timeout, unsupported,
infeasible, general; :class:`~tml.engine.failures.FailureReason`) is first offered to the
event handlers; unhandled, it climbs the tree as a
:class:`~tml.engine.failures.Failure` to the nearest task with ``on_error``, stopping the
siblings of ``parallel`` and ``first`` tasks on its way. A pick that times out and a lost
vehicle fail their task the same way.

*The log and the display.* Every state change of a task is recorded once, when it
happens, with the vehicle that flies the task: RUNNING when its body starts, then how it
ended, after its sub-tasks' ends. Each vehicle's :class:`~tml.engine.records.View` carries
these changes in order for the line display, besides the states for the live one.

*The operator's controls.* :meth:`Interpreter.pause` tells every flying vehicle of the
mission to hold and stops everything: no node or event handler is stepped, and the
mission's clock (:attr:`~tml.engine.context.Log.clock`, on which every time limit, wait
and elapsed time is measured) stands still until :meth:`Interpreter.resume`, which sends
each interrupted action's last request again, as CONTINUE does, with the time it had
left. :meth:`Interpreter.jump` is JUMP_TO_TASK asked from outside, refused with the
language's reason where a written one would be. Each is a ``control`` record in the log.

*Safety.* However the mission ends, every vehicle still bound to it is released: its
mission skills end and it is commanded to the safe state
(:func:`~tml.engine.safety.safe_state_request`: RTL by default, land or hold by option;
an armed vehicle on the ground is disarmed). A role's release does the same for its
vehicles, and a lost vehicle is sent the safe state in case its link comes back.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

from tml.engine.composites import NodeStatus, TasksNode
from tml.engine.context import Duty, Options, Pilot, Run, Verdict
from tml.engine.events import Events, find_task
from tml.engine.failures import Failure
from tml.engine.records import Output, Status, View
from tml.engine.resume import Progress, Restoring
from tml.engine.tasks import TaskNode
from tml.engine.wake import ANYTHING, Wake, Waker
from tml.errors import ControlRefused, EngineError
from tml.language.actions import CAPABILITIES, lookup
from tml.language.check import check_jump
from tml.language.failures import FailureReason
from tml.language.model import Mission
from tml.vehicle import Hold, IdSource, RequestResult, VehicleState


class Interpreter:
    """Runs one mission on ``vehicles``; see the module docstring.

    ``vehicles`` are the vehicle ids, in pick order of preference for ties; ``payloads``
    what each carries beyond what its state reports; ``ids`` numbers the requests and
    plans (a run shares one source with whoever else sends to its vehicles).
    """

    def __init__(self, mission: Mission, vehicles: Sequence[int],
                 options: Options | None = None,
                 payloads: Mapping[int, Iterable[str]] | None = None,
                 ids: IdSource | None = None) -> None:
        self.mission = mission
        self.run = run = Run(mission, vehicles, options or Options(), payloads or {},
                             ids or IdSource())
        self.events = Events(run)
        self.root = TasksNode(run, mission.tasks,
                              lambda task, entry: TaskNode(run, task, {}, None, entry))
        self._results: dict[int, list[RequestResult]] = {}
        self._started = False
        self._held: set[int] = set()  # the vehicles the last pause told to hold

    @property
    def status(self) -> Status:
        """Where the mission run is."""
        return self.run.status

    @property
    def reason(self) -> str:
        """Why it ended ("" while it runs)."""
        return self.run.reason

    # --- the public API ----------------------------------------------------------------------

    def start(self, now: float, states: Mapping[int, VehicleState],
              progress: Progress | None = None) -> Output:
        """Begin the mission: without roles its vehicles are bound to it at once.

        With ``progress`` (:func:`tml.engine.resume.progress`, read from the flight log of
        an interrupted run of this mission on this vehicle) the mission goes on where it
        stood instead: what had ended is not run again, the running task is re-entered with
        the time it had run, repeats go on from their round, memorized points are known
        again, and the mission's elapsed time continues. Only a mission without roles on
        one vehicle can be resumed (EngineError otherwise).
        """
        run = self.run
        self._begin(now, states, {})
        run.log.start = run.log.clock
        self._started = run.started = True
        mission = self.mission
        if progress is not None and progress.started:
            self._restore(progress)
        else:
            run.note("mission", f"mission {mission.name!r} started", run.log.vehicle_id,
                     name=mission.name, vehicles=list(run.pilots),
                     roles=[r.name for r in mission.roles])
        if not mission.roles:
            lacking = next((why for pilot in run.pilots.values()
                            for why in [self._lacking(pilot)] if why), "")
            if lacking:
                self._end(Status.FAILED, lacking)
                return run.log.take()
            run.bound[None] = tuple(run.pilots)
            for pilot in run.pilots.values():
                run.mission_skills(pilot, True)
        self._tick()
        run.restoring = None  # the first step took what it had to
        return run.log.take()

    def _restore(self, progress: Progress) -> None:
        """Take up an interrupted run's ``progress`` (see :meth:`start`)."""
        run = self.run
        if self.mission.roles or len(run.pilots) != 1:
            raise EngineError("only a mission without roles, on one vehicle, can be resumed")
        pilot = next(iter(run.pilots.values()))
        log = run.log
        log.start = log.clock - progress.elapsed
        pilot.labels.update(progress.labels)
        for path, state in progress.ended.items():
            pilot.states[path] = state
        run.restoring = Restoring(progress, log.clock)
        run.note("mission", f"mission {self.mission.name!r} resumed after "
                 f"{progress.elapsed:.1f} s: {len(progress.ended)} tasks ended, "
                 f"{len(progress.running)} running", log.vehicle_id, name=self.mission.name,
                 vehicles=list(run.pilots), elapsed=round(progress.elapsed, 3),
                 ended={path: state.value for path, state in sorted(progress.ended.items())},
                 running=sorted(progress.running),
                 rounds=dict(progress.rounds), labels=sorted(progress.labels))

    def step(self, now: float, states: Mapping[int, VehicleState],
             results: Mapping[int, Sequence[RequestResult]] | None = None) -> Output:
        """Take the time, the latest states and request results; return what to do."""
        run = self.run
        self._begin(now, states, results or {})
        if run.paused:  # the results wait for the work that asked for them
            return run.log.take()
        if run.status is Status.RUNNING:
            for pilot in run.pilots.values():
                self._hand_over(pilot, self._results.pop(pilot.vehicle_id, []))
            for pilot in run.pilots.values():
                self.events.watch(pilot)
            self._tick()
        self._results.clear()
        return run.log.take()

    def lost(self, now: float, vehicle_id: int, reason: str, taken: bool = False) -> Output:
        """A vehicle cannot be used any more (its link is lost): the work it does fails,
        and it is never picked again. A vehicle ``taken`` by someone else (the autopilot
        switched its mode) is not commanded again either, not even to the safe state: its
        failure reason is ``taken``."""
        run = self.run
        run.log.now = now
        pilot = run.pilots[vehicle_id]
        pilot.lost = reason
        self.events.drop(pilot, reason)
        if pilot.duty is not Duty.LOST:
            pilot.become(Duty.LOST)
        role = run.unbind(pilot, taken)  # the role's next task (an on_error) picks another
        run.note("vehicle", f"vehicle {vehicle_id}: {reason}", vehicle_id, vehicle=vehicle_id,
                 reason=reason)
        if run.status is Status.RUNNING:
            failure = Failure(FailureReason.TAKEN, f"taken: vehicle {vehicle_id}: {reason}",
                              vehicle_id) if taken else pilot.link_failure()
            for work in list(pilot.work):
                work.decide(Verdict.FAIL, failure)
            if run.paused:
                # Paused, nothing is stepped until resume: no handler could take the
                # failure up, and the vehicle would be flown by nobody meanwhile (an
                # operator's resume may never come). The run ends as an unhandled failure
                # ends it, and every vehicle still bound goes to its safe state.
                self._end(failure.status, failure.message)
            else:
                self._tick()  # its task fails (and is handled) now
        if role is not None and not taken:
            # Nobody flies it any more; if the link comes back, it goes to the safe state.
            run.safe_state(pilot, reason)
        return run.log.take()

    def abort(self, now: float, states: Mapping[int, VehicleState], reason: str) -> Output:
        """Stop everything and command the safe state (interpreter error, Ctrl-C)."""
        self._begin(now, states, {})
        if self.run.status is Status.RUNNING:
            self._end(Status.ABORTED, reason)
        return self.run.log.take()

    def wake(self) -> Wake:
        """When the interpreter must be stepped again, besides results, lost vehicles and
        controls (:mod:`tml.engine.wake`): asked after any call."""
        run = self.run
        if run.status is not Status.RUNNING:
            return Wake(math.inf, {})
        if (not self._started or run.paused or run.halted or run.jump_to is not None
                or run.restoring is not None or self._results):
            return ANYTHING
        waker = Waker()
        self.events.wake(waker)
        if waker.reads is not None:
            self.root.wake(waker)
        return waker.wake(run.log.now - run.now)

    # --- the operator's controls --------------------------------------------------------------

    @property
    def paused(self) -> bool:
        """Whether the run is paused (:meth:`pause`)."""
        return self.run.paused

    def pause(self, now: float, states: Mapping[int, VehicleState],
              reason: str = "paused by the operator") -> Output:
        """Hold everything: every flying vehicle of the mission is told to hold where it is,
        and until :meth:`resume` nothing is stepped -- no task, no action, no event handler
        -- and the mission's clock stands still, so time limits, waits, and the task's and
        mission's elapsed times stop counting. Request results that arrive meanwhile wait
        for the work that asked for them. ControlRefused when the run is not running or is
        paused already."""
        run = self._controllable("pause")
        if run.paused:
            raise ControlRefused("the run is paused already")
        self._begin(now, states, {})
        run.log.paused_at = now
        run.note("control", f"mission paused: {reason}", run.log.vehicle_id, control="pause",
                 reason=reason)
        self._held = set()
        for pilot in run.pilots.values():
            if pilot.duty is not Duty.LOST and pilot.state.possibly_flying \
                    and self._flies(pilot):
                run.send(Hold(pilot.vehicle_id))
                self._held.add(pilot.vehicle_id)
        return run.log.take()

    def resume(self, now: float, states: Mapping[int, VehicleState]) -> Output:
        """Go on after :meth:`pause`: the results that came meanwhile are handed over, then
        the work of every vehicle the pause held continues as after CONTINUE (its last
        request sent again), with the time it had left. ControlRefused when the run is not
        paused."""
        run = self._controllable("resume")
        if not run.paused:
            raise ControlRefused("the run is not paused")
        self._begin(now, states, {})
        log = run.log
        assert log.paused_at is not None
        paused, log.paused_at = max(0.0, now - log.paused_at), None
        log.paused += paused
        run.note("control", f"mission resumed after {paused:.1f} s paused", log.vehicle_id,
                 control="resume", paused=round(paused, 3))
        for pilot in run.pilots.values():  # what was answered meanwhile, first
            self._hand_over(pilot, self._results.pop(pilot.vehicle_id, []))
        if run.jump_to is None:  # a jump asked meanwhile stops the work instead
            for vid in self._held:  # a vehicle that did not hold has nothing to resend
                for work in list(run.pilots[vid].work):
                    work.carry_on()
        self._tick()
        return log.take()

    def jump(self, now: float, states: Mapping[int, VehicleState], target: str) -> Output:
        """Go on from the task ``target`` (a name or a path), as JUMP_TO_TASK does: what runs
        is stopped (its vehicle holds) and the walk goes on from the target. Refused
        (ControlRefused) with the language's reason where a written JUMP_TO_TASK to it
        would be (:func:`tml.language.check.check_jump`: no such task, an ambiguous name, a
        mission with roles or orchestration). Asked while paused, it is made on resume."""
        run = self._controllable("jump")
        refused = check_jump(self.mission, target)
        if refused:
            first = refused[0]
            raise ControlRefused(f"{first.code}: {first.message}"
                                 + (f" ({first.hint})" if first.hint else ""), first.code)
        path = find_task(run, target)
        self._begin(now, states, {})
        run.note("control", f"jump to {'/'.join(path)}", run.log.vehicle_id, control="jump",
                 task="/".join(path))
        run.jump_to = path
        self._tick()
        return run.log.take()

    def _controllable(self, what: str) -> Run:
        """The run, when an operator's control can act on it now."""
        if not self._started:
            raise ControlRefused(f"cannot {what}: the mission has not started")
        if self.run.status is not Status.RUNNING:
            raise ControlRefused(f"cannot {what}: the mission has ended "
                                 f"({self.run.status.value})")
        return self.run

    def _flies(self, pilot: Pilot) -> bool:
        """Whether the mission flies the vehicle now: bound to it, or at work for it."""
        return bool(pilot.work) or pilot.vehicle_id in {
            vid for bound in self.run.bound.values() for vid in bound}

    def views(self, now: float | None = None) -> dict[int, View]:
        """A snapshot per vehicle for the display, at the runner's time ``now`` (default:
        the last call's): times and waits move on between steps."""
        run = self.run
        at = run.log.now if now is None or self.status is not Status.RUNNING \
            else max(now, run.log.now)
        return {vid: run.view(pilot, at) for vid, pilot in run.pilots.items()}

    # --- a step ------------------------------------------------------------------------------

    def _begin(self, now: float, states: Mapping[int, VehicleState],
               results: Mapping[int, Sequence[RequestResult]]) -> None:
        run = self.run
        run.log.now = now
        for vid, state in states.items():
            if vid in run.pilots:
                run.pilots[vid].state = state
        for vid, found in results.items():
            if vid in run.pilots:
                self._results.setdefault(vid, []).extend(found)

    def _hand_over(self, pilot: Pilot, results: list[RequestResult]) -> None:
        """Each result to the work that sent its request; a failure nobody claims (a hold,
        a safe state) is logged."""
        for result in results:
            if not any(work.on_result(result) for work in list(pilot.work)) and not result.ok:
                self.run.note("result", f"request {result.request_id} failed: "
                              f"{result.reason}", pilot.vehicle_id,
                              request_id=result.request_id, ok=False, reason=result.reason,
                              detail=result.detail)

    def _tick(self) -> None:
        """Step the tree from the root, and end the mission when it is over (not while the
        run is paused: a failure or a jump decided meanwhile is applied on resume)."""
        run = self.run
        if run.paused:
            return
        if run.finish is None and run.jump_to is not None:
            path, run.jump_to = run.jump_to, None
            self.root.jump(path)
        status = NodeStatus.RUNNING if run.halted else self.root.tick()
        if run.status is not Status.RUNNING:
            return
        if run.finish is not None:
            self._end(*run.finish)
        elif status is NodeStatus.SUCCESS:
            self._end(Status.COMPLETED, "all tasks done")
        elif status is NodeStatus.FAILURE:
            failure = self.root.failure
            assert failure is not None
            self._end(failure.status, failure.message)

    def _lacking(self, pilot: Pilot) -> str:
        """Why a vehicle cannot fly this mission, for an action that needs what it has not
        got (a FLIP mode, a gripper); "" when it can."""
        capabilities = pilot.state.capabilities
        for _, action in self.mission.actions():
            spec = lookup(action.name)
            if spec is not None and spec.requires and spec.requires not in capabilities:
                return (f"{spec.name} (line {action.location.line}) needs "
                        f"{CAPABILITIES[spec.requires]}, and vehicle {pilot.vehicle_id} has "
                        "none (refused before take-off)")
        return ""

    # --- the end -----------------------------------------------------------------------------

    def _end(self, status: Status, reason: str) -> None:
        """End the mission: everything running is stopped (no hold: the safe state follows),
        and every vehicle still bound is released to the safe state."""
        run = self.run
        run.status, run.reason, run.ending = status, reason, True
        self.root.stop(reason)
        self.events.stop(reason)
        run.note("mission", f"mission {status.value}: {reason}", run.log.vehicle_id,
                 status=status.value, reason=reason)
        for role in list(run.bound):
            run.release(role, reason)
