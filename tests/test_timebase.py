"""tml.timebase: the system's time and the lock-step time of the embedded simulator."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tests.right_of_way import held_elsewhere
from tml import timebase as timebase_module
from tml.commands.cli import main
from tml.run.journal import read
from tml.timebase import SYSTEM, Flag, Lockstep, Timebase

# A guard against a hang, not a time limit: a flight in lock-step with the simulator is
# slower, never different, on a busy machine (tests/test_timebase.py), and one of a fleet
# beside three CPU spinners takes several minutes.
pytestmark = pytest.mark.timeout(900)

MISSIONS = Path(__file__).parent.parent / "missions"


def until(condition: Callable[[], bool], timeout: float = 30.0) -> None:
    """Wait for a state of another thread (generous: a state, not a duration, is tested)."""
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "the state never came"
        time.sleep(0.001)


# --- the system's time ------------------------------------------------------------------------

def test_the_systems_flag_behaves_as_an_event() -> None:
    flag: Flag = Flag(SYSTEM)
    assert not flag.wait(0.01)
    threading.Timer(0.01, flag.set).start()
    assert flag.wait(30.0) and flag.is_set()
    flag.clear()
    assert not flag.is_set()


# --- lock-step ----------------------------------------------------------------------------------

class Part:
    """A thread taking part in a lock-step time base that runs ``body`` once."""

    def __init__(self, timebase: Lockstep, body: Callable[[], object]) -> None:
        self.result: object = None
        self.done = threading.Event()
        timebase.announce()

        def run() -> None:
            with timebase.taking_part(announced=True):
                self.result = body()
            self.done.set()

        self.thread = threading.Thread(target=run, daemon=True)
        self.thread.start()


def test_a_thread_giving_way_waits_for_the_one_with_the_right_of_way(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(timebase_module, "GIVE_WAY_LIMIT", 600.0)
    for timebase in (Timebase(), Lockstep()):
        timebase.give_way()  # nobody has the right of way: at once
        giver = threading.Thread(target=timebase.give_way)
        with held_elsewhere(timebase, nested=True):  # nested: one stretch
            giver.start()
            giver.join(0.05)
            assert giver.is_alive()  # it waits ...
        giver.join(30)
        assert not giver.is_alive()  # ... until the right of way is let go of


def test_giving_way_waits_so_long_once_in_a_stretch(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(timebase_module, "GIVE_WAY_LIMIT", 0.01)
    timebase = Timebase()
    with held_elsewhere(timebase):
        timebase.give_way()  # the limit: it goes on while the right of way is held
        monkeypatch.setattr(timebase_module, "GIVE_WAY_LIMIT", 600.0)
        giver = threading.Thread(target=timebase.give_way)
        giver.start()
        giver.join(30)
        assert not giver.is_alive()  # this stretch outlasted a wait already: no second one


def test_time_waits_for_an_announced_thread_until_it_waits() -> None:
    timebase = Lockstep()
    go = threading.Event()
    Part(timebase, lambda: (go.wait(30.0), timebase.sleep(1.0)))
    assert not timebase.settled()  # started, still running (blocked outside the time base)
    go.set()
    until(timebase.settled)  # now waiting in sleep(1.0)


def test_a_wait_ends_at_its_deadline_only_once_fired() -> None:
    timebase = Lockstep()
    part = Part(timebase, lambda: timebase.sleep(1.0) or timebase.now())
    until(timebase.settled)
    timebase.advance(0.95)
    assert not timebase.fire()  # nothing due yet
    timebase.advance(1.0)
    assert timebase.settled()  # the instant's messages come before its timers
    assert timebase.fire()
    assert part.done.wait(30.0) and part.result == 1.0


def test_a_notify_counts_the_woken_thread_as_running_before_it_runs() -> None:
    timebase = Lockstep()
    flag = Flag(timebase)
    part = Part(timebase, lambda: flag.wait(10.0))
    until(timebase.settled)
    flag.set()
    # Whether or not the thread has been scheduled yet, time must not move on without it.
    assert not timebase.settled()
    assert part.done.wait(30.0) and part.result is True
    until(timebase.settled)  # it left: nobody takes part any more


def test_bytes_sent_and_not_read_hold_time() -> None:
    timebase = Lockstep()
    timebase.track(("127.0.0.1", 1))
    timebase.carried(("127.0.0.1", 1), 10)
    assert not timebase.settled()
    timebase.carried(("127.0.0.1", 1), -10)
    assert timebase.settled()
    timebase.carried(("127.0.0.1", 2), 5)  # not tracked: another client's bytes
    assert timebase.settled()


def test_a_thread_stuck_outside_the_time_base_holds_time_only_so_long() -> None:
    timebase = Lockstep(stall_after=0.05)
    stuck = threading.Event()
    Part(timebase, lambda: stuck.wait(30.0))
    try:
        until(lambda: timebase.settled() and timebase.stalls == 1)
    finally:
        stuck.set()


# --- a flight in lock-step ----------------------------------------------------------------------

@pytest.fixture
def busy_machine() -> Iterator[None]:
    """Three processes spinning on the CPU beside the test, stopped by their own pids."""
    spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
                for _ in range(3)]
    try:
        yield
    finally:
        for spinner in spinners:
            spinner.kill()
            spinner.wait()


def fly(tmp_path: Path, name: str) -> list[str]:
    """Fly paper_example1 on the lock-step simulator; the log, each instant's lines sorted
    (what happens at one instant may be written in either order) and without wall time."""
    log = tmp_path / f"{name}.jsonl"
    code = main(["run", str(MISSIONS / "paper_example1.xml"), "--sim", "-q", "--speedup", "50",
                 "--sim-param", "SIM_GPS_LOCKTIME=1", "--sim-param", "SIM_EKF_GPS_TIME=2",
                 "--log", str(log)])
    assert code == 0
    lines = []
    for line in read(str(log)):
        line.pop("wall", None)
        lines.append(line)
    return [text for _, group in itertools.groupby(lines, key=lambda line: line["t"])
            for text in sorted(json.dumps(line, sort_keys=True) for line in group)]


def test_a_flight_gives_the_same_log_on_an_idle_and_on_a_busy_machine(
        tmp_path: Path, request: pytest.FixtureRequest) -> None:
    idle = fly(tmp_path, "idle")
    request.getfixturevalue("busy_machine")
    busy = fly(tmp_path, "busy")
    assert busy == idle
