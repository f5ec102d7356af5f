"""A flight as its log tells it: tracks, tasks, events, autopilot messages, the outcome.

:func:`read_flight` reads a flight log (:mod:`tml.run.journal`, one JSON object per line)
into a :class:`Flight`. Lines of kinds it does not know are passed over, so that a log of
a later version still reads. The planned path comes from the mission file the log names
(:mod:`tml.plans.planned`: the path its mission items fly), when that file is still there
and valid; a report is drawn without it otherwise.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tml.errors import TmlError


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
    severity: str = ""


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
    _plan(flight)
    return flight


def _take(flight: Flight, line: dict[str, Any],
          open_tasks: dict[tuple[str, int | None], TaskSpan]) -> None:
    kind, t, vehicle = line["kind"], float(line["t"]), line.get("vehicle")
    flight.end = max(flight.end, t)
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
            bool(line.get("armed"))))
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
        flight.marks.append(Mark(t, vehicle, "event", str(line.get("event", ""))))
    elif kind == "autopilot":
        flight.marks.append(Mark(t, vehicle, "autopilot", str(line.get("text", "")),
                                 str(line.get("severity", ""))))
    elif kind in ("safety", "error"):
        flight.marks.append(Mark(t, vehicle, kind, str(line.get("message", ""))))


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
