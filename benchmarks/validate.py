"""Time `tml validate` against `xmllint --schema` on the same generated missions.

xmllint (Debian package libxml2-utils) checks the XML Schema only; tml checks the schema
and the language's semantic rules. Each validates all files of a run in one process, as a
CI job (1,000 files) or a pre-commit hook (1 or 10 files) would, so process start-up and
imports count. Runs are interleaved, so both see the same machine load; prints, for each
number of files, the median wall time and the median CPU time (user + system, workers
included) of each, their ratios, and the load average before and after.

tml runs from compiled bytecode, as an installed package does (a first, untimed run
writes it where PYTHONDONTWRITEBYTECODE would have kept it from being written).

    python benchmarks/validate.py [--files 1000 10 1] [--runs 5] [--seed 1]
"""

from __future__ import annotations

import argparse
import os
import random
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ACTIONS = [
    '<action name="TAKE_OFF"><argument name="altitude" value="{alt}"/></action>',
    '<action name="GO_TO_POINT"><argument name="coordinates" value="({x}, {y}, {alt})"/></action>',
    '<action name="MOVE"><argument name="coordinates" value="({x}, {y}, 0)"/></action>',
    '<action name="WAIT"><argument name="duration" value="{t}"/></action>',
    '<action name="ROTATE_YAW"><argument name="angle" value="{a}"/></action>',
    '<action name="LOITER"><argument name="turns" value="2"/><argument name="radius" '
    'value="{r}"/></action>',
    '<action name="SURVEY_AREA"><argument name="length" value="{l}"/><argument name="width" '
    'value="{l}"/><argument name="spacing" value="10"/></action>',
    '<action name="CAPTURE_PHOTO"/>',
    '<action name="SET_SPEED"><argument name="speed" value="{s}"/></action>',
    '<action name="STABILIZE"/>',
]
CONDITIONS = [
    '<condition parameter="BATTERY_CHARGE_PERCENTAGE" comparison="greater than" value="{p}"/>',
    '<condition parameter="ALTITUDE" comparison="less than" value="{alt}"/>',
    '<condition parameter="FLIGHT_MODE" comparison="equal" value="GUIDED"/>',
]


def mission(rng: random.Random, index: int) -> str:
    counter = iter(range(10**6))

    def values() -> dict[str, object]:
        return {"alt": rng.randint(5, 60), "x": rng.randint(-200, 200),
                "y": rng.randint(-200, 200), "t": rng.randint(1, 30), "a": rng.randint(-180, 180),
                "r": rng.randint(5, 30), "l": rng.randint(20, 200), "s": rng.randint(2, 15),
                "p": rng.randint(20, 60)}

    def task(depth: int) -> str:
        name = f"task {next(counter)}"
        inner = ""
        if rng.random() < 0.2:
            inner += rng.choice(CONDITIONS).format(**values())
        if rng.random() < 0.1:
            inner += f'<repeat times="{rng.randint(2, 4)}"/>'
        if depth < 3 and rng.random() < 0.3:
            inner += "".join(task(depth + 1) for _ in range(rng.randint(2, 5)))
        else:
            inner += rng.choice(ACTIONS).format(**values())
        return f'  <task name="{name}">{inner}</task>\n'

    tasks = "".join(task(0) for _ in range(rng.randint(3, 30)))
    events = ('<event_handling><event name="low battery"><condition '
              'parameter="BATTERY_CHARGE_PERCENTAGE" comparison="less than" value="25"/>'
              '<action name="RETURN_HOME_AND_LAND"/><termination mode="ABORT_MISSION"/>'
              '</event></event_handling>\n')
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<mission name="generated {index}">\n'
            f'  <task name="start"><action name="TAKE_OFF"/></task>\n{tasks}{events}</mission>\n')


def timed(command: list[str], env: dict[str, str] | None = None) -> tuple[float, float]:
    """Wall and CPU seconds (user + system, its children included) of one run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, env=env)
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        sys.exit(f"{command[0]} failed ({done.returncode}):\n{done.stdout[-2000:]}"
                 f"{done.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return elapsed, cpu


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, nargs="+", default=[1000, 10, 1],
                        help="numbers of files validated per call (default 1000 10 1)")
    parser.add_argument("--runs", type=int, default=5,
                        help="runs of each per number of files (more for fewer files)")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    xmllint = shutil.which("xmllint")
    tml = shutil.which("tml")
    if not xmllint or not tml:
        sys.exit("needs xmllint (apt-get install libxml2-utils) and tml (pip install .)")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    schema = str(ROOT / "schemas" / "tml.xsd")
    print(f"{os.cpu_count()} cores, load average {load()} (1, 5, 15 min)")
    print(f"{'files':>6} {'runs':>4} | {'xmllint wall':>12} {'tml wall':>9} {'ratio':>6} | "
          f"{'xmllint cpu':>11} {'tml cpu':>8} {'ratio':>6}")
    for count in args.files:
        rng = random.Random(args.seed)
        runs = args.runs if count >= 100 else args.runs * 4
        with tempfile.TemporaryDirectory() as folder:
            paths = []
            for index in range(count):
                path = Path(folder) / f"mission_{index:04d}.xml"
                path.write_text(mission(rng, index))
                paths.append(str(path))
            peer = [xmllint, "--noout", "--schema", schema, *paths]
            ours = [tml, "validate", "-q", folder]
            timed(ours, env)  # writes the bytecode an installed package has
            peer_times, our_times = [], []
            for _ in range(runs):  # interleaved, so both see the same machine load
                peer_times.append(timed(peer))
                our_times.append(timed(ours, env))
        peer_wall = statistics.median(t for t, _ in peer_times)
        our_wall = statistics.median(t for t, _ in our_times)
        peer_cpu = statistics.median(c for _, c in peer_times)
        our_cpu = statistics.median(c for _, c in our_times)
        print(f"{count:>6} {runs:>4} | {peer_wall:>10.3f} s {our_wall:>7.3f} s "
              f"{our_wall / peer_wall:>6.2f} | {peer_cpu:>9.3f} s {our_cpu:>6.3f} s "
              f"{our_cpu / max(peer_cpu, 1e-3):>6.2f}")
    print(f"load average after: {load()}; tml: schema and semantics, xmllint: schema only")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
