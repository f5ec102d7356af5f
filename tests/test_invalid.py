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
