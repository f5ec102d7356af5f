"""A MAVLink connection: sockets, receiving, heartbeats, routing, forwarding, signing.

Theory of operation
-------------------
A :class:`Link` owns one pymavlink connection (any address pymavlink understands, see
docs/connections.md). It has no thread of its own: every link of a process is served by one
thread, the :mod:`reactor <tml.mavlink.reactor>`, which waits on all their sockets at once,
so a message is handled as soon as it arrives, and for each message the link

1. drops it if signing is on and the signature is missing or wrong (counted), or if its
   system id is not one of the expected ones (counted);
2. forwards its raw bytes to every output address (QGroundControl, MAVProxy ...);
3. records the sender's HEARTBEAT for discovery and folds the message into that vehicle's
   :class:`~tml.mavlink.telemetry.TelemetryTracker` -- a vehicle's state only ever sees
   its own system id;
4. feeds mission-protocol messages, COMMAND_ACKs and HEARTBEATs to the sans-IO state
   machines running for that vehicle (:meth:`run`; each takes the plain messages of its
   ``inputs``) and sends their answers at once, from the reactor's thread: the time from
   an item request to the item on the wire is one Python call;
5. calls the listeners (:meth:`listen`) with the new snapshot, resumes the vehicle's
   procedures whose step is over (:meth:`begin`), and, when the message changed what the
   vehicle shows (:attr:`~tml.mavlink.telemetry.Telemetry.revision`), the change listeners
   (:meth:`on_change`): a runner woken only then does not step its interpreter for
   messages that repeat what it already knows.

*A TCP vehicle that goes away* (a simulator killed, a server that hangs up) is dialled
again, once every ``REDIAL_PERIOD`` seconds, each attempt bounded by ``REDIAL_TIMEOUT`` and
never waited for (pymavlink's own reconnection sleeps and retries, which would hold up every
link of the process); meanwhile :attr:`Link.down` says why there is no connection, the link
is still served, and the vehicle is lost as below -- and found again when it answers.

It also sends the ground-station HEARTBEAT at 1 Hz, and marks a vehicle *lost* when no
HEARTBEAT has come from it for ``lost_after`` seconds (``Telemetry.link_lost``, cleared by
the next HEARTBEAT): the blocking calls waiting on that vehicle then raise
:class:`~tml.errors.LinkLost` instead of waiting out their own time limits, and a runner
reads the state from the snapshot to command its safe state. The heartbeat, the lost check
and the redial are the link's :meth:`~Link.duties`, carried out by the reactor when due;
the lost check comes when the first vehicle of the link could be lost, not on a fixed beat.
The calling thread uses the link through snapshots (:meth:`telemetry`), :meth:`send`, and
:meth:`run`, which starts a state machine, then sleeps on a condition until an answer or
the machine's deadline and ticks it. A *procedure* (:mod:`tml.mavlink.steps`: a request's
exchanges and waits, one after the other) is carried out either by the calling thread,
waiting through each step (:meth:`drive`), or by the reactor without any thread waiting
(:meth:`begin`): the reactor resumes it when its step's answer arrives, when what it waits
for shows, or when its time is up -- a step's deadline is one of the link's duties.
The reactor rather than the caller reads the sockets because the link must answer the
vehicle (mission item requests, heartbeats) while the interpreter is busy; the interpreter
itself stays I/O-free and reads snapshots.

*Time.* Every wait, deadline and arrival time of the link reads its ``timebase``
(:mod:`tml.timebase`): the system's for real vehicles; the embedded simulator's lock-step
time in ``tml run --sim``, where the reactor's thread takes part (the simulator moves time
on only once it has handled every byte it was sent) and waits on the sockets through the
time base.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import select
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, TypeVar

from tml.errors import LinkLost, VehicleError, VehicleTimeout
from tml.mavlink import codec, reactor
from tml.mavlink.codec import mavlink, mavutil
from tml.mavlink.steps import Exchange, Machine, Step, Steps, Until
from tml.mavlink.telemetry import Telemetry, TelemetryTracker
from tml.signing import signature_first, timestamp_now
from tml.timebase import SYSTEM, Timebase

HEARTBEAT_PERIOD = 1.0
PROGRESS_PERIOD = 0.1
LOST_AFTER = 5.0
"""Default seconds without a HEARTBEAT before a vehicle counts as lost."""
LOST_CHECK_PERIOD = 0.05
REDIAL_PERIOD = 0.5
"""Seconds between two attempts to dial a TCP vehicle that went away."""
REDIAL_TIMEOUT = 1.0
"""Seconds one attempt to dial a TCP vehicle waits for its answer."""
READ_AHEAD = 65536
"""Bytes read from a TCP socket at once: whatever waits there, many messages in one call."""
DRAIN_LIMIT = 1000
"""Messages read at most, before judging a vehicle lost, from what waits in the socket."""
GCS_TYPES = frozenset({mavlink.MAV_TYPE_GCS})
SCHEMES = ("udpin", "udpout", "udp", "tcpin", "tcp")
"""Network address schemes; anything else is a serial device."""


@dataclass(frozen=True)
class Address:
    """A connection address taken apart: ``scheme`` is one of SCHEMES or ``serial``."""

    scheme: str
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = 0


def address_problem(text: str, output: bool = False) -> str | None:
    """What is wrong with a connection address, or None. An ``output`` (a copy of the
    vehicles' messages for a watching ground station) must be a network address."""
    networks = ", ".join(s + ":HOST:PORT" for s in SCHEMES)
    scheme, colon, rest = text.partition(":")
    if colon and scheme in SCHEMES:
        host, _, port = rest.rpartition(":")
        if not host or not port.isdigit() or int(port) > 65535:
            return f"expected {scheme}:HOST:PORT with a port from 0 to 65535"
        return None
    if output:
        return f"not an address a copy can be sent to ({networks})"
    if colon and "/" not in text and "\\" not in text:
        # Not a path: a network address without its scheme, or a scheme misspelt.
        host, _, port = text.rpartition(":")
        example = (f"tcp:{host}:{port} (connect to a vehicle that listens) or udpin:{host}:"
                   f"{port} (listen for one that sends)"
                   if port.isdigit() and host and (":" not in host or host.startswith("["))
                   else
                   "tcp:127.0.0.1:5760 or udpin:0.0.0.0:14550")
        return (f"not an address: a network address starts with its scheme "
                f"({', '.join(s + ':' for s in SCHEMES)}), e.g. {example}; a serial port is "
                f"DEVICE or DEVICE,BAUD (e.g. /dev/ttyUSB0,57600)")
    device, comma, speed = text.partition(",")
    if not device or (comma and not speed.isdigit()):
        return (f"expected DEVICE or DEVICE,BAUD (e.g. /dev/ttyUSB0,57600), or a network "
                f"address ({networks})")
    return None


def parse_address(text: str, baud: int = 57600) -> Address:
    """Take ``udpin:HOST:PORT``, ``tcp:HOST:PORT``, ... or ``DEVICE[,BAUD]`` apart.

    ``baud`` is the serial speed when the address names none. Raises VehicleError saying
    what is wrong with a malformed address (:func:`address_problem`).
    """
    problem = address_problem(text)
    if problem is not None:
        raise VehicleError(f"connection address {text!r}: {problem}")
    scheme, colon, rest = text.partition(":")
    if colon and scheme in SCHEMES:
        host, _, port = rest.rpartition(":")
        return Address(scheme, host=host, port=int(port))
    device, comma, speed = text.partition(",")
    return Address("serial", device=device, baud=int(speed) if comma else baud)


@dataclass(frozen=True)
class VehicleInfo:
    """A vehicle seen on the link: its ids and what its HEARTBEAT says it is."""

    system_id: int
    component_id: int
    vehicle_type: int
    autopilot: int
    components: frozenset[int]


@dataclass
class LinkStats:
    """Counters of what the link dropped, and of the times a vehicle was lost."""

    unexpected_system: int = 0
    unsigned_rejected: int = 0
    bad_signature: int = 0
    bad_data: int = 0
    losses: int = 0
    disconnects: int = 0
    fenced: int = 0
    """Messages not sent because :attr:`Link.gate` refused them."""


Listener = Callable[[int, Telemetry, Any], None]
Ended = Callable[[Any, "BaseException | None"], None]
"""What :meth:`Link.begin` calls when a procedure is over: with its outcome, or with what it
raised (then the outcome is None)."""
T = TypeVar("T")


@dataclass(eq=False)
class _Repeat:
    """A message sent again and again by the reactor (:meth:`Link.repeat`)."""

    send: Callable[[], None]
    period: float
    due: float


@dataclass(eq=False)
class _Procedure:
    """A procedure begun on the link (:meth:`Link.begin`), and the step it waits on."""

    steps: Steps[Any]
    system_id: int
    component_id: int
    on_end: Ended
    step: Step | None = None
    deadline: float = math.inf  # when the step's time is up (a machine's: when it is ticked)


class Link:
    """One MAVLink connection shared by every vehicle on it.

    ``system_ids`` lists the vehicles expected (others are dropped and counted; None
    accepts any). ``outputs`` are extra addresses that receive a copy of every message from
    the vehicles (one way, see docs/connections.md). With ``signing_key`` (32 bytes)
    outgoing messages are signed and incoming ones without a valid signature are dropped.
    A vehicle silent for ``lost_after`` seconds is lost (see the module docstring). Every
    time of the link is read from ``timebase``.
    """

    def __init__(self, address: str, *, outputs: Iterable[str] = (),
                 system_ids: Iterable[int] | None = None, signing_key: bytes | None = None,
                 source_system: int = codec.GCS_SYSTEM_ID,
                 source_component: int = codec.GCS_COMPONENT_ID, baud: int = 57600,
                 lost_after: float = LOST_AFTER, timebase: Timebase = SYSTEM) -> None:
        self.address = address
        self.source_system = source_system
        """The MAVLink system id this ground station sends as."""
        self.timebase = timebase
        self.lost_after = lost_after
        self.stats = LinkStats()
        self._expected = None if system_ids is None else frozenset(system_ids)
        self._signing = signing_key is not None
        self._signed_by: set[int] = set()
        """The vehicles heard signing their messages while this link has no key."""
        self._conn = _connect(address, baud, source_system, source_component)
        self.down = ""
        """Why the connection is down (a TCP vehicle went away), or "" while it is up."""
        if isinstance(self._conn, mavutil.mavtcp):
            _Redial(self._conn, self._went_down)
        # A connection that reads as every mavfile does is read by _receive (UDP's own
        # recv_msg remembers whom to answer).
        self._receive: Callable[[Any], Any] = (
            _receive if type(self._conn).recv_msg is mavutil.mavfile.recv_msg
            else type(self._conn).recv_msg)
        self._reader: _ReadAhead | None = None
        if parse_address(address, baud).scheme in ("tcp", "tcpin"):
            self._reader = _ReadAhead(self._conn)
            if timebase.lockstep:
                _count_bytes(self._conn, timebase)
        self._outputs = [_connect(out, baud, source_system, source_component, output=True)
                         for out in outputs]
        if signing_key is not None:
            if len(signing_key) != 32:
                raise VehicleError("a MAVLink 2 signing key is 32 bytes")
            self._conn.setup_signing(signing_key, sign_outgoing=True,
                                     allow_unsigned_callback=lambda _mav, _msgid: False)
            signature_first(self._conn.mav)  # a keyless frame moves no stream's time stamp
        lock = threading.RLock()
        self._lock = threading.Condition(lock)
        # Woken only when a machine finishes or its deadline comes closer, so that a
        # transfer's caller does not wake (and take the GIL from the reactor) on
        # every message.
        self._machine_done = threading.Condition(lock)
        self._waiting = 0  # threads waiting on _lock for news (changed under it)
        self._send_lock = threading.Lock()
        self._vehicles: dict[int, VehicleInfo] = {}
        self._trackers: dict[int, TelemetryTracker] = {}
        self._machines: dict[int, list[Machine]] = {}
        # Procedures of begin, by vehicle, while they wait on a step (guarded by _lock):
        # from then on only the reactor's thread advances them.
        self._procedures: dict[int, list[_Procedure]] = {}
        self._repeats: list[_Repeat] = []  # guarded by _lock
        self._duty_at = math.inf  # when the reactor carries out duties next (duties said)
        self._listeners: list[Listener] = []
        self._changes: list[Callable[[int], None]] = []
        self._running = False
        self._reactor: reactor.Reactor | None = None
        self._next_heartbeat = self._next_check = -math.inf
        self.gate: Callable[[int], bool] | None = None
        """When set, asked with each message's target system (0: broadcast) before it is
        sent; a message it refuses is dropped and counted (``stats.fenced``). A cluster of
        ``tml serve`` instances fences its vehicles this way (tml.serve.cluster)."""

    # -- life cycle -------------------------------------------------------------------

    def start(self) -> Link:
        """Have the process's reactor serve the link (see the module docstring); returns
        self."""
        if not self._running:
            self._running = True
            self._reactor = reactor.serve(self, self.timebase)
        return self

    def close(self) -> None:
        """Stop serving the link and close the sockets."""
        self._running = False
        if self._reactor is not None:
            reactor.unserve(self, self._reactor)
            self._reactor = None
        self._end_procedures()
        for conn in (self._conn, *self._outputs):
            if getattr(conn, "port", True) is not None:  # a TCP link down has no socket
                with contextlib.suppress(OSError):
                    conn.close()

    @property
    def serving(self) -> bool:
        """True while the reactor's thread serves the link."""
        served = self._reactor
        return served is not None and served.thread is not None and served.thread.is_alive()

    def __enter__(self) -> Link:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- what the caller reads ----------------------------------------------------------

    def vehicles(self) -> dict[int, VehicleInfo]:
        """The vehicles discovered so far, by system id."""
        with self._lock:
            return dict(self._vehicles)

    def wait_vehicle(self, system_id: int | None = None, timeout: float = 10.0) -> VehicleInfo:
        """Wait for a HEARTBEAT from ``system_id`` (any vehicle if None) and describe it."""
        end = self.timebase.now() + timeout
        with self._lock:
            while True:
                found = [v for v in self._vehicles.values()
                         if system_id is None or v.system_id == system_id]
                if found:
                    first = min(found, key=lambda v: v.system_id)
                    if first.system_id in self._signed_by:
                        raise VehicleError(
                            f"{self.address}: the vehicle signs its messages (MAVLink 2 "
                            "signing) and ignores unsigned commands: give its key "
                            "(--signing-key-file, or TML_SIGNING_KEY)",
                            first.system_id)
                    return first
                left = end - self.timebase.now()
                if left <= 0:
                    who = "a vehicle" if system_id is None else f"vehicle {system_id}"
                    raise LinkLost(f"no heartbeat from {who} on {self.address} "
                                   f"within {timeout:g} s{self._signing_hint()}", system_id)
                self._wait_for_news(left)

    def _wait_for_news(self, timeout: float) -> None:
        """Wait (holding ``_lock``) for the next message handled, or ``timeout``. Counted:
        the reactor wakes the waiters of a link only while there are some (a notify with
        nobody waiting cost a tenth of its time at 100 vehicles)."""
        self._waiting += 1
        try:
            self.timebase.wait(self._lock, timeout)
        finally:
            self._waiting -= 1

    def _signing_hint(self) -> str:
        """Why nothing was heard, when signing dropped what came (a vehicle that does not
        sign, or signs with another key); "" otherwise."""
        if not self._signing:
            return ""
        unsigned, bad = self.signing_counts
        if not unsigned and not bad:
            return ""
        return (f" (signing: {unsigned} unsigned and {bad} wrongly signed message(s) "
                "dropped: the vehicle does not sign with this key)")

    @property
    def local_address(self) -> tuple[str, int] | None:
        """The (host, port) a ``udpin:``/``udp:``/``tcpin:`` link listens on, else None.

        With port 0 in the address the system picks the port; this tells which.
        """
        sock = getattr(self._conn, "listen", None)  # tcpin
        if sock is None and getattr(self._conn, "udp_server", False):
            sock = self._conn.port
        return None if sock is None else sock.getsockname()[:2]

    def telemetry(self, system_id: int) -> Telemetry:
        """The latest snapshot of one vehicle (empty if nothing was heard from it yet)."""
        with self._lock:
            tracker = self._trackers.get(system_id)
            return tracker.snapshot if tracker else Telemetry(system_id)

    def revision(self, system_id: int) -> int:
        """The latest snapshot's :attr:`~tml.mavlink.telemetry.Telemetry.revision`, read
        without the lock (a runner asks it of every vehicle on every wake)."""
        tracker = self._trackers.get(system_id)
        return 0 if tracker is None else tracker.revision

    def arrivals(self, system_id: int) -> dict[str, float]:
        """When each kind of message last came from the vehicle's autopilot (s of the
        time base)."""
        with self._lock:
            tracker = self._trackers.get(system_id)
            return dict(tracker.arrived) if tracker else {}

    def wait_telemetry(self, system_id: int, until: Callable[[Telemetry], bool],
                       timeout: float, *, lost_ok: bool = False) -> Telemetry:
        """Wait until ``until(snapshot)`` holds.

        Raises VehicleTimeout after ``timeout``, and LinkLost as soon as the vehicle is
        lost unless ``lost_ok`` (to wait for a lost vehicle to come back).
        """
        found: list[Telemetry] = []

        def holds() -> bool:
            snapshot = self.telemetry(system_id)
            if until(snapshot):
                found.append(snapshot)
            return bool(found)
        self._wait_until(system_id, Until(holds, timeout, "condition", lost_ok))
        return found[0]

    def listen(self, listener: Listener) -> None:
        """Call ``listener(system_id, snapshot, msg)`` from the reactor on each message.

        Listeners must return quickly: they hold up the link.
        """
        self._listeners.append(listener)

    def on_change(self, listener: Callable[[int], None]) -> None:
        """Call ``listener(system_id)`` from the reactor whenever a vehicle's snapshot
        changes what it shows: a new :attr:`~tml.mavlink.telemetry.Telemetry.revision`, from
        a message or from the link found lost. Listeners must return quickly."""
        self._changes.append(listener)

    @property
    def signing_counts(self) -> tuple[int, int]:
        """(messages dropped for a missing signature, for a wrong one)."""
        signing = self._conn.mav.signing
        return signing.reject_count - signing.badsig_count, signing.badsig_count

    # -- what the caller sends ----------------------------------------------------------

    def send(self, msg: Any, system_id: int = 0, component_id: int = 0) -> None:
        """Send a plain message (addressed here) or a ready pymavlink message."""
        if not isinstance(msg, mavlink.MAVLink_message):
            msg = codec.encode(msg, system_id, component_id)
        gate = self.gate
        if gate is not None and not gate(getattr(msg, "target_system", 0)):
            self.stats.fenced += 1
            return
        with self._send_lock:
            signing = self._conn.mav.signing
            if signing.sign_outgoing:  # stamps that follow the clock, not one up per frame
                signing.timestamp = max(signing.timestamp, timestamp_now())
            self._conn.mav.send(msg)

    def run(self, machine: Machine, system_id: int, component_id: int,
            on_progress: Callable[[Machine], None] | None = None) -> Machine:
        """Drive a sans-IO ``machine`` with this vehicle until it is done; returns it.

        The reactor feeds the machine and sends its answers; this thread only
        sleeps until the machine is done or its deadline passes (then ticks it), waking
        every ``PROGRESS_PERIOD`` to report progress if ``on_progress`` is given. Raises
        LinkLost once the vehicle is lost: a machine started for a lost vehicle still
        sends its first message (the way up may work when the way down does not), but
        its retries are not waited out.
        """
        self._not_on_the_reactor(type(machine).__name__)
        with self._lock:
            self._machines.setdefault(system_id, []).append(machine)
            self._send_all(machine.start(self.timebase.now()), system_id, component_id)
        try:
            with self._lock:
                while not machine.done:
                    self._raise_if_lost(self.telemetry(system_id),
                                        f"during {type(machine).__name__}")
                    wait = machine.deadline - self.timebase.now()
                    if on_progress is not None:
                        wait = min(wait, PROGRESS_PERIOD)
                    if wait > 0:
                        self.timebase.wait(self._machine_done, min(wait, 1.0))
                    self._send_all(machine.tick(self.timebase.now()), system_id,
                                   component_id)
                    if on_progress is not None:
                        on_progress(machine)
        finally:
            with self._lock:
                self._machines[system_id].remove(machine)
        return machine

    def _send_all(self, msgs: list[Any], system_id: int, component_id: int) -> None:
        for msg in msgs:
            self.send(msg, system_id, component_id)

    # -- procedures (tml.mavlink.steps) ---------------------------------------------------

    def drive(self, steps: Steps[T], system_id: int, component_id: int) -> T:
        """Carry out a procedure on the calling thread, which waits through each of its
        steps (:meth:`run` for an Exchange); returns its outcome, raises what it raises."""
        error: BaseException | None = None
        while True:
            try:
                step = steps.send(None) if error is None else steps.throw(error)
            except StopIteration as stop:
                outcome: T = stop.value
                return outcome
            error = None
            try:
                if isinstance(step, Exchange):
                    self.run(step.machine, system_id, component_id, step.on_progress)
                else:
                    self._wait_until(system_id, step)
            except VehicleError as caught:
                error = caught

    def _wait_until(self, system_id: int, step: Until) -> None:
        self._not_on_the_reactor(f"waiting for {step.what}")
        end = self.timebase.now() + step.timeout
        with self._lock:
            while not step.holds():
                if not step.lost_ok:
                    self._raise_if_lost(self.telemetry(system_id), f"while waiting for {step.what}")
                left = end - self.timebase.now()
                if left <= 0:
                    raise _timed_out(step, system_id)
                self._wait_for_news(left)

    def begin(self, steps: Steps[Any], system_id: int, component_id: int,
              on_end: Ended) -> None:
        """Carry out a procedure without waiting: it runs on the calling thread up to its
        first step (so that its first message goes out at once), then the reactor drives
        it -- feeds each Exchange's machine the vehicle's answers, asks each Until again
        after each message from the vehicle, resumes the procedure when its step is over,
        and ticks or ends a step whose time is up. ``on_end(outcome, error)`` is called
        when the procedure is over, from the thread that resumed it last. Between its steps
        a procedure's code must be quick and never wait (a wait on the reactor's thread is
        refused, see :meth:`run`)."""
        procedure = _Procedure(steps, system_id, component_id, on_end)
        self._advance(procedure, None if self._running else self._closed(system_id))

    def _end_procedures(self) -> None:
        """The link closed: each procedure not over ends with LinkLost."""
        with self._lock:
            waiting = [p for ps in self._procedures.values() for p in ps]
        for procedure in waiting:
            self._release(procedure)
            self._advance(procedure, self._closed(procedure.system_id))

    def repeat(self, send: Callable[[], None], period: float) -> Callable[[], None]:
        """Call ``send`` every ``period`` seconds of the time base from the reactor's thread
        (the first time one period from now), until the function returned is called."""
        repeat = _Repeat(send, period, self.timebase.now() + period)
        with self._lock:
            self._repeats.append(repeat)

        def stop() -> None:
            with self._lock:
                if repeat in self._repeats:
                    self._repeats.remove(repeat)
        self._due_by(repeat.due)
        return stop

    def _repeats_due(self, now: float) -> None:
        """Send the repeated messages that are due."""
        with self._lock:
            due = [r for r in self._repeats if r.due <= now]
        for repeat in due:
            with contextlib.suppress(OSError):  # a link gone: the vehicle's own time-out
                repeat.send()
            repeat.due = now + repeat.period

    def _hurry(self) -> None:
        served = self._reactor
        if served is not None:
            served.hurry(self)

    def _due_by(self, when: float) -> None:
        """A step's time is up at ``when``: the reactor comes by then. (Compared under the
        lock with what duties last said, which they work out under it: a step registered
        while they ran is either in their answer or hurries them.)"""
        with self._lock:
            sooner = when < self._duty_at
            if sooner:
                self._duty_at = when
        if sooner:
            self._hurry()

    def _advance(self, procedure: _Procedure, error: BaseException | None) -> None:
        """Resume ``procedure`` (throwing ``error`` into it) up to its next step that
        waits, or to its end."""
        while True:
            try:
                step = procedure.steps.send(None) if error is None \
                    else procedure.steps.throw(error)
            except StopIteration as stop:
                _end(procedure, stop.value, None)
                return
            except Exception as failed:  # its result says so (on_end), not the reactor
                _end(procedure, None, failed)
                return
            waits, error = self._wait_on(procedure, step)
            if waits:
                return  # the reactor's from now on: not touched here again

    def _wait_on(self, procedure: _Procedure, step: Step
                 ) -> tuple[bool, BaseException | None]:
        """Start ``step``; unless it is over at once (False, and the error it ends with),
        hand the procedure to the reactor, waiting on it (True)."""
        system_id = procedure.system_id
        now = self.timebase.now()
        if not self._running:
            return False, self._closed(system_id)
        if isinstance(step, Until):
            if step.holds():
                return False, None
            lost = None if step.lost_ok else self._lost(self.telemetry(system_id),
                                                        f"while waiting for {step.what}")
            if lost is not None:
                return False, lost
            if step.timeout <= 0:
                return False, _timed_out(step, system_id)
            deadline = now + step.timeout
        with self._lock:
            if isinstance(step, Exchange):
                machine = step.machine
                self._machines.setdefault(system_id, []).append(machine)
                self._send_all(machine.start(now), system_id, procedure.component_id)
                # Its first message goes even to a vehicle lost: the way up may work when
                # the way down does not; its retries are not waited out (as run).
                lost = None if machine.done else self._lost(
                    self.telemetry(system_id), f"during {type(machine).__name__}")
                if machine.done or lost is not None:
                    self._machines[system_id].remove(machine)
                    return False, lost
                deadline = machine.deadline
            procedure.step, procedure.deadline = step, deadline
            self._procedures.setdefault(system_id, []).append(procedure)
        self._due_by(deadline)
        return True, None

    def _release(self, procedure: _Procedure) -> None:
        """The procedure's step is over: no longer waited on (nor its machine fed)."""
        step, procedure.step = procedure.step, None
        with self._lock:
            waiting = self._procedures.get(procedure.system_id, [])
            if procedure in waiting:
                waiting.remove(procedure)
            if isinstance(step, Exchange):
                machines = self._machines.get(procedure.system_id, [])
                if step.machine in machines:
                    machines.remove(step.machine)

    def _resume(self, system_id: int) -> None:
        """After a message from the vehicle: resume each of its procedures whose step is
        over (a machine done, an Until that holds)."""
        with self._lock:
            waiting = list(self._procedures.get(system_id, ()))
        for procedure in waiting:
            step = procedure.step
            if isinstance(step, Exchange):
                machine = step.machine
                if step.on_progress is not None:
                    step.on_progress(machine)
                if machine.done:
                    self._release(procedure)
                    self._advance(procedure, None)
                elif machine.deadline < procedure.deadline:
                    procedure.deadline = machine.deadline
                    self._due_by(machine.deadline)
            elif step is not None and step.holds():
                self._release(procedure)
                self._advance(procedure, None)

    def _procedures_due(self, now: float) -> None:
        """Tick or end the steps whose time is up, or whose vehicle is lost."""
        with self._lock:
            waiting = [p for ps in self._procedures.values() for p in ps]
        for procedure in waiting:
            step = procedure.step
            if step is None:
                continue  # over meanwhile (a message resumed it)
            snapshot = self.telemetry(procedure.system_id)
            if isinstance(step, Exchange):
                machine = step.machine
                if procedure.deadline <= now:
                    with self._lock:
                        self._send_all(machine.tick(now), procedure.system_id,
                                       procedure.component_id)
                    procedure.deadline = machine.deadline
                lost = self._lost(snapshot, f"during {type(machine).__name__}")
                if machine.done or lost is not None:
                    self._release(procedure)
                    self._advance(procedure, None if machine.done else lost)
            elif step.holds():
                self._release(procedure)
                self._advance(procedure, None)
            elif not step.lost_ok and snapshot.link_lost:
                self._release(procedure)
                self._advance(procedure, self._lost(snapshot, f"while waiting for {step.what}"))
            elif procedure.deadline <= now:
                self._release(procedure)
                self._advance(procedure, _timed_out(step, procedure.system_id))

    def _steps_due(self) -> float:
        """When the next procedure's step or repeated message is due (_lock held)."""
        return min(min((p.deadline for ps in self._procedures.values() for p in ps),
                       default=math.inf),
                   min((r.due for r in self._repeats), default=math.inf))

    def _raise_if_lost(self, snapshot: Telemetry, doing: str) -> None:
        lost = self._lost(snapshot, doing)
        if lost is not None:
            raise lost

    def _lost(self, snapshot: Telemetry, doing: str) -> LinkLost | None:
        if not snapshot.link_lost:
            return None
        age = snapshot.heartbeat_age(self.timebase.now())
        return LinkLost(f"link lost {doing}: no HEARTBEAT for {age:.1f} s "
                        f"(limit {self.lost_after:g} s) on {self.address}", snapshot.system_id)

    def _closed(self, system_id: int) -> LinkLost:
        return LinkLost(f"the link to {self.address} is closed", system_id)

    def _not_on_the_reactor(self, doing: str) -> None:
        """A wait on the reactor's own thread would wait for itself: a procedure yields its
        steps instead (:meth:`begin`)."""
        served = self._reactor
        if served is not None and served.thread is threading.current_thread():
            raise VehicleError(f"{doing} would wait on the MAVLink reactor's own thread")

    # -- served by the reactor (its thread) ----------------------------------------------

    def fileno(self) -> int | None:
        """The socket (or serial port) to watch; None while a TCP vehicle is gone."""
        if self._running and self._conn_up():
            fd: int = self._conn.fd
            return fd
        return None

    def readable(self, limit: int) -> bool:
        """Handle up to ``limit`` messages that wait (read from the socket, or whole in the
        parser already); True when more may wait."""
        conn, receive = self._conn, self._receive
        if self._reader is not None:
            self._reader.turn()
        for _ in range(limit):
            try:
                msg = receive(conn)
            except (OSError, ValueError) as error:
                if self._running:
                    # The vehicle went away: a later duty dials it again (see _Redial);
                    # its silence is judged by the lost check, as any other silence.
                    self._went_down(error)
                return False
            if msg is None:
                return False
            if self.down and self._conn_up():
                self.down = ""
            self._handle(msg, self.timebase.now())
        return True

    def duties(self, now: float) -> float:
        """The heartbeat, the lost check and, while a TCP vehicle is gone, its redial, when
        due; returns when the next is due."""
        if not self._running:
            return now + HEARTBEAT_PERIOD
        if now >= self._next_heartbeat:
            self._heartbeat()
            self._next_heartbeat = now + HEARTBEAT_PERIOD
        try:
            if now >= self._next_check:
                self._check_lost(now)  # may read the socket too
                self._next_check = max(now + LOST_CHECK_PERIOD, self._first_loss(now))
            if not self._conn_up():
                self.readable(DRAIN_LIMIT)  # dials again (_Redial), at most as often as it may
        except (OSError, ValueError) as error:
            self._went_down(error)
        later = self.timebase.now()  # (the duties above may have read the sockets)
        self._procedures_due(later)
        self._repeats_due(later)
        with self._lock:
            due = min(self._next_heartbeat, self._steps_due(),
                      self._next_check if self._conn_up() else now + LOST_CHECK_PERIOD)
            self._duty_at = due
        return due

    def _first_loss(self, now: float) -> float:
        """When the first vehicle not lost yet would be, without another HEARTBEAT: the
        next lost check need not come sooner (one for each vehicle's limit, not 20 a
        second for each link)."""
        with self._lock:
            beats = [t.snapshot.last_heartbeat for t in self._trackers.values()
                     if not t.snapshot.link_lost and t.snapshot.last_heartbeat is not None]
        return min(beats, default=now) + self.lost_after

    def _went_down(self, error: BaseException) -> None:
        reason = _reason(error)
        if not self.down:
            self.stats.disconnects += 1
        self.down = reason

    def _conn_up(self) -> bool:
        return getattr(self._conn, "port", True) is not None

    def _heartbeat(self) -> None:
        # udpin before any peer, or a TCP peer gone: nothing to send to yet.
        with contextlib.suppress(OSError):
            self.send(codec.gcs_heartbeat())

    def _check_lost(self, now: float) -> None:
        with self._lock:
            losing = any(not t.snapshot.link_lost and t.snapshot.heartbeat_age(now)
                         > self.lost_after for t in self._trackers.values())
        if losing:
            # Read what already waits in the socket first: after this thread was held up
            # (a slow listener, a busy machine) the HEARTBEATs may be there, not missing.
            # A connection gone down has nothing waiting: the receive says why.
            with contextlib.suppress(OSError, ValueError):
                self.readable(DRAIN_LIMIT)
            now = self.timebase.now()
        with self._lock:
            changed = [t for t in self._trackers.values() if t.check_link(now, self.lost_after)]
            self.stats.losses += sum(t.snapshot.link_lost for t in changed)
            if changed:
                self.timebase.notify_all(self._lock)
                self.timebase.notify_all(self._machine_done)
            ids = [t.snapshot.system_id for t in changed]
        for system_id in ids:
            for change in self._changes:
                change(system_id)

    def _handle(self, msg: Any, now: float) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            self.stats.bad_data += 1
            return
        sysid = msg.get_srcSystem()
        if self._expected is not None and sysid not in self._expected:
            self.stats.unexpected_system += 1
            return
        if self._outputs:
            raw = msg.get_msgbuf()
            for out in self._outputs:
                with contextlib.suppress(OSError):  # a watcher gone must not stop a flight
                    out.write(raw)
        with self._lock:
            if not self._signing and _signed(msg):
                self._signed_by.add(sysid)
            if kind == "HEARTBEAT":
                self._discover(msg, sysid)
            tracker = self._trackers.get(sysid)
            revision = -1 if tracker is None else tracker.revision
            if tracker is None or not tracker.apply(msg, now):
                if self._waiting:
                    self.timebase.notify_all(self._lock)
                return
            machines = self._machines.get(sysid)
            plain = codec.decode(msg) if machines else None  # no plain message unless asked
            if plain is not None and self._for_us(msg, tracker):
                for machine in list(machines or ()):
                    if isinstance(plain, machine.inputs):
                        info = self._vehicles[sysid]
                        deadline = machine.deadline
                        self._send_all(machine.receive(plain, now), sysid, info.component_id)
                        if machine.done or machine.deadline < deadline:
                            self.timebase.notify_all(self._machine_done)
            snapshot = tracker.snapshot if self._listeners else None
            changed = tracker.revision != revision
            if self._waiting:
                self.timebase.notify_all(self._lock)
        if snapshot is not None:
            for listener in self._listeners:
                listener(sysid, snapshot, msg)
            with self._lock:  # what a listener kept (a parameter's value) may end a wait
                if self._waiting:
                    self.timebase.notify_all(self._lock)
        if self._procedures.get(sysid):
            self._resume(sysid)
        if changed:
            for change in self._changes:
                change(sysid)

    def _for_us(self, msg: Any, tracker: TelemetryTracker) -> bool:
        # Another ground station on the same link has its own transfers with the vehicle.
        target = getattr(msg, "target_system", 0)
        return (msg.get_srcComponent() == tracker.autopilot_component
                and target in (0, self._conn.mav.srcSystem))

    def _discover(self, msg: Any, sysid: int) -> None:
        """A HEARTBEAT: note the vehicle (or the component of one) it comes from."""
        if msg.type in GCS_TYPES:
            return
        component = msg.get_srcComponent()
        known = self._vehicles.get(sysid)
        if msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID:
            # A camera, gimbal or companion computer of a vehicle: a component, not a vehicle.
            if known is not None:
                self._vehicles[sysid] = _with_component(known, component)
            return
        if known is None:
            self._vehicles[sysid] = VehicleInfo(sysid, component, msg.type, msg.autopilot,
                                                frozenset({component}))
            self._trackers[sysid] = TelemetryTracker(sysid, autopilot_component=component)
        else:
            self._vehicles[sysid] = _with_component(known, component)


def _signed(msg: Any) -> bool:
    """Whether a message came signed (MAVLink 2's incompatibility flag), whether or not
    the signature could be checked."""
    header = getattr(msg, "_header", None)
    return header is not None and bool(header.incompat_flags & mavlink.MAVLINK_IFLAG_SIGNED)


def _receive(conn: Any) -> Any:
    """The next message of a connection, None when no whole one waits: ``mavfile.recv_msg``
    without its ``post_message``, whose bookkeeping (the last message of each type, the
    flight mode, parameters, losses) tml keeps itself (TelemetryTracker), and which cost
    each message of each vehicle as much as a third of its parse. The message is stamped
    with its arrival (``_timestamp``, wall time) as pymavlink stamps it."""
    mav = conn.mav
    while True:
        data = conn.recv(mav.bytes_needed())
        if data and conn.first_byte:
            conn.auto_mavlink_version(data)
            mav = conn.mav
        msg = mav.parse_char(data)
        if msg:
            msg._timestamp = time.time()
            return msg
        if not data:
            return None


class _ReadAhead:
    """Makes a TCP connection read what waits in its socket at once, once per turn.

    pymavlink reads each message with two or three ``recv`` calls of exactly the bytes its
    parser needs next; every call lets go of the interpreter lock and takes it back, and
    with a receive thread per vehicle (as links once had) that hand-over was most of their cost
    (54,159 calls for 20,420 messages of 20 vehicles in docs/performance.md). Here a call
    reads up to :data:`READ_AHEAD` bytes, and none while the parser can go on with what it
    has buffered: one call for everything that arrived since the last.

    Within one turn of the reactor (:meth:`turn` begins it) the socket is read once, and
    again only after a read that filled :data:`READ_AHEAD` (more may wait): a second read
    of a socket just emptied finds nothing, and costs a system call, an exception inside
    pymavlink and a hand-over of the interpreter lock to the runner, for each vehicle at
    each turn. Whatever arrives after the read wakes the reactor again.
    """

    def __init__(self, conn: Any) -> None:
        self.read, self.parser = conn.recv, conn.mav
        self.may_read = True
        conn.recv = self

    def turn(self) -> None:
        """A new turn: the socket may be read again."""
        self.may_read = True

    def __call__(self, n: int | None = None) -> Any:
        if not self.may_read or self.parser.buf_len() >= self.parser.expected_length:
            return b""
        data = self.read(READ_AHEAD)
        self.may_read = len(data) >= READ_AHEAD
        return data


def _count_bytes(conn: Any, timebase: Timebase) -> None:
    """Tell ``timebase`` every byte a TCP connection sends and reads (a lock-step simulator
    moves time on only once every byte sent has been read: see :mod:`tml.timebase`)."""
    read, write = conn.recv, conn.write
    connection = conn.port.getsockname()
    timebase.track(connection)

    def recv(n: int | None = None) -> Any:
        data = read(n)
        timebase.carried(connection, -len(data))
        return data

    def counted(buf: bytes) -> None:
        write(buf)
        timebase.carried(connection, len(buf))

    conn.recv, conn.write = recv, counted


def _with_component(info: VehicleInfo, component: int) -> VehicleInfo:
    if component in info.components:
        return info
    return VehicleInfo(info.system_id, info.component_id, info.vehicle_type, info.autopilot,
                       info.components | {component})


def _connect(address: str, baud: int, source_system: int, source_component: int,
             output: bool = False) -> Any:
    parsed = parse_address(address, baud)
    if parsed.scheme == "serial":
        address, baud = parsed.device, parsed.baud
    try:
        # ``udp:`` listens (pymavlink's default), except as an output: there it sends to the
        # address, as MAVProxy's and the simulator's ``--out udp:HOST:PORT`` do.
        return mavutil.mavlink_connection(address, baud=baud, source_system=source_system,
                                          source_component=source_component,
                                          dialect="ardupilotmega", autoreconnect=True,
                                          input=not (output and parsed.scheme == "udp"))
    except ModuleNotFoundError as error:  # pyserial, a dependency: a broken installation
        raise LinkLost(f"cannot open serial port {address!r}: {error} (pip install "
                       "pyserial)") from error
    except (OSError, ValueError) as error:
        if parsed.scheme == "serial":
            # pyserial's own words repeat the device and the errno: the system's cause is
            # what it wraps.
            cause = error.__context__ if isinstance(error.__context__, OSError) else error
            raise LinkLost(f"cannot open serial port {address}: {_reason(cause)}"
                           ) from error
        raise LinkLost(f"cannot open MAVLink connection {address!r}: {_reason(error)}"
                       ) from error


def _reason(error: BaseException) -> str:
    """An OS error said as the system says it ("Connection refused"), without its number."""
    return str(error.strerror if isinstance(error, OSError) and error.strerror else error)


class _Redial:
    """Dials a pymavlink TCP connection again when its peer went away, in place of
    pymavlink's own reconnection (see the module docstring): at most once every
    REDIAL_PERIOD, each attempt bounded by REDIAL_TIMEOUT, the socket and the descriptor
    the reactor watches both replaced. An attempt never waits: the connection is begun, and
    looked at again at each later call until it is made, refused or out of time -- the
    thread that serves every link must not stop for one vehicle's silence. Meanwhile the
    caller gets an OSError saying why (a write drops its message; the reactor tries again
    at its next duty).
    """

    def __init__(self, conn: Any, on_down: Callable[[BaseException], None]) -> None:
        self.conn = conn
        self.on_down = on_down
        self.last = 0.0
        self.why: OSError = ConnectionResetError("connection closed by the vehicle")
        self.dialling: socket.socket | None = None
        self.lock = threading.Lock()
        conn.reconnect = conn.handle_eof = conn.handle_disconnect = self.redial

    def redial(self) -> None:
        with self.lock:
            conn = self.conn
            if conn.port is not None:
                with contextlib.suppress(OSError):
                    conn.port.close()
                conn.port = None
                self.on_down(self.why)
            if self.dialling is None:
                now = time.monotonic()
                if now - self.last < REDIAL_PERIOD:
                    raise self.why
                self.last = now
                self._dial()
            sock = self._answered()
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn.port, conn.fd = sock, sock.fileno()
            self.why = ConnectionResetError("connection closed by the vehicle")

    def _dial(self) -> None:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setblocking(False)
        code = sock.connect_ex(self.conn.destination_addr)
        if code not in (0, errno.EINPROGRESS, errno.EWOULDBLOCK):
            sock.close()
            self._failed(OSError(code, os.strerror(code)))
        self.dialling = sock

    def _answered(self) -> socket.socket:
        """The socket dialled, once connected; raises why not while it is not (yet)."""
        sock = self.dialling
        assert sock is not None
        _, writable, _ = select.select([], [sock], [], 0)
        if not writable:
            if time.monotonic() - self.last < REDIAL_TIMEOUT:
                raise self.why
            self.dialling = None
            sock.close()
            self._failed(TimeoutError("timed out"))
        self.dialling = None
        code = sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
        if code:
            sock.close()
            self._failed(OSError(code, os.strerror(code)))
        return sock

    def _failed(self, error: OSError) -> None:
        self.why = error
        self.on_down(error)
        raise error


def _end(procedure: _Procedure, outcome: Any, error: BaseException | None) -> None:
    """Tell the procedure's end; a failure of the one told is reported as a thread's would
    be, and goes no further: the reactor serves every other vehicle of the process."""
    try:
        procedure.on_end(outcome, error)
    except Exception:
        exc_type, exc_value, traceback = sys.exc_info()
        assert exc_type is not None
        threading.excepthook(threading.ExceptHookArgs(
            (exc_type, exc_value, traceback, threading.current_thread())))


def _timed_out(step: Until, system_id: int) -> VehicleTimeout:
    return VehicleTimeout(f"{step.what} not reached within {step.timeout:g} s", system_id)
