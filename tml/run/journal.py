"""The flight log: one JSON object per line, written as things happen.

Every line has ``t`` (the run's clock, seconds), ``kind``, ``vehicle`` when it is about a
vehicle, ``mission_time`` and ``wall``; the other keys depend on the kind. The times a
person reads are the two last: ``mission_time`` is seconds since the mission's first task
started (the ``mission`` line that says it started or resumed is its 0; null on the lines
before it; a resumed run counts on from the interrupted run's time; pauses are counted, as
on a stopwatch), the time the live view, the line display and the reports show;
``wall`` is the wall-clock time the line was written, ISO 8601 to the millisecond with the
local UTC offset (``2026-05-01T14:03:22.125+02:00``), to set the log beside other records of
the day. ``t`` stays the run's own clock (the simulator's vehicle time with ``--sim``,
monotonic otherwise), on which every rule of the run is measured.

The interpreter's records keep their own kinds (``mission``, ``task``, ``action``,
``decision``, ``event``, ``request``, ``result``, ``safety``); the runner adds ``run``
(start and end of the run, with the mission file and options), ``result`` (every request
outcome a vehicle reported), ``telemetry`` (a vehicle's state once a second, its position
both in the local frame and as latitude, longitude and altitude AMSL, so that a log can be
drawn on any map), ``autopilot`` (each message of a vehicle's autopilot, a STATUSTEXT, with
its severity), ``ready`` (what a vehicle still lacks before the first task, each time that
changes) and ``safety`` (what it did to leave the vehicles safe). docs/run.md lists the
fields; :mod:`tml.engine.flightlog` has a record class per kind and the schema (its
version is on the ``run`` lines: ``log_version``), and :func:`read_log` is the one reader
of a log (resume, reports, the service). Lines are flushed at once, so that a log
survives a crash of the run up to its last event, and every decision (:data:`DECISIONS`)
is synced to the disk too (fsync), so that a log read back after the machine itself went
down holds every decision taken: ``tml run --resume`` goes on from it
(:mod:`tml.run.resume`). The decisions of one engine call are synced together
(:meth:`Journal.grouped`), before the requests they lead to are sent.

A log that cannot be written (a full disk, a directory removed under it) never stops the
flight: the first failure is kept (:attr:`Journal.failure`) and told to ``on_failure``, the
lines after it are only counted (:attr:`Journal.unwritten`), and the run goes on to its end
and its safe state as it would have; the command says what it could not write.

*One writer.* A flight log opened by :meth:`Journal.open` is locked (``flock``, exclusive)
for as long as its file is open: a second ``tml run --resume LOG`` -- or a second run
given the same ``--log`` -- while a process still writes LOG would interleave two runs'
decisions in one log and fly one vehicle from two ground stations. It is refused
(:class:`JournalBusy`) before the file is changed. The operating system lets go of the lock
when the writer closes the file, exits or is killed, so a run killed with SIGKILL leaves a
log that resumes at once.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import stat
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Protocol

from tml.engine.flightlog import VERSION
from tml.errors import TmlError
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
    """The fields of an ``autopilot`` line: the severity's word and number, and the text."""
    return {"severity": message.severity_name, "level": message.severity,
            "text": message.text}


DECISIONS = frozenset({"run", "mission", "task", "action", "decision", "request", "control",
                       "safety", "event"})
"""The kinds of line a resumed run goes on from: synced to the disk as they are written."""


class Sink(Protocol):
    """Where a journal writes: a text file, or anything that takes text the same way."""

    def write(self, text: str, /) -> int: ...

    def flush(self) -> None: ...

    def close(self) -> None: ...


def local_now() -> datetime:
    """The wall-clock time now, with the local UTC offset."""
    return datetime.now().astimezone()


def wall_time(moment: datetime) -> str:
    """A ``wall`` field: ISO 8601 to the millisecond, with the UTC offset."""
    return moment.isoformat(timespec="milliseconds")


HEAD = ("t", "kind", "vehicle", "mission_time", "wall")
"""The fields every line begins with; a field of the same name is written as
``<kind>_<name>``."""


class JournalBusy(TmlError):
    """Another process writes this flight log (see "One writer" in the module docstring)."""


def lock(stream: Any, path: str) -> None:
    """Take the flight log's writer lock on ``stream`` (the open file ``path``), or raise
    :class:`JournalBusy`; held until the file is closed (or the process ends)."""
    try:
        fcntl.flock(stream.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        raise JournalBusy(f"{path}: another process is writing this flight log (a run "
                          f"still going on): one run writes a log at a time") from None
    except OSError:
        # A file that takes no lock (a device such as /dev/full, a file system without
        # flock): the log is written unguarded -- a missing lock must not stop a flight.
        pass


class Journal:
    """Writes log lines to ``stream`` (nothing at all when ``stream`` is None); ``wall``
    tells the wall-clock time of each line (the local time by default)."""

    def __init__(self, stream: Sink | None, owned: bool = False,
                 wall: Callable[[], datetime] = local_now,
                 on_failure: Callable[[str], None] | None = None) -> None:
        self.stream = stream
        self.owned = owned  # the journal opened the stream, and closes it
        self.wall = wall
        self.on_failure = on_failure
        self.lines = 0
        self.failure = ""
        """Why the log could not be written, from the first line that was not ("": none)."""
        self.unwritten = 0
        """Lines not written since then."""
        self.mission_start: float | None = None
        """Where mission time 0 is on the run's clock (``t``); None before the mission
        started."""
        self._grouping: int | None = None  # the thread whose decisions are synced together
        self._unsynced = False  # a decision of the group is not on the disk yet

    @classmethod
    def open(cls, path: str | None, append: bool = False) -> Journal:
        """A journal writing to the file ``path`` (created or truncated; ``append``: added
        to, as a resumed run does: the file must exist), or a silent one; locked for its
        writer (:func:`lock`: :class:`JournalBusy` when another process writes it, before
        anything of it is changed)."""
        if not path:
            return cls(None)
        # Opened without truncating, so that a log another process writes is left whole.
        stream = open(path, "r+" if append else "a", encoding="utf-8")  # noqa: SIM115
        try:
            # Only a file is locked and truncated: a device or a pipe (/dev/null, /dev/full)
            # is no log to resume, has nothing to truncate, and two runs may share it.
            if stat.S_ISREG(os.fstat(stream.fileno()).st_mode):
                lock(stream, path)
                if append:
                    stream.seek(0, os.SEEK_END)
                else:
                    stream.truncate(0)
        except BaseException:
            stream.close()
            raise
        return cls(stream, owned=True)

    def mission_time(self, time: float) -> float | None:
        """The mission time of the run's ``time`` (None before the mission started)."""
        return None if self.mission_start is None else time - self.mission_start

    def write(self, time: float, kind: str, vehicle: int | None = None,
              fields: Mapping[str, Any] | None = None, **more: Any) -> None:
        """Append one line: ``fields`` and ``more`` after ``t``, ``kind``, ``vehicle``,
        ``mission_time`` and ``wall`` (:data:`HEAD`).

        A field named like one of those (a SetSpeed request's ``kind``) is written as
        ``<kind>_<name>`` (``request_kind``) so that it cannot hide them. The first
        ``mission`` line (the interpreter's "started", or "resumed" with the ``elapsed``
        mission time it goes on from) sets mission time 0.
        """
        data = {**(fields or {}), **more}
        if kind == "mission" and self.mission_start is None:
            elapsed = data.get("elapsed", 0.0)
            self.mission_start = time - (float(elapsed)
                                         if isinstance(elapsed, (int, float)) else 0.0)
        if self.stream is None:
            return
        line: dict[str, Any] = {"t": round(time, 3), "kind": kind}
        if vehicle is not None:
            line["vehicle"] = vehicle
        mission = self.mission_time(time)
        line["mission_time"] = None if mission is None else round(mission, 3)
        line["wall"] = wall_time(self.wall())
        for name, value in data.items():
            key = f"{kind}_{name}" if name in HEAD else name
            line[key] = jsonable(value)
        if self.failure:
            self.unwritten += 1
            return
        try:
            self.stream.write(json.dumps(line, separators=(",", ":")) + "\n")
            self.stream.flush()
        except (OSError, ValueError) as error:
            self._failed(error)
            return
        if kind in DECISIONS:
            if self._grouping == threading.get_ident():
                self._unsynced = True
            else:
                self._sync()
        self.lines += 1

    @contextlib.contextmanager
    def grouped(self) -> Iterator[None]:
        """Sync the decisions the calling thread writes meanwhile once, at the end, instead
        of one by one: the caller acts on them only after it (the runner sends an engine
        call's requests after the call's decisions are on the disk). A burst of events in
        a fleet is one sync, not one per line (docs/performance.md, *A flight log*)."""
        # Nested in this thread's group: the outer one syncs; in another thread's group:
        # this thread's decisions are synced line by line (see write).
        if self._grouping is not None:
            yield
            return
        self._grouping = threading.get_ident()
        try:
            yield
        finally:
            self._grouping = None
            if self._unsynced:
                self._unsynced = False
                self._sync()

    def _failed(self, error: Exception) -> None:
        reason = error.strerror if isinstance(error, OSError) and error.strerror else error
        self.failure = f"could not write line {self.lines + 1}: {reason}"
        self.unwritten = 1
        if self.on_failure is not None:
            self.on_failure(f"flight log: {self.failure}; the flight goes on without it")

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
            try:
                self.stream.close()
            except OSError as error:  # what the file's buffer held could not be written
                if not self.failure:
                    self._failed(error)


MAX_LOG_BYTES = 1 << 30
"""A flight log larger than this is not read back (a day of telemetry is about 100 MB)."""


class LogUnreadable(TmlError):
    """A file that is not a flight log this tml reads: not one at all, a line that is no
    log line, too large, or of a later version; the message says where and why."""


@dataclass(frozen=True)
class FlightLog:
    """A flight log read back (:func:`read_log`)."""

    path: str
    version: int  # its schema version (1: written before the version was kept)
    lines: list[dict[str, Any]]  # every line, parsed, in order
    cut: bool = False  # the last line was cut short (the writer was killed) and is left out


def read_log(path: str, max_bytes: int = MAX_LOG_BYTES) -> FlightLog:
    """The flight log at ``path``: the one reader of flight logs (resume, reports, the
    service). A last line cut short by a crash is left out; :class:`LogUnreadable` for a
    file larger than ``max_bytes``, a line before the last that is not a log line (a JSON
    object with ``t`` and ``kind``), a file whose first line is none (not a flight log), or
    a log of a later schema version than :data:`~tml.engine.flightlog.VERSION`; OSError
    when it cannot be read."""
    with open(path, "rb") as stream:
        data = stream.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise LogUnreadable(f"{path}: larger than {max_bytes} bytes, not read")
    texts = data.decode("utf-8", errors="replace").splitlines()
    lines: list[dict[str, Any]] = []
    cut = False
    for number, text in enumerate(texts, 1):
        if not text.strip():
            continue
        try:
            line = json.loads(text)
        except ValueError as error:
            if number == len(texts) and lines:
                cut = True  # written when the run was killed
                break
            said = error.msg if isinstance(error, json.JSONDecodeError) else error
            raise LogUnreadable(f"{path}:{number}: not a JSON line: {said}"
                                + ("" if lines else " (not a tml flight log)")) from None
        if not isinstance(line, dict) or "t" not in line or "kind" not in line:
            raise LogUnreadable(f"{path}:{number}: not a flight log line (no 't' and 'kind')"
                                + ("" if lines else ": not a tml flight log"))
        lines.append(line)
    version = version_of(lines)
    if version > VERSION:
        raise LogUnreadable(f"{path}: a flight log of version {version}, written by a later "
                            f"tml; this one reads versions 1 to {VERSION}")
    return FlightLog(path, version, lines, cut)


def version_of(lines: Sequence[Mapping[str, Any]]) -> int:
    """A log's schema version: its first ``run`` line's ``log_version`` (1 without)."""
    for line in lines:
        if line.get("kind") == "run":
            found = line.get("log_version", 1)
            return found if isinstance(found, int) and not isinstance(found, bool) else 1
    return 1


def read(path: str) -> list[dict[str, Any]]:
    """Every line of a flight log, parsed (:func:`read_log`)."""
    return read_log(path).lines
