"""Time `tml validate` against `xmllint --schema` on the same 1,000 generated missions.

xmllint (Debian package libxml2-utils) checks the XML Schema only; tml checks the schema
and the language's semantic rules. Both validate all files in one process, as a CI job
would. Prints the median of several runs of each and their ratio.

    python benchmarks/validate.py [--files 1000] [--runs 5] [--seed 1]
"""

from __future__ import annotations

import argparse
import random
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


def timed(command: list[str]) -> float:
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"{command[0]} failed ({done.returncode}):\n{done.stdout[-2000:]}"
                 f"{done.stderr[-2000:]}")
    return elapsed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, default=1000)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    xmllint = shutil.which("xmllint")
    tml = shutil.which("tml")
    if not xmllint or not tml:
        sys.exit("needs xmllint (apt-get install libxml2-utils) and tml (pip install .)")
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory() as folder:
        paths = []
        for index in range(args.files):
            path = Path(folder) / f"mission_{index:04d}.xml"
            path.write_text(mission(rng, index))
            paths.append(str(path))
        size = sum(Path(p).stat().st_size for p in paths)
        schema = str(ROOT / "schemas" / "tml.xsd")
        peer = [xmllint, "--noout", "--schema", schema, *paths]
        ours = [tml, "validate", "-q", folder]
        peer_times, our_times = [], []
        for _ in range(args.runs):  # interleaved, so both see the same machine load
            peer_times.append(timed(peer))
            our_times.append(timed(ours))
    peer_median, our_median = statistics.median(peer_times), statistics.median(our_times)
    print(f"{args.files} files, {size / 1e6:.1f} MB, median of {args.runs} runs")
    print(f"xmllint --schema (schema only):        {peer_median:7.3f} s")
    print(f"tml validate (schema and semantics):   {our_median:7.3f} s")
    print(f"ratio tml / xmllint:                   {our_median / peer_median:7.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
