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
from dataclasses import dataclass, field
from typing import Any

from tml.language.kinds import Kind
from tml.mavlink.mission import MissionItem
from tml.plans.planned import GLOBAL_FRAMES, Plan, local_to_global
from tml.world import Cylinder, Home, Prism

FIRMWARE_ARDUPILOT = 3  # MAV_AUTOPILOT_ARDUPILOTMEGA
VEHICLE_TYPES = {Kind.MULTICOPTER: 2, Kind.FIXED_WING: 1, Kind.GROUND: 10}  # MAV_TYPE


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


def item_params(item: MissionItem) -> list[float | None]:
    """The seven params of an item as plan files write them: 5-7 in degrees for the global
    frames, else as the item carries them."""
    scale = 1e7 if item.frame in GLOBAL_FRAMES else 1.0
    return [item.param1, item.param2, item.param3, item.param4,
            item.x / scale, item.y / scale, item.z]


def item_from_params(seq: int, frame: int, command: int, params: list[Any],
                     autocontinue: bool = True) -> MissionItem:
    """A mission item from the seven params of a plan file (None and NaN read as 0)."""
    values = [0.0 if v is None or (isinstance(v, float) and math.isnan(v)) else float(v)
              for v in params]
    if len(values) != 7:
        raise PlanFileError(f"item {seq}: expected 7 params, got {len(values)}")
    scale = 1e7 if frame in GLOBAL_FRAMES else 1.0
    return MissionItem(seq=seq, frame=frame, command=command, param1=values[0],
                       param2=values[1], param3=values[2], param4=values[3],
                       x=round(values[4] * scale), y=round(values[5] * scale), z=values[6],
                       autocontinue=int(autocontinue))


def write_plan(plan: Plan) -> str:
    """The ``.plan`` JSON text of ``plan``."""
    home = plan.home
    items = []
    for item in plan.items:
        entry: dict[str, Any] = {
            "autoContinue": bool(item.autocontinue), "command": item.command,
            "doJumpId": item.seq + 1, "frame": item.frame, "params": item_params(item),
            "type": "SimpleItem"}
        items.append(entry)
    polygons: list[dict[str, Any]] = []
    circles: list[dict[str, Any]] = []
    fence = plan.world.geofence
    if fence is not None and fence.polygon:
        polygons.append({"inclusion": True, "version": 1, "polygon": [
            list(local_to_global(home, n, e)[:2]) for n, e in fence.polygon]})
    for obstacle in plan.world.obstacles:
        if isinstance(obstacle, Cylinder):
            centre = local_to_global(home, obstacle.north, obstacle.east)
            circles.append({"inclusion": False, "version": 1, "circle": {
                "center": list(centre[:2]), "radius": obstacle.radius}})
        elif isinstance(obstacle, Prism):
            polygons.append({"inclusion": False, "version": 1, "polygon": [
                list(local_to_global(home, n, e)[:2]) for n, e in obstacle.polygon]})
    document = {
        "fileType": "Plan", "version": 1, "groundStation": "tml",
        "mission": {
            "version": 2, "firmwareType": FIRMWARE_ARDUPILOT,
            "vehicleType": VEHICLE_TYPES[plan.kind], "cruiseSpeed": 15, "hoverSpeed": 5,
            "globalPlanAltitudeMode": 1,
            "plannedHomePosition": [home.latitude, home.longitude, home.altitude],
            "items": items},
        "geoFence": {"version": 2, "polygons": polygons, "circles": circles},
        "rallyPoints": {"version": 2, "points": []},
    }
    return json.dumps(document, indent=4) + "\n"


def read_plan(text: str, name: str = "plan") -> PlanFile:
    """The items, home, fence and rally points of a ``.plan`` file's text."""
    try:
        document = json.loads(text)
    except json.JSONDecodeError as error:
        raise PlanFileError(f"{name}:{error.lineno}:{error.colno}: not JSON: {error.msg}"
                            ) from None
    if not isinstance(document, dict) or document.get("fileType") != "Plan":
        raise PlanFileError(f"{name}: not a QGroundControl plan (no \"fileType\": \"Plan\")")
    mission = document.get("mission") or {}
    skipped: list[str] = []
    items: list[MissionItem] = []
    try:
        for entry in mission.get("items", []):
            for simple in _simple_items(entry, skipped):
                items.append(item_from_params(len(items), int(simple["frame"]),
                                              int(simple["command"]), simple["params"],
                                              bool(simple.get("autoContinue", True))))
        home = None
        planned = mission.get("plannedHomePosition")
        if planned:
            home = Home(float(planned[0]), float(planned[1]), float(planned[2]))
        zones = _zones(document.get("geoFence") or {})
        rally = tuple((float(p[0]), float(p[1]), float(p[2]))
                      for p in (document.get("rallyPoints") or {}).get("points", []))
    except (KeyError, TypeError, ValueError, IndexError) as error:
        if isinstance(error, PlanFileError):
            raise PlanFileError(f"{name}: {error}") from None
        raise PlanFileError(f"{name}: malformed plan: {error!r}") from None
    return PlanFile(tuple(items), home, zones, rally, tuple(skipped))


def _simple_items(entry: dict[str, Any], skipped: list[str]) -> list[dict[str, Any]]:
    """The simple items an entry of ``items`` stands for."""
    if entry.get("type") == "SimpleItem":
        return [entry]
    nested = entry.get("TransectStyleComplexItem", {}).get("Items")
    if nested:  # a survey or corridor scan keeps the items it was flown as
        return [e for e in nested if e.get("type") == "SimpleItem"]
    skipped.append(f"complex item {entry.get('complexItemType', '?')!r} with no items in "
                   "the file (open and save it in QGroundControl to have them)")
    return []


def _zones(fence: dict[str, Any]) -> tuple[Zone, ...]:
    zones = [Zone(tuple((float(p[0]), float(p[1])) for p in polygon["polygon"]),
                  bool(polygon.get("inclusion", True)))
             for polygon in fence.get("polygons", [])]
    for circle in fence.get("circles", []):
        centre = circle["circle"]["center"]
        zones.append(Zone(((float(centre[0]), float(centre[1])),),
                          bool(circle.get("inclusion", True)), float(circle["circle"]["radius"])))
    return tuple(zones)
