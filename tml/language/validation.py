"""The validation pipeline: safe read, XML Schema, model building, semantic checks.

Every finding is reported in one round, the schema's and the language's together, where
the schema's leave the language's meaningful. A mission the schema refuses is still built,
leniently (:mod:`tml.language.build`: the elements out of place left out, the values
refused read as absent or their defaults), and checked; of the findings on that model,
those that could be an echo of what the schema refused are dropped:

- a finding on an element the schema refused a value or a child of (E102, E104, E105), or
  an attribute that looks like a misspelt one (E103), that the refused part could cause
  (:data:`ECHOES`): a misspelt or refused comparison= is not also "no comparison", but the
  same condition's unknown parameter is still said;
- when an element was out of place (E101) and left out, or an attribute that names or
  declares what other parts read (a task's or a role's name, a label, a role, a parameter
  declaration) was refused, the findings that read the whole mission: references to tasks
  and labels, roles, declared parameters and orchestration (:data:`READS_THE_WHOLE`).

What is left is reported with the schema's findings, each at its file:line:column. A
document whose root is not the one expected (E007), or that is not XML, stops there.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from tml.errors import Location, MissionError, MissionSemanticError, MissionSyntaxError
from tml.language import build, check, schema, xml
from tml.language.diagnostics import Diagnostic, error, sort_key
from tml.language.model import Mission


@dataclass
class ValidationResult:
    """The outcome of validating one file."""

    file: str
    mission: Mission | None
    diagnostics: list[Diagnostic] = field(default_factory=list)
    source: str = ""

    @property
    def errors(self) -> list[Diagnostic]:
        """The diagnostics that are errors."""
        return [d for d in self.diagnostics if d.is_error]

    def valid(self, strict: bool = False) -> bool:
        """No errors (and, when strict, no warnings either)."""
        return not (self.diagnostics if strict else self.errors)


def validate_file(path: str | Path, data: bytes | None = None,
                  root: str | None = "mission") -> ValidationResult:
    """Validate one mission file (``root="world"``: one world file, whose result holds no
    mission; ``root=None``: a world file when its root element is ``<world>``, else a
    mission); I/O errors (missing file) raise OSError."""
    file = str(path)
    try:
        doc = xml.read_xml(file, data)
    except MissionSyntaxError as exc:
        location = exc.location or Location(file, 1, 1)
        source = "" if exc.code == "E005" else _text_of(path, data)
        hint = _plan_hint(path, data) if exc.code == "E002" else ""
        return ValidationResult(file, None, [error(location, exc.code, exc.message, hint)],
                                source)
    if root is None:  # the name as written, as xml.root_name reads it from the text
        written = etree.QName(doc.root).localname
        if doc.root.prefix:
            written = f"{doc.root.prefix}:{written}"
        root = "world" if written == "world" else "mission"
    problems = schema.problems(doc, root)
    if problems:
        found = [p.diagnostic for p in problems]
        if root == "mission":
            found += _beyond_the_schema(doc, problems)
        return ValidationResult(file, None, sorted(found, key=sort_key), doc.text)
    if root == "world":
        _, structural = build.build_world(doc)
        return ValidationResult(file, None, sorted(structural, key=sort_key), doc.text)
    mission, structural = build.build_mission(doc)
    found = structural + check.check(mission)
    return ValidationResult(file, mission, sorted(found, key=sort_key), doc.text)


READS_THE_WHOLE = frozenset({
    "E225", "E227", "W301", "E254",  # parameters, as the declarations and skills say
    "E230", "E231", "E232",  # labels, as the MEMORIZE_POINTs store them
    "E240", "E244", "W310",  # tasks named, as the tasks are
    "E253",  # latitude and longitude, from the <home>
    "E261", "E274", "E275", "E283", "W306",  # orchestration, as the tasks and roles are
    "E270", "E271", "W305",  # roles, as declared and flown
})
"""Codes of the semantic findings that read other parts of the mission than the element
they are reported on: kept beside schema findings only when those parts were built whole."""

_CONDITION_READ = frozenset({"E220", "E221", "E222", "E223", "E224", "E225", "E227", "W301",
                             "E230", "E232", "E240", "E244", "E275", "E281"})
ECHOES: dict[str, frozenset[str]] = {
    "comparison": frozenset({"E221", "E223", "E224"}),
    "value": frozenset({"E212", "E213", "E214", "E222", "E224"}),
    "parameter": _CONDITION_READ, "label": _CONDITION_READ | {"E213", "E214", "E231"},
    "current_task": _CONDITION_READ, "currentTask": _CONDITION_READ,
    "mode": frozenset({"E240", "E242", "E244", "E283", "W304"}),
    "task": frozenset({"E240", "E242", "E244", "W304"}),
    "times": frozenset({"E250"}),
    "dispatch": frozenset({"E260", "E261", "W307", "W308"}),
    "composition": frozenset({"E280", "E283", "W306"}),
    "role": frozenset({"E270", "E274", "E275"}),
    "release": frozenset({"E270"}),
    "trigger": frozenset(), "description": frozenset(),
    "time_limit": frozenset({"E255"}), "count": frozenset({"E255"}),
    "pick_timeout": frozenset({"E255"}), "radius": frozenset({"E253", "E255"}),
}
"""For an attribute the schema refused (or that is missing, or misspelt): the codes of the
semantic findings on its element that may only echo it. An attribute not listed (a name)
may cause any."""

NAMING = frozenset({("task", "name"), ("action", "name"), ("argument", "name"),
                    ("task", "role"), ("task", "release"),
                    ("task", "dispatch"), ("task", "composition"), ("role", "name"),
                    ("parameter", "name"), ("parameter", "type"), ("argument", "label"),
                    ("event", "role"), ("condition", "role")})
"""(element, attribute) whose value other parts of a mission read: a task's name for
current_task and JUMP_TO_TASK, a label for its readers, a role for its tasks ..."""


def _beyond_the_schema(doc: xml.XmlDocument,
                       problems: list[schema.SchemaProblem]) -> list[Diagnostic]:
    """The findings of the language's rules on a mission the schema refused, where they
    can be trusted (see the module's docstring)."""
    if any(p.diagnostic.code in ("E007", "E008") for p in problems):
        return []  # not a mission at all, or not a TML one
    left_out = frozenset(p.element for p in problems
                         if p.diagnostic.code == "E101" and p.element is not None)
    whole = not any(_breaks_the_whole(p) for p in problems)
    # The places (start tag, attributes) of the elements the schema refused part of, and
    # the codes that may echo it there (None: any).
    refused: dict[tuple[int, int], frozenset[str] | None] = {}
    refusals: list[tuple[etree._Element, frozenset[str] | None]] = []
    for problem in problems:
        element = problem.element
        if element is None:
            continue
        if problem.diagnostic.code != "E101":
            refusals.append((element, _echoes(problem)))
        parent = element.getparent()
        if parent is not None and (problem.diagnostic.code in ("E100", "E101")
                                   or xml.element_name(element) == "argument"):
            # What holds an element left out, or an argument refused, misses it: "WAIT
            # needs argument 'duration'" would only echo a misspelt <argumnt>.
            refusals.append((parent, None))
    for element, echoes in refusals:
        for attribute in (None, *(a for a in element.attrib if isinstance(a, str))):
            where = doc.location(element, attribute)
            key = (where.line, where.column)
            before = refused.get(key, frozenset())
            refused[key] = None if echoes is None or before is None else before | echoes
    try:
        mission, structural = build.build_mission(doc, lenient=True, left_out=left_out)
        found = structural + check.check(mission)
    except (ValueError, TypeError, LookupError, ArithmeticError, MissionError):
        # The schema's findings are the answer: a model built from what it refused may
        # break the builder or a check in a way no valid mission can; those findings
        # must not be lost to it.
        return []
    kept = []
    for diagnostic in found:
        place = (diagnostic.location.line, diagnostic.location.column)
        if place in refused and (refused[place] is None
                                 or diagnostic.code in (refused[place] or ())):
            continue
        if whole or diagnostic.code not in READS_THE_WHOLE:
            kept.append(diagnostic)
    return kept


def _breaks_the_whole(problem: schema.SchemaProblem) -> bool:
    """Whether the problem may leave the mission without what other parts read: an element
    left out or refused whole, or a name (or a misspelt name) refused."""
    if problem.element is None or problem.diagnostic.code in ("E100", "E101"):
        return True
    attribute = problem.meant if problem.diagnostic.code == "E103" else problem.attribute
    return (xml.element_name(problem.element), attribute) in NAMING


def _echoes(problem: schema.SchemaProblem) -> frozenset[str] | None:
    """The codes of the findings on the problem's element it may cause (None: any)."""
    code = problem.diagnostic.code
    if code == "E103":  # read by nobody, unless it is a misspelt attribute
        return ECHOES.get(problem.meant) if problem.meant else frozenset()
    if code in ("E104", "E105") and problem.attribute is not None:
        return ECHOES.get(problem.attribute)
    return None


def load_mission(path: str | Path) -> Mission:
    """A valid mission, or a :class:`MissionError` naming the first error and the count."""
    result = validate_file(path)
    if result.errors or result.mission is None:
        first = result.errors[0]
        more = f" (and {len(result.errors) - 1} more)" if len(result.errors) > 1 else ""
        kind = MissionSyntaxError if first.code < "E200" else MissionSemanticError
        raise kind(first.message + more, first.location, first.code)
    return result.mission


PLAN_SUFFIXES = (".plan", ".waypoints")
"""Suffixes of the plans ``tml import`` reads (QGroundControl's .plan, QGC WPL waypoint
files; a WPL file named .txt is known by its header)."""


def _plan_hint(path: str | Path, data: bytes | None) -> str:
    """For a file that is not XML but looks like a plan ``tml import`` reads (JSON, a QGC
    WPL header, a plan's suffix), the hint to import it; else ""."""
    import shlex

    try:
        raw = data if data is not None else xml.read_bounded(path)
    except (OSError, MissionSyntaxError):
        raw = b""
    start = raw.lstrip(b"\xef\xbb\xbf \t\r\n")
    suffix = Path(path).suffix.lower()
    command = f"tml import {shlex.quote(str(path))} -o " \
        f"{shlex.quote(Path(path).with_suffix('.xml').name)}"
    if start.startswith(b"{") and b'"Plan"' not in raw:
        return f"this is JSON, not a mission; if it is a QGroundControl plan, `{command}` " \
            "makes a mission of it"
    if start.startswith(b"{"):
        what = "a QGroundControl plan"
    elif start.startswith(b"QGC WPL"):
        what = "a QGC WPL waypoint file"
    elif suffix in PLAN_SUFFIXES:
        what = f"a {suffix} file"
    else:
        return ""
    return f"this looks like {what}, not a mission: `{command}` makes a mission of it"


def _text_of(path: str | Path, data: bytes | None) -> str:
    """The text of a file that failed to read as XML, for quoting its lines; "" for a file
    that is not XML at all (a password file, a binary), whose content is never quoted."""
    try:
        raw = data if data is not None else xml.read_bounded(path)
    except (OSError, MissionSyntaxError):
        return ""
    if b"\x00" in raw:  # UTF-16 and binary files: no source line is worth quoting
        return ""
    text = raw.decode("utf-8", "replace")
    return text if text.lstrip("\ufeff \t\r\n").startswith("<") else ""


__all__ = ["MissionError", "ValidationResult", "load_mission", "validate_file"]
