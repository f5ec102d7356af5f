"""The heap while runs fly (tml.run.heap): what exists when the first run starts to fly is
kept out of the garbage collector's passes until the last run ends, and nothing is lost."""

from __future__ import annotations

import gc
import time
import weakref
from collections.abc import Iterator

import pytest

from tml.run import heap
from tml.run.heap import frozen


@pytest.fixture(autouse=True)
def no_other_run() -> Iterator[None]:
    """These tests read the process's frozen heap: a run another test left flying in this
    process (a service's thread winding down) is waited for first."""
    end = time.monotonic() + 60.0  # a hang guard
    while heap._flying:
        assert time.monotonic() < end, "a run of another test still flies"
        time.sleep(0.01)
    yield


class _Node:
    def __init__(self) -> None:
        self.other: _Node | None = None


def _cycle() -> weakref.ref[_Node]:
    """A reference cycle, already garbage: only the collector frees it."""
    a, b = _Node(), _Node()
    a.other, b.other = b, a
    return weakref.ref(a)


def test_objects_are_frozen_while_any_run_flies_and_given_back_after_the_last() -> None:
    assert gc.get_freeze_count() == 0
    with frozen():
        first = gc.get_freeze_count()
        assert first > 0
        later = _cycle()
        with frozen():  # a second run (tml serve): it freezes nothing more
            # (frozen objects may still be freed by their reference counts: fewer, never more)
            assert gc.get_freeze_count() <= first
            gc.collect()
            assert later() is None
        assert 0 < gc.get_freeze_count() <= first  # the first still flies
    assert gc.get_freeze_count() == 0


def test_garbage_frozen_with_a_run_is_collected_once_it_ends() -> None:
    gc.collect()
    made_before = _cycle()
    with frozen():
        gc.collect()
        assert made_before() is not None  # frozen: out of the collector's reach
        made_during = _cycle()
        gc.collect()
        assert made_during() is None  # what the flight makes is collected as ever
    gc.collect()
    assert made_before() is None  # given back: nothing is kept for good


def test_an_error_in_the_flight_gives_the_objects_back() -> None:
    try:
        with frozen():
            raise RuntimeError("boom")
    except RuntimeError:
        pass
    assert gc.get_freeze_count() == 0


def test_a_run_flies_frozen_and_ends_thawed() -> None:
    from test_runner import HOVER, LAND, TAKE_OFF, run

    from tml.errors import ExitCode

    counts: list[int] = []
    steps = [0]

    def count(_sim: object) -> None:
        # Every 20th step: the count walks the whole frozen heap, which in a worker that
        # ran many tests before holds millions of objects.
        if steps[0] % 20 == 0:
            counts.append(gc.get_freeze_count())
        steps[0] += 1

    outcome, *_ = run(TAKE_OFF + HOVER + LAND, hooks=[count])
    assert outcome.exit_code == ExitCode.OK
    assert counts and min(counts) > 0  # from the first task to the settling after the last
    assert gc.get_freeze_count() == 0
