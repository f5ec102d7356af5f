"""Kinds of vehicle (tml.language.kinds): what each can do, and a fixed-wing's landing approach."""

from __future__ import annotations

import math

import pytest

from tml.errors import Location
from tml.language.actions import bind
from tml.language.kinds import (
    GLIDE_RATIO,
    MIN_FINAL,
    VEHICLE_TYPES,
    Kind,
    cannot,
    kind_of,
    landing_approach,
    refusal,
    role_kinds,
)
from tml.language.model import Action, Argument

HERE = Location("m.xml", 1, 1)


def action(name: str, **values: str):
    return bind(Action(name, tuple(Argument(k, v, None, HERE) for k, v in values.items()),
                       HERE))


@pytest.mark.parametrize(("vehicle_type", "kind"), [
    ("quadcopter", Kind.MULTICOPTER), ("hexacopter", Kind.MULTICOPTER),
    ("helicopter", Kind.MULTICOPTER), ("", Kind.MULTICOPTER),
    ("fixed-wing", Kind.FIXED_WING), ("rover", Kind.GROUND), ("boat", Kind.GROUND)])
def test_kind_of_a_vehicle_type(vehicle_type: str, kind: Kind) -> None:
    assert kind_of(vehicle_type) is kind


def test_every_vehicle_type_has_a_kind() -> None:
    assert {kind_of(t) for t in VEHICLE_TYPES} == set(Kind)


@pytest.mark.parametrize(("wanted", "kinds"), [
    (None, set(Kind)), ("UAV", {Kind.MULTICOPTER, Kind.FIXED_WING}),
    ("uav", {Kind.MULTICOPTER, Kind.FIXED_WING}), ("multicopter", {Kind.MULTICOPTER}),
    ("rover", {Kind.GROUND}), ("fixed-wing", {Kind.FIXED_WING})])
def test_the_kinds_a_role_admits(wanted: str | None, kinds: set[Kind]) -> None:
    assert role_kinds(wanted) == kinds


def test_a_multicopter_can_do_everything() -> None:
    assert cannot(Kind.MULTICOPTER) == ()
    assert refusal(action("FLIP"), Kind.MULTICOPTER) is None


@pytest.mark.parametrize(("bound", "kind", "expected"), [
    (action("ROTATE_YAW", angle="90"), Kind.FIXED_WING, "a fixed-wing cannot turn in place"),
    (action("PICK_UP_ITEM"), Kind.FIXED_WING, "a fixed-wing cannot hover"),
    (action("TAKE_OFF"), Kind.GROUND, "a ground vehicle cannot take off"),
    (action("LANDING_POINT", coordinates="(1, 2, 0)"), Kind.GROUND,
     "a ground vehicle cannot land"),
    (action("SET_ALTITUDE", altitude="5"), Kind.GROUND, "has no altitude"),
    (action("MOVE", direction="down", distance="2"), Kind.GROUND, "cannot move up or down"),
])
def test_what_a_kind_cannot_do(bound, kind: Kind, expected: str) -> None:
    reason = refusal(bound, kind)
    assert reason is not None and expected in reason


@pytest.mark.parametrize(("bound", "kind"), [
    (action("LAND"), Kind.FIXED_WING), (action("WAIT", duration="3"), Kind.FIXED_WING),
    (action("LOITER", radius="80"), Kind.FIXED_WING),
    (action("MOVE", direction="forward", distance="2"), Kind.GROUND),
    (action("MOVE", coordinates="(3, 0, 0)"), Kind.GROUND),
    (action("RETURN_HOME_AND_LAND"), Kind.GROUND), (action("WAIT", duration="3"), Kind.GROUND),
])
def test_what_a_kind_can_do(bound, kind: Kind) -> None:
    assert refusal(bound, kind) is None


def test_the_reason_names_the_vehicle_type_when_known() -> None:
    assert refusal(action("TAKE_OFF"), Kind.GROUND, "boat").startswith("a boat cannot")


def test_landing_straight_ahead_glides_eight_metres_for_each_metre_down() -> None:
    approach, touchdown = landing_approach((100.0, 0.0, 50.0), 90.0, None)
    assert approach == (100.0, 0.0, 50.0)
    assert touchdown == pytest.approx((100.0, GLIDE_RATIO * 50.0, 0.0))


def test_a_low_landing_keeps_the_shortest_final() -> None:
    _, touchdown = landing_approach((0.0, 0.0, 5.0), 0.0, None)
    assert touchdown == pytest.approx((MIN_FINAL, 0.0, 0.0))


def test_landing_at_a_point_comes_in_from_the_side_the_vehicle_is_on() -> None:
    approach, touchdown = landing_approach((300.0, 400.0, 40.0), 180.0, (0.0, 0.0, 0.0))
    assert touchdown == (0.0, 0.0, 0.0)
    assert approach[2] == 40.0
    assert math.hypot(*approach[:2]) == pytest.approx(GLIDE_RATIO * 40.0)
    # On the line from the touchdown to the vehicle: the vehicle flies there, then glides.
    assert approach[0] / approach[1] == pytest.approx(300.0 / 400.0)


def test_right_over_the_touchdown_the_approach_is_behind_it_along_the_heading() -> None:
    approach, _ = landing_approach((0.0, 0.0, 30.0), 90.0, (0.0, 0.0, 0.0))
    assert approach == pytest.approx((0.0, -GLIDE_RATIO * 30.0, 30.0), abs=1e-9)
