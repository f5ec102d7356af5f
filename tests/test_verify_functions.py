"""The functions of the paper's feasibility model."""

from __future__ import annotations

import math

import pytest

from tml.verify import functions
from tml.verify.planner import Planner
from tml.world import Cylinder


@pytest.mark.parametrize(("charge", "rate", "metres"), [
    (80.0, 0.02, 4000.0), (0.0, 0.02, 0.0), (-5.0, 0.02, 0.0), (50.0, 0.0, math.inf),
])
def test_distance_battery(charge: float, rate: float, metres: float) -> None:
    assert functions.distance_battery(charge, rate) == pytest.approx(metres)


@pytest.mark.parametrize(("length", "now", "arrival", "needed"), [
    (100.0, 10.0, 30.0, 5.0), (0.0, 10.0, 5.0, 0.0), (100.0, 10.0, 10.0, math.inf),
])
def test_speed(length: float, now: float, arrival: float, needed: float) -> None:
    assert functions.speed(length, now, arrival) == pytest.approx(needed)


def test_distance_obstacle_counts_the_height_above_the_top() -> None:
    planner = Planner([Cylinder("tank", 0, 0, 5, top=10)], 3)
    assert functions.distance_obstacle((0, 8, 5), planner) == pytest.approx(3.0)
    assert functions.distance_obstacle((0, 8, 14), planner) == pytest.approx(5.0)  # 3-4-5
    assert functions.distance_obstacle((0, 0, 10), Planner([], 3)) == math.inf


def test_distance_length_and_trajectory() -> None:
    planner = Planner([], 3)
    path = functions.trajectory((0, 0, 0), (3, 4, 12), planner)
    assert path is not None
    assert functions.length(path) == pytest.approx(13.0)
    assert functions.distance((0, 0, 0), (3, 4, 12)) == pytest.approx(13.0)
