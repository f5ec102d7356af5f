"""Plans and their world for map viewers: GeoJSON (RFC 7946) and KML 2.2.

Both hold the same features: each plan's path (a line from home through every item with a
position, altitudes AMSL), a point per item with a position (its number, command and
task), home, the geofence's polygon and the obstacles (a prism's polygon, a cylinder's
circle drawn as a polygon of :data:`CIRCLE_CORNERS` corners). Coordinates are longitude,
latitude, altitude, as both formats write them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any

from lxml import etree

from tml.mavlink.codec import mavlink
from tml.plans.planned import Plan, local_to_global
from tml.world import Cylinder, Home, Obstacle, World

CIRCLE_CORNERS = 36
KML_NAMESPACE = "http://www.opengis.net/kml/2.2"
OPEN_TOP = 100.0
"""Metres above home drawn as the top of an obstacle that has none (it has no end)."""


def command_name(command: int) -> str:
    """``NAV_WAYPOINT`` for 16: MAVLink's name of a MAV_CMD without its prefix."""
    entry = mavlink.enums["MAV_CMD"].get(command)
    return entry.name.removeprefix("MAV_CMD_") if entry is not None else str(command)


def _ring(home: Home, corners: Sequence[tuple[float, float]],
          up: float = 0.0) -> list[tuple[float, float, float]]:
    """A closed ring of (longitude, latitude, altitude AMSL) of local corners."""
    points = [local_to_global(home, n, e, up) for n, e in corners]
    ring = [(lon, lat, alt) for lat, lon, alt in points]
    return ring + ring[:1]


def outline(obstacle: Obstacle) -> tuple[tuple[float, float], ...]:
    """The corners (north, east) of an obstacle's ground outline: a prism's polygon, a
    cylinder's circle as :data:`CIRCLE_CORNERS` corners."""
    if isinstance(obstacle, Cylinder):
        return tuple((obstacle.north + obstacle.radius * math.cos(a),
                      obstacle.east + obstacle.radius * math.sin(a))
                     for a in (2 * math.pi * i / CIRCLE_CORNERS
                               for i in range(CIRCLE_CORNERS)))
    return obstacle.polygon


def _top(obstacle: Obstacle) -> float:
    return obstacle.top if math.isfinite(obstacle.top) else OPEN_TOP


def _features(plans: Sequence[Plan], world: World) -> list[tuple[str, str, Any, dict[str, Any]]]:
    """(geometry kind, name, coordinates, properties) of every feature, in drawing order."""
    home = world.home_or_default
    found: list[tuple[str, str, Any, dict[str, Any]]] = []
    fence = world.geofence
    if fence is not None and fence.polygon:
        found.append(("Polygon", "geofence", _ring(home, fence.polygon),
                      {"kind": "geofence", "max_altitude": fence.max_altitude,
                       "min_altitude": fence.min_altitude}))
    for obstacle in world.obstacles:
        found.append(("Polygon", obstacle.name or "obstacle",
                      _ring(home, outline(obstacle), _top(obstacle)),
                      {"kind": "obstacle", "bottom": obstacle.bottom,
                       "top": obstacle.top if math.isfinite(obstacle.top) else None}))
    found.append(("Point", "home", (home.longitude, home.latitude, home.altitude),
                  {"kind": "home"}))
    for plan in plans:
        who = f" ({plan.role})" if plan.role else ""
        found.append(("LineString", f"planned path{who}",
                      [(lon, lat, alt) for lat, lon, alt in plan.path()],
                      {"kind": "path", "role": plan.role, "mission": plan.name}))
        for item, task in zip(plan.items, plan.tasks, strict=True):
            position = plan.position(item)
            if position is not None:
                lat, lon, alt = position
                found.append(("Point", f"{item.seq + 1} {command_name(item.command)}{who}",
                              (lon, lat, alt), {"kind": "item", "seq": item.seq + 1,
                                                "command": command_name(item.command),
                                                "task": task, "role": plan.role}))
    return found


def write_geojson(plans: Sequence[Plan], world: World) -> str:
    """A GeoJSON FeatureCollection of the plans and the world."""
    features = []
    for geometry, name, coordinates, properties in _features(plans, world):
        if geometry == "Polygon":
            coordinates = [coordinates]
        features.append({"type": "Feature", "properties": {"name": name, **properties},
                         "geometry": {"type": geometry, "coordinates": coordinates}})
    return json.dumps({"type": "FeatureCollection", "features": features}, indent=2) + "\n"


def _coordinates(points: Sequence[tuple[float, float, float]]) -> str:
    return " ".join(f"{lon:.7f},{lat:.7f},{alt:.2f}" for lon, lat, alt in points)


STYLES = {"geofence": ("ff0000ff", "00000000"), "obstacle": ("ff0080ff", "800080ff"),
          "path": ("ffff8000", "00000000"), "item": ("ffff8000", "00000000"),
          "home": ("ff00ff00", "00000000")}
"""KML colours (aabbggrr) of each kind of feature: line, fill."""


def write_kml(plans: Sequence[Plan], world: World, name: str) -> str:
    """A KML document of the plans and the world (altitudes absolute, AMSL)."""
    k = f"{{{KML_NAMESPACE}}}"
    root = etree.Element(f"{k}kml", nsmap={None: KML_NAMESPACE})
    document = etree.SubElement(root, f"{k}Document")
    etree.SubElement(document, f"{k}name").text = name
    for kind, (line, fill) in STYLES.items():
        style = etree.SubElement(document, f"{k}Style", id=kind)
        line_style = etree.SubElement(style, f"{k}LineStyle")
        etree.SubElement(line_style, f"{k}color").text = line
        etree.SubElement(line_style, f"{k}width").text = "3" if kind == "path" else "2"
        poly_style = etree.SubElement(style, f"{k}PolyStyle")
        etree.SubElement(poly_style, f"{k}color").text = fill
    for geometry, title, coordinates, properties in _features(plans, world):
        mark = etree.SubElement(document, f"{k}Placemark")
        etree.SubElement(mark, f"{k}name").text = title
        if properties.get("task"):
            etree.SubElement(mark, f"{k}description").text = f"task {properties['task']}"
        etree.SubElement(mark, f"{k}styleUrl").text = f"#{properties['kind']}"
        shape = etree.SubElement(mark, f"{k}{geometry}")
        if properties["kind"] == "obstacle":
            etree.SubElement(shape, f"{k}extrude").text = "1"
        etree.SubElement(shape, f"{k}altitudeMode").text = "absolute"
        if geometry == "Polygon":
            ring = etree.SubElement(etree.SubElement(shape, f"{k}outerBoundaryIs"),
                                    f"{k}LinearRing")
            etree.SubElement(ring, f"{k}coordinates").text = _coordinates(coordinates)
        elif geometry == "Point":
            etree.SubElement(shape, f"{k}coordinates").text = _coordinates([coordinates])
        else:
            etree.SubElement(shape, f"{k}coordinates").text = _coordinates(coordinates)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8",
                          pretty_print=True).decode("utf-8")
