"""The mission's safety as the vehicle keeps it: its fence and rally points (no I/O).

What keeps a vehicle safe when tml is gone lives on the vehicle. Before the first take-off
the runner asks each vehicle (:class:`tml.vehicle.Safeguard`) to take the mission's
``<environment>`` as its own:

* the geofence polygon becomes an inclusion polygon (MAV_CMD_NAV_FENCE_POLYGON_VERTEX_
  INCLUSION, one item per corner, param1 the corner count) of the fence mission type;
* each obstacle the vehicle can never fly over or under -- from the ground (``bottom`` 0 or
  less) up to no ``top``, or a top at or above the geofence's ``max_altitude`` -- becomes an
  exclusion zone: a prism an exclusion polygon (..._VERTEX_EXCLUSION), a cylinder an
  exclusion circle (NAV_FENCE_CIRCLE_EXCLUSION, param1 the radius). ArduPilot's exclusion
  zones reach from the ground to the sky, so an obstacle a mission may fly over (a hangar
  8 m high) stays the verifier's and the simulator's business and is named as not uploaded;
* ``max_altitude`` becomes the parameter FENCE_ALT_MAX with bit 1 of FENCE_TYPE; bit 4
  (polygons and circles) is set when zones were uploaded; FENCE_ENABLE is set to 1 when
  either is. The circle around home (bit 2) is switched off: the mission's fence is the
  fence; FENCE_ACTION, what the vehicle does on a breach, stays the vehicle's and is said
  (:func:`fence_action`). ``min_altitude`` is not put on the vehicle: a copter takes off
  and lands below it, and ArduCopter's floor would have to be enabled in the air (the
  verifier checks it);
* the ``<rally>`` points become MAV_CMD_NAV_RALLY_POINT items of the rally mission type,
  altitudes relative to home, where ArduPilot's RTL may go instead of home.

Local positions are relative to the vehicle's home, as every local position of a mission
is (a fleet's vehicles each fly the mission around their own home). The adapter uploads the
items, reads them back and compares them by the vehicle's storage rules
(:func:`tml.mavlink.mission.ardupilot_form`), then sets the parameters and reads them back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from tml import geo
from tml.mavlink.mission import MissionItem, MissionType
from tml.world import Cylinder, Home, Point2, Prism, World

POLYGON_INCLUSION = 5001  # MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
POLYGON_EXCLUSION = 5002  # MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
CIRCLE_EXCLUSION = 5004  # MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
RALLY_POINT = 5100  # MAV_CMD_NAV_RALLY_POINT
FRAME_GLOBAL = 0  # MAV_FRAME_GLOBAL: how ArduPilot reads fence items back
FRAME_RELATIVE = 3  # MAV_FRAME_GLOBAL_RELATIVE_ALT
FENCE_ALT_MAX_BIT = 1
FENCE_CIRCLE_BIT = 2
FENCE_POLYGON_BIT = 4


FENCE_ACTIONS = {0: "report only", 1: "RTL or land", 2: "land", 3: "SmartRTL, RTL or land",
                 4: "brake or land", 5: "SmartRTL or land"}
"""ArduCopter's FENCE_ACTION values: what the vehicle does on a breach. tml leaves it as the
vehicle has it and says it (0, report only, is said as a warning: the fence stops nothing)."""


def fence_action(value: float | None) -> str:
    """How the journal says the vehicle's FENCE_ACTION ``value`` (None: not reported)."""
    if value is None:
        return "FENCE_ACTION not reported"
    said = f"FENCE_ACTION {value:g} ({FENCE_ACTIONS.get(round(value), 'unknown')})"
    return said + (": a breach is only reported" if round(value) == 0 else "")


@dataclass(frozen=True)
class Safeguards:
    """What goes onto a vehicle: fence items, rally items, the fence parameters, and the
    obstacles left out (with why)."""

    fence: list[MissionItem] = field(default_factory=list)
    rally: list[MissionItem] = field(default_factory=list)
    parameters: dict[str, float] = field(default_factory=dict)
    left_out: list[str] = field(default_factory=list)
    summary: str = ""

    @property
    def has_fence(self) -> bool:
        """True when the mission gives the vehicle a fence (zones or a ceiling)."""
        return bool(self.parameters)


def has_safeguards(world: World | None) -> bool:
    """True when ``world`` holds something to put on a vehicle: a geofence, an obstacle or
    a rally point."""
    return world is not None and bool(world.geofence or world.obstacles or world.rally)


def safeguards(world: World, home: Home, *, fence: bool = True) -> Safeguards:
    """The fence and rally items, fence parameters and a one-line summary of ``world`` for
    a vehicle whose home is ``home`` (``fence`` False: rally points only)."""
    items: list[MissionItem] = []
    said: list[str] = []
    left_out: list[str] = []
    geofence = world.geofence
    ceiling = geofence.max_altitude if geofence is not None else None
    if fence:
        if geofence is not None and len(geofence.polygon) >= 3:
            items += _polygon(geofence.polygon, POLYGON_INCLUSION, home, len(items))
            said.append(f"inclusion polygon of {len(geofence.polygon)} corners")
        for obstacle in world.obstacles:
            if obstacle.bottom > 0 or (math.isfinite(obstacle.top) and (
                    ceiling is None or obstacle.top < ceiling)):
                left_out.append(f"{obstacle.name} (can be flown "
                                f"{'under' if obstacle.bottom > 0 else 'over'})")
            elif isinstance(obstacle, Cylinder):
                lat, lon = _global((obstacle.north, obstacle.east), home)
                items.append(MissionItem(len(items), FRAME_GLOBAL, CIRCLE_EXCLUSION,
                                         param1=obstacle.radius, x=lat, y=lon,
                                         mission_type=MissionType.FENCE))
                said.append(f"exclusion circle {obstacle.name}")
            elif isinstance(obstacle, Prism):
                items += _polygon(obstacle.polygon, POLYGON_EXCLUSION, home, len(items))
                said.append(f"exclusion polygon {obstacle.name}")
    kinds = 0
    parameters: dict[str, float] = {}
    if fence and ceiling is not None:
        kinds |= FENCE_ALT_MAX_BIT
        parameters["FENCE_ALT_MAX"] = ceiling
        said.append(f"FENCE_ALT_MAX {ceiling:g} m")
    if items:
        kinds |= FENCE_POLYGON_BIT
    if kinds:
        parameters |= {"FENCE_TYPE": kinds, "FENCE_ENABLE": 1}
        said.append(f"FENCE_TYPE {kinds}, FENCE_ENABLE 1")
    rally: list[MissionItem] = []
    for point in world.rally:
        lat, lon = _global((point.north, point.east), home)
        rally.append(MissionItem(len(rally), FRAME_RELATIVE, RALLY_POINT, x=lat, y=lon,
                                 z=point.altitude, mission_type=MissionType.RALLY))
    if rally:
        said.append(f"{len(rally)} rally point{'s' if len(rally) > 1 else ''}")
    if left_out:
        said.append("not uploaded: " + ", ".join(left_out))
    return Safeguards(items, rally, parameters, left_out, "; ".join(said))


def _global(point: Point2, home: Home) -> tuple[int, int]:
    lat, lon, _ = geo.to_global(point[0], point[1], 0.0, home.latitude, home.longitude,
                                home.altitude)
    return round(lat * 1e7), round(lon * 1e7)


def _polygon(corners: tuple[Point2, ...], command: int, home: Home,
             first: int) -> list[MissionItem]:
    items = []
    for i, corner in enumerate(corners):
        lat, lon = _global(corner, home)
        items.append(MissionItem(first + i, FRAME_GLOBAL, command, param1=len(corners),
                                 x=lat, y=lon, mission_type=MissionType.FENCE))
    return items
