"""Hardened reading of mission and world files, and building the model from them.

Reading is defensive because mission files come from anywhere: the bytes must be UTF-8,
no DOCTYPE is accepted (so no entity expansion, no external entities, no network or file
access from the document), and size and nesting depth are bounded. Each of those problems,
an empty file, or XML that is not well-formed gives one :class:`MissionSyntaxError` that
says where, never a traceback.

lxml reports an element's line only (and the line of the *end* of its start tag), so the
text is scanned once for start tags in document order; the i-th start tag is the i-th
element, which gives every element and attribute an exact line and column.

Building the model assumes the document passed the XML Schema (:mod:`tml.schema`); what the
schema cannot express is reported as diagnostics by the builder (structure found while
building) and by :mod:`tml.check` (everything else).
"""

from __future__ import annotations

import bisect
import functools
import re
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from tml import geo
from tml.diagnostics import Diagnostic, error
from tml.errors import Location, MissionSyntaxError
from tml.model import (
    Action,
    Argument,
    Comparison,
    Composition,
    Condition,
    ConditionKind,
    Dispatch,
    Event,
    EventTrigger,
    Loop,
    Mission,
    ParameterDeclaration,
    Region,
    Role,
    Skill,
    Task,
    Termination,
    TerminationMode,
)
from tml.world import Cylinder, Geofence, Home, Prism, World, WorldObject

MAX_BYTES = 8 * 1024 * 1024
MAX_DEPTH = 64

_MARKUP = re.compile(
    r"<!--.*?-->|<!\[CDATA\[.*?\]\]>|<\?.*?\?>|<!DOCTYPE|<(?P<tag>[A-Za-z_][\w.\-:]*)",
    re.S,
)
_ATTRIBUTE = re.compile(r"""\s+([^\s=/>]+)\s*=\s*(?:"[^"]*"|'[^']*')""")
_ENCODING_DECL = re.compile(rb"^\s*<\?xml[^>]*encoding\s*=\s*[\"']([^\"']+)[\"']")


@dataclass
class XmlDocument:
    """A parsed, safe XML document with exact positions of elements and attributes."""

    file: str
    text: str
    root: etree._Element
    # Each element's start tag: character offset, line and column (found in one sweep).
    _starts: dict[etree._Element, tuple[int, int, int]] = field(repr=False)

    @functools.cached_property
    def _line_starts(self) -> list[int]:
        # Only attribute positions need it, and only for files with problems.
        return [0] + [m.end() for m in re.finditer("\n", self.text)]

    def location_of_offset(self, offset: int) -> Location:
        """Line and column (1-based, in characters) of a character offset in the text."""
        index = bisect.bisect_right(self._line_starts, offset) - 1
        return Location(self.file, index + 1, offset - self._line_starts[index] + 1)

    def location(self, element: etree._Element, attribute: str | None = None) -> Location:
        """Where an element's start tag (or one of its attributes) begins."""
        found = self._starts.get(element)
        if found is None:
            return Location(self.file, element.sourceline or 0, 0)
        start, line, column = found
        if attribute is not None:
            offset = _attribute_offset(self.text, start, attribute)
            if offset is not None:
                return self.location_of_offset(offset)
        return Location(self.file, line, column)

    def element_at(self, xpath: str) -> etree._Element | None:
        """The element an lxml error path (``/mission/task[2]``) names, if any."""
        try:
            found = self.root.getroottree().xpath(xpath)
        except etree.XPathError:
            return None
        return found[0] if found and isinstance(found[0], etree._Element) else None


_TAG_NAME = re.compile(r"<[A-Za-z_][\w.\-:]*")


def _attribute_offset(text: str, start: int, attribute: str) -> int | None:
    """Offset of ``attribute``'s name in the start tag that begins at ``start``, if written."""
    tag = _TAG_NAME.match(text, start)
    if tag is None:
        return None
    # Walk the start tag attribute by attribute, so that a ">" or a name inside an earlier
    # quoted value is not taken for the end of the tag or for the attribute.
    position = tag.end()
    while match := _ATTRIBUTE.match(text, position):
        if match.group(1) == attribute:
            return match.start(1)
        position = match.end()
    return None


def attribute_location(text: str, element: Location, attribute: str) -> Location:
    """Where ``attribute`` is written in the start tag at ``element`` (the location of its
    ``<`` in ``text``, the whole document); ``element`` itself if the attribute is not there.

    For stages that hold only the model and the source text, such as the semantic checks.
    """
    start = 0
    for _ in range(element.line - 1):
        start = text.find("\n", start) + 1
        if start == 0:
            return element
    offset = _attribute_offset(text, start + element.column - 1, attribute)
    if offset is None:
        return element
    line_start = text.rfind("\n", 0, offset) + 1
    return Location(element.file, element.line + text.count("\n", start, line_start),
                    offset - line_start + 1)


def read_xml(source: str | Path, data: bytes | None = None) -> XmlDocument:
    """Read a file (or ``data`` under the name ``source``) safely into an :class:`XmlDocument`.

    Raises :class:`MissionSyntaxError` (with file:line:column and a code) for empty input,
    input that is too large, not UTF-8, has a DOCTYPE, is not well-formed, or nests too deep.
    """
    file = str(source)
    if data is None:
        data = Path(source).read_bytes()
    start = Location(file, 1, 1)
    if len(data) > MAX_BYTES:
        raise MissionSyntaxError(
            f"file is {len(data)} bytes; mission files are limited to {MAX_BYTES} bytes",
            start, "E005")
    if not data.strip():
        raise MissionSyntaxError("file is empty; expected a <mission> document", start, "E001")
    text = _decode(file, data)

    def at(offset: int) -> Location:
        line_start = text.rfind("\n", 0, offset) + 1
        return Location(file, text.count("\n", 0, offset) + 1, offset - line_start + 1)

    tags: list[tuple[int, int, int]] = []  # offset, line, column of each start tag
    line, previous = 1, 0
    for match in _MARKUP.finditer(text):
        if match.group("tag"):
            offset = match.start()
            line += text.count("\n", previous, offset)  # counted in C, tag to tag
            previous = offset
            tags.append((offset, line, offset - text.rfind("\n", 0, offset)))
        elif match.group(0) == "<!DOCTYPE":
            raise MissionSyntaxError(
                "DOCTYPE declarations are not accepted (no DTDs or entities in mission files)",
                at(match.start()), "E003")
    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, dtd_validation=False,
        huge_tree=False, remove_blank_text=False, collect_ids=False,
    )
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        line, column = exc.position if exc.position else (1, 0)
        message = re.sub(r", line \d+, column \d+$", "", exc.msg or "not well-formed")
        raise MissionSyntaxError(f"not well-formed XML: {message}",
                                 Location(file, line, column), "E002") from None
    elements = list(root.iter(etree.Element))
    starts = dict(zip(elements, tags, strict=False)) if len(elements) == len(tags) else {}
    depths = {root: 0}
    for element in elements:
        parent = element.getparent()
        depth = depths[element] = depths[parent] + 1 if parent is not None else 0
        if depth >= MAX_DEPTH:
            where = starts.get(element)
            raise MissionSyntaxError(
                f"elements nest {depth + 1} deep; the limit is {MAX_DEPTH}",
                Location(file, where[1], where[2]) if where
                else Location(file, element.sourceline or 1, 0), "E006")
    return XmlDocument(file, text, root, starts)


def _decode(file: str, data: bytes) -> str:
    if data.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in data[:4]:
        raise MissionSyntaxError("file is UTF-16; mission files must be UTF-8",
                                 Location(file, 1, 1), "E004")
    declared = _ENCODING_DECL.match(data)
    if declared and declared.group(1).decode("ascii", "replace").lower() not in (
            "utf-8", "utf8", "us-ascii", "ascii"):
        raise MissionSyntaxError(
            f"file declares encoding {declared.group(1).decode('ascii', 'replace')!r}; "
            "mission files must be UTF-8", Location(file, 1, 1), "E004")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise MissionSyntaxError(
            f"byte 0x{data[exc.start]:02x} is not UTF-8; mission files must be UTF-8",
            Location(file, line, column), "E004") from None


# --- model building ------------------------------------------------------------------------


class _Builder:
    """Turns a schema-valid document into the model, collecting structural diagnostics."""

    def __init__(self, doc: XmlDocument) -> None:
        self.doc = doc
        self.diagnostics: list[Diagnostic] = []
        self._children: dict[etree._Element, dict[str, list[etree._Element]]] = {}

    def loc(self, element: etree._Element, attribute: str | None = None) -> Location:
        return self.doc.location(element, attribute)

    def children(self, element: etree._Element, tag: str) -> list[etree._Element]:
        groups = self._children.get(element)
        if groups is None:  # group once: the builder asks each element for several tags
            groups = self._children[element] = {}
            for child in element:
                groups.setdefault(child.tag, []).append(child)
        return groups.get(tag, [])

    def mission(self, root: etree._Element) -> Mission:
        world: World | None = None
        for env in self.children(root, "environment"):
            if world is not None:
                self.diagnostics.append(error(
                    self.loc(env), "E252", "a mission has at most one <environment> block",
                    "merge the blocks into one"))
                continue
            world = self.world(env)
        events: list[Event] = []
        for handling in self.children(root, "event_handling"):
            events.extend(self.event(e) for e in self.children(handling, "event"))
        roles = tuple(self.role(r, world.home if world else None)
                      for block in self.children(root, "roles")
                      for r in self.children(block, "role"))
        # With a single role, every task is flown by it unless it says otherwise.
        default_role = roles[0].name if len(roles) == 1 else None
        return Mission(
            name=root.get("name", ""),
            location=self.loc(root),
            tasks=tuple(self.task(t, (), Dispatch.COMMAND, default_role)
                        for t in self.children(root, "task")),
            skills=tuple(self.skill(s) for s in self.children(root, "skill")),
            events=tuple(events),
            parameters=tuple(
                ParameterDeclaration(p.get("name", "").strip(), p.get("type", "string"),
                                     self.loc(p),
                                     p.get("description", ""))
                for p in self.children(root, "parameter")),
            world=world,
            source=self.doc.text,
            roles=roles,
        )

    def role(self, element: etree._Element, home: Home | None) -> Role:
        region: Region | None = None
        for block in self.children(element, "region"):
            for shape in block:
                if shape.tag == "circle":
                    region = Region((self.point(shape, home),), self.loc(shape),
                                    float(shape.get("radius", "0")))
                elif shape.tag == "polygon":
                    region = Region(tuple(self.point(p, home)
                                          for p in self.children(shape, "point")),
                                    self.loc(shape))
        kind = element.get("type")
        return Role(
            name=element.get("name", "").strip(),
            location=self.loc(element),
            count=int(element.get("count", "1")),
            vehicle_type=kind.strip() if kind else None,
            payloads=tuple(p.get("name", "").strip()
                           for p in self.children(element, "payload")),
            region=region,
            pick_timeout=float(element.get("pick_timeout", "30")),
        )

    def skill(self, element: etree._Element) -> Skill:
        return Skill(element.get("name", "").strip(), self.loc(element))

    def task(self, element: etree._Element, parent: tuple[str, ...],
             inherited: Dispatch, inherited_role: str | None = None) -> Task:
        name = element.get("name", "").strip()
        path = (*parent, name)
        dispatch = Dispatch(element.get("dispatch", inherited.value))
        written_role = element.get("role")
        role = written_role.strip() if written_role is not None else inherited_role
        skills: list[Skill] = []
        conditions: list[Condition] = []
        repeats: list[etree._Element] = []
        action: Action | None = None
        children: list[Task] = []
        gates: dict[str, list[etree._Element]] = {}
        handlers: list[Task] = []
        for child in element:  # one pass: tasks are the bulk of a mission
            tag = child.tag
            if tag == "task":
                children.append(self.task(child, path, dispatch, role))
            elif tag == "action":
                action = self.action(child)
            elif tag == "condition":
                conditions.append(self.condition(child))
            elif tag == "skill":
                skills.append(self.skill(child))
            elif tag == "repeat":
                repeats.append(child)
            elif tag in ("wait_for", "until", "loop"):
                gates.setdefault(tag, []).append(child)
            elif tag == "on_error":
                handlers.extend(self.task(t, path, dispatch, role)
                                for t in self.children(child, "task"))
        for extra in repeats[1:]:
            self.diagnostics.append(error(
                self.loc(extra), "E251", f"task {name!r} has more than one <repeat>",
                "keep one <repeat times=...>"))
        for tag, found in gates.items():
            for extra in found[1:]:
                self.diagnostics.append(error(
                    self.loc(extra), "E251", f"task {name!r} has more than one <{tag}>",
                    f"put all the conditions in one <{tag}>: they must all hold"))
        for tag in ("wait_for", "until"):
            found = gates.get(tag, [])
            if found and not self.children(found[0], "condition"):
                self.diagnostics.append(error(
                    self.loc(found[0]), "E282",
                    f"<{tag}> in task {name!r} has no condition",
                    "it would " + ("wait for nothing" if tag == "wait_for" else
                                   "stop the task at once") + "; give it a <condition> "
                    "or remove it"))
        if repeats and "loop" in gates:
            self.diagnostics.append(error(
                self.loc(gates["loop"][0]), "E251",
                f"task {name!r} has both <repeat> and <loop>",
                "keep <repeat times=...> for a count, or <loop> for while/forever"))

        def conditions_of(tag: str) -> tuple[Condition, ...]:
            found = gates.get(tag)
            return tuple(self.condition(c) for c in self.children(found[0], "condition")) \
                if found else ()

        loops = gates.get("loop")
        limit = element.get("time_limit")
        release = element.get("release")
        return Task(
            name=name,
            path=path,
            location=self.loc(element),
            skills=tuple(skills),
            conditions=tuple(conditions),
            repeat=int(repeats[0].get("times", "1")) if repeats else 1,
            repeat_location=self.loc(repeats[0], "times") if repeats else None,
            action=action,
            children=tuple(children),
            dispatch=dispatch,
            role=role,
            role_location=self.loc(element, "role") if written_role is not None else None,
            composition=Composition(element.get("composition", "sequence").strip()),
            wait_for=conditions_of("wait_for"),
            until=conditions_of("until"),
            time_limit=float(limit) if limit is not None else None,
            on_error=tuple(handlers),
            loop=Loop(conditions_of("loop"), self.loc(loops[0])) if loops else None,
            release=tuple(release.split()) if release else (),
            release_location=self.loc(element, "release") if release is not None else None,
        )

    def action(self, element: etree._Element) -> Action:
        arguments = []
        for arg in element:  # the schema allows only <argument> children here
            value, label = arg.get("value"), arg.get("label")
            if (value is None) == (label is None):
                which = "both" if value is not None else "neither"
                self.diagnostics.append(error(
                    self.loc(arg), "E213",
                    f"argument {arg.get('name')!r} has {which} of value= and label=",
                    "give value= for a literal, or label= for a memorized point"))
            arguments.append(Argument(arg.get("name", "").strip(), value,
                                      label.strip() if label else label, self.loc(arg)))
        return Action(element.get("name", "").strip(), tuple(arguments), self.loc(element))

    def condition(self, element: etree._Element) -> Condition:
        given = [(a, element.get(a)) for a in ("parameter", "label", "current_task",
                                               "currentTask") if element.get(a) is not None]
        if len(given) != 1:
            self.diagnostics.append(error(
                self.loc(element), "E220",
                "a condition reads exactly one of parameter=, label= or current_task=; "
                f"this one has {len(given) or 'none'}"
                + (f" ({', '.join(a for a, _ in given)})" if given else ""),
                'e.g. <condition parameter="BATTERY_CHARGE_PERCENTAGE" '
                'comparison="less than" value="30"/>'))
        attribute, subject = given[0] if given else ("parameter", "")
        kind = {"parameter": ConditionKind.PARAMETER, "label": ConditionKind.LABEL}.get(
            attribute, ConditionKind.CURRENT_TASK)
        comparison = element.get("comparison")
        return Condition(
            kind=kind,
            subject=subject.strip(),
            comparison=Comparison(" ".join(comparison.split())) if comparison else None,
            value=element.get("value"),
            location=self.loc(element),
            role=element.get("role", "").strip() or None,
        )

    def event(self, element: etree._Element) -> Event:
        term = self.children(element, "termination")[0]
        return Event(
            name=element.get("name", "").strip(),
            conditions=tuple(self.condition(c) for c in self.children(element, "condition")),
            actions=tuple(self.action(a) for a in self.children(element, "action")),
            termination=Termination(TerminationMode(term.get("mode", "").strip()),
                                    self.loc(term), term.get("task")),
            location=self.loc(element),
            trigger=EventTrigger(element.get("trigger", "edge").strip()),
            role=element.get("role", "").strip() or None,
        )

    # --- environment -----------------------------------------------------------------------

    def world(self, element: etree._Element) -> World:
        homes = self.children(element, "home")
        for extra in homes[1:]:
            self.diagnostics.append(error(self.loc(extra), "E253",
                                          "more than one <home>", "keep one"))
        home = None
        if homes:
            h = homes[0]
            home = Home(float(h.get("latitude")), float(h.get("longitude")),
                        float(h.get("altitude")), float(h.get("heading", "0")), self.loc(h))
        fences = self.children(element, "geofence")
        for extra in fences[1:]:
            self.diagnostics.append(error(self.loc(extra), "E253",
                                          "more than one <geofence>", "keep one"))
        geofence = None
        if fences:
            f = fences[0]
            polygon = tuple(self.point(p, home) for p in self.children(f, "point"))
            if 0 < len(polygon) < 3:
                self.diagnostics.append(error(
                    self.loc(f), "E253",
                    f"a geofence polygon needs at least 3 points; this one has {len(polygon)}",
                    "give 3 or more <point>s, or none for altitude limits only"))
            low, high = _optional_float(f.get("min_altitude")), _optional_float(
                f.get("max_altitude"))
            if low is not None and high is not None and low >= high:
                self.diagnostics.append(error(
                    self.loc(f, "min_altitude"), "E253",
                    f"min_altitude {low:g} m is not below max_altitude {high:g} m"))
            geofence = Geofence(polygon, low, high, self.loc(f))
        obstacles: list[Cylinder | Prism] = []
        objects: list[WorldObject] = []
        for child in element:
            if child.tag == "cylinder":
                north, east = self.point(child, home)
                obstacles.append(Cylinder(
                    child.get("name", f"cylinder at line {child.sourceline}"), north, east,
                    float(child.get("radius")), float(child.get("bottom", "0")),
                    self.top(child), self.loc(child)))
            elif child.tag == "prism":
                obstacles.append(Prism(
                    child.get("name", f"prism at line {child.sourceline}"),
                    tuple(self.point(p, home) for p in self.children(child, "point")),
                    float(child.get("bottom", "0")), self.top(child), self.loc(child)))
            elif child.tag == "object":
                north, east = self.point(child, home)
                objects.append(WorldObject(
                    child.get("kind"), child.get("id").strip(), north, east,
                    float(child.get("altitude", "0")), child.get("color", ""),
                    child.get("name", ""), self.loc(child)))
        return World(home, geofence, tuple(obstacles), tuple(objects), self.loc(element))

    def top(self, element: etree._Element) -> float:
        top = _optional_float(element.get("top"))
        bottom = float(element.get("bottom", "0"))
        if top is None:
            return float("inf")
        if top <= bottom:
            self.diagnostics.append(error(
                self.loc(element, "top"), "E253",
                f"top {top:g} m is not above bottom {bottom:g} m"))
        return top

    def point(self, element: etree._Element, home: Home | None) -> tuple[float, float]:
        local = element.get("north") is not None or element.get("east") is not None
        world = element.get("latitude") is not None or element.get("longitude") is not None
        if local == world:
            self.diagnostics.append(error(
                self.loc(element), "E253",
                f"<{element.tag}> needs either north= and east= (metres from home) or "
                "latitude= and longitude=, not " + ("both" if local else "neither")))
            return (0.0, 0.0)
        names = ("north", "east") if local else ("latitude", "longitude")
        missing = [n for n in names if element.get(n) is None]
        if missing:
            self.diagnostics.append(error(
                self.loc(element), "E253", f"<{element.tag}> is missing {missing[0]}="))
            return (0.0, 0.0)
        if local:
            return float(element.get("north")), float(element.get("east"))
        if home is None:
            self.diagnostics.append(error(
                self.loc(element, "latitude"), "E253",
                "latitude/longitude positions need a <home> in the same block",
                "add <home latitude=... longitude=... altitude=.../>"))
            return (0.0, 0.0)
        north, east, _ = geo.to_local(float(element.get("latitude")),
                                      float(element.get("longitude")), home.altitude,
                                      home.latitude, home.longitude, home.altitude)
        return north, east


def _optional_float(text: str | None) -> float | None:
    return None if text is None else float(text)


def build_mission(doc: XmlDocument) -> tuple[Mission, list[Diagnostic]]:
    """The model of a schema-valid mission document, and structural diagnostics."""
    builder = _Builder(doc)
    mission = builder.mission(doc.root)
    return mission, builder.diagnostics


def build_world(doc: XmlDocument) -> tuple[World, list[Diagnostic]]:
    """The model of a schema-valid world document, and structural diagnostics."""
    builder = _Builder(doc)
    return builder.world(doc.root), builder.diagnostics


def load_world(path: str | Path) -> World:
    """Read, schema-validate and build a world file; raises :class:`MissionSyntaxError`
    (schema or structure problems, the first one, with the count) on bad input."""
    from tml import schema  # tml.schema imports this module

    doc = read_xml(path)
    problems = schema.validate(doc, "world")
    world, structural = (None, []) if problems else build_world(doc)
    problems += structural
    errors = [d for d in problems if d.is_error]
    if errors or world is None:
        first = errors[0]
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        raise MissionSyntaxError(first.message + more, first.location, first.code)
    return world
