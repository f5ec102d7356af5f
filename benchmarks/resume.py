"""Kill ``tml run`` with SIGKILL mid-mission and resume it: the same outcome as a run left alone?

For each mission and kill point, a vehicle is started in a process of its own (``python -m
sitl``, or ArduCopter SITL through tests/interop), the mission is flown once uninterrupted,
then again on a fresh vehicle with ``tml run`` killed (SIGKILL) at the kill point and run
again with ``--resume`` on the same vehicle, as often as needed until the run ends. A kill
point is "after decision N (+ D s)": the N-th ``task`` or ``request`` line of the flight log,
then D seconds of wall time, so that the kill falls before the request reached the vehicle,
while the vehicle carries it out, or just after a task ended.

Compared: the exit code, the tasks' ends in order (path and how each ended), the take-offs
commanded (TakeOff requests) and flown (the vehicle leaving the ground, from the log's
telemetry). Prints a Markdown table; docs/reliability.md keeps it.

    python benchmarks/resume.py                  # the simulator, every kill point
    python benchmarks/resume.py --quick          # two missions, a few points
    TML_INTEROP_FIRST_INSTANCE=80 python benchmarks/resume.py --ardupilot   # ArduCopter SITL
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tml.run.journal import read  # noqa: E402

MISSIONS = ROOT / "missions"
RUN_TIMEOUT = 240.0  # wall s for one tml run
SIM_PARAMS = ("SIM_EKF_GPS_TIME=2",)


@dataclass(frozen=True)
class Flown:
    """What a flight log says of a mission flown (across its resumed runs)."""

    exit_code: int | None
    ends: tuple[tuple[str, str], ...]  # each task's end, in order
    takeoffs_commanded: int
    takeoffs_flown: int
    uploads: int  # plans uploaded (FlyMission requests not following a plan flown)
    runs: int  # tml run processes it took


def summary(lines: Sequence[dict[str, Any]]) -> Flown:
    """The outcome of a flight log."""
    ended = [line for line in lines if line.get("kind") == "run"
             and line.get("message") == "run ended"]
    ends = tuple((str(line["task"]), str(line["state"])) for line in lines
                 if line.get("kind") == "task" and line.get("state") != "running")
    commanded = sum(1 for line in lines
                    if line.get("kind") == "request" and line.get("message") == "TakeOff")
    flown, landed = 0, True
    for line in lines:
        if line.get("kind") == "telemetry" and isinstance(line.get("landed"), bool):
            if landed and not line["landed"]:
                flown += 1
            landed = line["landed"]
    uploads = sum(1 for line in lines if line.get("kind") == "request"
                  and line.get("message") == "FlyMission" and not line.get("track"))
    runs = sum(1 for line in lines if line.get("kind") == "run"
               and line.get("message") in ("run started", "run resumed"))
    return Flown(int(ended[-1]["exit_code"]) if ended else None, ends, commanded, flown,
                 uploads, runs)


def decisions(path: Path) -> int:
    """The ``task`` and ``request`` lines in a log written so far."""
    try:
        text = path.read_text(errors="replace")
    except FileNotFoundError:
        return 0
    return text.count('"kind":"task"') + text.count('"kind":"request"')


def tml_run(mission: Path, address: str, log: Path, *, resume: bool,
            kill_after: tuple[int, float] | None = None) -> int | None:
    """One ``tml run`` (``--resume log`` or ``--log log``); its exit code, None if killed
    with SIGKILL after decision ``kill_after[0]`` plus ``kill_after[1]`` wall seconds."""
    command = [sys.executable, "-m", "tml", "run", str(mission), "--connect", address,
               "--clock", "vehicle", "-q", "--timeout", "60",
               *(["--resume", str(log)] if resume else ["--log", str(log)])]
    process = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    try:
        end = time.monotonic() + RUN_TIMEOUT
        if kill_after is not None:
            count, delay = kill_after
            while process.poll() is None and time.monotonic() < end:
                if decisions(log) >= count:
                    time.sleep(delay)
                    break
                time.sleep(0.02)
            if process.poll() is None:
                os.kill(process.pid, signal.SIGKILL)
                process.wait()
                return None
        return process.wait(timeout=max(1.0, end - time.monotonic()))
    finally:
        if process.poll() is None:
            os.kill(process.pid, signal.SIGKILL)
            process.wait()


def fly(mission: Path, address: str, log: Path,
        kill_after: tuple[int, float] | None = None) -> Flown:
    """Fly ``mission`` (killed once at ``kill_after``, then resumed until it ends)."""
    code = tml_run(mission, address, log, resume=False, kill_after=kill_after)
    for _ in range(3):
        if code is not None:
            break
        code = tml_run(mission, address, log, resume=True)
    return summary(read(str(log)))


def _free_port() -> int:
    for base in range(16560, 17560, 10):
        with socket.socket() as sock:
            if sock.connect_ex(("127.0.0.1", base)) != 0:
                return base
    raise RuntimeError("no free port for the simulator")


@contextlib.contextmanager
def simulator(speedup: float = 10.0) -> Iterator[str]:
    """``python -m sitl`` as a process of its own; its address. Stopped by its pid."""
    port = _free_port()
    params = [arg for p in SIM_PARAMS for arg in ("--param", p)]
    process = subprocess.Popen([sys.executable, "-m", "sitl", "--tcp-base-port", str(port),
                                "--speedup", str(speedup), *params], cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        end = time.monotonic() + 20
        while time.monotonic() < end:
            with socket.socket() as sock:
                if sock.connect_ex(("127.0.0.1", port)) == 0:
                    break
            time.sleep(0.1)
        yield f"tcp:127.0.0.1:{port}"
    finally:
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


Vehicle = Callable[[], contextlib.AbstractContextManager[str]]


@dataclass(frozen=True)
class Row:
    mission: str
    point: str
    alone: Flown
    resumed: Flown

    @property
    def same(self) -> bool:
        return (self.alone.exit_code == self.resumed.exit_code
                and self.alone.ends == self.resumed.ends
                and self.resumed.takeoffs_flown == self.alone.takeoffs_flown)


def campaign(plan: Sequence[tuple[str, Sequence[tuple[int, float]]]], vehicle: Vehicle,
             folder: Path, say: Callable[[Row], None] = lambda row: None) -> list[Row]:
    """Fly each mission alone, then killed at each of its points and resumed."""
    rows: list[Row] = []
    for name, points in plan:
        mission = MISSIONS / f"{name}.xml"
        with vehicle() as address:
            alone = fly(mission, address, folder / f"{name}-alone.jsonl")
        for count, delay in points:
            with vehicle() as address:
                log = folder / f"{name}-{count}-{delay:g}.jsonl"
                resumed = fly(mission, address, log, (count, delay))
            row = Row(name, f"decision {count} + {delay:g} s", alone, resumed)
            rows.append(row)
            say(row)
    return rows


def table(rows: Sequence[Row]) -> str:
    """The Markdown table of a campaign."""
    out = ["| mission | kill point | outcome alone | outcome resumed | tasks ended alone / "
           "resumed | take-offs flown alone / resumed (commanded) | plans uploaded alone / "
           "resumed | runs | same |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r.mission} | {r.point} | exit {r.alone.exit_code} | exit "
                   f"{r.resumed.exit_code} | {len(r.alone.ends)} / {len(r.resumed.ends)} | "
                   f"{r.alone.takeoffs_flown} / {r.resumed.takeoffs_flown} "
                   f"({r.resumed.takeoffs_commanded}) | {r.alone.uploads} / "
                   f"{r.resumed.uploads} | {r.resumed.runs} | "
                   f"{'yes' if r.same else 'NO'} |")
    return "\n".join(out)


PLAN: list[tuple[str, Sequence[tuple[int, float]]]] = [
    # Take-off (its requests, mid-climb), stabilize, a leg, the landing.
    ("paper_example1", [(1, 0.0), (3, 0.0), (3, 0.4), (5, 0.3), (9, 0.0), (11, 0.5),
                        (14, 0.2)]),
    # A memorized point, three rounds of a four-leg repeat, events.
    ("jump_and_repeat", [(4, 0.5), (7, 0.0), (9, 0.3), (14, 0.0), (20, 0.5), (28, 0.0),
                         (40, 0.3), (46, 0.0)]),
    # Skills, sub-tasks, an action repeated.
    ("aerostack_example", [(3, 0.5), (8, 0.0), (12, 0.3), (18, 0.2), (24, 0.0)]),
    # A plan flown in AUTO: killed before it is sent, as it is sent, while it is flown.
    ("mission_dispatch", [(6, 0.0), (7, 0.3), (8, 1.0), (14, 2.0), (24, 0.5)]),
]
ARDUPILOT_PLAN: list[tuple[str, Sequence[tuple[int, float]]]] = [
    ("paper_example1", [(3, 0.4), (5, 0.3), (9, 0.0), (14, 0.2)]),
    ("jump_and_repeat", [(9, 0.3), (20, 0.5)]),
    ("mission_dispatch", [(8, 1.0), (14, 2.0)]),
]
QUICK: list[tuple[str, Sequence[tuple[int, float]]]] = [
    ("paper_example1", [(3, 0.4), (9, 0.0)]),
    ("jump_and_repeat", [(20, 0.5)]),
]


@contextlib.contextmanager
def arducopter(speedup: float = 10.0) -> Iterator[str]:
    """ArduCopter SITL (tests/interop/ardupilot_sitl.py finds it; instances from
    TML_INTEROP_FIRST_INSTANCE) with ``tml companion`` on its second port, for the skills
    of paper_example1 and aerostack_example (tml run waits for it); its address. Both are
    stopped by their pids."""
    sys.path.insert(0, str(ROOT / "tests" / "interop"))
    from ardupilot_sitl import find_launcher, vehicles

    launcher, reason = find_launcher()
    if launcher is None:
        raise SystemExit(f"no ArduPilot SITL: {reason}")
    with vehicles(launcher, 1, "copter", speedup=speedup) as [sitl]:
        helper = subprocess.Popen([sys.executable, "-m", "tml", "companion", "--connect",
                                   sitl.companion_address], stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        try:
            yield sitl.address
        finally:
            helper.terminate()
            helper.wait(timeout=10)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="two missions, three points")
    parser.add_argument("--ardupilot", action="store_true",
                        help="ArduCopter SITL instead of the simulator")
    parser.add_argument("--speedup", type=float, default=10.0)
    args = parser.parse_args()
    plan = QUICK if args.quick else ARDUPILOT_PLAN if args.ardupilot else PLAN
    vehicle = arducopter if args.ardupilot else simulator
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="tml-resume-") as folder:
        rows = campaign(plan, lambda: vehicle(args.speedup), Path(folder),
                        lambda row: print(table([row]).splitlines()[-1], flush=True))
    what = ("ArduCopter SITL" if args.ardupilot
            else "simulator (python -m sitl, its own process)")
    print()
    print(f"python benchmarks/resume.py{' --quick' if args.quick else ''}"
          f"{' --ardupilot' if args.ardupilot else ''} -- {what} at {args.speedup:g}x, "
          f"{time.monotonic() - started:.0f} s, load average {os.getloadavg()[0]:.1f}")
    print()
    print(table(rows))
    return 0 if all(r.same for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
