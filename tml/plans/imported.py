"""A plan read from a QGroundControl or MAVProxy file, made into a TML mission.

Theory of operation
-------------------
Import is exact or says what it could not keep. Each mission item becomes one task, all in
one task with ``dispatch="mission"``: the file was a plan for the autopilot to fly in AUTO,
and so it stays. An item becomes the action that compiles back to it
(:mod:`tml.mavlink.compile`, read backwards by the ``imports`` part of each action's
definition, :mod:`tml.actions.reading`: NAV_TAKEOFF a TAKE_OFF, NAV_WAYPOINT a
GO_TO_POSITION, NAV_LAND a LANDING_POINT ...) only when that action compiles back to *the
same item*, every field of it: the mission is compiled and compared item for item, and
every item no action says exactly (a DO_JUMP, a spline waypoint, a waypoint with a hold
time or a yaw left unset, a value an action's range refuses) is a ``<mission_item>`` (the
action ``MISSION_ITEM``): the item as written, command, frame, seven params and
autocontinue. Items the mission compiler writes as several (a LANDING_POINT with a
heading: CONDITION_YAW then NAV_LAND) are read back as one action when they compile back
the same.

Positions travel as the 1e-7-degree integers mission items carry, never through a local
frame; a param left unset (null in a ``.plan``, NaN) stays unset. The plan's home, its
geofence (the inclusion polygon), its exclusion zones (as obstacles from the ground up:
a plan gives them no top) and its rally points become the mission's ``<environment>``.
What has no TML form (a second inclusion zone, a rally point below home or outside the
geofence, a complex item saved without its items) is a *loss*:
:attr:`Imported.losses` names each source item, and ``tml import`` refuses the file
unless the losses are allowed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lxml import etree

from tml.actions.mav import GLOBAL_FRAMES
from tml.actions.reading import Reader, Reading
from tml.actions.reading import value as _value
from tml.actions.registry import REGISTRY
from tml.errors import Location, MissionSemanticError
from tml.language.actions import BoundAction, bind, lookup
from tml.language.kinds import Kind
from tml.language.mavlink_tables import MAV_CMD, MAV_FRAME
from tml.language.model import Action, Argument
from tml.mavlink.codec import mavlink
from tml.mavlink.compile import CompileError, compile_mission
from tml.mavlink.mission import MissionItem
from tml.plans.planned import JUMP_FRAME, plan_mission, same_item
from tml.plans.qgc import PlanFile, PlanFileError
from tml.world import DEFAULT_HOME, inside

SCHEMA_INSTANCE = "http://www.w3.org/2001/XMLSchema-instance"


@dataclass
class _Action:
    """An action being written: its name, arguments (in order) and the items it came from."""

    name: str
    arguments: dict[str, str] = field(default_factory=dict)
    items: list[int] = field(default_factory=list)  # the seq (0-based) of each source item


@dataclass(frozen=True)
class Imported:
    """The mission's (or world file's) XML text, notes, the tasks written, and what could
    not be brought over (losses)."""

    text: str
    warnings: tuple[str, ...]
    actions: int
    losses: tuple[str, ...] = ()
    raw: int = 0  # items carried as MISSION_ITEM
    world: bool = False  # a world file (the plan's fence), not a mission


def _readers() -> dict[int, list[tuple[str, Reader]]]:
    """Mission item command -> the actions that may read back from it, with their readers
    (the ``imports`` parts of the action registry), in the catalogue's order."""
    found: dict[int, list[tuple[str, Reader]]] = {}
    for name, action in REGISTRY.items():
        if isinstance(action.imports, Reading):
            for command, reader in action.imports.commands.items():
                found.setdefault(command, []).append((name, reader))
    return found


READERS = _readers()


def _read_next(actions: list[_Action], item: MissionItem) -> None:
    """Read ``item`` onto ``actions``: joined into the last one when an action that reads
    it says both are one (the first such in the catalogue's order: a NAV_LOITER_TURNS
    after an ORBIT's ROI is the ORBIT's circle, not a LOITER), else as the first action
    that reads it, else as a MISSION_ITEM."""
    readings = [(name, arguments) for name, reader in READERS.get(item.command, ())
                if (arguments := reader(item)) is not None]
    for name, arguments in readings if actions else ():
        if _joined(actions[-1], _Action(name, arguments, [item.seq])):
            return
    action = _Action(*readings[0]) if readings else _raw(item)
    action.items.append(item.seq)
    actions.append(action)


def _joined(previous: _Action, action: _Action) -> bool:
    """Join ``action`` into ``previous`` when both are what one action compiled to (its
    definition's ``join`` says); True when joined."""
    imports = REGISTRY[action.name].imports
    join = imports.join if isinstance(imports, Reading) else None
    joined = join(previous.name, previous.arguments, action.arguments) if join else None
    if joined is None:
        return False
    previous.name, previous.arguments = action.name, joined
    previous.items += action.items
    return True


def _without_defaults(action: _Action) -> dict[str, str]:
    """The arguments that differ from the catalogue's defaults."""
    spec = lookup(action.name)
    assert spec is not None
    kept = {}
    for name, value in action.arguments.items():
        argument = spec.argument(name)
        default = argument.default if argument is not None else None
        if default is not None and (str(default) == value or (
                isinstance(default, float) and float(value) == default)):
            continue
        kept[name] = value
    return kept


def _raw(item: MissionItem) -> _Action:
    """The MISSION_ITEM that is ``item`` exactly."""
    placed = item.frame in GLOBAL_FRAMES
    arguments = {
        "command": MAV_CMD.get(item.command) or str(item.command),
        "frame": MAV_FRAME.get(item.frame) or str(item.frame),
        "param1": _value(item.param1), "param2": _value(item.param2),
        "param3": _value(item.param3), "param4": _value(item.param4),
        "param5": _value(item.x / 1e7) if placed else str(item.x),
        "param6": _value(item.y / 1e7) if placed else str(item.y),
        "param7": _value(item.z)}
    if not item.autocontinue:
        arguments["autocontinue"] = "no"
    return _Action("MISSION_ITEM", arguments)


def _bound(action: _Action, line: int) -> BoundAction | None:
    """The action typed as the language types it, or None when it does not validate."""
    location = Location("import", line, 0)
    model = Action(action.name, tuple(Argument(k, v, None, location)
                                      for k, v in _without_defaults(action).items()), location)
    try:
        return bind(model)
    except MissionSemanticError:
        return None


def _exact(actions: list[_Action], plan: PlanFile, losses: list[str]) -> list[_Action]:
    """The actions with each one that does not compile back to its items exactly made
    the MISSION_ITEMs of its items; a MISSION_ITEM that does not either is a loss."""
    home = plan.home or DEFAULT_HOME
    while True:
        bound = [_bound(a, n) for n, a in enumerate(actions)]
        wrong = {n for n, b in enumerate(bound) if b is None}
        if not wrong:
            try:
                compiled = compile_mission([b for b in bound if b is not None], home,
                                           (0.0, 0.0, 0.0), home.heading, Kind.MULTICOPTER)
            except CompileError:
                wrong = {n for n, a in enumerate(actions) if a.name != "MISSION_ITEM"}
            else:
                made: list[list[MissionItem]] = [[] for _ in actions]
                for item, owner in zip(compiled.items, compiled.action_index, strict=True):
                    made[owner].append(item)
                wrong = {n for n, a in enumerate(actions) if len(made[n]) != len(a.items)
                         or not all(same_item(x, plan.items[seq])
                                    for x, seq in zip(made[n], a.items, strict=False))}
        if not wrong:
            return actions
        again: list[_Action] = []
        for n, action in enumerate(actions):
            if n not in wrong or (action.name == "MISSION_ITEM" and len(action.items) == 1):
                again.append(action)
                continue
            for seq in action.items:
                raw = _raw(plan.items[seq])
                raw.items.append(seq)
                again.append(raw)
        if again == actions:  # items not even a MISSION_ITEM carries exactly
            losses.extend(f"{plan.source(actions[n].items[0])}: not carried exactly (its "
                          "MISSION_ITEM compiles to another item)" for n in sorted(wrong)
                          if bound[n] is not None)  # the others: said by validation
            return actions
        actions = again


def import_plan(plan: PlanFile, name: str) -> Imported:
    """The TML mission of ``plan``, named ``name``.

    A plan with a fence or rally points and a home but no mission item is a world file
    (:attr:`Imported.world`): the fence and rally points, for ``--world``. Raises
    :class:`PlanFileError` for a plan with no mission item and nothing a world file holds
    (a TML mission flies at least one task)."""
    if not plan.items and (plan.zones or plan.rally) and plan.home is not None:
        return _world(plan, name)
    if not plan.items:
        if plan.zones or plan.rally:
            raise PlanFileError("no mission items to fly (it holds a fence or rally points "
                                "only, and no home to place them from): give one with --home "
                                "LAT,LON[,ALT] to have them as a world file")
        raise PlanFileError("no mission items to fly: a TML mission needs one")
    warnings = list(plan.skipped)
    losses = list(plan.losses)
    actions: list[_Action] = []
    for item in plan.items:
        _read_next(actions, item)
    actions = _exact(actions, plan, losses)
    repeats = _repeats(actions, plan)
    text = _mission(plan, name, actions, repeats, losses)
    if repeats and not _compiles_back(text, plan):  # a round flies other items than the first
        repeats = {}
        text = _mission(plan, name, actions, repeats, losses)
    raw = sum(a.name == "MISSION_ITEM" for a in actions) - len(repeats)
    return Imported(text, tuple(warnings), len(actions) - len(repeats), tuple(losses), raw)


def _repeats(actions: list[_Action], plan: PlanFile) -> dict[int, tuple[int, int, int]]:
    """The DO_JUMPs that are a ``<repeat>``: body's first action -> (the DO_JUMP's action,
    times, its frame). A DO_JUMP is one when it is what a repeat exports (:data:`JUMP_FRAME`
    or, with ``jump_frame``, QGroundControl's MISSION, a repeat count of 1 or more, nothing
    else set) and jumps back to the first item of an action,
    over a body that holds no other DO_JUMP; any other (forward, into the middle of an
    action, forever, in another frame) stays a MISSION_ITEM with its target."""
    starts = {a.items[0]: n for n, a in enumerate(actions)}
    found: dict[int, tuple[int, int, int]] = {}
    for n, action in enumerate(actions):
        item = plan.items[action.items[0]]
        if action.name != "MISSION_ITEM" or item.command != mavlink.MAV_CMD_DO_JUMP \
                or item.frame not in (JUMP_FRAME, mavlink.MAV_FRAME_MISSION) \
                or (item.param3, item.param4, item.x, item.y, item.z,
                    bool(item.autocontinue)) != (0, 0, 0, 0, 0, True) \
                or not (item.param1.is_integer() and item.param2.is_integer()
                        and item.param2 >= 1):
            continue
        body = starts.get(int(item.param1) - 1)
        if body is None or body >= n or any(
                plan.items[a.items[0]].command == mavlink.MAV_CMD_DO_JUMP
                and a.name == "MISSION_ITEM" for a in actions[body:n]) \
                or any(start < n and body <= jump for start, (jump, _, _) in found.items()):
            continue
        found[body] = (n, int(item.param2) + 1, item.frame)
    return found


def _mission(plan: PlanFile, name: str, actions: list[_Action],
             repeats: dict[int, tuple[int, int, int]], losses: list[str]) -> str:
    """The mission's XML text: a task per action, in one ``dispatch="mission"`` task; the
    actions of a repeat's body in a task with ``<repeat>``."""
    root = etree.Element("mission", nsmap={"xsi": SCHEMA_INSTANCE}, name=name)
    from tml.language.schema import SCHEMA_LOCATION

    root.set(f"{{{SCHEMA_INSTANCE}}}noNamespaceSchemaLocation", SCHEMA_LOCATION)
    root.append(etree.Comment(f" Imported from a plan of {len(plan.items)} mission items. "))
    _environment(root, plan, losses)
    top = etree.SubElement(root, "task", name="Plan", dispatch="mission")
    parent, ends = top, -1
    for n, action in enumerate(actions):
        if n in repeats:
            ends, times, frame = repeats[n]
            jump = plan.source(actions[ends].items[0])
            parent = etree.SubElement(top, "task", name=f"{plan.source(action.items[0])} to "
                                      f"{plan.source(actions[ends - 1].items[-1])}: "
                                      f"{times} times ({jump}: DO_JUMP)")
            repeat = etree.SubElement(parent, "repeat", times=str(times))
            if frame != JUMP_FRAME:  # QGroundControl's MISSION frame, exported back
                repeat.set("jump_frame", str(frame))
        if n == ends:  # the DO_JUMP is the repeat
            parent = top
            continue
        sources = ", ".join(plan.source(seq) for seq in action.items)
        what = action.name if action.name != "MISSION_ITEM" else \
            action.arguments["command"].removeprefix("MAV_CMD_")
        task = etree.SubElement(parent, "task", name=f"{sources}: {what}")
        if action.name == "MISSION_ITEM":  # the item on one line: <mission_item .../>
            etree.SubElement(task, "mission_item", _without_defaults(action))
            continue
        element = etree.SubElement(task, "action", name=action.name)
        for argument, value in _without_defaults(action).items():
            etree.SubElement(element, "argument", name=argument, value=value)
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8").decode("utf-8") + "\n"


def _compiles_back(text: str, plan: PlanFile) -> bool:
    """Whether the mission ``text`` exports as ``plan``'s items, item for item."""
    from tml.language.validation import validate_file

    result = validate_file("import.xml", text.encode("utf-8"))
    if result.errors or result.mission is None:
        return False
    items = plan_mission(result.mission).items
    return len(items) == len(plan.items) and all(
        same_item(a, b) for a, b in zip(items, plan.items, strict=True))


def _world(plan: PlanFile, name: str) -> Imported:
    """The world file of a plan that holds a fence or rally points and no item."""
    from tml.language.schema import stable_location

    root = etree.Element("world", nsmap={"xsi": SCHEMA_INSTANCE}, name=name)
    root.set(f"{{{SCHEMA_INSTANCE}}}noNamespaceSchemaLocation", stable_location("world.xsd"))
    root.append(etree.Comment(" Imported from a plan with a fence or rally points and no "
                                 "mission item. "))
    losses = list(plan.losses)
    _environment(root, plan, losses, environment=root)
    etree.indent(root, space="  ")
    text = etree.tostring(root, xml_declaration=True, encoding="UTF-8").decode("utf-8")
    return Imported(text + "\n", tuple(plan.skipped), 0, tuple(losses), 0, world=True)


def _environment(root: etree._Element, plan: PlanFile, losses: list[str],
                 environment: etree._Element | None = None) -> None:
    """The plan's home and zones in a new ``<environment>`` of ``root`` (or in
    ``environment``: a world file's root)."""
    if plan.home is None and plan.rally:
        losses.append(f"{len(plan.rally)} rally point(s): a mission places latitudes and "
                      "longitudes from its home, and the file gives none: left out")
    if plan.home is None and plan.zones:
        losses.append(f"{len(plan.zones)} fence zone(s): a mission places latitudes and "
                      "longitudes from its home, and the file gives none: left out")
    if plan.home is None and plan.settings is None:
        return
    if environment is None:
        environment = etree.SubElement(root, "environment")
    if plan.home is not None:
        etree.SubElement(environment, "home", latitude=_value(plan.home.latitude),
                         longitude=_value(plan.home.longitude),
                         altitude=_value(plan.home.altitude))
    if plan.settings is not None:  # QGroundControl's Mission Settings, for the export
        settings = {name: _value(value) for name, value in (
            ("firmware_type", plan.settings.firmware_type),
            ("vehicle_type", plan.settings.vehicle_type),
            ("cruise_speed", plan.settings.cruise_speed),
            ("hover_speed", plan.settings.hover_speed),
            ("altitude_mode", plan.settings.altitude_mode)) if value is not None}
        if plan.settings.ground_station is not None:
            settings["ground_station"] = plan.settings.ground_station
        written = etree.SubElement(environment, "plan_settings", settings)
        for editor in plan.settings.items:  # QGroundControl's editor fields of each item
            etree.SubElement(written, "item", {"number": str(editor.number)} | {
                name: _value(value) for name, value in (
                    ("altitude", editor.altitude), ("altitude_mode", editor.altitude_mode),
                    ("amsl_above_terrain", editor.amsl_above_terrain)) if value is not None})
    if plan.home is None:
        return
    fenced: tuple[tuple[float, float], ...] = ()
    for index, zone in enumerate(plan.zones, start=1):
        if zone.inclusion and zone.radius is None and not fenced:
            fenced = zone.points
            parent = etree.SubElement(environment, "geofence")
        elif zone.inclusion:
            losses.append(f"geofence zone {index}: a second inclusion zone or an inclusion "
                            "circle has no TML form: left out")
            continue
        elif zone.radius is not None:
            (lat, lon), = zone.points
            etree.SubElement(environment, "cylinder", name=f"exclusion zone {index}",
                             latitude=_value(lat), longitude=_value(lon),
                             radius=_value(zone.radius))
            continue
        else:
            parent = etree.SubElement(environment, "prism", name=f"exclusion zone {index}")
        for lat, lon in zone.points:
            etree.SubElement(parent, "point", latitude=_value(lat), longitude=_value(lon))
    rally = None
    for index, (lat, lon, altitude) in enumerate(plan.rally, start=1):
        if not altitude >= 0:
            losses.append(f"rally point {index}: altitude {altitude:g} m, below home, has no "
                          "TML form: left out")
            continue
        if fenced and not inside(fenced, (lat, lon)):
            losses.append(f"rally point {index}: outside the geofence, where the vehicle's "
                          "fence would stop it on the way: left out")
            continue
        if rally is None:
            rally = etree.SubElement(environment, "rally")
        etree.SubElement(rally, "point", latitude=_value(lat), longitude=_value(lon),
                         altitude=_value(altitude))
