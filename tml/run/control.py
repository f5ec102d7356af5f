"""A running ``tml run``'s control socket: an operator's command goes through the run.

Theory of operation
-------------------
One controller at a time. A ``tml command`` sent straight to a vehicle that a run flies
would be undone by the run's next target (both are ground stations of system 255, so the
vehicle's mode need not change, and the run would not notice). So while a run flies, it
listens on a local Unix socket per vehicle (:func:`control_path`): in the per-user runtime
directory (:func:`runtime_dir`: ``$TML_RUNTIME_DIR``, else ``$XDG_RUNTIME_DIR/tml``, else
``/tmp/tml-UID``; the directory is the user's alone, mode 0700, and the socket 0600),
named after the vehicle's address (:func:`address_key`: two spellings of one address are
one) and its MAVLink system id.
``tml command`` with the same address and system id connects there first
(:func:`ask_run`) and falls back to the vehicle itself only when nothing listens (no run,
or a socket a dead run left behind, which the next run to listen replaces).

The exchange is one JSON line each way: ``{"command": "hold", "system_id": 1, "timeout":
30}``, answered by ``{"outcome": ..., "message": ..., "exit_code": ...}`` once the vehicle's
telemetry confirmed the command (:class:`~tml.engine.confirm.Confirmation`) or the
timeout passed. A peer of another user is refused (``SO_PEERCRED``).

The run carries the command out as ``tml serve`` does (:class:`OperatorDesk`): refused
with the reason when :func:`~tml.engine.safety.operator_request` refuses it (a disarm in
the air); ``hold`` pauses the run (every vehicle of it holds, the journal's ``control``
line says "mission paused: operator command hold"); ``rtl`` and ``land`` end the run into
that safe state, ``disarm`` (on the ground) into its own (:meth:`Runner.take_over
<tml.run.runner.Runner.take_over>`, as the service's command: the run ends taken by the
operator), the reason "operator command: ..." in the outcome.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import socket
import stat
import struct
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from tml.engine.confirm import Confirmation
from tml.engine.safety import CommandRefusal, operator_request
from tml.errors import ControlRefused, ExitCode, VehicleError
from tml.vehicle import Vehicle, VehicleState

if TYPE_CHECKING:
    from tml.mavlink.targets import TargetWatch
    from tml.run.runner import Runner

ENVIRONMENT = "TML_RUNTIME_DIR"
"""The environment variable that names the directory of the control sockets."""
POLL_PERIOD = 0.05  # s between two looks at a vehicle's state while confirming
MAX_REQUEST = 4096  # bytes: a request line longer than this is refused


class ControlUnsafe(OSError):
    """The control sockets' directory is not the user's alone."""


def runtime_dir() -> str:
    """The directory of the control sockets (module docstring), made if missing; raises
    :class:`ControlUnsafe` when it belongs to another user or others may enter it."""
    base = os.environ.get(ENVIRONMENT)
    if not base:
        xdg = os.environ.get("XDG_RUNTIME_DIR")
        base = os.path.join(xdg, "tml") if xdg and os.path.isdir(xdg) \
            else os.path.join("/tmp", f"tml-{os.getuid()}")
    os.makedirs(base, mode=0o700, exist_ok=True)
    info = os.stat(base)
    if info.st_uid != os.getuid() or info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ControlUnsafe(f"{base}: not the user's alone (owner {info.st_uid}, mode "
                            f"{stat.S_IMODE(info.st_mode):o}); control sockets need mode 0700")
    return base


def control_path(address: str, system_id: int, directory: str | None = None) -> str:
    """The control socket of the run flying vehicle ``system_id`` at ``address``:
    ``run-<digest of the address>-<system id>.sock``."""
    return os.path.join(directory or runtime_dir(), f"{_prefix(address)}{system_id}.sock")


def _prefix(address: str) -> str:
    return f"run-{hashlib.sha256(address_key(address).encode()).hexdigest()[:20]}-"


def address_key(address: str) -> str:
    """The vehicle's address as its control socket is named after it: one vehicle reached
    by two spellings of one address is one key -- a host name is resolved
    (``tcp:localhost:5760`` is ``tcp:127.0.0.1:5760``; IPv4 first), a serial device is
    followed through its links (``/dev/serial/by-id/...`` is the ``/dev/ttyUSB0`` it
    points to) and its speed left out. An address that cannot be taken apart is kept as
    written (the run refuses it before it listens anyway)."""
    from tml.mavlink.link import parse_address  # the MAVLink layer: only when one is named

    try:
        parsed = parse_address(address.strip())
    except VehicleError:
        return address.strip()
    if parsed.scheme == "serial":
        return f"serial:{os.path.realpath(parsed.device)}"
    return f"{parsed.scheme}:{_numeric_host(parsed.host, parsed.port)}:{parsed.port}"


def _numeric_host(host: str, port: int) -> str:
    """``host`` as the address the system resolves it to (IPv4 first); as written when it
    does not resolve (the run could not reach it either)."""
    try:
        found = socket.getaddrinfo(host.strip("[]"), port, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError):
        return host
    numbers = [str(info[4][0]) for info in found]
    return next((n for n in numbers if ":" not in n), numbers[0] if numbers else host)


def runs_at(address: str) -> list[int]:
    """The system ids of the vehicles at ``address`` a live run listens for (sockets a
    dead run left behind are not counted)."""
    try:
        directory = runtime_dir()
        names = os.listdir(directory)
    except OSError:
        return []
    prefix, found = _prefix(address), []
    for name in sorted(names):
        number = name[len(prefix):-len(".sock")]
        if name.startswith(prefix) and name.endswith(".sock") and number.isdigit() \
                and _alive(os.path.join(directory, name)):
            found.append(int(number))
    return sorted(found)


def _alive(path: str) -> bool:
    """Whether a run listens on the socket ``path``."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:
        try:
            probe.connect(path)
        except OSError:
            return False
        return True


@dataclass(frozen=True)
class Answer:
    """The run's answer to an operator's command."""

    outcome: str  # "done", "nothing to do", "refused", "not confirmed", "no run"
    message: str
    exit_code: int


def ask_run(address: str, system_id: int, command: str, timeout: float) -> Answer | None:
    """Send ``command`` to the run flying vehicle ``system_id`` at ``address``, and wait
    for its answer (up to ``timeout`` s for the confirmation, and a little more). None when
    no run listens there (no socket, or a dead run's)."""
    try:
        path = control_path(address, system_id)
    except OSError:
        return None
    if not os.path.exists(path):
        return None
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as peer:
        # The run waits up to ``timeout`` for its loop to take a pause, then as long for
        # the confirmation: its own waits end first.
        peer.settimeout(2 * timeout + 30.0)
        try:
            peer.connect(path)
        except (ConnectionRefusedError, FileNotFoundError):
            return None  # a dead run's socket
        peer.sendall(json.dumps({"command": command, "system_id": system_id,
                                 "timeout": timeout}).encode() + b"\n")
        try:
            reply = _read_line(peer)
        except OSError as error:  # (a timeout too)
            return Answer("not confirmed", f"the run did not answer: {error}",
                          int(ExitCode.FAILURE))
    if reply is None:
        return Answer("not confirmed", "the run closed the control socket without an answer",
                      int(ExitCode.FAILURE))
    try:
        data = json.loads(reply)
        return Answer(str(data["outcome"]), str(data["message"]), int(data["exit_code"]))
    except (ValueError, KeyError, TypeError):
        return Answer("not confirmed", f"the run's answer cannot be read: {reply[:80]!r}",
                      int(ExitCode.FAILURE))


def _read_line(peer: socket.socket) -> str | None:
    data = b""
    while b"\n" not in data and len(data) <= MAX_REQUEST:
        chunk = peer.recv(1024)
        if not chunk:
            break
        data += chunk
    line, newline, _ = data.partition(b"\n")
    return line.decode("utf-8", "replace") if newline else None


class OperatorDesk:
    """Carries out an operator's command on a vehicle of ``runner`` (module docstring).

    ``vehicles`` are the run's vehicles by MAVLink system id; ``vehicle_time`` gives a
    vehicle's own time (s) for a state of it (the confirmation's thresholds are in it)."""

    def __init__(self, runner: Runner, vehicles: Mapping[int, Vehicle],
                 vehicle_time: Callable[[Vehicle, VehicleState], float] | None = None) -> None:
        self.runner = runner
        self.vehicles = dict(vehicles)
        self.vehicle_time = vehicle_time or own_time
        self._targets = TargetWatches()  # by system id

    def command(self, system_id: int, command: str, timeout: float) -> Answer:
        vehicle = self.vehicles.get(system_id)
        if vehicle is None:
            return Answer("no run", f"the run flies no vehicle {system_id}",
                          int(ExitCode.FAILURE))
        who = _who(vehicle, system_id)
        state = vehicle.state()
        try:
            request = operator_request(state, command)
        except CommandRefusal as refusal:
            return Answer("refused", f"{who}: {command} refused: {refusal}",
                          int(ExitCode.USAGE))
        if request is None:
            return Answer("nothing to do", f"{who}: nothing to do: {_where(state)}",
                          int(ExitCode.OK))
        watch = self._targets.fresh(system_id, vehicle, system_id)
        reason = f"operator command: {command}"
        if command == "hold":
            try:
                self.runner.control("pause", reason=reason, timeout=timeout)
            except ControlRefused as refusal:
                if not self.runner.paused:
                    return Answer("no run", f"the run cannot pause: {refusal}",
                                  int(ExitCode.FAILURE))
            said = "the run paused"
        elif self.runner.flying:
            self.runner.take_over(command)  # as the service's command (tml.run.endings)
            said = f"the run ends into {command}"
        else:
            return Answer("no run", "the run is not flying its mission",
                          int(ExitCode.FAILURE))
        return self.confirm(vehicle, command, timeout, said, who, watch)

    def confirm(self, vehicle: Vehicle, command: str, timeout: float, said: str,
                who: str, targets: TargetWatch | None = None) -> Answer:
        """Wait up to ``timeout`` wall seconds for the telemetry to confirm ``command``
        (with the GUIDED targets the vehicle reports since, when ``targets`` watches
        them)."""
        check = MotionCheck(vehicle, command, targets, self.vehicle_time)
        confirmation = check.confirmation
        end = time.monotonic() + timeout
        while True:
            if check.look():
                return Answer("done", f"{who}: {command} done ({said}): "
                                      f"{confirmation.seen()}", int(ExitCode.OK))
            if time.monotonic() >= end:
                return Answer("not confirmed",
                              f"{who}: {command} not confirmed within {timeout:g} s "
                              f"({said}; wanted {confirmation.criterion()}; seen "
                              f"{confirmation.seen()})", int(ExitCode.FAILURE))
            time.sleep(POLL_PERIOD)


def target_watch(vehicle: Vehicle, system_id: int) -> TargetWatch | None:
    """A watch of the GUIDED targets vehicle ``system_id`` reports, asked for (of a
    vehicle on a MAVLink link; None for another vehicle). One per vehicle: it listens to
    the link for good."""
    link, mav = getattr(vehicle, "link", None), getattr(vehicle, "mav", None)
    if link is None or mav is None:
        return None
    from tml.mavlink.targets import TargetWatch

    watch = TargetWatch(link, system_id)
    watch.ask(mav)
    return watch


class TargetWatches:
    """One :func:`target_watch` per vehicle (each listens to its link for good), handed out
    cleared: the GUIDED targets reported from now on. Safe to share between threads."""

    def __init__(self) -> None:
        self._watches: dict[int, TargetWatch | None] = {}
        self._lock = threading.Lock()

    def fresh(self, key: int, vehicle: Vehicle, system_id: int) -> TargetWatch | None:
        """The watch of the vehicle known here as ``key`` (system ``system_id`` on its
        link), cleared."""
        with self._lock:  # one watch per vehicle, however many commands come at once
            if key not in self._watches:
                self._watches[key] = target_watch(vehicle, system_id)
            watch = self._watches[key]
        if watch is not None:
            watch.clear()
        return watch


class MotionCheck:
    """Whether a vehicle's telemetry confirms an operator's ``command`` (the
    :class:`~tml.engine.confirm.Confirmation` of the states :meth:`look` reads, with the
    GUIDED target ``targets`` saw reported, in the vehicle's own time)."""

    def __init__(self, vehicle: Vehicle, command: str, targets: TargetWatch | None = None,
                 vehicle_time: Callable[[Vehicle, VehicleState], float] | None = None
                 ) -> None:
        self.vehicle = vehicle
        self.confirmation = Confirmation(command)
        self.targets = targets
        self.vehicle_time = vehicle_time or own_time
        self.confirmed = False  # what the latest look showed

    def look(self) -> bool:
        """Read the vehicle's state; whether it confirms the command now."""
        state = self.vehicle.state()
        target = None if self.targets is None else self.targets.latest
        self.confirmed = self.confirmation.see(state, self.vehicle_time(self.vehicle, state),
                                               target)
        return self.confirmed


def own_time(vehicle: Vehicle, state: VehicleState) -> float:
    """The vehicle's own time (s since its boot, the ``time_boot_ms`` of its latest
    message) for a vehicle on a MAVLink link; else the state's time."""
    link, system_id = getattr(vehicle, "link", None), getattr(vehicle, "system_id", None)
    telemetry = getattr(link, "telemetry", None)
    if telemetry is None or system_id is None:
        return state.time
    boot = telemetry(system_id).boot_time
    return state.time if boot is None else float(boot)


def _who(vehicle: Vehicle, system_id: int) -> str:
    """The run's name of a vehicle, with its system id when that differs."""
    vid = vehicle.vehicle_id
    return f"vehicle {vid}" if vid == system_id else f"vehicle {vid} (system id {system_id})"


def _where(state: VehicleState) -> str:
    armed = "armed" if state.armed else "disarmed"
    ground = "on the ground" if state.landed else f"{state.altitude:.1f} m up"
    return f"mode {state.mode or '?'}, {armed}, {ground}"


class ControlServer:
    """Listens on the control sockets of a run's vehicles while it flies (module docstring).

    ``sockets`` maps each socket path to the system id of the vehicle it commands."""

    def __init__(self, desk: OperatorDesk, sockets: Mapping[str, int],
                 on_problem: Callable[[str], None] | None = None) -> None:
        self.desk = desk
        self.on_problem = on_problem
        self.listening: dict[str, tuple[socket.socket, int]] = {}
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._peers: set[threading.Thread] = set()  # commands being answered
        for path, system_id in sockets.items():
            server = self._bind(path)
            if server is not None:
                self.listening[path] = (server, system_id)

    def _bind(self, path: str) -> socket.socket | None:
        if os.path.exists(path):
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:
                try:
                    probe.connect(path)
                except (ConnectionRefusedError, FileNotFoundError):
                    with contextlib.suppress(FileNotFoundError):
                        os.unlink(path)  # a dead run's
                except OSError as error:
                    self._problem(f"control socket {path}: {error}")
                    return None
                else:
                    self._problem(f"control socket {path}: another run listens there; "
                                  "operator commands go to it")
                    return None
        server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            old = os.umask(0o177)
            try:
                server.bind(path)
            finally:
                os.umask(old)
            os.chmod(path, 0o600)
            server.listen(4)
            server.settimeout(0.2)
        except OSError as error:
            server.close()
            self._problem(f"control socket {path}: {error}")
            return None
        return server

    def _problem(self, text: str) -> None:
        if self.on_problem is not None:
            self.on_problem(text)

    def start(self) -> None:
        for path, (server, system_id) in self.listening.items():
            thread = threading.Thread(target=self._accept, args=(server, system_id),
                                      name=f"control {os.path.basename(path)}", daemon=True)
            thread.start()
            self._threads.append(thread)

    def close(self) -> None:
        """Stop listening and remove the sockets, once every command taken is answered
        (a run ended into RTL by one still has its vehicles' links open: the answer
        says what their telemetry confirmed, within the command's own timeout)."""
        self._stop.set()
        for path in self.listening:
            _alive(path)  # wakes its accept() at once
        for thread in self._threads:
            thread.join(2.0)
        for thread in list(self._peers):
            thread.join()
        for path, (server, _) in self.listening.items():
            server.close()
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path)

    def __enter__(self) -> ControlServer:
        self.start()
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def _accept(self, server: socket.socket, system_id: int) -> None:
        while not self._stop.is_set():
            try:
                peer, _ = server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            if self._stop.is_set():
                peer.close()
                return
            thread = threading.Thread(target=self._serve, args=(peer, system_id),
                                      daemon=True, name="control peer")
            self._peers.add(thread)
            thread.start()

    def _serve(self, peer: socket.socket, system_id: int) -> None:
        try:
            self._serve_peer(peer, system_id)
        finally:
            self._peers.discard(threading.current_thread())

    def _serve_peer(self, peer: socket.socket, system_id: int) -> None:
        with peer:
            peer.settimeout(5.0)
            try:
                if not _same_user(peer):
                    _reply(peer, Answer("refused", "the control socket takes commands from "
                                                   "its own user only", int(ExitCode.USAGE)))
                    return
                line = _read_line(peer)
                if line is None:
                    return  # a probe (runs_at), or a peer gone
                answer = self._answer(line, system_id)
                peer.settimeout(None)
                _reply(peer, answer)
            except OSError:
                return  # the peer went away

    def _answer(self, line: str | None, system_id: int) -> Answer:
        try:
            request: Any = json.loads(line or "")
            command = str(request["command"])
            timeout = float(request.get("timeout", 30.0))
            asked = int(request.get("system_id", system_id))
        except (ValueError, KeyError, TypeError, AttributeError):
            return Answer("refused", "not a command request", int(ExitCode.USAGE))
        if asked != system_id:
            return Answer("refused", f"this socket commands vehicle {system_id}, not "
                                     f"{asked}", int(ExitCode.USAGE))
        try:
            return self.desk.command(system_id, command, max(0.1, min(timeout, 3600.0)))
        except Exception as error:  # the run's answer must never be a dropped socket
            return Answer("not confirmed", f"the run failed to carry it out: {error!r}",
                          int(ExitCode.FAILURE))


def _reply(peer: socket.socket, answer: Answer) -> None:
    peer.sendall(json.dumps({"outcome": answer.outcome, "message": answer.message,
                             "exit_code": answer.exit_code}).encode() + b"\n")


def _same_user(peer: socket.socket) -> bool:
    """Whether the peer runs as this user (Linux SO_PEERCRED; elsewhere the socket's mode
    0600 in a 0700 directory alone keeps others out)."""
    option = getattr(socket, "SO_PEERCRED", None)
    if option is None:
        return True
    raw = peer.getsockopt(socket.SOL_SOCKET, option, struct.calcsize("3i"))
    _pid, uid, _gid = struct.unpack("3i", raw)
    return bool(uid == os.getuid())


@contextlib.contextmanager
def listening(runner: Runner, vehicles: Mapping[tuple[str, int], Vehicle],
              vehicle_time: Callable[[Vehicle, VehicleState], float] | None = None,
              on_problem: Callable[[str], None] | None = None) -> Iterator[ControlServer]:
    """The control sockets of a run's ``vehicles`` (by (address, system id)) open while
    this holds."""
    try:
        directory: str | None = runtime_dir()
    except OSError as error:
        if on_problem is not None:
            on_problem(f"no control socket: {error}")
        directory = None
    sockets = {} if directory is None else {
        control_path(address, sid, directory): sid for address, sid in vehicles}
    desk = OperatorDesk(runner, {sid: v for (_, sid), v in vehicles.items()}, vehicle_time)
    with ControlServer(desk, sockets, on_problem) as server:
        yield server
