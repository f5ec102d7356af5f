"""The tml command line (tml.commands.cli)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tml.commands.cli import main
from tml.errors import ExitCode

VALID = ('<mission name="m">\n  <task name="Take off"><action name="TAKE_OFF"/></task>\n'
         '  <task name="Land"><action name="LAND"/></task>\n</mission>\n')
WARNS = VALID.replace('<action name="LAND"/>',
                      '<condition parameter="colour" comparison="equal" value="red"/>'
                      '<action name="LAND"/>')
INVALID = VALID.replace("LAND", "LANDD")


@pytest.fixture
def files(tmp_path: Path) -> Path:
    (tmp_path / "valid.xml").write_text(VALID)
    (tmp_path / "warns.xml").write_text(WARNS)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "invalid.xml").write_text(INVALID)
    (tmp_path / "notes.txt").write_text("not a mission")
    return tmp_path


def test_valid_file_exits_0(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", str(files / "valid.xml")]) == 0
    assert "1 file(s) checked: 1 valid, 0 invalid" in capsys.readouterr().out


def test_directory_is_searched_recursively(files: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", str(files)]) == 1
    out = capsys.readouterr().out
    assert "3 file(s) checked: 2 valid, 1 invalid" in out
    assert f"{files / 'sub' / 'invalid.xml'}:3:" in out and "E201" in out
    assert "notes.txt" not in out


def test_warnings_fail_only_when_strict(files: Path) -> None:
    assert main(["validate", "-q", str(files / "warns.xml")]) == 0
    assert main(["validate", "-q", "--strict", str(files / "warns.xml")]) == 1


def test_missing_file_is_a_usage_error(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", str(files / "nope.xml"), str(files / "valid.xml")]) == 2
    assert "nope.xml: no such file or directory" in capsys.readouterr().err


def test_a_directory_without_xml_files_is_a_usage_error(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "notes.txt").write_text("not a mission")
    assert main(["validate", str(tmp_path)]) == 2
    assert f"{tmp_path}: no .xml files in this directory" in capsys.readouterr().err


def test_unreadable_file_is_an_io_error(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = files / "dir.xml"
    target.mkdir()
    (target / "x.xml").write_text(VALID)
    assert main(["validate", str(files / "valid.xml"), str(target)]) == 0
    bad = files / "unreadable.xml"
    bad.symlink_to(files / "missing-target.xml")
    assert main(["validate", str(bad)]) == 2


def test_json_format(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", "--format", "json", str(files)]) == 1
    report = {Path(r["file"]).name: r for r in json.loads(capsys.readouterr().out)}
    assert report["valid.xml"] == {"file": str(files / "valid.xml"), "valid": True,
                                   "diagnostics": []}
    [problem] = report["invalid.xml"]["diagnostics"]
    assert (problem["code"], problem["line"], problem["severity"]) == ("E201", 3, "error")
    assert report["warns.xml"]["valid"] is True


def test_github_format(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", "--format", "github", str(files / "sub")]) == 1
    out = capsys.readouterr().out.strip()
    assert out.startswith(f"::error file={files / 'sub' / 'invalid.xml'},line=3,col=")
    assert "title=E201::unknown action 'LANDD'" in out


PLAN = '{"fileType": "Plan", "mission": {"items": []}, "version": 1}\n'
WPL = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t-35.36\t149.16\t584\t1\n"


@pytest.mark.parametrize(("name", "text", "looks"), [
    ("survey.plan", PLAN, "this looks like a QGroundControl plan, not a mission"),
    ("survey.json", PLAN, "this looks like a QGroundControl plan, not a mission"),
    ("survey.txt", WPL, "this looks like a QGC WPL waypoint file, not a mission"),
    ("survey.waypoints", "0 1 0 16\n", "this looks like a .waypoints file, not a mission"),
    ("survey.xml", '{"a": 1}', "this is JSON, not a mission; if it is a QGroundControl plan"),
])
def test_a_plan_given_to_validate_is_pointed_to_import(
        tmp_path: Path, name: str, text: str, looks: str,
        capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / name
    path.write_text(text)
    assert main(["validate", "-q", str(path)]) == ExitCode.INVALID
    out = capsys.readouterr().out
    assert "error E002: not well-formed XML" in out
    assert f"  hint: {looks}" in out
    assert f"`tml import {path} -o survey.xml` makes a mission of it" in out


def test_text_that_is_no_plan_gets_no_import_hint(files: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", "-q", str(files / "notes.txt")]) == ExitCode.INVALID
    out = capsys.readouterr().out
    assert "error E002" in out and "hint" not in out


def test_usage_errors_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    assert main(["validate"]) == 2
    assert main(["frobnicate"]) == 2
    assert main(["--version"]) == 0
    assert "tml 0.1.0" in capsys.readouterr().out


@pytest.mark.parametrize(("argv", "line"), [
    (["run", "m.xml", "--sim", "--speedup", "-1"],
     "tml run: error: argument --speedup: expected a finite number greater than 0, got -1 "
     "(see tml run --help)"),
    (["run", "m.xml"],
     "tml run: error: one of the arguments --sim --connect is required (see tml run --help)"),
    (["validate", "--format", "xml", "m.xml"],
     "tml validate: error: argument --format: invalid choice: 'xml' (choose from 'human', "
     "'json', 'github') (see tml validate --help)"),
    (["verify"], "tml verify: error: the following arguments are required: FILE "
                 "(see tml verify --help)"),
    (["frobnicate"], "tml: error: argument COMMAND: invalid choice: 'frobnicate' (choose "
                     "from 'validate', 'verify', 'run', 'companion', 'command', 'export', "
                     "'import', 'report', 'schema', 'completion', 'serve', 'sim') (see tml "
                     "--help)"),
    (["sim", "--vehicles", "0"], "tml sim: error: argument --vehicles: expected a whole "
                                 "number of at least 1, got '0' (see tml sim --help)"),
])
def test_a_usage_error_is_one_line_and_exits_2(argv: list[str], line: str,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == ExitCode.USAGE
    out, err = capsys.readouterr()
    assert (out, err) == ("", line + "\n")


def test_python_dash_m_and_console_script(files: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "tml", "validate", str(files / "valid.xml")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "1 valid" in done.stdout


def test_validate_does_not_load_pymavlink(files: Path) -> None:
    code = ("import sys; from tml.commands.cli import main; "
            "rc = main(['validate', '-q', sys.argv[1]]);"
            "print(rc, 'pymavlink' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code, str(files / "valid.xml")],
                          capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["0", "False"]


def test_many_files_are_validated_in_parallel_with_the_same_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import tml.commands.cli

    for index in range(120):
        (tmp_path / f"m{index:03d}.xml").write_text(INVALID if index % 40 == 7 else VALID)
    monkeypatch.setattr(tml.commands.cli, "PARALLEL_BATCH", 10)
    monkeypatch.setattr(tml.commands.cli.os, "cpu_count", lambda: 2)
    assert main(["validate", str(tmp_path)]) == 1
    parallel = capsys.readouterr().out
    monkeypatch.setattr(tml.commands.cli, "PARALLEL_BATCH", 10**6)
    assert main(["validate", str(tmp_path)]) == 1
    serial = capsys.readouterr().out
    assert parallel == serial
    assert "120 file(s) checked: 117 valid, 3 invalid" in serial


def test_pre_commit_hook_entry_is_a_working_command(files: Path) -> None:
    hooks = (Path(__file__).parent.parent / ".pre-commit-hooks.yaml").read_text()
    entry = next(line.split(":", 1)[1].split() for line in hooks.splitlines()
                 if line.strip().startswith("entry:"))
    assert entry[0] == "tml"
    # pre-commit appends the staged file names to the entry.
    assert main([*entry[1:], str(files / "valid.xml")]) == 0
    assert main([*entry[1:], str(files / "valid.xml"), str(files / "sub" / "invalid.xml")]) == 1


def test_closed_pipe_is_not_a_traceback(files: Path) -> None:
    many = [str(files / "sub" / "invalid.xml")] * 200
    done = subprocess.run(f"{sys.executable} -m tml validate {' '.join(many)} | head -1",
                          shell=True, capture_output=True, text=True)
    assert "Traceback" not in done.stderr and "BrokenPipe" not in done.stderr
    assert done.stdout.count("\n") == 1


def test_sim_help_is_the_simulator_help(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "--help"]) == 0
    assert "--vehicles" in capsys.readouterr().out
    assert main(["sim", "--vehicles", "0"]) == 2


def test_the_documented_exit_codes_are_the_enums() -> None:
    # The numbers are an interface to shells and scripts: docs/run.md's table and the one
    # ExitCode enum every command returns must agree.
    doc = (Path(__file__).resolve().parent.parent / "docs" / "run.md").read_text("utf-8")
    section = doc.split("## Exit codes", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| (\d) \| (.+?) \|$", section, re.M)
    assert [int(code) for code, _ in rows] == [
        ExitCode.OK, ExitCode.INVALID, ExitCode.USAGE, ExitCode.ABORTED, ExitCode.FAILURE]
    assert "completed" in rows[0][1] and "invalid" in rows[1][1]
    assert "usage" in rows[2][1]
    assert "aborted" in rows[3][1] and "failure" in rows[4][1]


def _completions(line: str, tmp_path: Path) -> list[str]:
    out = tmp_path / "completions"
    env = {**os.environ, "_ARGCOMPLETE": "1", "COMP_LINE": line,
           "COMP_POINT": str(len(line)), "_ARGCOMPLETE_STDOUT_FILENAME": str(out)}
    subprocess.run([sys.executable, "-m", "tml"], env=env, timeout=60, check=False,
                   capture_output=True)
    return sorted(out.read_text().split("\x0b"))


def test_the_shell_completes_commands_options_and_choices(tmp_path: Path, capsys) -> None:
    assert _completions("tml ex", tmp_path) == ["export "]
    assert _completions("tml export m.xml --format ", tmp_path) == [
        "fence", "geojson", "kml", "plan", "rally", "wpl"]
    assert "--safe-state" in _completions("tml run m.xml --sa", tmp_path)[0]
    assert main(["completion", "bash"]) == 0
    assert "complete " in capsys.readouterr().out  # bash's builtin registers it
    assert main(["completion", "zsh"]) == 0
    assert capsys.readouterr().out.startswith("#compdef tml")


def test_validate_loads_what_validation_needs_only(files: Path) -> None:
    # A hook validates a file or two per call, so start-up is most of its time: the other
    # commands' modules, the shell completion, the did-you-mean helper and (for a mission
    # without an <environment>) the world's classes stay unloaded.
    code = ("import sys\nfrom tml.commands.cli import main\n"
            f"code = main(['validate', '-q', {str(files / 'valid.xml')!r}])\n"
            "print(code, ' '.join(sorted(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, check=True)
    code, modules = done.stdout.split(" ", 1)
    assert code == "0" and "tml.language.check" in modules.split()
    loaded = set(modules.split())
    assert not loaded & {"tml.commands.run", "tml.commands.verify", "tml.commands.plans",
                         "tml.commands.command", "tml.engine",
                         "tml.commands.serve", "tml.commands.report", "argcomplete",
                         "difflib", "shapely", "pymavlink", "tml.world"}


def test_every_command_keeps_its_options_and_help_lists_them_all(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--help"]) == 0
    listed = capsys.readouterr().out
    for command in ("validate", "verify", "run", "companion", "command", "export", "import",
                    "report", "schema", "completion", "serve", "sim"):
        assert command in listed
    assert main(["run", "--help"]) == 0
    assert "--sim" in capsys.readouterr().out
    assert main(["validate", "--help"]) == 0
    assert "--tml-only" in capsys.readouterr().out
    assert main(["verify", "--no-such-option", "m.xml"]) == 2
