"""Conversions between the local mission frame and WGS84.

The local frame of tml: metres from the home position, ``north`` and ``east`` on the
ground plane and ``up`` above home (the same axes as MAVLink's LOCAL_NED x and y, with
z pointing up). Global positions are latitude/longitude in degrees and altitude in metres
above mean sea level (AMSL); an altitude "relative" to home is ``up``.

The conversions go through Earth-centred Earth-fixed coordinates on the WGS84 ellipsoid,
with pymap3d's formulas (``enu2geodetic``, ``geodetic2enu``; ECEF to geodetic by You's
closed form, no iteration) written on floats with :mod:`math`: pymap3d's own functions
cost about a hundred times more per point in numpy scalar overhead, and the simulator
converts every vehicle's position several times a second (docs/performance.md). The
home's ECEF position and rotation are computed once per home.
"""

from __future__ import annotations

import math
from functools import lru_cache

Point = tuple[float, float, float]
"""A local point: (north, east, up) in metres from home."""

SEMIMAJOR = 6378137.0  # WGS84 a, metres
SEMIMINOR = 6356752.31424518  # WGS84 b = a (1 - f), f = 1 / 298.257223563
_E = math.sqrt(SEMIMAJOR**2 - SEMIMINOR**2)  # linear eccentricity


def _ecef(latitude: float, longitude: float, altitude: float) -> Point:
    lat, lon = math.radians(latitude), math.radians(longitude)
    cos_lat, sin_lat = math.cos(lat), math.sin(lat)
    # radius of curvature of the prime vertical section
    n = SEMIMAJOR**2 / math.hypot(SEMIMAJOR * cos_lat, SEMIMINOR * sin_lat)
    return ((n + altitude) * cos_lat * math.cos(lon), (n + altitude) * cos_lat * math.sin(lon),
            (n * (SEMIMINOR / SEMIMAJOR) ** 2 + altitude) * sin_lat)


@lru_cache(maxsize=256)
def _frame(latitude: float, longitude: float, altitude: float
           ) -> tuple[Point, tuple[float, float, float, float]]:
    """A home's ECEF position and the sines and cosines of its latitude and longitude."""
    lat, lon = math.radians(latitude), math.radians(longitude)
    return (_ecef(latitude, longitude, altitude),
            (math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)))


def _geodetic(x: float, y: float, z: float) -> tuple[float, float, float]:
    """ECEF -> (latitude, longitude, altitude above the ellipsoid), You (2000)."""
    r2 = x * x + y * y + z * z
    u = math.sqrt(0.5 * (r2 - _E**2) + 0.5 * math.hypot(r2 - _E**2, 2 * _E * z))
    hxy = math.hypot(x, y)
    hue = math.hypot(u, _E)
    if math.isclose(u, 0.0, abs_tol=1e-8) or math.isclose(hxy, 0.0, abs_tol=1e-8):
        beta = 0.0 if math.isclose(z, 0.0, abs_tol=1e-8) else math.copysign(math.pi / 2, z)
    else:
        beta = math.atan(hue / u * z / hxy)
        beta += ((SEMIMINOR * u - SEMIMAJOR * hue + _E**2) * math.sin(beta)) / (
            SEMIMAJOR * hue / math.cos(beta) - _E**2 * math.cos(beta))
    lat = math.atan(SEMIMAJOR / SEMIMINOR * math.tan(beta))
    altitude = math.hypot(z - SEMIMINOR * math.sin(beta), hxy - SEMIMAJOR * math.cos(beta))
    if (x * x + y * y) / SEMIMAJOR**2 + z * z / SEMIMINOR**2 < 1:  # inside the ellipsoid
        altitude = -altitude
    return math.degrees(lat), math.degrees(math.atan2(y, x)), altitude


def to_local(
    latitude: float, longitude: float, altitude_amsl: float,
    home_latitude: float, home_longitude: float, home_altitude_amsl: float,
) -> Point:
    """(north, east, up) in metres of a WGS84 point relative to home."""
    (x0, y0, z0), (sin_lat, cos_lat, sin_lon, cos_lon) = _frame(
        home_latitude, home_longitude, home_altitude_amsl)
    x, y, z = _ecef(latitude, longitude, altitude_amsl)
    u, v, w = x - x0, y - y0, z - z0
    t = cos_lon * u + sin_lon * v
    east = -sin_lon * u + cos_lon * v
    up = cos_lat * t + sin_lat * w
    north = -sin_lat * t + cos_lat * w
    return north, east, up


def to_global(
    north: float, east: float, up: float,
    home_latitude: float, home_longitude: float, home_altitude_amsl: float,
) -> tuple[float, float, float]:
    """(latitude, longitude, altitude AMSL) of a local point relative to home."""
    (x0, y0, z0), (sin_lat, cos_lat, sin_lon, cos_lon) = _frame(
        home_latitude, home_longitude, home_altitude_amsl)
    t = cos_lat * up - sin_lat * north
    w = sin_lat * up + cos_lat * north
    u = cos_lon * t - sin_lon * east
    v = sin_lon * t + cos_lon * east
    return _geodetic(x0 + u, y0 + v, z0 + w)


def horizontal_distance(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Ground distance in metres between two local points (north, east[, up])."""
    return math.hypot(a[0] - b[0], a[1] - b[1])


def distance(a: Point, b: Point) -> float:
    """Straight-line distance in metres between two local points."""
    return math.dist(a, b)
