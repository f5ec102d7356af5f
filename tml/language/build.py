"""Building the model from a read mission or world document.

Building assumes the document passed the XML Schema (:mod:`tml.language.schema`); what the
schema cannot express is reported as diagnostics by the builder (structure found while
building) and by :mod:`tml.language.check` (everything else).

A document the schema refused is built too, leniently, so that the semantic checks can
report what else is wrong in the same round (:mod:`tml.language.validation` says which of
their findings are kept): the elements given as ``left_out`` (those out of place) are
skipped with everything in them, and a value the schema refused is read as absent or as
its default -- an optional number as absent, a required one as 0 (or the nearest bound of
its range), a word of a list as the default word -- without a diagnostic of the builder's
own, the schema's saying it already.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from lxml import etree

from tml import geo
from tml.errors import Location, MissionSyntaxError
from tml.language import schema
from tml.language.diagnostics import Diagnostic, error, printable
from tml.language.model import (
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
from tml.language.parameters import ParamType
from tml.language.quantities import RANGES, Quantity, out_of_range
from tml.language.xml import XmlDocument, element_name, read_xml

if TYPE_CHECKING:
    from tml.world import Geofence, Home, RallyPoint, TerrainSource, World


E = TypeVar("E", bound=StrEnum)
D = TypeVar("D")
N = TypeVar("N")


# Enum members read for every task or condition, bound once: reading a member from its
# class costs some 900 instructions more than reading a global (the enum class's lookup).
_SEQUENCE = Composition.SEQUENCE
_CONDITION_KINDS = {"parameter": ConditionKind.PARAMETER, "label": ConditionKind.LABEL}
_BY_CURRENT_TASK = ConditionKind.CURRENT_TASK


def _built(node: type[N], /, **fields: object) -> N:
    """``node(**fields)`` for a frozen dataclass of the model given every one of its fields.

    Its generated ``__init__`` sets each field through ``object.__setattr__`` (4 us for a
    task's 20, a sixth of building a mission): here the fields fill the new instance's
    ``__dict__`` in one step. tests/test_build.py checks that every node so built has all
    its fields and equals the one its ``__init__`` makes.
    """
    built = object.__new__(node)
    _set(built, "__dict__", fields)  # the keywords' own new dict, taken as it is
    return built


_set = object.__setattr__


class _Builder:
    """Turns a schema-valid document into the model, collecting structural diagnostics
    (a document the schema refused, leniently: see the module's docstring)."""

    def __init__(self, doc: XmlDocument, lenient: bool = False,
                 left_out: frozenset[etree._Element] = frozenset()) -> None:
        self.doc = doc
        self.lenient = lenient
        self.left_out = left_out
        self.diagnostics: list[Diagnostic] = []
        self._children: dict[etree._Element, dict[str, list[etree._Element]]] = {}
        # Where an element (or one of its attributes) is: asked for every node built.
        self.loc = doc.location
        self._starts = doc.starts

    def at(self, element: etree._Element) -> Location:
        """Where an element's start tag begins (``loc(element)``, in one step for the
        elements the read placed, which are all of them but in a document built apart)."""
        found = self._starts.get(element)
        return found[1] if found is not None else self.loc(element)

    def number(self, element: etree._Element, attribute: str, quantity: Quantity,
               default: str | None = None) -> float:
        """A number attribute (the schema requires it unless a default is given), bounded
        to its quantity's range: a value outside (NaN and INF too, which xs:double reads)
        is reported and taken as the nearest bound, so building goes on."""
        text = element.get(attribute, default) if default is not None \
            else element.get(attribute) if self.lenient else self.doc.required(element, attribute)
        bounds = RANGES[quantity]
        try:
            value = float(text) if text is not None else None
        except ValueError:
            if not self.lenient:
                raise
            value = None
        if value is None:  # refused by the schema, which says so: read as 0, in range
            return min(max(0.0, bounds.low), bounds.high)
        why = out_of_range(quantity, value)
        if why is None:
            return value
        self.diagnostics.append(error(
            self.loc(element, attribute), "E255",
            f"<{element_name(element)}> {attribute}={(text or '').strip()!r} {why}"))
        return min(max(value, bounds.low), bounds.high) if value == value else bounds.low

    def optional_number(self, element: etree._Element, attribute: str,
                        quantity: Quantity) -> float | None:
        """A number attribute that may be absent, bounded as :meth:`number` bounds it."""
        text = element.get(attribute)
        if text is None:
            return None
        if self.lenient:  # a value the schema refused is read as absent
            try:
                float(text)
            except ValueError:
                return None
        return self.number(element, attribute, quantity)

    def children(self, element: etree._Element, tag: str) -> list[etree._Element]:
        groups = self._children.get(element)
        if groups is None:  # group once: the builder asks each element for several tags
            groups = self._children[element] = {}
            for child in element:
                if child not in self.left_out:
                    groups.setdefault(element_name(child), []).append(child)
        return groups.get(tag, [])

    def text(self, element: etree._Element, attribute: str) -> str:
        """A text attribute the schema requires; leniently, "" when it is missing."""
        if self.lenient:
            return element.get(attribute, "")
        return self.doc.required(element, attribute)

    def word(self, kind: type[E], text: str | None, default: D) -> E | D:
        """The word ``text`` of the list ``kind`` (``default`` when absent); leniently,
        ``default`` for one the schema refused too."""
        if not text:
            return default
        try:
            return kind(" ".join(text.split()))
        except ValueError:
            if not self.lenient:
                raise
            return default

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
        command = Dispatch.COMMAND
        return Mission(
            name=root.get("name", ""),
            location=self.loc(root),
            tasks=tuple(self.task(t, (), command, default_role)
                        for t in self.children(root, "task")),
            skills=tuple(self.skill(s) for s in self.children(root, "skill")),
            events=tuple(events),
            parameters=tuple(
                ParameterDeclaration(p.get("name", "").strip(),
                                     self.word(ParamType, p.get("type"), ParamType.STRING).value,
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
                if shape in self.left_out:
                    continue
                if shape.tag == "circle":
                    region = Region((self.point(shape, home),), self.loc(shape),
                                    self.number(shape, "radius", Quantity.RADIUS, "0"))
                elif shape.tag == "polygon":
                    region = Region(tuple(self.point(p, home)
                                          for p in self.children(shape, "point")),
                                    self.loc(shape))
        kind = element.get("type")
        return Role(
            name=element.get("name", "").strip(),
            location=self.loc(element),
            count=int(self.number(element, "count", Quantity.COUNT, "1")),
            vehicle_type=kind.strip() if kind else None,
            payloads=tuple(p.get("name", "").strip()
                           for p in self.children(element, "payload")),
            region=region,
            pick_timeout=self.number(element, "pick_timeout", Quantity.DURATION, "30"),
        )

    def skill(self, element: etree._Element) -> Skill:
        return Skill(element.get("name", "").strip(), self.loc(element))

    def task(self, element: etree._Element, parent: tuple[str, ...],
             inherited: Dispatch, inherited_role: str | None = None) -> Task:
        name = element.get("name", "").strip()
        path = (*parent, name)
        written_dispatch = element.get("dispatch")
        dispatch = inherited if written_dispatch is None \
            else self.word(Dispatch, written_dispatch, inherited)
        written_role = element.get("role")
        role = written_role.strip() if written_role is not None else inherited_role
        skills: list[Skill] = []
        conditions: list[Condition] = []
        repeats: list[etree._Element] = []
        action: Action | None = None
        children: list[Task] = []
        gates: dict[str, list[etree._Element]] = {}
        handlers: list[Task] = []
        left_out = self.left_out
        for child in element:  # one pass: tasks are the bulk of a mission
            if left_out and child in left_out:
                continue
            tag = child.tag
            if tag == "task":
                children.append(self.task(child, path, dispatch, role))
            elif tag == "action":
                action = self.action(child)
            elif tag == "mission_item":
                action = self.mission_item(child)
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
        wait_for: tuple[Condition, ...] = ()
        until: tuple[Condition, ...] = ()
        loop: Loop | None = None
        if len(repeats) > 1 or gates:  # rare: most tasks have neither
            self.gates(name, repeats, gates)
            wait_for = self.conditions_of(gates, "wait_for")
            until = self.conditions_of(gates, "until")
            if "loop" in gates:
                loop = Loop(self.conditions_of(gates, "loop"), self.at(gates["loop"][0]))
        release = element.get("release")
        composition = element.get("composition")
        time_limit = element.get("time_limit")
        return _built(
            Task,
            name=name,
            path=path,
            location=self.at(element),
            skills=tuple(skills) if skills else (),
            conditions=tuple(conditions) if conditions else (),
            repeat=_whole(repeats[0].get("times", "1")) if repeats else 1,
            repeat_location=self.loc(repeats[0], "times") if repeats else None,
            repeat_frame=_whole(repeats[0].get("jump_frame", "0"))
            if repeats and repeats[0].get("jump_frame") is not None else None,
            action=action,
            children=tuple(children) if children else (),
            dispatch=dispatch,
            role=role,
            role_location=self.loc(element, "role") if written_role is not None else None,
            composition=_SEQUENCE if composition is None
            else self.word(Composition, composition, _SEQUENCE),
            wait_for=wait_for,
            until=until,
            time_limit=None if time_limit is None
            else self.optional_number(element, "time_limit", Quantity.DURATION),
            on_error=tuple(handlers) if handlers else (),
            loop=loop,
            release=tuple(release.split()) if release else (),
            release_location=self.loc(element, "release") if release is not None else None,
        )

    def gates(self, name: str, repeats: list[etree._Element],
              gates: dict[str, list[etree._Element]]) -> None:
        """E251 for a second <repeat> or gate of task ``name``, E282 for a gate without a
        condition."""
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

    def conditions_of(self, gates: dict[str, list[etree._Element]],
                      tag: str) -> tuple[Condition, ...]:
        """The conditions of a task's first gate ``tag`` (``()`` without one)."""
        found = gates.get(tag)
        return tuple(self.condition(c) for c in self.children(found[0], "condition")) \
            if found else ()

    def action(self, element: etree._Element) -> Action:
        arguments = []
        left_out = self.left_out
        for arg in element:  # the schema allows only <argument> children here
            if arg.tag != "argument" or (left_out and arg in left_out):
                continue
            value, label = arg.get("value"), arg.get("label")
            if (value is None) == (label is None):
                which = "both" if value is not None else "neither"
                self.diagnostics.append(error(
                    self.loc(arg), "E213",
                    f"argument {arg.get('name')!r} has {which} of value= and label=",
                    "give value= for a literal, or label= for a memorized point"))
            arguments.append(_built(Argument, name=arg.get("name", "").strip(), value=value,
                                    label=label.strip() if label else label,
                                    location=self.at(arg)))
        return _built(Action, name=element.get("name", "").strip(), arguments=tuple(arguments),
                      location=self.at(element))

    def mission_item(self, element: etree._Element) -> Action:
        """``<mission_item command=... frame=... param1=.../>``: the action MISSION_ITEM,
        each attribute one of its arguments (located at the attribute)."""
        arguments = tuple(Argument(name, value, None, self.loc(element, name))
                          for name in MISSION_ITEM_ATTRIBUTES
                          if (value := element.get(name)) is not None)
        return Action("MISSION_ITEM", arguments, self.loc(element))

    def condition(self, element: etree._Element) -> Condition:
        given = [(a, value) for a in ("parameter", "label", "current_task", "currentTask")
                 if (value := element.get(a)) is not None]
        if len(given) != 1:
            self.diagnostics.append(error(
                self.loc(element), "E220",
                "a condition reads exactly one of parameter=, label= or current_task=; "
                f"this one has {len(given) or 'none'}"
                + (f" ({', '.join(a for a, _ in given)})" if given else ""),
                'e.g. <condition parameter="BATTERY_CHARGE_PERCENTAGE" '
                'comparison="less than" value="30"/>'))
        attribute, subject = given[0] if given else ("parameter", "")
        kind = _CONDITION_KINDS.get(attribute, _BY_CURRENT_TASK)
        comparison = element.get("comparison")
        return _built(
            Condition,
            kind=kind,
            subject=subject.strip(),
            comparison=self.word(Comparison, comparison, None),
            value=element.get("value"),
            location=self.loc(element),
            role=element.get("role", "").strip() or None,
        )

    def event(self, element: etree._Element) -> Event:
        # An event without its <termination> (refused by the schema) goes on as CONTINUE.
        term = (self.children(element, "termination") or [element])[0]
        return Event(
            name=element.get("name", "").strip(),
            conditions=tuple(self.condition(c) for c in self.children(element, "condition")),
            actions=tuple(self.action(a) for a in self.children(element, "action")),
            termination=Termination(
                self.word(TerminationMode, term.get("mode"), TerminationMode.CONTINUE),
                self.loc(term), term.get("task") if term is not element else None),
            location=self.loc(element),
            trigger=self.word(EventTrigger, element.get("trigger", "edge"), EventTrigger.EDGE),
            role=element.get("role", "").strip() or None,
        )

    # --- environment -----------------------------------------------------------------------

    def world(self, element: etree._Element) -> World:
        # Imported here: a mission without an <environment> does without these classes,
        # whose creation is a tenth of the start-up of a one-file validation.
        from tml.world import (
            Cylinder,
            Geofence,
            Home,
            ItemAltitude,
            PlanSettings,
            Prism,
            RallyPoint,
            World,
            WorldObject,
        )

        homes = self.children(element, "home")
        for extra in homes[1:]:
            self.diagnostics.append(error(self.loc(extra), "E253",
                                          "more than one <home>", "keep one"))
        home = None
        if homes:
            h = homes[0]
            home = Home(self.number(h, "latitude", Quantity.LATITUDE),
                        self.number(h, "longitude", Quantity.LONGITUDE),
                        self.number(h, "altitude", Quantity.ALTITUDE),
                        self.number(h, "heading", Quantity.ANGLE, "0"), self.loc(h))
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
            low = self.optional_number(f, "min_altitude", Quantity.ALTITUDE)
            high = self.optional_number(f, "max_altitude", Quantity.ALTITUDE)
            if low is not None and high is not None and low >= high:
                self.diagnostics.append(error(
                    self.loc(f, "min_altitude"), "E253",
                    f"min_altitude {low:g} m is not below max_altitude {high:g} m"))
            geofence = Geofence(polygon, low, high, self.loc(f),
                                self.written(self.children(f, "point")))
        obstacles: list[Cylinder | Prism] = []
        objects: list[WorldObject] = []
        rally: list[RallyPoint] = []
        for child in element:
            if child in self.left_out:
                continue
            if child.tag == "cylinder":
                north, east = self.point(child, home)
                obstacles.append(Cylinder(
                    child.get("name", f"cylinder at line {child.sourceline}"), north, east,
                    self.number(child, "radius", Quantity.RADIUS),
                    self.number(child, "bottom", Quantity.ALTITUDE, "0"),
                    self.top(child), self.loc(child), self.written([child])))
            elif child.tag == "prism":
                obstacles.append(Prism(
                    child.get("name", f"prism at line {child.sourceline}"),
                    tuple(self.point(p, home) for p in self.children(child, "point")),
                    self.number(child, "bottom", Quantity.ALTITUDE, "0"), self.top(child),
                    self.loc(child), self.written(self.children(child, "point"))))
            elif child.tag == "object":
                north, east = self.point(child, home)
                objects.append(WorldObject(
                    self.text(child, "kind"), self.text(child, "id").strip(),
                    north, east,
                    self.number(child, "altitude", Quantity.ALTITUDE, "0"),
                    child.get("color", ""),
                    child.get("name", ""), self.loc(child)))
            elif child.tag == "rally":
                for p in self.children(child, "point"):
                    north, east = self.point(p, home)
                    rally.append(RallyPoint(
                        north, east, self.number(p, "altitude", Quantity.ALTITUDE),
                        self.loc(p), self.written([p])))
                    self.rally_point_fits(p, rally[-1], geofence)
        settings = self.children(element, "plan_settings")
        for extra in settings[1:]:
            self.diagnostics.append(error(self.loc(extra), "E253",
                                          "more than one <plan_settings>", "keep one"))
        plan_settings = None
        if settings:
            s = settings[0]
            numbers = [s.get(name) for name in ("firmware_type", "vehicle_type",
                                                "altitude_mode")]
            firmware, vehicle, mode = (None if n is None else _whole(n) for n in numbers)
            plan_settings = PlanSettings(
                firmware, vehicle,
                self.optional_number(s, "cruise_speed", Quantity.SPEED),
                self.optional_number(s, "hover_speed", Quantity.SPEED), mode,
                location=self.loc(s), ground_station=s.get("ground_station"),
                items=tuple(ItemAltitude(_whole(i.get("number", "1")), *(
                    _double(i.get(name))
                    for name in ("altitude", "altitude_mode", "amsl_above_terrain")))
                    for i in self.children(s, "item")))
        return World(home, geofence, tuple(obstacles), tuple(objects), self.loc(element),
                     tuple(rally), plan_settings, self.terrain(element))

    def terrain(self, element: etree._Element) -> TerrainSource | None:
        """The ``<terrain>`` named, resolved relative to the file; one that is not there is
        an error (it is read when the mission is verified)."""
        from tml.world import TerrainSource

        found = self.children(element, "terrain")
        for extra in found[1:]:
            self.diagnostics.append(error(self.loc(extra), "E253", "more than one <terrain>",
                                          "keep one: a directory holds several tiles"))
        if not found:
            return None
        source = (found[0].get("source") or "").strip()
        if not source:
            return None  # the schema says so
        path = Path(self.doc.file).parent / source
        try:
            path = path.resolve()
            why = "" if path.exists() else "no such file or directory"
        except (OSError, RuntimeError) as exc:  # a name too long, a loop of links
            why = getattr(exc, "strerror", None) or str(exc)
        if why:
            self.diagnostics.append(error(
                self.loc(found[0], "source"), "E253",
                f"terrain source '{printable(source)}': {why} ({printable(str(path))})",
                "give an SRTM .hgt tile, a GeoTIFF or a directory of them, relative to "
                "this file"))
        return TerrainSource(source, str(path), self.loc(found[0]))

    def rally_point_fits(self, element: etree._Element, point: RallyPoint,
                         geofence: Geofence | None) -> None:
        """A rally point outside the geofence is one the vehicle could never return to:
        its fence would stop it on the way (E253)."""
        from tml.world import inside

        if geofence is None:
            return
        if geofence.polygon and not inside(geofence.polygon, (point.north, point.east)):
            self.diagnostics.append(error(
                self.loc(element), "E253",
                f"rally point at north {point.north:g} m, east {point.east:g} m is outside "
                "the geofence", "move it inside the geofence polygon"))
        if geofence.max_altitude is not None and point.altitude > geofence.max_altitude:
            self.diagnostics.append(error(
                self.loc(element, "altitude"), "E253",
                f"rally point altitude {point.altitude:g} m is above the geofence's "
                f"max_altitude {geofence.max_altitude:g} m"))

    def top(self, element: etree._Element) -> float:
        top = self.optional_number(element, "top", Quantity.ALTITUDE)
        try:  # bounded where the obstacle reads it
            bottom = float(element.get("bottom", "0"))
        except ValueError:  # refused by the schema
            bottom = 0.0
        if top is None:
            return float("inf")
        if top <= bottom:
            self.diagnostics.append(error(
                self.loc(element, "top"), "E253",
                f"top {top:g} m is not above bottom {bottom:g} m"))
        return top

    def written(self, elements: Iterable[etree._Element]) -> tuple[tuple[float, float], ...]:
        """The latitudes and longitudes of ``elements`` as written, when every one is given
        so (else ``()``: the positions are the local ones)."""
        found = []
        for element in elements:
            try:
                found.append((float(element.get("latitude", "")),
                              float(element.get("longitude", ""))))
            except ValueError:
                return ()
        return tuple(found)

    def point(self, element: etree._Element, home: Home | None) -> tuple[float, float]:
        local = element.get("north") is not None or element.get("east") is not None
        world = element.get("latitude") is not None or element.get("longitude") is not None
        if local == world:
            self.diagnostics.append(error(
                self.loc(element), "E253",
                f"<{element_name(element)}> needs either north= and east= (metres from home) or "
                "latitude= and longitude=, not " + ("both" if local else "neither")))
            return (0.0, 0.0)
        names = ("north", "east") if local else ("latitude", "longitude")
        missing = [n for n in names if element.get(n) is None]
        if missing:
            self.diagnostics.append(error(
                self.loc(element), "E253", f"<{element_name(element)}> is missing {missing[0]}="))
            return (0.0, 0.0)
        if local:
            return (self.number(element, "north", Quantity.COORDINATE),
                    self.number(element, "east", Quantity.COORDINATE))
        if home is None:
            self.diagnostics.append(error(
                self.loc(element, "latitude"), "E253",
                "latitude/longitude positions need a <home> in the same block",
                "add <home latitude=... longitude=... altitude=.../>"))
            return (0.0, 0.0)
        north, east, _ = geo.to_local(self.number(element, "latitude", Quantity.LATITUDE),
                                      self.number(element, "longitude", Quantity.LONGITUDE),
                                      home.altitude,
                                      home.latitude, home.longitude, home.altitude)
        return north, east


MISSION_ITEM_ATTRIBUTES = ("command", "frame", "param1", "param2", "param3", "param4",
                           "param5", "param6", "param7", "autocontinue")
"""The attributes of ``<mission_item>``, the arguments of MISSION_ITEM."""


def _double(text: str | None) -> float | None:
    """An xs:double the schema accepted (NaN included), None when absent; one the schema
    refused is read as NaN."""
    if text is None:
        return None
    try:
        return float(text)
    except ValueError:
        return math.nan


def _whole(text: str) -> int:
    """A whole number the schema accepted; one of more digits than any range allows is
    read as 10**18, which every range refuses (int() of a long enough text raises). One
    the schema refused (not a whole number) is read as 1."""
    digits = text.strip().lstrip("+")
    if len(digits) > 18:
        return 10**18
    try:
        return int(digits)
    except ValueError:
        return 1


def build_mission(doc: XmlDocument, lenient: bool = False,
                  left_out: frozenset[etree._Element] = frozenset(),
                  ) -> tuple[Mission, list[Diagnostic]]:
    """The model of a schema-valid mission document, and structural diagnostics; with
    ``lenient``, of one the schema refused, skipping the elements ``left_out`` (see the
    module's docstring)."""
    builder = _Builder(doc, lenient, left_out)
    mission = builder.mission(doc.root)
    return mission, builder.diagnostics


def build_world(doc: XmlDocument) -> tuple[World, list[Diagnostic]]:
    """The model of a schema-valid world document, and structural diagnostics."""
    builder = _Builder(doc)
    return builder.world(doc.root), builder.diagnostics


def load_world(path: str | Path) -> World:
    """Read, schema-validate and build a world file; raises :class:`MissionSyntaxError`
    (schema or structure problems, the first one, with the count) on bad input."""
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
