"""The trajectory planner: paths keep the clearance, are never shorter than the straight
line, are the straight line when nothing is in the way, and go over low obstacles."""

from __future__ import annotations

import math

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from tml.verify.planner import Planner, Trajectory
from tml.world import Cylinder, Prism

coordinate = st.floats(-100, 100, allow_nan=False)
cylinders = st.lists(
    st.builds(lambda n, e, r: Cylinder("c", n, e, r), coordinate, coordinate,
              st.floats(0.5, 15)), max_size=8)
prisms = st.lists(
    st.builds(lambda n, e, w, h: Prism("p", ((n, e), (n + w, e), (n + w, e + h), (n, e + h))),
              coordinate, coordinate, st.floats(1, 30), st.floats(1, 30)), max_size=4)
point = st.tuples(coordinate, coordinate, st.floats(0, 50, allow_nan=False))


def _surface_distance(planner: Planner, p: tuple[float, float, float]) -> float:
    return planner.clearance_of((p,))


@settings(max_examples=60, deadline=None)
@given(cylinders, prisms, st.floats(0, 10), point, point)
def test_path_keeps_the_clearance_and_is_not_shorter_than_the_line(
        round_ones: list[Cylinder], boxes: list[Prism], clearance: float,
        start: tuple[float, float, float], end: tuple[float, float, float]) -> None:
    planner = Planner([*round_ones, *boxes], clearance)
    assume(_surface_distance(planner, start) > clearance + 0.1)
    assume(_surface_distance(planner, end) > clearance + 0.1)
    path = planner.trajectory(start, end)
    if path is None:
        return
    assert path.points[0] == start
    assert path.points[-1] == end
    assert planner.clearance_of(path.points) >= clearance - 1e-6
    assert path.length >= math.dist(start, end) - 1e-9


@settings(max_examples=40, deadline=None)
@given(point, point, st.floats(0, 10))
def test_without_obstacles_the_path_is_the_line(start: tuple[float, float, float],
                                                end: tuple[float, float, float],
                                                clearance: float) -> None:
    path = Planner([], clearance).trajectory(start, end)
    assert path is not None
    assert path.points in ((start, end), (start,))
    assert path.length == pytest.approx(math.dist(start, end))


def test_goes_around_a_cylinder_as_short_as_the_tangents() -> None:
    planner = Planner([Cylinder("mast", 50, 0, 5)], 5)
    path = planner.trajectory((0, 0, 10), (100, 0, 10))
    assert path is not None
    # Two tangents to a 10 m circle from 50 m away plus the arc between them.
    tangent = math.sqrt(50**2 - 10**2)
    arc = 10 * 2 * math.asin(10 / 50)
    assert 2 * tangent + arc <= path.length <= (2 * tangent + arc) * 1.04
    assert planner.clearance_of(path.points) >= 5


def test_flies_straight_over_a_prism_below_the_leg() -> None:
    building = Prism("block", ((40, -20), (60, -20), (60, 20), (40, 20)), top=20)
    planner = Planner([building], 5)
    over = planner.trajectory((0, 0, 30), (100, 0, 30))
    assert over == Trajectory(((0, 0, 30), (100, 0, 30)))
    # 24 m is within the clearance above the top: the leg must go around.
    around = planner.trajectory((0, 0, 24), (100, 0, 24))
    assert around is not None and around.length > 100


def test_flies_under_an_overhang() -> None:
    bridge = Prism("bridge", ((40, -50), (60, -50), (60, 50), (40, 50)), bottom=30, top=35)
    path = Planner([bridge], 5).trajectory((0, 0, 10), (100, 0, 10))
    assert path == Trajectory(((0, 0, 10), (100, 0, 10)))


def test_no_path_into_a_closed_courtyard() -> None:
    walls = [Prism("n", ((20, -20), (22, -20), (22, 22), (20, 22))),
             Prism("s", ((-22, -22), (-20, -22), (-20, 20), (-22, 20))),
             Prism("e", ((-20, 20), (22, 20), (22, 22), (-20, 22))),
             Prism("w", ((-22, -22), (20, -22), (20, -20), (-22, -20)))]
    planner = Planner(walls, 3)
    assert planner.trajectory((100, 0, 10), (0, 0, 10)) is None


def test_altitude_changes_evenly_along_the_path() -> None:
    path = Planner([Cylinder("mast", 50, 0, 5)], 5).trajectory((0, 0, 10), (100, 0, 30))
    assert path is not None
    ground = 0.0
    for previous, here in zip(path.points, path.points[1:], strict=False):
        ground += math.hypot(here[0] - previous[0], here[1] - previous[1])
        assert here[2] == pytest.approx(10 + 20 * ground / path.horizontal_length)


def test_endpoint_inside_an_obstacle_is_left_to_c1() -> None:
    planner = Planner([Cylinder("mast", 50, 0, 5)], 5)
    path = planner.trajectory((0, 0, 10), (47, 0, 10))
    assert path == Trajectory(((0, 0, 10), (47, 0, 10)))


def test_nearest_names_the_obstacle() -> None:
    planner = Planner([Cylinder("mast", 50, 0, 5), Cylinder("tree", -50, 0, 5)], 5)
    assert planner.nearest((40, 0, 10)) == (pytest.approx(5.0), "mast")
    assert planner.nearest((40, 0, 10)) != planner.nearest((-40, 0, 10))


def test_degenerate_legs_give_no_numeric_warnings() -> None:
    import warnings

    planner = Planner([Cylinder("c", 0.0, 0.0, 1.0), Cylinder("d", 5.0, 0.0, 1.0)], 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tiny = planner.trajectory((2.0, 0.0, 0.0), (2.0, 3.1659946594612924e-298, 0.0))
        assert tiny is not None and planner.clearance_of(tiny.points) == pytest.approx(1.0)
        around = planner.trajectory((-3.0, 0.0, 0.0), (8.0, 0.0, 0.0))  # shared vertices
        assert around is not None and planner.clearance_of(around.points) >= -1e-6



def test_an_obstacle_inflated_by_a_vanishing_clearance_gives_no_numeric_warnings() -> None:
    # Growing the unit square inflated by 1e-49 m raises GEOS's invalid flag; the planner
    # grows every obstacle when it is made, met by a leg or not.
    import warnings

    square = Prism("p", ((0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        planner = Planner([square], 3.4781332200485605e-49)
        assert planner.trajectory((-5.0, 3.0, 1.0), (5.0, 3.0, 1.0)) is not None


crowded = st.lists(
    st.builds(lambda n, e, r: Cylinder("c", n, e, r), st.floats(-40, 40), st.floats(-40, 40),
              st.floats(0.5, 10)), max_size=12)


@settings(max_examples=150, deadline=None)
@given(crowded, prisms, st.floats(0, 6), point, point)
def test_tangent_edges_find_the_shortest_path_of_all_visible_edges(
        round_ones: list[Cylinder], boxes: list[Prism], clearance: float,
        start: tuple[float, float, float], end: tuple[float, float, float]) -> None:
    # The planner keeps only edges tangent at both ends; among overlapping obstacles too,
    # its path is as short as the one over every visible edge (within 1e-6 of it) and it
    # finds a path whenever that graph has one.
    obstacles = [*round_ones, *boxes]
    reduced, full = Planner(obstacles, clearance), Planner(obstacles, clearance, reduced=False)
    fast, reference = reduced.trajectory(start, end), full.trajectory(start, end)
    assert (fast is None) == (reference is None)
    if fast is not None and reference is not None:
        assert fast.length <= reference.length * (1 + 1e-6) + 1e-9


@settings(max_examples=40, deadline=None)
@given(crowded, prisms, st.floats(0, 6), st.lists(point, min_size=2, max_size=12))
def test_segments_meet_the_polygons_shapely_says_they_meet(
        round_ones: list[Cylinder], boxes: list[Prism], clearance: float,
        ends: list[tuple[float, float, float]]) -> None:
    # Segments decided by the disks inside and around each polygon without asking shapely
    # are decided as shapely decides them: random ones, and ones between the graph's own
    # nodes, which run along and close by the polygons.
    import numpy as np
    import shapely

    obstacles = [*round_ones, *boxes]
    assume(obstacles)
    planner = Planner(obstacles, clearance)
    everyone = np.arange(len(obstacles))
    nodes = np.concatenate([[complex(*p[:2]) for p in ends], planner._ring_nodes])
    first, second = np.triu_indices(len(nodes), 1)
    hit, polygon = planner._crossings(nodes[first], nodes[second], everyone)
    found = np.zeros((len(first), len(obstacles)), dtype=bool)
    found[hit, polygon] = True
    points = np.stack([nodes.real, nodes.imag], axis=1)
    lines = shapely.linestrings(np.stack([points[first], points[second]], axis=1))
    expected = shapely.intersects(lines[:, None], planner.inflated[None, :])
    assert (found == expected).all()
