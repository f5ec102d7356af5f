"""The distribution's name: its own on the package index, and the one every install hint
gives (``tml`` there is another project's: a hint naming it installs a stranger's package)."""

from __future__ import annotations

import ast
import importlib.metadata
import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
NAME = tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))["project"]["name"]
# What follows `pip install`: a requirement, quoted or not, with its extras.
HINT = re.compile(r"pip install\s+(?:-e\s+)?['\"]?([A-Za-z0-9_.\-]+)(?:\[([^\]]*)\])?")


def _normal(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _hints(paths: list[Path]) -> list[tuple[str, str, str]]:
    """(where, requirement name, extras) of every ``pip install`` that names one."""
    found = []
    for path in paths:
        for match in HINT.finditer(path.read_text("utf-8")):
            found.append((str(path.relative_to(ROOT)), match.group(1), match.group(2) or ""))
    return found


def _strings(path: Path) -> str:
    """The string literals of a module, one a line: adjacent literals are one string to the
    parser, so a hint split over source lines is read whole (an f-string's text parts)."""
    texts = []
    for node in ast.walk(ast.parse(path.read_text("utf-8"))):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            texts.append(node.value)
        elif isinstance(node, ast.JoinedStr):
            texts.append("".join(part.value for part in node.values
                                 if isinstance(part, ast.Constant)))
    return "\n".join(texts)


def _code_hints() -> list[tuple[str, str, str]]:
    """(module, requirement name, extras) of every install hint in tml's strings."""
    return [(str(path.relative_to(ROOT)), match.group(1), match.group(2) or "")
            for path in sorted((ROOT / "tml").rglob("*.py"))
            for match in HINT.finditer(_strings(path))]


def test_the_distribution_is_installed_under_its_own_name() -> None:
    assert _normal(NAME) != "tml"  # the index's tml is a translation SDK
    installed = importlib.metadata.packages_distributions()["tml"]
    assert NAME in installed
    metadata = importlib.metadata.metadata(NAME)
    assert metadata["Name"] == NAME
    # The test extra asks for the others by this name (pip would fetch "tml" otherwise).
    assert any(requirement.startswith(f"{NAME}[") and "extra == \"test\"" in requirement
               for requirement in importlib.metadata.requires(NAME) or [])


def test_every_install_hint_in_the_code_names_this_distribution() -> None:
    dependencies = {_normal(re.split(r"[\s<>=!~;\[]", requirement, maxsplit=1)[0])
                    for requirement in importlib.metadata.requires(NAME) or []
                    if "extra ==" not in requirement}
    extras = set(importlib.metadata.metadata(NAME).get_all("Provides-Extra") or [])
    hints = _code_hints()
    assert "pyserial" in {name for _, name, _ in hints}  # a hint over several lines is read
    ours = [(where, name, wanted) for where, name, wanted in hints if name != "."]
    assert len([h for h in ours if _normal(h[1]) == _normal(NAME)]) >= 2
    for where, name, wanted in ours:
        # tml itself by its distribution name, or a dependency it declares (pyserial).
        assert _normal(name) == _normal(NAME) or _normal(name) in dependencies, (where, name)
        assert set(filter(None, wanted.split(","))) <= extras, (where, wanted)


def test_the_readme_and_docs_install_this_distribution_or_the_checkout() -> None:
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    hints = _hints(pages)
    assert hints
    for where, name, _ in hints:
        assert name == "." or _normal(name) == _normal(NAME), (where, name)
    text = "\n".join(page.read_text("utf-8") for page in pages)
    assert not re.search(r"(?<![\w-])tml\[", text)  # tml[serve] is the other project's


def test_a_missing_serve_extra_is_said_with_the_distribution_name(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from tml.commands.cli import main

    monkeypatch.setitem(__import__("sys").modules, "uvicorn", None)  # not installed
    assert main(["serve", "--sim"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("tml serve: uvicorn is missing") and "Traceback" not in err
    assert f"pip install '{NAME}[serve]'" in err


def test_a_missing_postgresql_extra_is_said_with_the_distribution_name(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from tml.serve.storage import Storage, StorageError

    monkeypatch.setitem(__import__("sys").modules, "psycopg", None)  # not installed
    with pytest.raises(StorageError) as raised:
        Storage("postgresql+psycopg://user@127.0.0.1:1/tml")
    assert f"pip install '{NAME}[postgresql]'" in str(raised.value)


def test_every_package_of_the_source_tree_is_in_the_distribution() -> None:
    """A package left out of pyproject.toml's list works in an editable install (the
    source tree is on the path) and is missing from every wheel: ``pip install .`` then
    fails at its first import."""
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))
                 ["tool"]["setuptools"]["packages"])
    found = {".".join(init.parent.relative_to(ROOT).parts)
             for top in ("tml", "sitl") for init in (ROOT / top).rglob("__init__.py")}
    assert found - listed == set(), "packages not in pyproject.toml's list"
