"""Flight patterns: the points an action flies through, one source for all that flies them.

Theory of operation
-------------------
An action is flown three ways: with commands by a script (:mod:`tml.engine.scripts`, each
point a GUIDED target reached before the next is sent), as mission items
(:mod:`tml.mavlink.compile`, each point a NAV_WAYPOINT), and in prediction by the verifier
(:mod:`tml.verify.motion`, each point the end of a leg it times, costs and checks against
the obstacles). None of them computes a pattern of its own: each asks this module, so that
the path verified is the path flown, whichever way it is flown
(tests/test_patterns.py flies all three and compares them).

A pattern is a pure function of an action's arguments and of where it starts, returning
local points ``(north, east, up)`` in metres from home (see :mod:`tml.geo`), in the order
they are flown. Headings and bearings are clockwise from north.

- :func:`displaced`: where a move of a distance in a body direction (MOVE, MOVE_FORWARDS)
  leads.
- :func:`survey`: SURVEY_AREA's lawnmower.
- :func:`expanding_square`: EXPLORE_SPACE's expanding square, back to its centre.
- :func:`circle`, :func:`circle_point`, :func:`circle_entry`: LOITER and
  RETURN_HOME_AND_LOITER flown as a polygon of GUIDED targets.
- :func:`stop_to_stop`: how long a leg between two points where the vehicle stops takes
  (the verifier's prediction and the interpreter's time limits alike).
"""

from __future__ import annotations

import math

Point3 = tuple[float, float, float]

_EDGE = 1e-9
"""Relative tolerance under which a distance counts as reaching an edge (a width or a
radius that is a multiple of the spacing, up to rounding)."""


# --- moves in the body frame ----------------------------------------------------------------

BODY_DIRECTIONS: dict[str, float] = {"forward": 0.0, "right": 90.0, "backward": 180.0,
                                     "left": 270.0}
"""The horizontal directions of MOVE, as bearings relative to the heading."""

VERTICAL_DIRECTIONS: dict[str, float] = {"up": 1.0, "down": -1.0}
"""The vertical directions of MOVE, as the sign of the change of altitude."""


def displaced(position: Point3, heading: float, direction: str, distance: float) -> Point3:
    """Where ``distance`` metres in ``direction`` (a word of :data:`BODY_DIRECTIONS` or
    :data:`VERTICAL_DIRECTIONS`) lead from ``position`` for a vehicle facing ``heading``
    (degrees); a horizontal move keeps the altitude."""
    north, east, up = position
    if direction in VERTICAL_DIRECTIONS:
        return (north, east, up + VERTICAL_DIRECTIONS[direction] * distance)
    bearing = math.radians(heading + BODY_DIRECTIONS[direction])
    return (north + distance * math.cos(bearing), east + distance * math.sin(bearing), up)


# --- SURVEY_AREA ------------------------------------------------------------------------------

QUADRANTS: dict[str, tuple[float, float]] = {
    "NORTH_EAST": (1.0, 1.0), "NORTH_WEST": (1.0, -1.0),
    "SOUTH_EAST": (-1.0, 1.0), "SOUTH_WEST": (-1.0, -1.0)}
"""SURVEY_AREA's directions: the quadrant the area extends into from its base point, as
(north sign, east sign)."""


def survey_offsets(width: float, spacing: float) -> list[float]:
    """How far across the area each pass of a survey lies: ``spacing`` apart from the near
    edge (0), the last one on the far edge (``width``).

    The first pass lies on the near edge, so the area is covered to its far edge only if
    the last pass lies on that edge too: with passes at whole multiples of the spacing
    alone, a strip up to one spacing wide along the far edge would be flown past (width 25,
    spacing 10: passes at 0, 10, 20 leave 20 to 25; width 29 leaves 20 to 29). The last
    pass is then closer to the one before it than the spacing, never farther.
    """
    if spacing <= 0:
        raise ValueError(f"a survey's spacing must be positive, not {spacing:g}")
    passes = math.ceil(width / spacing * (1 - _EDGE))  # those short of the far edge
    return [index * spacing for index in range(passes)] + [width]


def survey(base: Point3, length: float, width: float, spacing: float,
           direction: str) -> list[Point3]:
    """The lawnmower of SURVEY_AREA at ``base``'s altitude: from the base point, passes
    ``length`` metres long along north/south, across ``width`` metres east/west as
    :func:`survey_offsets` lays them, into the quadrant ``direction`` names
    (:data:`QUADRANTS`). The first point is the base point; each pass is flown the other
    way from the one before."""
    north_sign, east_sign = QUADRANTS[direction]
    points: list[Point3] = []
    for index, across in enumerate(survey_offsets(width, spacing)):
        ends = (0.0, length) if index % 2 == 0 else (length, 0.0)
        points.extend((base[0] + north_sign * along, base[1] + east_sign * across, base[2])
                      for along in ends)
    return points


# --- EXPLORE_SPACE ----------------------------------------------------------------------------

_SQUARE_LEGS = ((1, 0), (0, 1), (-1, 0), (0, -1))  # north, east, south, west


def expanding_square(centre: Point3, radius: float, spacing: float) -> list[Point3]:
    """The expanding square of EXPLORE_SPACE over the square of half-width ``radius``
    around ``centre``, at the centre's altitude, ending back at the centre.

    Legs go north, east, south, west, 1, 1, 2, 2, 3, 3 ... times ``spacing`` long, so that
    the passes lie ``spacing`` apart. A corner beyond the square is brought back onto its
    edge, and the pattern ends once it has flown along all four edges: as a survey's last
    pass lies on its far edge (:func:`survey_offsets`), the outermost ring runs on the
    edges of the square, so that no strip along an edge is left when the radius is not a
    multiple of the spacing, nor along the side the square grew from last.
    """
    if spacing <= 0 or radius <= 0:
        raise ValueError(f"an expanding square needs a positive radius and spacing, not "
                         f"{radius:g} and {spacing:g}")
    edge = radius * (1 - _EDGE)

    def onto_square(steps: int) -> float:
        """``steps`` times the spacing from the centre, brought back onto the square."""
        offset = steps * spacing
        return math.copysign(radius, offset) if abs(offset) >= edge else offset

    points: list[Point3] = []
    flown: set[tuple[int, float]] = set()  # the edges flown along: (axis, side)
    north = east = 0  # the corner in spacings, as if there were no edge
    leg = 0
    while len(flown) < 4:
        d_north, d_east = _SQUARE_LEGS[leg % 4]
        size = leg // 2 + 1
        north, east = north + d_north * size, east + d_east * size
        n, e = onto_square(north), onto_square(east)
        kept = e if d_north else n  # the coordinate the leg keeps: on an edge or not
        if abs(kept) == radius:
            flown.add((0 if d_north else 1, kept))
        points.append((centre[0] + n, centre[1] + e, centre[2]))
        leg += 1
    return [*points, centre]


# --- LOITER -----------------------------------------------------------------------------------

CIRCLE_POINTS_PER_TURN = 16
"""A circle (LOITER, RETURN_HOME_AND_LOITER) is flown as a polygon of this many GUIDED
targets per turn, each reached before the next is sent."""


def circle_entry(centre: Point3, position: Point3) -> float:
    """The bearing (radians) from ``centre`` of the point where a vehicle at ``position``
    joins a circle around it: the nearest point of the circle (the centre itself may be
    what it circles, a mast or a tower), north when it is over the centre."""
    north, east = position[0] - centre[0], position[1] - centre[1]
    return math.atan2(east, north) if math.hypot(north, east) > 1e-6 else 0.0


def circle_point(centre: Point3, radius: float, start: float, step: int) -> Point3:
    """The ``step``-th target of a circle around ``centre`` that begins at the bearing
    ``start`` (radians), going clockwise."""
    angle = start + 2 * math.pi * step / CIRCLE_POINTS_PER_TURN
    return (centre[0] + radius * math.cos(angle), centre[1] + radius * math.sin(angle),
            centre[2])


def circle(centre: Point3, radius: float, start: float, turns: int = 1) -> list[Point3]:
    """The targets of ``turns`` turns of a circle from the bearing ``start``: the entry
    point first, and again at the end of each turn."""
    return [circle_point(centre, radius, start, step)
            for step in range(turns * CIRCLE_POINTS_PER_TURN + 1)]


def circle_chord(radius: float) -> float:
    """Metres between two consecutive targets of a circle of ``radius``."""
    return 2 * radius * math.sin(math.pi / CIRCLE_POINTS_PER_TURN)


def stop_to_stop(metres: float, speed: float, acceleration: float) -> float:
    """Seconds to fly ``metres`` from a stop to a stop: speeding up and braking at
    ``acceleration`` (m/s²; 0: at once) around a cruise at ``speed``, or, when the distance
    is too short to reach ``speed``, speeding up half way and braking the other half."""
    if acceleration <= 0:
        return metres / speed
    if metres >= speed * speed / acceleration:
        return metres / speed + speed / acceleration
    return 2 * math.sqrt(metres / acceleration)
