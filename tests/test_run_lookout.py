"""Which vehicles a wake of the runner looks at (tml.run.lookout)."""

from __future__ import annotations

import math

from tml.run.lookout import Lookout


def settle(lookout: Lookout, now: float, due_at: float = math.inf) -> list[int]:
    """One wake: what it looks at, each then left with nothing to follow."""
    picked = lookout.due(now)
    for index in picked:
        lookout.looked(index, due_at, False)
    return picked


def test_the_first_wake_looks_at_every_vehicle_and_the_next_at_none() -> None:
    lookout = Lookout(4)
    assert settle(lookout, 0.0) == [0, 1, 2, 3]
    assert lookout.due(0.1) == []


def test_a_stirred_vehicle_is_looked_at_once_by_the_next_wake() -> None:
    lookout = Lookout(5)
    settle(lookout, 0.0)
    lookout.stir(3)
    lookout.stir(1)
    lookout.stir(3)
    assert lookout.due(0.1) == [1, 3]  # in their order, each once
    assert lookout.due(0.2) == []


def test_a_stir_while_a_vehicle_is_looked_at_is_not_lost() -> None:
    lookout = Lookout(2)
    settle(lookout, 0.0)
    lookout.stir(0)
    assert lookout.due(0.1) == [0]
    lookout.stir(0)  # a message arrives while its state is being read
    lookout.looked(0, math.inf, False)
    assert lookout.due(0.2) == [0]


def test_a_vehicle_is_looked_at_when_its_own_time_comes() -> None:
    lookout = Lookout(3)
    settle(lookout, 0.0)
    lookout.looked(2, 1.0, False)
    assert lookout.due(0.9) == []
    assert lookout.due(1.0) == [2]
    assert lookout.due(1.1) == []


def test_only_the_latest_time_of_a_vehicle_counts() -> None:
    lookout = Lookout(2)
    settle(lookout, 0.0)
    lookout.looked(1, 1.0, False)
    lookout.looked(1, 2.0, False)  # looked at again before 1.0: its time moved on
    assert lookout.due(1.5) == []
    assert lookout.due(2.0) == [1]


def test_a_vehicle_left_with_something_to_follow_is_looked_at_every_wake() -> None:
    lookout = Lookout(3)
    settle(lookout, 0.0)
    lookout.looked(1, math.inf, True)  # a lost link being timed
    assert lookout.due(0.1) == [1]
    assert lookout.due(0.2) == [1]
    lookout.looked(1, math.inf, False)
    assert lookout.due(0.3) == []
