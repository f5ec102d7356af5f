"""The run loop: clock, vehicles, interpreters, flight log and display.

Theory of operation
-------------------
A mission with roles is flown by one :class:`~tml.engine.Interpreter` that picks its
vehicles; one without is flown by every vehicle on its own, one interpreter each (each
relative to its own home). The loop wakes ``rate`` times a second, and at once whenever
``wake`` is set -- the link sets it when a message changes what a vehicle shows, and a
vehicle when a request is done, so an event reacts to the message that made its condition
true without waiting for the next tick. Each wake, for every vehicle still running: collect
the results of its requests, read its state, step its interpreter with the time, submit the
requests that come out, and write everything to the journal; then refresh the display.

*Only what changed.* A vehicle that tells its ``revision()`` (:class:`tml.mavlink.adapter.
MavlinkVehicle`: it changes with every message that changes what the vehicle shows) has its
state rebuilt only when that changed, when it has results, when its telemetry line is due,
or ``refresh`` seconds after the last time (what time alone changes: the link's health,
detections held for a while); a vehicle with none of these, whose last look left nothing to
follow (no lost link being timed, no take-over to handle), is passed over at once. A vehicle
that also tells *when* it changes, and which fields (``watch``, as MavlinkVehicle does), is
not even visited then: it wakes the loop itself, from the thread that saw the change, only
for a change of a field its interpreter reads (or the runner: its link, a take-over, its
messages, a reboot), and a wake looks at those vehicles and at those whose own time came
(:mod:`tml.run.lookout`); one that says how long time alone changes nothing of its state
(``calm``) is refreshed then rather than every ``refresh`` seconds. A fleet's positions
change with every message, and nothing but the display reads them while it hovers: the
display is given the state each vehicle shows now (:meth:`Runner.views`), built apart from
the looks, whose changes the interpreter must see. An
interpreter is stepped when results came, a vehicle was
lost, a field of a vehicle's state it reads changed, or at the time it waits for -- after
each call it says what it waits for (:meth:`tml.engine.Interpreter.wake`, see
:mod:`tml.engine.wake`), and it is stepped no sooner than ``1 / rate`` seconds after its
last step for time alone. A fleet hovering in a WAIT whose events read its batteries costs
the interpreter a step when a battery changes, not one for every message of every vehicle
nor ``rate`` a second; an interpreter that cannot say more waits for anything, as before.
A change alone does not step an interpreter again sooner than :data:`STEP_REST` times its
last step's duration after it: in a large fleet some vehicle changes at every wake, and the
steps take at most half of the process's time, the rest left to reading the links.

*Right of way.* Each turn of the loop after a wake (the controls, the looks, the step, the
requests) is taken with the time base's right of way
(:meth:`tml.timebase.Timebase.right_of_way`): the thread reading the links gives way
between two connections' turns, so that a turn after a vehicle's event is done in one
piece, not in slices between the reading of a fleet's burst of telemetry.

*The heap.* From the first task to the end, what existed before is kept out of the garbage
collector's passes (:mod:`tml.run.heap`): a full pass over a large fleet's objects held
every thread up for tens of milliseconds.

*Time.* The interpreter sees the runner's ``clock``. For a real vehicle that is the
monotonic clock; for the embedded simulator it is the simulator's own vehicle time, so a
speed-up (or a simulator falling behind on a busy machine) changes nothing for the mission:
time limits derived from distance and speed stay true to how the vehicle moves. The loop
waits through ``timebase`` (:mod:`tml.timebase`) and takes part in it: with the embedded
simulator in lock-step, vehicle time moves on only once the loop has stepped on everything
the vehicles said and waits again, so a busy machine slows the flight down but never
changes what happens in it.

*Readiness.* Before the first task, every vehicle must be ready
(:func:`tml.vehicle.awaiting`): its heartbeat, position, home, GPS and battery reported,
and, on the ground, armable (a position estimate and the autopilot's pre-arm checks); in a
mission without roles, every skill the mission switches on the vehicle must be there (its
companion computer heard; a resumed run waits for it too, flying or not). The loop waits
for that up to ``ready_timeout`` seconds of its clock, writing what each vehicle still lacks
to the journal whenever that changes; a vehicle still not ready then fails the run (exit 4)
with what it lacked and the autopilot's own reason, before anything is sent to any vehicle.
A skill nothing on a vehicle switches (:func:`tml.vehicle.unprovided`) fails it at once:
waiting would not bring it. So the first conditions never read a value that has not arrived
as if it were real, and no skill is found missing in flight. A vehicle whose autopilot
reboots while waited for, or whose link, alive once the wait began, stays lost longer than
``link_lost_limit``, fails the run as it would in flight; and a run that ends before its
first task tells a vehicle that may be in the air (a resumed run's) its safe state, and
watches for it, as after a flight.

*The vehicle's own safety.* Once a vehicle on the ground is ready, and before the first
task, the runner puts the mission's fence and rally points on it (one
:class:`~tml.vehicle.Safeguard` request, :mod:`tml.mavlink.safeguards`): the geofence and the
obstacles that reach the sky as its fence, the ``<rally>`` points as its rally points, read
back and compared, and the fence parameters set. Meanwhile the vehicle is waiting for "fence
and rally upload"; the journal's ``safeguard`` line says what was uploaded and that the
read-back matched, or why it could not be done, which fails the run (exit 4) before anything
flies: what keeps a vehicle safe when tml is gone lives on the vehicle.
``RunOptions.vehicle_fence`` False keeps the vehicle's own fence (rally points still go up).
A vehicle already armed or flying is taken as it is.

*Resume.* Given ``resume`` (each vehicle's :class:`~tml.engine.resume.Progress`, read from
the flight log of an interrupted run by :mod:`tml.run.resume`), the run's first line says
``run resumed`` and each interpreter starts from its vehicle's progress instead of from the
first task, once the vehicles are ready as for any run; the caller gives an ``ids`` source
that numbers on from the interrupted run's requests.

*The operator's controls.* :meth:`Runner.control` asks, from any thread, for a pause, a
resume or a jump (:meth:`tml.engine.Interpreter.pause` ...): the request is queued, the
loop wakes and applies it to every interpreter still running between two steps, and the
caller gets the answer -- done, or refused with the reason. Before the first task (the
vehicles not ready yet) and after the run, a control is refused. While paused, the loop goes
on stepping: the telemetry is logged, a lost link still aborts the run, and the
interpreters keep every result for when they resume.

*Safety.* The run stops early on an interpreter exception, on a link that stays ``lost``
longer than ``link_lost_limit`` seconds, on :meth:`Runner.stop` (Ctrl-C, SIGTERM), or on
:meth:`Runner.take_over` (an operator's command through the run, into its state). Then
every vehicle still running is handed to its interpreter's :meth:`abort`, which commands
the safe state (``rtl``, ``land`` or ``hold`` when flying, disarm when armed on the
ground); if the interpreter itself is broken, the runner sends the same request itself
(:func:`~tml.engine.safety.safe_state_request`, the one rule). Requests are numbered from
one :class:`~tml.vehicle.IdSource` for the whole run, the interpreters' and the runner's. After
the interpreters have ended, the runner waits (up to ``settle_timeout`` seconds of the time
base) until the vehicles have carried out what was asked, and if one is still flying an uploaded
mission in AUTO that nobody watches any more, commands the safe state to it as well. Every
such step is written to the journal and to ``on_safety`` so that the run says what it did.

*The end.* How the run ended is one row of :mod:`tml.run.endings` (:attr:`Outcome.ending`,
from each vehicle's status and the cause the runner gave it): its status and exit code are
in the journal's last line, and are what ``tml run`` and ``tml serve`` say.
"""

from __future__ import annotations

import math
import queue
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Any

from tml.engine import Interpreter, Options, Output, Status, View
from tml.engine.flightlog import VERSION as LOG_VERSION
from tml.engine.resume import Progress
from tml.engine.safety import left_to_itself, safe_state_request, safe_state_shown
from tml.engine.wake import ANYTHING, fields_read
from tml.errors import ControlRefused, ExitCode
from tml.language.model import Mission
from tml.language.skills import mission_vehicle_skills
from tml.run.endings import Ending
from tml.run.heap import frozen
from tml.run.journal import Journal, autopilot_fields, telemetry_fields
from tml.run.lookout import Lookout
from tml.timebase import SYSTEM, Flag, Timebase
from tml.vehicle import (
    SEVERITIES,
    WARNING,
    AutopilotMessage,
    IdSource,
    RequestResult,
    Safeguard,
    Vehicle,
    VehicleState,
    awaiting,
    same_state,
    unprovided,
)

LOOKED_AT = frozenset(("link", "taken", "messages", "rejected", "reboots"))
"""The fields of a vehicle's state the runner itself reads at each look (:meth:`Runner._tick`)."""
SAID_WITHIN = 5.0
"""Seconds (the run's clock) before a take-over within which the autopilot's messages are
taken for its words about it: the switch is believed about a second after it is shown."""
NOTICE = SEVERITIES.index("notice")
STEP_REST = 1.0
"""After a step that took ``d`` seconds of the runner's clock, a vehicle's change alone
steps the interpreter again only ``STEP_REST * d`` seconds later (the changes of that
time are taken together); results, lost vehicles and the ``1 / rate`` tick step it at
once. With hundreds of vehicles some vehicle changes at every wake, and a step over all
of them each time left the thread that reads the links too little of the process (see
docs/performance.md, *Fleet*): so the steps take at most half of it. On the simulator in
lock-step, and with a test's clock, no time passes during a step and nothing waits."""


@dataclass
class RunOptions:
    """How the loop runs."""

    rate: float = 20.0  # Hz: wakes without a message, and steps at least
    refresh: float = 0.25  # s between rebuilds of a state whose vehicle says nothing changed
    telemetry_period: float = 1.0  # s between telemetry lines in the journal
    link_lost_limit: float = 10.0  # s of a lost link before the run is aborted
    settle_timeout: float = 30.0  # s (of the time base) to wait for the last requests
    ready_timeout: float = 180.0  # s for every vehicle to be ready before the first task
    safe_state_timeout: float = 120.0  # s to command the safe state until telemetry shows it
    safe_state_period: float = 5.0  # s between two commands of a safe state not shown yet
    safe_state: str = "rtl"
    vehicle_fence: bool = True  # put the mission's fence on the vehicles (False: keep theirs)
    engine: Options = field(default_factory=Options)


CONTROLS = ("pause", "resume", "jump")  # what Runner.control asks the interpreters for


@dataclass
class _Control:
    """An operator's control waiting for the loop, and its answer."""

    kind: str
    target: str = ""
    reason: str = ""  # a pause's reason, for the journal (default: by the operator)
    done: threading.Event = field(default_factory=threading.Event)
    refusal: ControlRefused | None = None


@dataclass(frozen=True)
class VehicleOutcome:
    """How the mission ended on one vehicle."""

    vehicle_id: int
    status: Status
    reason: str
    # What ended its work when the runner did (the cause of an Ending of tml.run.endings:
    # "link", "error", "stop", "operator", "ready", "taken", "rebooted"); "" otherwise.
    cause: str = ""


@dataclass(frozen=True)
class Outcome:
    """How the run ended."""

    vehicles: tuple[VehicleOutcome, ...]

    @property
    def ending(self) -> Ending:
        """Its row of the one table of endings (tml.run.endings): the worst vehicle's."""
        return Ending.of((v.status.value, v.cause) for v in self.vehicles)

    @property
    def exit_code(self) -> ExitCode:
        """The exit code of its ending: 0 completed, 3 aborted, 4 taken or failed."""
        return self.ending.code


class _Flight:
    """One vehicle as the loop sees it."""

    def __init__(self, vehicle: Vehicle) -> None:
        self.vehicle = vehicle
        self.state: VehicleState | None = None
        self.lost_since: float | None = None
        self.lost = False  # reported to the engine
        self.next_telemetry = -math.inf  # when its next telemetry line is due
        self.spread = 0.0  # its share of a period by which its lines come after the first
        self.number = 0  # its place in its crew (tml.run.lookout numbers them so)
        self.cause = ""
        self.messages_told = 0  # the number of the last autopilot message journaled
        self.rejected_told = 0  # absurd telemetry messages journaled so far
        # The autopilot's latest messages with when they were told (for a take-over's words).
        self.said: deque[tuple[float, AutopilotMessage]] = deque(maxlen=16)
        self.boots = 0  # the autopilot's reboots seen before the run began (a vehicle kept open)
        self.taken = False  # someone else switched its mode: it is commanded no more
        self.safe_asked = False  # the safe state was commanded: to be confirmed
        # The link was lost since the safe state was last commanded: that command may not
        # have arrived, and the next is sent the moment the vehicle is heard again.
        self.unheard = False
        self.safe_request = ""  # the name of the last safe-state request sent to it
        self.revision: object = None  # the vehicle's revision when its state was built
        self.revision_of: Callable[[], object] | None = getattr(vehicle, "revision", None)
        # Tells the runner when the vehicle changed, and which fields (tml.run.lookout;
        # MavlinkVehicle.watch); None: it cannot.
        self.watch: Callable[[Callable[[frozenset[str] | None], None]],
                             Callable[[], None]] | None = getattr(vehicle, "watch", None)
        # How long time alone changes nothing of its state (MavlinkVehicle.calm): a vehicle
        # that tells every other change is looked at again then, not every ``refresh`` s.
        self.calm: Callable[[], float] | None = getattr(vehicle, "calm", None) \
            if self.watch is not None else None
        self.shown: tuple[object, VehicleState] | None = None  # (revision, state) displayed
        self.refresh_at = -math.inf  # when the state is rebuilt however the revision stands
        # The last look left nothing to follow up (no lost link to time, no take-over to
        # handle): until its refresh or telemetry line is due, a wake with no result and
        # the same revision changes nothing of it (see Runner._tick), and it is passed over.
        self.settled = False
        self.link = "ok"  # the link's health last journaled
        self.heard = False  # its link was seen alive while the run waited for it
        # The mission's fence and rally points on the vehicle: None not asked yet, the
        # request's id while asked, "done", or why they could not be put there.
        self.safeguard: int | str | None = None


class _Crew:
    """An interpreter and the vehicles it flies."""

    def __init__(self, engine: Interpreter, flights: list[_Flight]) -> None:
        self.engine = engine
        self.flights = flights
        self.broken = False  # the engine raised: it is not asked anything again
        self.step_at = -math.inf  # when the engine is stepped even if nothing changed
        self.wake = ANYTHING  # what the engine waits for (asked after each call)
        self.changed = False  # a field the engine waits for changed since the last step
        self.rest_until = -math.inf  # a change alone steps the engine from then on (STEP_REST)
        self.rest_for = 0.0  # the same rest in seconds of the time base (to sleep it)
        # Which vehicles a wake looks at, when every one of them tells its changes (else a
        # wake walks them all).
        self.lookout = Lookout(len(flights)) if all(f.watch is not None for f in flights) \
            else None
        self.by_id = {f.vehicle.vehicle_id: f for f in flights}
        for number, flight in enumerate(flights):
            flight.number, flight.spread = number, number / len(flights)

    @property
    def running(self) -> bool:
        return self.engine.status is Status.RUNNING and not self.broken

    def states(self) -> dict[int, VehicleState]:
        return {f.vehicle.vehicle_id: f.state for f in self.flights if f.state is not None}


class Runner:
    """Flies ``mission`` on ``vehicles``; see the module docstring."""

    def __init__(self, mission: Mission, vehicles: Sequence[Vehicle], *,
                 clock: Callable[[], float] = time.monotonic,
                 options: RunOptions | None = None, journal: Journal | None = None,
                 wake: Flag | threading.Event | None = None,
                 timebase: Timebase = SYSTEM,
                 on_update: Callable[[Runner], None] | None = None,
                 on_safety: Callable[[str], None] | None = None,
                 wait: Callable[[float], None] | None = None,
                 payloads: Mapping[int, Iterable[str]] | None = None,
                 ids: IdSource | None = None,
                 resume: Mapping[int, Progress] | None = None,
                 about: Mapping[str, Any] | None = None) -> None:
        self.mission = mission
        self.options = options or RunOptions()
        self.clock = clock
        self.timebase = timebase
        self.journal = journal or Journal(None)
        self.wake = wake or Flag(timebase)
        self.on_update = on_update
        self.on_safety = on_safety
        self._wait = wait or self._wait_for_wake
        engine = self.options.engine
        engine.safe_state = self.options.safe_state
        self.flights = [_Flight(v) for v in vehicles]
        # The skills each vehicle must be able to switch before the first task (a companion
        # computer heard): with roles, which vehicle flies which task is decided in flight.
        self.skills = frozenset() if mission.roles else mission_vehicle_skills(mission)
        # One numbering for every request of the run (and of the runs before it on the
        # same vehicles, when the caller gives its source).
        self.ids = ids or IdSource()
        vids = [f.vehicle.vehicle_id for f in self.flights]
        if mission.roles:  # one interpreter picks its vehicles for the roles
            self.crews = [_Crew(Interpreter(mission, vids, engine, payloads, self.ids),
                                self.flights)]
        else:  # every vehicle flies the whole mission on its own
            self.crews = [_Crew(Interpreter(mission, [f.vehicle.vehicle_id], engine, payloads,
                                            self.ids), [f]) for f in self.flights]
        # An interrupted run's progress per vehicle (tml.run.resume): the mission goes on.
        self.resume = resume
        self.about = dict(about or {})  # more for the run's first line (the file's digest)
        self._stop_reason = ""
        self._stop_cause = Ending.STOPPED.cause
        self.safety_actions: list[str] = []
        self._controls: queue.SimpleQueue[_Control] = queue.SimpleQueue()
        self._flying = False  # between the first task and the end: controls are taken
        self._control_lock = threading.Lock()

    # --- control -------------------------------------------------------------------------

    def stop(self, reason: str, safe_state: str | None = None,
             ending: Ending = Ending.STOPPED) -> None:
        """Ask the loop to abort the run (safe to call from a signal handler or a thread);
        with ``safe_state`` (rtl, land, hold: an operator's command), into that one instead
        of the run's own, unless the run is stopping already. ``ending`` is how the run
        ends (:mod:`tml.run.endings`): ``STOPPED`` (Ctrl-C, an abort), or ``OPERATOR``
        for an operator's command that goes through the run (a take-over)."""
        if not self._stop_reason:
            if safe_state is not None:
                self.options.safe_state = self.options.engine.safe_state = safe_state
            self._stop_cause = ending.cause
        self._stop_reason = self._stop_reason or reason
        self.wake.set()

    def take_over(self, command: str) -> None:
        """An operator's command (rtl, land, hold, disarm) to a vehicle of the run, carried
        out through it: the run is stopped into that state -- a disarm, allowed only on the
        ground, into the run's own, which disarms a vehicle on the ground -- every vehicle
        of it, and ends taken by the operator (``Ending.OPERATOR``)."""
        self.stop(f"operator command: {command}", None if command == "disarm" else command,
                  Ending.OPERATOR)

    @property
    def paused(self) -> bool:
        """Whether the run is paused (:meth:`control`)."""
        return any(crew.engine.paused for crew in self.crews if crew.running)

    @property
    def flying(self) -> bool:
        """Whether the mission is under way: from its first task until the run stops."""
        return self._flying and not self._stop_reason

    def control(self, kind: str, target: str = "", timeout: float = 10.0,
                reason: str = "") -> None:
        """Pause, resume or jump to ``target`` (safe to call from any thread); returns once
        the loop has done it, or raises :class:`~tml.errors.ControlRefused` with the reason
        (the run has not started or has ended, the interpreters refused, no answer within
        ``timeout`` wall seconds). ``reason`` is a pause's, for the journal."""
        if kind not in CONTROLS:
            raise ControlRefused(f"{kind!r} is not a control (controls: {', '.join(CONTROLS)})")
        ask = _Control(kind, target, reason)
        with self._control_lock:
            if not self._flying:
                raise ControlRefused(self._not_flying())
            self._controls.put(ask)
        self.wake.set()
        if not ask.done.wait(timeout):
            raise ControlRefused(f"the run did not answer within {timeout:g} s")
        if ask.refusal is not None:
            raise ask.refusal

    def _not_flying(self) -> str:
        if any(c.running for c in self.crews) and not self._stop_reason:
            return "the mission has not started: its vehicles are not ready yet"
        return "the run has ended"

    def _apply_controls(self, now: float) -> None:
        """Apply the controls asked since the last step, in order."""
        while True:
            try:
                ask = self._controls.get_nowait()
            except queue.Empty:
                return
            running = [crew for crew in self.crews if crew.running]
            if not running:
                ask.refusal = ControlRefused("the run has ended")
            for crew in running:
                for flight in crew.flights:
                    flight.state = flight.vehicle.state()
                self._guarded(crew, now, partial(self._ask, crew, ask, now))
            if ask.kind == "pause" and ask.reason and running and ask.refusal is None:
                self._said(f"mission paused: {ask.reason}")  # (an operator's command)
            ask.done.set()

    @staticmethod
    def _ask(crew: _Crew, ask: _Control, now: float) -> Output:
        """One interpreter's part of a control; its refusal is the control's answer."""
        engine, states = crew.engine, crew.states()
        try:
            if ask.kind == "pause":
                return engine.pause(now, states, *([ask.reason] if ask.reason else []))
            if ask.kind == "resume":
                return engine.resume(now, states)
            return engine.jump(now, states, ask.target)
        except ControlRefused as refusal:
            ask.refusal = ask.refusal or refusal
            return Output()

    def _close_controls(self) -> None:
        """No more controls: refuse those still waiting."""
        with self._control_lock:
            self._flying = False
        while True:
            try:
                ask = self._controls.get_nowait()
            except queue.Empty:
                return
            ask.refusal = ControlRefused("the run has ended")
            ask.done.set()

    def views(self) -> list[tuple[View, VehicleState | None]]:
        """The display's view of each vehicle: the engine's view and the last state."""
        views: list[tuple[View, VehicleState | None]] = []
        for crew in self.crews:
            found = crew.engine.views(self.clock())
            views.extend((found[f.vehicle.vehicle_id], _shown(f)) for f in crew.flights)
        return views

    # --- the loop ----------------------------------------------------------------------------

    def run(self) -> Outcome:
        """Fly until every interpreter has ended; return how it went."""
        # A vehicle that tells its changes wakes the loop itself (see _stirred), from the
        # first look at it to the last.
        unwatch = [flight.watch(partial(self._stirred, crew, flight))
                   for crew in self.crews for flight in crew.flights
                   if flight.watch is not None]
        try:
            with self.timebase.taking_part():
                return self._run()
        finally:
            for stop_watching in unwatch:
                stop_watching()

    def _run(self) -> Outcome:
        now = self.clock()
        for flight in self.flights:  # a reboot before this run is not this run's
            flight.boots = flight.vehicle.state().reboots
        self.journal.write(now, "run", message="run resumed" if self.resume is not None
                           else "run started", log_version=LOG_VERSION,
                           mission=self.mission.name,
                           file=self.mission.file, vehicles=[f.vehicle.vehicle_id
                                                             for f in self.flights],
                           roles=[r.name for r in self.mission.roles],
                           safe_state=self.options.safe_state, **self.about)
        unready = self._wait_ready()
        if unready is not None:
            return self._end(unready)
        with frozen():  # what exists now lives as long as the flight (tml.run.heap)
            return self._fly()

    def _fly(self) -> Outcome:
        """From the first task to the end of the run."""
        now = self.clock()
        for flight in self.flights:
            flight.state = flight.vehicle.state()
            # The state the mission starts from: a look later in this instant may already
            # show what its first requests did, or not, as the threads happen to run.
            self._telemetry(flight, flight.state, now)
        for crew in self.crews:
            self._guarded(crew, now, partial(crew.engine.start, now, crew.states(),
                                             self._progress(crew)))
        with self._control_lock:
            self._flying = True
        self._fly_on()
        self._close_controls()
        self._settle()
        return self._end(Outcome(tuple(
            VehicleOutcome(f.vehicle.vehicle_id, c.engine.status, c.engine.reason, f.cause)
            for c in self.crews for f in c.flights)))

    def _stirred(self, crew: _Crew, flight: _Flight, fields: frozenset[str] | None) -> None:
        """A vehicle of ``crew`` changed, in ``fields`` (None: any; told from the thread
        that saw it). A change of fields neither the interpreter nor the runner reads
        waits for the vehicle's own time (its state's refresh, its telemetry line): in a
        fleet, most messages change a position or an attitude that nothing reads."""
        if fields is not None and fields.isdisjoint(LOOKED_AT):
            reads = crew.wake.reads  # (after the run: nothing, and the loop polls)
            if reads is not None:
                names = reads.get(flight.vehicle.vehicle_id, ())
                if names is not None and fields.isdisjoint(names):
                    return
        if crew.lookout is not None:
            crew.lookout.stir(flight.number)
        self.wake.set()

    def _fly_on(self) -> None:
        """Wake after wake until every interpreter has ended, or the run is stopped."""
        while any(c.running for c in self.crews):
            running, at = [c for c in self.crews if c.running], self.clock()
            if all(c.rest_until > at for c in running):
                # Changes coming meanwhile are taken together after it. The rest is slept
                # on the time base: the runner's clock may be a simulator's, faster.
                self.timebase.sleep(min(min(c.rest_for for c in running),
                                        1.0 / self.options.rate))
            self._wait(1.0 / self.options.rate)
            now = self.clock()
            if self._stop_reason:
                self._abort_all(now, self._stop_reason, self._stop_cause)
                break
            # The look, the step and the requests in one piece, not in slices between the
            # link thread's reading (tml.timebase.Timebase.right_of_way).
            with self.timebase.right_of_way():
                self._apply_controls(now)
                for crew in self.crews:
                    if crew.running:
                        self._tick(crew, now)
            if self.on_update is not None:
                self.on_update(self)

    def _progress(self, crew: _Crew) -> Progress | None:
        """Where the interrupted run left the mission of ``crew`` (one vehicle), if resumed."""
        if self.resume is None or len(crew.flights) != 1:
            return None
        return self.resume.get(crew.flights[0].vehicle.vehicle_id)

    def _end(self, outcome: Outcome) -> Outcome:
        for flight in self.flights:  # the state each vehicle is left in
            flight.state = flight.vehicle.state()
            self._tell_messages(flight, self.clock())
            self.journal.write(self.clock(), "telemetry", flight.vehicle.vehicle_id,
                               **telemetry_fields(flight.state))
        ending = outcome.ending
        self.journal.write(self.clock(), "run", message="run ended", status=ending.status,
                           exit_code=int(outcome.exit_code),
                           outcomes=[{"vehicle": v.vehicle_id, "status": v.status.value,
                                      "reason": v.reason} for v in outcome.vehicles])
        if self.on_update is not None:
            self.on_update(self)
        return outcome

    def _wait_ready(self) -> Outcome | None:
        """Wait until every vehicle is ready; the outcome if the run must end instead."""
        timeout = self.options.ready_timeout
        if timeout <= 0:
            return None
        start = self.clock()
        said: dict[int, tuple[str, ...]] = {}
        while True:
            now = self.clock()
            waiting: dict[int, tuple[str, ...]] = {}
            # A vehicle lost or rebooted while waited for: the run ends as it would in flight.
            troubled: dict[int, str] = {}
            for flight in self.flights:
                state = flight.state = flight.vehicle.state()
                self._tell_messages(flight, now)
                vid = flight.vehicle.vehicle_id
                trouble = self._trouble_waiting(flight, state, now)
                if trouble:
                    troubled[vid] = trouble
                missing = waiting[vid] = awaiting(state, self.skills)
                if not missing:
                    missing = waiting[vid] = self._safeguard(flight, state, now)
                if missing != said.get(vid, ()) or vid not in said:
                    said[vid] = missing
                    message = f"waiting for {', '.join(missing)}" if missing else "ready"
                    self.journal.write(now, "ready", vid, message=message,
                                       awaiting=list(missing))
            if not any(waiting.values()):
                return None
            absent = {f.vehicle.vehicle_id: unprovided(f.state, self.skills)
                      for f in self.flights if f.state is not None}
            refused = any(isinstance(f.safeguard, str) and f.safeguard != "done"
                          for f in self.flights) or any(absent.values()) or bool(troubled)
            if self._stop_reason or now - start > timeout or refused:
                stopped = bool(self._stop_reason)
                outcomes = []
                for flight in self.flights:
                    vid = flight.vehicle.vehicle_id
                    if stopped:
                        reason, status = self._stop_reason, Status.ABORTED
                    elif vid in troubled:
                        reason, status = troubled[vid], Status.FAILED
                    elif isinstance(flight.safeguard, str) and flight.safeguard != "done":
                        reason, status = flight.safeguard, Status.FAILED
                    elif absent.get(vid):
                        names = absent[vid]
                        reason = (f"the mission's skill{'s' if len(names) > 1 else ''} "
                                  f"{', '.join(names)}: nothing on this vehicle switches "
                                  f"{'them' if len(names) > 1 else 'it'}")
                        status = Status.FAILED
                    elif refused:
                        reason, status = "another vehicle was not ready", Status.ABORTED
                    elif waiting[vid]:
                        reason = (f"not ready after {timeout:g} s: waiting for "
                                  f"{', '.join(waiting[vid])}")
                        status = Status.FAILED
                    else:
                        reason, status = "another vehicle was not ready", Status.ABORTED
                    flight.cause = flight.cause or (self._stop_cause if stopped
                                                    else Ending.NOT_READY.cause)
                    outcomes.append(VehicleOutcome(vid, status, reason, flight.cause))
                    if status is Status.FAILED and vid not in troubled:
                        self._said(f"vehicle {vid}: {reason}")
                self._safe_after_waiting(now, outcomes)
                return Outcome(tuple(outcomes))
            if self.on_update is not None:
                self.on_update(self)
            self._wait(1.0 / self.options.rate)

    def _trouble_waiting(self, flight: _Flight, state: VehicleState, now: float) -> str:
        """Why a vehicle waited for ends the run as it would end it in flight ("" if
        nothing does): its autopilot rebooted (let go, commanded no more: whatever it had
        been asked is gone, and a mission started on it would be flown on nothing tml set
        up), or its link, alive since the wait began, lost for longer than
        ``link_lost_limit`` seconds. A vehicle never heard yet is waited for (its
        ``heartbeat``) until ``ready_timeout``."""
        if state.reboots > flight.boots and not flight.taken:
            return self._let_go(flight, now)
        if state.link != "lost":
            flight.heard, flight.lost_since = True, None
            return ""
        if not flight.heard:
            return ""
        flight.lost_since = now if flight.lost_since is None else flight.lost_since
        if now - flight.lost_since <= self.options.link_lost_limit:
            return ""
        flight.lost, flight.cause = True, Ending.LINK_LOST.cause
        reason = f"link lost for more than {self.options.link_lost_limit:g} s"
        self._said(f"vehicle {flight.vehicle.vehicle_id}: {reason}")
        return reason

    def _safe_after_waiting(self, now: float, outcomes: Sequence[VehicleOutcome]) -> None:
        """A run that ends before its first task leaves no vehicle flying without a
        controller: one that may be in the air (a resumed run's, or a continued one's) is
        told its safe state and watched until it shows it, as at the end of a flight; one
        on the ground and disarmed is left as it is (nothing was sent to it)."""
        reason = next((o.reason for o in outcomes if o.status is Status.FAILED),
                      outcomes[0].reason if outcomes else "")
        for flight in self.flights:
            if flight.state is not None and not flight.taken and (
                    flight.state.possibly_flying or flight.state.armed):
                self._fallback_safe_state(flight, now, f"the run ended before its first "
                                                       f"task: {reason}")
        self._confirm_safe_states()

    def _safeguard(self, flight: _Flight, state: VehicleState, now: float) -> tuple[str, ...]:
        """Put the mission's fence and rally points on a ready vehicle (once, on the ground,
        a :class:`~tml.vehicle.Safeguard` request); what it still waits for meanwhile."""
        world = self.options.engine.world or self.mission.world
        if flight.safeguard is None:
            if world is None or state.armed or not (
                    world.rally or (self.options.vehicle_fence and (
                        world.geofence or world.obstacles))):
                flight.safeguard = "done"
                return ()
            request = Safeguard(flight.vehicle.vehicle_id, world,
                                fence=self.options.vehicle_fence, request_id=self.ids.take())
            flight.safeguard = request.request_id
            flight.vehicle.submit(request)
        if isinstance(flight.safeguard, int):
            for result in flight.vehicle.poll():  # nothing else is asked before take-off
                if result.request_id != flight.safeguard:
                    continue
                vid = flight.vehicle.vehicle_id
                if result.ok:
                    flight.safeguard = "done"
                    self.journal.write(now, "safeguard", vid, ok=True,
                                       message=f"on the vehicle: {result.detail}")
                else:
                    flight.safeguard = (f"the mission's fence and rally points could not be "
                                        f"put on the vehicle: {result.detail or result.reason}")
                    self.journal.write(now, "safeguard", vid, ok=False,
                                       message=flight.safeguard, reason=result.reason)
        return () if flight.safeguard == "done" else ("fence and rally upload",)

    def _tell_messages(self, flight: _Flight, now: float) -> None:
        """Journal the autopilot's messages not journaled yet."""
        assert flight.state is not None
        for message in flight.state.messages:
            if message.number > flight.messages_told:
                flight.messages_told = message.number
                flight.said.append((now, message))
                self.journal.write(now, "autopilot", flight.vehicle.vehicle_id,
                                   **autopilot_fields(message))

    def _tell_rejected(self, flight: _Flight, now: float) -> None:
        """Journal, at the telemetry's pace, the absurd telemetry ignored since the last
        time (counted: a broken or hostile sender may send thousands)."""
        assert flight.state is not None
        count = flight.state.rejected
        if count > flight.rejected_told:
            self.journal.write(now, "rejected", flight.vehicle.vehicle_id,
                               message=f"ignored {count - flight.rejected_told} telemetry "
                                       f"message(s) with an absurd value, "
                                       f"last: {flight.state.rejected_last}",
                               count=count, last=flight.state.rejected_last)
            if not flight.rejected_told:
                self._said(f"vehicle {flight.vehicle.vehicle_id}: absurd telemetry ignored "
                           f"({flight.state.rejected_last})")
            flight.rejected_told = count

    def _wait_for_wake(self, timeout: float) -> None:
        self.wake.wait(timeout)
        self.wake.clear()

    def _tick(self, crew: _Crew, now: float) -> None:
        began = self.timebase.now()
        results: dict[int, list[RequestResult]] = {}
        lost: list[_Flight] = []
        taken: list[_Flight] = []
        changed = False
        reads = crew.wake.reads
        lookout = crew.lookout
        flights = crew.flights if lookout is None else [crew.flights[n]
                                                         for n in lookout.due(now)]
        for flight in flights:
            vehicle = flight.vehicle
            found = vehicle.poll()
            revision = None if flight.revision_of is None else flight.revision_of()
            if (flight.settled and not found and revision == flight.revision
                    and now < flight.refresh_at and now < flight.next_telemetry):
                continue  # in a fleet, most vehicles at most wakes: nothing below would act
            if found:
                results[vehicle.vehicle_id] = found
            if (revision is None or revision != flight.revision or found
                    or now >= flight.refresh_at or now >= flight.next_telemetry
                    or flight.state is None):
                before, state = flight.state, vehicle.state()
                flight.state, flight.revision = state, revision
                flight.refresh_at = now + (self.options.refresh if flight.calm is None
                                           else max(self.options.refresh, flight.calm()))
                if not changed and state is not before:
                    changed = before is None or not same_state(
                        before, state, fields_read(reads, vehicle.vehicle_id))
                self._tell_messages(flight, now)
            else:
                state = flight.state
            for result in found:
                self.journal.write(now, "result", vehicle.vehicle_id,
                                   request_id=result.request_id, ok=result.ok,
                                   reason=result.reason, detail=result.detail)
            if now >= flight.next_telemetry:
                self._telemetry(flight, state, now)
            self._tell_link(flight, state, now)
            if state.link == "lost":
                flight.lost_since = now if flight.lost_since is None else flight.lost_since
                if now - flight.lost_since > self.options.link_lost_limit and not flight.lost:
                    lost.append(flight)
            else:
                flight.lost_since = None
            if flight.lost:  # given up on: back, it is told its safe state at once
                self._heard_again(flight, state, now)
            pending = (state.taken or state.reboots > flight.boots) and not flight.taken
            if pending:
                taken.append(flight)
            flight.settled = not (pending or revision is None or flight.lost
                                  or flight.lost_since is not None)
            if lookout is not None:
                lookout.looked(flight.number, min(flight.refresh_at, flight.next_telemetry),
                               not flight.settled)
        for flight in taken:
            self._taken(crew, flight, now)
        for flight in lost:
            flight.lost = True
            flight.cause = Ending.LINK_LOST.cause
            reason = f"link lost for more than {self.options.link_lost_limit:g} s"
            self._said(f"vehicle {flight.vehicle.vehicle_id}: {reason}")
            self._guarded(crew, now, partial(crew.engine.lost, now, flight.vehicle.vehicle_id,
                                             reason))
        crew.changed = crew.changed or changed
        if crew.running and (results or lost or taken or now >= crew.step_at
                             or (crew.changed and now >= crew.rest_until)):
            crew.changed = False
            self._guarded(crew, now, lambda: crew.engine.step(now, crew.states(), results))
            # Time alone steps it at the rate, or later when the engine says nothing can
            # happen before then (a WAIT, a request's answer: tml.engine.wake).
            crew.step_at = max(now + 1.0 / self.options.rate, crew.wake.at)
            ended = self.clock()
            crew.rest_until = ended + STEP_REST * (ended - now)
            crew.rest_for = STEP_REST * (self.timebase.now() - began)

    def _telemetry(self, flight: _Flight, state: VehicleState, now: float) -> None:
        """The vehicle's telemetry line, and when its next is due."""
        # Every line of a fleet due at the same wake made one wake look at every vehicle
        # once a period: the second line of each comes its share of a period later.
        flight.next_telemetry = now + self.options.telemetry_period * (
            1.0 + (flight.spread if flight.next_telemetry == -math.inf else 0.0))
        if self.journal.stream is not None:  # (a fleet's thousand lines a second: not for nothing)
            self.journal.write(now, "telemetry", flight.vehicle.vehicle_id,
                               **telemetry_fields(state))
        self._tell_rejected(flight, now)

    def _taken(self, crew: _Crew, flight: _Flight, now: float) -> None:
        """Someone else switched the vehicle's mode (see tml.mavlink.modes.ModeWatch): its
        work fails, and nothing is sent to it any more, not even the safe state -- whoever
        took it flies it now. A vehicle whose autopilot rebooted is let go too."""
        assert flight.state is not None
        if flight.state.reboots > flight.boots:
            self._rebooted(crew, flight, now)
            return
        vid, mode = flight.vehicle.vehicle_id, flight.state.taken
        flight.taken, flight.cause = True, Ending.TAKEN.cause
        # Nothing in the telemetry says who: the autopilot's failsafe, the pilot's RC
        # switch and another ground station's command look alike (the journal's line keeps
        # the autopilot's last message, which may tell a reader).
        reason = f"switched to {mode} outside tml"
        words = self._words(flight, now)
        if words:  # the autopilot's own words, when it gave them (Polygon fence breached)
            reason += f" (autopilot: {words})"
        self.journal.write(now, "taken", vid, message=f"vehicle {vid} {reason}", mode=mode,
                           status_text=flight.state.status_text)
        self._said(f"vehicle {vid} {reason}: tml commands it no more")
        self._guarded(crew, now, partial(crew.engine.lost, now, vid, reason, True))

    def _words(self, flight: _Flight, now: float) -> str:
        """What the autopilot said of a take-over: of its messages told within
        :data:`SAID_WITHIN` s before it, the most severe at NOTICE or worse, the first of
        those (ArduCopter says ``Polygon fence breached`` as a notice, then ``Fence breach
        cleared`` as one when it is back inside); else its last warning, if any."""
        near = [m for at, m in flight.said if now - at <= SAID_WITHIN and m.severity <= NOTICE]
        if near:
            return min(near, key=lambda m: (m.severity, m.number)).text
        assert flight.state is not None
        warned = [m for m in flight.state.messages if m.severity <= WARNING]
        return warned[-1].text if warned else ""

    def _rebooted(self, crew: _Crew, flight: _Flight, now: float) -> None:
        """The autopilot rebooted (tml.mavlink.reboot): it came back disarmed, in its first
        mode, with nothing of what it was asked. On the ground that ends its work; in the
        air the vehicle fell or flies on nothing tml set up. Either way its work fails with
        the reason and nothing is sent to it any more: what it does now is the operator's
        to decide, on what the vehicle shows."""
        reason = self._let_go(flight, now)
        if flight.lost:
            return  # its work failed with the link already
        self._guarded(crew, now, partial(crew.engine.lost, now, flight.vehicle.vehicle_id,
                                         reason, True))

    def _let_go(self, flight: _Flight, now: float) -> str:
        """A rebooted vehicle is commanded no more: logged (a ``taken`` line with
        ``reboot``) and said; the reason ("rebooted while armed (its clock went from
        ...)")."""
        assert flight.state is not None
        vid, state = flight.vehicle.vehicle_id, flight.state
        flight.taken, flight.cause = True, Ending.REBOOTED.cause
        reason = state.rebooted or "rebooted"
        self.journal.write(now, "taken", vid, message=f"vehicle {vid} {reason}",
                           mode=state.mode, reboot=True, status_text=state.status_text)
        self._said(f"vehicle {vid} {reason}: tml commands it no more")
        return reason

    def _guarded(self, crew: _Crew, now: float, call: Callable[[], Output]) -> None:
        """Run an engine call; an exception aborts every vehicle."""
        try:
            output = call()
            crew.wake = crew.engine.wake()
        except Exception as error:  # any engine bug must end in the safe state
            crew.broken = True
            for flight in crew.flights:
                flight.cause = flight.cause or Ending.ERROR.cause
            self.journal.write(now, "error", None, message=f"interpreter error: {error!r}",
                               traceback=traceback.format_exc())
            for flight in crew.flights:
                self._fallback_safe_state(flight, now, f"interpreter error: {error}")
            self._abort_all(now, f"interpreter error: {error}", Ending.ERROR.cause)
            return
        self._dispatch(crew, output)

    def _dispatch(self, crew: _Crew, output: Output) -> None:
        # The call's decisions are on the disk before its requests go out, in one sync.
        with self.journal.grouped():
            for record in output.records:
                self.journal.write(record.time, record.kind, record.vehicle_id, record.data)
                if record.kind == "safety":
                    self._said(f"vehicle {record.vehicle_id}: {record.data['message']}")
        for record in output.records:
            if record.kind == "safety" and record.vehicle_id in crew.by_id:
                flight = crew.by_id[record.vehicle_id]
                flight.safe_asked = True
                flight.safe_request = str(record.data.get("request", ""))
                # Sent into a dead link: again once the vehicle is heard.
                flight.unheard = flight.unheard or (
                    flight.state is not None and flight.state.link == "lost")
        for request in output.requests:
            flight = crew.by_id[request.vehicle_id]
            flight.vehicle.submit(request)
            if crew.lookout is not None:  # what it asked shows in its next state
                crew.lookout.stir(flight.number)

    def _abort_all(self, now: float, reason: str, cause: str) -> None:
        for crew in self.crews:
            if crew.running:
                for flight in crew.flights:
                    flight.cause = flight.cause or cause
                    flight.state = flight.vehicle.state()
                self._said(f"vehicle{'s' if len(crew.flights) > 1 else ''} "
                           f"{', '.join(str(f.vehicle.vehicle_id) for f in crew.flights)}: "
                           f"aborting: {reason}")
                self._guarded(crew, now, partial(crew.engine.abort, now, crew.states(), reason))

    # --- the end -----------------------------------------------------------------------------

    def _fallback_safe_state(self, flight: _Flight, now: float, reason: str) -> None:
        """The safe-state request, sent from here when the engine cannot be asked."""
        state = flight.state = flight.vehicle.state()
        if flight.taken:
            return  # flown by whoever took it
        safe = safe_state_request(state, self.options.safe_state)
        vid = flight.vehicle.vehicle_id
        left = "" if safe is not None else left_to_itself(state, self.options.safe_state)
        if left:  # landing or returning already: a decision, said as the engine says it
            self.journal.write(now, "safety", vid, message=f"{left} ({reason})", request="")
            self._said(f"vehicle {vid}: {left} ({reason})")
            flight.safe_asked, flight.safe_request = True, ""  # confirmed like the others
        if safe is not None:
            request = replace(safe[0], request_id=self.ids.take())
            self.journal.write(now, "safety", vid, message=f"{request.name} ({reason})",
                               request=request.name, request_id=request.request_id)
            self._said(f"vehicle {vid}: {request.name} ({reason})")
            flight.safe_asked, flight.safe_request = True, request.name
            flight.unheard = flight.unheard or state.link == "lost"
            flight.vehicle.submit(request)

    def _settle(self) -> None:
        """Wait for the last requests; leave no vehicle flying an unwatched AUTO mission."""
        end = self.timebase.now() + self.options.settle_timeout
        while self.timebase.now() < end and not all(_idle(f.vehicle) for f in self.flights):
            self._wait(0.05)
        now = self.clock()
        for flight in self.flights:
            for result in flight.vehicle.poll():
                self.journal.write(now, "result", flight.vehicle.vehicle_id,
                                   request_id=result.request_id, ok=result.ok,
                                   reason=result.reason, detail=result.detail)
                if not result.ok:
                    self._said(f"vehicle {flight.vehicle.vehicle_id}: request "
                               f"{result.request_id} failed: {result.reason} {result.detail}")
            state = flight.state = flight.vehicle.state()
            if state.mode == "AUTO" and not state.landed:
                self._fallback_safe_state(flight, now, "the run ended with the vehicle "
                                                       "flying an uploaded mission")
        while self.timebase.now() < end and not all(_idle(f.vehicle) for f in self.flights):
            self._wait(0.05)
        self._confirm_safe_states()

    def _confirm_safe_states(self) -> None:
        """Command the safe state again until the telemetry shows it, or give up after
        ``safe_state_timeout`` s of the run's clock: one sent into a dead link is lost, and
        the vehicle would hover on in GUIDED when its link comes back."""
        waiting = [f for f in self.flights if f.safe_asked and not f.taken]
        start = self.clock()
        sent = dict.fromkeys(id(f) for f in waiting)
        while waiting:
            now = self.clock()
            for flight in list(waiting):
                state = flight.state = flight.vehicle.state()
                self._tell_messages(flight, now)
                self._tell_link(flight, state, now)
                for result in flight.vehicle.poll():
                    self.journal.write(now, "result", flight.vehicle.vehicle_id,
                                       request_id=result.request_id, ok=result.ok,
                                       reason=result.reason, detail=result.detail)
                vid = flight.vehicle.vehicle_id
                if safe_state_shown(state, self.options.safe_state):
                    waiting.remove(flight)
                    self.journal.write(now, "safety", vid, confirmed=True, mode=state.mode,
                                       message=f"safe state shown: {state.mode}"
                                       + (", landed" if state.landed else ""))
                elif now - start > self.options.safe_state_timeout:
                    waiting.remove(flight)
                    self._said(f"vehicle {vid}: safe state not confirmed within "
                               f"{self.options.safe_state_timeout:g} s (mode {state.mode}, "
                               f"link {state.link}): given up")
                elif self._heard_again(flight, state, now) or self._overtaken(flight, state,
                                                                              now):
                    sent[id(flight)] = now
                elif _idle(flight.vehicle) and state.link != "lost" and (
                        sent[id(flight)] is None or now - (sent[id(flight)] or 0.0)
                        >= self.options.safe_state_period):  # (not into a dead link)
                    if sent[id(flight)] is not None:  # the first was the run's own
                        self._fallback_safe_state(flight, now, "not shown yet")
                    sent[id(flight)] = now
            if waiting:
                self._wait(0.1)

    def _overtaken(self, flight: _Flight, state: VehicleState, now: float) -> bool:
        """The safe-state request last sent no longer fits what fresh telemetry shows --
        told to disarm on the ground, the vehicle is seen climbing on the take-off asked a
        moment before (a copter refuses a disarm in the air) -- so the one that fits now is
        sent at once rather than a period later. Whether it was sent."""
        if flight.taken or state.link == "lost" or not state.current \
                or not _idle(flight.vehicle):
            return False
        safe = safe_state_request(state, self.options.safe_state)
        if safe is None or safe[0].name == flight.safe_request:
            return False
        self._fallback_safe_state(flight, now, f"{safe[1].split(':')[0]} now")
        return True

    def _heard_again(self, flight: _Flight, state: VehicleState, now: float) -> bool:
        """A vehicle told its safe state whose link was lost since: command the safe state
        again the moment it is heard (its requests through, and every reading the rule
        judges by arrived after the one sent into the dead link), without waiting for the
        next period -- that command never arrived, and the vehicle hovers on in GUIDED
        meanwhile. Whether it was sent."""
        if not flight.safe_asked or flight.taken:
            return False
        if state.link == "lost":
            flight.unheard = True
            return False
        if not flight.unheard or not state.current or not _idle(flight.vehicle):
            return False  # (not current: a picture from before the outage decides nothing)
        flight.unheard = False
        self._fallback_safe_state(flight, now, "the link came back")
        return True

    def _tell_link(self, flight: _Flight, state: VehicleState, now: float) -> None:
        """Journal a change of the vehicle's link health at the wake that sees it, not only
        in the next telemetry line (a second apart): when trouble was noticed is what an
        operator asks first."""
        if state.link != flight.link:
            self.journal.write(now, "link", flight.vehicle.vehicle_id,
                               message=f"link {state.link} (was {flight.link})",
                               link=state.link, was=flight.link)
            flight.link = state.link

    def _said(self, message: str) -> None:
        self.safety_actions.append(message)
        if self.on_safety is not None:
            self.on_safety(message)



def _shown(flight: _Flight) -> VehicleState | None:
    """A vehicle's latest state for the display. A look waits for a change of a field
    something reads (or the vehicle's own time): the display gets the state the vehicle
    shows now, built apart from the looks' (whose changes the interpreter must see)."""
    if flight.state is None or flight.watch is None or flight.revision_of is None:
        return flight.state  # (a vehicle that tells nothing is looked at at every change)
    revision = flight.revision_of()
    if revision == flight.revision:
        return flight.state
    if flight.shown is None or flight.shown[0] != revision:
        flight.shown = (revision, flight.vehicle.state())
    return flight.shown[1]


def _idle(vehicle: Any) -> bool:
    """Whether a vehicle has carried out everything submitted (True if it cannot say)."""
    idle = getattr(vehicle, "idle", None)
    return True if idle is None else bool(idle())
