"""A flight as its log tells it: tracks, tasks, events, autopilot messages, the outcome.

:func:`read_flight` reads a flight log (:mod:`tml.run.journal`, one JSON object per line;
its one reader, :func:`~tml.run.journal.read_log`) as typed records
(:mod:`tml.engine.flightlog`) into a :class:`Flight`. Lines of kinds it does not know, or
without their kind's fields, are passed over; a log of a later version is refused.
The planned path comes from the mission file the log names
(:mod:`tml.plans.planned`: the path its mission items fly), when that file is still there
and valid; a report is drawn without it otherwise.

*Time.* A report speaks in mission time, as the live view and the log's ``mission_time``
do: :attr:`Flight.origin` is where the mission started on the log's clock ``t`` (from the
lines' ``mission_time``, or, in a log written before they had it, from the line that says
the mission started), and every time shown is ``t`` less it. A log whose mission never
started counts from the run's start.

*Tasks* are kept in tree order -- a task, then the tasks it ran, each vehicle's under the
task it flew them in -- whatever order they started in: in a fleet, the sorties of two
vehicles start side by side, and sorting them by start put one's sub-tasks under the
other.

*Event handlers' actions* are spans too (:attr:`TaskSpan.event` names the event whose handler
flew them), from the ``action`` lines of no task: a landing an event commands is on the
timeline and in the table beside the task it cut short, and sorted after the mission's
tasks.

*Rounds.* A task run again under the same run of its parent (a repeat's or a loop's next
round) is numbered (:attr:`TaskSpan.round`): the second "North-west corner" of a patrol is
round 2 of the repeat, and what it did explains a task done right after an aborted one.
Siblings are listed round by round, each round's tasks in the order they first started,
and the vehicles of a fleet by number: whichever vehicle began a task first, vehicle 1's
run of it comes before vehicle 2's.

*Photos and detections* (:attr:`Flight.spots`): where a vehicle took a photo (an action
line of CAPTURE_PHOTO, CAPTURE_PHOTOS or START_CAPTURING; in an autopilot plan, the task
of such an action of the mission file when it ran) and where a detection appeared in its
telemetry (a name of ``detections`` with a new value).

*Autopilot messages* keep their severity, except a reason not to arm, which ArduPilot says
only while disarmed (ArduCopter's ``PreArm: Mode not armable`` after every landing):
shown as info (:func:`tml.vehicle.shown_severity`) with the severity it was said with.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tml.engine.flightlog import (
    ActionLine,
    AutopilotLine,
    DecisionLine,
    ErrorLine,
    EventLine,
    MissionLine,
    PickLine,
    RunLine,
    SafetyLine,
    TaskLine,
    TelemetryLine,
    UnknownKind,
    parse,
)
from tml.errors import TmlError
from tml.run.journal import LogUnreadable, read_log
from tml.vehicle import SEVERITIES, shown_severity


class LogError(TmlError):
    """A flight log that cannot be read (says where and why)."""


@dataclass(frozen=True)
class Sample:
    """One telemetry line of a vehicle."""

    t: float
    north: float
    east: float
    up: float
    latitude: float | None
    longitude: float | None
    altitude: float | None  # AMSL, m
    battery: float | None
    mode: str
    armed: bool
    wall: str = ""  # the wall-clock time of the line (ISO 8601), "" in an older log


@dataclass
class TaskSpan:
    """A task as it ran on a vehicle (None: a task no vehicle flies): from ``start`` to
    ``end`` (None while it still ran when the log ended), and how it ended."""

    task: str
    vehicle: int | None
    start: float
    end: float | None = None
    state: str = "running"
    event: str = ""
    """For an event handler's action: the event (``task`` is then the action's name)."""
    round: int = 0
    """Which run of the task under the same run of its parent this is, from 1, when its
    parent ran some of its tasks more than once (a repeat, a loop); 0 otherwise."""
    rounds: int | None = None
    """The rounds its parent was to fly (a repeat's ``times``), when the log says."""


PHOTO_ACTIONS = frozenset({"CAPTURE_PHOTO", "CAPTURE_PHOTOS", "START_CAPTURING"})
"""The actions that take photos: each is a photo spot where it started."""


@dataclass(frozen=True)
class Spot:
    """Something seen or taken at ``t`` where a vehicle was: ``kind`` "photo" (the action's
    name as ``text``) or "detection" (``name: value``)."""

    t: float
    vehicle: int
    kind: str
    text: str


@dataclass(frozen=True)
class Mark:
    """Something that happened at ``t``: an event fired, an autopilot message, a safety
    step; ``severity`` for autopilot messages."""

    t: float
    vehicle: int | None
    kind: str  # "event", "autopilot", "safety", "error"
    text: str
    severity: str = ""  # as shown: a reason not to arm said disarmed is "info"
    said: str = ""  # the severity the autopilot said, when it is not the one shown
    wall: str = ""  # the wall-clock time of the line (ISO 8601), "" in an older log


@dataclass
class Flight:
    """Everything a report shows of one run."""

    file: str  # the log's path
    mission: str = ""
    mission_file: str = ""
    start: float = 0.0
    end: float = 0.0
    tracks: dict[int, list[Sample]] = field(default_factory=dict)
    tasks: list[TaskSpan] = field(default_factory=list)
    marks: list[Mark] = field(default_factory=list)
    outcomes: list[dict[str, Any]] = field(default_factory=list)
    exit_code: int | None = None
    planned: dict[str, list[tuple[float, float, float]]] = field(default_factory=dict)
    """Planned path (north, east, up) by role ("" for a mission without roles)."""
    obstacles: list[list[tuple[float, float]]] = field(default_factory=list)
    geofence: list[tuple[float, float]] = field(default_factory=list)
    mission_start: float | None = None
    """Where the mission started on the log's clock ``t``; None if it never did."""
    walls: tuple[str, str] = ("", "")
    """The wall-clock times of the first and last lines (ISO 8601), "" in an older log."""
    spots: list[Spot] = field(default_factory=list)
    picked: dict[str, list[int]] = field(default_factory=dict)
    """The vehicles each role was flown by, in the order they were picked."""
    world_home: tuple[float, float, float] | None = None
    """The home the mission file declares (latitude, longitude, altitude AMSL): where its
    planned path, obstacles and geofence are, in metres from it."""
    photo_tasks: set[str] = field(default_factory=set)
    """The tasks of the mission file that take photos (their paths)."""

    @property
    def origin(self) -> float:
        """Where time 0 of the report is on the log's clock: the mission's start, or the
        run's when the mission never started."""
        return self.start if self.mission_start is None else self.mission_start

    @property
    def time_label(self) -> str:
        """What the report's times count."""
        return "time since the run started (s)" if self.mission_start is None \
            else "mission time (s): since the first task started"

    @property
    def vehicles(self) -> list[int]:
        """The vehicles the log has telemetry of."""
        return sorted(self.tracks)

    @property
    def outcome(self) -> str:
        """One line: how the run ended on each vehicle, each outcome once, the vehicles it
        is theirs named together, by number."""
        if not self.outcomes:
            return "the log ends before the run did"
        said: dict[str, list[str]] = {}
        for o in sorted(self.outcomes, key=_by_vehicle):
            said.setdefault(f"{o.get('status')} ({o.get('reason')})", []).append(
                str(o.get("vehicle")))
        return "; ".join(f"vehicle{'s' if len(ids) > 1 else ''} {', '.join(ids)}: {what}"
                         for what, ids in said.items())


def _by_vehicle(outcome: dict[str, Any]) -> tuple[float, str]:
    vehicle = outcome.get("vehicle")
    return (vehicle, "") if isinstance(vehicle, int) else (math.inf, str(vehicle))


def read_flight(path: str) -> Flight:
    """The flight of the log at ``path`` (read by :func:`tml.run.journal.read_log`: a last
    line cut short is left out, a log of a later version refused); OSError when it cannot
    be opened, LogError when a line is not JSON or the file is no flight log."""
    flight = Flight(path)
    reading = _Reading()
    try:
        log = read_log(path)
    except LogUnreadable as error:
        raise LogError(str(error)) from None
    for line in log.lines:
        _take(flight, line, reading)
    if not flight.tracks and not flight.tasks and not flight.mission:
        raise LogError(f"{path}: no run in this log (not a tml flight log?)")
    flight.tracks = dict(sorted(flight.tracks.items()))
    flight.outcomes.sort(key=_by_vehicle)
    _plan(flight)
    _photo_tasks(flight)
    flight.tasks = tree_order(flight.tasks)
    for span in flight.tasks:
        if span.round:
            span.rounds = reading.repeats.get(span.task.rsplit("/", 1)[0])
    flight.spots.sort(key=lambda spot: (spot.t, spot.vehicle))
    return flight


@dataclass
class _Reading:
    """What the reading of a log keeps between its lines."""

    open_tasks: dict[tuple[str, int | None], TaskSpan] = field(default_factory=dict)
    open_actions: dict[int | None, TaskSpan] = field(default_factory=dict)  # a handler's
    fired: dict[int | None, str] = field(default_factory=dict)  # each vehicle's last event
    seen: dict[tuple[int, str], object] = field(default_factory=dict)  # detections
    repeats: dict[str, int] = field(default_factory=dict)  # a repeat's times, by task


ROUND = re.compile(r": repeat \d+ of (\d+)$")
"""A repeat's decision to fly another round says how many it flies in all."""


def tree_order(spans: list[TaskSpan]) -> list[TaskSpan]:
    """The spans in tree order: each task, then the tasks it ran, a vehicle's under the
    run of the task it flew them in (its own, else the fleet's); the tasks under one run
    of a task round by round (a task run again there begins the next round), each round's
    in the order the tasks first started and each task's vehicles by number; the event
    handlers' actions after the mission's tasks, by vehicle, each's in the order they
    started. Numbers the
    rounds (:attr:`TaskSpan.round`)."""
    children: dict[int, list[TaskSpan]] = {}
    roots: list[TaskSpan] = []
    for index, span in enumerate(spans):
        parent = None if span.event else _parent(spans[:index], span)
        if parent is None:
            roots.append(span)
        else:
            children.setdefault(id(parent), []).append(span)
    ordered: list[TaskSpan] = []

    def walk(found: list[TaskSpan]) -> None:
        for span in _rounds(found):
            ordered.append(span)
            walk(children.get(id(span), []))

    walk(roots)
    return ordered


def _rounds(siblings: list[TaskSpan]) -> list[TaskSpan]:
    """Siblings (in the order they started) sorted as :func:`tree_order` says, their
    rounds numbered when there are several."""
    first: dict[str, int] = {}  # each task's place: the order they first started in
    runs: dict[tuple[str, int | None], int] = {}
    keyed: list[tuple[tuple[float, ...], TaskSpan]] = []
    for order, span in enumerate(siblings):
        if span.event:
            keyed.append(((math.inf, _number(span.vehicle), span.start, order), span))
            continue
        place = first.setdefault(span.task, len(first))
        done = runs[span.task, span.vehicle] = runs.get((span.task, span.vehicle), 0) + 1
        span.round = done
        keyed.append(((done, place, _number(span.vehicle), order), span))
    if max(runs.values(), default=0) < 2:
        for span in siblings:
            span.round = 0
    return [span for _, span in sorted(keyed, key=lambda found: found[0])]


def _number(vehicle: int | None) -> float:
    """A vehicle's place in a list: by number, tasks no vehicle flies first."""
    return -1.0 if vehicle is None else float(vehicle)


def _parent(before: list[TaskSpan], span: TaskSpan) -> TaskSpan | None:
    """The run of the task around ``span`` it began in: the latest begun before it, of the
    same vehicle if there is one, else of none (a task no vehicle flies)."""
    if "/" not in span.task:
        return None
    path = span.task.rsplit("/", 1)[0]
    found: TaskSpan | None = None
    for candidate in reversed(before):
        if candidate.event or candidate.task != path or candidate.start > span.start:
            continue
        if candidate.vehicle == span.vehicle:
            return candidate
        if candidate.vehicle is None and found is None:
            found = candidate
    return found


def _take(flight: Flight, line: dict[str, Any], reading: _Reading) -> None:
    """One line of the log: its times, then what its record (typed) tells."""
    t = float(line["t"])
    flight.end = max(flight.end, t)
    wall = str(line.get("wall") or "")
    if wall:
        flight.walls = (flight.walls[0] or wall, wall)
    try:
        record = parse(line)
    except (UnknownKind, TypeError):  # a later kind, or a line without its fields
        return
    vehicle = record.vehicle
    mission_time = record.mission_time
    if flight.mission_start is None and isinstance(mission_time, (int, float)):
        flight.mission_start = t - float(mission_time)
    elif flight.mission_start is None and isinstance(record, MissionLine):
        # A log without mission_time.
        flight.mission_start = t - (float(record.elapsed) if record.elapsed is not None
                                    else 0.0)
    if isinstance(record, RunLine) and record.mission is not None:
        flight.mission, flight.mission_file, flight.start = (
            str(record.mission), str(record.file or ""), t)
    elif isinstance(record, RunLine) and record.exit_code is not None:
        flight.exit_code = int(record.exit_code)
        flight.outcomes = list(record.outcomes or [])
    elif isinstance(record, TelemetryLine) and record.position and vehicle is not None:
        _sample(flight, record, int(vehicle), t, wall, reading)
    elif isinstance(record, TaskLine):
        key = (record.task, vehicle)
        open_tasks = reading.open_tasks
        if record.state == "running":
            open_tasks[key] = span = TaskSpan(key[0], vehicle, t)
            flight.tasks.append(span)
        elif key in open_tasks:
            span = open_tasks.pop(key)
            span.end, span.state = t, record.state
        else:  # ended without running (skipped)
            flight.tasks.append(TaskSpan(key[0], vehicle, t, t, record.state))
    elif isinstance(record, ActionLine):
        _action(flight, record, vehicle, t, reading)
    elif isinstance(record, DecisionLine) and isinstance(record.iteration, int):
        found = ROUND.search(record.message)
        if found:
            reading.repeats[str(record.task)] = int(found.group(1))
    elif isinstance(record, PickLine):
        picked = flight.picked.setdefault(record.role, [])
        picked.extend(v for v in record.vehicles or [] if v not in picked)
    elif isinstance(record, EventLine):
        reading.fired[vehicle] = record.event
        flight.marks.append(Mark(t, vehicle, "event", record.event, wall=wall))
    elif isinstance(record, AutopilotLine):
        text, said = record.text, record.severity
        shown = said
        if said in SEVERITIES:
            level = shown_severity(SEVERITIES.index(said), text)
            shown = SEVERITIES[level]
        flight.marks.append(Mark(t, vehicle, "autopilot", text, shown,
                                 said if shown != said else "", wall))
    elif isinstance(record, (SafetyLine, ErrorLine)):
        flight.marks.append(Mark(t, vehicle, record.kind, record.message, wall=wall))


def _sample(flight: Flight, record: TelemetryLine, vehicle: int, t: float, wall: str,
            reading: _Reading) -> None:
    """A telemetry line: a sample of the vehicle's track, and the detections new in it."""
    north, east, up = (float(v) for v in record.position or ())
    where = record.global_ or (None, None, None)
    battery = record.battery
    flight.tracks.setdefault(vehicle, []).append(Sample(
        t, north, east, up, where[0], where[1], where[2],
        None if battery is None else float(battery), str(record.mode or ""),
        bool(record.armed), wall))
    detections = record.detections
    if not isinstance(detections, dict):
        return
    for name, value in detections.items():
        before = reading.seen.get((vehicle, name))
        reading.seen[vehicle, name] = value
        if value not in (None, "", [], {}) and value != before:
            shown = ", ".join(map(str, value)) if isinstance(value, list) else str(value)
            flight.spots.append(Spot(t, vehicle, "detection", f"{name}: {shown}"))
    for name in [n for v, n in reading.seen if v == vehicle and n not in detections]:
        del reading.seen[vehicle, name]


def _action(flight: Flight, record: ActionLine, vehicle: Any, t: float,
            reading: _Reading) -> None:
    """An action line: a photo taken, or an event handler's action begun or ended."""
    name, started = record.action or "", record.arguments is not None
    if started and name in PHOTO_ACTIONS and isinstance(vehicle, int):
        flight.spots.append(Spot(t, vehicle, "photo", name))
    if record.task is not None:
        return
    if started:  # a handler's action (a task's names its task)
        begun = TaskSpan(name, vehicle, t, event=reading.fired.get(vehicle, "?"))
        reading.open_actions[vehicle] = begun
        flight.tasks.append(begun)
        return
    span = reading.open_actions.get(vehicle)
    if span is None or span.task != name:
        return
    message = record.message
    state = "done" if message == f"{name} done" else "failed" if record.reason is not None \
        else "aborted" if record.why is not None else ""
    if state:
        span.end, span.state = t, state
        del reading.open_actions[vehicle]


def _photo_tasks(flight: Flight) -> None:
    """The photos of an autopilot plan: a task of the mission file that takes photos, run
    with no action line of its own (a plan's tasks are told by the items flown)."""
    said = {(s.vehicle, round(s.t, 3)) for s in flight.spots if s.kind == "photo"}
    for span in flight.tasks:
        if span.task in flight.photo_tasks and isinstance(span.vehicle, int) \
                and span.state == "done" and (span.vehicle, round(span.start, 3)) not in said:
            flight.spots.append(Spot(span.start, span.vehicle, "photo",
                                     span.task.rsplit("/", 1)[-1]))


def _plan(flight: Flight) -> None:
    """The planned paths, obstacles and geofence of the mission file the log names."""
    if not flight.mission_file or not Path(flight.mission_file).is_file():
        return
    from tml.geo import to_local
    from tml.language.actions import lookup
    from tml.language.validation import validate_file
    from tml.plans.maps import outline
    from tml.plans.planned import PlanError, plan_mission

    try:
        result = validate_file(flight.mission_file)
    except OSError:
        return
    mission = result.mission
    if mission is None or result.errors:
        return
    for task in mission.walk():
        spec = lookup(task.action.name) if task.action is not None else None
        if spec is not None and spec.name in PHOTO_ACTIONS:
            flight.photo_tasks.add(task.path_name)
    roles: list[str | None] = [r.name for r in mission.roles] or [None]
    for role in roles:
        try:
            plan = plan_mission(mission, role)
        except PlanError:
            continue
        home = plan.home
        flight.planned[role or ""] = [
            to_local(lat, lon, alt, home.latitude, home.longitude, home.altitude)
            for lat, lon, alt in plan.path()]
    world = mission.world
    if world is None:
        return
    if world.home is not None:
        flight.world_home = (world.home.latitude, world.home.longitude, world.home.altitude)
    for obstacle in world.obstacles:
        corners = outline(obstacle)
        flight.obstacles.append([*corners, corners[0]])
    if world.geofence is not None and world.geofence.polygon:
        flight.geofence = [*world.geofence.polygon, world.geofence.polygon[0]]
