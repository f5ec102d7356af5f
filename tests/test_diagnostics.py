"""Printing diagnostics (tml.language.diagnostics)."""

from __future__ import annotations

import json

from tml.errors import Location
from tml.language.diagnostics import (
    error,
    format_github,
    format_human,
    format_json,
    indefinite,
    warning,
)

SOURCE = '<mission name="m">\n  <task name="t" bogus="1">\n</mission>\n'


def test_human_format_quotes_the_line_with_a_caret() -> None:
    text = format_human(error(Location("m.xml", 2, 18), "E103", "no attribute 'bogus'",
                              "remove it"), {"m.xml": SOURCE})
    lines = text.splitlines()
    assert lines[0] == "m.xml:2:18: error E103: no attribute 'bogus'"
    assert lines[1].endswith('<task name="t" bogus="1">')
    assert lines[2].index("^") == lines[1].index("bogus")
    assert lines[3] == "  hint: remove it"


def test_human_format_without_source_or_column() -> None:
    text = format_human(warning(Location("m.xml", 9), "W301", "careful"), {})
    assert text == "m.xml:9: warning W301: careful"


def test_github_annotations() -> None:
    line = format_github(error(Location("m.xml", 2, 18), "E103", "bad\nthing", "fix 100%"))
    assert line == "::error file=m.xml,line=2,col=18,title=E103::bad%0Athing (fix 100%25)"
    assert format_github(warning(Location("m.xml", 3), "W301", "w")).startswith("::warning ")


def test_json_format() -> None:
    data = json.loads(format_json([("m.xml", False, [error(Location("m.xml", 2, 3), "E1",
                                                            "msg")])]))
    assert data == [{"file": "m.xml", "valid": False, "diagnostics": [
        {"file": "m.xml", "line": 2, "column": 3, "code": "E1", "message": "msg", "hint": "",
         "severity": "error"}]}]


def test_github_annotation_properties_are_escaped() -> None:
    # Properties (file=, title=) also escape ':' and ',', which would end them early.
    line = format_github(error(Location("dir,a/50%:m.xml", 2, 18), "E103", "a: b, c\r\n"))
    assert line == ("::error file=dir%2Ca/50%25%3Am.xml,line=2,col=18,title=E103"
                    "::a: b, c%0D%0A")


def test_indefinite_article_follows_the_sound_of_the_word() -> None:
    assert [indefinite(w) for w in ("altitude", "angle", "airship", "octocopter",
                                    "latitude", "number", "UAV", "uav", "fixed-wing")] == [
        "an altitude", "an angle", "an airship", "an octocopter", "a latitude", "a number",
        "a UAV", "a uav", "a fixed-wing"]
