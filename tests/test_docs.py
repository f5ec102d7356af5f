"""docs/language.md and missions/ keep up with the language.

The reference must name every action, argument, skill, built-in parameter, termination
mode, comparison and schema element the code defines; every XML example in it must be
an excerpt of a file in missions/ (so the examples are validated with those files); and
the example missions together must use every action of the catalogue.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from lxml import etree

from tml.language import actions, parameters, skills
from tml.language.model import Comparison, TerminationMode
from tml.language.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
DOC_PATH = ROOT / "docs" / "language.md"
DOC = DOC_PATH.read_text(encoding="utf-8")
MISSIONS = ROOT / "missions"
XSD = "{http://www.w3.org/2001/XMLSchema}"

_CODE_SPANS = set(re.findall(r"`([^`\n]+)`", DOC))
_XML_BLOCK = re.compile(r"^```xml\n(.*?)^```", re.M | re.S)
_NAMES_FILE = re.compile(r"`(missions/[\w.\-]+\.xml)`")


def in_code(text: str) -> bool:
    """True if the doc writes ``text`` as inline code (`text`), as names must be."""
    return text in _CODE_SPANS


def schema_elements(name: str) -> list[str]:
    """Every element name an XSD file declares (top-level and local)."""
    tree = etree.parse(str(ROOT / "schemas" / name))
    return sorted({e.get("name") for e in tree.iter(f"{XSD}element") if e.get("name")})


@pytest.mark.parametrize("name", [a.name for a in actions.CATALOGUE])
def test_every_action_is_documented(name: str) -> None:
    assert f"#### {name}\n" in DOC, f"docs/language.md has no section '#### {name}'"


@pytest.mark.parametrize("alias", [a for s in actions.CATALOGUE for a in s.aliases])
def test_every_action_alias_is_documented(alias: str) -> None:
    assert in_code(alias)


@pytest.mark.parametrize(
    ("action", "argument"),
    [(a.name, s.name) for a in actions.CATALOGUE for s in a.arguments],
    ids=lambda v: v,
)
def test_every_argument_is_documented_under_its_action(action: str, argument: str) -> None:
    start = DOC.find(f"#### {action}\n")
    assert start >= 0, f"docs/language.md has no section '#### {action}'"
    end = DOC.find("\n#### ", start + 1)
    section = DOC[start:end if end >= 0 else len(DOC)]
    assert f"| `{argument}` |" in section, f"{action}'s table lacks argument {argument}"


@pytest.mark.parametrize("name", [s.name for s in skills.CATALOGUE]
                         + [a for s in skills.CATALOGUE for a in s.aliases])
def test_every_skill_is_documented(name: str) -> None:
    assert in_code(name)


@pytest.mark.parametrize("name", [p.name for p in parameters.BUILT_IN]
                         + [a for p in parameters.BUILT_IN for a in p.aliases])
def test_every_builtin_parameter_is_documented(name: str) -> None:
    assert in_code(name)


@pytest.mark.parametrize("mode", [m.value for m in TerminationMode])
def test_every_termination_mode_is_documented(mode: str) -> None:
    assert f"| `{mode}` |" in DOC, f"the termination modes table lacks {mode}"


@pytest.mark.parametrize("comparison", [c.value for c in Comparison])
def test_every_comparison_is_documented(comparison: str) -> None:
    assert f"| `{comparison}` |" in DOC, f"the comparisons table lacks {comparison!r}"


@pytest.mark.parametrize("element", schema_elements("tml.xsd")
                         + schema_elements("environment.xsd"))
def test_every_schema_element_is_documented(element: str) -> None:
    assert in_code(f"<{element}>"), f"docs/language.md never writes `<{element}>`"


def test_every_diagnostic_code_is_documented() -> None:
    sources = "".join((ROOT / "tml" / f).read_text(encoding="utf-8")
                      for f in ("language/xml.py", "language/build.py", "language/schema.py",
                                "language/check.py"))
    codes = set(re.findall(r'"([EW]\d{3})"', sources))
    assert codes, "no diagnostic codes found in the sources"
    missing = sorted(c for c in codes if f"| {c} |" not in DOC)
    assert not missing, f"codes without a row in docs/language.md: {missing}"


def xml_examples() -> list[tuple[int, str, str]]:
    """(line in the doc, preceding text, block) for every ```xml block."""
    found = []
    for match in _XML_BLOCK.finditer(DOC):
        line = DOC.count("\n", 0, match.start()) + 1
        before = DOC[:match.start()].rstrip("\n").rsplit("\n", 1)[-1]
        found.append((line, before, match.group(1)))
    return found


def test_the_doc_has_xml_examples() -> None:
    assert len(xml_examples()) >= 20


def excerpt_problem(block: str, file_lines: list[str]) -> str | None:
    """None if the non-blank lines of ``block`` appear verbatim, in order, in ``file_lines``;
    else the first line that does not."""
    lines = [s.rstrip() for s in file_lines]
    position = 0
    for wanted in (s.rstrip() for s in block.splitlines()):
        if not wanted:
            continue
        try:
            position = lines.index(wanted, position) + 1
        except ValueError:
            return wanted
    return None


def test_excerpt_check_keeps_order_and_indentation() -> None:
    text = ["<a>", "  <b/>", "  <c/>", "</a>"]
    assert excerpt_problem("<a>\n  <c/>\n</a>\n", text) is None
    assert excerpt_problem("  <c/>\n  <b/>\n", text) == "  <b/>"
    assert excerpt_problem("<b/>\n", text) == "<b/>"


@pytest.mark.parametrize(("line", "before", "block"),
                         [pytest.param(*e, id=f"docs line {e[0]}") for e in xml_examples()])
def test_xml_example_is_an_excerpt_of_a_mission(line: int, before: str, block: str) -> None:
    named = _NAMES_FILE.search(before)
    assert named, f"docs/language.md:{line}: the line before ```xml names no missions/ file"
    path = ROOT / named.group(1)
    assert path.is_file(), f"docs/language.md:{line}: {named.group(1)} does not exist"
    wrong = excerpt_problem(block, path.read_text(encoding="utf-8").splitlines())
    assert wrong is None, (f"docs/language.md:{line}: {wrong.strip()!r} is not in "
                           f"{named.group(1)} (verbatim, after the lines before it)")


def mission_files() -> list[Path]:
    return sorted(MISSIONS.glob("*.xml"))


def test_every_action_is_used_in_some_mission() -> None:
    used: set[str] = set()
    for path in mission_files():
        mission = validate_file(path).mission
        assert mission is not None, f"{path.name} does not validate"
        for _, action in mission.actions():
            spec = actions.lookup(action.name)
            if spec is not None:
                used.add(spec.name)
    missing = sorted({a.name for a in actions.CATALOGUE} - used)
    assert not missing, f"actions no file in missions/ uses: {missing}"


def test_used_in_lists_of_the_action_sections_are_true() -> None:
    """Each file an action's "Used in:" line names does use that action."""
    uses: dict[str, set[str]] = {}
    for path in mission_files():
        mission = validate_file(path).mission
        assert mission is not None
        for _, action in mission.actions():
            spec = actions.lookup(action.name)
            if spec is not None:
                uses.setdefault(spec.name, set()).add(f"missions/{path.name}")
    sections = re.findall(r"^#### (\w+)\n(.*?)(?=^#{2,4} |\Z)", DOC, re.M | re.S)
    checked = 0
    for name, body in sections:
        line = re.search(r"^- Used in: (.*)$", body, re.M)
        if line is None:
            continue
        claimed = set(_NAMES_FILE.findall(line.group(1)))
        wrong = sorted(claimed - uses.get(name, set()))
        assert not wrong, f"{name} is not used in {wrong}"
        checked += 1
    assert checked == len(actions.CATALOGUE)


def test_every_doc_mission_table_row_names_an_existing_file() -> None:
    named = set(_NAMES_FILE.findall(DOC))
    assert named
    absent = sorted(n for n in named if not (ROOT / n).is_file())
    assert not absent, f"docs/language.md names missing files: {absent}"


@pytest.mark.parametrize("page", ["run.md", "serve.md"])
def test_the_missions_the_run_and_serve_pages_name_are_files_the_suite_flies(page: str) -> None:
    # Their examples (the fence and rally points, the API's runs) name missions of missions/,
    # each validated and flown by tests/test_missions.py.
    text = (ROOT / "docs" / page).read_text(encoding="utf-8")
    named = set(re.findall(r"(missions/[\w.\-]+\.xml)", text))
    assert named, f"docs/{page} names no mission of missions/"
    for path in sorted(named):
        assert (ROOT / path).is_file(), f"docs/{page} names {path}, which does not exist"
