"""The service: missions, runs and vehicles, as the HTTP API and the page see them.

Theory of operation
-------------------
:class:`Service` is everything ``tml serve`` does, without HTTP: the API
(:mod:`tml.serve.api`) turns each request into one call here and each answer into JSON,
and every refusal into a :class:`RequestError` with its HTTP status. A refusal is never
a traceback: an invalid mission is answered with the diagnostics of ``tml validate``, an
infeasible one with the report of ``tml verify``.

*Missions* are validated on upload with :func:`tml.language.validation.validate_file`,
the pipeline of ``tml validate``; only valid ones are stored (warnings are kept with
them). A stored mission is parsed again from its text when it is needed (and kept parsed).

*Runs* are flown as ``tml run`` flies, by the one use case :class:`tml.run.flight.Flight`
with the run's :class:`~tml.run.flight.FlightOptions` (:meth:`ServiceOptions.flight`): the
mission is cleared for the run's vehicles by the pre-flight clearance (verified against
the vehicle profile, the vehicles' kinds checked against its actions; refused unless
``force``), the vehicles are claimed, and a :class:`~tml.serve.live.LiveRun` flies it in
its own thread with the in-flight checks of :func:`tml.run.checked.checked_options`.
Without roles every vehicle of the run flies the whole mission, as with ``tml run
--vehicles N``; with roles the run's vehicles are the ones its roles pick from. A run
asked for without vehicles takes the first free one (a mission with roles: every free
one).

*A run whose end could not be stored* (the database full or gone) has ended all the same:
its vehicles are free and its stream has ended. The service keeps it (its outcome, its
log) and shows it as it ended until the database takes it; each later write request
(an upload, a start, a delete) tries to store it first.

*Answers* are the API's typed models (:mod:`tml.serve.answers`), built here; the API
sends them as they are.

*Stopping.* :meth:`Service.stop` aborts every live run (each vehicle to its safe state,
as Ctrl-C does to ``tml run``) and waits for the runs to end. A run that was flying when
the service died is marked ``interrupted`` by :meth:`Service.start`.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import json
import math
import secrets
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ParamSpec, TypeVar

from pydantic import JsonValue

from tml import __version__
from tml.engine.resume import Progress
from tml.errors import ControlRefused, TmlError
from tml.language.model import Event, Mission, Role, Task
from tml.language.validation import ValidationResult, validate_file
from tml.run.clearance import Incapable, Infeasible, NoParameters, NotCleared
from tml.run.control import MotionCheck, TargetWatches
from tml.run.endings import Ending
from tml.run.flight import Flight, FlightOptions
from tml.run.journal import telemetry_fields
from tml.run.resume import ResumeRefused, progress_point
from tml.run.session import VEHICLE_PROFILE
from tml.serve.answers import (
    AnswerOutcome,
    CommandAnswer,
    CommandOutcome,
    CylinderOutline,
    Diagnostic,
    EventOutline,
    FenceOutline,
    HomeOutline,
    HomeView,
    MissionDetail,
    MissionRef,
    MissionSummary,
    ObjectOutline,
    OperatorCommand,
    OperatorCommandSeen,
    PrismOutline,
    RoleOutline,
    RunView,
    ServiceStatus,
    TaskOutline,
    VehicleOutcome,
    VehicleView,
    WorldOutline,
    answer_outcome,
    json_value,
    operator_command,
    run_status,
)
from tml.serve.forward import Answer, Forwarded
from tml.serve.hangar import Hangar, VehicleTaken
from tml.serve.live import LiveRun, TaskBoard
from tml.serve.storage import ACTIVE, Storage, StoredMission, StoredRun
from tml.vehicle import IdSource, Vehicle, awaiting
from tml.verify.motion import PredictedState
from tml.verify.profile import SHIPPED, VehicleProfile, load_profile
from tml.verify.report import report_document
from tml.verify.static import Report, verify_mission
from tml.world import Cylinder, World

if TYPE_CHECKING:
    from tml.mavlink.targets import TargetWatch

P = ParamSpec("P")
T = TypeVar("T")
SAFE_STATES = ("rtl", "land", "hold")
CONFIRM_PERIOD = 0.05  # s between two looks at a vehicle while a command is confirmed
KEPT_SOURCE = 64 * 1024  # characters of the largest mission kept parsed between requests
KEPT_MISSIONS = 64  # how many are kept
TRIM_ABOVE = 256 * 1024  # bytes of a mission whose parsing is followed by a heap trim
_parsed_large = threading.local()  # .seen: this thread parsed a large mission (_validate)


def _validate(filename: str, data: bytes) -> ValidationResult:
    """:func:`validate_file`, noting a large mission for :func:`_gives_memory_back`."""
    if len(data) > TRIM_ABOVE:
        _parsed_large.seen = True
    return validate_file(filename, data)


def _gives_memory_back(method: Callable[P, T]) -> Callable[P, T]:
    """A service call after which, when it parsed a large mission, the C heap's free
    memory is given back to the system: the parser's and the model's memory is freed
    when the call returns, but glibc keeps it unless asked (without this a service that
    took six 4 MB missions stays 150 MB larger after they are deleted)."""
    @functools.wraps(method)
    def call(*args: P.args, **kwargs: P.kwargs) -> T:
        try:
            return method(*args, **kwargs)
        finally:
            if getattr(_parsed_large, "seen", False):
                _parsed_large.seen = False
                _trim()

    return call


def _trim() -> None:
    """glibc's malloc_trim: free memory at the top and inside the heap back to the system
    (nothing elsewhere)."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).malloc_trim(0)


class RequestError(TmlError):
    """A request the service refuses; ``status`` is its HTTP status, ``detail`` more
    JSON for the answer (diagnostics, a report)."""

    status = 400

    def __init__(self, message: str, **detail: JsonValue) -> None:
        super().__init__(message)
        self.message = message
        self.detail: dict[str, JsonValue] = detail


class NotFound(RequestError):
    """No such mission, run or vehicle."""

    status = 404


class Conflict(RequestError):
    """The request does not fit what is going on (a vehicle held, a run ended)."""

    status = 409


class Refused(RequestError):
    """The request is well formed but cannot be done (invalid or infeasible mission)."""

    status = 422


@dataclass
class Asked:
    """An operator's command being answered: to which vehicle, and the run that held it
    (:meth:`Service.command`)."""

    vehicle: int
    command: OperatorCommand
    run: str | None = None


@dataclass
class ServiceOptions:
    """How the service flies its runs."""

    instance: str = "local"  # the name its runs are stored under (docs/serve.md)
    link_lost_limit: float = 10.0  # s of a lost link before a run is aborted
    ready_timeout: float = 180.0  # s for a run's vehicles to be ready before its first task
    stop_timeout: float = 60.0  # wall s to wait for each run to end when the service stops
    command_timeout: float = 30.0  # wall s an operator's command waits for its answer
    vehicle_fence: bool = True  # put each mission's fence on its vehicles (False: keep theirs)

    def flight(self, safe_state: str = "rtl", force: bool = False) -> FlightOptions:
        """How a run is cleared and flown (``safe_state`` and ``force``: the run's own);
        the GCS failsafe of every vehicle was read when the service opened it (or leased
        it), not again for each run."""
        return FlightOptions(safe_state=safe_state, link_lost_limit=self.link_lost_limit,
                             ready_timeout=self.ready_timeout,
                             vehicle_fence=self.vehicle_fence, force=force,
                             gcs_failsafe=False)


class Service:
    """Missions, runs and vehicles; see the module docstring."""

    def __init__(self, storage: Storage, hangar: Hangar,
                 options: ServiceOptions | None = None) -> None:
        self.storage = storage
        self.hangar = hangar
        self.options = options or ServiceOptions()
        self.started = time.time()
        self.said: list[str] = []  # what stopping did to leave the vehicles safe
        # One numbering of requests and plans for every run: a vehicle that still reports
        # the last run's plan never has it taken for the next run's.
        self.ids = IdSource()
        self._live: dict[str, LiveRun] = {}
        self._unsaved: dict[str, LiveRun] = {}  # ended, not stored yet (module docstring)
        self._parsed: OrderedDict[str, Mission] = OrderedDict()  # small ones: _parse
        self._lock = threading.Lock()
        self._commands: dict[int, OperatorCommandSeen] = {}  # each vehicle's last one
        self._targets = TargetWatches()  # GUIDED targets, by vehicle id
        # In a cluster (tml.serve.cluster): has the instance named carry out a request
        # about a run it flies, and answers as it did (tml.serve.forward).
        self.forward: Callable[[str, Forwarded], Answer] | None = None

    # --- life ----------------------------------------------------------------------------

    def start(self) -> list[str]:
        """Mark the runs that were flying when this instance last stopped; their ids."""
        return self.storage.interrupt_unfinished(self.options.instance)

    def stop(self, reason: str = "the service is stopping") -> None:
        """Abort every live run (safe state first) and wait for each to end; what was done
        to leave the vehicles safe is in :attr:`said`."""
        with self._lock:
            live = list(self._live.values())
        for run in live:
            run.abort(reason)
        for run in live:
            run.join(self.options.stop_timeout)
            self.said.extend(f"run {run.id}: {message}" for message in run.safety)

    def status(self) -> ServiceStatus:
        """What the service is: version, instance, storage, vehicles, live runs."""
        with self._lock:
            live = sorted(self._live)
        return ServiceStatus(version=__version__, instance=self.options.instance,
                             storage=self.storage.backend, started=self.started,
                             vehicles=sorted(self.hangar.vehicles), live_runs=live)

    # --- missions ------------------------------------------------------------------------

    @_gives_memory_back
    def upload(self, filename: str, data: bytes) -> MissionSummary:
        """Validate and keep a mission; Refused with the diagnostics when it is invalid."""
        self.save_ended()
        filename = filename or "mission.xml"
        result = _validate(filename, data)
        diagnostics = [d.to_dict() for d in result.diagnostics]
        if result.errors or result.mission is None:
            raise Refused(f"{filename}: invalid mission ({len(result.errors)} error(s))",
                          diagnostics=json_value(diagnostics))
        stored = StoredMission(secrets.token_hex(6), result.mission.name, filename,
                               result.source, time.time(), diagnostics)
        self.storage.add_mission(stored)
        self._keep(stored.id, result.mission, len(stored.source))
        return self._mission_summary(stored)

    def missions(self) -> list[MissionSummary]:
        """Every stored mission, summed up."""
        return [self._mission_summary(m) for m in self.storage.missions()]

    @_gives_memory_back
    def mission(self, mission_id: str) -> MissionDetail:
        """A mission: its summary, task tree, roles and world."""
        stored = self._stored_mission(mission_id)
        mission = self._parse(stored.id, stored.filename, stored.source)
        return MissionDetail(id=stored.id, name=stored.name, filename=stored.filename,
                             uploaded=stored.uploaded, warnings=_diagnostics(stored.warnings),
                             tasks=[_task(t) for t in mission.tasks],
                             roles=[_role(r) for r in mission.roles],
                             events=[_event(e) for e in mission.events],
                             world=world_outline(mission.world or World()))

    def mission_source(self, mission_id: str) -> str:
        """A mission's XML text as it was uploaded."""
        return self._stored_mission(mission_id).source

    @_gives_memory_back
    def delete_mission(self, mission_id: str) -> None:
        """Forget a mission (its past runs stay); Conflict while a run flies it."""
        with self._lock:
            flying = [r.id for r in self._live.values() if r.record.mission_id == mission_id]
        if flying:
            raise Conflict(f"mission {mission_id} is flying in run {flying[0]}")
        self.save_ended()
        if not self.storage.delete_mission(mission_id):
            raise NotFound(f"no mission {mission_id}")
        with self._lock:
            self._parsed.pop(mission_id, None)

    @_gives_memory_back
    def verify(self, mission_id: str, profile: str = "quadcopter",
               battery: float = 100.0) -> Report:
        """The ``tml verify`` report of a mission (:func:`report_document`: its JSON
        form)."""
        stored = self._stored_mission(mission_id)
        mission = self._parse(stored.id, stored.filename, stored.source)
        home = (mission.world or World()).home_or_default
        report = verify_mission(mission, _profile(profile), None,
                                PredictedState(battery=battery, heading=home.heading))
        return report

    # --- runs ----------------------------------------------------------------------------

    @_gives_memory_back
    def start_run(self, mission_id: str, vehicles: Sequence[int] | None = None, *,
                  safe_state: str = "rtl", profile: str = "quadcopter",
                  force: bool = False) -> RunView:
        """Start flying a mission; the run as :meth:`run` shows it."""
        self.save_ended()
        stored = self._stored_mission(mission_id)
        mission = self._parse(stored.id, stored.filename, stored.source)
        if safe_state not in SAFE_STATES:
            raise Refused(f"safe_state {safe_state!r}: expected one of {', '.join(SAFE_STATES)}")
        run_id = secrets.token_hex(6)
        chosen = self._choose(mission, vehicles, run_id)
        try:
            checked = self._clear(mission, stored.filename, profile, chosen, force)
            record = StoredRun(run_id, stored.id, stored.name, stored.source, list(chosen),
                               "waiting", "", [], None, self.options.instance,
                               {"safe_state": safe_state, "profile": profile,
                                "force": force}, time.time(), None)
            return self._launch(record, mission, checked, claimed=not vehicles)
        except BaseException:
            if not vehicles:  # the vehicles chosen for it were taken for it: free them
                self.hangar.release(run_id)
            raise

    @_gives_memory_back
    def continue_run(self, run_id: str) -> RunView:
        """Go on with a run the service was flying when it died (``interrupted``), as
        ``tml run --resume`` does from its log: a new run on the same vehicles, whose
        mission goes on where the stored log stood (:mod:`tml.engine.resume`). Refused
        (422) for a run that was not interrupted, was continued already, or has roles; 409
        when a vehicle is held."""
        self.save_ended()
        stored = self._stored_run(run_id)
        if stored.status != Ending.INTERRUPTED.status:
            raise Refused(f"run {run_id} is {stored.status}: only an interrupted run can be "
                          "continued")
        later = next((r.id for r in self.storage.runs()
                      if r.options.get("continues") == run_id), None)
        if later is not None:
            raise Refused(f"run {run_id} was continued already, as run {later}")
        mission = self._parse(f"run {stored.id}", "mission.xml", stored.mission_source)
        lines = [json.loads(line) for _, line in self.storage.lines(run_id)]
        try:
            point = progress_point(lines, mission, stored.vehicles)
        except ResumeRefused as refused:
            raise Refused(f"run {run_id}: {refused}") from None
        while self.ids.take() < point.next_id:  # its requests and plans are numbered on
            pass
        options = {**stored.options, "continues": run_id}
        record = StoredRun(secrets.token_hex(6), stored.mission_id, stored.mission_name,
                           stored.mission_source, list(stored.vehicles), "waiting", "", [],
                           None, self.options.instance, options, time.time(), None)
        checked = self._clear(mission, f"run {run_id}",
                              str(options.get("profile", "quadcopter")), stored.vehicles,
                              bool(options.get("force", False)))
        return self._launch(record, mission, checked, point.progress)

    def _clear(self, mission: Mission, filename: str, profile: str, vehicles: Sequence[int],
               force: bool) -> VehicleProfile:
        """The profile a run flies with, once :func:`tml.run.clearance.clear` cleared its
        mission for its vehicles, as ``tml run`` does: ``profile`` a shipped one, or
        ``vehicle``, the first vehicle's kind filled in from its own parameters. The GCS
        failsafe of every vehicle was read when the service opened it (or leased it).
        Refused (422) with the report, the violations or the reason when not cleared."""
        choice = None if profile == VEHICLE_PROFILE else _profile(profile)
        # A vehicle this service does not have (a continued run's) fails when it is flown,
        # as before there was a clearance here.
        found = Flight(mission, [self.hangar.vehicles[v] for v in vehicles
                                 if v in self.hangar.vehicles],
                       self.options.flight(force=force)).clear(choice)
        if not isinstance(found, NotCleared):
            return found.profile
        why = found.reason
        if isinstance(why, Infeasible):
            raise Refused(f"{filename}: infeasible mission, not flown (force flies it "
                          "anyway)", report=json_value(report_document(why.report)))
        if isinstance(why, Incapable):
            raise Refused(f"{filename}: the vehicles cannot do every action of the mission, "
                          "not flown (force flies it anyway)",
                          violations=json_value([v.to_dict() for v in why.violations]))
        if isinstance(why, NoParameters):
            raise Refused(f"profile 'vehicle': vehicle {why.vehicle_id} does not report its "
                          "parameters")
        raise Refused(f"{filename}: not cleared for flight ({found.refusal.value})")

    def _launch(self, record: StoredRun, mission: Mission, checked: VehicleProfile,
                resume: Mapping[int, Progress] | None = None,
                claimed: bool = False) -> RunView:
        """Hold the run's vehicles (unless ``claimed`` already), store it and start flying
        it."""
        if not claimed:
            try:
                self.hangar.claim(record.vehicles, record.id)
            except VehicleTaken as taken:
                raise Conflict(str(taken), vehicle=taken.vehicle_id,
                               run=taken.run_id) from None
        options = self.options.flight(safe_state=str(record.options.get("safe_state", "rtl")),
                                      force=bool(record.options.get("force", False)))
        try:
            self.storage.add_run(record)
            live = LiveRun(record, mission, self.hangar, self.storage, options, checked,
                           self.ids, on_end=self._ended, resume=resume)
        except BaseException:
            self.hangar.release(record.id)
            raise
        with self._lock:
            self._live[record.id] = live
        live.start()
        return self.run(record.id)

    def runs(self) -> list[RunView]:
        """Every run, summed up, the oldest first."""
        return [self._run_summary(r) for r in self.storage.runs()]

    @_gives_memory_back
    def run(self, run_id: str) -> RunView:
        """A run: status, outcome, exit code, every task's state per vehicle."""
        live = self.live(run_id)
        if live is not None:
            return self._run_summary(live.record, live, tasks=live.board.snapshot(),
                                     safety=list(live.safety))
        stored = self._stored_run(run_id)
        mission = self._parse(f"run {stored.id}", "mission.xml", stored.mission_source)
        board = TaskBoard(mission, stored.vehicles)
        safety: list[str] = []
        for _seq, line in self.storage.lines(run_id):
            record = json.loads(line)
            board.see(record)
            if record.get("kind") in ("safety", "taken"):
                safety.append(_safety_said(record))
        return self._run_summary(stored, tasks=board.snapshot(), safety=safety)

    def save_ended(self) -> None:
        """Store the ended runs the database could not take when they ended."""
        with self._lock:
            waiting = list(self._unsaved.values())
        for run in waiting:
            if run.save():
                with self._lock:
                    self._unsaved.pop(run.id, None)

    def abort(self, run_id: str, reason: str = "aborted by the operator") -> RunView:
        """Abort a live run: every vehicle to its safe state (``Ending.STOPPED``)."""
        if self._elsewhere(run_id, {"op": "abort"}):
            return self.run(run_id)
        live = self._live_run(run_id)
        live.abort(reason)
        return self.run(run_id)

    def control(self, run_id: str, kind: str, target: str = "") -> RunView:
        """Pause, resume or jump a live run: 409 when the run refuses now (not started,
        paused already ...), 422 when the language refuses the jump (with its ``code``)."""
        if self._elsewhere(run_id, {"op": "control", "kind": kind, "target": target}):
            return self.run(run_id)
        live = self._live_run(run_id)
        try:
            live.control(kind, target)
        except ControlRefused as refusal:
            if refusal.code:
                raise Refused(f"cannot jump to {target!r}: {refusal}", code=refusal.code
                              ) from None
            raise Conflict(f"cannot {kind} run {run_id}: {refusal}") from None
        return self.run(run_id)

    def carry_out(self, request: Forwarded) -> Answer:
        """A request another instance of the cluster forwarded about a run this one flies
        or a vehicle it leases (``op``: ``abort``, ``control`` or ``command``): its HTTP
        status, message and detail."""
        try:
            if request.get("op") == "command":
                answer, done = self.command(int(request["vehicle"]), str(request["command"]))
                return 200 if done else 202, answer.message, {
                    "run": answer.run, "outcome": answer.outcome, "seen": answer.seen}
            if request.get("op") == "abort":
                self.abort(str(request["run"]))
            elif request.get("op") == "control":
                self.control(str(request["run"]), str(request["kind"]),
                             str(request.get("target", "")))
            else:
                raise RequestError(f"unknown forwarded request {request.get('op')!r}")
        except RequestError as refused:
            return refused.status, refused.message, refused.detail
        return 200, "done", {}

    def _command_elsewhere(self, vehicle_id: int,
                           command: str) -> tuple[CommandAnswer, bool] | None:
        """In a cluster, an operator's command to a vehicle another instance leases:
        carried out there, and answered as it answered; None for a vehicle no other
        instance leases (tml.serve.cluster.ClusterHangar.owner_elsewhere)."""
        owner_elsewhere = getattr(self.hangar, "owner_elsewhere", None)
        owner = None if self.forward is None or owner_elsewhere is None \
            else owner_elsewhere(vehicle_id)
        if self.forward is None or owner is None:
            return None
        status, message, detail = self.forward(
            str(owner), {"op": "command", "vehicle": vehicle_id, "command": command})
        if status not in (200, 202):
            refused = RequestError(message, **detail)
            refused.status = status
            raise refused
        run = detail.get("run")
        outcome = detail.get("outcome", "done" if status == 200 else "not confirmed")
        return CommandAnswer(vehicle=vehicle_id, command=operator_command(command),
                             run=None if run is None else str(run),
                             outcome=answer_outcome(str(outcome)), confirmed=status == 200,
                             seen=str(detail.get("seen", "")), message=message,
                             vehicle_state=self.vehicle(vehicle_id)), status == 200

    def _elsewhere(self, run_id: str, request: Forwarded) -> bool:
        """Whether the run is flown by another instance of the cluster, which then
        carried out ``request`` (its refusal raised here as it gave it)."""
        if self.forward is None or self.live(run_id) is not None:
            return False
        stored = self.storage.run(run_id)
        if stored is None or stored.instance == self.options.instance \
                or stored.status not in ACTIVE:
            return False
        status, message, detail = self.forward(stored.instance, {**request, "run": run_id})
        if status != 200:
            refused = RequestError(message, **detail)
            refused.status = status
            raise refused
        return True

    def live(self, run_id: str) -> LiveRun | None:
        """The run if it is flying (or about to), or has ended and is not stored yet; else
        None."""
        with self._lock:
            return self._live.get(run_id) or self._unsaved.get(run_id)

    def log(self, run_id: str) -> Iterator[str]:
        """A run's flight log, line by line (the lines of ``tml run --log``)."""
        live = self.live(run_id)
        if live is not None:
            lines = list(live.log.lines)
        else:
            self._stored_run(run_id)
            lines = list(self.storage.lines(run_id))
        for _seq, line in lines:
            yield line + "\n"

    # --- vehicles ------------------------------------------------------------------------

    def vehicles(self) -> list[VehicleView]:
        """Every vehicle with its live telemetry, link and the run that holds it."""
        return [self.vehicle(vid) for vid in sorted(self.hangar.vehicles)]

    def vehicle(self, vehicle_id: int) -> VehicleView:
        """One vehicle."""
        found = self.hangar.vehicles.get(vehicle_id)
        if found is None:
            raise NotFound(f"no vehicle {vehicle_id}")
        state = found.state()
        home = None if state.home is None else HomeView(
            latitude=state.home.latitude, longitude=state.home.longitude,
            altitude=state.home.altitude)
        # The telemetry fields of the flight log's telemetry lines ("global" among them).
        return VehicleView(id=vehicle_id, run=self.hangar.holder(vehicle_id),
                           vehicle_type=state.vehicle_type, time=round(state.time, 3),
                           **telemetry_fields(state), home=home,
                           status_text=state.status_text, awaiting=list(awaiting(state)),
                           command=self._commands.get(vehicle_id))

    def command(self, vehicle_id: int, command: str) -> tuple[CommandAnswer, bool]:
        """An operator's command to a vehicle (rtl, land, hold, disarm), and whether it is
        confirmed: done only when the vehicle's telemetry shows it carried out, by the
        rule of ``tml command`` (:class:`~tml.engine.confirm.Confirmation`), within
        :attr:`ServiceOptions.command_timeout` wall seconds; else not confirmed, with
        what was seen.

        Refused (409) with the reason when the rule of
        :func:`tml.engine.safety.operator_request` refuses it (a disarm in the air ...).
        A vehicle held by a run: the operator takes it over through the run: ``hold``
        pauses the run (every vehicle of it holds), the others end it into that safe
        state (a disarm, on the ground: into its own, which disarms a vehicle on the
        ground), ``taken`` (``Ending.OPERATOR``); once it has ended, the command is sent
        again should the vehicle not show it. A free vehicle is held for the command (no
        run takes it meanwhile) until it is confirmed or not, sent the request (``hold``:
        the mode that holds by itself, :func:`~tml.engine.safety.holding_mode`); refused
        by the vehicle or unanswered: 409.
        """
        from tml.engine.safety import CommandRefusal, operator_command_shown, operator_request

        found = self.hangar.vehicles.get(vehicle_id)
        if found is None:
            raise NotFound(f"no vehicle {vehicle_id}")
        elsewhere = self._command_elsewhere(vehicle_id, command)
        if elsewhere is not None:
            return elsewhere
        try:
            operator_request(found.state(), command)
        except CommandRefusal as refusal:
            self._tell(vehicle_id, command, "refused", str(refusal))
            raise Conflict(f"vehicle {vehicle_id}: {command} refused: {refusal}") from None
        # (operator_request refuses any other word than an operator command's)
        asked = Asked(vehicle_id, operator_command(command))
        holder = self.hangar.holder(vehicle_id)
        live = self.live(holder) if holder is not None else None
        if live is not None and not live.ended:
            asked.run = live.id
            check = MotionCheck(found, command, self._fresh_targets(vehicle_id, found))
            said = self._through_run(live, command)
            self._tell(vehicle_id, command, "sent", said)
            # Done once the telemetry confirms it and (rtl, land, disarm) the run has ended.
            ending = None if live.runner.paused and command == "hold" else live
            self._confirm(check, ending)
            if check.confirmed or not live.ended \
                    or operator_command_shown(found.state(), command):
                return self._answered(asked, check, said)
        outcome = self._send(found, vehicle_id, command)
        if isinstance(outcome, str):
            return self._answer(asked, "nothing to do", outcome,
                                f"vehicle {vehicle_id}: nothing to do: {outcome}"), True
        return self._answered(asked, *outcome)

    def _through_run(self, live: LiveRun, command: str) -> str:
        """Carry out an operator's command through the run that holds the vehicle: a hold
        pauses it (ended into hold when it cannot pause: not started yet), another command
        ends it into that state; what was done."""
        reason = f"operator command: {command}"
        if command == "hold":
            try:
                live.control("pause", reason=reason)
            except ControlRefused:
                if not live.runner.paused:
                    live.take_over(command)
                    return f"run {live.id} ends into hold (it could not pause)"
            return f"run {live.id} paused"
        live.take_over(command)
        return f"run {live.id} ends into {command}"

    def _fresh_targets(self, vehicle_id: int, vehicle: Vehicle) -> TargetWatch | None:
        """The GUIDED targets the vehicle reports from now on (its system id on its link
        may differ from the service's vehicle id)."""
        return self._targets.fresh(vehicle_id, vehicle,
                                   int(getattr(vehicle, "system_id", vehicle_id)))

    def _confirm(self, check: MotionCheck, ending: LiveRun | None = None) -> None:
        """Look at the vehicle until its telemetry confirms the command (and ``ending``,
        when given, has ended), for up to the command's timeout."""
        wake = threading.Event()
        self.hangar.subscribe(wake)
        end = time.monotonic() + self.options.command_timeout
        try:
            while not (check.look() and (ending is None or ending.ended)) \
                    and time.monotonic() < end:
                self.hangar.wait(wake, CONFIRM_PERIOD)
        finally:
            self.hangar.unsubscribe(wake)

    def _answered(self, asked: Asked, check: MotionCheck,
                  said: str) -> tuple[CommandAnswer, bool]:
        """The answer to a command sent (``said``: how), confirmed or not."""
        confirmation, command, vehicle_id = check.confirmation, asked.command, asked.vehicle
        seen = confirmation.seen()
        if check.confirmed:
            self._tell(vehicle_id, command, "done", seen)
            message = f"vehicle {vehicle_id}: {command} done ({said}): {seen}"
        else:
            detail = f"wanted {confirmation.criterion()}; seen {seen}"
            self._tell(vehicle_id, command, "not confirmed", detail)
            message = (f"vehicle {vehicle_id}: {command} not confirmed within "
                       f"{self.options.command_timeout:g} s ({said}; {detail})")
        return self._answer(asked, "done" if check.confirmed else "not confirmed", seen,
                            message), check.confirmed

    def _answer(self, asked: Asked, outcome: AnswerOutcome, seen: str,
                message: str) -> CommandAnswer:
        return CommandAnswer(vehicle=asked.vehicle, command=asked.command, run=asked.run,
                             outcome=outcome, confirmed=outcome != "not confirmed", seen=seen,
                             message=message, vehicle_state=self.vehicle(asked.vehicle))

    def _send(self, found: Vehicle, vehicle_id: int,
              command: str) -> tuple[MotionCheck, str] | str:
        """Send an operator's command to a vehicle no run holds, wait for its answer and
        for the telemetry to confirm it (holding the vehicle meanwhile); the confirmation
        and what was sent, or (nothing to do) where the vehicle is."""
        from dataclasses import replace

        from tml.engine.safety import CommandRefusal, holding_mode, operator_request
        from tml.vehicle import SetMode

        holder = f"command {secrets.token_hex(3)}"
        try:
            self.hangar.claim([vehicle_id], holder)
        except VehicleTaken as taken:
            self._tell(vehicle_id, command, "refused", f"not sent: {taken}")
            raise Conflict(f"vehicle {vehicle_id}: {command} not sent: {taken}",
                           run=taken.run_id) from None
        wake = threading.Event()
        self.hangar.subscribe(wake)
        try:
            state = found.state()
            try:
                request = operator_request(state, command)
            except CommandRefusal as refusal:
                self._tell(vehicle_id, command, "refused", str(refusal))
                raise Conflict(f"vehicle {vehicle_id}: {command} refused: {refusal}") from None
            if request is None:
                self._tell(vehicle_id, command, "done", "nothing to do")
                return f"{state.mode}, on the ground, disarmed"
            sent = request.name
            if command == "hold":  # a mode that holds by itself (nothing keeps a target)
                request = SetMode(vehicle_id, holding_mode(state))
                sent = f"{request.name} {request.mode}"
            check = MotionCheck(found, command, self._fresh_targets(vehicle_id, found))
            request = replace(request, request_id=self.ids.take())
            found.submit(request)
            self._tell(vehicle_id, command, "sent", sent)
            end = time.monotonic() + self.options.command_timeout
            while True:
                result = next((r for r in found.poll() if r.request_id == request.request_id),
                              None)
                if result is not None:
                    break
                if time.monotonic() >= end:
                    self._tell(vehicle_id, command, "unanswered", sent)
                    raise Conflict(f"vehicle {vehicle_id}: {command}: no answer within "
                                   f"{self.options.command_timeout:g} s")
                self.hangar.wait(wake, CONFIRM_PERIOD)
            if not result.ok:
                detail = f"{result.reason} {result.detail}".strip()
                self._tell(vehicle_id, command, "refused", f"by the vehicle: {detail}")
                raise Conflict(f"vehicle {vehicle_id}: {command} refused by the vehicle: "
                               f"{detail}")
            self._tell(vehicle_id, command, "accepted", sent)
            self._confirm(check)
            return check, sent
        finally:
            self.hangar.unsubscribe(wake)
            self.hangar.release(holder)

    def _tell(self, vehicle_id: int, command: str, outcome: CommandOutcome,
              detail: str) -> None:
        """Keep a vehicle's last operator command (GET /vehicles shows it) and log it (a
        word that is no command, refused, is only logged)."""
        import logging

        with contextlib.suppress(ValueError):
            self._commands[vehicle_id] = OperatorCommandSeen(
                command=operator_command(command), outcome=outcome, detail=detail,
                at=time.time())
        logging.getLogger("tml.serve").warning("vehicle %d: operator command %s: %s (%s)",
                                               vehicle_id, command, outcome, detail)

    # --- helpers -------------------------------------------------------------------------

    def _choose(self, mission: Mission, vehicles: Sequence[int] | None,
                run_id: str) -> list[int]:
        """The vehicles named, or (none named) the free ones the run takes, held for
        ``run_id`` at once."""
        if vehicles:
            chosen = list(dict.fromkeys(vehicles))
            unknown = [v for v in chosen if v not in self.hangar.vehicles]
            if unknown:
                raise Refused(f"no vehicle {unknown[0]} (vehicles: "
                              f"{', '.join(map(str, sorted(self.hangar.vehicles)))})")
            return chosen
        free = self.hangar.claim_free(run_id, every=bool(mission.roles))
        if not free:
            raise Conflict("every vehicle is held by a run")
        return free

    def _ended(self, run: LiveRun) -> None:
        with self._lock:
            self._live.pop(run.id, None)
            if not run.saved:
                self._unsaved[run.id] = run

    def _parse(self, key: str, filename: str, source: str) -> Mission:
        """The mission of a stored text: parsed again, unless it is small and was parsed
        lately (a large one is not kept: a stored mission is its text in the database)."""
        with self._lock:
            found = self._parsed.get(key)
            if found is not None:
                self._parsed.move_to_end(key)
        if found is None:
            result = _validate(filename, source.encode("utf-8"))
            if result.mission is None:  # stored valid: only a change of the rules does this
                raise Conflict(f"{filename} is no longer valid: "
                               + "; ".join(d.message for d in result.errors[:3]))
            found = result.mission
            self._keep(key, found, len(source))
        return found

    def _keep(self, key: str, mission: Mission, size: int) -> None:
        """Keep a small mission parsed, the last ``KEPT_MISSIONS`` of them."""
        if size > KEPT_SOURCE:
            return
        with self._lock:
            self._parsed[key] = mission
            self._parsed.move_to_end(key)
            while len(self._parsed) > KEPT_MISSIONS:
                self._parsed.popitem(last=False)

    def _stored_mission(self, mission_id: str) -> StoredMission:
        found = self.storage.mission(mission_id)
        if found is None:
            raise NotFound(f"no mission {mission_id}")
        return found

    def _stored_run(self, run_id: str) -> StoredRun:
        found = self.storage.run(run_id)
        if found is None:
            raise NotFound(f"no run {run_id}")
        return found

    def _live_run(self, run_id: str) -> LiveRun:
        live = self.live(run_id)
        if live is not None and live.ended:
            raise Conflict(f"run {run_id} has ended ({live.status})", run_status=live.status)
        if live is None:
            stored = self._stored_run(run_id)
            if stored.instance != self.options.instance and stored.status in ACTIVE:
                raise Conflict(f"run {run_id} is flown by the service instance "
                               f"{stored.instance!r}, not this one ({self.options.instance!r})",
                               instance=stored.instance)
            raise Conflict(f"run {run_id} has ended ({stored.status})", run_status=stored.status)
        return live

    @staticmethod
    def _mission_summary(stored: StoredMission) -> MissionSummary:
        return MissionSummary(id=stored.id, name=stored.name, filename=stored.filename,
                              uploaded=stored.uploaded, warnings=_diagnostics(stored.warnings))

    @staticmethod
    def _run_summary(stored: StoredRun, live: LiveRun | None = None, *,
                     tasks: dict[str, dict[str, str]] | None = None,
                     safety: list[str] | None = None) -> RunView:
        """A run as it is stored, or as it stands when it is ``live``; ``tasks`` and
        ``safety`` (:meth:`run`) when given."""
        outcomes = live.outcomes if live is not None else stored.outcomes
        return RunView(
            id=stored.id, mission=MissionRef(id=stored.mission_id, name=stored.mission_name),
            vehicles=stored.vehicles,
            status=run_status(live.status if live is not None else stored.status),
            reason=live.reason if live is not None else stored.reason,
            outcomes=[VehicleOutcome.model_validate(o) for o in outcomes],
            exit_code=live.exit_code if live is not None else stored.exit_code,
            instance=stored.instance, options=stored.options, created=stored.created,
            ended=stored.ended if live is None else live.ended_at, tasks=tasks, safety=safety)


def _safety_said(record: Mapping[str, Any]) -> str:
    """What a ``safety`` or ``taken`` line of a flight log says was done, as a live run
    says it: "vehicle 1: RTL (aborted by the operator)"."""
    message = str(record.get("message", ""))
    vehicle = record.get("vehicle")
    if vehicle is None or message.startswith(f"vehicle {vehicle} "):
        return message
    return f"vehicle {vehicle}: {message}"


def _profile(name: str) -> VehicleProfile:
    """A shipped profile by name (``vehicle`` is a run's, read from its vehicle)."""
    if name not in SHIPPED:
        raise Refused(f"profile {name!r}: expected one of {', '.join(SHIPPED)}")
    return load_profile(name)


def _diagnostics(found: Sequence[object]) -> list[Diagnostic]:
    """Diagnostics stored with a mission (:meth:`Diagnostic.to_dict`'s form)."""
    return [Diagnostic.model_validate(d) for d in found]


def _task(task: Task) -> TaskOutline:
    return TaskOutline(name=task.name, path=task.path_name, line=task.location.line,
                       action=task.action.name if task.action is not None else None,
                       role=task.role, composition=task.composition.value,
                       children=[_task(t) for t in task.children],
                       on_error=[_task(t) for t in task.on_error])


def _role(role: Role) -> RoleOutline:
    return RoleOutline(name=role.name, count=role.count, vehicle_type=role.vehicle_type,
                       payloads=list(role.payloads))


def _event(event: Event) -> EventOutline:
    return EventOutline(name=event.name, line=event.location.line,
                        termination=event.termination.mode.value)


def world_outline(world: World) -> WorldOutline:
    """A world in plain values: home, geofence, obstacles and objects in the local frame
    (north, east metres from home; an unbounded top is null)."""
    home = world.home_or_default
    fence = world.geofence
    obstacles: list[CylinderOutline | PrismOutline] = []
    for obstacle in world.obstacles:
        top = None if math.isinf(obstacle.top) else obstacle.top
        if isinstance(obstacle, Cylinder):
            obstacles.append(CylinderOutline(
                name=obstacle.name, bottom=obstacle.bottom, top=top, shape="cylinder",
                north=obstacle.north, east=obstacle.east, radius=obstacle.radius))
        else:
            obstacles.append(PrismOutline(name=obstacle.name, bottom=obstacle.bottom, top=top,
                                          shape="prism",
                                          polygon=[list(p) for p in obstacle.polygon]))
    return WorldOutline(
        home=HomeOutline(latitude=home.latitude, longitude=home.longitude,
                         altitude=home.altitude, heading=home.heading,
                         declared=world.home is not None),
        geofence=None if fence is None else FenceOutline(
            polygon=[list(p) for p in fence.polygon], min_altitude=fence.min_altitude,
            max_altitude=fence.max_altitude),
        obstacles=obstacles,
        objects=[ObjectOutline(kind=o.kind, ident=o.ident, north=o.north, east=o.east,
                               altitude=o.altitude, color=o.color, name=o.name)
                 for o in world.objects])
