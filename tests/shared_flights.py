"""Flights several test modules read: each flown once per test session, by whichever
pytest-xdist worker asks first, its flight log then read by every test that asks again.

A flight on the embedded simulator runs in lock-step with tml, so the same command line
flies the same flight on any machine and at any speed-up (tests/test_timebase.py): the log
one worker wrote is the log another would have written. The flights are kept in the test
session's base directory, shared by its workers, under a lock each, so that a second
worker asking for a flight under way waits for it instead of flying it again.
"""

from __future__ import annotations

import fcntl
import hashlib
from pathlib import Path

import pytest

from tml.commands.cli import main
from tml.run.journal import read

MISSIONS = Path(__file__).parent.parent / "missions"
FAST = ["--speedup", "50", "--sim-param", "SIM_GPS_LOCKTIME=1",
        "--sim-param", "SIM_EKF_GPS_TIME=2"]
"""Fifty times real time at most, the GPS and EKF delays cut to 1-2 s."""
FLEET = ["--sim-param", "BATT_CAPACITY=1700", "--sim-param", "SIM_BATT_CHARGE=64",
         "--link-lost-limit", "60"]
"""The fleet missions' battery (1700 mAh) and charging pad (64 A): rounds that drain to
30 % and recharge to 90 % in minutes (tests/test_fleet_flights.py); several simulated
vehicles load the machine, so a stalled link is given longer before a run is aborted."""


def flown(factory: pytest.TempPathFactory, name: str, options: list[str]
          ) -> tuple[int, list[dict]]:
    """``tml run missions/NAME.xml --sim -q OPTIONS`` with the :data:`FAST` settings,
    flown once per session: its exit code and its flight log's lines."""
    arguments = ["run", str(MISSIONS / f"{name}.xml"), "--sim", "-q", *FAST, *options]
    base = factory.getbasetemp()
    if base.name.startswith("popen-gw"):  # a pytest-xdist worker's: the session's is above
        base = base.parent
    folder = base / "shared-flights"
    folder.mkdir(exist_ok=True)
    key = hashlib.sha256("\0".join(arguments).encode()).hexdigest()[:16]
    log, code = folder / f"{name}-{key}.jsonl", folder / f"{name}-{key}.exit"
    with open(folder / f"{name}-{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file is closed
        if not code.exists():
            log.unlink(missing_ok=True)  # a flight of a worker that died in it
            code.write_text(str(main([*arguments, "--log", str(log)])))
    return int(code.read_text()), read(str(log))
