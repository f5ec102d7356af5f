"""The flight log's lines as types: one record class per kind, a versioned schema.

Theory of operation
-------------------
A flight log (:mod:`tml.run.journal` writes it) is one JSON object per line. Every line
begins with :class:`Line`'s fields -- ``t``, ``kind``, ``vehicle``, ``mission_time``,
``wall`` -- and ``kind`` says which class the rest follows (:data:`KINDS`): a ``task``
line is a :class:`TaskLine` with ``task`` and ``state``, a ``telemetry`` line a
:class:`TelemetryLine` ... The classes declare the fields every reader relies on, with
their types; a line may carry more (a request's own fields depend on the request: a
``GoTo`` has a ``target``, a ``SetSpeed`` a ``speed``), kept in :attr:`Line.extra`, so
that a log of a later minor change still reads.

*Versions.* :data:`VERSION` is the version of this schema; the ``run`` line that starts
(or resumes) a run says it (``log_version``). A log without it was written before the
version was kept (version 1: the same lines, without ``log_version``); a log of a higher
version is not read (:func:`version_of`).

*The schema* (:func:`json_schema`) is these classes written as JSON Schema (draft
2020-12); it is published in the package as ``flightlog.schema.json`` beside this module,
and a test keeps the file equal to what the classes say. :func:`problems` checks a line
against the classes, as the schema would, cheaply enough to check every line the test
suite's flights write.
"""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Union

VERSION = 2
"""The flight log's schema version: 2 added ``log_version`` to the ``run`` lines (version
1: the logs written before)."""

SCHEMA_FILE = Path(__file__).with_name("flightlog.schema.json")
"""The JSON Schema of a flight log line, as published in the package."""


@dataclass(frozen=True, kw_only=True)
class Line:
    """What every line has: the run's clock ``t`` (s), the ``kind``, the vehicle it is
    about (None: the run's, or a task no vehicle flies), the mission time (None before the
    mission started) and the wall-clock time it was written (ISO 8601)."""

    KIND: ClassVar[str] = ""
    t: float
    kind: str
    vehicle: int | None = None
    mission_time: float | None = None
    wall: str = ""
    message: str = ""
    extra: Mapping[str, Any] = field(default_factory=dict, compare=False)
    """The line's fields its class does not declare."""


@dataclass(frozen=True, kw_only=True)
class RunLine(Line):
    """A run started, resumed or ended (``message`` says which)."""

    KIND: ClassVar[str] = "run"
    log_version: int | None = None  # on a run started or resumed (version 2 on)
    mission: str | None = None
    file: str | None = None
    vehicles: list[int] | None = None
    roles: list[str] | None = None
    safe_state: str | None = None
    sha256: str | None = None
    connect: list[str] | None = None
    system_ids: list[int] | None = None
    status: str | None = None  # the run ended: how
    exit_code: int | None = None
    outcomes: list[dict[str, Any]] | None = None


@dataclass(frozen=True, kw_only=True)
class MissionLine(Line):
    """The mission started, resumed (``elapsed``: the mission time it goes on from; what
    had ended, was running, the rounds and labels) or ended (``status``)."""

    KIND: ClassVar[str] = "mission"
    name: str | None = None
    vehicles: list[int] | None = None
    roles: list[str] | None = None
    elapsed: float | None = None
    ended: dict[str, str] | None = None
    running: list[str] | None = None
    rounds: dict[str, int] | None = None
    labels: list[str] | None = None
    status: str | None = None
    reason: str | None = None


@dataclass(frozen=True, kw_only=True)
class TaskLine(Line):
    """A task's state changed (``resumed``: said by a resumed run re-entering it)."""

    KIND: ClassVar[str] = "task"
    task: str
    state: str
    resumed: bool = False
    decided: float | None = None  # the mission time it was decided, when said later


@dataclass(frozen=True, kw_only=True)
class ActionLine(Line):
    """An action started (``arguments``), ended or failed; ``task`` None: an event
    handler's."""

    KIND: ClassVar[str] = "action"
    action: str | None = None  # None: a mission flight's (dispatch="mission") failure
    task: str | None = None
    line: int | None = None
    arguments: dict[str, Any] | None = None
    labels: dict[str, Any] | None = None
    reason: str | None = None
    why: str | None = None


@dataclass(frozen=True, kw_only=True)
class DecisionLine(Line):
    """What the interpreter decided: a round, a choice, a plan flown as a mission, an
    event's termination, a point memorized ..."""

    KIND: ClassVar[str] = "decision"
    task: str | None = None
    action: str | None = None
    iteration: int | None = None
    round: int | None = None
    rounds: int | None = None
    resumed: bool = False
    recover: bool = False
    actions: list[str] | None = None
    label: str | None = None
    point: list[float] | None = None
    event: str | None = None
    termination: str | None = None


@dataclass(frozen=True, kw_only=True)
class EventLine(Line):
    """An event fired."""

    KIND: ClassVar[str] = "event"
    event: str
    line: int | None = None


@dataclass(frozen=True, kw_only=True)
class RequestLine(Line):
    """A request sent to a vehicle; its own fields follow (see the module docstring)."""

    KIND: ClassVar[str] = "request"
    request_id: int
    plan_id: int | None = None
    start: list[float] | None = None
    actions: list[str] | None = None


@dataclass(frozen=True, kw_only=True)
class ResultLine(Line):
    """What became of a request, as the vehicle reported it."""

    KIND: ClassVar[str] = "result"
    request_id: int | None = None
    ok: bool | None = None
    reason: str | None = None
    detail: str | None = None


@dataclass(frozen=True, kw_only=True)
class ControlLine(Line):
    """An operator's control: ``pause``, ``resume`` (``paused``: the seconds it was
    paused) or ``jump`` (to ``task``)."""

    KIND: ClassVar[str] = "control"
    control: str
    reason: str | None = None
    paused: float | None = None
    task: str | None = None


@dataclass(frozen=True, kw_only=True)
class SafetyLine(Line):
    """A step taken to leave a vehicle safe, or its confirmation."""

    KIND: ClassVar[str] = "safety"
    request: str | None = None
    confirmed: bool | None = None
    mode: str | None = None


@dataclass(frozen=True, kw_only=True)
class TelemetryLine(Line):
    """A vehicle's state (once a second)."""

    KIND: ClassVar[str] = "telemetry"
    link: str | None = None
    mode: str | None = None
    armed: bool | None = None
    landed: bool | None = None
    position: list[float] | None = None
    global_: list[float] | None = field(default=None, metadata={"name": "global"})
    heading: float | None = None
    ground_speed: float | None = None
    climb: float | None = None
    battery: float | None = None
    voltage: float | None = None
    gps_fix: int | None = None
    satellites: int | None = None
    mission: dict[str, Any] | None = None
    detections: dict[str, Any] | None = None


@dataclass(frozen=True, kw_only=True)
class AutopilotLine(Line):
    """A message of the vehicle's autopilot (STATUSTEXT)."""

    KIND: ClassVar[str] = "autopilot"
    severity: str
    text: str
    level: int | None = None  # the severity's number (0 the worst)


@dataclass(frozen=True, kw_only=True)
class ReadyLine(Line):
    """What a vehicle still lacks before the first task."""

    KIND: ClassVar[str] = "ready"
    awaiting: list[str] | None = None


@dataclass(frozen=True, kw_only=True)
class SafeguardLine(Line):
    """The fence and rally points uploaded to a vehicle, or not."""

    KIND: ClassVar[str] = "safeguard"
    ok: bool
    reason: str | None = None


@dataclass(frozen=True, kw_only=True)
class RejectedLine(Line):
    """Telemetry messages with absurd values, ignored."""

    KIND: ClassVar[str] = "rejected"


@dataclass(frozen=True, kw_only=True)
class TakenLine(Line):
    """A vehicle taken over (by another controller, a reboot): tml commands it no more."""

    KIND: ClassVar[str] = "taken"
    mode: str | None = None
    reboot: bool = False
    status_text: str | None = None


@dataclass(frozen=True, kw_only=True)
class LinkLine(Line):
    """A vehicle's link changed."""

    KIND: ClassVar[str] = "link"
    link: str
    was: str | None = None


@dataclass(frozen=True, kw_only=True)
class ErrorLine(Line):
    """The interpreter or the service failed."""

    KIND: ClassVar[str] = "error"
    traceback: str | None = None


@dataclass(frozen=True, kw_only=True)
class PickLine(Line):
    """Vehicles picked for a role (or the pick failed)."""

    KIND: ClassVar[str] = "pick"
    role: str
    vehicles: list[int] | None = None
    waited: float | None = None
    refused: dict[str, Any] | None = None


@dataclass(frozen=True, kw_only=True)
class ReleaseLine(Line):
    """A vehicle released from its role."""

    KIND: ClassVar[str] = "release"
    role: str


@dataclass(frozen=True, kw_only=True)
class VehicleLine(Line):
    """A vehicle lost to the mission (its reason in ``message``)."""

    KIND: ClassVar[str] = "vehicle"


@dataclass(frozen=True, kw_only=True)
class SayLine(Line):
    """A task said aloud by a vehicle that speaks (the ``say tasks`` skill)."""

    KIND: ClassVar[str] = "say"
    task: str


@dataclass(frozen=True, kw_only=True)
class SigningLine(Line):
    """MAVLink signing: what came unsigned or wrongly signed, per address."""

    KIND: ClassVar[str] = "signing"
    address: str | None = None
    unsigned: int | None = None
    bad_signature: int | None = None


KINDS: dict[str, type[Line]] = {cls.KIND: cls for cls in (
    RunLine, MissionLine, TaskLine, ActionLine, DecisionLine, EventLine, RequestLine,
    ResultLine, ControlLine, SafetyLine, TelemetryLine, AutopilotLine, ReadyLine,
    SafeguardLine, RejectedLine, TakenLine, LinkLine, ErrorLine, PickLine, ReleaseLine,
    VehicleLine, SayLine, SigningLine)}
"""Every kind of line, and its class."""


class UnknownKind(ValueError):
    """A line of a kind this version does not know."""


def parse(data: Mapping[str, Any]) -> Line:
    """The record of one parsed line (``t`` and ``kind`` it must have: KeyError; a kind
    not known: :class:`UnknownKind`). Fields are taken as they are, not checked
    (:func:`problems` checks them)."""
    kind = data["kind"]
    cls = KINDS.get(kind)
    if cls is None:
        raise UnknownKind(kind)
    known = _NAMES[kind]
    values: dict[str, Any] = {}
    extra: dict[str, Any] = {}
    for name, value in data.items():
        found = known.get(name)
        if found is None:
            extra[name] = value
        elif value is not None or not found.required:
            values[found.attribute] = value
    if extra:
        values["extra"] = extra
    return cls(**values)


def get(line: Line, name: str, default: Any = None) -> Any:
    """A field of the line by the name it has in the log, declared or not."""
    found = _NAMES[line.kind].get(name) if line.kind in _NAMES else None
    if found is not None:
        return getattr(line, found.attribute)
    return line.extra.get(name, default)


# -- Checking a line and the JSON Schema ---------------------------------------------

_JSON_TYPES: dict[str, tuple[type, ...]] = {
    "null": (type(None),), "boolean": (bool,), "integer": (int,), "number": (int, float),
    "string": (str,), "array": (list,), "object": (dict,)}


def _valid(value: Any, schema: Mapping[str, Any]) -> bool:
    """Whether a JSON value follows ``schema``, of the part of JSON Schema that
    :func:`_json_type` writes (the checks the published schema makes, without a library)."""
    if "anyOf" in schema:
        return any(_valid(value, s) for s in schema["anyOf"])
    if "enum" in schema:
        return value in schema["enum"]
    wanted = schema.get("type")
    if wanted is None:
        return True
    if not isinstance(value, _JSON_TYPES[wanted]) \
            or (isinstance(value, bool) and wanted in ("integer", "number")):
        return False
    if isinstance(value, list):
        return all(_valid(v, schema["items"]) for v in value)
    if isinstance(value, dict):
        return all(_valid(v, schema["additionalProperties"]) for v in value.values())
    return True


def problems(data: Any) -> list[str]:
    """What is wrong with one parsed line by the schema ([]: nothing)."""
    if not isinstance(data, dict):
        return ["not a JSON object"]
    kind = data.get("kind")
    if kind not in FIELDS:
        return [f"kind {kind!r} is not a kind of line"]
    found = []
    for spec in FIELDS[kind]:
        if spec.name not in data:
            if spec.required:
                found.append(f"{kind} line without {spec.name!r}")
        elif not _valid(data[spec.name], spec.schema):
            found.append(f"{kind} line: {spec.name!r} is {data[spec.name]!r}, "
                         f"not {json.dumps(spec.schema)}")
    return found


def _json_type(kind: Any) -> dict[str, Any]:
    origin = typing.get_origin(kind)
    if origin in (Union, types.UnionType):
        return {"anyOf": [_json_type(k) for k in typing.get_args(kind)]}
    if kind is type(None):
        return {"type": "null"}
    if kind is Any:
        return {}
    if kind is bool:
        return {"type": "boolean"}
    if kind is int:
        return {"type": "integer"}
    if kind is float:  # the journal writes a non-finite number as text
        return {"anyOf": [{"type": "number"}, {"enum": ["inf", "-inf", "nan"]}]}
    if kind is str:
        return {"type": "string"}
    if origin is list:
        return {"type": "array", "items": _json_type(typing.get_args(kind)[0])}
    if origin is dict:
        return {"type": "object", "additionalProperties": _json_type(typing.get_args(kind)[1])}
    raise TypeError(f"no JSON type for {kind!r}")


# -- The classes' fields, as the lines name them ----------------------------------------

@dataclass(frozen=True)
class _Field:
    attribute: str  # the class's name for it
    name: str  # the line's
    kind: Any  # its type
    required: bool
    schema: Mapping[str, Any]  # its type in JSON Schema


def _fields(cls: type[Line]) -> tuple[_Field, ...]:
    hints = typing.get_type_hints(cls)
    return tuple(_Field(f.name, f.metadata.get("name", f.name), hints[f.name],
                        f.default is dataclasses.MISSING
                        and f.default_factory is dataclasses.MISSING,
                        _json_type(hints[f.name]))
                 for f in dataclasses.fields(cls) if f.name != "extra")


FIELDS: dict[str, tuple[_Field, ...]] = {kind: _fields(cls) for kind, cls in KINDS.items()}
_NAMES = {kind: {f.name: f for f in fields} for kind, fields in FIELDS.items()}


def json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of one flight log line, from the classes."""
    definitions: dict[str, Any] = {}
    for kind, cls in KINDS.items():
        fields = FIELDS[kind]
        properties = {f.name: dict(f.schema) for f in fields}
        properties["kind"] = {"const": kind}
        definitions[cls.__name__] = {
            "description": (cls.__doc__ or "").strip(),
            "type": "object",
            "properties": properties,
            "required": [f.name for f in fields if f.required],
        }
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": f"https://tml.invalid/flightlog/{VERSION}/line.schema.json",
        "title": "tml flight log line",
        "description": f"One line of a tml flight log, schema version {VERSION}: the fields "
                       "every line has, and those of its kind (more may follow).",
        "x-version": VERSION,
        "type": "object",
        "required": ["t", "kind"],
        "properties": {"kind": {"enum": list(KINDS)}},
        "oneOf": [{"$ref": f"#/$defs/{cls.__name__}"} for cls in KINDS.values()],
        "$defs": definitions,
    }


def schema_text() -> str:
    """:func:`json_schema` as the published file has it."""
    return json.dumps(json_schema(), indent=2) + "\n"
