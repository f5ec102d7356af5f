"""What a vehicle can do: the range of every number a mission may hold, per quantity.

Theory of operation: every number read from a mission or world file names the quantity it
measures (an action argument through its :class:`~tml.language.actions.ArgumentSpec`, a
condition through its built-in parameter, an environment attribute or a repeat count
through the builder and the checker), and :func:`out_of_range` is the one place that
decides whether the value is one a vehicle can fly. A value outside is refused with a
diagnostic where it was written, so that what validates is finite and of a size the
verifier and the interpreter can work with (a survey of 1e12 m, a spacing of 1e-320 m or
10^23 repeats validate no more than ``inf`` does). docs/language.md keeps the table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from tml.language.diagnostics import indefinite


class Quantity(StrEnum):
    """What a number measures; each has one range in :data:`RANGES`."""

    LATITUDE = "latitude"
    LONGITUDE = "longitude"
    ALTITUDE = "altitude"
    COORDINATE = "coordinate"
    DISTANCE = "distance"
    RADIUS = "radius"
    SPACING = "spacing"
    SPEED = "speed"
    DURATION = "duration"
    ANGLE = "angle"
    TURNS = "turns"
    COUNT = "count"
    REPEAT = "repeat"
    PERCENTAGE = "percentage"
    OPTICS = "optics"
    GROUND_RESOLUTION = "ground resolution"
    FIX_TYPE = "fix type"
    ITEM_PARAM = "mission item param"


@dataclass(frozen=True)
class Range:
    """The closed interval a quantity's values lie in, with its unit and what it covers."""

    low: float
    high: float
    unit: str
    covers: str

    def text(self) -> str:
        """``low to high unit``, as diagnostics and the documentation say it."""
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.low:,g} to {self.high:,g}{unit}"


RANGES: dict[Quantity, Range] = {
    Quantity.LATITUDE: Range(-90.0, 90.0, "deg", "WGS84 latitudes"),
    Quantity.LONGITUDE: Range(-180.0, 180.0, "deg", "WGS84 longitudes"),
    Quantity.ALTITUDE: Range(-10_000.0, 10_000.0, "m",
                             "altitudes (above home, sea level or terrain), the up of a point, "
                             "obstacle and geofence heights"),
    Quantity.COORDINATE: Range(-50_000.0, 50_000.0, "m",
                               "north and east of a point or a displacement, from home or "
                               "from the vehicle"),
    Quantity.DISTANCE: Range(0.0, 50_000.0, "m",
                             "distances to move, survey sides, distance to home"),
    Quantity.RADIUS: Range(0.0, 10_000.0, "m", "loiter, exploration and region radii"),
    Quantity.SPACING: Range(0.5, 10_000.0, "m", "distance between survey passes"),
    Quantity.SPEED: Range(0.0, 100.0, "m/s", "speeds"),
    Quantity.DURATION: Range(0.0, 86_400.0, "s",
                             "waits, loiter times, photo intervals, time limits and timeouts, "
                             "elapsed times"),
    Quantity.ANGLE: Range(-360.0, 360.0, "deg", "turns, headings and pitches"),
    Quantity.TURNS: Range(1.0, 1_000.0, "", "loiter turns"),
    Quantity.COUNT: Range(1.0, 10_000.0, "",
                          "photo counts, image widths in pixels, vehicles of a role"),
    Quantity.REPEAT: Range(1.0, 1_000.0, "",
                           "repeat times of one task; nested repeats multiply to at most "
                           "MAX_ROUNDS rounds"),
    Quantity.PERCENTAGE: Range(0.0, 100.0, "%", "battery charge, photo overlaps"),
    Quantity.OPTICS: Range(0.0, 1_000.0, "mm", "camera sensor sizes and focal lengths"),
    Quantity.GROUND_RESOLUTION: Range(0.0, 1_000.0, "cm/px",
                                      "ground resolution of a photo (ground sample distance)"),
    Quantity.FIX_TYPE: Range(0.0, 8.0, "", "GPS fix type (MAVLink GPS_FIX_TYPE)"),
    # What a 32-bit float carries: a raw item's params are the autopilot's to judge.
    Quantity.ITEM_PARAM: Range(-3.4028234663852886e38, 3.4028234663852886e38, "",
                               "params of a MISSION_ITEM (a 32-bit float; NaN: not set)"),
}
"""The sane range of each quantity: what a vehicle can do, with a margin."""

MAX_ROUNDS = 10_000
"""The most rounds a task may run through nested repeats (the product of their times)."""


def out_of_range(quantity: Quantity, value: float) -> str | None:
    """Why ``value`` is not a ``quantity`` a vehicle can fly (not finite, or outside its
    range), or None if it is one."""
    bounds = RANGES[quantity]
    if bounds.low <= value <= bounds.high:  # the common case: no words to build
        return None
    if not math.isfinite(value):
        return f"must be a finite number ({bounds.text()})"
    unit = f" {bounds.unit}" if bounds.unit else ""
    kind = indefinite(quantity.value)
    if value < bounds.low:
        return f"must be at least {bounds.low:,g}{unit} ({kind}: {bounds.text()})"
    if value > bounds.high:
        return f"must be at most {bounds.high:,g}{unit} ({kind}: {bounds.text()})"
    return None
