"""The action catalogue (tml.language.actions)."""

from __future__ import annotations

import math

import pytest

from tml.errors import Location, MissionSemanticError
from tml.language import actions
from tml.language.actions import ArgType, LabelUse
from tml.language.model import Action, Argument

HERE = Location("a.xml", 1, 1)


def action(name: str, **values: str) -> Action:
    return Action(name, tuple(Argument(k, v, None, HERE) for k, v in values.items()), HERE)


def test_catalogue_covers_the_paper_aerostack_and_dolphin() -> None:
    names = {spec.name for spec in actions.CATALOGUE}
    assert {"TAKE_OFF", "LAND", "GO_TO_POINT", "MOVE", "MOVE_FORWARDS", "ROTATE_YAW",
            "STABILIZE", "WAIT", "FLIP", "MEMORIZE_POINT", "GO_TO_RECTANGLE", "EXPLORE_SPACE",
            "PICK_UP_ITEM", "DROP_ITEM"} <= names
    assert {"GO_TO_POSITION", "MOVE_FROM_HOME", "LOITER", "LANDING_POINT", "RETURN_HOME",
            "RETURN_HOME_AND_LOITER", "RETURN_HOME_AND_LAND", "SET_SPEED", "SET_ALTITUDE",
            "SURVEY_AREA", "CAPTURE_PHOTO", "CAPTURE_PHOTOS", "START_CAPTURING",
            "STOP_CAPTURING", "SET_HOME"} <= names
    assert actions.lookup("DELAY").name == "WAIT"


def test_catalogue_is_consistent() -> None:
    for spec in actions.CATALOGUE:
        names = [a.name for a in spec.arguments]
        assert len(names) == len(set(names)), spec.name
        for group in (*spec.exactly_one_of, *spec.at_most_one_of, *spec.together):
            assert set(group) <= set(names), (spec.name, group)
        for argument in spec.arguments:
            assert argument.description, (spec.name, argument.name)
            # a raw mission item's params are in the units its command gives them
            if argument.type in (ArgType.NUMBER, ArgType.POINT) and argument.name not in (
                    "pitch",) and spec.name != "MISSION_ITEM":
                assert argument.unit, (spec.name, argument.name)
            if argument.type is ArgType.CHOICE:
                assert argument.default is None or argument.default in argument.choices
            if argument.required:
                assert argument.default is None, (spec.name, argument.name)


@pytest.mark.parametrize("written", ["GO_TO_POINT", "go to point", "Go-To-Point", "GO TO POINT"])
def test_action_names_ignore_case_and_separators(written: str) -> None:
    assert actions.lookup(written).name == "GO_TO_POINT"


def test_argument_aliases_as_the_paper_and_aerostack_spell_them() -> None:
    go = actions.lookup("GO_TO_POINT")
    assert go.argument("point").name == "coordinates"
    assert go.argument("relative coordinates").name == "relative_coordinates"
    assert go.argument("relative point").name == "relative_coordinates"
    assert actions.lookup("WAIT").argument("time").name == "duration"
    assert actions.lookup("ROTATE_YAW").argument("rotation angle").name == "angle"
    assert actions.lookup("GO_TO_RECTANGLE").argument("frame color").name == "frame_color"
    assert actions.lookup("MEMORIZE_POINT").argument("coordinates").label is LabelUse.WRITE


@pytest.mark.parametrize(
    ("action_name", "argument", "raw", "expected"),
    [
        ("GO_TO_POINT", "coordinates", "(3.0,4.0,1.5)", (3.0, 4.0, 1.5)),
        ("GO_TO_POINT", "coordinates", " 1, -2 , 3e1 ", (1.0, -2.0, 30.0)),
        ("WAIT", "duration", "2.5", 2.5),
        ("CAPTURE_PHOTOS", "count", "4", 4),
        ("EXPLORE_SPACE", "build_map", "Yes", True),
        ("FLIP", "direction", "BACK", "back"),
        ("SURVEY_AREA", "direction", "north_east", "NORTH_EAST"),
        ("GO_TO_RECTANGLE", "frame_color", " red ", "red"),
    ],
)
def test_parse_value(action_name: str, argument: str, raw: str, expected: object) -> None:
    spec = actions.lookup(action_name).argument(argument)
    assert actions.parse_value(spec, raw) == expected


@pytest.mark.parametrize(
    ("action_name", "argument", "raw", "message"),
    [
        ("GO_TO_POINT", "coordinates", "(1, 2)", "three numbers"),
        ("GO_TO_POINT", "coordinates", "here", "three numbers"),
        ("WAIT", "duration", "soon", "expected a number in s"),
        ("WAIT", "duration", "-1", "at least 0 s"),
        ("WAIT", "duration", "nan", "expected a number"),
        ("CAPTURE_PHOTOS", "count", "2.5", "whole number"),
        ("CAPTURE_PHOTOS", "count", "0", "greater than 0"),
        ("GO_TO_POSITION", "latitude", "91", "at most 90 deg"),
        ("EXPLORE_SPACE", "build_map", "maybe", "yes or no"),
        ("FLIP", "direction", "up", "one of front, back, left, right"),
    ],
)
def test_parse_value_rejects(action_name: str, argument: str, raw: str, message: str) -> None:
    spec = actions.lookup(action_name).argument(argument)
    with pytest.raises(ValueError, match=message):
        actions.parse_value(spec, raw)


def test_bind_types_arguments_and_fills_defaults() -> None:
    bound = actions.bind(action("LOITER", turns="3", point="(1, 2, 10)"))
    assert bound.name == "LOITER"
    assert bound.values == {"turns": 3, "coordinates": (1.0, 2.0, 10.0), "radius": 15.0,
                            "altitude_reference": "relative", "frame_encoding": "int"}
    assert "duration" not in bound.values


def test_accessors_give_each_argument_its_type() -> None:
    bound = actions.bind(action("LOITER", turns="3", point="(1, 2, 10)"))
    assert bound.integer("turns") == 3 and type(bound.integer("turns")) is int
    assert bound.number("turns") == 3.0 and type(bound.number("turns")) is float
    assert bound.number("radius") == 15.0  # the default
    assert bound.point("coordinates") == (1.0, 2.0, 10.0)
    assert bound.choice("altitude_reference") == "relative"
    explore = actions.bind(action("EXPLORE_SPACE", build_map="yes"))
    assert explore.flag("build_map") is True
    rectangle = actions.bind(action("GO_TO_RECTANGLE", color="red"))
    assert rectangle.text("frame_color") == "red"


def test_an_absent_argument_gives_the_default_or_raises() -> None:
    bound = actions.bind(action("LOITER"))
    assert bound.number("duration", None) is None
    assert bound.point("from_home", (0.0, 0.0, 5.0)) == (0.0, 0.0, 5.0)
    with pytest.raises(KeyError, match="duration"):
        bound.number("duration")


def test_an_accessor_refuses_an_argument_of_another_type_or_name() -> None:
    bound = actions.bind(action("LOITER", turns="3"))
    with pytest.raises(TypeError, match="no point argument 'turns'"):
        bound.point("turns")
    with pytest.raises(TypeError, match="no number or integer argument 'time'"):
        bound.number("time")  # an alias: accessors take the canonical name (duration)
    with pytest.raises(TypeError, match="argument 'speed'"):
        bound.number("speed", None)


def test_takes_says_which_canonical_arguments_an_action_has() -> None:
    bound = actions.bind(action("LOITER", turns="3"))
    assert bound.takes("turns") and bound.takes("duration")
    assert not bound.takes("time")  # an alias, not the canonical name
    assert not bound.takes("speed")


def test_bind_keeps_labels() -> None:
    memorize = Action("MEMORIZE_POINT", (Argument("coordinates", None, "door", HERE),), HERE)
    assert actions.bind(memorize).labels == {"coordinates": "door"}


def test_bind_raises_with_location_on_bad_actions() -> None:
    with pytest.raises(MissionSemanticError, match="unknown action"):
        actions.bind(action("FLY"))
    with pytest.raises(MissionSemanticError, match="no argument 'speed'"):
        actions.bind(action("WAIT", speed="3"))
    with pytest.raises(MissionSemanticError) as info:
        actions.bind(action("WAIT", duration="x"))
    assert info.value.location == HERE and info.value.code == "E212"


def test_the_mavlink_tables_are_pymavlinks() -> None:
    from pymavlink.dialects.v20 import ardupilotmega

    from tml.language.mavlink_tables import MAV_CMD, MAV_FRAME

    for table, enum in ((MAV_CMD, "MAV_CMD"), (MAV_FRAME, "MAV_FRAME")):
        wanted = {number: entry.name for number, entry in ardupilotmega.enums[enum].items()
                  if not entry.name.endswith("ENUM_END")}
        assert table == wanted, sorted(set(wanted.items()) ^ set(table.items()))


@pytest.mark.parametrize(("written", "value"), [
    ("MAV_CMD_DO_JUMP", "MAV_CMD_DO_JUMP"), ("do_jump", "MAV_CMD_DO_JUMP"),
    ("177", "MAV_CMD_DO_JUMP"), ("40000", "40000")])
def test_a_raw_items_command_is_a_name_or_a_number(written: str, value: str) -> None:
    spec = actions.lookup("MISSION_ITEM")
    assert actions.parse_value(spec.argument("command"), written) == value


@pytest.mark.parametrize("written", ["DO_JUMPS", "70000", "-1", ""])
def test_a_raw_items_command_that_names_nothing_is_refused(written: str) -> None:
    spec = actions.lookup("MISSION_ITEM")
    with pytest.raises(ValueError):
        actions.parse_value(spec.argument("command"), written)


def test_a_raw_items_params_may_be_unset_and_are_not_range_checked() -> None:
    spec = actions.lookup("MISSION_ITEM")
    assert math.isnan(actions.parse_value(spec.argument("param4"), "NaN"))
    assert actions.parse_value(spec.argument("param1"), "640") == 640.0
    with pytest.raises(ValueError):  # x and y are integers: never NaN
        actions.parse_value(spec.argument("param5"), "NaN")
