"""The service's answers: what :class:`~tml.serve.service.Service` returns and the HTTP API
(:mod:`tml.serve.api`) sends as JSON, one typed model per document.

The service builds these models and the API declares them as its routes' response models,
so that the shape of every answer is checked by mypy from where it is made to where it is
sent, and FastAPI's OpenAPI document describes the same classes.
"""

from __future__ import annotations

from typing import Literal, cast, get_args

from pydantic import BaseModel, Field, JsonValue

from tml.run.journal import jsonable

RunStatus = Literal["waiting", "running", "paused", "completed", "aborted", "taken",
                    "failed", "interrupted"]
OperatorCommand = Literal["rtl", "land", "hold", "disarm"]
CommandOutcome = Literal["refused", "sent", "unanswered", "accepted", "done",
                         "not confirmed"]
AnswerOutcome = Literal["done", "nothing to do", "not confirmed"]


def json_value(value: object) -> JsonValue:
    """``value`` in JSON's own values (:func:`tml.run.journal.jsonable`: tuples as lists,
    keys as text, a non-finite number as its text)."""
    found: JsonValue = jsonable(value)
    return found


def _spelled(choices: tuple[str, ...], word: str, what: str) -> str:
    if word not in choices:
        raise ValueError(f"unknown {what} {word!r}")
    return word


def run_status(status: str) -> RunStatus:
    """A run's status as the model spells it (ValueError for any other word)."""
    return cast(RunStatus, _spelled(get_args(RunStatus), status, "run status"))


def operator_command(command: str) -> OperatorCommand:
    """An operator's command as the model spells it (ValueError for any other word)."""
    return cast(OperatorCommand, _spelled(get_args(OperatorCommand), command, "command"))


def answer_outcome(outcome: str) -> AnswerOutcome:
    """What came of an operator's command, as the answer spells it (ValueError for any
    other word)."""
    return cast(AnswerOutcome, _spelled(get_args(AnswerOutcome), outcome, "outcome"))


class Diagnostic(BaseModel):
    """One problem found in a mission, as ``tml validate --format json`` gives it."""

    file: str
    line: int
    column: int
    code: str
    message: str
    hint: str
    severity: Literal["error", "warning"]


class MissionSummary(BaseModel):
    """A stored mission."""

    id: str
    name: str
    filename: str
    uploaded: float = Field(description="when it was uploaded (Unix time)")
    warnings: list[Diagnostic]


class TaskOutline(BaseModel):
    """A task of a mission's tree, as the page draws it."""

    name: str
    path: str
    line: int
    action: str | None
    role: str | None
    composition: str
    children: list[TaskOutline]
    on_error: list[TaskOutline]


class RoleOutline(BaseModel):
    """A mission's role."""

    name: str
    count: int
    vehicle_type: str | None
    payloads: list[str]


class EventOutline(BaseModel):
    """A mission's event handler."""

    name: str
    line: int
    termination: str


class HomeOutline(BaseModel):
    """A world's home (the default one when the mission declares none)."""

    latitude: float
    longitude: float
    altitude: float
    heading: float
    declared: bool


class FenceOutline(BaseModel):
    """A world's geofence."""

    polygon: list[list[float]]
    min_altitude: float | None
    max_altitude: float | None


class CylinderOutline(BaseModel):
    """A cylindrical obstacle (an unbounded top is null)."""

    name: str
    bottom: float
    top: float | None
    shape: Literal["cylinder"]
    north: float
    east: float
    radius: float


class PrismOutline(BaseModel):
    """A prism obstacle (an unbounded top is null)."""

    name: str
    bottom: float
    top: float | None
    shape: Literal["prism"]
    polygon: list[list[float]]


class ObjectOutline(BaseModel):
    """An object of the world."""

    kind: str
    ident: str
    north: float
    east: float
    altitude: float
    color: str
    name: str


class WorldOutline(BaseModel):
    """A world in metres north and east of home."""

    home: HomeOutline
    geofence: FenceOutline | None
    obstacles: list[CylinderOutline | PrismOutline]
    objects: list[ObjectOutline]


class MissionDetail(MissionSummary):
    """A stored mission with what the page draws of it."""

    tasks: list[TaskOutline] = Field(description="the task tree: name, path, line, action, "
                                                 "role, composition, children, on_error")
    roles: list[RoleOutline]
    events: list[EventOutline]
    world: WorldOutline = Field(description="home, geofence, obstacles and objects, in "
                                              "metres north and east of home")


class MissionRef(BaseModel):
    """The mission a run flies."""

    id: str
    name: str


class VehicleOutcome(BaseModel):
    """How a run ended for one of its vehicles."""

    vehicle: int
    status: str
    reason: str
    cause: str


class RunView(BaseModel):
    """A run."""

    id: str
    mission: MissionRef
    vehicles: list[int]
    status: RunStatus = Field(
        description="how the run stands, then how it ended (docs/run.md, How a run ends)")
    reason: str
    outcomes: list[VehicleOutcome] = Field(description="per vehicle: status, reason, cause")
    exit_code: int | None = Field(description="the exit code tml run gives for the same "
                                              "ending (0, 3, 4)")
    instance: str
    options: dict[str, JsonValue] = Field(description="safe_state, profile, force, and "
                                                      "continues: the run it goes on with")
    created: float
    ended: float | None
    tasks: dict[str, dict[str, str]] | None = Field(
        default=None,
        description="per vehicle id ('' for tasks no vehicle flies): every task's state, "
                    "by path")
    safety: list[str] | None = Field(
        default=None, description="what was done to leave the vehicles safe")


class HomeView(BaseModel):
    """A vehicle's home: the origin of its local frame."""

    latitude: float
    longitude: float
    altitude: float = Field(description="metres above mean sea level")


class OperatorCommandSeen(BaseModel):
    """An operator's last command to a vehicle, as the service saw it through."""

    command: OperatorCommand
    outcome: CommandOutcome = Field(
        description="refused (by the rule or the vehicle), sent (to the vehicle, or "
                    "through the run that held it), unanswered, accepted by the vehicle "
                    "(its motion awaited), done (confirmed by the vehicle's telemetry, or "
                    "nothing to do), not confirmed (within the command's timeout: what "
                    "was wanted and seen in detail)")
    detail: str
    at: float = Field(description="when (Unix time)")


class MissionProgressView(BaseModel):
    """How far a vehicle is in the plan it flies in AUTO."""

    plan: int
    action: int
    finished: bool
    item: int
    items: int


class VehicleView(BaseModel):
    """A vehicle with its live telemetry."""

    id: int
    run: str | None = Field(description="the run that holds it")
    vehicle_type: str
    time: float
    link: str
    mode: str
    armed: bool
    landed: bool
    position: list[float] | None = Field(description="north, east, up in metres from home")
    global_position: list[float] | None = Field(
        alias="global", description="latitude, longitude (degrees) and altitude AMSL (m)")
    home: HomeView | None = Field(description="where the vehicle's local frame starts")
    heading: float
    ground_speed: float
    climb: float = Field(description="vertical speed, m/s, up positive")
    battery: float | None = Field(description="charge left, %")
    voltage: float | None = Field(description="battery voltage, V")
    gps_fix: int | None = Field(description="GPS_RAW_INT fix type (3: 3D)")
    satellites: int | None = Field(description="GPS satellites visible")
    mission: MissionProgressView | None
    detections: dict[str, JsonValue]
    status_text: str = Field(description="the autopilot's last message")
    awaiting: list[str] = Field(description="what it still lacks before a mission may start")
    command: OperatorCommandSeen | None = Field(
        default=None, description="the last operator command and what came of it")


class CommandAnswer(BaseModel):
    """What an operator's command did."""

    vehicle: int
    command: OperatorCommand
    run: str | None = Field(description="the run that held the vehicle, paused (hold) or "
                                        "ended by the command")
    outcome: AnswerOutcome = Field(
        description="done: the vehicle's telemetry confirmed it (docs/command.md: hold "
                    "stopped, rtl on its way home, land descending, disarm disarmed); "
                    "nothing to do: disarmed on the ground; not confirmed: not within the "
                    "command's timeout (30 s)")
    confirmed: bool = Field(description="whether the telemetry confirmed it (outcome done "
                                        "or nothing to do)")
    seen: str = Field(description="what the vehicle's telemetry showed last")
    message: str = Field(description="what was done, in one sentence")
    vehicle_state: VehicleView = Field(description="the vehicle as it is now")


class ServiceStatus(BaseModel):
    """What the service is."""

    version: str
    instance: str
    storage: str
    started: float
    vehicles: list[int]
    live_runs: list[str]
