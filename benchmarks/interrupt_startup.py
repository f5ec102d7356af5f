"""Ctrl-C at random moments of ``tml run``'s start-up, on a busy machine.

Run by hand: ``python benchmarks/interrupt_startup.py [--tries 40] [--spinners 3] [--seed 1]``.

Each try starts ``python -m tml run MISSION --connect tcp:127.0.0.1:PORT`` against a
listener that takes the connection and says nothing (so tml waits there for a vehicle,
300 s), sends SIGINT after a random delay of 0.05-1.5 s -- while the interpreter starts,
while tml loads its modules, reads the mission, opens the link, or waits for the vehicle --
and waits up to 20 s for it to end. ``--spinners`` processes spin on the CPU meanwhile (a
busy machine stretches every window). It prints each try and a count of the endings: tml's
``3`` (interrupted, one line), ``signal`` (ended by the signal itself) and ``python``
(Python's own start-up interrupted, before any of tml ran), anything else (a traceback from
tml: a defect), and ``hung`` (the interrupt was lost: a defect).
"""

from __future__ import annotations

import argparse
import collections
import random
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

MISSION = ('<mission name="Hop"><task name="Up"><action name="TAKE_OFF">'
           '<argument name="altitude" value="4"/></action></task></mission>\n')


def _before_tml(err: str) -> bool:
    """Whether an interrupt ended Python's own start-up, before any of tml ran: its
    traceback (or "Fatal Python error: init_import_site") has no frame of tml's files."""
    interrupted = err.rstrip().endswith("KeyboardInterrupt") or "init_import_site" in err
    return interrupted and "/tml/" not in err


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tries", type=int, default=40)
    parser.add_argument("--spinners", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
                for _ in range(args.spinners)]
    endings: collections.Counter[str] = collections.Counter()
    try:
        with tempfile.TemporaryDirectory() as folder:
            mission = Path(folder) / "hop.xml"
            mission.write_text(MISSION)
            for number in range(args.tries):
                delay = rng.uniform(0.05, 1.5)
                with socket.create_server(("127.0.0.1", 0)) as silent:
                    port = silent.getsockname()[1]
                    process = subprocess.Popen(
                        [sys.executable, "-m", "tml", "run", str(mission), "--connect",
                         f"tcp:127.0.0.1:{port}", "--timeout", "300"],
                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                        cwd=Path(__file__).resolve().parent.parent)
                    time.sleep(delay)
                    process.send_signal(signal.SIGINT)
                    try:
                        _, err = process.communicate(timeout=20)
                    except subprocess.TimeoutExpired:
                        process.kill()
                        process.communicate()
                        ending, err = "hung", ""
                    else:
                        code = process.returncode
                        ending = ("3" if code == 3 else "signal" if code == -signal.SIGINT
                                  else "python" if _before_tml(err) else f"exit {code}")
                endings[ending] += 1
                last = err.strip().splitlines()[-1] if err.strip() else ""
                print(f"{number:3d}  {delay:5.3f} s  {ending:8s}  {last[:70]}", flush=True)
    finally:
        for spinner in spinners:
            spinner.kill()
            spinner.wait()
    print("endings:", ", ".join(f"{name}: {count}" for name, count in endings.most_common()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
