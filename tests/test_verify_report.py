"""Printing a verification report: the rich table and the JSON document."""

from __future__ import annotations

import io
import json
from dataclasses import replace

from rich.console import Console

from tml.validation import validate_file
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


def _report() -> object:
    mission = validate_file("m.xml", MISSION).mission
    assert mission is not None
    return verify_mission(mission, replace(load_profile("quadcopter"), name="test"))


def test_table_has_a_row_per_action_and_every_violation() -> None:
    buffer = io.StringIO()
    print_report(_report(), Console(file=buffer, width=160))  # type: ignore[arg-type]
    text = buffer.getvalue()
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
