"""Flight patterns flown by the interpreter and predicted by the verifier: one source for both.

Points are local ``(north, east, up)`` metres from home (see :mod:`tml.geo`).
"""

from __future__ import annotations

import math

Point3 = tuple[float, float, float]

CIRCLE_POINTS_PER_TURN = 16
"""A circle (LOITER, RETURN_HOME_AND_LOITER) is flown as a polygon of this many GUIDED
targets per turn, each reached before the next is sent."""


def circle_point(centre: Point3, radius: float, start: float, step: int) -> Point3:
    """The ``step``-th target of a circle around ``centre`` that begins at the bearing
    ``start`` (radians, clockwise from north), going clockwise."""
    angle = start + 2 * math.pi * step / CIRCLE_POINTS_PER_TURN
    return (centre[0] + radius * math.cos(angle), centre[1] + radius * math.sin(angle),
            centre[2])


def circle_chord(radius: float) -> float:
    """Metres between two consecutive targets of a circle of ``radius``."""
    return 2 * radius * math.sin(math.pi / CIRCLE_POINTS_PER_TURN)
