"""A flight as its log tells it: tracks, tasks, events, autopilot messages, the outcome.

:func:`read_flight` reads a flight log (:mod:`tml.run.journal`, one JSON object per line)
into a :class:`Flight`. Lines of kinds it does not know are passed over, so that a log of
a later version still reads. The planned path comes from the mission file the log names
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

*Autopilot messages* keep their severity, except a reason not to arm, which ArduPilot says
only while disarmed (ArduCopter's ``PreArm: Mode not armable`` after every landing):
shown as info (:func:`tml.vehicle.shown_severity`) with the severity it was said with.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tml.errors import TmlError
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
        """One line: how the run ended on each vehicle."""
        if not self.outcomes:
            return "the log ends before the run did"
        return "; ".join(f"vehicle {o.get('vehicle')}: {o.get('status')} ({o.get('reason')})"
                         for o in self.outcomes)


def read_flight(path: str) -> Flight:
    """The flight of the log at ``path``; OSError when it cannot be opened, LogError when a
    line is not JSON or the file is no flight log."""
    flight = Flight(path)
    open_tasks: dict[tuple[str, int | None], TaskSpan] = {}
    with open(path, encoding="utf-8") as stream:
        for number, text in enumerate(stream, start=1):
            if not text.strip():
                continue
            try:
                line = json.loads(text)
            except json.JSONDecodeError as error:
                raise LogError(f"{path}:{number}: not a JSON line: {error.msg}") from None
            if not isinstance(line, dict) or "kind" not in line or "t" not in line:
                raise LogError(f"{path}:{number}: not a flight log line (no 't' and 'kind')")
            _take(flight, line, open_tasks)
    if not flight.tracks and not flight.tasks and not flight.mission:
        raise LogError(f"{path}: no run in this log (not a tml flight log?)")
    flight.tasks = tree_order(flight.tasks)
    _plan(flight)
    return flight


def tree_order(spans: list[TaskSpan]) -> list[TaskSpan]:
    """The spans in tree order: each task, then the tasks it ran (in the order they
    started), a vehicle's under the run of the task it flew them in (its own, else the
    fleet's), whatever order they started in."""
    children: dict[int, list[TaskSpan]] = {}
    roots: list[TaskSpan] = []
    for index, span in enumerate(spans):
        parent = _parent(spans[:index], span)
        if parent is None:
            roots.append(span)
        else:
            children.setdefault(id(parent), []).append(span)
    ordered: list[TaskSpan] = []

    def walk(found: list[TaskSpan]) -> None:
        for span in found:
            ordered.append(span)
            walk(children.get(id(span), []))

    walk(roots)
    return ordered


def _parent(before: list[TaskSpan], span: TaskSpan) -> TaskSpan | None:
    """The run of the task around ``span`` it began in: the latest begun before it, of the
    same vehicle if there is one, else of none (a task no vehicle flies)."""
    if "/" not in span.task:
        return None
    path = span.task.rsplit("/", 1)[0]
    found: TaskSpan | None = None
    for candidate in reversed(before):
        if candidate.task != path or candidate.start > span.start:
            continue
        if candidate.vehicle == span.vehicle:
            return candidate
        if candidate.vehicle is None and found is None:
            found = candidate
    return found


def _take(flight: Flight, line: dict[str, Any],
          open_tasks: dict[tuple[str, int | None], TaskSpan]) -> None:
    kind, t, vehicle = line["kind"], float(line["t"]), line.get("vehicle")
    flight.end = max(flight.end, t)
    wall = str(line.get("wall") or "")
    if wall:
        flight.walls = (flight.walls[0] or wall, wall)
    mission_time = line.get("mission_time")
    if flight.mission_start is None and isinstance(mission_time, (int, float)):
        flight.mission_start = t - float(mission_time)
    elif flight.mission_start is None and kind == "mission":  # a log without mission_time
        elapsed = line.get("elapsed")
        flight.mission_start = t - (float(elapsed) if isinstance(elapsed, (int, float))
                                    else 0.0)
    if kind == "run" and "mission" in line:
        flight.mission, flight.mission_file, flight.start = (
            str(line["mission"]), str(line.get("file") or ""), t)
    elif kind == "run" and "exit_code" in line:
        flight.exit_code = int(line["exit_code"])
        flight.outcomes = list(line.get("outcomes") or [])
    elif kind == "telemetry" and line.get("position") and vehicle is not None:
        north, east, up = (float(v) for v in line["position"])
        where = line.get("global") or (None, None, None)
        battery = line.get("battery")
        flight.tracks.setdefault(int(vehicle), []).append(Sample(
            t, north, east, up, where[0], where[1], where[2],
            None if battery is None else float(battery), str(line.get("mode", "")),
            bool(line.get("armed")), wall))
    elif kind == "task":
        key = (str(line["task"]), vehicle)
        if line["state"] == "running":
            open_tasks[key] = span = TaskSpan(key[0], vehicle, t)
            flight.tasks.append(span)
        elif key in open_tasks:
            span = open_tasks.pop(key)
            span.end, span.state = t, str(line["state"])
        else:  # ended without running (skipped)
            flight.tasks.append(TaskSpan(key[0], vehicle, t, t, str(line["state"])))
    elif kind == "event":
        flight.marks.append(Mark(t, vehicle, "event", str(line.get("event", "")), wall=wall))
    elif kind == "autopilot":
        text, said = str(line.get("text", "")), str(line.get("severity", ""))
        shown = said
        if said in SEVERITIES:
            level = shown_severity(SEVERITIES.index(said), text)
            shown = SEVERITIES[level]
        flight.marks.append(Mark(t, vehicle, "autopilot", text, shown,
                                 said if shown != said else "", wall))
    elif kind in ("safety", "error"):
        flight.marks.append(Mark(t, vehicle, kind, str(line.get("message", "")), wall=wall))



def _plan(flight: Flight) -> None:
    """The planned paths, obstacles and geofence of the mission file the log names."""
    if not flight.mission_file or not Path(flight.mission_file).is_file():
        return
    from tml.geo import to_local
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
    for obstacle in world.obstacles:
        corners = outline(obstacle)
        flight.obstacles.append([*corners, corners[0]])
    if world.geofence is not None and world.geofence.polygon:
        flight.geofence = [*world.geofence.polygon, world.geofence.polygon[0]]
