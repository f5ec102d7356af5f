"""Event handlers: checked for each vehicle while it flies a task, run on that vehicle, and
their termination applied to that vehicle's work.

On every step, before the task tree is stepped, each vehicle that flies a task and is not
handling an event checks the handlers that apply to it (no role, or its role) in document
order, and the first that triggers fires: on the rising edge of its conditions, or at every
check while they hold with ``trigger="level"``. An action's failure is checked at once, in
the step it happens (ACTION_FAILURE has just changed).

*Edges during a handling.* While a handler runs on a vehicle, no event of that vehicle
fires, but each edge-triggered one is still watched: when one of its conditions that reads
the vehicle (:func:`~tml.engine.conditions.reads_vehicle`: telemetry, detections) is seen
false, the event is armed again, and fires at the first check after the handling where all
its conditions hold. Conditions on the interpreter's own state (CURRENT_ACTION,
CURRENT_TASK, elapsed times, ACTION_FAILURE, labels) are not read then: during a handling
they describe the handler, and a photo taken by the handler of "window seen during a
survey" must not arm that event again. So an event never goes deaf: a condition that falls
and rises again while the vehicle handles an event is a new edge.

A handler whose actions only memorize points and that continues runs them at once and
disturbs nothing. Any other holds the vehicle's work (the vehicle is told to hold), runs its
actions one after the other on the vehicle (a :class:`Handler`), and then its termination
decides for the work it held, or for the action whose failure fired it: CONTINUE resumes
it (or, after a failure, goes on as if it were done), NEXT_TASK abandons its task,
REPEAT_TASK begins the action anew, ABORT_TASK abandons the task the handler is scoped to
with ``current_task`` (else the running task), JUMP_TO_TASK goes on from the named task,
END_MISSION and ABORT_MISSION end the mission. A failure of a handler's own action lets the
other handlers react; if none does, the held work fails with it.
"""

from __future__ import annotations

from tml.engine.composites import Asleep, NodeStatus, SequenceNode
from tml.engine.conditions import names_task, reads_vehicle
from tml.engine.context import Duty, Pilot, Run, TaskOwner, Verdict, Work, WorkMode
from tml.engine.leaves import ActionLeaf
from tml.engine.records import Status
from tml.engine.scripts import ActionFailed, procedure
from tml.engine.wake import Waker, condition_fields
from tml.language.actions import Category, bind
from tml.language.model import ConditionKind, Event, EventTrigger, TerminationMode
from tml.vehicle import Hold, VehicleState, same_state


class Handler(SequenceNode):
    """An event's actions, run one after the other on one vehicle."""

    def __init__(self, run: Run, pilot: Pilot, event: Event) -> None:
        super().__init__(run, len(event.actions), lambda i: ActionLeaf(
            run, pilot, event.actions[i], None, None, event.name))
        self.event = event


class Events:
    """The event handling of a run; see the module docstring."""

    def __init__(self, run: Run) -> None:
        self.run = run
        self.handlers: dict[int, Handler] = {}  # the handler running on each vehicle
        # Per vehicle: the state (and role) in which its last check fired nothing, when all
        # its handlers' conditions read only that vehicle. Checked again in a state that
        # shows the same in the fields they read (tml.engine.wake.condition_fields), they
        # read the same values and fire nothing again (an edge needs a change; a level
        # event that held would have fired), so the check is skipped: in a fleet most
        # vehicles' positions change at every step, their batteries seldom. (A handling
        # begins only where a check fired, which forgets the mark.)
        self._quiet: dict[int, tuple[VehicleState, str | None]] = {}
        self._read: dict[str | None, frozenset[str] | None] = {}  # per role: see _fields
        self._waiting: dict[str | None, frozenset[str] | None] = {}  # per role: see _waits
        # Per vehicle handling an event: the state its edges were last looked at in (see
        # _rearm), while every condition that re-arms them reads that vehicle alone.
        self._rearmed: dict[int, tuple[VehicleState, str | None]] = {}
        # Per vehicle handling an event: what its handler waits for, after its last drive.
        # Until then, with nothing new in what it reads, driving it and re-arming its edges
        # would do nothing (tml.engine.wake): of a fleet landing on low batteries, a step
        # drives the handlers of the vehicles that moved, not of all that land.
        self._asleep: dict[int, Asleep] = {}
        run.react = self.react

    def watch(self, pilot: Pilot) -> None:
        """A step's event handling for one vehicle: its running handler goes on, or its
        handlers are checked."""
        handler = self.handlers.get(pilot.vehicle_id)
        if handler is not None:
            asleep = self._asleep.get(pilot.vehicle_id)
            if asleep is not None and asleep.sleeps(self.run):
                return  # a landing in a fleet: driven again when its vehicle shows more
            self._rearm(pilot)
            self._drive(pilot, handler)
            self._rest(pilot)
        elif pilot.duty is Duty.WATCHING:
            quiet, fields = self._quiet.get(pilot.vehicle_id), self._fields(pilot.role)
            if quiet is not None and fields is not None and quiet[1] == pilot.role \
                    and same_state(quiet[0], pilot.state, fields):
                if quiet[0] is not pilot.state:  # as quiet: known at once next time
                    self._quiet[pilot.vehicle_id] = (pilot.state, pilot.role)
            elif pilot.flying_a_task():
                self._check(pilot)

    def wake(self, waker: Waker) -> None:
        """Tell ``waker`` what the event handling waits for (:mod:`tml.engine.wake`): the
        fields each watching vehicle's handlers read, the running handlers' work, and any
        field of a vehicle whose handling re-arms its edges."""
        run = self.run
        for pilot in run.pilots.values():
            handler = self.handlers.get(pilot.vehicle_id)
            if handler is not None:
                asleep = self._asleep.get(pilot.vehicle_id)
                if asleep is not None and asleep.still():
                    asleep.told.tell(waker)  # what it said after its last drive still holds
                else:
                    self._waits_handling(pilot, handler, waker)
            elif pilot.duty is Duty.WATCHING and pilot.flying_a_task():
                fields = self._waits(pilot.role)
                if fields is None:
                    waker.anything()  # another's state, the interpreter's, or every check
                    return
                waker.state(pilot.vehicle_id, fields)

    def _waits_handling(self, pilot: Pilot, handler: Handler, waker: Waker) -> None:
        """What a vehicle handling an event waits for: its handler's work, and the fields of
        its state its handlers' conditions read (its edges are re-armed on what they show:
        see _rearm)."""
        handler.wake(waker)
        fields = self._fields(pilot.role)
        if fields is None:
            waker.anything()  # re-arming reads more than the vehicle: at every step
        else:  # re-arming reads what the conditions read (see _rearm)
            waker.state(pilot.vehicle_id, fields)

    def _rest(self, pilot: Pilot) -> None:
        """After a handler's drive: note what it waits for, so that it is not driven (nor
        its vehicle's edges re-armed) again before that; nothing if it ended."""
        handler = self.handlers.get(pilot.vehicle_id)
        asleep = None
        if handler is not None:
            waker = Waker()
            self._waits_handling(pilot, handler, waker)
            asleep = Asleep.after(self.run, waker)
        if asleep is None:
            self._asleep.pop(pilot.vehicle_id, None)
        else:
            self._asleep[pilot.vehicle_id] = asleep

    def react(self, pilot: Pilot) -> bool:
        """An action failed on the vehicle: True when a handler fired and decides what
        follows."""
        return pilot.duty is Duty.WATCHING and self._check(pilot)

    def stop(self, why: str) -> None:
        """Stop every running handler (the mission ends)."""
        for vid, handler in list(self.handlers.items()):
            self._drop(self.run.pilots[vid])
            handler.stop(why)

    def drop(self, pilot: Pilot, why: str) -> None:
        """Stop the vehicle's running handler, if any (its link is lost)."""
        handler = self._drop(pilot)
        if handler is not None:
            handler.stop(why)

    def _drop(self, pilot: Pilot) -> Handler | None:
        self._rearmed.pop(pilot.vehicle_id, None)
        self._asleep.pop(pilot.vehicle_id, None)
        handler = self.handlers.pop(pilot.vehicle_id, None)
        if handler is not None and pilot.duty is Duty.HANDLING:
            pilot.become(Duty.WATCHING)
        return handler

    # --- firing ----------------------------------------------------------------------------

    def _check(self, pilot: Pilot) -> bool:
        """Evaluate the vehicle's handlers; fire the first that triggers. True if one fired."""
        run, vid = self.run, pilot.vehicle_id
        self._rearmed.pop(vid, None)  # it sets what each event's conditions held
        memory = pilot.memory(run.now, run.log.mission_time)
        roles = {pilot.role: vid}
        fired: Event | None = None
        for event in run.mission.events:
            if event.role is not None and event.role != pilot.role:
                continue
            readings = [run.reading(c, pilot, memory, roles) for c in event.conditions]
            holds = all(h for h, _ in readings)
            was = pilot.holding.get(event.name, False)
            triggers = holds and (event.trigger is EventTrigger.LEVEL or not was)
            if triggers and fired is None:
                fired = event
                pilot.holding[event.name] = True
                run.note("event", f"event {event.name!r} fired", vid, event=event.name,
                         line=event.location.line,
                         read=[{"subject": c.subject, "value": v}
                               for c, (_, v) in zip(event.conditions, readings, strict=True)])
            elif not triggers or not holds:
                pilot.holding[event.name] = holds  # a rising edge left pending fires next
        if fired is None:
            if self._fields(pilot.role) is not None:
                self._quiet[vid] = (pilot.state, pilot.role)
            return False
        self._quiet.pop(vid, None)
        pilot.events.append((run.log.stamp, fired.name))
        self._fire(pilot, fired)
        return True

    def _waits(self, role: str | None) -> frozenset[str] | None:
        """What the handlers of a watching vehicle in ``role`` wait for: the fields they
        read of its state; None when that is not all (they read the interpreter's state or
        another vehicle's, or one is level-triggered: it fires at every check)."""
        if role not in self._waiting:
            level = any(event.trigger is EventTrigger.LEVEL
                        for event in self.run.mission.events if event.role in (None, role))
            self._waiting[role] = None if level else self._fields(role)
        return self._waiting[role]

    def _fields(self, role: str | None) -> frozenset[str] | None:
        """The state fields the conditions of the handlers of a vehicle in ``role`` read
        (:func:`~tml.engine.wake.condition_fields`); None when one reads more than that
        vehicle's state (the interpreter's, another vehicle's)."""
        if role not in self._read:
            read = [condition_fields(condition) for event in self.run.mission.events
                    if event.role in (None, role) for condition in event.conditions]
            self._read[role] = frozenset().union(*(f for f in read if f is not None)) \
                if None not in read else None
        return self._read[role]

    def _rearm(self, pilot: Pilot) -> None:
        """During a handling: arm again each edge-triggered event one of whose conditions
        on the vehicle is false (see the module docstring)."""
        run, vid = self.run, pilot.vehicle_id
        seen, fields = self._rearmed.get(vid), self._fields(pilot.role)
        if seen is not None and fields is not None and seen[1] == pilot.role and same_state(
                seen[0], pilot.state, fields):
            return  # the same readings: no condition fell since the last look
        memory = pilot.memory(run.now, run.log.mission_time)
        roles = {pilot.role: vid}
        for event in run.mission.events:
            if (event.trigger is EventTrigger.LEVEL or not pilot.holding.get(event.name)
                    or (event.role is not None and event.role != pilot.role)):
                continue
            if any(not run.reading(c, pilot, memory, roles)[0]
                   for c in event.conditions if reads_vehicle(c)):
                pilot.holding[event.name] = False
        if fields is not None:
            self._rearmed[vid] = (pilot.state, pilot.role)

    def _fire(self, pilot: Pilot, event: Event) -> None:
        run = self.run
        if event.termination.mode is TerminationMode.CONTINUE and all(
                bind(a).spec.category is Category.MEMORY for a in event.actions):
            self._memorize(pilot, event)  # without disturbing the running action
            for work in _held(pilot):  # an action's failure fired it: its task goes on
                work.decide(Verdict.GO_ON)
            return
        pilot.become(Duty.HANDLING)
        held = [work.hold() for work in pilot.work if work.owner is not None]
        if any(held) and pilot.state.flying:
            run.send(Hold(pilot.vehicle_id))
        handler = self.handlers[pilot.vehicle_id] = Handler(run, pilot, event)
        self._drive(pilot, handler)

    def _memorize(self, pilot: Pilot, event: Event) -> None:
        run, vid = self.run, pilot.vehicle_id
        for action in event.actions:
            bound = bind(action)
            run.note("action", f"{bound.name} (event {event.name!r})", vid, action=bound.name,
                     line=action.location.line)
            try:
                for _ in procedure(pilot, bound):
                    pass  # memory actions finish without waiting
            except ActionFailed as failure:
                pilot.failure = failure.reason
                run.note("action", f"{bound.name} failed: {failure}", vid, action=bound.name,
                         reason=failure.reason.value)

    def _drive(self, pilot: Pilot, handler: Handler) -> None:
        status = handler.tick()
        if status is NodeStatus.RUNNING:
            return
        self._drop(pilot)
        if status is NodeStatus.SUCCESS:
            self._terminate(pilot, handler.event)
            return
        failure = handler.failure
        assert failure is not None
        if self._check(pilot):  # another handler reacts to the failure
            return
        held = _held(pilot)
        for work in held:
            work.decide(Verdict.FAIL, failure)
        if not held:
            self.run.finish = (failure.status, failure.message)

    # --- terminations ----------------------------------------------------------------------

    def _terminate(self, pilot: Pilot, event: Event) -> None:
        run, mode = self.run, event.termination.mode
        run.note("decision", f"event {event.name!r}: {mode.value}", pilot.vehicle_id,
                 event=event.name, termination=mode.value)
        why = f"event {event.name!r}: {mode.value}"
        held = _held(pilot)
        if mode is TerminationMode.CONTINUE:
            for work in held:
                work.decide(Verdict.RESUME if work.mode is WorkMode.HELD else Verdict.GO_ON)
        elif mode is TerminationMode.NEXT_TASK:
            for owner in _owners(held):
                owner.abandon(why)
        elif mode is TerminationMode.REPEAT_TASK:
            for work in held:
                work.decide(Verdict.RESTART)
        elif mode is TerminationMode.ABORT_TASK:
            for owner in _scopes(event, held):
                owner.abandon(why)
        elif mode is TerminationMode.JUMP_TO_TASK:
            run.jump_to = find_task(run, event.termination.task or "")
        elif mode is TerminationMode.END_MISSION:
            run.finish = (Status.COMPLETED, f"event {event.name!r} ended the mission")
        else:
            run.finish = (Status.ABORTED, f"event {event.name!r} aborted the mission")


def _held(pilot: Pilot) -> list[Work]:
    """The vehicle's task work that a handler holds, or whose failure fired it."""
    return [w for w in pilot.work
            if w.owner is not None and w.mode in (WorkMode.HELD, WorkMode.AWAITING)]


def _owners(held: list[Work]) -> list[TaskOwner]:
    owners: list[TaskOwner] = []
    for work in held:
        if work.owner is not None and work.owner not in owners:
            owners.append(work.owner)
    return owners


def _scopes(event: Event, held: list[Work]) -> list[TaskOwner]:
    """The tasks ABORT_TASK abandons: the one its ``current_task`` condition names among
    those each held work runs in, else (or for a task inside a plan) the work's own."""
    named = next((c.subject for c in event.conditions
                  if c.kind is ConditionKind.CURRENT_TASK), None)
    scopes: list[TaskOwner] = []
    for owner in _owners(held):
        scope: TaskOwner | None = owner
        if named is not None:
            while scope is not None and not names_task(named, scope.task.path):
                scope = scope.owner
        scope = scope or owner
        if scope not in scopes:
            scopes.append(scope)
    return scopes


def find_task(run: Run, reference: str) -> tuple[str, ...]:
    """The path of the task a JUMP_TO_TASK names (checked to exist: E240, E244)."""
    if "/" in reference:
        return tuple(p.strip() for p in reference.split("/"))
    return next(t.path for t in run.mission.walk() if t.name == reference.strip())

