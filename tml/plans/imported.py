"""A plan read from a QGroundControl or MAVProxy file, made into a TML mission.

Theory of operation
-------------------
Each mission item becomes one task holding the action that compiles back to it
(:mod:`tml.mavlink.compile`, read backwards): NAV_TAKEOFF a TAKE_OFF, NAV_WAYPOINT a
GO_TO_POSITION at its latitude, longitude and altitude (above home, AMSL or above terrain,
from the item's frame), NAV_LOITER_* a LOITER, NAV_LAND a LAND or LANDING_POINT, NAV_DELAY
a WAIT, DO_CHANGE_SPEED a SET_SPEED, the camera and gripper commands theirs. The tasks sit
in one task with ``dispatch="mission"``: the file was a plan for the autopilot to fly in
AUTO, and so it stays -- uploaded whole, flown on if the link drops. Items the mission
compiler writes as several (a LANDING_POINT with a heading: CONDITION_YAW then NAV_LAND; a
loiter of more than 255 turns) are read back as one action. An item with no action (a
DO_JUMP, a servo, a region of interest) is left out and named in the warnings.

The plan's home, its geofence (the inclusion polygon) and its exclusion zones (as
obstacles from the ground up: a plan gives them no top) become the mission's
``<environment>``, every position in latitude and longitude.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from lxml import etree

from tml.language.actions import lookup
from tml.mavlink.codec import command_text, mavlink
from tml.mavlink.compile import PRECISION_MODES, SPEED_TYPES
from tml.mavlink.mission import LOITER_TURNS_MAX, MissionItem
from tml.plans.planned import AMSL_FRAMES, GLOBAL_FRAMES, TERRAIN_FRAMES
from tml.plans.qgc import PlanFile

SCHEMA_INSTANCE = "http://www.w3.org/2001/XMLSchema-instance"


@dataclass
class _Action:
    """An action being written: its name, arguments (in order) and the items it came from."""

    name: str
    arguments: dict[str, str] = field(default_factory=dict)
    items: list[int] = field(default_factory=list)  # item numbers (1-based, as in the file)


@dataclass(frozen=True)
class Imported:
    """The mission's XML text and what could not be brought over."""

    text: str
    warnings: tuple[str, ...]
    actions: int


def _value(number: float) -> str:
    """The shortest text that reads back as ``number`` (``15``, not ``15.0``)."""
    number = float(number)
    return str(int(number)) if number.is_integer() else repr(number)


def _position(action: _Action, item: MissionItem) -> None:
    """Latitude, longitude, altitude and its reference, from a global item."""
    action.arguments["latitude"] = _value(item.x / 1e7)
    action.arguments["longitude"] = _value(item.y / 1e7)
    action.arguments["altitude"] = _value(item.z)
    if item.frame in AMSL_FRAMES:
        action.arguments["altitude_reference"] = "amsl"
    elif item.frame in TERRAIN_FRAMES:
        action.arguments["altitude_reference"] = "terrain"


def _placed(item: MissionItem) -> bool:
    return item.frame in GLOBAL_FRAMES and (item.x != 0 or item.y != 0)


def _take_off(item: MissionItem) -> _Action:
    return _Action("TAKE_OFF", {"altitude": _value(item.z), "pitch": _value(item.param1)})


def _waypoint(item: MissionItem) -> _Action:
    if not _placed(item):  # "here", at an altitude
        return _Action("SET_ALTITUDE", {"altitude": _value(item.z)})
    action = _Action("GO_TO_POSITION")
    _position(action, item)
    return action


def _loiter(item: MissionItem) -> _Action:
    action = _Action("LOITER")
    if _placed(item):
        _position(action, item)
    if item.command == mavlink.MAV_CMD_NAV_LOITER_TURNS:
        action.arguments["turns"] = _value(item.param1)
    elif item.command == mavlink.MAV_CMD_NAV_LOITER_TIME:
        action.arguments["duration"] = _value(item.param1)
    if item.param3:
        action.arguments["radius"] = _value(abs(item.param3))
    return action


def _land(item: MissionItem) -> _Action:
    if not _placed(item):
        return _Action("LAND")
    action = _Action("LANDING_POINT")
    _position(action, item)
    precision = {number: name for name, number in PRECISION_MODES.items()}
    if int(item.param2) in precision:
        action.arguments["precision_mode"] = precision[int(item.param2)]
    if item.param4:
        action.arguments["yaw"] = _value(item.param4)
    return action


def _delay(item: MissionItem) -> _Action:
    if item.param1 <= 0:
        return _Action("STABILIZE")
    return _Action("WAIT", {"duration": _value(item.param1)})


def _yaw(item: MissionItem) -> _Action:
    if item.param4:  # relative, in the direction param3 gives
        return _Action("ROTATE_YAW", {"angle": _value(item.param1 * (-1 if item.param3 < 0
                                                                      else 1))})
    return _Action("ROTATE_YAW", {"orientation_angle": _value(item.param1)})


def _speed(item: MissionItem) -> _Action:
    kinds = {number: name for name, number in SPEED_TYPES.items()}
    return _Action("SET_SPEED", {"speed": _value(item.param2),
                                 "speed_type": kinds.get(int(item.param1), "airspeed")})


def _capture(item: MissionItem) -> _Action:
    if item.param3 > 0:
        return _Action("CAPTURE_PHOTOS", {"count": _value(item.param3),
                                          "interval": _value(item.param2)})
    return _Action("START_CAPTURING", {"interval": _value(item.param2)})


def _gripper(item: MissionItem) -> _Action:
    grab = int(item.param2) == mavlink.GRIPPER_ACTION_GRAB
    return _Action("PICK_UP_ITEM" if grab else "DROP_ITEM")


def _set_home(item: MissionItem) -> _Action:
    if item.param1 == 1 or not (item.x or item.y):
        return _Action("SET_HOME")
    return _Action("SET_HOME", {"latitude": _value(item.x / 1e7),
                                "longitude": _value(item.y / 1e7), "altitude": _value(item.z)})


ACTIONS: dict[int, Callable[[MissionItem], _Action]] = {
    mavlink.MAV_CMD_NAV_TAKEOFF: _take_off,
    mavlink.MAV_CMD_NAV_WAYPOINT: _waypoint,
    mavlink.MAV_CMD_NAV_LOITER_UNLIM: _loiter,
    mavlink.MAV_CMD_NAV_LOITER_TURNS: _loiter,
    mavlink.MAV_CMD_NAV_LOITER_TIME: _loiter,
    mavlink.MAV_CMD_NAV_LAND: _land,
    mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH: lambda item: _Action("RETURN_HOME_AND_LAND"),
    mavlink.MAV_CMD_NAV_DELAY: _delay,
    mavlink.MAV_CMD_CONDITION_YAW: _yaw,
    mavlink.MAV_CMD_DO_CHANGE_SPEED: _speed,
    mavlink.MAV_CMD_DO_DIGICAM_CONTROL: lambda item: _Action("CAPTURE_PHOTO"),
    mavlink.MAV_CMD_IMAGE_START_CAPTURE: _capture,
    mavlink.MAV_CMD_IMAGE_STOP_CAPTURE: lambda item: _Action("STOP_CAPTURING"),
    mavlink.MAV_CMD_DO_GRIPPER: _gripper,
    mavlink.MAV_CMD_DO_SET_HOME: _set_home,
}
"""Mission item command -> the action that compiles back to it."""


def _joined(previous: _Action, action: _Action) -> bool:
    """Join ``action`` into ``previous`` when both are what one action compiled to; True
    when joined."""
    if action.name == "LANDING_POINT" and previous.name == "ROTATE_YAW" \
            and "yaw" in action.arguments \
            and previous.arguments.get("orientation_angle") == action.arguments["yaw"]:
        previous.name, previous.arguments = action.name, action.arguments
        previous.items += action.items
        return True
    same_circle = all(previous.arguments.get(k) == action.arguments.get(k)
                      for k in ("latitude", "longitude", "altitude", "radius"))
    if action.name == previous.name == "LOITER" and "turns" in action.arguments \
            and previous.arguments.get("turns") == str(LOITER_TURNS_MAX) and same_circle:
        previous.arguments["turns"] = str(LOITER_TURNS_MAX + int(action.arguments["turns"]))
        previous.items += action.items
        return True
    return False


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


def import_plan(plan: PlanFile, name: str) -> Imported:
    """The TML mission of ``plan``, named ``name``."""
    warnings = list(plan.skipped)
    actions: list[_Action] = []
    for item in plan.items:
        number = item.seq + 1
        make = ACTIONS.get(item.command)
        if make is None:
            warnings.append(f"item {number}: {command_text(item.command)} has no TML action: "
                            "left out")
            continue
        action = make(item)
        action.items.append(number)
        if not (actions and _joined(actions[-1], action)):
            actions.append(action)
    if not actions:
        warnings.append("the plan has no item a TML action flies: the mission only lands")
        actions.append(_Action("LAND"))
    root = etree.Element("mission", nsmap={"xsi": SCHEMA_INSTANCE}, name=name)
    from tml.language.schema import SCHEMA_LOCATION

    root.set(f"{{{SCHEMA_INSTANCE}}}noNamespaceSchemaLocation", SCHEMA_LOCATION)
    root.append(etree.Comment(f" Imported from a plan of {len(plan.items)} mission items. "))
    _environment(root, plan, warnings)
    top = etree.SubElement(root, "task", name="Plan", dispatch="mission")
    for action in actions:
        numbers = ", ".join(str(n) for n in action.items)
        task = etree.SubElement(top, "task", name=f"item {numbers}: {action.name}")
        element = etree.SubElement(task, "action", name=action.name)
        for argument, value in _without_defaults(action).items():
            etree.SubElement(element, "argument", name=argument, value=value)
    etree.indent(root, space="  ")
    text = etree.tostring(root, xml_declaration=True, encoding="UTF-8").decode("utf-8")
    return Imported(text + "\n", tuple(warnings), len(actions))


def _environment(root: etree._Element, plan: PlanFile, warnings: list[str]) -> None:
    if plan.home is None and not plan.zones:
        return
    environment = etree.SubElement(root, "environment")
    if plan.home is not None:
        etree.SubElement(environment, "home", latitude=_value(plan.home.latitude),
                         longitude=_value(plan.home.longitude),
                         altitude=_value(plan.home.altitude))
    fenced = False
    for index, zone in enumerate(plan.zones, start=1):
        if zone.inclusion and zone.radius is None and not fenced:
            fenced = True
            parent = etree.SubElement(environment, "geofence")
        elif zone.inclusion:
            warnings.append(f"geofence zone {index}: a second inclusion zone or an inclusion "
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
    if plan.rally:
        warnings.append(f"{len(plan.rally)} rally point(s) have no TML form: left out")
