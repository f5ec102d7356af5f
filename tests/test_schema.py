"""XML Schema validation and its diagnostics (tml.language.schema)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tml.language import schema
from tml.language.validation import validate_file
from tml.language.xml import read_xml


def problems(xml: str, root: str = "mission"):
    return schema.validate(read_xml("s.xml", xml.encode()), root)


def test_schema_files_are_found() -> None:
    for name in ("tml.xsd", "world.xsd", "environment.xsd", "mavlink.xsd"):
        assert schema.schema_path(name).is_file()


def test_installed_package_ships_the_schemas(tmp_path) -> None:
    # Run from an empty directory so the import comes from the installed distribution.
    code = ("import json, importlib.metadata as m, importlib.resources as r\n"
            "from tml.language.schema import schema_path\n"
            "url = m.distribution('tml-flight').read_text('direct_url.json') or '{}'\n"
            "editable = json.loads(url).get('dir_info', {}).get('editable', False)\n"
            "shipped = [] if editable else sorted(\n"
            "    p.name for p in r.files('tml.schemas').iterdir() if p.name.endswith('.xsd'))\n"
            "print(json.dumps([str(schema_path()), editable, shipped]))")
    out = subprocess.run([sys.executable, "-I", "-c", code], cwd=tmp_path,
                         capture_output=True, text=True, check=True).stdout
    path, editable, shipped = json.loads(out)
    assert path.endswith("tml.xsd") and Path(path).is_file()
    if not editable:  # a real install: the XSDs are inside the package
        assert shipped == ["environment.xsd", "mavlink.xsd", "tml.xsd", "world.xsd"]
        assert Path(path).parent.name == "schemas" and Path(path).parent.parent.name == "tml"


def test_valid_paper_constructs_pass() -> None:
    xml = ('<mission name="m"><skill name="AVOID_OBSTACLES"/>'
           '<task name="t"><skill name="RECOGNIZE_ITEMS"/><repeat times="3"/>'
           '<condition parameter="p" comparison="greater than or equal to" value="1"/>'
           '<action name="FLIP"/></task>'
           '<event_handling><event name="e"><condition currentTask="t"/>'
           '<termination mode="END_MISSION"/></event></event_handling></mission>')
    assert problems(xml) == []


def test_unknown_attribute_points_at_the_attribute_with_suggestion() -> None:
    found = problems('<mission name="m">\n  <task name="t" dispach="mission">'
                     '<action name="LAND"/></task></mission>')
    assert [(p.code, p.location.line, p.location.column) for p in found] == [("E103", 2, 18)]
    assert "did you mean 'dispatch'" in found[0].hint


def test_bad_enumeration_value_suggests_the_closest() -> None:
    found = problems('<mission name="m"><task name="t"><action name="LAND"/></task>'
                     '<event_handling><event name="e">'
                     '<termination mode="ABORT_MISION"/></event></event_handling></mission>')
    assert [p.code for p in found] == ["E105"]
    assert "did you mean 'ABORT_MISSION'" in found[0].hint


def test_value_of_wrong_type() -> None:
    found = problems('<world><home latitude="north" longitude="8" altitude="0"/></world>',
                     "world")
    assert [p.code for p in found] == ["E105"]
    assert "is not a latitude in degrees" in found[0].message


def test_range_violation() -> None:
    found = problems('<world><home latitude="91" longitude="8" altitude="0"/></world>', "world")
    assert [p.code for p in found] == ["E105"]
    assert "at most 90" in found[0].message


@pytest.mark.parametrize(
    ("xml", "code", "words"),
    [
        ('<mission name="m"/>', "E102", "no <task>"),
        ('<mission name="m"><task name="t"/></mission>', "E102", "neither an <action>"),
        ('<mission name="m"><task name="t"><action name="LAND"/><action name="LAND"/></task>'
         '</mission>', "E101", "exactly one <action>"),
        ('<mission name="m"><task name="t"><action name="LAND"/></task><landing/></mission>',
         "E101", "<landing> is not allowed"),
        ('<mission><task name="t"><action name="LAND"/></task></mission>', "E104", "'name'"),
        ('<mission name=" "><task name="t"><action name="LAND"/></task></mission>', "E105",
         "non-empty name"),
    ],
)
def test_structure_errors(xml: str, code: str, words: str) -> None:
    found = problems(xml)
    assert found and found[0].code == code
    assert words in found[0].message + found[0].hint


def test_wrong_root() -> None:
    found = problems('<world/>')
    assert [p.code for p in found] == ["E007"]
    assert "world file" in found[0].message


FLEET_TASK = '<task name="t">\n<task name="u"><action name="LAND"/></task></task>'


@pytest.mark.parametrize(
    ("xml", "code", "line", "words"),
    [
        (FLEET_TASK.replace('"t"', '"t" composition="together"'), "E105", 2, "parallel"),
        (FLEET_TASK.replace('"t"', '"t" time_limit="-5"'), "E105", 2, "time_limit"),
        (FLEET_TASK.replace('"t"', '"t" time_limit="0"'), "E105", 2, "time_limit"),
        ('<roles>\n<role name="r"><region><polygon><point north="0" east="0"/>'
         '<point north="1" east="0"/></polygon></region></role></roles>' + FLEET_TASK,
         "E102", 3, "point"),
        ('<roles>\n<role name="r" count="0"/></roles>' + FLEET_TASK, "E105", 3, "count"),
        ('<roles>\n<role name="r"><region><circle north="0" east="0"/></region></role>'
         '</roles>' + FLEET_TASK, "E104", 3, "radius"),
        (FLEET_TASK.replace('<action name="LAND"/></task>',
                            '<action name="LAND"/></task><until/>'), "E101", 3, "until"),
        (FLEET_TASK.replace('</task></task>', '</task><on_error/></task>'), "E102", 3,
         "task"),
    ],
)
def test_fleet_schema_errors(xml: str, code: str, line: int, words: str) -> None:
    found = problems(f'<mission name="m">\n{xml}</mission>')
    assert [(p.code, p.location.line) for p in found][:1] == [(code, line)], found
    assert words in found[0].message + found[0].hint


def test_the_mavlink_schema_names_pymavlinks_commands_and_frames() -> None:
    from lxml import etree
    from pymavlink.dialects.v20 import ardupilotmega

    tree = etree.parse(str(Path(__file__).parent.parent / "schemas" / "mavlink.xsd"))
    xs = "{http://www.w3.org/2001/XMLSchema}"
    for type_name, enum, prefix in (("MavCmdType", "MAV_CMD", "MAV_CMD_"),
                                    ("MavFrameType", "MAV_FRAME", "MAV_FRAME_")):
        simple = tree.find(f"{xs}simpleType[@name='{type_name}']")
        written = {e.get("value") for e in simple.iter(f"{xs}enumeration")}
        names = {entry.name for entry in ardupilotmega.enums[enum].values()
                 if not entry.name.endswith("ENUM_END")}
        assert written == names | {n.removeprefix(prefix) for n in names}


def test_a_mission_item_is_checked_by_the_schema() -> None:
    def codes(item: str) -> list[str]:
        text = (f'<mission name="m"><task name="p" dispatch="mission"><task name="i">{item}'
                '</task></task></mission>')
        return [d.code for d in validate_file("m.xml", text.encode()).diagnostics]

    assert codes('<mission_item command="DO_JUMP" frame="MISSION" param1="1"/>') == []
    assert codes('<mission_item command="177" frame="2" param4="NaN"/>') == []
    assert codes('<mission_item command="DO_JUMPS" frame="2"/>') == ["E105"]
    assert codes('<mission_item command="DO_JUMP" frame="2" param1="one"/>') == ["E105"]
    assert codes('<mission_item frame="2"/>') == ["E104"]
