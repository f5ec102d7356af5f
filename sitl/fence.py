"""The geofence as ArduCopter checks it: which limit, if any, a position breaks.

``FENCE_TYPE`` is a bit mask: 1 maximum altitude (``FENCE_ALT_MAX``, or the world's
ceiling when lower), 2 a circle of ``FENCE_RADIUS`` metres around home, 4 the polygons and
circles uploaded with the fence mission type (else the world's polygon). As ArduPilot's
AC_PolyFence_loader reads them, the vehicle must be inside every inclusion polygon
(MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, a run of param1 corners) and inclusion circle
(NAV_FENCE_CIRCLE_INCLUSION, param1 the radius), and outside every exclusion polygon and
circle (..._EXCLUSION), from the ground to the sky. Positions are local (north, east, up)
metres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

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


BREACH_TEXTS = {"maximum altitude": "Max altitude fence breached",
                "circle": "Circle fence breached", "polygon": "Polygon fence breached",
                "exclusion zone": "Polygon fence breached"}
"""The limit broken -> ArduCopter's STATUSTEXT (AC_Fence; exclusion zones are polygons)."""

POLYGON_INCLUSION, POLYGON_EXCLUSION = 5001, 5002
CIRCLE_INCLUSION, CIRCLE_EXCLUSION = 5003, 5004


def uploaded_zones(items: Sequence[tuple[int, float, tuple[float, float]]]
                   ) -> tuple[list[Polygon], list[Polygon]]:
    """The inclusion and exclusion zones of uploaded fence items, each given as (command,
    param1, local (north, east)): consecutive polygon corners make a polygon of param1
    corners; a circle is a polygon of 64 sides round its centre. A polygon left short of
    its count, or with fewer than three corners, is left out as ArduPilot refuses it."""
    inclusion: list[Polygon] = []
    exclusion: list[Polygon] = []
    corners: list[tuple[float, float]] = []
    for i, (command, param1, point) in enumerate(items):
        if command in (CIRCLE_INCLUSION, CIRCLE_EXCLUSION):
            zone = Point(point).buffer(param1, quad_segs=16)
            (inclusion if command == CIRCLE_INCLUSION else exclusion).append(zone)
        elif command in (POLYGON_INCLUSION, POLYGON_EXCLUSION):
            corners.append(point)
            ends = i + 1 == len(items) or items[i + 1][0] != command or len(
                corners) >= round(param1)
            if ends:
                if len(corners) == round(param1) >= 3:
                    (inclusion if command == POLYGON_INCLUSION else exclusion).append(
                        Polygon(corners))
                corners = []
    return inclusion, exclusion


def breach(position: Vector, params: Params, home: Vector, polygon: Polygon | None,
           ceiling: float | None = None, *, inclusions: Sequence[Polygon] = (),
           exclusions: Sequence[Polygon] = ()) -> str:
    """The limit ``position`` breaks ("maximum altitude", "circle", "polygon", "exclusion
    zone"), or "". ``inclusions`` are uploaded zones the vehicle must be inside besides
    ``polygon``, ``exclusions`` those it must stay out of (both with bit 4)."""
    kinds = round(params["FENCE_TYPE"])
    max_alt = params["FENCE_ALT_MAX"] if ceiling is None else min(params["FENCE_ALT_MAX"],
                                                                   ceiling)
    if kinds & 1 and position[2] > max_alt:
        return "maximum altitude"
    if kinds & 2 and math.hypot(position[0] - home[0], position[1] - home[1]) > params[
            "FENCE_RADIUS"]:
        return "circle"
    here = Point(position[:2])
    if kinds & 4 and any(not zone.contains(here) for zone in (
            *([] if polygon is None else [polygon]), *inclusions)):
        return "polygon"
    if kinds & 4 and any(zone.contains(here) for zone in exclusions):
        return "exclusion zone"
    return ""


class Geofence:
    """One vehicle's fence zones: the inclusion polygon (the first one uploaded, else the
    world's), the further inclusion zones and the exclusion zones uploaded with it."""

    def __init__(self, world: World) -> None:
        self.world = world
        self.polygon = world_polygon(world)
        self.inclusions: list[Polygon] = []
        self.exclusions: list[Polygon] = []

    def load(self, items: Sequence[tuple[int, float, tuple[float, float]]]) -> None:
        """Take the uploaded fence items (as :func:`uploaded_zones` reads them)."""
        inclusions, self.exclusions = uploaded_zones(items)
        # No inclusion zone uploaded: the world's polygon (a vehicle set up beforehand).
        self.polygon = inclusions[0] if inclusions else world_polygon(self.world)
        self.inclusions = inclusions[1:]

    def breach(self, position: Vector, params: Params, home: Vector) -> str:
        """The limit ``position`` breaks (:func:`breach`), home being ``home``."""
        geofence = self.world.geofence
        ceiling = geofence.max_altitude if geofence is not None else None
        return breach(position, params, home, self.polygon, ceiling,
                      inclusions=self.inclusions, exclusions=self.exclusions)
