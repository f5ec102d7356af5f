"""A run in flight: the runner's thread, its flight log as it is written, its task states.

Theory of operation
-------------------
A :class:`LiveRun` is ``tml run`` inside the service: one :class:`~tml.run.flight.Flight`
(the use case ``tml run`` flies with too) of a mission on the vehicles the run holds, in a
thread of its own, with the clock and the vehicle links of the
:class:`~tml.serve.hangar.Hangar`. Its journal writes to a
:class:`RunLog` instead of a file: the same JSON lines, numbered from 1 as they come,
kept in memory for the live stream, stored in the database in batches (every
``STORE_PERIOD`` seconds and at the end), and handed at once to every listener (the
API's event streams). The log is read as it is written: a ``mission`` line means the
vehicles were ready and the mission started (status ``running``), and every ``task``
line updates the :class:`TaskBoard`, the state of every task per vehicle (the log's one
fold, :class:`tml.engine.resume.Fold`).

When the runner returns, the run's outcome is stored (its status and exit code are those
of its ending, :mod:`tml.run.endings`: ``completed``, ``aborted``, ``taken`` or ``failed``),
then the log is closed (the streams end), and only then are its vehicles released: a client
that saw the stream end finds the run ended, and a vehicle is never given to a second run
while the first still commands it.

*A database that fails* (full, gone) during the flight ends the run as any exception of
the runner does: ``failed`` (``Ending.ERROR``), its vehicles sent to their safe state
(:meth:`~tml.run.flight.Flight.fly`). Its
lines not stored are kept, and so is its outcome when that cannot be stored either
(:attr:`LiveRun.saved` is False): the run still ends -- its streams end, its vehicles are
released -- and the service stores it later (:meth:`LiveRun.save`), once the database
takes writes again.
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from tml.engine.resume import Fold, Progress
from tml.language.model import Mission
from tml.run.endings import Ending
from tml.run.flight import Flight, FlightOptions
from tml.run.journal import Journal
from tml.run.runner import Outcome
from tml.serve.hangar import Hangar
from tml.serve.storage import Storage, StoredRun, failure
from tml.vehicle import IdSource
from tml.verify.profile import VehicleProfile
from tml.world import World

STORE_PERIOD = 0.5  # s between two writes of a run's new log lines to the database

Listener = Callable[[int, str | None], None]  # (seq, line); line None: the log has ended


class TaskBoard:
    """Every task's state per vehicle, as the flight log's one fold has it
    (:class:`~tml.engine.resume.Fold`: a repeat's next round or a jump back shows the tasks
    below it pending again, as a resumed run would fly them)."""

    def __init__(self, mission: Mission, vehicles: Iterable[int]) -> None:
        self.paths = [task.path_name for task in mission.walk()]
        self.vehicles = list(vehicles)
        self.fold = Fold()

    def see(self, record: Mapping[str, Any]) -> None:
        """Take one log record."""
        self.fold.see(record)

    @property
    def changes(self) -> int:
        """Counts the board's changes: it moved when this did."""
        return self.fold.changes

    def snapshot(self) -> dict[str, dict[str, str]]:
        """Per vehicle (by id, as text; "" for tasks no vehicle flies) every task's state,
        ``pending`` for a task not reached."""
        return self.fold.board(self.paths, self.vehicles)


class RunLog:
    """The stream a run's journal writes to; see the module docstring."""

    def __init__(self, run_id: str, storage: Storage, board: TaskBoard,
                 on_record: Callable[[dict[str, Any]], None] | None = None) -> None:
        self.run_id = run_id
        self.storage = storage
        self.board = board
        self.on_record = on_record
        self.lines: list[tuple[int, str]] = []
        self.closed = False
        self._partial = ""
        self._stored = 0  # lines[:_stored] are in the database
        self._last_store = time.monotonic()
        self._listeners: list[Listener] = []
        self._lock = threading.Lock()
        self._store_lock = threading.Lock()

    def write(self, text: str) -> int:
        """Take text from the journal (whole lines, as it writes them)."""
        self._partial += text
        *complete, self._partial = self._partial.split("\n")
        for line in complete:
            if line:
                self._add(line)
        return len(text)

    def flush(self) -> None:
        """Store the new lines when the last store is ``STORE_PERIOD`` old."""
        if time.monotonic() - self._last_store >= STORE_PERIOD:
            self._store()

    def close(self) -> None:
        """Store what is left and end every listener's stream (ended even when the store
        fails: its error is raised after)."""
        try:
            self._store()
        finally:
            with self._lock:
                self.closed = True
                listeners = list(self._listeners)
                self._listeners.clear()
            for listener in listeners:
                listener(len(self.lines), None)

    def store(self) -> None:
        """Store the lines not stored yet (raises what the database raises)."""
        self._store()

    def listen(self, after: int, listener: Listener) -> tuple[list[tuple[int, str]], bool]:
        """The lines numbered above ``after``, and whether the log is still open; while it
        is, ``listener`` is called with every later line (from the run's thread)."""
        with self._lock:
            history = self.lines[after:] if after >= 0 else list(self.lines)
            if not self.closed:
                self._listeners.append(listener)
            return history, not self.closed

    def unlisten(self, listener: Listener) -> None:
        """Stop calling ``listener``."""
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)

    def _add(self, line: str) -> None:
        record = json.loads(line)
        with self._lock:
            seq = len(self.lines) + 1
            self.lines.append((seq, line))
            self.board.see(record)
            listeners = list(self._listeners)
        if self.on_record is not None:
            self.on_record(record)
        for listener in listeners:
            listener(seq, line)

    def _store(self) -> None:
        with self._store_lock:  # one store at a time: the run's thread, or a retry
            with self._lock:
                new = self.lines[self._stored:]
            self._last_store = time.monotonic()
            self.storage.add_lines(self.run_id, new)  # all or nothing: kept until stored
            with self._lock:
                self._stored += len(new)


class LiveRun:
    """One run flying in its own thread; see the module docstring."""

    def __init__(self, record: StoredRun, mission: Mission, hangar: Hangar, storage: Storage,
                 options: FlightOptions, profile: VehicleProfile, ids: IdSource,
                 payloads: Mapping[int, Iterable[str]] | None = None,
                 on_end: Callable[[LiveRun], None] | None = None,
                 resume: Mapping[int, Progress] | None = None) -> None:
        self.id = record.id
        self.record = record
        self.mission = mission
        self.hangar = hangar
        self.storage = storage
        self.status = record.status
        self.reason = ""
        self.outcomes: list[dict[str, Any]] = []
        self.exit_code: int | None = None
        self.ended_at: float | None = None
        self.saved = False  # the outcome and every log line are in the database
        self.on_end = on_end
        self.board = TaskBoard(mission, record.vehicles)
        self.log = RunLog(record.id, storage, self.board, self._seen)
        self.safety: list[str] = []
        self.wake = threading.Event()
        vehicles = [hangar.vehicles[vid] for vid in record.vehicles]
        self.flight = Flight(mission, vehicles, options, on_safety=self.safety.append)
        self.runner = self.flight.start(profile, mission.world or World(), Journal(self.log),
                                        clock=hangar.clock, wake=self.wake,
                                        wait=lambda timeout: hangar.wait(self.wake, timeout),
                                        payloads=payloads, ids=ids, resume=resume)
        self.thread = threading.Thread(target=self._fly, name=f"run {record.id}", daemon=True)

    def start(self) -> None:
        """Take off: the runner's loop in its thread."""
        self.hangar.subscribe(self.wake)
        self.thread.start()

    def control(self, kind: str, target: str = "", reason: str = "") -> None:
        """Pause, resume or jump (:meth:`~tml.run.runner.Runner.control`; ``reason``: a
        pause's, for the journal); raises ControlRefused with the reason."""
        self.runner.control(kind, target, reason=reason)
        if kind in ("pause", "resume") and not self.ended:
            self._set_status("paused" if self.runner.paused else "running")

    def abort(self, reason: str) -> None:
        """End the run now: every vehicle to its safe state (as Ctrl-C does to tml run)."""
        self.runner.stop(reason)

    def take_over(self, command: str) -> None:
        """An operator's command to a vehicle of the run, through the run
        (:meth:`~tml.run.runner.Runner.take_over`)."""
        self.runner.take_over(command)

    def join(self, timeout: float | None = None) -> bool:
        """Wait for the run's thread to end; whether it has."""
        self.thread.join(timeout)
        return not self.thread.is_alive()

    @property
    def ended(self) -> bool:
        """True once the runner has returned (its outcome stored, or :attr:`saved` False)."""
        return self.exit_code is not None

    def save(self) -> bool:
        """Store the ended run's outcome and the log lines not stored yet; whether they
        are stored now."""
        if not self.saved:
            try:
                self.storage.update_run(self.id, status=self.status, reason=self.reason,
                                        outcomes=self.outcomes,
                                        exit_code=self.exit_code, ended=self.ended_at)
                self.log.store()
            except Exception:  # still unwritable: tried again later
                return False
            self.saved = True
        return True

    def _seen(self, record: dict[str, Any]) -> None:
        if record.get("kind") == "mission" and self.status == "waiting":
            self._set_status("running")

    def _set_status(self, status: str, **more: Any) -> None:
        self.status = status
        self.storage.update_run(self.id, status=status, **more)

    def _fly(self) -> None:
        try:
            outcome = self.flight.fly(_said)
            self.outcomes = _outcomes(outcome)
            ending = outcome.ending
            self.reason = _reason(outcome)
        except Exception as error:  # a broken vehicle adapter, a failed database write
            self.reason = _said(error)  # (journaled, the vehicles sent to their safe state)
            ending = Ending.ERROR
        assert ending.status is not None  # (a run that flew has a status)
        self.ended_at = time.time()
        self.status = ending.status
        # Whatever the database says, the run is over: its streams end, its vehicles are
        # free (an outcome not stored is stored later: save).
        self.exit_code = int(ending.code)
        self.save()
        with contextlib.suppress(Exception):
            self.log.close()
        self.hangar.unsubscribe(self.wake)
        self.hangar.release(self.id)
        if self.on_end is not None:
            self.on_end(self)


def _said(error: Exception) -> str:
    """A run's reason when the service failed under it."""
    return f"service error: {failure(error)}"


def _outcomes(outcome: Outcome) -> list[dict[str, Any]]:
    return [{"vehicle": v.vehicle_id, "status": v.status.value, "reason": v.reason,
             "cause": v.cause} for v in outcome.vehicles]


def _reason(outcome: Outcome) -> str:
    """The run's reason: the first vehicle's that did not complete, else the first's."""
    ended = [v for v in outcome.vehicles if v.status.value != "completed"] or \
        list(outcome.vehicles)
    return ended[0].reason if ended else ""
