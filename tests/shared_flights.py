"""Flights several test modules read: each flown once per test session, by whichever
pytest-xdist worker asks first, its flight log and the live view's screens then read by
every test that asks again.

A flight on the embedded simulator runs in lock-step with tml, so the same command line
flies the same flight on any machine and at any speed-up (tests/test_timebase.py): the log
one worker wrote is the log another would have written. The flights are kept in the test
session's base directory, shared by its workers, under a lock each, so that a second
worker asking for a flight under way waits for it instead of flying it again.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import io
import pickle
import shutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

import pytest
from rich.console import Console, RenderableType

import tml.run.display as display
from tml.commands.cli import main
from tml.language.validation import load_mission
from tml.run.display import LiveDisplay, Views, render_text
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


@dataclass
class Flight:
    """A flight flown by :func:`flown`: its exit code, its flight log (the file and its
    lines), the live view's last screen and its last screen drawn while an event handler
    held a task (text, as an 80x24 terminal showed them)."""

    code: int
    log: Path
    lines: list[dict]
    last: str
    held: str | None


@dataclass
class Watched:
    """What the live view drew: its last screen and the views with a task held."""

    last: RenderableType | None = None
    held: list[Views] = field(default_factory=list)


@contextlib.contextmanager
def watched(seen: Watched) -> Iterator[None]:
    """Within: ``tml run`` prints to an 80x24 terminal, and its live view's last screen
    and the views with a task held are kept in ``seen``."""
    terminal = Console(file=io.StringIO(), width=80, height=24, force_terminal=True)
    errors = Console(file=io.StringIO(), width=80, stderr=True)
    shown: list[LiveDisplay] = []
    originals = (display.output_console, LiveDisplay.__enter__, LiveDisplay.update)

    def enter(self: LiveDisplay) -> LiveDisplay:
        shown.append(self)
        return originals[1](self)

    def update(self: LiveDisplay, views: Views, force: bool = False) -> None:
        if any(view.held for view, _ in views):
            seen.held.append(list(views))
        originals[2](self, views, force)

    display.output_console = lambda stderr=False: errors if stderr else terminal  # type: ignore[assignment]
    LiveDisplay.__enter__ = enter  # type: ignore[method-assign]
    LiveDisplay.update = update  # type: ignore[method-assign]
    try:
        yield
    finally:
        display.output_console, LiveDisplay.__enter__, LiveDisplay.update = originals  # type: ignore[method-assign]
        seen.last = shown[-1].shown if shown else None


def screen(shown: RenderableType | None) -> str:
    """A screen of the live view as text, at 80x24 ("" for none)."""
    if shown is None:
        return ""
    console = Console(file=io.StringIO(), width=80, height=24, record=True)
    console.print(shown)
    return console.export_text()


def fly(folder: Path, name: str, options: list[str]) -> Flight:
    """``tml run missions/NAME.xml --sim --log FOLDER/NAME.jsonl OPTIONS`` with the live
    view on an 80x24 terminal."""
    log, mission = folder / f"{name}.jsonl", MISSIONS / f"{name}.xml"
    seen = Watched()
    with watched(seen):
        code = main(["run", str(mission), "--sim", "--log", str(log), *options])
    held = (render_text(load_mission(str(mission)), seen.held[-1], 80, 23) if seen.held
            else None)
    return Flight(code, log, read(str(log)), screen(seen.last), held)


def flown(factory: pytest.TempPathFactory, name: str, options: list[str]) -> Flight:
    """:func:`fly` with the :data:`FAST` settings and OPTIONS, flown once per session."""
    arguments = [*FAST, *options]
    return once(factory, name, "\0".join(arguments),
                lambda folder: fly(folder, name, arguments))
