"""Hardened reading and model building (tml.parse)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tml import parse
from tml.errors import MissionSyntaxError
from tml.model import Comparison, ConditionKind, Dispatch, EventTrigger, TerminationMode
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
    doc = parse.read_xml("m.xml", data)
    return parse.build_mission(doc)


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
        parse.read_xml("bad.xml", data)
    assert info.value.code == code
    assert info.value.location.file == "bad.xml"
    assert info.value.location.line >= 1


def test_entities_are_never_expanded() -> None:
    laughs = (b'<!DOCTYPE l [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;">]>'
              b'<mission name="&b;"/>')
    with pytest.raises(MissionSyntaxError, match="DOCTYPE"):
        parse.read_xml("laughs.xml", laughs)


def test_size_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(parse, "MAX_BYTES", 100)
    with pytest.raises(MissionSyntaxError) as info:
        parse.read_xml("big.xml", b"<mission name='x'>" + b" " * 200 + b"</mission>")
    assert info.value.code == "E005"


def test_depth_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(parse, "MAX_DEPTH", 3)
    data = b"<mission name='x'>\n<task name='a'>\n<task name='b'>\n<task name='c'>\n" \
           b"<action name='LAND'/></task></task></task></mission>"
    with pytest.raises(MissionSyntaxError) as info:
        parse.read_xml("deep.xml", data)
    assert info.value.code == "E006"
    assert info.value.location.line == 4


def test_utf8_bom_and_non_ascii_names_are_fine() -> None:
    doc = parse.read_xml("bom.xml", '\ufeff<mission name="Misión"/>'.encode())
    assert doc.root.get("name") == "Misión"


def test_columns_count_characters_not_bytes() -> None:
    text = '<mission name="ñañá">\n  <task name="é" x="1"/></mission>'
    doc = parse.read_xml("u.xml", text.encode())
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
    world = parse.load_world(path)
    assert world.home.latitude == 47 and world.obstacles[0].name == "pole"


def test_load_world_rejects_bad_files_with_location(tmp_path: Path) -> None:
    path = tmp_path / "field.xml"
    path.write_text('<world>\n  <cylinder north="3" east="4"/>\n</world>\n')
    with pytest.raises(MissionSyntaxError) as info:
        parse.load_world(path)
    assert (info.value.code, info.value.location.line) == ("E104", 2)
    assert "radius" in str(info.value)
    path.write_text('<mission name="m"><task name="t"><action name="LAND"/></task></mission>')
    with pytest.raises(MissionSyntaxError, match="expected a <world>"):
        parse.load_world(path)


def test_attribute_columns_skip_quoted_values() -> None:
    text = '<mission name="m">\n<parameter name="x" description="a > b typo=" typo="1"/></mission>'
    doc = parse.read_xml("q.xml", text.encode())
    assert doc.location(doc.root[0], "typo").column == 47
    assert doc.location(doc.root[0], "description").column == 21
