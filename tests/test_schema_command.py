"""``tml schema`` and the stable schema location editors resolve."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tml.commands.cli import main
from tml.language.schema import SCHEMA_LOCATION

MISSION = ('<mission xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" '
           'xsi:noNamespaceSchemaLocation="{}" name="m">'
           '<task name="t"><action name="LAND"/></task></mission>')


def test_schema_path_and_text(capsys) -> None:
    assert main(["schema"]) == 0
    path = Path(capsys.readouterr().out.strip())
    assert path.name == "tml.xsd" and path.is_file()
    assert main(["schema", "--print"]) == 0
    assert capsys.readouterr().out == path.read_text()
    assert main(["schema", "--path", "--world"]) == 0
    assert capsys.readouterr().out.strip().endswith("world.xsd")


def test_the_catalog_resolves_the_stable_location_to_the_installed_schema(
        tmp_path: Path, capsys) -> None:
    assert main(["schema", "--catalog"]) == 0
    catalog = tmp_path / "catalog.xml"
    catalog.write_text(capsys.readouterr().out)
    # libxml2, as editors built on it do, loads the schema by its stable name.
    done = subprocess.run(
        [sys.executable, "-c", "from lxml import etree; import sys; "
         f"etree.XMLSchema(etree.parse({SCHEMA_LOCATION!r})); print('resolved')"],
        capture_output=True, text=True, env={**os.environ, "XML_CATALOG_FILES": str(catalog)},
        timeout=60)
    assert done.stdout.strip() == "resolved", done.stderr


def test_validate_accepts_either_schema_location(tmp_path: Path) -> None:
    for location in (SCHEMA_LOCATION, "../schemas/tml.xsd"):
        path = tmp_path / "m.xml"
        path.write_text(MISSION.format(location))
        assert main(["validate", "-q", str(path)]) == 0


def test_the_pre_commit_hook_looks_at_tml_files_only(tmp_path: Path, capsys) -> None:
    hooks = (Path(__file__).resolve().parent.parent / ".pre-commit-hooks.yaml").read_text()
    entry = next(line.split(":", 1)[1].split() for line in hooks.splitlines()
                 if line.strip().startswith("entry:"))
    assert entry[:2] == ["tml", "validate"]
    pom = tmp_path / "pom.xml"
    pom.write_text('<?xml version="1.0"?>\n<!-- a build file -->\n<project><modelVersion>4.0.0'
                   '</modelVersion></project>\n')
    mission = tmp_path / "m.xml"
    mission.write_text(MISSION.format(SCHEMA_LOCATION))
    bad = tmp_path / "bad.xml"
    bad.write_text(MISSION.format(SCHEMA_LOCATION).replace("LAND", "LANDD"))
    # pre-commit passes every staged file its files pattern matches.
    assert main([*entry[1:], str(pom), str(mission)]) == 0
    assert capsys.readouterr().out == ""
    assert main([*entry[1:], str(pom), str(bad)]) == 1
    assert "E201" in capsys.readouterr().out
