"""Printing a verification report: the rich table and the JSON document."""

from __future__ import annotations

import io
import json
import re
from dataclasses import replace

from rich.console import Console

from tml.language.validation import validate_file
from tml.verify.profile import load_profile
from tml.verify.report import print_report, report_json
from tml.verify.static import verify_mission

MISSION = b"""<?xml version="1.0"?>
<mission name="m">
  <environment><cylinder name="mast" north="50" east="0" radius="1"/></environment>
  <task name="up"><action name="TAKE_OFF"/></task>
  <task name="close"><action name="GO_TO_POINT">
    <argument name="coordinates" value="(47, 0, 10)"/></action></task>
</mission>
"""


def _report(file: str = "m.xml", text: bytes = MISSION) -> object:
    mission = validate_file(file, text).mission
    assert mission is not None
    return verify_mission(mission, replace(load_profile("quadcopter"), name="test"))


def _printed(report: object) -> str:
    buffer = io.StringIO()
    print_report(report, Console(file=buffer, width=200))  # type: ignore[arg-type]
    return buffer.getvalue()


def test_table_has_a_row_per_action_and_every_violation() -> None:
    text = _printed(_report())
    assert "m.xml with profile test" in text
    assert "TAKE_OFF" in text and "GO_TO_POINT" in text
    assert "m.xml:5:" in text and "c1: GO_TO_POINT" in text and "(in close)" in text
    assert "INFEASIBLE: 1 constraint(s) broken" in text


def test_json_document() -> None:
    data = json.loads(report_json(_report()))  # type: ignore[arg-type]
    assert data["file"] == "m.xml"
    assert data["feasible"] is False
    assert [row["action"] for row in data["actions"]] == ["TAKE_OFF", "GO_TO_POINT"]
    assert data["actions"][1]["clearance"] == 2.0
    assert data["violations"][0]["task"] == "close"
    assert data["end"]["position"] == [47.0, 0.0, 10.0]


FLEET = b"""<?xml version="1.0"?>
<mission name="f">
  <environment><cylinder name="mast" north="50" east="0" radius="1"/></environment>
  <roles><role name="north"/><role name="south" count="2"/></roles>
  <task name="both" composition="parallel">
    <task name="n" role="north">
      <task name="up"><action name="TAKE_OFF"/></task>
      <task name="close"><action name="GO_TO_POINT">
        <argument name="coordinates" value="(47, 0, 10)"/></action></task>
    </task>
    <task name="s" role="south"><action name="TAKE_OFF"/></task>
  </task>
</mission>
"""


def test_table_of_a_fleet_names_roles_and_vehicles() -> None:
    text = _printed(_report("f.xml", FLEET))
    assert "role (vehicles)" in text and "north (1)" in text and "south (1, 2)" in text
    assert "role north, vehicle 1: f.xml:8:" in text and "(in both/n/close)" in text
    assert "; role north ends after" in text and "; role south ends after" in text


def test_json_of_a_fleet_has_roles() -> None:
    data = json.loads(report_json(_report("f.xml", FLEET)))  # type: ignore[arg-type]
    assert [(row["role"], row["vehicles"]) for row in data["actions"]] == [
        ("north", [1]), ("north", [1]), ("south", [1, 2])]
    assert [(v["role"], v["vehicles"], v["constraint"]) for v in data["violations"]] == [
        ("north", [1], "c1")]
    assert sorted(data["ends"]) == ["north", "south"]
    assert data["ends"]["north"]["position"] == [47.0, 0.0, 10.0]


def test_json_without_roles_has_no_role_fields() -> None:
    data = json.loads(report_json(_report()))  # type: ignore[arg-type]
    assert "ends" not in data
    assert all("role" not in row for row in data["actions"] + data["violations"])


def test_the_report_escapes_control_characters_bidi_overrides_and_markup() -> None:
    hostile = MISSION.replace(b'task name="close"', b'task name="cl[/x]\xe2\x80\xaeose\xc2\x9b"')
    text = _printed(_report("m\u202e\x1b.xml", hostile))
    for bad in ("\u202e", "\x9b", "\x1b"):
        assert bad not in text
    assert "cl[/x]\\u202eose\\x9b" in text.replace("\n", "").replace("│", "").replace(" ", "")
    assert "m\\u202e\\x1b.xml" in text


DRAINED = b"""<?xml version="1.0"?>
<mission name="d">
  <task name="up"><action name="TAKE_OFF"/></task>
  <task name="far"><action name="GO_TO_POINT">
    <argument name="coordinates" value="(1900, 0, 10)"/></action></task>
  <task name="photo"><action name="CAPTURE_PHOTO"/></task>
  <task name="back"><action name="GO_TO_POINT">
    <argument name="coordinates" value="(0, 0, 10)"/></action></task>
  <task name="photo again"><action name="CAPTURE_PHOTO"/></task>
  <task name="far again"><action name="GO_TO_POINT">
    <argument name="coordinates" value="(1900, 0, 10)"/></action></task>
  <task name="last photo"><action name="CAPTURE_PHOTO"/></task>
  <task name="down"><action name="LAND"/></task>
</mission>
"""


def test_a_battery_that_runs_out_is_said_once_where_it_does() -> None:
    report = _report("d.xml", DRAINED)
    text = _printed(report)
    # The table says "empty" from the action where it runs out, never a negative charge.
    rows = [line for line in text.splitlines() if line.startswith("│")]
    assert [row.split("│")[6].strip() for row in rows][3:] == ["empty"] * 5
    assert not re.search(r"-\d+\.\d+ ?%", text)
    # Going out leaves no way home; c2 at the action where it runs out; none after it.
    assert [(v.constraint.value, v.location.line) for v in report.violations  # type: ignore
            if v.constraint.value in ("c2", "return-reserve")] == [("return-reserve", 4),
                                                                   ("c2", 7)]
    assert "d.xml:4:20: return-reserve: GO_TO_POINT: the battery runs out on the way home " \
        "from (1900.0, 0.0, 10.0): 0.0 %, must be >= 20.0 % (in far)" in text
    assert text.rstrip().endswith("with the battery empty: it runs out at line 7 "
                                  "(GO_TO_POINT in back)")
    data = json.loads(report_json(report))  # type: ignore[arg-type]
    assert min(row["battery"] for row in data["actions"]) == 0.0
    assert data["end"]["battery"] == 0.0


def test_a_note_said_of_several_actions_is_printed_once_with_their_lines() -> None:
    text = _printed(_report("d.xml", DRAINED))
    notes = [line for line in text.splitlines() if "CAPTURE_PHOTO takes no time" in line]
    assert notes == ["note: d.xml:6:22: CAPTURE_PHOTO: CAPTURE_PHOTO takes no time or battery "
                     "in the model (3 actions, lines 6, 9, 12)"]
