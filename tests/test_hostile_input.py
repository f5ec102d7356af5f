"""Hostile input: files that leak, never end or are not files; terminal escapes; huge output.

Each test here is a regression test for a defect an adversarial probe found: a symlink
out of a validated directory printed /etc/passwd's first line, /dev/zero and FIFOs were
read until memory ran out or forever, raw ESC and BEL bytes of a file reached the terminal,
and 150,000 duplicated task names took a minute to print.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tracemalloc
from pathlib import Path

import pytest
from fuzzing import time_bound

from tml.commands.cli import main
from tml.errors import ExitCode, Location
from tml.language import xml
from tml.language.diagnostics import error, format_human, printable
from tml.language.validation import validate_file

SECRET = "root:x:0:0:SECRET-LINE:/root:/bin/bash"
VALID = ('<mission name="m">\n  <task name="Take off"><action name="TAKE_OFF"/></task>\n'
         '  <task name="Land"><action name="LAND"/></task>\n</mission>\n')


def _tml(*args: str) -> subprocess.CompletedProcess[str]:
    """``python -m tml ARGS`` with 1 GB of address space: a command that reads without
    bound fails at once instead of taking the machine's memory; the timeout stops a hang."""
    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))

    return subprocess.run([sys.executable, "-m", "tml", *args], capture_output=True,
                          text=True, timeout=120, preexec_fn=limit, check=False)


# --- leaks and unbounded reads ---------------------------------------------------------------

def test_a_symlink_leaving_the_directory_is_refused_unread(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    outside = tmp_path / "passwd"
    outside.write_text(SECRET + "\n")
    tree = tmp_path / "missions"
    tree.mkdir()
    (tree / "good.xml").write_text(VALID)
    (tree / "x.xml").symlink_to(outside)
    assert main(["validate", str(tree)]) == ExitCode.USAGE
    out, err = capsys.readouterr()
    assert "SECRET" not in out + err
    assert "x.xml" in err and "symbolic link" in err
    assert "1 file(s) checked: 1 valid" in out


def test_a_symlink_inside_the_directory_is_validated(tmp_path: Path) -> None:
    (tmp_path / "real.xml").write_text(VALID)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "alias.xml").symlink_to(tmp_path / "real.xml")
    assert main(["validate", str(tmp_path)]) == ExitCode.OK


def test_the_content_of_a_file_that_is_not_xml_is_never_quoted(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "x.xml"
    path.write_text(SECRET + "\n")
    assert main(["validate", str(path)]) == ExitCode.INVALID
    out = capsys.readouterr().out
    assert "E002" in out and "SECRET" not in out


def test_a_large_file_is_refused_without_being_read_whole(tmp_path: Path) -> None:
    path = tmp_path / "big.xml"
    with path.open("wb") as stream:  # sparse: 100 MB that take no disk
        stream.write(b"<mission>")
        stream.truncate(100 * 1024 * 1024)
    tracemalloc.start()
    try:
        result = validate_file(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert [d.code for d in result.diagnostics] == ["E005"]
    assert str(100 * 1024 * 1024) in result.diagnostics[0].message
    assert peak < 3 * xml.MAX_BYTES


@pytest.mark.parametrize("command", [["verify"], ["validate"], ["run", "--sim"]])
def test_dev_zero_is_refused_as_not_a_regular_file(command: list[str]) -> None:
    done = _tml(*command[:1], "/dev/zero", *command[1:])
    assert done.returncode == ExitCode.USAGE, done.stderr
    assert "not a regular file" in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize("command", [["verify"], ["validate"], ["run", "--sim"]])
def test_a_fifo_is_refused_at_once(tmp_path: Path, command: list[str]) -> None:
    fifo = tmp_path / "pipe.xml"
    os.mkfifo(fifo)
    done = _tml(*command[:1], str(fifo), *command[1:])  # opening it to read would block
    assert done.returncode == ExitCode.USAGE, done.stderr
    assert "not a regular file" in done.stderr


# --- terminal injection ----------------------------------------------------------------------

def test_escape_bytes_of_a_file_never_reach_the_terminal(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "m.xml"
    path.write_bytes(b'<?xml version="1.0"?>\n'
                     b'<mission name="m"><!-- \x1b]0;PWNED\x07 --></mission>\n')
    assert main(["validate", str(path)]) == ExitCode.INVALID
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out
    assert "\\x1b]0;PWNED\\x07" in out


def test_controls_and_bidi_overrides_are_escaped_everywhere_in_a_diagnostic() -> None:
    source = "<mission name='\u202eevil\u2066'>\x9b31m\n"
    text = format_human(error(Location("a\x1bb.xml", 1, 2), "E1", "name '\u202eevil'",
                              "hint \x07"), {"a\x1bb.xml": source})
    for bad in ("\x1b", "\x07", "\x9b", "\u202e", "\u2066"):
        assert bad not in text
    assert "\\u202e" in text and "\\x9b" in text


def test_printable_keeps_tabs_newlines_and_ordinary_text() -> None:
    assert printable("a\tb\nc é 東") == "a\tb\nc é 東"
    assert printable("a\rb\x00\x7f") == "a\\rb\\x00\\x7f"
    assert printable("one\ntwo", newlines=False) == "one\\ntwo"


# --- quadratic output ------------------------------------------------------------------------

class _CountingText(str):
    """Source text that counts how often it is split into lines."""

    splits = 0

    def splitlines(self, keepends: bool = False) -> list[str]:
        _CountingText.splits += 1
        return super().splitlines(keepends)


def test_many_diagnostics_split_the_source_once() -> None:
    source = _CountingText("".join(f"<task name='t{i}'/>\n" for i in range(2000)))
    _CountingText.splits = 0
    for line in range(1, 1001):
        format_human(error(Location("m.xml", line, 2), "E244", "twice"), {"m.xml": source})
    assert _CountingText.splits == 1


def test_repeated_diagnostics_are_capped_with_a_count(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tasks = "".join('<task name="same"><action name="WAIT"><argument name="duration" '
                    'value="1"/></action></task>\n' for _ in range(5000))
    path = tmp_path / "dup.xml"
    path.write_text(f'<mission name="m">\n{tasks}</mission>\n')
    assert main(["validate", str(path)]) == ExitCode.OK  # twins are a warning (W310)
    out = capsys.readouterr().out
    assert out.count("warning W310") < 100
    assert "4999 warning(s)" in out
    assert "more W310" in out
    more = [line for line in out.splitlines() if "more W310" in line]
    assert len(more) == 1 and str(4999 - out.count("warning W310")) in more[0]


# --- numbers that validate but break verify and run ------------------------------------------

@pytest.mark.parametrize("value", ["1e309", "-1e309", "(1e309, 0, 10)"])
def test_a_number_too_large_for_a_float_is_refused_as_inf_is(
        tmp_path: Path, value: str) -> None:
    name, argument = (("GO_TO_POINT", "coordinates") if value.startswith("(")
                      else ("WAIT", "duration"))
    path = tmp_path / "m.xml"
    path.write_text(VALID.replace(
        '<action name="LAND"/>',
        f'<action name="{name}"><argument name="{argument}" value="{value}"/></action>'))
    assert [d.code for d in validate_file(path).errors] == ["E212"]


def test_a_file_on_one_line_is_read_in_linear_time() -> None:
    # Found by benchmarks/hostile.py: each start tag's column was found by searching back
    # to the start of its line, so 100,000 nested tasks on one line (2 MB) took 7 s and
    # 8 MB on one line took many minutes: the search is bounded by the previous tag now.
    opening = b'<task name="n">'
    count = (xml.MAX_BYTES - 100) // len(opening)
    data = b'<mission name="m">' + opening * count
    with time_bound(60.0):
        result = validate_file("one_line.xml", data)
    [problem] = result.errors
    assert problem.code == "E002" and "depth" in problem.message
    assert (problem.location.line, problem.location.column) == (1, 18 + 256 * len(opening))


def test_a_long_line_is_quoted_around_its_column_only() -> None:
    # Found by benchmarks/hostile.py: the diagnostic of a mission on one line quoted the
    # whole line, 2 MB of it for 100,000 nested tasks (8 MB at the size bound) each time.
    line = "<m>" + "x" * 100_000 + "<bad>" + "y" * 100_000
    column = line.index("<bad>") + 1
    text = format_human(error(Location("m.xml", 1, column), "E002", "bad"), {"m.xml": line})
    quoted, caret = text.splitlines()[1:3]
    assert len(quoted) < 200 and quoted.startswith("     1 | …") and quoted.endswith("…")
    assert quoted[caret.index("^"):].startswith("<bad>")
    short = format_human(error(Location("m.xml", 1, 4), "E002", "bad"), {"m.xml": "<m><bad>"})
    assert short.splitlines()[1:3] == ["     1 | <m><bad>", "       |    ^"]
