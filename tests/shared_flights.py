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
import pickle
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import pytest

from tml.commands.cli import main
from tml.run.journal import read

T = TypeVar("T")
MISSIONS = Path(__file__).parent.parent / "missions"
FAST = ["--speedup", "50", "--sim-param", "SIM_GPS_LOCKTIME=1",
        "--sim-param", "SIM_EKF_GPS_TIME=2"]
"""Fifty times real time at most, the GPS and EKF delays cut to 1-2 s."""
FLEET = ["--sim-param", "BATT_CAPACITY=1700", "--sim-param", "SIM_BATT_CHARGE=64",
         "--link-lost-limit", "60"]
"""The fleet missions' battery (1700 mAh) and charging pad (64 A): rounds that drain to
30 % and recharge to 90 % in minutes (tests/test_fleet_flights.py); several simulated
vehicles load the machine, so a stalled link is given longer before a run is aborted."""


def once(factory: pytest.TempPathFactory, name: str, key: str,
         produce: Callable[[Path], T]) -> T:
    """``produce(folder)`` run once per session for ``name`` and ``key``, by whichever
    worker asks first; its result (pickled) returned to every worker that asks again."""
    base = factory.getbasetemp()
    if base.name.startswith("popen-gw"):  # a pytest-xdist worker's: the session's is above
        base = base.parent
    folder = base / "shared-flights"
    folder.mkdir(exist_ok=True)
    stem = f"{name}-{hashlib.sha256(key.encode()).hexdigest()[:16]}"
    result = folder / f"{stem}.pickle"
    with open(folder / f"{stem}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file is closed
        if not result.exists():  # else flown by another worker (or this one) before
            work = folder / stem
            shutil.rmtree(work, ignore_errors=True)  # a worker that died in it
            work.mkdir()
            result.write_bytes(pickle.dumps(produce(work)))
    loaded: T = pickle.loads(result.read_bytes())
    return loaded


def flown(factory: pytest.TempPathFactory, name: str, options: list[str]
          ) -> tuple[int, list[dict]]:
    """``tml run missions/NAME.xml --sim -q OPTIONS`` with the :data:`FAST` settings,
    flown once per session: its exit code and its flight log's lines."""
    arguments = ["run", str(MISSIONS / f"{name}.xml"), "--sim", "-q", *FAST, *options]

    def fly(folder: Path) -> tuple[int, list[dict]]:
        log = folder / f"{name}.jsonl"
        return main([*arguments, "--log", str(log)]), read(str(log))

    return once(factory, name, "\0".join(arguments), fly)
