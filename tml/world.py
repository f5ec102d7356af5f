"""What the planner and the simulator know of the world, in the local frame.

A world comes from an ``<environment>`` block inside a mission or from a separate world
file (root ``<world>``, schema ``schemas/world.xsd``); :mod:`tml.language.xml` reads both and
:mod:`tml.language.build` builds them. All
coordinates here are local metres (see :mod:`tml.geo`): points given as latitude/longitude
in the file are converted when the file is read, relative to the world's home.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from tml.errors import Location

Point2 = tuple[float, float]  # (north, east) in metres


@dataclass(frozen=True)
class Home:
    """The home position: WGS84 latitude/longitude (degrees), altitude AMSL (m), heading."""

    latitude: float
    longitude: float
    altitude: float
    heading: float = 0.0  # degrees clockwise from north
    location: Location | None = None


# ArduPilot SITL's default location (CMAC, Canberra), used when a world names no home.
DEFAULT_HOME = Home(latitude=-35.363261, longitude=149.165230, altitude=584.0, heading=353.0)


@dataclass(frozen=True)
class Geofence:
    """An inclusion polygon (optional) and altitude limits above home, in metres."""

    polygon: tuple[Point2, ...] = ()
    min_altitude: float | None = None
    max_altitude: float | None = None
    location: Location | None = None
    # The corners (a cylinder: the centre) in latitude and longitude as written, when they
    # were: a plan file gets them back exactly, not through the local frame.
    written: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class Cylinder:
    """A vertical cylinder obstacle: centre, radius, and the altitudes it spans (m)."""

    name: str
    north: float
    east: float
    radius: float
    bottom: float = 0.0
    top: float = float("inf")
    location: Location | None = None
    # The corners (a cylinder: the centre) in latitude and longitude as written, when they
    # were: a plan file gets them back exactly, not through the local frame.
    written: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class Prism:
    """A polygon extruded between two altitudes (a building, a no-fly block)."""

    name: str
    polygon: tuple[Point2, ...]
    bottom: float = 0.0
    top: float = float("inf")
    location: Location | None = None
    # The corners (a cylinder: the centre) in latitude and longitude as written, when they
    # were: a plan file gets them back exactly, not through the local frame.
    written: tuple[tuple[float, float], ...] = ()


Obstacle = Cylinder | Prism


@dataclass(frozen=True)
class WorldObject:
    """Something a skill can recognise: a marker, an item, a bucket, a coloured frame.

    ``kind`` is one of ``OBJECT_KINDS``; ``ident`` is the marker number or item name that
    a detection reports; ``color`` is used by frames, items and buckets.
    """

    kind: str
    ident: str
    north: float
    east: float
    altitude: float = 0.0
    color: str = ""
    name: str = ""
    location: Location | None = None


@dataclass(frozen=True)
class RallyPoint:
    """A place the vehicle may return to instead of home (ArduPilot's rally point): its
    position and the altitude above home (m) it flies there at."""

    north: float
    east: float
    altitude: float
    location: Location | None = None
    # The point's latitude and longitude as written, when it was given so.
    written: tuple[tuple[float, float], ...] = ()


OBJECT_KINDS = ("marker", "aruco", "item", "bucket", "frame", "subject")


@dataclass(frozen=True)
class ItemAltitude:
    """What QGroundControl's editor keeps beside a mission item's params (the plan's
    ``Altitude``, ``AltitudeMode`` and ``AMSLAltAboveTerrain`` of item ``number``, counted
    from 1): for each, None when the file does not have it, NaN for its ``null``."""

    number: int
    altitude: float | None = None
    altitude_mode: float | None = None
    amsl_above_terrain: float | None = None


@dataclass(frozen=True)
class PlanSettings:
    """What a ground station's plan says beside its items, as QGroundControl's Mission
    Settings hold it: the firmware and vehicle the plan was made for (MAV_AUTOPILOT and
    MAV_TYPE numbers), the speeds it estimates times with (m/s) and its global altitude
    mode (QGroundControl's AltMode: the altitude frame its editor gives new items; the
    items keep their own frames). Kept so that a plan imported from a ``.plan`` exports
    back with them; None where the plan gave none."""

    firmware_type: int | None = None
    vehicle_type: int | None = None
    cruise_speed: float | None = None
    hover_speed: float | None = None
    altitude_mode: int | None = None
    location: Location | None = None
    ground_station: str | None = None  # the plan's groundStation
    items: tuple[ItemAltitude, ...] = ()  # the editor's fields of the items that have them


@dataclass(frozen=True)
class TerrainSource:
    """Elevation data a mission or world names (``<terrain source="..."/>``): the path as
    written and resolved relative to the file (:mod:`tml.terrain` reads it)."""

    source: str
    path: str
    location: Location | None = None


@dataclass(frozen=True)
class World:
    """Home, geofence, obstacles, recognisable objects, rally points, the plan settings and
    the terrain data named."""

    home: Home | None = None
    geofence: Geofence | None = None
    obstacles: tuple[Obstacle, ...] = ()
    objects: tuple[WorldObject, ...] = ()
    location: Location | None = None
    rally: tuple[RallyPoint, ...] = ()
    plan_settings: PlanSettings | None = None
    terrain: TerrainSource | None = None

    @property
    def home_or_default(self) -> Home:
        """The declared home, or ArduPilot SITL's default location."""
        return self.home or DEFAULT_HOME

    def merged(self, other: World | None) -> World:
        """This world with ``other`` laid over it: other's home and fence win, lists add up."""
        if other is None:
            return self
        return replace(
            self,
            home=other.home or self.home,
            geofence=other.geofence or self.geofence,
            obstacles=self.obstacles + other.obstacles,
            objects=self.objects + other.objects,
            rally=self.rally + other.rally,
            plan_settings=other.plan_settings or self.plan_settings,
            terrain=other.terrain or self.terrain,
        )


def inside(polygon: tuple[Point2, ...], point: Point2) -> bool:
    """True when ``point`` is inside ``polygon`` (even-odd rule; a point on an edge may
    count either way)."""
    north, east = point
    found = False
    for (n1, e1), (n2, e2) in zip(polygon, polygon[1:] + polygon[:1], strict=True):
        if (e1 > east) != (e2 > east):
            crossing = n1 + (east - e1) * (n2 - n1) / (e2 - e1)
            if north < crossing:
                found = not found
    return found
