"""Every test the documentation names exists.

docs/*.md and README.md back their statements about outcomes, exit codes and safety
behaviour with the test that shows them, written as ``tests/test_x.py::test_name`` (a
parametrized case as ``test_name[id]``), and a later ``::test_other`` in the same table
cell or paragraph names another test of the same file. A name that is misspelt, or a
test renamed or removed, would leave a statement standing on nothing: this file parses
the named test files (with ast, nothing imported) and fails on any name they do not define.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCUMENTS = [*sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md"]

# A test file, optionally followed by ::name and a parametrize id; or ::test_name alone
# (a continuation naming another test of the last file of the same cell or paragraph;
# not C++'s Class::method, which docs quote from ArduPilot).
_REFERENCE = re.compile(
    r"(?P<file>tests/[\w/]+\.py)(?:::(?P<name>\w+)(?P<case>\[[^\]\n]*\])?)?"
    r"|(?<![\w:])::(?P<more>test\w*)(?P<more_case>\[[^\]\n]*\])?"
)
_FENCE = re.compile(r"^```")
_LIST_ITEM = re.compile(r"^\s*(?:[-*+]|\d+[.)])\s")


@dataclass(frozen=True)
class Reference:
    """One test named by a document, with where it is written."""

    document: str
    line: int
    file: str
    name: str | None  # None: the file alone is named
    case: str | None  # the parametrize id written in [..], without the brackets

    def __str__(self) -> str:
        named = f"{self.file}::{self.name}{'' if self.case is None else f'[{self.case}]'}"
        return f"{self.document}:{self.line}: {named if self.name else self.file}"


def segments(text: str) -> list[tuple[int, str]]:
    """The text cut where a continuation ``::name`` stops reaching back.

    A table row is cut at its ``|`` (each cell is a segment); prose is cut at blank lines
    and list items (each paragraph or item is a segment); a fenced code block is one
    segment. Each comes with the number of the line it starts on.
    """
    found: list[tuple[int, str]] = []
    paragraph: list[str] = []
    paragraph_start = 0
    in_fence = False

    def close() -> None:
        if paragraph:
            found.append((paragraph_start, "\n".join(paragraph)))
            paragraph.clear()

    for number, line in enumerate(text.splitlines(), start=1):
        if _FENCE.match(line):
            if not in_fence:
                close()
                paragraph_start = number
            paragraph.append(line)
            in_fence = not in_fence
            if not in_fence:
                close()
            continue
        if in_fence:
            paragraph.append(line)
        elif not line.strip():
            close()
        elif line.lstrip().startswith("|"):
            close()
            found.extend((number, cell) for cell in line.split("|"))
        else:
            if _LIST_ITEM.match(line):
                close()
            if not paragraph:
                paragraph_start = number
            paragraph.append(line)
    close()
    return found


def references(document: str, text: str) -> list[Reference]:
    """Every test file and test the text names, continuations resolved to their file."""
    found: list[Reference] = []
    for start, segment in segments(text):
        last_file: str | None = None
        for match in _REFERENCE.finditer(segment):
            file, name, case = match.group("file", "name", "case")
            if file is None:
                name, case = match.group("more", "more_case")
            line = start + segment.count("\n", 0, match.start())
            if file is None:
                # A bare ::name with no file before it in its cell or paragraph names
                # nothing findable: reported as such (file "").
                file = last_file or ""
            last_file = file
            found.append(Reference(document, line, file, name,
                                   None if case is None else case[1:-1]))
    return found


def _is_parametrize(decorator: ast.expr) -> bool:
    target = decorator.func if isinstance(decorator, ast.Call) else decorator
    return isinstance(target, ast.Attribute) and target.attr == "parametrize"


def _parametrized_fixtures(tree: ast.Module) -> set[str]:
    """Names of the module's fixtures declared with params= (each makes cases too)."""
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            for decorator in node.decorator_list:
                if isinstance(decorator, ast.Call) and any(
                        k.arg == "params" for k in decorator.keywords):
                    names.add(node.name)
    return names


@cache
def defined_tests(path: Path) -> dict[str, bool]:
    """The tests a file defines, each with whether it is parametrized.

    Module-level ``def test_*`` and ``test_*`` methods of ``class Test*``; a test is
    parametrized if a decorator is ``parametrize`` or it takes a fixture of the file (or
    of its conftest.py) declared with ``params=``.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    fixtures = _parametrized_fixtures(tree)
    conftest = path.parent / "conftest.py"
    if conftest.exists():
        fixtures |= _parametrized_fixtures(ast.parse(conftest.read_text(encoding="utf-8")))
    functions: list[ast.FunctionDef | ast.AsyncFunctionDef] = []
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            functions.append(node)
        elif isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
            functions.extend(n for n in node.body
                             if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef))
    return {
        f.name: any(_is_parametrize(d) for d in f.decorator_list)
        or any(a.arg in fixtures for a in f.args.args)
        for f in functions if f.name.startswith("test")
    }


def problem(reference: Reference, root: Path = ROOT) -> str | None:
    """Why the reference names nothing, or None if it names a test that exists."""
    if not reference.file:
        return (f"{reference}: ::{reference.name} has no test file before it"
                " in its cell or paragraph")
    if not (root / reference.file).is_file():
        return f"{reference}: no such file"
    if reference.name is None:
        return None
    tests = defined_tests(root / reference.file)
    if reference.name not in tests:
        return f"{reference}: {reference.file} defines no test {reference.name}"
    if reference.case is not None and not tests[reference.name]:
        return (f"{reference}: {reference.name} is not parametrized,"
                f" so it has no case [{reference.case}]")
    return None


def all_references() -> list[Reference]:
    return [r for d in DOCUMENTS
            for r in references(d.relative_to(ROOT).as_posix(), d.read_text(encoding="utf-8"))]


def test_every_test_the_docs_name_exists() -> None:
    problems = [p for r in all_references() if (p := problem(r)) is not None]
    assert not problems, "\n".join(problems)


def test_the_docs_name_tests() -> None:
    # The check above passes vacuously on a pattern that matches nothing.
    named = [r for r in all_references() if r.name is not None]
    assert len(named) >= 16
    assert any(r.case is not None for r in named)


# The checker itself.

_FAKE_TESTS = '''
import pytest

@pytest.fixture(params=["a", "b"])
def flavour(request):
    return request.param

def test_lands():
    pass

@pytest.mark.parametrize("link", ["udp", "udpin"])
def test_flies(link):
    pass

def test_tastes(flavour):
    pass

class TestGroup:
    def test_in_class(self):
        pass

def helper_not_a_test():
    pass
'''


@pytest.fixture
def fake_root(tmp_path: Path) -> Path:
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_fake.py").write_text(_FAKE_TESTS, encoding="utf-8")
    return tmp_path


def check(root: Path, text: str) -> list[str]:
    return [p for r in references("doc.md", text) if (p := problem(r, root)) is not None]


def test_the_checker_accepts_tests_that_exist(fake_root: Path) -> None:
    text = ("Lands (tests/test_fake.py::test_lands); also tests/test_fake.py::test_flies[udp],"
            " ::test_tastes[a] and ::test_in_class. The file tests/test_fake.py, not"
            " C++'s AP_Rally::calc_best_rally nor ::init.\n\n"
            "| a | tests/test_fake.py::test_flies[udpin], ::test_lands |\n")
    assert len(references("doc.md", text)) == 7
    assert check(fake_root, text) == []


@pytest.mark.parametrize(("text", "why"), [
    ("It lands (tests/test_fake.py::test_land).", "defines no test test_land"),
    ("tests/test_fake.py::test_lands, ::test_fly", "defines no test test_fly"),
    ("tests/test_fake.py::helper_not_a_test", "defines no test helper_not_a_test"),
    ("tests/test_fake.py::test_lands[udp]", "is not parametrized"),
    ("tests/test_missing.py::test_lands", "no such file"),
    ("tests/test_missing.py", "no such file"),
    ("It flies (::test_flies).", "has no test file before it"),
    ("| tests/test_fake.py::test_lands | ::test_flies |", "has no test file before it"),
    ("tests/test_fake.py::test_lands.\n\nAnd ::test_flies.", "has no test file before it"),
    ("- tests/test_fake.py::test_lands\n- and ::test_flies", "has no test file before it"),
], ids=["misspelt", "misspelt continuation", "not a test", "not parametrized",
        "no file", "no bare file", "bare continuation", "continuation across cells",
        "continuation across paragraphs", "continuation across list items"])
def test_the_checker_finds_a_name_that_does_not_exist(fake_root: Path, text: str, why: str) -> None:
    problems = check(fake_root, text)
    assert len(problems) == 1 and why in problems[0], problems
    assert problems[0].startswith("doc.md:")


def test_the_checker_tells_the_line(fake_root: Path) -> None:
    text = "Intro.\n\nFirst line of a paragraph,\nthen tests/test_fake.py::test_nope here.\n"
    assert check(fake_root, text) == [
        "doc.md:4: tests/test_fake.py::test_nope: tests/test_fake.py defines no test test_nope"]
