"""The flight patterns (tml.patterns) and the three paths that fly or predict them.

An action is flown with commands by a script (:mod:`tml.engine.scripts`), compiled to
mission items (:mod:`tml.mavlink.compile`) and predicted by the verifier
(:mod:`tml.verify.motion`). For the same bound action the three must go through the same
points, or the verifier checks a path the vehicle does not fly.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import pairwise

import pytest
from fake_vehicle import FakeVehicle
from hypothesis import given, settings
from hypothesis import strategies as st

from tml.engine.scripts import Limits, Send, Sleep, Until, script_for
from tml.errors import Location
from tml.geo import to_local
from tml.language.actions import BoundAction, bind
from tml.language.model import Action, Argument
from tml.mavlink.codec import mavlink
from tml.mavlink.compile import compile_mission
from tml.patterns import (
    BODY_DIRECTIONS,
    CIRCLE_POINTS_PER_TURN,
    QUADRANTS,
    VERTICAL_DIRECTIONS,
    circle,
    circle_chord,
    circle_entry,
    displaced,
    expanding_square,
    survey,
    survey_offsets,
)
from tml.vehicle import GoTo, Point, VehicleState
from tml.verify.motion import FlightModel, PredictedState
from tml.verify.profile import load_profile
from tml.world import DEFAULT_HOME, World

HERE = Location("test.xml", 1)
START: Point = (3.0, -4.0, 12.0)


def act(name: str, **values: str) -> BoundAction:
    return bind(Action(name, tuple(Argument(k, v, None, HERE) for k, v in values.items()),
                       HERE))


@dataclass
class _Context:
    """What a script reads and changes, over a fake vehicle (no router, no world)."""

    vehicle: FakeVehicle
    vehicle_id: int = 1
    limits: Limits = field(default_factory=Limits)
    labels: dict[str, Point] = field(default_factory=dict)
    world: World | None = None
    last_target: Point | None = None
    route: Callable[[Point, Point], list[Point] | None] | None = None

    @property
    def state(self) -> VehicleState:
        return self.vehicle.state()

    @property
    def now(self) -> float:
        return self.vehicle.time  # the mission's clock: the fake's own

    def note(self, message: str, **data: object) -> None:
        pass


def flown(bound: BoundAction, start: Point = START, heading: float = 0.0,
          most: int | None = None) -> list[Point]:
    """The targets a script sends while it flies ``bound`` on a fake vehicle from ``start``
    facing ``heading`` (the first ``most`` of them: for an action that never ends)."""
    vehicle = FakeVehicle(speed=50.0, climb_rate=50.0, armed=True, mode="GUIDED",
                          position=start, heading=heading)
    ctx = _Context(vehicle)
    for step in script_for(ctx, bound):
        if most is not None and len(targets(vehicle)) >= most:
            break
        if isinstance(step, Send):
            vehicle.submit(step.request)
            assert all(result.ok for result in vehicle.poll())
        elif isinstance(step, Until):
            deadline = vehicle.time + step.limit
            while not step.predicate(vehicle.state()):
                assert vehicle.time < deadline, f"the fake vehicle did not {step.what}"
                vehicle.advance(0.1)
        else:
            assert isinstance(step, Sleep)
            vehicle.advance(step.seconds)
    return targets(vehicle)


def targets(vehicle: FakeVehicle) -> list[Point]:
    """The GUIDED targets a vehicle was sent."""
    return [r.target for r in vehicle.submitted if isinstance(r, GoTo)]


def compiled(bound: BoundAction, start: Point = START, heading: float = 0.0) -> list[Point]:
    """The points of the mission items ``bound`` compiles to, flown from ``start``."""
    home = DEFAULT_HOME
    points = []
    for item in compile_mission([bound], home, start, heading).items:
        assert item.frame == mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        north, east, _ = to_local(item.x / 1e7, item.y / 1e7, home.altitude + item.z,
                                  home.latitude, home.longitude, home.altitude)
        points.append((north, east, item.z))
    return points


def predicted(bound: BoundAction, start: Point = START, heading: float = 0.0) -> list[Point]:
    """The points the verifier predicts ``bound`` flies through from ``start`` facing
    ``heading``: the end of each leg, then the loiter circle when there is one."""
    step = FlightModel(load_profile("quadcopter"), World()).step(
        bound, PredictedState(position=start, flying=True, heading=heading))
    points = [leg.points[-1] for leg in step.legs]
    return points + (step.loiter.points() if step.loiter is not None else [])


def same_path(a: list[Point], b: list[Point], tolerance: float = 0.05) -> bool:
    """Whether two paths go through the same points in the same order (1e-7 degree of a
    mission item is about 1 cm)."""
    return len(a) == len(b) and all(math.dist(p, q) <= tolerance for p, q in zip(a, b, strict=True))


# --- the regression: three paths, one pattern -------------------------------------------------

SURVEY = act("SURVEY_AREA", length="100", width="25", spacing="10", direction="NORTH_EAST")
EXPLORE = act("EXPLORE_SPACE", radius="25", spacing="10")


@pytest.mark.parametrize("bound", [SURVEY, EXPLORE], ids=["survey", "explore"])
def test_the_script_the_mission_items_and_the_verifier_fly_the_same_points(
        bound: BoundAction) -> None:
    script = flown(bound)
    assert same_path(compiled(bound), script), (compiled(bound), script)
    assert same_path(predicted(bound), script), (predicted(bound), script)


def test_a_survey_of_width_25_flies_its_last_pass_on_the_far_edge() -> None:
    easts = sorted({round(p[1] - START[1], 6) for p in flown(SURVEY)})
    assert easts == [0.0, 10.0, 20.0, 25.0]


def test_the_verifier_checks_the_loiter_circle_the_script_flies() -> None:
    bound = act("LOITER", coordinates="(30, 10, 12)", radius="8", turns="1")
    script = flown(bound)
    assert same_path(predicted(bound), [script[0], *script]), (predicted(bound), script)


# --- the three agree for any arguments ----------------------------------------------------------

PROPERTY = settings(max_examples=40, deadline=None, derandomize=True)
metres = st.floats(1.0, 60.0, allow_nan=False)
directions = st.sampled_from(sorted(QUADRANTS))
points = st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(2, 40))


@PROPERTY
@given(metres, metres, st.floats(1.0, 30.0), directions, points, st.floats(2, 40))
def test_a_survey_is_flown_compiled_and_predicted_alike(
        length: float, width: float, spacing: float, direction: str, base: Point,
        altitude: float) -> None:
    bound = act("SURVEY_AREA", length=repr(length), width=repr(width), spacing=repr(spacing),
                direction=direction, coordinates=repr(base), altitude=repr(altitude))
    script = flown(bound)
    assert same_path(compiled(bound), script)
    assert same_path(predicted(bound), script)


@PROPERTY
@given(st.floats(1.0, 40.0), st.floats(1.0, 30.0), points)
def test_an_expanding_square_is_flown_compiled_and_predicted_alike(
        radius: float, spacing: float, start: Point) -> None:
    bound = act("EXPLORE_SPACE", radius=repr(radius), spacing=repr(spacing))
    script = flown(bound, start)
    assert same_path(compiled(bound, start), script)
    assert same_path(predicted(bound, start), script)


@PROPERTY
@given(st.floats(0, 359.9), st.sampled_from([*BODY_DIRECTIONS, *VERTICAL_DIRECTIONS]),
       st.floats(0.5, START[2] - 1))  # down: not below home
def test_a_move_is_flown_compiled_and_predicted_alike(
        heading: float, direction: str, distance: float) -> None:
    bound = act("MOVE", direction=direction, distance=repr(distance))
    script = flown(bound, START, heading)
    assert same_path(compiled(bound, START, heading), script)
    assert same_path(predicted(bound, START, heading), script)


@PROPERTY
@given(points, st.floats(2.0, 30.0), st.integers(1, 2))
def test_the_verifier_checks_the_circle_a_loiter_flies(
        centre: Point, radius: float, turns: int) -> None:
    bound = act("LOITER", coordinates=repr(centre), radius=repr(radius), turns=str(turns))
    script = flown(bound)
    assert same_path(predicted(bound), [script[0], *script[:CIRCLE_POINTS_PER_TURN + 1]])
    assert len(script) == turns * CIRCLE_POINTS_PER_TURN + 1


def test_return_home_and_loiter_joins_the_circle_the_verifier_checks() -> None:
    bound = act("RETURN_HOME_AND_LOITER", radius="6")
    script = flown(bound, most=CIRCLE_POINTS_PER_TURN + 1)  # it circles until stopped
    assert same_path(predicted(bound), [script[0], *script])


# --- the patterns themselves ------------------------------------------------------------------

def test_survey_passes_cover_the_area_in_its_quadrant() -> None:
    assert survey((0.0, 0.0, 20.0), 100.0, 50.0, 20.0, "NORTH_EAST") == [
        (0, 0, 20), (100, 0, 20), (100, 20, 20), (0, 20, 20), (0, 40, 20), (100, 40, 20),
        (100, 50, 20), (0, 50, 20)]
    south_west = survey((5.0, 5.0, 10.0), 30.0, 20.0, 10.0, "SOUTH_WEST")
    assert south_west[-1] == (-25, -15, 10)
    assert {n for n, _, _ in south_west} == {5.0, -25.0}
    assert {e for _, e, _ in south_west} == {5.0, -5.0, -15.0}


@pytest.mark.parametrize(("direction", "signs"), sorted(QUADRANTS.items()))
def test_the_dolphin_survey_flies_21_passes(direction: str, signs: tuple[float, float]) -> None:
    legs = survey((10.0, 20.0, 30.0), 30.0, 100.0, 5.0, direction)
    assert len(legs) == 2 * 21  # 21 passes of 30 m, as the Dolphin listing says
    assert {round((p[0] - 10) * signs[0], 6) for p in legs} == {0.0, 30.0}
    assert sorted({round((p[1] - 20) * signs[1], 6) for p in legs}) == [5.0 * i for i in range(21)]
    assert all(p[2] == 30.0 for p in legs)
    for a, b in zip(legs[::2], legs[1::2], strict=True):  # each pass runs along the length
        assert a[1] == b[1] and abs(a[0] - b[0]) == 30.0


@pytest.mark.parametrize(("width", "spacing", "offsets"), [
    (25, 10, [0, 10, 20, 25]), (20, 10, [0, 10, 20]), (7, 3, [0, 3, 6, 7]), (5, 10, [0, 5]),
    (0.3, 0.1, [0, 0.1, 0.2, 0.3])])
def test_the_last_pass_of_a_survey_lies_on_the_far_edge(
        width: float, spacing: float, offsets: list[float]) -> None:
    assert survey_offsets(width, spacing) == pytest.approx(offsets)


@PROPERTY
@given(metres, st.floats(0.5, 30.0))
def test_survey_passes_are_at_most_the_spacing_apart_from_edge_to_edge(
        width: float, spacing: float) -> None:
    offsets = survey_offsets(width, spacing)
    assert offsets[0] == 0 and offsets[-1] == width
    gaps = [b - a for a, b in pairwise(offsets)]
    assert all(0 < gap <= spacing * (1 + 1e-9) for gap in gaps)
    assert all(gap == pytest.approx(spacing) for gap in gaps[:-1])


def test_an_expanding_square_ends_with_a_ring_on_the_edges_and_comes_back() -> None:
    assert expanding_square((0.0, 0.0, 5.0), 4.0, 2.0) == [
        (2, 0, 5), (2, 2, 5), (-2, 2, 5), (-2, -2, 5), (4, -2, 5), (4, 4, 5), (-4, 4, 5),
        (-4, -4, 5), (4, -4, 5), (0, 0, 5)]
    # A radius that is not a multiple of the spacing: the last ring is brought onto the edge.
    assert expanding_square((0.0, 0.0, 5.0), 25.0, 10.0)[7:] == [
        (-20, -20, 5), (25, -20, 5), (25, 25, 5), (-25, 25, 5), (-25, -25, 5), (25, -25, 5),
        (0, 0, 5)]


@PROPERTY
@given(st.floats(0.5, 50.0), st.floats(0.5, 30.0), points)
def test_an_expanding_square_stays_in_the_square_and_flies_along_all_its_edges(
        radius: float, spacing: float, centre: Point) -> None:
    path = [centre, *expanding_square(centre, radius, spacing)]
    assert path[-1] == centre
    offsets = [(n - centre[0], e - centre[1]) for n, e, _ in path]
    assert all(max(abs(n), abs(e)) <= radius * (1 + 1e-9) for n, e in offsets)
    edges = set()
    legs = list(pairwise(offsets[:-1]))
    for number, ((n0, e0), (n1, e1)) in enumerate(legs):
        assert (n0 == n1) != (e0 == e1)  # every leg runs north/south or east/west, not still
        size = spacing * (number // 2 + 1)
        assert math.dist((n0, e0), (n1, e1)) <= size * (1 + 1e-9)  # growing by the spacing
        if n0 == n1 and abs(n0) == pytest.approx(radius):
            edges.add(("north", n0 > 0))
        if e0 == e1 and abs(e0) == pytest.approx(radius):
            edges.add(("east", e0 > 0))
    assert len(edges) == 4


@pytest.mark.parametrize(
    ("heading", "direction", "expected"),
    [(0, "forward", (2, 0, 5)), (90, "forward", (0, 2, 5)), (0, "right", (0, 2, 5)),
     (90, "backward", (0, -2, 5)), (180, "left", (0, 2, 5)), (45, "up", (0, 0, 7)),
     (45, "down", (0, 0, 3))],
)
def test_displaced(heading: float, direction: str, expected: tuple[float, ...]) -> None:
    assert displaced((0.0, 0.0, 5.0), heading, direction, 2.0) == pytest.approx(expected)


def test_a_circle_is_joined_at_its_nearest_point_and_closed_after_each_turn() -> None:
    centre = (10.0, 10.0, 5.0)
    start = circle_entry(centre, (10.0, 30.0, 5.0))  # due east of the centre
    assert start == pytest.approx(math.pi / 2)
    assert circle_entry(centre, centre) == 0.0  # over the centre: joined north of it
    ring = circle(centre, 4.0, start, turns=2)
    assert len(ring) == 2 * CIRCLE_POINTS_PER_TURN + 1
    assert ring[0] == pytest.approx((10, 14, 5)) and ring[-1] == pytest.approx(ring[0])
    assert ring[CIRCLE_POINTS_PER_TURN // 4] == pytest.approx((6, 10, 5))  # clockwise: south
    assert all(math.dist(a, b) == pytest.approx(circle_chord(4.0)) for a, b in pairwise(ring))
