"""Hardened reading and model building (tml.parse)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tml.errors import Location, MissionSyntaxError
from tml.language import build as builder
from tml.language import xml
from tml.language.model import (
    Comparison,
    Composition,
    ConditionKind,
    Dispatch,
    EventTrigger,
    TerminationMode,
)
from tml.world import Cylinder, Prism

MISSION = b"""<?xml version="1.0" encoding="UTF-8"?>
<mission name="Parsed">
  <skill name="AVOID_OBSTACLES"/>
  <parameter name="observed color" type="string"/>
  <environment>
    <home latitude="47.3977" longitude="8.5456" altitude="488" heading="90"/>
    <geofence min_altitude="0" max_altitude="40">
      <point north="-50" east="-50"/><point north="50" east="-50"/><point north="0" east="50"/>
    </geofence>
    <cylinder name="tree" north="10" east="5" radius="2" top="12"/>
    <prism name="shed" bottom="0" top="4">
      <point north="20" east="0"/><point north="25" east="0"/><point north="25" east="5"/>
    </prism>
    <object kind="aruco" id="3" north="8" east="0"/>
    <cylinder name="mast" latitude="47.3978" longitude="8.5456" radius="1"/>
  </environment>
  <task name="Outer" dispatch="mission">
    <repeat times="2"/>
    <task name="Inner">
      <condition parameter="observed color"
                 comparison="equal" value="green"/>
      <action name="GO_TO_POINT">
        <argument name="point" value="(3.0, 4.0, 1.5)"/>
      </action>
    </task>
  </task>
  <event_handling>
    <event name="seen" trigger="level">
      <condition currentTask="Outer/Inner"/>
      <action name="MEMORIZE_POINT"><argument name="coordinates" label="spot"/></action>
      <termination mode="JUMP_TO_TASK" task="Outer"/>
    </event>
  </event_handling>
</mission>
"""


def build(data: bytes = MISSION):
    doc = xml.read_xml("m.xml", data)
    return builder.build_mission(doc)


def test_builds_the_whole_model() -> None:
    mission, problems = build()
    assert problems == []
    assert mission.name == "Parsed"
    assert [s.name for s in mission.skills] == ["AVOID_OBSTACLES"]
    assert mission.parameters[0].name == "observed color"
    outer = mission.tasks[0]
    inner = outer.children[0]
    assert outer.repeat == 2 and not outer.is_terminal
    assert inner.path == ("Outer", "Inner") and inner.path_name == "Outer/Inner"
    assert inner.dispatch is Dispatch.MISSION  # inherited from the parent
    condition = inner.conditions[0]
    assert (condition.kind, condition.subject, condition.comparison, condition.value) == (
        ConditionKind.PARAMETER, "observed color", Comparison.EQUAL, "green")
    assert inner.action.argument("point").value == "(3.0, 4.0, 1.5)"
    event = mission.events[0]
    assert event.trigger is EventTrigger.LEVEL
    assert event.conditions[0].kind is ConditionKind.CURRENT_TASK
    assert event.termination.mode is TerminationMode.JUMP_TO_TASK
    assert event.termination.task == "Outer"


def test_every_node_knows_its_line_and_column() -> None:
    mission, _ = build()
    inner = mission.tasks[0].children[0]
    assert (inner.location.line, inner.location.column) == (19, 5)
    # A start tag spread over two lines is placed where it starts, not where it ends.
    assert (inner.conditions[0].location.line, inner.conditions[0].location.column) == (20, 7)
    assert inner.action.arguments[0].location.line == 23
    assert mission.tasks[0].repeat_location.line == 18
    assert mission.events[0].termination.location.line == 31


def test_environment_is_converted_to_the_local_frame() -> None:
    mission, _ = build()
    world = mission.world
    assert world.home.heading == 90
    assert world.geofence.max_altitude == 40 and len(world.geofence.polygon) == 3
    tree, shed, mast = world.obstacles
    assert isinstance(tree, Cylinder) and (tree.north, tree.east, tree.top) == (10, 5, 12)
    assert isinstance(shed, Prism) and shed.top == 4 and len(shed.polygon) == 3
    assert mast.top == float("inf")
    # 0.0001 degree of latitude is about 11.1 m north.
    assert mast.north == pytest.approx(11.1, abs=0.1) and abs(mast.east) < 0.01
    assert world.objects[0].kind == "aruco" and world.objects[0].ident == "3"


@pytest.mark.parametrize(
    ("data", "code"),
    [
        (b"", "E001"),
        (b"   \n", "E001"),
        (b"no xml here", "E002"),
        (b"<mission name='x'><task></mission>", "E002"),
        (b'<!DOCTYPE m [<!ENTITY e SYSTEM "file:///etc/passwd">]><mission name="&e;"/>',
         "E003"),
        (b'<?xml version="1.0" encoding="latin-1"?><mission name="x"/>', "E004"),
        (b'<mission name="\xe9"/>', "E004"),
        ('<mission name="x"/>'.encode("utf-16"), "E004"),
    ],
)
def test_hostile_or_broken_input_gives_one_clear_error(data: bytes, code: str) -> None:
    with pytest.raises(MissionSyntaxError) as info:
        xml.read_xml("bad.xml", data)
    assert info.value.code == code
    assert info.value.location.file == "bad.xml"
    assert info.value.location.line >= 1


def test_entities_are_never_expanded() -> None:
    laughs = (b'<!DOCTYPE l [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;">]>'
              b'<mission name="&b;"/>')
    with pytest.raises(MissionSyntaxError, match="DOCTYPE"):
        xml.read_xml("laughs.xml", laughs)


def test_size_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(xml, "MAX_BYTES", 100)
    with pytest.raises(MissionSyntaxError) as info:
        xml.read_xml("big.xml", b"<mission name='x'>" + b" " * 200 + b"</mission>")
    assert info.value.code == "E005"


def test_depth_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(xml, "MAX_DEPTH", 3)
    data = b"<mission name='x'>\n<task name='a'>\n<task name='b'>\n<task name='c'>\n" \
           b"<action name='LAND'/></task></task></task></mission>"
    with pytest.raises(MissionSyntaxError) as info:
        xml.read_xml("deep.xml", data)
    assert info.value.code == "E006"
    assert info.value.location.line == 4


def test_utf8_bom_and_non_ascii_names_are_fine() -> None:
    doc = xml.read_xml("bom.xml", '\ufeff<mission name="Misión"/>'.encode())
    assert doc.root.get("name") == "Misión"


def test_columns_count_characters_not_bytes() -> None:
    text = '<mission name="ñañá">\n  <task name="é" x="1"/></mission>'
    doc = xml.read_xml("u.xml", text.encode())
    task = doc.root[0]
    assert doc.location(task).column == 3
    assert doc.location(task, "x").column == 18


def test_structural_problems_are_reported_while_building() -> None:
    data = b"""<mission name="x">
  <environment>
    <geofence><point north="0" east="0"/></geofence>
    <cylinder north="1" latitude="2" radius="1"/>
    <prism top="0" bottom="5"><point north="0" east="0"/><point north="1" east="0"/>
      <point north="0" east="1"/></prism>
  </environment>
  <task name="t"><condition/><action name="LAND"><argument name="a"/></action></task>
</mission>"""
    _, problems = build(data)
    codes = sorted((p.code, p.location.line) for p in problems)
    assert codes == [("E213", 8), ("E220", 8), ("E253", 3), ("E253", 4), ("E253", 5)]


def test_load_world(tmp_path: Path) -> None:
    path = tmp_path / "field.xml"
    path.write_text('<world name="field">\n'
                    '  <home latitude="47" longitude="8" altitude="400"/>\n'
                    '  <cylinder name="pole" north="3" east="4" radius="0.5" top="10"/>\n'
                    '</world>\n')
    world = builder.load_world(path)
    assert world.home.latitude == 47 and world.obstacles[0].name == "pole"


def test_load_world_rejects_bad_files_with_location(tmp_path: Path) -> None:
    path = tmp_path / "field.xml"
    path.write_text('<world>\n  <cylinder north="3" east="4"/>\n</world>\n')
    with pytest.raises(MissionSyntaxError) as info:
        builder.load_world(path)
    assert (info.value.code, info.value.location.line) == ("E104", 2)
    assert "radius" in str(info.value)
    path.write_text('<mission name="m"><task name="t"><action name="LAND"/></task></mission>')
    with pytest.raises(MissionSyntaxError, match="expected a <world>"):
        builder.load_world(path)


def test_attribute_columns_skip_quoted_values() -> None:
    text = '<mission name="m">\n<parameter name="x" description="a > b typo=" typo="1"/></mission>'
    doc = xml.read_xml("q.xml", text.encode())
    assert doc.location(doc.root[0], "typo").column == 47
    assert doc.location(doc.root[0], "description").column == 21


FLEET = b"""<mission name="Fleet">
  <environment><home latitude="47.3977" longitude="8.5456" altitude="488"/></environment>
  <roles>
    <role name="north" count="2" type="quadcopter" pick_timeout="12.5">
      <payload name="camera"/><payload name="gripper"/>
      <region><circle latitude="47.3978" longitude="8.5456" radius="300"/></region>
    </role>
    <role name="south">
      <region><polygon><point north="0" east="0"/><point north="0" east="10"/>
        <point latitude="47.3978" longitude="8.5457"/></polygon></region>
    </role>
  </roles>
  <task name="Round" composition="parallel" time_limit="600" release=" north  south ">
    <loop><condition parameter="BATTERY_CHARGE_PERCENTAGE" role="north"
                     comparison="greater than" value="30"/></loop>
    <task name="N" role="north">
      <wait_for><condition parameter="ALTITUDE" comparison="less than" value="1"/></wait_for>
      <until><condition parameter="TASK_ELAPSED_TIME" comparison="greater than" value="9"/>
      </until>
      <task name="Up"><action name="TAKE_OFF"/></task>
      <on_error><task name="Down"><action name="LAND"/></task></on_error>
    </task>
    <task name="S" role="south" composition="first"><action name="LAND"/></task>
  </task>
  <event_handling><event name="e" role="south">
    <termination mode="END_MISSION"/></event></event_handling>
</mission>
"""


def test_roles_are_built_with_regions_in_local_metres() -> None:
    mission, problems = build(FLEET)
    assert problems == []
    north, south = mission.roles
    assert mission.role("south") is south and mission.role("west") is None
    assert (north.count, north.vehicle_type, north.payloads, north.pick_timeout) == (
        2, "quadcopter", ("camera", "gripper"), 12.5)
    assert north.location.line == 4
    assert north.region.is_circle and north.region.radius == 300
    (centre,) = north.region.points
    assert centre[0] == pytest.approx(11.1, abs=0.1) and abs(centre[1]) < 0.01
    assert not south.region.is_circle and south.region.location.line == 9
    corners = south.region.points
    assert corners[:2] == ((0, 0), (0, 10))
    # 0.0001 degree of longitude at 47.4 degrees north is about 7.5 m east.
    assert corners[2] == (pytest.approx(11.1, abs=0.1), pytest.approx(7.5, abs=0.1))
    assert (south.count, south.vehicle_type, south.pick_timeout) == (1, None, 30.0)


def test_orchestration_fields_roles_and_handler_paths() -> None:
    mission, _ = build(FLEET)
    (round_,) = mission.tasks
    n, s = round_.children
    assert round_.composition is Composition.PARALLEL and round_.time_limit == 600
    assert round_.release == ("north", "south") and round_.release_location.line == 13
    assert round_.role is None and round_.role_location is None
    assert (n.role, n.role_location.line, n.role_location.column) == ("north", 16, 20)
    up = n.children[0]
    assert up.role == "north" and up.role_location is None  # inherited
    (down,) = n.on_error
    assert down.path == ("Round", "N", "Down") and down.role == "north"
    assert [t.name for t in round_.walk()] == ["Round", "N", "Up", "Down", "S"]
    assert [c.subject for c in n.wait_for] == ["ALTITUDE"]
    assert [c.subject for c in n.until] == ["TASK_ELAPSED_TIME"]
    assert round_.loop.location.line == 14
    assert [(c.subject, c.role) for c in round_.loop.conditions] == [
        ("BATTERY_CHARGE_PERCENTAGE", "north")]
    assert s.composition is Composition.FIRST and s.loop is None
    assert n.time_limit is None and n.release == ()
    assert round_.orchestrated and n.orchestrated and not up.orchestrated
    assert mission.events[0].role == "south"


def test_with_one_role_every_task_is_flown_by_it() -> None:
    data = (b'<mission name="m"><roles><role name="solo"/></roles>'
            b'<task name="a"><task name="b"><action name="LAND"/></task></task></mission>')
    mission, _ = build(data)
    assert [t.role for t in mission.walk()] == ["solo", "solo"]
    assert mission.tasks[0].role_location is None


def test_forever_loop_has_no_conditions() -> None:
    mission, _ = build(b'<mission name="m"><task name="a"><loop/><action name="LAND"/></task>'
                       b'</mission>')
    assert mission.tasks[0].loop is not None and mission.tasks[0].loop.conditions == ()


@pytest.mark.parametrize(("gates", "words"), [
    ("<until><condition parameter='ALTITUDE' comparison='less than' value='1'/></until>"
     "\n<until><condition parameter='ALTITUDE' comparison='less than' value='2'/></until>",
     "more than one <until>"),
    ("<wait_for><condition parameter='ALTITUDE' comparison='less than' value='1'/></wait_for>"
     "\n<wait_for><condition parameter='ALTITUDE' comparison='less than' value='2'/>"
     "</wait_for>", "more than one <wait_for>"),
    ("<loop/>\n<loop/>", "more than one <loop>"),
    ("<repeat times='2'/>\n<loop/>", "both <repeat> and <loop>"),
])
def test_gates_given_twice_or_repeat_with_loop(gates: str, words: str) -> None:
    data = f'<mission name="m"><task name="a">\n{gates}<action name="LAND"/></task></mission>'
    _, problems = build(data.encode())
    assert [(p.code, p.location.line) for p in problems] == [("E251", 3)]
    assert words in problems[0].message


def test_empty_until_or_wait_for_is_reported_while_building() -> None:
    data = (b'<mission name="m"><task name="a">\n  <until/><wait_for/><action name="LAND"/>'
            b'</task></mission>')
    _, problems = build(data)
    assert sorted((p.code, p.location.line, p.location.column) for p in problems) == [
        ("E282", 2, 3), ("E282", 2, 11)]


def test_attribute_location_from_the_source_text() -> None:
    text = 'ab\n<mission name="m">\n  <task\n    name="t" role="r"/></mission>'
    task = Location("x.xml", 3, 3)
    assert xml.attribute_location(text, task, "role") == Location("x.xml", 4, 14)
    assert xml.attribute_location(text, task, "missing") == task
    assert xml.attribute_location(text, Location("x.xml", 9, 1), "role") == Location(
        "x.xml", 9, 1)


def test_a_required_attribute_missing_outside_the_schema_is_a_syntax_error() -> None:
    # The builder trusts the schema; a document built without it gets a located error for
    # an attribute the schema requires, not a traceback.
    doc = xml.read_xml("w.xml", b'<world>\n  <home latitude="1" longitude="2"/>\n</world>')
    with pytest.raises(MissionSyntaxError, match="<home> is missing the required attribute "
                       "'altitude'") as info:
        builder.build_world(doc)
    assert info.value.location == Location("w.xml", 2, 3) and info.value.code == "E104"


def test_nodes_built_have_every_field_and_equal_their_constructors() -> None:
    # The builder fills the frozen nodes' fields without their __init__ (for speed).
    import dataclasses

    mission, _ = build()
    nodes: list[object] = []
    for task in mission.walk():
        nodes.append(task)
        nodes.extend(task.conditions)
        if task.action is not None:
            nodes.append(task.action)
            nodes.extend(task.action.arguments)
    for event in mission.events:
        nodes.extend(event.conditions)
    assert {type(n).__name__ for n in nodes} >= {"Task", "Condition", "Action", "Argument"}
    for node in nodes:
        assert dataclasses.is_dataclass(node) and not isinstance(node, type)
        names = {f.name for f in dataclasses.fields(node)}
        assert set(vars(node)) == names
        assert type(node)(**vars(node)) == node
