"""QGroundControl's ``.plan`` file (JSON): mission items, geofence and rally points.

The layout is QGroundControl's own (file version 1, mission version 2, geofence version
2): every item a ``SimpleItem`` with its seven params (params 5-7 are latitude, longitude
and altitude in the global frames, else the raw x, y and z), the planned home position,
the geofence's inclusion polygon and its obstacles as exclusion polygons and circles.
:func:`read_plan` reads such a file back, the items of QGroundControl's complex items
(surveys, corridor scans) included where the file holds them.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from typing import Any

from tml.actions.mav import GLOBAL_FRAMES
from tml.language.kinds import Kind
from tml.mavlink.mission import MissionItem
from tml.plans.planned import Plan, local_to_global
from tml.world import Cylinder, Home, ItemAltitude, PlanSettings, Prism

FIRMWARE_ARDUPILOT = 3  # MAV_AUTOPILOT_ARDUPILOTMEGA
FLOAT32_MAX = 3.4028234663852886e38  # the largest param a mission item carries
FIRMWARES = {0: "generic", 3: "ArduPilot", 12: "PX4"}  # MAV_AUTOPILOT, as QGroundControl
VEHICLE_TYPES = {Kind.MULTICOPTER: 2, Kind.FIXED_WING: 1, Kind.GROUND: 10}  # MAV_TYPE
CRUISE_SPEED, HOVER_SPEED = 15, 5
"""The speeds (m/s) written for a plan that gives none: QGroundControl's own defaults
(its OfflineEditingCruiseSpeed and OfflineEditingHoverSpeed settings)."""
ALTITUDE_MODES = {0: "mixed", 1: "relative", 2: "absolute", 3: "calculated above terrain",
                  4: "terrain frame", 5: "none"}
"""QGroundControl's AltMode, the plan's ``globalPlanAltitudeMode``: the altitude frame
its editor gives the items added to the plan (1 GLOBAL_RELATIVE_ALT, 2 GLOBAL, 3 GLOBAL
with altitudes it computes from terrain data, 4 GLOBAL_TERRAIN_ALT; 0 each item its own,
as loaded). The items of a file keep the frames written in them: the mode changes no
item the vehicle is sent."""
ALTITUDE_MODE_RELATIVE = 1
"""The mode written for a mission written in TML: QGroundControl's default for a new plan.
An imported plan that gave none is written without one again (QGroundControl reads that
as mixed)."""


class PlanFileError(ValueError):
    """A plan or waypoint file that cannot be read (says where and why)."""


@dataclass(frozen=True)
class Zone:
    """A polygon (latitude, longitude corners) or a circle (one centre and a radius in m)."""

    points: tuple[tuple[float, float], ...]
    inclusion: bool
    radius: float | None = None


@dataclass(frozen=True)
class PlanFile:
    """What a plan or waypoint file holds: items (seq 0..N-1), home, fence, rally points."""

    items: tuple[MissionItem, ...]
    home: Home | None = None
    zones: tuple[Zone, ...] = ()
    rally: tuple[tuple[float, float, float], ...] = ()
    skipped: tuple[str, ...] = field(default=())  # what the reader could not take
    # How each item is named in messages: "item 3" (counted from 1 in the file's order), or
    # "item 3 (line 5)" in a waypoint file; one per item.
    sources: tuple[str, ...] = ()
    # What the file says that the items cannot carry exactly ("item 4: param5 0.5 ..."):
    # import refuses the file unless the loss is allowed.
    losses: tuple[str, ...] = ()
    # A .plan's firmware and vehicle type and speeds, as written (None: not in the file).
    settings: PlanSettings | None = None

    def source(self, seq: int) -> str:
        """How item ``seq`` (0-based) is named in messages."""
        return self.sources[seq] if seq < len(self.sources) else f"item {seq + 1}"


def item_params(item: MissionItem) -> list[float | None]:
    """The seven params of an item as plan files write them: 5-7 in degrees for the global
    frames, else as the item carries them."""
    scale = 1e7 if item.frame in GLOBAL_FRAMES else 1.0
    return [item.param1, item.param2, item.param3, item.param4,
            item.x / scale, item.y / scale, item.z]


def _float(value: Any) -> float:
    """A param as written: a number, or None (QGroundControl's NaN, "not set") as NaN."""
    if value is None:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise PlanFileError(f"{value!r} is not a number")
    return float(value)


def item_from_params(seq: int, frame: int, command: int, params: list[Any],
                     autocontinue: bool = True, losses: list[str] | None = None,
                     source: str = "") -> MissionItem:
    """A mission item from the seven params of a plan file. None and NaN stay NaN in
    params 1-4 and 7 (the command's "not set"); params 5 and 6 travel as 1e-7-degree
    integers in a global frame and as integers otherwise: what they cannot carry that
    way (NaN, a fraction) is said in ``losses`` (and read as the nearest integer)."""
    if len(params) != 7:
        raise PlanFileError(f"{source or f'item {seq + 1}'}: expected 7 params, "
                            f"got {len(params)}")
    try:
        values = [_float(v) for v in params]
    except PlanFileError as error:
        raise PlanFileError(f"{source or f'item {seq + 1}'}: {error}") from None
    said = losses if losses is not None else []
    for index in (0, 1, 2, 3, 6):  # 32-bit floats on the wire; NaN is "not set"
        value = values[index]
        if not math.isnan(value) and not abs(value) <= FLOAT32_MAX:
            said.append(f"{source}: param{index + 1} {value:g} is beyond what a mission "
                        "item carries (a 32-bit float): read as 0")
            values[index] = 0.0
    scale = 1e7 if frame in GLOBAL_FRAMES else 1.0
    xy = []
    for number, value in ((5, values[4]), (6, values[5])):
        if not math.isfinite(value):
            said.append(f"{source}: param{number} {value} cannot travel in a mission item "
                        "(an integer): read as 0")
            value = 0.0
        integer = round(value * scale)
        if not -2**31 <= integer < 2**31:
            said.append(f"{source}: param{number} {value:g} is beyond what a mission item "
                        "carries (a 32-bit integer): read as 0")
            integer = 0
        elif scale == 1.0 and integer != value:
            said.append(f"{source}: param{number} {value!r} in frame {frame} is an integer "
                        f"in a mission item: read as {integer}")
        xy.append(integer)
    return MissionItem(seq=seq, frame=frame, command=command, param1=values[0],
                       param2=values[1], param3=values[2], param4=values[3],
                       x=xy[0], y=xy[1], z=values[6], autocontinue=int(autocontinue))


def write_plan(plan: Plan) -> str:
    """The ``.plan`` JSON text of ``plan``."""
    home = plan.home
    settings = plan.world.plan_settings or PlanSettings()
    editors = {e.number: e for e in settings.items}
    items = []
    for item in plan.items:
        entry: dict[str, Any] = {}
        editor = editors.get(item.seq + 1)
        for key, name in EDITOR_FIELDS if editor is not None else ():
            value = getattr(editor, name)
            if value is not None:  # as the imported plan had it; NaN its null
                entry[key] = None if math.isnan(value) else _given(value, 0)
        entry |= {
            "autoContinue": bool(item.autocontinue), "command": item.command,
            "doJumpId": item.seq + 1, "frame": item.frame,
            "params": [None if v is not None and math.isnan(v) else v
                       for v in item_params(item)],  # QGroundControl's NaN is null
            "type": "SimpleItem"}
        items.append(entry)
    polygons: list[dict[str, Any]] = []
    circles: list[dict[str, Any]] = []
    fence = plan.world.geofence
    if fence is not None and fence.polygon:
        polygons.append({"inclusion": True, "version": 1,
                         "polygon": global_corners(home, fence.polygon, fence.written)})
    for obstacle in plan.world.obstacles:
        if isinstance(obstacle, Cylinder):
            centre, = global_corners(home, ((obstacle.north, obstacle.east),), obstacle.written)
            circles.append({"inclusion": False, "version": 1, "circle": {
                "center": centre, "radius": obstacle.radius}})
        elif isinstance(obstacle, Prism):
            polygons.append({"inclusion": False, "version": 1,
                             "polygon": global_corners(home, obstacle.polygon, obstacle.written)})
    mission: dict[str, Any] = {
        "version": 2, "firmwareType": _given(settings.firmware_type, FIRMWARE_ARDUPILOT),
        "vehicleType": _given(settings.vehicle_type, VEHICLE_TYPES[plan.kind]),
        "cruiseSpeed": _given(settings.cruise_speed, CRUISE_SPEED),
        "hoverSpeed": _given(settings.hover_speed, HOVER_SPEED),
        "globalPlanAltitudeMode": _given(settings.altitude_mode, ALTITUDE_MODE_RELATIVE),
        "plannedHomePosition": [home.latitude, home.longitude, home.altitude],
        "items": items}
    if plan.world.plan_settings is not None and settings.altitude_mode is None:
        del mission["globalPlanAltitudeMode"]  # as the imported plan had it
    document = {
        "fileType": "Plan", "version": 1, "groundStation": settings.ground_station or "tml",
        "mission": mission,
        "geoFence": {"version": 2, "polygons": polygons, "circles": circles},
        "rallyPoints": {"version": 2, "points": [
            [*global_corners(home, ((p.north, p.east),), p.written)[0], p.altitude]
            for p in plan.world.rally]},
    }
    return json.dumps(document, indent=4) + "\n"


def _given(value: float | None, default: float) -> float:
    """``value`` as the plan gave it (a whole number as an int), else ``default``."""
    number = default if value is None else value
    return int(number) if float(number).is_integer() else number


def global_corners(home: Home, local: tuple[tuple[float, float], ...],
                   written: tuple[tuple[float, float], ...]) -> list[list[float]]:
    """Latitude and longitude of each corner: as written in the mission when it was
    written so (exact), else from the local corners."""
    if written and len(written) == len(local):
        return [list(corner) for corner in written]
    return [list(local_to_global(home, n, e)[:2]) for n, e in local]


def read_plan(text: str, name: str = "plan") -> PlanFile:
    """The items, home, fence and rally points of a ``.plan`` file's text: QGroundControl's
    layout (items with seven ``params``), its older one (a ``coordinate`` and four params)
    and the still older ``.mission`` file (``"fileType": "Mission"``)."""
    try:
        document = json.loads(text)
    except json.JSONDecodeError as error:
        raise PlanFileError(f"{name}:{error.lineno}:{error.colno}: not JSON: {error.msg}"
                            ) from None
    if not isinstance(document, dict) or document.get("fileType") not in ("Plan", "Mission"):
        raise PlanFileError(f"{name}: not a QGroundControl plan (no \"fileType\": \"Plan\")")
    mission = document if document.get("fileType") == "Mission" else document.get("mission")
    if not isinstance(mission, dict):
        raise PlanFileError(f"{name}: the plan has no \"mission\": no items to fly")
    skipped: list[str] = []
    losses: list[str] = []
    nulls: list[str] = []
    items: list[MissionItem] = []
    jump_ids: dict[int, int] = {}  # doJumpId -> the item's number (from 1)
    sources: list[str] = []
    editors: list[ItemAltitude] = []
    try:
        for number, entry in enumerate(mission.get("items", []), start=1):
            nested = _simple_items(entry, f"item {number}", losses)
            for index, simple in enumerate(nested, start=1):
                source = f"item {number}" if len(nested) == 1 and simple is entry \
                    else f"item {number}.{index}"
                params = _params(simple, source)
                frame = int(simple["frame"])
                if frame not in GLOBAL_FRAMES and None in params[4:6]:
                    nulls.append(source)
                    params[4:6] = [0 if v is None else v for v in params[4:6]]
                items.append(item_from_params(len(items), frame, int(simple["command"]),
                                              params, bool(simple.get("autoContinue", True)),
                                              losses, source))
                sources.append(source)
                editor = _item_altitude(len(items), simple)
                if editor is not None:
                    editors.append(editor)
                if "doJumpId" in simple:
                    jump_ids[int(simple["doJumpId"])] = len(items)
        items = _jumps_by_number(items, jump_ids, sources, losses)
        home = _home(mission.get("plannedHomePosition"))
        zones = _zones(document.get("geoFence") or {})
        rally = tuple((float(p[0]), float(p[1]), float(p[2]))
                      for p in (document.get("rallyPoints") or {}).get("points", []))
    except PlanFileError as error:
        raise PlanFileError(f"{name}: {error}") from None
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as error:
        raise PlanFileError(f"{name}: malformed plan: {error!r}") from None
    settings = _settings(mission, document.get("groundStation"), tuple(editors))
    firmware = settings.firmware_type if settings is not None else None
    if firmware not in (None, FIRMWARE_ARDUPILOT):
        skipped.append(f"the plan was made for firmware type {firmware} "
                       f"({FIRMWARES.get(firmware, 'MAV_AUTOPILOT')}): its items are kept as "
                       "written and flown as ArduPilot flies them; the export writes firmware "
                       f"type {firmware} back")
    if nulls:
        skipped.append(f"{', '.join(nulls)}: params 5 and 6 null in a frame where they are "
                       "integers: read as 0, as MISSION_ITEM_INT sends them")
    return PlanFile(tuple(items), home, zones, rally, tuple(skipped), tuple(sources),
                    tuple(losses), settings)


EDITOR_FIELDS = (("Altitude", "altitude"), ("AltitudeMode", "altitude_mode"),
                 ("AMSLAltAboveTerrain", "amsl_above_terrain"))
"""The fields QGroundControl's editor writes beside an item's params, and their names in
:class:`ItemAltitude`."""


def _item_altitude(number: int, simple: dict[str, Any]) -> ItemAltitude | None:
    """The editor's fields of a simple item (``number`` counted from 1), when it has any
    that is a number or null."""
    values: dict[str, float] = {}
    for key, name in EDITOR_FIELDS:
        value = simple.get(key, False)
        if value is None:
            values[name] = math.nan
        elif isinstance(value, int | float) and not isinstance(value, bool) \
                and math.isfinite(value):
            values[name] = float(value)
    return ItemAltitude(number, **values) if values else None


def _settings(mission: dict[str, Any], ground_station: Any = None,
              editors: tuple[ItemAltitude, ...] = ()) -> PlanSettings | None:
    """The firmware and vehicle type, the speeds and the global altitude mode a plan's
    mission gives, as QGroundControl reads them (numbers; one of another type is ignored,
    as it is there; an altitude mode QGroundControl has no AltMode for too), the ground
    station that wrote it and its editor's fields of each item."""
    def number(key: str) -> float | None:
        value = mission.get(key)
        if isinstance(value, bool) or not isinstance(value, int | float):
            return None
        return float(value) if math.isfinite(value) and value >= 0 else None

    firmware, vehicle = number("firmwareType"), number("vehicleType")
    mode = number("globalPlanAltitudeMode")
    found = PlanSettings(
        int(firmware) if firmware is not None and firmware.is_integer() else None,
        int(vehicle) if vehicle is not None and vehicle.is_integer() else None,
        number("cruiseSpeed"), number("hoverSpeed"),
        int(mode) if mode is not None and mode in ALTITUDE_MODES else None,
        ground_station=ground_station if isinstance(ground_station, str) else None,
        items=editors)
    return found if found != PlanSettings() else None


def _jumps_by_number(items: list[MissionItem], jump_ids: dict[int, int], sources: list[str],
                     losses: list[str]) -> list[MissionItem]:
    """The items with each DO_JUMP's target, a doJumpId in a ``.plan``, made the number of
    the item it names (from 1, as the vehicle counts behind its home, and as the export
    writes the doJumpIds), as QGroundControl does when it uploads."""
    numbered = []
    for item in items:
        if item.command == 177 and jump_ids:  # MAV_CMD_DO_JUMP
            target = jump_ids.get(int(item.param1)) if item.param1.is_integer() else None
            if target is None:
                losses.append(f"{sources[item.seq]}: DO_JUMP to doJumpId {item.param1:g}, "
                              "which no item has: left as written")
            else:
                item = replace(item, param1=float(target))
        numbered.append(item)
    return numbered


def _params(simple: dict[str, Any], source: str) -> list[Any]:
    """The seven params of a simple item, in either of QGroundControl's layouts."""
    params = simple.get("params")
    if params is None:
        params = [simple.get(f"param{n}", 0) for n in range(1, 5)]
    params = list(params)
    if "coordinate" in simple and len(params) == 4:
        coordinate = list(simple["coordinate"])
        if len(coordinate) != 3:
            raise PlanFileError(f"{source}: expected a coordinate of 3 numbers, got "
                                f"{len(coordinate)}")
        params += coordinate
    return params


def _home(planned: Any) -> Home | None:
    """The planned home: [lat, lon, alt], or an older file's item with a coordinate."""
    if isinstance(planned, dict):
        planned = planned.get("coordinate")
    if not planned:
        return None
    latitude, longitude, altitude = (float(v) for v in planned)
    if latitude == longitude == 0:  # QGroundControl's "no home"
        return None
    return Home(latitude, longitude, altitude)


def _simple_items(entry: dict[str, Any], source: str,
                  losses: list[str]) -> list[dict[str, Any]]:
    """The simple items an entry of ``items`` stands for."""
    if entry.get("type") in ("SimpleItem", "missionItem") or "command" in entry:
        return [entry]
    nested = (entry.get("TransectStyleComplexItem") or {}).get("Items")
    if nested:  # a survey or corridor scan keeps the items it was flown as
        return [e for e in nested if e.get("type") == "SimpleItem"]
    losses.append(f"{source}: complex item {entry.get('complexItemType', '?')!r} saved "
                  "without its mission items (open and save it in QGroundControl to have "
                  "them): left out")
    return []


def _zones(fence: dict[str, Any]) -> tuple[Zone, ...]:
    zones = [Zone(tuple((float(p[0]), float(p[1])) for p in polygon["polygon"]),
                  bool(polygon.get("inclusion", True)))
             for polygon in fence.get("polygons", [])]
    old = fence.get("polygon")  # geofence version 1: one inclusion polygon
    if old:
        zones.append(Zone(tuple((float(p[0]), float(p[1])) for p in old), True))
    for circle in fence.get("circles", []):
        centre = circle["circle"]["center"]
        zones.append(Zone(((float(centre[0]), float(centre[1])),),
                          bool(circle.get("inclusion", True)), float(circle["circle"]["radius"])))
    return tuple(zones)
