"""Geometry and limits of the action scripts (tml.engine.scripts)."""

from __future__ import annotations

import math

import pytest

from tml.actions import bind
from tml.engine.scripts import _displaced, _expanding_square, survey_legs
from tml.errors import Location
from tml.model import Action, Argument

HERE = Location("m.xml", 1, 1)


def survey(**values: str):
    return bind(Action("SURVEY_AREA", tuple(Argument(k, v, None, HERE)
                                            for k, v in values.items()), HERE))


def test_survey_legs_cover_the_area_in_the_right_quadrant() -> None:
    corners = survey_legs(0.0, 0.0, survey(length="30", width="20", spacing="10",
                                           direction="NORTH_EAST"))
    assert corners == [(0, 0), (30, 0), (30, 10), (0, 10), (0, 20), (30, 20)]
    south_west = survey_legs(5.0, 5.0, survey(length="30", width="20", spacing="10",
                                              direction="SOUTH_WEST"))
    assert {n for n, _ in south_west} == {5.0, -25.0}
    assert {e for _, e in south_west} == {5.0, -5.0, -15.0}


def test_survey_last_pass_stays_inside_the_width() -> None:
    corners = survey_legs(0.0, 0.0, survey(length="10", width="25", spacing="10"))
    assert max(abs(e) for _, e in corners) == 20  # passes at 0, 10, 20: none beyond 25


def test_expanding_square_stays_within_radius_and_reaches_it() -> None:
    points = list(_expanding_square(3.0, 1.0))
    assert all(abs(n) <= 3 and abs(e) <= 3 for n, e in points)
    assert max(max(abs(n), abs(e)) for n, e in points) == 3
    assert len(points) == len(set(points))


@pytest.mark.parametrize(
    ("heading", "direction", "expected"),
    [(0, "forward", (2, 0, 5)), (90, "forward", (0, 2, 5)), (0, "right", (0, 2, 5)),
     (90, "backward", (0, -2, 5)), (180, "left", (0, 2, 5)), (45, "up", (0, 0, 7)),
     (45, "down", (0, 0, 3))],
)
def test_displaced(heading: float, direction: str, expected: tuple[float, ...]) -> None:
    result = _displaced((0.0, 0.0, 5.0), heading, direction, 2.0)
    assert all(math.isclose(a, b, abs_tol=1e-9) for a, b in zip(result, expected, strict=True))
