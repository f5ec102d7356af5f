"""Every file in tests/data/invalid/ produces its expected error code at its expected line."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from tml.commands.cli import main
from tml.language.validation import validate_file

INVALID = Path(__file__).parent / "data" / "invalid"
EXPECTED = tomllib.loads((INVALID / "expected.toml").read_text())


def test_corpus_is_complete() -> None:
    on_disk = {p.name for p in INVALID.glob("*.xml")}
    assert on_disk == set(EXPECTED)
    assert len(on_disk) >= 30


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_invalid_file_reports_expected_error(name: str) -> None:
    expected = EXPECTED[name]
    result = validate_file(INVALID / name)
    assert not result.valid()
    found = [(d.code, d.location.line) for d in result.errors]
    assert (expected["code"], expected["line"]) in found, result.diagnostics
    for diagnostic in result.errors:
        assert diagnostic.location.file == str(INVALID / name)
        assert diagnostic.message


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_cli_exits_1_with_location_and_no_traceback(
    name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    expected = EXPECTED[name]
    assert main(["validate", str(INVALID / name)]) == 1
    out, err = capsys.readouterr()
    assert f"{INVALID / name}:{expected['line']}:" in out
    assert f"error {expected['code']}:" in out
    assert "Traceback" not in out + err


def test_schema_and_language_mistakes_are_all_reported_in_one_run(
        capsys: pytest.CaptureFixture[str]) -> None:
    # Before, the schema's four findings came alone, then the language's in two more runs.
    path = INVALID / "several_mistakes.xml"
    found = [(d.code, d.location.line, d.location.column) for d in validate_file(path).errors]
    assert found == [("E103", 5, 25), ("E105", 9, 13), ("E201", 11, 7), ("E212", 17, 9),
                     ("E230", 23, 7), ("E225", 27, 5), ("E105", 27, 53), ("E224", 28, 5),
                     ("E105", 32, 23), ("E240", 34, 7)]
    assert main(["validate", str(path)]) == 1
    out = capsys.readouterr().out
    assert out.count(f"{path}:") == 10
    assert out.rstrip().endswith("0 valid, 1 invalid (10 error(s), 0 warning(s))")


def _codes(tmp_path: Path, body: str) -> list[tuple[str, int]]:
    path = tmp_path / "m.xml"
    path.write_text(f'<mission name="m">\n{body}</mission>\n')
    return [(d.code, d.location.line) for d in validate_file(path).diagnostics]


TAKE_OFF = '  <task name="Up"><action name="TAKE_OFF"/></task>\n'


@pytest.mark.parametrize(("body", "expected"), [
    # A comparison refused or misspelt is not also "no comparison=" (E221).
    (TAKE_OFF + '  <task name="Down">\n'
     '    <condition parameter="ALTITUDE" comparison="below" value="5"/>\n'
     '    <action name="LAND"/></task>\n', [("E105", 4)]),
    (TAKE_OFF + '  <task name="Down">\n'
     '    <condition parameter="ALTITUDE" comparision="less than" value="5"/>\n'
     '    <action name="LAND"/></task>\n', [("E103", 4)]),
    # A misspelt <argument> is not also "WAIT needs argument 'duration'" (E211).
    (TAKE_OFF + '  <task name="Hold"><action name="WAIT">\n'
     '    <argumnt name="duration" value="5"/></action></task>\n', [("E101", 4)]),
    # A task left out (misspelt <tsk>) may hold what others read: no "label never stored"
    # (E230) nor "no task has this name" (E240), but the unknown action still said.
    (TAKE_OFF + '  <tsk name="Mark"><action name="MEMORIZE_POINT">\n'
     '    <argument name="coordinates" label="spot"/></action></tsk>\n'
     '  <task name="Go"><action name="GO_TO_POINT">\n'
     '    <argument name="coordinates" label="spot"/></action></task>\n'
     '  <task name="Spin"><action name="SPINN"/></task>\n'
     '  <event_handling><event name="e">\n'
     '    <condition parameter="ALTITUDE" comparison="greater than" value="50"/>\n'
     '    <termination mode="JUMP_TO_TASK" task="Mark"/></event></event_handling>\n',
     [("E101", 3), ("E201", 7)]),
    # A task's name refused: references to it are not judged.
    (TAKE_OFF + '  <task name=""><action name="LAND"/></task>\n'
     '  <task name="Turn"><action name="SPINN"/></task>\n'
     '  <event_handling><event name="e">\n'
     '    <condition current_task="Down" comparison="equal" value="yes"/>\n'
     '    <termination mode="CONTINUE"/></event></event_handling>\n',
     [("E105", 3), ("E201", 4)]),
    # An optional number refused is taken as not written: no time limit.
    (TAKE_OFF + '  <task name="Down" time_limit="soon"><action name="LAND"/></task>\n',
     [("E105", 3)]),
])
def test_what_only_echoes_a_schema_finding_is_not_said_again(
        tmp_path: Path, body: str, expected: list[tuple[str, int]]) -> None:
    # A mistake of the language's own after them is still said in the same run.
    spin = '  <task name="Turn"><action name="SPINN"/></task>\n'
    after = ("E201", body.count("\n") + 2)
    if "<event_handling>" in body:  # the body has one before its event handlers
        assert _codes(tmp_path, body) == expected
    else:
        assert _codes(tmp_path, body + spin) == [*expected, after]
