"""Fleet: one interpreter flying 10, 100, 500 or 1,000 simulated vehicles -- CPU, event delay,
memory and threads.

Run by hand: ``python benchmarks/fleet.py [--vehicles 10,100,500] [--speedup 1] [--seconds 30]
[--log FILE]``.

For each fleet size N the simulator runs in its own processes (``python -m sitl --vehicles M
--speedup K --tcp-base-port 0``, ports read from what it prints, all on 127.0.0.1; at most
250 vehicles in one, since MAVLink numbers a system with one byte), and this process flies
them as ``tml run --connect`` would: one Link and one MavlinkVehicle per vehicle (numbered
1..N whatever its system id), and one Runner whose single Interpreter drives them all
(with ``--log``, writing its flight log there, every decision synced to the disk). The
mission, generated below, declares one role with ``count=N`` (every vehicle) flying two
tasks: take off to 5 m, then hover until an event. The event,
``BATTERY_CHARGE_PERCENTAGE < 25``, lands the vehicle.

The benchmark makes each vehicle's event true at a moment it chooses: once every vehicle
hovers, it sends vehicle i (1..N) a PARAM_SET ``BATT_CAPACITY`` = 1 mAh at (i - 0.5)/N of
the way through ``--seconds`` of vehicle time, so the simulator reports 0 % left from its
next SYS_STATUS on, and the triggers are spread evenly. Two stamps per vehicle, both taken in
this process:

- *received*: when pymavlink finished parsing the first SYS_STATUS that shows the low
  battery (the message's own ``_timestamp``, set before tml sees it);
- *left*: when the COMMAND_LONG NAV_LAND for that vehicle has been written to its socket
  (``Link.send`` is wrapped to note it).

Their difference is the event delay: the reactor's hand-off (tml.mavlink.reactor: one thread
reads every link), the runner's wake, one engine step, the Land's procedure begun (on the
runner's thread, up to its first command) and the command's encoding. p50/p99 are over the N
vehicles of one run.

CPU: ``time.process_time`` of this process while ``Runner.run`` flies (take-off, hover,
landing; the set-up before it is not counted), divided by the vehicle time flown (vehicle
1's ``time_boot_ms``) and by N. The runner's wakes (loop rounds) are counted too: each
vehicle wakes the runner on a change of a field the mission reads (and on a result), as in
``tml run`` (:meth:`tml.mavlink.adapter.MavlinkVehicle.watch`).
The simulators' CPU comes from ``getrusage(RUSAGE_CHILDREN)`` after their processes have
exited, over their whole life. Memory per vehicle: how much this process's resident set grew
from before the links were opened to the end of the flight, divided by N; threads: the most
this process had at once while it flew (read at each wake of the runner).

The peer, measured in the same run at each N (:func:`peer`): one bare pymavlink loop that
reads the same streams of as many vehicles through ``selectors`` (epoll), flies them up, and sends
NAV_LAND on the first SYS_STATUS that shows a low battery, with the same stamps -- the least
a Python ground station reading these streams can spend. The ratios tml / peer are printed,
and tml's growth from the smallest fleet.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import resource
import selectors
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

os.environ.setdefault("MAVLINK20", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

ROOT = Path(__file__).resolve().parent.parent

ALTITUDE = 5.0  # m: the take-off height; the hover starts once every vehicle is near it
LOW = 25  # %: the event's threshold
NAV_LAND = mavlink.MAV_CMD_NAV_LAND
FAST_FIX = {"SIM_GPS_LOCKTIME": 1.0, "SIM_EKF_GPS_TIME": 2.0}  # armable within seconds
PER_SIMULATOR = 250  # vehicles in one simulator process: system ids are 1 to 255
PORT_LINE = re.compile(r"vehicle (\d+): tcp:127\.0\.0\.1:(\d+)")

MISSION = """<mission name="Fleet benchmark">
  <roles><role name="fleet" count="{count}" type="quadcopter" pick_timeout="60"/></roles>
  <task name="Patrol" role="fleet">
    <task name="Take off">
      <action name="TAKE_OFF"><argument name="altitude" value="{altitude:g}"/></action>
    </task>
    <task name="Hover">
      <action name="WAIT"><argument name="duration" value="86400"/></action>
    </task>
  </task>
  <event_handling>
    <event name="Low battery" role="fleet">
      <condition parameter="BATTERY_CHARGE_PERCENTAGE" comparison="less than" value="{low}"/>
      <action name="LAND"/>
      <termination mode="NEXT_TASK"/>
    </event>
  </event_handling>
</mission>"""


@dataclass
class Probe:
    """Per vehicle: when its trigger went out, its trigger telemetry arrived, its command left."""

    triggered: dict[int, float] = field(default_factory=dict)
    received: dict[int, float] = field(default_factory=dict)
    left: dict[int, float] = field(default_factory=dict)
    altitude: dict[int, float] = field(default_factory=dict)
    vehicle_time: float = 0.0  # s, vehicle 1's time_boot_ms
    first_vehicle_time: float | None = None  # s, vehicle 1's first time seen

    def on_message(self, system_id: int, msg: Any) -> None:
        """Note the low-battery SYS_STATUS, the altitude and vehicle 1's time."""
        kind = msg.get_type()
        if kind == "SYS_STATUS":
            if (system_id in self.triggered and system_id not in self.received
                    and 0 <= msg.battery_remaining < LOW):
                self.received[system_id] = msg._timestamp  # set by pymavlink as it parsed
        elif kind == "GLOBAL_POSITION_INT":
            self.altitude[system_id] = msg.relative_alt / 1000.0
            if system_id == 1:
                self.vehicle_time = msg.time_boot_ms / 1000.0
                if self.first_vehicle_time is None:
                    self.first_vehicle_time = self.vehicle_time

    def on_send(self, system_id: int, msg: Any) -> None:
        """Note the first NAV_LAND written to a triggered vehicle."""
        if (getattr(msg, "command", None) == NAV_LAND and system_id in self.triggered
                and system_id not in self.left):
            self.left[system_id] = time.time()

    def delays(self) -> list[float]:
        """Event delays in milliseconds, one per vehicle that answered."""
        return [(self.left[v] - self.received[v]) * 1000
                for v in self.received if v in self.left]


@dataclass
class Result:
    """One fleet size's measurements."""

    vehicles: int
    wall: float  # s the flight took
    flown: float  # vehicle s the flight took
    cpu: float  # s of this process's CPU during the flight
    wakes: int  # rounds of the runner's loop during the flight
    memory: float  # MB the resident set grew from before the links to the flight's end
    threads: int  # the most threads of this process at once during the flight
    sim_cpu: float  # s of the simulator's CPU over its life
    sim_time: float  # vehicle s the simulator ran
    delays: list[float]
    outcome: str
    runner_cpu: float = math.nan  # s of the flight's CPU in the runner's thread
    reactor_cpu: float = math.nan  # ... in the thread that reads every link (Linux only)

    @property
    def cpu_per_vehicle_second(self) -> float:
        """ms of CPU per vehicle per simulated second."""
        return self.cpu * 1000 / (self.vehicles * self.flown)

    @property
    def memory_per_vehicle(self) -> float:
        """kB of this process's memory per vehicle."""
        return self.memory * 1024 / self.vehicles

    @property
    def sim_cpu_per_vehicle_second(self) -> float:
        return self.sim_cpu * 1000 / (self.vehicles * self.sim_time)


@contextmanager
def simulator(vehicles: int, speedup: float) -> Iterator[tuple[list[int], list[float]]]:
    """Run ``python -m sitl`` in its own process; yield its TCP ports and a one-item list
    that holds the simulator's CPU seconds once the process has exited."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    process = subprocess.Popen(
        [sys.executable, "-m", "sitl", "--vehicles", str(vehicles), "--speedup", f"{speedup:g}",
         "--tcp-base-port", "0", "--bind", "127.0.0.1"],
        cwd=ROOT, stdout=subprocess.PIPE, text=True)
    cpu: list[float] = []
    try:
        assert process.stdout is not None
        ports: list[int] = []
        while len(ports) < vehicles:
            line = process.stdout.readline()
            if not line:
                raise SystemExit(f"the simulator exited ({process.wait()}) before listing "
                                 f"{vehicles} vehicles")
            found = PORT_LINE.search(line)
            if found:
                ports.append(int(found.group(2)))
        yield ports, cpu
    finally:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)


@contextmanager
def simulators(vehicles: int, speedup: float) -> Iterator[tuple[list[tuple[int, int]],
                                                                  list[list[float]]]]:
    """As many simulator processes as ``vehicles`` needs (MAVLink numbers a system with one
    byte: at most PER_SIMULATOR vehicles in one); yield each vehicle's (TCP port, system id)
    and one list per simulator that holds its CPU seconds once it has exited."""
    with ExitStack() as stack:
        vehicles_at: list[tuple[int, int]] = []
        cpus: list[list[float]] = []
        left = vehicles
        while left > 0:
            count = min(left, PER_SIMULATOR)
            ports, cpu = stack.enter_context(simulator(count, speedup))
            cpus.append(cpu)  # filled once the process has exited
            vehicles_at.extend((port, system_id) for system_id, port in enumerate(ports, 1))
            left -= count
        yield vehicles_at, cpus


def param_set(system_id: int, name: str, value: float) -> Any:
    """A PARAM_SET to the autopilot of ``system_id``."""
    return mavlink.MAVLink_param_set_message(system_id, 1, name.encode(), value,
                                             mavlink.MAV_PARAM_TYPE_REAL32)


def fly(vehicles: int, speedup: float, seconds: float, log: str | None = None) -> Result:
    """Fly the generated mission on ``vehicles`` simulated vehicles; measure it (with a
    flight log written to ``log``, as ``tml run --log`` writes it, if given)."""
    from tml.engine import Options
    from tml.language.validation import validate_file
    from tml.mavlink.adapter import MavlinkVehicle
    from tml.mavlink.link import Link
    from tml.run.journal import Journal
    from tml.run.runner import Runner, RunOptions
    from tml.timebase import Flag

    source = MISSION.format(count=vehicles, altitude=ALTITUDE, low=LOW).encode()
    mission = validate_file("fleet.xml", source).mission
    assert mission is not None, "the generated mission is invalid"
    probe = Probe()
    wake = Flag()  # as tml run's (tml.run.session)
    threads = [0]
    with ExitStack() as stack:
        at, sim_cpu = stack.enter_context(simulators(vehicles, speedup))
        resident = _resident()
        links = []
        for number, (port, _) in enumerate(at, start=1):
            link = stack.enter_context(Link(f"tcp:127.0.0.1:{port}"))
            # The probe listens first: it sees each message before the runner is woken.
            link.listen(partial(_probe_message, probe, number))
            link.send = _stamped(link.send, number, probe.on_send)  # type: ignore[method-assign]
            links.append(link)
        for link, (_, system_id) in zip(links, at, strict=True):
            link.wait_vehicle(system_id, timeout=30)
            for name, value in FAST_FIX.items():
                link.send(param_set(system_id, name, value))

        # The mission's time limits (a take-off's climb) are in vehicle seconds: below 1x
        # the wall clock would run out before the vehicle could (the simulators keep the
        # speed-up asked for; a flight that starves them fails whatever the clock).
        def clock() -> float:
            return time.monotonic() * speedup

        def connect(number: int) -> MavlinkVehicle:
            vehicle = MavlinkVehicle(links[number - 1], at[number - 1][1], vehicle_id=number,
                                     on_result=wake.set, clock=clock,
                                     connect_timeout=30)
            vehicle.prepare()
            return vehicle

        with ThreadPoolExecutor(max_workers=16) as pool:  # set-up is not measured
            fleet = list(pool.map(connect, range(1, vehicles + 1)))
        for vehicle in fleet:
            stack.callback(vehicle.close)
        wakes = [0]

        def wait(timeout: float) -> None:  # the runner's own wait, counted
            wake.wait(timeout)
            wake.clear()
            wakes[0] += 1
            threads[0] = max(threads[0], threading.active_count())

        journal = stack.enter_context(contextlib.closing(Journal.open(log)))
        runner = Runner(mission, fleet, options=RunOptions(engine=Options()), wake=wake,
                        wait=wait, journal=journal, clock=clock)
        limit = 120 + 3 * (seconds + 60) / speedup  # wall s: a stuck run is stopped
        trigger = threading.Thread(target=_trigger, daemon=True,
                                   args=([(link, sid) for link, (_, sid) in zip(links, at,
                                                                                 strict=True)],
                                         probe, seconds / speedup, limit))
        trigger.start()
        watchdog = threading.Timer(limit, runner.stop, args=("benchmark time limit",))
        watchdog.daemon = True
        watchdog.start()
        started_cpu, started_wall = time.process_time(), time.perf_counter()
        started_vehicle = probe.vehicle_time
        started_runner, started_reactor = time.thread_time(), _reactor_cpu()
        outcome = runner.run()
        runner_cpu = time.thread_time() - started_runner
        reactor_cpu = _reactor_cpu() - started_reactor
        cpu = time.process_time() - started_cpu
        wall = time.perf_counter() - started_wall
        flown = probe.vehicle_time - started_vehicle
        watchdog.cancel()
        sim_time = probe.vehicle_time
        grown = _resident() - resident
    statuses = sorted({v.status.value for v in outcome.vehicles})
    # Why the vehicles that did not complete ended, the commonest first (numbers elided).
    why = Counter(re.sub(r"\d+(\.\d+)?", "N", f"{v.cause or v.status.value}: {v.reason}")
                  for v in outcome.vehicles if v.status.value != "completed")
    return Result(vehicles, wall, flown, cpu, wakes[0], grown, threads[0],
                  sum(map(sum, sim_cpu)), sim_time, probe.delays(),
                  f"{'/'.join(statuses)} (exit {int(outcome.exit_code)})"
                  + "".join(f"; {count} x {reason}" for reason, count in why.most_common(3)),
                  runner_cpu,
                  reactor_cpu)


def _reactor_cpu() -> float:
    """CPU seconds of the thread that reads every link so far (NaN where /proc has none)."""
    from tml.mavlink.reactor import THREAD_NAME

    for thread in threading.enumerate():
        if thread.name == THREAD_NAME and thread.native_id is not None:
            try:
                stat = Path(f"/proc/self/task/{thread.native_id}/stat").read_text()
            except OSError:
                break
            fields = stat.rsplit(")", 1)[1].split()  # utime and stime: fields 14 and 15
            return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return math.nan


def _resident() -> float:
    """MB of this process's resident set now (Linux's /proc; 0 elsewhere)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
    except (OSError, IndexError, ValueError):
        return 0.0
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def peer(vehicles: int, speedup: float, seconds: float) -> Result:
    """The same flight, stamps and CPU count without tml: one bare pymavlink loop.

    One thread reads every vehicle's socket through ``selectors``, parses every message
    pymavlink hands it and notes the same stamps; the vehicles are asked for the same
    streams at the same rates as tml asks (``DEFAULT_RATES``), put in GUIDED, armed and
    taken off to ALTITUDE, and each is sent NAV_LAND on the first SYS_STATUS that shows its
    battery low. The least a Python ground station reading these streams can spend.
    """
    from tml.mavlink.autopilot import DEFAULT_RATES

    probe = Probe()
    with ExitStack() as stack:
        at, sim_cpu = stack.enter_context(simulators(vehicles, speedup))
        resident = _resident()
        conns = []
        for port, _ in at:
            conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=255,
                                              source_component=190)
            stack.callback(conn.close)
            conns.append(conn)
        lock = threading.Lock()  # the trigger thread writes to the same sockets
        for conn, (_, system_id) in zip(conns, at, strict=True):
            conn.wait_heartbeat(timeout=30)
            for name, value in FAST_FIX.items():
                conn.mav.send(param_set(system_id, name, value))
            for name, hz in DEFAULT_RATES.items():
                conn.mav.command_long_send(
                    system_id, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                    getattr(mavlink, f"MAVLINK_MSG_ID_{name}"), 1e6 / hz, 0, 0, 0, 0, 0)
        selector = stack.enter_context(selectors.DefaultSelector())
        for number, (conn, (_, system_id)) in enumerate(zip(conns, at, strict=True), 1):
            selector.register(conn.fd, selectors.EVENT_READ, (number, system_id, conn))
        armed: set[int] = set()
        asked: dict[int, float] = {}  # system id -> when GUIDED and ARM were last asked
        links: list[Any] = [_Locked(conn, lock) for conn in conns]
        limit = 120 + 3 * (seconds + 60) / speedup
        trigger = threading.Thread(target=_trigger, daemon=True,
                                   args=([(link, sid) for link, (_, sid) in zip(links, at,
                                                                                 strict=True)],
                                         probe, seconds / speedup, limit))
        trigger.start()
        started_cpu, started_wall = time.process_time(), time.perf_counter()
        end = time.monotonic() + limit
        while len(probe.left) < vehicles and time.monotonic() < end:
            ready = selector.select(0.1)
            now = time.monotonic()
            for key, _ in ready:
                number, system_id, conn = key.data
                while (msg := conn.recv_msg()) is not None:
                    probe.on_message(number, msg)
                    kind = msg.get_type()
                    if kind == "SYS_STATUS" and number in probe.received \
                            and number not in probe.left:
                        with lock:
                            conn.mav.command_long_send(system_id, 1, NAV_LAND, 0,
                                                       0, 0, 0, 0, 0, 0, 0)
                        probe.left[number] = time.time()
                    elif kind == "HEARTBEAT" and msg.get_srcComponent() == 1 and \
                            number not in armed and msg.system_status != mavlink.MAV_STATE_BOOT:
                        if msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                            armed.add(number)
                            with lock:
                                conn.mav.command_long_send(
                                    system_id, 1, mavlink.MAV_CMD_NAV_TAKEOFF, 0,
                                    0, 0, 0, 0, 0, 0, ALTITUDE)
                        elif now - asked.get(number, -1e9) > 0.5:  # until armable
                            asked[number] = now
                            with lock:
                                conn.mav.command_long_send(
                                    system_id, 1, mavlink.MAV_CMD_DO_SET_MODE, 0,
                                    mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4, 0, 0, 0, 0, 0)
                                conn.mav.command_long_send(
                                    system_id, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                    1, 0, 0, 0, 0, 0, 0)
        cpu = time.process_time() - started_cpu
        wall = time.perf_counter() - started_wall
        flown = probe.vehicle_time - (probe.first_vehicle_time or 0.0)
        sim_time = probe.vehicle_time
        grown = _resident() - resident
    return Result(vehicles, wall, flown, cpu, 0, grown, threading.active_count(),
                  sum(map(sum, sim_cpu)), sim_time, probe.delays(),
                  f"{len(probe.left)}/{vehicles} landed")


class _Locked:
    """A pymavlink connection's send, behind the lock the reading loop takes to send."""

    def __init__(self, conn: Any, lock: threading.Lock) -> None:
        self.conn, self.lock = conn, lock

    def send(self, msg: Any) -> None:
        with self.lock:
            self.conn.mav.send(msg)


def _probe_message(probe: Probe, number: int, _system_id: int, _snapshot: Any,
                   msg: Any) -> None:
    probe.on_message(number, msg)


def _stamped(send: Callable[..., None], system_id: int,
             note: Callable[[int, Any], None]) -> Callable[..., None]:
    def stamped(msg: Any, target: int = 0, component: int = 0) -> None:
        send(msg, target, component)
        note(system_id, msg)
    return stamped


def _trigger(links: list[tuple[Any, int]], probe: Probe, window: float,
             limit: float) -> None:
    """Once every vehicle hovers, drop vehicle i's battery at i/N of ``window`` wall s
    (``links``: each vehicle's link and system id, vehicle 1 first)."""
    end = time.monotonic() + limit
    while time.monotonic() < end:
        if len(probe.altitude) == len(links) and all(
                a >= ALTITUDE - 0.5 for a in probe.altitude.values()):
            break
        time.sleep(0.1)
    start = time.monotonic()
    for index, (link, system_id) in enumerate(links):
        time.sleep(max(0.0, start + (index + 0.5) * window / len(links) - time.monotonic()))
        probe.triggered[index + 1] = time.time()
        link.send(param_set(system_id, "BATT_CAPACITY", 1.0))


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))] if ordered else \
        float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", default="10,100,500",
                        help="comma-separated fleet sizes (default 10,100,500)")
    parser.add_argument("--speedup", type=float, default=1.0,
                        help="simulated time this many times faster than real (default 1)")
    parser.add_argument("--seconds", type=float, default=30.0,
                        help="vehicle seconds over which the triggers are spread (default 30)")
    parser.add_argument("--log", metavar="FILE",
                        help="write tml's flight log here, as tml run --log does (default: "
                             "none; each decision of it is synced to the disk)")
    args = parser.parse_args()
    try:
        sizes = [int(n) for n in args.vehicles.split(",")]
    except ValueError:
        parser.error(f"--vehicles: expected numbers separated by commas, got {args.vehicles!r}")
    if not sizes or min(sizes) < 1 or args.speedup <= 0 or args.seconds <= 0:
        parser.error("fleet sizes, --speedup and --seconds must be positive")

    from tml.errors import TmlError

    rows: list[tuple[Result, Result]] = []
    for n in sizes:
        try:
            tml = fly(n, args.speedup, args.seconds, args.log)
            bare = peer(n, args.speedup, args.seconds)
        except TmlError as error:  # e.g. a simulator too slow to keep its vehicles' links
            print(f"  {n} vehicles: not measured: {error}", flush=True)
            continue
        rows.append((tml, bare))
        for who, r in (("tml", tml), ("peer", bare)):
            print(f"  {n} vehicles, {who}: {r.outcome}, {len(r.delays)}/{n} events timed, "
                  f"{r.wall:.1f} s wall for {r.flown:.1f} s of vehicle time, "
                  f"{100 * r.cpu / r.wall:.0f} % of a core, {r.cpu_per_vehicle_second:.2f} "
                  f"ms/veh/s, delay p50 {percentile(r.delays, 0.5):.2f} ms, p99 "
                  f"{percentile(r.delays, 0.99):.2f} ms; {r.memory_per_vehicle:.0f} kB/veh, "
                  f"{r.threads} threads; simulator "
                  f"{r.sim_cpu_per_vehicle_second:.2f} ms/veh/s", flush=True)
        if not math.isnan(tml.reactor_cpu):
            print(f"  {n} vehicles, tml's CPU by thread: reading the links "
                  f"{100 * tml.reactor_cpu / tml.cpu:.0f} %, the runner (state, events, task "
                  f"tree) {100 * tml.runner_cpu / tml.cpu:.0f} %, requests and the rest "
                  f"{100 * (tml.cpu - tml.reactor_cpu - tml.runner_cpu) / tml.cpu:.0f} %",
                  flush=True)
    print(f"\nfleet: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}, speedup "
          f"{args.speedup:g}, triggers over {args.seconds:g} vehicle s; delay = trigger "
          f"telemetry parsed -> NAV_LAND written; peer = a bare pymavlink loop reading the "
          f"same streams of the same number of vehicles")
    print(f"{'vehicles':>8} {'who':>4} {'core %':>6} {'ms/veh/s':>8} {'wakes/s':>7} "
          f"{'p50 ms':>7} {'p99 ms':>7} {'max ms':>7} {'kB/veh':>6} {'threads':>7}")
    for pair in rows:
        for who, r in zip(("tml", "peer"), pair, strict=True):
            print(f"{r.vehicles:>8} {who:>4} {100 * r.cpu / r.wall:>6.0f} "
                  f"{r.cpu_per_vehicle_second:>8.2f} "
                  f"{r.wakes / r.wall if who == 'tml' else float('nan'):>7.0f} "
                  f"{percentile(r.delays, 0.5):>7.2f} {percentile(r.delays, 0.99):>7.2f} "
                  f"{max(r.delays, default=float('nan')):>7.2f} "
                  f"{r.memory_per_vehicle:>6.0f} {r.threads:>7}")
    for tml, bare in rows:
        print(f"tml / peer at {tml.vehicles} vehicles: CPU per vehicle-second "
              f"x{tml.cpu_per_vehicle_second / bare.cpu_per_vehicle_second:.2f}, delay p50 "
              f"x{percentile(tml.delays, 0.5) / percentile(bare.delays, 0.5):.2f}, p99 "
              f"x{percentile(tml.delays, 0.99) / percentile(bare.delays, 0.99):.2f}")
    if not rows:
        raise SystemExit("no fleet size was measured")
    first = rows[0][0]
    for tml, _ in rows[1:]:
        print(f"tml growth {first.vehicles} -> {tml.vehicles} vehicles "
              f"(x{tml.vehicles / first.vehicles:g}): CPU per simulated s "
              f"x{(tml.cpu / tml.flown) / (first.cpu / first.flown):.2f}, per vehicle "
              f"x{tml.cpu_per_vehicle_second / first.cpu_per_vehicle_second:.2f}; delay p50 "
              f"x{percentile(tml.delays, 0.5) / percentile(first.delays, 0.5):.2f}, p99 "
              f"x{percentile(tml.delays, 0.99) / percentile(first.delays, 0.99):.2f}")


if __name__ == "__main__":
    main()
