"""What the engine reports: how the mission stands, what became of each task, the lines of
the flight log, and the snapshots the display draws."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

from tml.vehicle import FlyMission, Point, Request


class Status(StrEnum):
    """Where a mission run is."""

    RUNNING = "running"
    COMPLETED = "completed"
    ABORTED = "aborted"  # ABORT_MISSION, an infeasible action, or the runner's abort
    FAILED = "failed"  # an action failed (vehicle refusal, timeout) and nothing handled it


class TaskState(StrEnum):
    """What happened to a task, for the live view and the log."""

    PENDING = "pending"
    RUNNING = "running"
    DONE = "done"
    SKIPPED = "skipped"
    FAILED = "failed"
    ABORTED = "aborted"


@dataclass(frozen=True)
class Record:
    """One line of the flight log: what the interpreter decided or saw, and when.

    ``data`` holds plain values (numbers, text, tuples, sets); the journal writes them as JSON.
    """

    time: float
    kind: str
    data: dict[str, object]
    vehicle_id: int | None = None  # whose record it is, in a fleet


@dataclass
class Output:
    """What a call of the engine returns: requests to submit and records to log."""

    requests: list[Request] = field(default_factory=list)
    records: list[Record] = field(default_factory=list)


@dataclass(frozen=True)
class Change:
    """One change of a task's state, in the order the changes happened."""

    time: float  # mission time (the flight log's mission_time)
    task: str  # the task's path, as in the log
    state: TaskState
    vehicle_id: int | None  # None: a task no vehicle flies (orchestration only)
    number: int = 0  # counts the changes of one interpreter from 1: the order they were said


@dataclass(frozen=True)
class View:
    """A snapshot of one vehicle's part of the mission, for the display."""

    status: Status
    task_states: dict[str, TaskState]  # every task of the mission, as this vehicle sees it
    current_task: str
    current_action: str
    progress: float | None
    labels: dict[str, Point]
    events: tuple[tuple[float, str], ...]  # (mission time, event) fired on this vehicle
    mission_time: float  # seconds since the mission started (pauses counted)
    reason: str
    role: str = ""  # the role the vehicle flies, in a fleet
    changes: tuple[Change, ...] = ()  # the vehicle's task changes and the fleet's, in order
    started: bool = False  # the mission has started (before: mission_time means nothing)
    held: tuple[str, ...] = ()  # the tasks whose work an event handler holds (their paths)


def request_fields(request: Request) -> dict[str, object]:
    """A request's own fields, for its line in the log."""
    data = {k: v for k, v in request.__dict__.items() if k not in ("vehicle_id", "request_id")}
    if isinstance(request, FlyMission):
        data["actions"] = [a.name for a in request.actions]
    return data
