"""Time and peak memory of `tml validate` on hostile files, beside xmllint on the same files.

The files: 200 MB of tasks, one million tasks, elements nested 100,000 deep, and the
largest mission tml accepts (tasks up to the 8 MB bound of tml.language.xml), with a small
valid mission for the start-up cost. Each command runs in its own process; its maximum
resident set size comes from the kernel's accounting of that process (wait4). The peer,
`xmllint --noout` (Debian package libxml2-utils), parses the same file in the same run:
it checks well-formedness only, with no bound on size or depth. Prints one row per file
and command (median time of the runs, largest RSS), and the ratios tml / xmllint.

    python benchmarks/hostile.py [--runs 3] [--only NAME]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

TASK = b'  <task name="t%d"><action name="WAIT"><argument name="duration" value="1"/>' \
       b'</action></task>\n'
HEAD = b'<?xml version="1.0" encoding="UTF-8"?>\n<mission name="hostile">\n'
TAIL = b"</mission>\n"
MAX_BYTES = 8 * 1024 * 1024  # tml.language.xml.MAX_BYTES, not imported: tml may be absent


def tasks_up_to(size: int) -> Callable[[BinaryIO], None]:
    def write(stream: BinaryIO) -> None:
        stream.write(HEAD)
        written, index = len(HEAD) + len(TAIL), 0
        while True:
            task = TASK % index
            if written + len(task) > size:
                break
            stream.write(task)
            written, index = written + len(task), index + 1
        stream.write(TAIL)
    return write


def tasks(count: int) -> Callable[[BinaryIO], None]:
    def write(stream: BinaryIO) -> None:
        stream.write(HEAD)
        for start in range(0, count, 10_000):
            stream.write(b"".join(TASK % i for i in range(start, min(count, start + 10_000))))
        stream.write(TAIL)
    return write


def nesting(depth: int) -> Callable[[BinaryIO], None]:
    def write(stream: BinaryIO) -> None:
        stream.write(HEAD)
        stream.write(b'<task name="n">' * depth)
        stream.write(b'<action name="LAND"/>')
        stream.write(b"</task>" * depth)
        stream.write(TAIL)
    return write


FILES: dict[str, Callable[[BinaryIO], None]] = {
    "small valid mission (start-up)": tasks(3),
    "largest accepted (8 MB of tasks)": tasks_up_to(MAX_BYTES),
    "1,000,000 tasks": tasks(1_000_000),
    "200 MB of tasks": tasks_up_to(200 * 1000 * 1000),
    "100,000 nested tasks": nesting(100_000),
}


def measure(command: list[str]) -> tuple[float, float, int]:
    """(seconds, max RSS in MB, exit code) of one run of ``command``."""
    start = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(process.pid, 0)
    elapsed = time.perf_counter() - start
    process.returncode = os.waitstatus_to_exitcode(status)
    return elapsed, usage.ru_maxrss / 1024, process.returncode


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--only", default="", help="the files whose label contains this")
    args = parser.parse_args()
    xmllint = shutil.which("xmllint")
    tml = shutil.which("tml") or str(Path(sys.executable).with_name("tml"))
    if not xmllint or not Path(tml).exists():
        sys.exit("needs xmllint (apt-get install libxml2-utils) and tml (pip install .)")
    print(f"load average {os.getloadavg()[0]:.1f}; median of {args.runs} runs; "
          f"RSS: the largest of the runs")
    print("| file | size | tml validate: exit, time, max RSS | xmllint --noout: exit, time, "
          "max RSS | time ratio | RSS ratio |")
    print("|---|---:|---|---|---:|---:|")
    with tempfile.TemporaryDirectory() as folder:
        for label, write in FILES.items():
            if args.only not in label:
                continue
            path = Path(folder) / "hostile.xml"
            with path.open("wb") as stream:
                write(stream)
            size = path.stat().st_size
            rows: dict[str, tuple[float, float, int]] = {}
            ours, peers = [], []
            for _ in range(args.runs):  # interleaved: both see the same load
                ours.append(measure([tml, "validate", "-q", str(path)]))
                peers.append(measure([xmllint, "--noout", "--huge", str(path)]))
            for name, runs in (("tml", ours), ("xmllint", peers)):
                rows[name] = (statistics.median(r[0] for r in runs), max(r[1] for r in runs),
                              runs[0][2])
            (t_time, t_rss, t_code), (x_time, x_rss, x_code) = rows["tml"], rows["xmllint"]
            print(f"| {label} | {size / 1e6:.1f} MB | {t_code}, {t_time:.2f} s, "
                  f"{t_rss:.0f} MB | {x_code}, {x_time:.2f} s, {x_rss:.0f} MB | "
                  f"{t_time / x_time:.2f} | {t_rss / x_rss:.2f} |", flush=True)
            path.unlink()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
