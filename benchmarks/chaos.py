"""The chaos campaign: `tml run --connect` flown through link faults, vehicle faults and signals.

Each row flies one mission of missions/ with `tml run` (a process of its own, as a user runs
it) on the embedded simulator (`sitl`, five times real time) through the MAVLink-aware
lossy TCP proxy of tests/lossy_proxy.py, and injects one fault at a moment the vehicle
shows (mid take-off, mid flight, mid upload) or at a seeded random time:

- frame loss each way (0 to 40 %), latency and jitter (wall seconds, the simulator's);
- link outages of 1 to 20 s (the proxy drops every frame), mid-action and mid-upload;
- GPS loss and battery failure (the simulator's faults, set at the moment);
- a vehicle reboot (the proxy hangs up and connects on to a fresh vehicle on the ground);
- SIGINT or SIGTERM to tml at a random moment;
- tml killed (SIGKILL) mid take-off, mid flight or mid upload, then run again with
  ``--resume`` on its flight log.

For each row it prints the mission's outcome (exit code and reason), how the vehicle ended
(watched for 30 s after tml exits: landed, in its safe state RTL/LAND, or still flying in
another mode: *unwatched*), the take-offs the vehicle made (counted on the vehicle, from
on the ground to in the air) and the TakeOff requests tml sent, the actions done, the
time from the fault to the first line of the flight log that shows the link degraded
(detected: no HEARTBEAT for 2.5 s) and lost (5 s, when tml starts counting towards
--link-lost-limit) -- the runner writes a `link` line at the wake that sees the change --,
and whether the uploaded mission items are the vehicle's stored items. Then whether the row
meets the goals: no vehicle left flying unwatched, no duplicate take-off, link loss
detected within 3 s, every upload read back identical.

    python benchmarks/chaos.py [--rows NAME,...] [--seed 1] [--ardupilot]

``--ardupilot`` flies the rows that need no simulator fault on ArduCopter SITL
(../shared/ardupilot, or TML_ARDUPILOT_SITL; instances from TML_INTEROP_FIRST_INSTANCE),
watched through its second serial port. docs/reliability.md keeps the table.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "tests" / "interop")]

from lossy_proxy import LossyProxy  # noqa: E402

from sitl.faults import Faults  # noqa: E402
from sitl.server import Simulator  # noqa: E402

SPEEDUP = 5.0
FAST = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2, "DISARM_DELAY": 0}
SAFE_MODES = frozenset({"RTL", "LAND", "SMART_RTL"})
WATCH_AFTER = 30.0
"""Wall seconds the vehicle is watched after tml exits (150 s of the simulator's time)."""
RUN_LIMIT = 240.0
"""Wall seconds a run may take before tml is killed (the row then says so)."""
DETECT_GOAL = 3.0


@dataclass(frozen=True)
class Row:
    """One experiment: a mission, a fault, and when the fault comes."""

    name: str
    mission: str = "paper_example1"
    loss: float = 0.0
    latency: float = 0.0
    jitter: float = 0.0
    moment: str = ""  # "climb", "flight", "upload", "start", "airborne"
    outage: float = 0.0
    gps_loss: bool = False
    battery: bool = False
    reboot: bool = False
    signal: int = 0
    delay: float = 0.0  # wall seconds after the moment
    resume: bool = False  # tml killed (SIGKILL) at the moment, then run with --resume
    pending: str = ""  # a row that cannot be flown yet, and why
    sim_only: bool = False  # needs a fault only the simulator has


def _rows(seed: int) -> list[Row]:
    rng = random.Random(seed)
    rows = [Row("no fault"), Row("no fault, mission items", mission="mission_dispatch")]
    rows += [Row(f"loss {p} % each way", loss=p / 100) for p in (10, 20, 30, 40)]
    rows += [Row("loss 30 %, mission items", mission="mission_dispatch", loss=0.3),
             Row("latency 0.3 s, jitter 0.3 s", latency=0.3, jitter=0.3, sim_only=True)]
    rows += [Row(f"outage {s} s mid take-off", moment="climb", outage=s) for s in (1, 5, 20)]
    rows += [Row(f"outage {s} s mid flight", moment="flight", outage=s) for s in (3, 10)]
    rows += [Row(f"outage {s} s mid upload", mission="mission_dispatch", moment="upload",
                 outage=s) for s in (1, 5, 20)]
    rows += [Row("GPS loss mid flight", moment="flight", gps_loss=True, sim_only=True),
             Row("battery failure mid flight", moment="flight", battery=True, sim_only=True),
             Row("vehicle reboot mid flight", moment="flight", reboot=True, sim_only=True)]
    for moment, sig in (("start", signal.SIGINT), ("start", signal.SIGTERM),
                        ("airborne", signal.SIGINT), ("airborne", signal.SIGTERM),
                        ("airborne", signal.SIGINT), ("airborne", signal.SIGTERM)):
        delay = round(rng.uniform(0.0, 4.0 if moment == "start" else 6.0), 1)
        after = "tml started" if moment == "start" else "take-off"
        rows.append(Row(f"{signal.Signals(sig).name} {delay} s after {after}", moment=moment,
                        signal=sig, delay=delay))
    rows += [Row("tml killed mid take-off and resumed", moment="climb", resume=True),
             Row("tml killed mid flight and resumed", moment="flight", resume=True),
             Row("tml killed mid upload and resumed", mission="mission_dispatch",
                 moment="upload", outage=0.1, resume=True)]
    return rows


@dataclass
class Seen:
    """What the vehicle did, as the vehicle itself reports it."""

    armed: bool = False
    landed: bool = True
    mode: str = ""
    altitude: float = 0.0
    takeoffs: int = 0
    climbed: float | None = None  # when it first passed 9.5 m (seconds after tml started)


class SimVehicle:
    """The simulator's vehicle, read from its model (exact, no link between)."""

    def __init__(self, row: Row, seed: int) -> None:
        self.row, self.seed = row, seed
        self.sim = self._start()
        self.port = self.sim.tcp_ports[0]

    def _start(self) -> Simulator:
        faults = Faults(seed=self.seed, latency=self.row.latency * SPEEDUP,
                        jitter=self.row.jitter * SPEEDUP)
        return Simulator(vehicles=1, speedup=SPEEDUP, tcp_base_port=0, params=FAST,
                         faults=faults).start()

    def look(self) -> tuple[bool, bool, str, float]:
        model = self.sim.vehicle(1)
        return model.armed, model.landed, model.mode, model.position[2]

    def inject(self, row: Row, proxy: LossyProxy) -> None:
        model = self.sim.vehicle(1)
        if row.gps_loss:
            model.faults = replace(model.faults, gps_loss_at=model.time)
        if row.battery:
            model.faults = replace(model.faults, battery_failure_at=model.time)
        if row.reboot:
            old, self.sim = self.sim, self._start()
            proxy.retarget(self.sim.tcp_ports[0])
            old.stop()

    def stored_items(self) -> list[Any]:
        return self.sim.vehicle(1).mission_items

    def stop(self) -> None:
        self.sim.stop()


class ArduCopter:
    """ArduCopter SITL, watched through its second serial port (in the air above 1 m of
    relative altitude, landed again below 0.3 m)."""

    def __init__(self, row: Row, seed: int) -> None:
        from ardupilot_sitl import find_launcher, start_vehicle
        from pymavlink import mavutil

        launcher, why = find_launcher()
        if launcher is None:
            raise SystemExit(f"no ArduPilot SITL: {why}")
        self.sitl = start_vehicle(launcher, "copter", speedup=SPEEDUP,
                                  params={"DISARM_DELAY": 0})
        self.port = int(self.sitl.address.rsplit(":", 1)[1])
        self.watch = mavutil.mavlink_connection(self.sitl.companion_address,
                                                source_system=251, source_component=158)
        heartbeat = self.watch.wait_heartbeat(timeout=30)
        if heartbeat is None:
            raise SystemExit(f"no heartbeat on {self.sitl.companion_address}")
        self.watch.mav.request_data_stream_send(heartbeat.get_srcSystem(), 1,
                                                mavutil.mavlink.MAV_DATA_STREAM_ALL, 10, 1)
        self.state = (False, True, "", 0.0)
        self._running = True
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        armed, landed, mode, altitude = self.state
        while self._running:
            msg = self.watch.recv_match(blocking=True, timeout=0.2)
            if msg is None or msg.get_srcComponent() != 1:
                continue
            kind = msg.get_type()
            if kind == "HEARTBEAT":
                armed = bool(msg.base_mode & 128)
                mode = self.watch.flightmode
            elif kind == "GLOBAL_POSITION_INT":  # in the air above 1 m, landed below 0.3 m
                altitude = msg.relative_alt / 1000
                landed = altitude < 0.3 or (landed and altitude < 1.0)
            self.state = (armed, landed, mode, altitude)

    def look(self) -> tuple[bool, bool, str, float]:
        return self.state

    def inject(self, row: Row, proxy: LossyProxy) -> None:
        pass

    def stored_items(self) -> list[Any]:
        return []  # tml's own read-back (tml.mavlink.autopilot.check_read_back) says it

    def stop(self) -> None:
        self._running = False
        self._thread.join(timeout=2)
        self.watch.close()
        self.sitl.stop()


@dataclass
class Result:
    """One row of the table."""

    row: Row
    exit_code: int | str = ""
    reason: str = ""
    ended: str = ""
    takeoffs: int = 0
    takeoff_requests: int = 0
    actions: list[str] = field(default_factory=list)
    degraded: float | None = None
    lost: float | None = None
    upload: str = "-"
    fault_at: float | None = None

    def failures(self) -> list[str]:
        """The goals this row misses."""
        missed = []
        if self.ended.startswith("FLYING"):
            missed.append("left flying unwatched")
        if self.takeoffs > 1:
            missed.append("duplicate take-off")
        if self.row.outage >= DETECT_GOAL + 1 and (
                self.degraded is None or self.degraded > DETECT_GOAL):
            missed.append("link loss not detected within 3 s")
        if self.upload == "DIFFERENT":
            missed.append("upload not identical")
        return missed


def fly(row: Row, seed: int, ardupilot: bool, folder: Path) -> Result:
    """Fly one row; return what happened."""
    result = Result(row)
    vehicle: SimVehicle | ArduCopter = (ArduCopter(row, seed) if ardupilot
                                        else SimVehicle(row, seed))
    stem = row.name.replace(" ", "_").replace("%", "pc")
    log, errors = folder / f"{stem}.jsonl", folder / f"{stem}.err"
    seen = Seen()
    try:
        with LossyProxy(vehicle.port, loss=row.loss, seed=seed, lifetime=600.0) as proxy:
            if row.moment == "upload":
                proxy.cut_on("MISSION_ITEM_INT", row.outage)
            command = [sys.executable, "-m", "tml", "run",
                       str(ROOT / "missions" / f"{row.mission}.xml"),
                       "--connect", proxy.address, "-q"]
            tml = subprocess.Popen([*command, "--log", str(log)],
                                   stdout=subprocess.DEVNULL, stderr=errors.open("w"))
            started = time.monotonic()
            fired_at: float | None = None
            signalled = False
            while tml.poll() is None and time.monotonic() - started < RUN_LIMIT:
                _observe(vehicle, seen)
                now = time.monotonic()
                if fired_at is None and _moment(row, seen, now - started, proxy):
                    fired_at = now
                    result.fault_at = now
                    if row.outage and row.moment != "upload":
                        proxy.cut(row.outage)
                    vehicle.inject(row, proxy)
                    if row.resume:
                        tml.kill()
                        tml.wait()
                        tml = subprocess.Popen([*command, "--resume", str(log)],
                                               stdout=subprocess.DEVNULL,
                                               stderr=errors.open("a"))
                if (row.signal and not signalled and fired_at is not None
                        and now - fired_at >= row.delay):
                    tml.send_signal(row.signal)
                    signalled = True
                time.sleep(0.02)
            if tml.poll() is None:
                tml.kill()
                result.exit_code = "killed after 240 s"
            else:
                result.exit_code = tml.returncode
            tml.wait()
            if proxy.outages:
                result.fault_at = proxy.outages[0][0]
            end = time.monotonic() + WATCH_AFTER
            while time.monotonic() < end and not (seen.landed and not seen.armed):
                _observe(vehicle, seen)
                time.sleep(0.05)
            _observe(vehicle, seen)
            result.ended = _ending(seen)
            result.takeoffs = seen.takeoffs
            result.upload = _upload(proxy, vehicle)
    finally:
        vehicle.stop()
    _read_log(log, result)
    said = errors.read_text(errors="replace").strip().splitlines()
    if said and said[-1].strip() and "Traceback (most recent call last):" in said:
        result.reason += f" TRACEBACK: {said[-1].strip()}"
    return result


def _observe(vehicle: SimVehicle | ArduCopter, seen: Seen) -> None:
    armed, landed, mode, altitude = vehicle.look()
    if seen.landed and not landed and armed:
        seen.takeoffs += 1
    seen.armed, seen.landed, seen.mode, seen.altitude = armed, landed, mode, altitude


def _moment(row: Row, seen: Seen, elapsed: float, proxy: LossyProxy) -> bool:
    if row.moment == "start":
        return True
    if row.moment == "airborne":
        return not seen.landed and seen.armed
    if row.moment == "climb":
        return not seen.landed and 1.0 < seen.altitude < 6.0
    if row.moment == "flight":  # one second after the take-off (to 10 m) ended
        if seen.climbed is None and not seen.landed and seen.altitude > 9.5:
            seen.climbed = elapsed
        return seen.climbed is not None and elapsed - seen.climbed >= 1.0
    if row.moment == "upload":
        return bool(proxy.outages)
    return False


def _ending(seen: Seen) -> str:
    if seen.landed and not seen.armed:
        return "landed, disarmed"
    if seen.landed:
        return "landed, armed"
    if seen.mode in SAFE_MODES:
        return f"safe: {seen.mode} at {seen.altitude:.0f} m"
    return f"FLYING {seen.mode} at {seen.altitude:.0f} m"


def _upload(proxy: LossyProxy, vehicle: SimVehicle | ArduCopter) -> str:
    """The items tml sent (the proxy saw them, lost or not) against the vehicle's stored
    items, by ArduPilot's storage rules (tml.mavlink.mission.ardupilot_form)."""
    from tml.mavlink.mission import MissionItem, ardupilot_form, read_back_differences

    fields = ("seq", "frame", "command", "current", "autocontinue", "param1", "param2",
              "param3", "param4", "x", "y", "z")
    sent = sorted((MissionItem(**{n: getattr(m, n) for n in fields})
                   for (_, seq), m in proxy.up.sent.items() if seq > 0), key=lambda i: i.seq)
    if not sent:
        return "-"
    stored = [MissionItem(**{n: getattr(i, n) for n in fields})
              for i in vehicle.stored_items() if i.seq > 0]
    if not stored:
        return "-" if isinstance(vehicle, ArduCopter) else "not stored"
    if len(stored) != len(sent) or read_back_differences(sent, stored, ardupilot_form):
        return "DIFFERENT"
    return "identical"


def _read_log(log: Path, result: Result) -> None:
    if not log.exists():
        result.reason = "no flight log"
        return
    lines = [json.loads(text) for text in log.read_text().splitlines() if text.strip()]
    ends = [line for line in lines if line["kind"] == "run" and "outcomes" in line]
    if ends:
        result.reason = "; ".join(o.get("reason", "") for o in ends[-1]["outcomes"])
    result.takeoff_requests = sum(1 for line in lines if line["kind"] == "request"
                                  and line.get("message") == "TakeOff")
    result.actions = [line["action"] for line in lines if line["kind"] == "action"
                      and line["message"].endswith(" done")]
    start = result.fault_at
    if start is None:
        return
    for line in lines:
        if line["kind"] not in ("telemetry", "link") or line["t"] < start:
            continue
        if result.degraded is None and line["link"] != "ok":
            result.degraded = round(line["t"] - start, 1)
        if result.lost is None and line["link"] == "lost":
            result.lost = round(line["t"] - start, 1)


def _cell(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", help="comma-separated row names (substrings) to fly")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--ardupilot", action="store_true",
                        help="fly on ArduCopter SITL (the rows without simulator faults)")
    args = parser.parse_args()
    rows = _rows(args.seed)
    if args.rows:
        wanted = args.rows.split(",")
        rows = [r for r in rows if any(w in r.name for w in wanted)]
    print(f"vehicle: {'ArduCopter SITL' if args.ardupilot else 'sitl'} at speed-up "
          f"{SPEEDUP:g}; seed {args.seed}; load average {os.getloadavg()[0]:.1f}")
    print("| row | mission | exit, reason | vehicle ended | take-offs (vehicle / asked) | "
          "actions done | link degraded / lost after (s) | upload | goals |")
    print("|---|---|---|---|---|---|---|---|---|")
    failed = 0
    with tempfile.TemporaryDirectory(prefix="chaos-") as folder:
        for row in rows:
            if row.pending:
                print(f"| {row.name} | | not flown: {row.pending} | | | | | | |", flush=True)
                continue
            if args.ardupilot and row.sim_only:
                continue
            result = fly(row, args.seed, args.ardupilot, Path(folder))
            missed = result.failures()
            failed += bool(missed)
            print(f"| {row.name} | {row.mission} | {result.exit_code}, {result.reason} | "
                  f"{result.ended} | {result.takeoffs} / {result.takeoff_requests} | "
                  f"{' '.join(result.actions) or '-'} | {_cell(result.degraded)} / "
                  f"{_cell(result.lost)} | {result.upload} | "
                  f"{'MISSED: ' + ', '.join(missed) if missed else 'met'} |", flush=True)
    print(f"{failed} row(s) missed a goal")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
