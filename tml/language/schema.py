"""XML Schema validation of mission and world files.

libxml2 (through lxml) validates: it is fast and reports every violation with its line and
element path. Its messages are then made precise: each becomes a diagnostic with a stable
code, placed on the offending attribute's column, with a hint listing what the schema
allows there (read from the XSD once with xmlschema) and a did-you-mean for near misses.

The XSD files ship inside the wheel as the package ``tml.schemas``; from a source checkout
that is not installed they are read from the repository's ``schemas/`` directory.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from tml.errors import Location
from tml.language.diagnostics import Diagnostic, error
from tml.language.xml import XmlDocument, element_name

ROOTS = {"mission": "tml.xsd", "world": "world.xsd"}
SCHEMA_FILES = ("tml.xsd", "world.xsd", "environment.xsd", "mavlink.xsd")
SCHEMA_LOCATION = "urn:tml:schemas:tml.xsd"
"""The stable name a mission may give its schema (``xsi:noNamespaceSchemaLocation``), for
editors that map it to the installed file through an XML catalog (``tml schema
--catalog``). tml itself validates with the shipped schema whatever a file names."""


def stable_location(name: str) -> str:
    """The stable name of a shipped XSD file (``urn:tml:schemas:world.xsd``)."""
    return SCHEMA_LOCATION.rsplit(":", 1)[0] + ":" + name


def schema_path(name: str = "tml.xsd") -> Path:
    """The path of a shipped XSD file (``tml.xsd``, ``world.xsd``, ``environment.xsd``,
    ``mavlink.xsd``)."""
    package = Path(__file__).resolve().parents[1]
    # Files first, as a wheel installs the package tml.schemas or a source checkout holds
    # them: importlib.resources, for any other way of installing, costs start-up time.
    for candidate in (package / "schemas" / name, package.parent / "schemas" / name):
        if candidate.is_file():
            return candidate
    import importlib.resources

    return Path(str(importlib.resources.files("tml.schemas") / name))


@functools.cache
def _lxml_schema(name: str) -> etree.XMLSchema:
    return etree.XMLSchema(etree.parse(str(schema_path(name))))


@functools.cache
def _vocabulary(name: str) -> dict[str, tuple[set[str], set[str]]]:
    """For each element name: (allowed attribute names, allowed child element names)."""
    # Slower to import; only needed when a file is invalid.
    from xmlschema import XMLSchema
    from xmlschema.validators import XsdComplexType, XsdElement, XsdGroup

    schema = XMLSchema(str(schema_path(name)))
    vocabulary: dict[str, tuple[set[str], set[str]]] = {}

    def visit(element: XsdElement, seen: set[int]) -> None:
        if id(element) in seen or element.name is None:
            return
        seen.add(id(element))
        attributes, children = vocabulary.setdefault(element.name, (set(), set()))
        element_type = element.type
        if not isinstance(element_type, XsdComplexType):
            return  # a simple type: text only, no attributes
        attributes.update(a for a in element_type.attributes if a)
        if element_type.has_complex_content() and isinstance(element_type.content, XsdGroup):
            for child in element_type.content.iter_elements():
                if isinstance(child, XsdElement) and child.name is not None:
                    children.add(child.name)
                    visit(child, seen)

    for element in schema.elements.values():
        visit(element, set())
    return vocabulary


@dataclass(frozen=True)
class SchemaProblem:
    """A schema violation: its diagnostic, the element it is about (None when libxml2 did
    not say) and the attribute (None for a problem with the element itself)."""

    diagnostic: Diagnostic
    element: etree._Element | None = None
    attribute: str | None = None
    meant: str | None = None  # an unknown attribute's likely meaning (did you mean ...?)


def validate(doc: XmlDocument, expected_root: str = "mission") -> list[Diagnostic]:
    """All schema violations of ``doc``, as diagnostics (empty when valid)."""
    return [problem.diagnostic for problem in problems(doc, expected_root)]


AEROSTACK_LATER = frozenset({"task_tree", "behavior", "recurrent_behavior"})
"""The elements of Aerostack's later, behaviour-tree mission format (not TML v1)."""


def problems(doc: XmlDocument, expected_root: str = "mission") -> list[SchemaProblem]:
    """All schema violations of ``doc``, each with where it is (empty when valid)."""
    root = doc.root
    name = element_name(root)
    # Searched by libxml2 (names in no namespace, in document order), not element by element.
    later = next(root.iter(*AEROSTACK_LATER), None)
    if expected_root == "mission" and later is not None:
        return [SchemaProblem(error(
            doc.location(later), "E008",
            f"<{element_name(later)}> is Aerostack's later mission format (a behaviour tree "
            "of <task_tree> and <behavior>), which tml does not read: its behaviours are "
            "those of Aerostack's own catalogue, with parameters and a coordinator TML has no "
            "counterpart for, so no mission could say the same",
            "tml reads TML v1 as Aerostack shipped it (<mission>, <task>, <action>, "
            "<event_handling>): write the tasks as <task> with one <action> each"))]
    if name != expected_root:
        other = "a world file" if name == "world" else f"<{name}>"
        return [SchemaProblem(error(doc.location(root), "E007",
                                    f"expected a <{expected_root}> document, found {other}",
                                    f"the root element must be <{expected_root}>"))]
    schema_name = ROOTS[expected_root]
    schema = _lxml_schema(schema_name)
    if schema.validate(root.getroottree()):
        return []
    found: list[SchemaProblem] = []
    seen: set[tuple[int, int, str]] = set()
    for entry in schema.error_log:
        problem = _translate(doc, entry, schema_name)
        location = problem.diagnostic.location
        key = (location.line, location.column, problem.diagnostic.code)
        if key not in seen:  # libxml2 reports a bad value twice (facet, then type)
            seen.add(key)
            found.append(problem)
    return found


_ATTRIBUTE = re.compile(r"^Element '([^']+)', attribute '([^']+)': (.*)$", re.S)
_ELEMENT = re.compile(r"^Element '([^']+)': (.*)$", re.S)


def _translate(doc: XmlDocument, entry: etree._LogEntry, schema_name: str) -> SchemaProblem:
    element = doc.element_at(entry.path) if entry.path else None
    message = entry.message.strip()
    match = _ATTRIBUTE.match(message)
    if match and element is not None:
        diagnostic = _attribute_problem(doc, element, match.group(2), match.group(3),
                                        schema_name)
        meant = re.match(r"did you mean '([^']+)'\?", diagnostic.hint) \
            if diagnostic.code == "E103" else None
        return SchemaProblem(diagnostic, element, match.group(2),
                             meant.group(1) if meant else None)
    match = _ELEMENT.match(message)
    if match and element is not None:
        required = re.search(r"The attribute '([^']+)' is required but missing",
                             match.group(2))
        return SchemaProblem(_element_problem(doc, element, match.group(2), schema_name),
                             element, required.group(1) if required else None)
    location = doc.location(element) if element is not None else Location(doc.file, entry.line)
    return SchemaProblem(error(location, "E100", message), element)


def _attribute_problem(doc: XmlDocument, element: etree._Element, attribute: str,
                       detail: str, schema_name: str) -> Diagnostic:
    import difflib  # here: a valid mission never needs it, so start-up does without

    name = element_name(element)
    allowed = sorted(_vocabulary(schema_name).get(name, (set(), set()))[0])
    if "is not allowed" in detail:
        guess = difflib.get_close_matches(attribute, allowed, n=1)
        hint = (f"did you mean {guess[0]!r}? " if guess else "") + \
            f"<{name}> accepts: {', '.join(allowed) or 'no attributes'}"
        return error(doc.location(element, attribute), "E103",
                     f"<{name}> has no attribute {attribute!r}", hint)
    if "is required but missing" in detail:
        return error(doc.location(element), "E104",
                     f"<{name}> is missing the required attribute {attribute!r}",
                     f'add {attribute}="..."')
    value = element.get(attribute, "")
    enumeration = re.search(r"set \{(.*)\}", detail)
    if enumeration:
        choices = re.findall(r"'([^']*)'", enumeration.group(1))
        guess = difflib.get_close_matches(value, choices, n=1)
        hint = (f"did you mean {guess[0]!r}? " if guess else "") + \
            "expected one of: " + ", ".join(choices)
        return error(doc.location(element, attribute), "E105",
                     f"<{name} {attribute}={value!r}> is not an accepted value", hint)
    expected = _expected_type(detail)
    return error(doc.location(element, attribute), "E105",
                 f"<{name} {attribute}={value!r}> is not {expected}",
                 f"give {attribute}= as {expected}")


_TYPE_WORDS = {
    "xs:double": "a number",
    "xs:integer": "a whole number",
    "LatitudeType": "a latitude in degrees, -90 to 90",
    "LongitudeType": "a longitude in degrees, -180 to 180",
    "PositiveType": "a number greater than 0",
    "NonNegativeType": "a number, 0 or more",
    "NameType": "a non-empty name",
    "MavCmdType": "a MAV_CMD of ArduPilot's dialect (MAV_CMD_DO_JUMP or DO_JUMP) or a "
                  "number from 0 to 65535",
    "MavFrameType": "a MAV_FRAME of ArduPilot's dialect (MAV_FRAME_GLOBAL_RELATIVE_ALT or "
                    "GLOBAL_RELATIVE_ALT) or a number",
}


def _expected_type(detail: str) -> str:
    atomic = re.search(r"(?:atomic|union) type '([^']+)'", detail)
    if atomic and atomic.group(1) in _TYPE_WORDS:
        return _TYPE_WORDS[atomic.group(1)]
    bound = re.search(r"\[facet '((?:min|max)\w+)'\].*'([^']+)'\)?\.?$", detail.strip())
    if bound:
        relation = {"maxInclusive": "at most", "minInclusive": "at least",
                    "minExclusive": "greater than", "maxExclusive": "less than"}
        return f"{relation.get(bound.group(1), 'within')} {bound.group(2)}"
    if "minLength" in detail or "pattern" in detail:
        return "a non-empty name"
    return "a valid value"


def _element_problem(doc: XmlDocument, element: etree._Element, detail: str,
                     schema_name: str) -> Diagnostic:
    import difflib  # here: a valid mission never needs it, so start-up does without

    name = element_name(element)
    parent = element.getparent()
    if "This element is not expected" in detail:
        context = element_name(parent) if parent is not None else ""
        allowed = sorted(_vocabulary(schema_name).get(context, (set(), set()))[1])
        guess = difflib.get_close_matches(name, allowed, n=1)
        expected = re.search(r"Expected is (?:one of )?\( ([^)]*) \)", detail)
        if expected:
            here = "expected here: " + expected.group(1)
        else:
            here = "nothing more is expected here"
        hint = (f"did you mean <{guess[0]}>? " if guess and guess[0] != name else "") + here
        if name == "action" and parent is not None and parent.tag == "task":
            hint = ("a terminal task holds exactly one <action>, after its skills, "
                    "repeat and conditions, and no sub-tasks")
        elif name == "task" and parent is not None and parent.tag == "task":
            hint = "a task holds either one <action> or sub-tasks, not both"
        return error(doc.location(element), "E101",
                     f"<{name}> is not allowed here (inside <{context}>)", hint)
    required = re.search(r"The attribute '([^']+)' is required but missing", detail)
    if required:
        return _attribute_problem(doc, element, required.group(1), detail, schema_name)
    if "Missing child element" in detail:
        if name == "task":
            return error(doc.location(element), "E102",
                         f"task {element.get('name', '')!r} holds neither an <action> "
                         "nor sub-tasks", "a terminal task holds one <action>; "
                         "a non-terminal task holds <task>s")
        if name == "mission":
            return error(doc.location(element), "E102", "the mission has no <task>",
                         "add at least one <task>")
        if name == "event":
            return error(doc.location(element), "E102",
                         f"event {element.get('name', '')!r} has no <termination>",
                         'end it with <termination mode="CONTINUE"/> (or another mode)')
        expected = re.search(r"Expected is (?:one of )?\( ([^)]*) \)", detail)
        return error(doc.location(element), "E102", f"<{name}> is missing child elements",
                     f"expected: {expected.group(1)}" if expected else "")
    return error(doc.location(element), "E100", f"<{name}>: {detail}")
