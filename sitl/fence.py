"""The geofence as ArduCopter checks it: which limit, if any, a position breaks.

``FENCE_TYPE`` is a bit mask: 1 maximum altitude (``FENCE_ALT_MAX``, or the world's
ceiling when lower), 2 a circle of ``FENCE_RADIUS`` metres around home, 4 an inclusion
polygon (the one uploaded with the fence mission type, else the world's). Positions are
local (north, east, up) metres.
"""

from __future__ import annotations

import math

from shapely.geometry import Point, Polygon

from sitl.params import Params
from tml.world import World

Vector = tuple[float, float, float]


def world_polygon(world: World) -> Polygon | None:
    """The world's geofence polygon, or None when it has none."""
    fence = world.geofence
    if fence is None or len(fence.polygon) < 3:
        return None
    return Polygon(fence.polygon)


def inclusion_polygon(vertices: list[tuple[float, float]], world: World) -> Polygon | None:
    """The uploaded inclusion polygon (three vertices or more), else the world's."""
    return Polygon(vertices) if len(vertices) >= 3 else world_polygon(world)


def breach(position: Vector, params: Params, home: Vector, polygon: Polygon | None,
           ceiling: float | None = None) -> str:
    """The limit ``position`` breaks ("maximum altitude", "circle", "polygon"), or ""."""
    kinds = round(params["FENCE_TYPE"])
    max_alt = params["FENCE_ALT_MAX"] if ceiling is None else min(params["FENCE_ALT_MAX"],
                                                                   ceiling)
    if kinds & 1 and position[2] > max_alt:
        return "maximum altitude"
    if kinds & 2 and math.hypot(position[0] - home[0], position[1] - home[1]) > params[
            "FENCE_RADIUS"]:
        return "circle"
    if kinds & 4 and polygon is not None and not polygon.contains(Point(position[:2])):
        return "polygon"
    return ""
