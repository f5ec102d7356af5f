"""The flight log: one JSON object per line, written as things happen.

Every line has ``t`` (mission clock, seconds), ``kind`` and, when it is about a vehicle,
``vehicle``; the other keys depend on the kind. The interpreter's records keep their own
kinds (``mission``, ``task``, ``action``, ``decision``, ``event``, ``request``,
``result``, ``safety``); the runner adds ``run`` (start and end of the run, with the
mission file and options), ``result`` (every request outcome a vehicle reported),
``telemetry`` (a vehicle's state once a second, its position both in the local frame and
as latitude, longitude and altitude AMSL, so that a log can be drawn on any map),
``autopilot`` (each message of a vehicle's autopilot, a STATUSTEXT, with its severity),
``ready`` (what a vehicle still lacks before the first task, each time that changes) and
``safety`` (what it did to leave the vehicles safe). docs/run.md lists the fields. Lines
are flushed at once, so that a log survives a crash of the run up to its last event, and
every decision (:data:`DECISIONS`) is synced to the disk too (fsync), so that a log read
back after the machine itself went down holds every decision taken: ``tml run --resume``
goes on from it (:mod:`tml.run.resume`).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Mapping
from typing import Any, Protocol

from tml.geo import to_global
from tml.vehicle import AutopilotMessage, VehicleState


def jsonable(value: Any) -> Any:
    """``value`` with tuples, sets, mappings and non-finite floats made JSON-safe."""
    if isinstance(value, dict) or hasattr(value, "items"):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (set, frozenset)):
        return sorted((jsonable(v) for v in value), key=str)
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if value is None or isinstance(value, (str, int, float, bool)):
        return value
    return str(value)


def telemetry_fields(state: VehicleState) -> dict[str, Any]:
    """The fields of a ``telemetry`` line for one vehicle state."""
    position = state.position
    home = state.home
    where = None
    if position is not None and home is not None:
        lat, lon, alt = to_global(*position, home.latitude, home.longitude, home.altitude)
        where = [round(lat, 7), round(lon, 7), round(alt, 2)]
    return {
        "link": state.link, "mode": state.mode, "armed": state.armed, "landed": state.landed,
        "position": None if position is None else [round(v, 2) for v in position],
        "global": where,
        "heading": round(state.heading, 1), "ground_speed": round(state.ground_speed, 2),
        "climb": round(state.climb, 2),
        "battery": state.battery,
        "voltage": None if state.voltage is None else round(state.voltage, 2),
        "gps_fix": state.gps_fix, "satellites": state.satellites,
        "mission": None if state.mission is None else {
            "plan": state.mission.plan_id, "action": state.mission.action_index,
            "finished": state.mission.finished, "item": state.mission.item,
            "items": state.mission.items},
        "detections": jsonable(state.detections),
    }


def autopilot_fields(message: AutopilotMessage) -> dict[str, Any]:
    """The fields of an ``autopilot`` line: the severity's word and number, the text, and
    whether the vehicle was armed when it said it (None: not known)."""
    return {"severity": message.severity_name, "level": message.severity,
            "text": message.text, "armed": message.armed}


DECISIONS = frozenset({"run", "mission", "task", "action", "decision", "request", "control",
                       "safety", "event"})
"""The kinds of line a resumed run goes on from: synced to the disk as they are written."""


class Sink(Protocol):
    """Where a journal writes: a text file, or anything that takes text the same way."""

    def write(self, text: str, /) -> int: ...

    def flush(self) -> None: ...

    def close(self) -> None: ...


class Journal:
    """Writes log lines to ``stream`` (nothing at all when ``stream`` is None)."""

    def __init__(self, stream: Sink | None, owned: bool = False) -> None:
        self.stream = stream
        self.owned = owned  # the journal opened the stream, and closes it
        self.lines = 0

    @classmethod
    def open(cls, path: str | None, append: bool = False) -> Journal:
        """A journal writing to the file ``path`` (created or truncated; ``append``: added
        to, as a resumed run does), or a silent one."""
        if not path:
            return cls(None)
        return cls(open(path, "a" if append else "w", encoding="utf-8"), owned=True)

    def write(self, time: float, kind: str, vehicle: int | None = None,
              fields: Mapping[str, Any] | None = None, **more: Any) -> None:
        """Append one line: ``fields`` and ``more`` after ``t``, ``kind`` and ``vehicle``.

        A field named like one of those three (a SetSpeed request's ``kind``) is written
        as ``<kind>_<name>`` (``request_kind``) so that it cannot hide them.
        """
        if self.stream is None:
            return
        line: dict[str, Any] = {"t": round(time, 3), "kind": kind}
        if vehicle is not None:
            line["vehicle"] = vehicle
        for name, value in {**(fields or {}), **more}.items():
            key = f"{kind}_{name}" if name in ("t", "kind", "vehicle") else name
            line[key] = jsonable(value)
        self.stream.write(json.dumps(line, separators=(",", ":")) + "\n")
        self.stream.flush()
        if kind in DECISIONS:
            self._sync()
        self.lines += 1

    def _sync(self) -> None:
        """Put what was written on the disk (a stream without a file descriptor: nothing)."""
        fileno = getattr(self.stream, "fileno", None)
        if fileno is None:
            return
        # Not a file (a pipe, a closed or in-memory stream): flushed is all it can be.
        with contextlib.suppress(OSError, ValueError):
            os.fsync(fileno())

    def close(self) -> None:
        """Close the file (a journal on a caller's stream leaves it open)."""
        if self.owned and self.stream is not None:
            self.stream.close()


def read(path: str) -> list[dict[str, Any]]:
    """Every line of a flight log, parsed."""
    with open(path, encoding="utf-8") as stream:
        return [json.loads(line) for line in stream if line.strip()]
