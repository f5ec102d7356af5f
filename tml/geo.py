"""Conversions between the local mission frame and WGS84, via pymap3d.

The local frame of tml: metres from the home position, ``north`` and ``east`` on the
ground plane and ``up`` above home (the same axes as MAVLink's LOCAL_NED x and y, with
z pointing up). Global positions are latitude/longitude in degrees and altitude in metres
above mean sea level (AMSL); an altitude "relative" to home is ``up``.
"""

from __future__ import annotations

import math

Point = tuple[float, float, float]
"""A local point: (north, east, up) in metres from home."""


def to_local(
    latitude: float, longitude: float, altitude_amsl: float,
    home_latitude: float, home_longitude: float, home_altitude_amsl: float,
) -> Point:
    """(north, east, up) in metres of a WGS84 point relative to home."""
    import pymap3d  # imports numpy: only when a conversion is needed

    east, north, up = pymap3d.geodetic2enu(
        latitude, longitude, altitude_amsl, home_latitude, home_longitude, home_altitude_amsl
    )
    return float(north), float(east), float(up)


def to_global(
    north: float, east: float, up: float,
    home_latitude: float, home_longitude: float, home_altitude_amsl: float,
) -> tuple[float, float, float]:
    """(latitude, longitude, altitude AMSL) of a local point relative to home."""
    import pymap3d

    latitude, longitude, altitude = pymap3d.enu2geodetic(
        east, north, up, home_latitude, home_longitude, home_altitude_amsl
    )
    return float(latitude), float(longitude), float(altitude)


def horizontal_distance(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Ground distance in metres between two local points (north, east[, up])."""
    return math.hypot(a[0] - b[0], a[1] - b[1])


def distance(a: Point, b: Point) -> float:
    """Straight-line distance in metres between two local points."""
    return math.dist(a, b)
