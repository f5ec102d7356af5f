"""Start and stop ArduPilot SITL vehicles (Copter, Plane, Rover) for the interoperability suite.

Where ArduPilot is found, in this order:

1. ``TML_ARDUPILOT_SITL``: a launcher in the style of ``../shared/ardupilot/ardupilot-sitl``
   (``LAUNCHER [--vehicle copter|plane|rover] -I N --speedup K``), or an ``arducopter``
   (``arduplane``, ``ardurover``) binary built with ``./waf configure --board sitl``, or the
   directory that holds either. A bare binary is run with the parameter files ArduPilot's
   autotest uses: ``VEHICLE.parm`` beside the binary, else the ArduPilot checkout's
   ``Tools/autotest/default_params/`` (``models/plane.parm`` for Plane), found from
   ``build/sitl/bin/``.
2. ``../shared/ardupilot/ardupilot-sitl`` beside the checkout (CI has it).

Instance ``N`` serves MAVLink on TCP ``5760 + 10 * N`` (SERIAL0) and ``5762 + 10 * N``
(SERIAL1, where a companion computer attaches), with system id ``N + 1``. SERIAL0 can be put
elsewhere (``serial0="uart:/dev/pts/3:57600"``, a serial device; ``udpclient:HOST:PORT``,
UDP sent to a ground station): the vehicle is then waited for and set up on SERIAL1. Instances are
taken from ``TML_INTEROP_FIRST_INSTANCE`` (default 0) upwards, skipping any whose ports are
busy, so that several runs of the suite on one machine keep out of each other's way; under
pytest-xdist each worker starts 20 instances further up.

Each vehicle is stopped by its own pid (SIGTERM, then SIGKILL) when the test ends.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from pymavlink import mavutil

ROOT = Path(__file__).resolve().parents[2]
SHARED_LAUNCHER = ROOT.parent / "shared" / "ardupilot" / "ardupilot-sitl"
BINARIES = {"copter": "arducopter", "plane": "arduplane", "rover": "ardurover"}
MODELS = {"copter": "+", "plane": "plane", "rover": "rover"}
DEFAULT_HOME = "-35.363261,149.165230,584,353"
BASE_PORT = 5760
MAX_INSTANCE = 250
BOOT_TIMEOUT = 60.0


@dataclass(frozen=True)
class Launcher:
    """How to start a vehicle: a launcher script, or a binary with its parameter file."""

    path: Path
    is_script: bool

    def command(self, vehicle: str, instance: int, speedup: float, home: str,
                scratch: Path, boot_parm: Path | None = None,
                extra: Sequence[str] = (), wipe: bool = True) -> list[str]:
        """The command line that starts ``vehicle`` as ``instance``; ``boot_parm`` is a
        parameter file read after ArduPilot's autotest one (for parameters that take
        effect only at boot, such as GRIP_ENABLE); ``extra``: more of ArduPilot's options
        (e.g. ``--serial1 udpclient:127.0.0.1:14550``). ``wipe`` False runs the binary
        (the launcher script's, beside it) without ``--wipe``, so that a reboot keeps the
        parameters set over MAVLink (the EEPROM starts empty in a new ``scratch`` anyway)."""
        if self.is_script and wipe:
            command = [str(self.path), "--vehicle", vehicle, "-I", str(instance),
                       "--speedup", f"{speedup:g}", "--home", home]
            if boot_parm is not None:  # replaces the launcher's --defaults: name both
                beside = self.path.parent / f"{vehicle}.parm"
                files = [beside, boot_parm] if beside.is_file() else [boot_parm]
                command += ["--defaults", ",".join(map(str, files))]
            return [*command, *extra]
        binary = self.path.parent / BINARIES[vehicle]
        command = [str(binary), *(["--wipe"] if wipe else []), "--model", MODELS[vehicle],
                   "--speedup", f"{speedup:g}", "-I", str(instance), "--sysid", str(instance + 1),
                   "--home", home]
        files = [p for p in (parameter_file(binary, vehicle), boot_parm) if p is not None]
        if files:
            command += ["--defaults", ",".join(map(str, files))]
        return [*command, *extra]


def parameter_file(binary: Path, vehicle: str) -> Path | None:
    """ArduPilot's autotest parameters for ``vehicle``, beside the binary or in its checkout."""
    beside = binary.parent / f"{vehicle}.parm"
    if beside.is_file():
        return beside
    # build/sitl/bin/arducopter -> the checkout's Tools/autotest
    autotest = binary.resolve().parents[3] / "Tools" / "autotest" if len(
        binary.resolve().parents) > 3 else None
    if autotest is None:
        return None
    found = (autotest / "models" / "plane.parm" if vehicle == "plane"
             else autotest / "default_params" / f"{vehicle}.parm")
    return found if found.is_file() else None


def find_launcher() -> tuple[Launcher | None, str]:
    """The launcher to use, or None and the one-line reason there is none."""
    configured = os.environ.get("TML_ARDUPILOT_SITL", "")
    if configured:
        path = Path(configured).expanduser()
        if path.is_dir():
            script = path / "ardupilot-sitl"
            path = script if script.is_file() else path / "arducopter"
        if not path.is_file() or not os.access(path, os.X_OK):
            return None, f"TML_ARDUPILOT_SITL={configured} is not an executable launcher " \
                         f"or arducopter binary"
        return Launcher(path, path.name not in BINARIES.values()), ""
    if SHARED_LAUNCHER.is_file():
        return Launcher(SHARED_LAUNCHER, True), ""
    return None, ("no ArduPilot SITL: set TML_ARDUPILOT_SITL to an ardupilot-sitl launcher "
                  "or an arducopter binary (see docs/interop.md)")


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


_claimed: set[int] = set()
_claim_lock = threading.Lock()


def _first_instance() -> int:
    """``TML_INTEROP_FIRST_INSTANCE``, plus 20 for each pytest-xdist worker before this one
    (``PYTEST_XDIST_WORKER`` is ``gw0``, ``gw1``...), so that workers never race for one
    instance's ports: a port that is free when one worker looks may be bound by the other's
    vehicle a moment later."""
    first = int(os.environ.get("TML_INTEROP_FIRST_INSTANCE", "0"))
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if worker.startswith("gw") and worker[2:].isdigit():
        first += 20 * int(worker[2:])
    return first


def _claim_instance() -> int:
    first = _first_instance()
    with _claim_lock:
        for instance in range(first, MAX_INSTANCE):
            ports = (BASE_PORT + 10 * instance, BASE_PORT + 10 * instance + 2)
            if instance not in _claimed and all(_port_free(p) for p in ports):
                _claimed.add(instance)
                return instance
    raise RuntimeError("no free ArduPilot SITL instance (ports 5760 + 10 * N are all busy)")


@dataclass
class SitlVehicle:
    """One running ArduPilot SITL vehicle."""

    vehicle: str
    instance: int
    process: subprocess.Popen[bytes]
    log: Path
    serial0: str | None = None
    """ArduPilot's SERIAL0 device when it is not TCP (``uart:PATH:BAUD``, ``udpclient:...``)."""
    command: tuple[str, ...] = ()
    """The command line it was started with (:meth:`restart` runs it again)."""

    @property
    def system_id(self) -> int:
        """MAV_SYSID (the launcher's default: instance + 1)."""
        return self.instance + 1

    @property
    def port(self) -> int:
        """SERIAL0's TCP port, for the ground station."""
        return BASE_PORT + 10 * self.instance

    @property
    def address(self) -> str:
        """SERIAL0, the ground station's connection string."""
        return f"tcp:127.0.0.1:{self.port}"

    @property
    def companion_address(self) -> str:
        """SERIAL1, where a companion computer is attached."""
        return f"tcp:127.0.0.1:{self.port + 2}"

    @property
    def setup_port(self) -> int:
        """The TCP port the harness waits for and sets parameters on: SERIAL0's, or
        SERIAL1's when SERIAL0 is elsewhere (a serial device, UDP)."""
        return self.port if self.serial0 is None else self.port + 2

    def output(self) -> str:
        """What the vehicle printed (for failure messages)."""
        return self.log.read_text(errors="replace")[-2000:] if self.log.exists() else ""

    def restart(self) -> None:
        """Kill the vehicle's process (SIGKILL: a crash, a power loss) and start it again
        as it was started, the same instance on the same ports: an autopilot that
        reboots. Its parameters start from the launcher's again (the EEPROM is wiped) and
        its clock when a client connects to SERIAL0 (a ground station that dials again)."""
        if self.process.poll() is None:
            os.kill(self.process.pid, signal.SIGKILL)
            self.process.wait(timeout=5)
        with self.log.open("ab") as out:
            self.process = subprocess.Popen(self.command, cwd=self.log.parent, stdout=out,
                                            stderr=subprocess.STDOUT,
                                            stdin=subprocess.DEVNULL)

    def stop(self) -> None:
        """Stop the vehicle by its pid: SIGTERM, then SIGKILL after 5 s."""
        if self.process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.process.pid, signal.SIGTERM)
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                os.kill(self.process.pid, signal.SIGKILL)
                self.process.wait(timeout=5)
        with _claim_lock:
            _claimed.discard(self.instance)


def start_vehicle(launcher: Launcher, vehicle: str = "copter", *, speedup: float = 10.0,
                  home: str = DEFAULT_HOME, params: Mapping[str, float] | None = None,
                  boot_params: Mapping[str, float] | None = None,
                  scratch: Path | None = None, extra: Sequence[str] = (),
                  serial0: str | None = None,
                  reboot_params: Mapping[str, float] | None = None) -> SitlVehicle:
    """Start one vehicle, wait until it answers on SERIAL0, and set ``params`` on it.

    ``serial0`` puts SERIAL0 on another of ArduPilot's devices (``uart:PATH:BAUD``,
    ``udpclient:HOST:PORT``); the vehicle is then waited for and set up on SERIAL1, and
    its clock runs from the start (there is no first client to wait for).

    ``boot_params`` are read at boot, after ArduPilot's autotest parameters (those that
    take effect only then: GRIP_ENABLE ...). The first connection starts the vehicle's
    clock; ``params`` are set over it and it is closed again, so that the ground station
    under test connects to a vehicle that has already booted (ArduPilot takes the next
    client on the same port).

    ``reboot_params`` are set over MAVLink and the vehicle is rebooted with them (run
    without ``--wipe``): for parameters read only at boot that a defaults file does not
    set (CAM1_TYPE on ArduPilot 4.7).
    """
    for _ in range(5):
        instance = _claim_instance()
        folder = Path(scratch or tempfile.mkdtemp(prefix="ardupilot-"))
        log = folder / f"{vehicle}-{instance}.log"
        boot_parm = None
        if boot_params:
            boot_parm = folder / "boot.parm"
            boot_parm.write_text("".join(f"{name} {value:g}\n"
                                         for name, value in boot_params.items()))
        more = [*extra, "--serial0", serial0] if serial0 is not None else list(extra)
        command = launcher.command(vehicle, instance, speedup, home, folder, boot_parm, more,
                                   wipe=not reboot_params)
        with log.open("wb") as out:
            process = subprocess.Popen(command, cwd=folder, stdout=out,
                                       stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        sitl = SitlVehicle(vehicle, instance, process, log, serial0, tuple(command))
        if _wait_listening(sitl):
            break
        sitl.stop()  # another run took the ports between the check and the start
    else:
        raise RuntimeError(f"ArduPilot SITL did not start: {sitl.output()}")
    try:
        if reboot_params:
            _first_contact(sitl, dict(reboot_params), reboot=True)
        _first_contact(sitl, dict(params or {}))
    except Exception:
        sitl.stop()
        raise
    return sitl


def _wait_listening(sitl: SitlVehicle) -> bool:
    end = time.monotonic() + 15.0
    while time.monotonic() < end:
        if sitl.process.poll() is not None:
            return False
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
            if sock.connect_ex(("127.0.0.1", sitl.setup_port)) == 0:
                return True
        time.sleep(0.1)
    return False


def _connect(sitl: SitlVehicle) -> mavutil.mavfile:
    """A connection to the setup port that has heard a HEARTBEAT. A vehicle run without
    ``--wipe`` may reset a connection made while it takes the port again after the first
    one closed: then it is tried again, for up to :data:`BOOT_TIMEOUT` s."""
    address = f"tcp:127.0.0.1:{sitl.setup_port}"
    end = time.monotonic() + BOOT_TIMEOUT
    while True:
        conn = mavutil.mavlink_connection(address, source_system=250, source_component=190)
        try:
            if conn.wait_heartbeat(timeout=BOOT_TIMEOUT) is None:
                raise RuntimeError(f"no heartbeat from {address}: {sitl.output()}")
            return conn
        except ConnectionError:
            conn.close()
            if time.monotonic() > end or sitl.process.poll() is not None:
                raise
            time.sleep(0.2)


def _first_contact(sitl: SitlVehicle, params: dict[str, float], reboot: bool = False) -> None:
    conn = _connect(sitl)
    try:
        for name, value in params.items():
            set_parameter(conn, sitl.system_id, name, value)
        if reboot:  # PREFLIGHT_REBOOT_SHUTDOWN: the same process starts again
            conn.mav.command_long_send(sitl.system_id, 1, 246, 0, 1, 0, 0, 0, 0, 0, 0)
            if conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=5.0) is None:
                raise RuntimeError(f"no answer to the reboot: {sitl.output()}")
            conn.port.settimeout(BOOT_TIMEOUT)  # the old process's link ends with it
            with contextlib.suppress(OSError):
                while conn.port.recv(4096):
                    pass
    finally:
        conn.close()
    if reboot and not _wait_listening(sitl):
        raise RuntimeError(f"not back after the reboot: {sitl.output()}")


def set_parameter(conn: mavutil.mavfile, system_id: int, name: str, value: float) -> None:
    """PARAM_SET until the vehicle echoes the value (raises after 10 tries)."""
    for _ in range(10):
        conn.mav.param_set_send(system_id, 1, name.encode(), value,
                                mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
        end = time.monotonic() + 1.0
        while time.monotonic() < end:
            msg = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.2)
            if msg is not None and msg.param_id == name and abs(msg.param_value - value) < 1e-3:
                return
    raise RuntimeError(f"{name}={value} was not taken by vehicle {system_id}")


@contextlib.contextmanager
def vehicles(launcher: Launcher, count: int = 1, vehicle: str = "copter",
             **options: object) -> Iterator[list[SitlVehicle]]:
    """``count`` vehicles, stopped (by pid) on leaving."""
    started: list[SitlVehicle] = []
    try:
        for _ in range(count):
            started.append(start_vehicle(launcher, vehicle, **options))  # type: ignore[arg-type]
        yield started
    finally:
        for sitl in started:
            sitl.stop()
        for sitl in started:
            shutil.rmtree(sitl.log.parent, ignore_errors=True)


class ChargingPad:
    """A charging pad under an ArduPilot SITL vehicle, as the embedded simulator's
    ``SIM_BATT_CHARGE``: while the vehicle is disarmed its battery gains ``amps`` of charge.

    ArduPilot SITL has no charger, so the pad talks to the vehicle's second port (SERIAL1):
    once a vehicle second (each HEARTBEAT) it adds ``amps`` x 1 s to what the battery holds
    and sets the battery monitor's remaining charge with MAV_CMD_BATTERY_RESET, which
    ArduPilot implements for monitors that integrate the current (BATT_MONITOR 4).
    ``capacity`` is BATT_CAPACITY in mAh (0: read from the vehicle).
    """

    def __init__(self, sitl: SitlVehicle, amps: float, capacity: float = 0.0) -> None:
        self.sitl = sitl
        self.amps = amps
        self.capacity = capacity
        self.charges = 0  # resets sent, for the test to see the pad worked
        self._running = False
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Attach to the vehicle and charge in a thread until :meth:`stop`."""
        conn = mavutil.mavlink_connection(self.sitl.companion_address, source_system=250,
                                          source_component=158)
        if conn.wait_heartbeat(timeout=30) is None:
            raise RuntimeError(f"no heartbeat on {self.sitl.companion_address}")
        if not self.capacity:
            conn.mav.param_request_read_send(self.sitl.system_id, 1, b"BATT_CAPACITY", -1)
            msg = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=5)
            self.capacity = msg.param_value if msg is not None else 3300.0
        conn.mav.command_long_send(self.sitl.system_id, 1,
                                   mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                   mavutil.mavlink.MAVLINK_MSG_ID_SYS_STATUS, 500_000,
                                   0, 0, 0, 0, 0)
        self._running = True
        self._thread = threading.Thread(target=self._charge, args=(conn,), daemon=True,
                                        name=f"pad {self.sitl.instance}")
        self._thread.start()

    def stop(self) -> None:
        """Stop charging and detach."""
        self._running = False
        if self._thread is not None:
            self._thread.join(timeout=5)

    def _charge(self, conn: mavutil.mavfile) -> None:
        per_second = self.amps * 1000.0 / 3600.0 / self.capacity * 100.0  # % a second
        remaining: float | None = None
        charge: float | None = None
        try:
            while self._running:
                msg = conn.recv_match(type=["HEARTBEAT", "SYS_STATUS"], blocking=True,
                                      timeout=0.5)
                if msg is None or msg.get_srcSystem() != self.sitl.system_id \
                        or msg.get_srcComponent() != 1:
                    continue
                if msg.get_type() == "SYS_STATUS":
                    remaining = None if msg.battery_remaining < 0 else msg.battery_remaining
                    continue
                armed = msg.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED
                if armed or remaining is None:
                    charge = None
                    continue
                charge = min(100.0, (remaining if charge is None else charge) + per_second)
                if charge > remaining:
                    conn.mav.command_long_send(
                        self.sitl.system_id, 1, mavutil.mavlink.MAV_CMD_BATTERY_RESET, 0,
                        1, charge, 0, 0, 0, 0, 0)
                    self.charges += 1
        finally:
            conn.close()
