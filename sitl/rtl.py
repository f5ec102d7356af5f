"""ArduCopter's RTL: climb to the return altitude, fly home at it, loiter, land.

The return altitude is ``RTL_ALT``, or the present altitude (plus ``RTL_CLIMB_MIN``) if
higher, but no higher than ``RTL_CONE_SLOPE`` times the distance home, so a vehicle
already near home does not climb (``ModeRTL::compute_return_target``). The climb and the
return are two waypoint legs, the first blended into the second; the vehicle then
loiters ``RTL_LOIT_TIME`` ms and lands. "Home" is the nearest uploaded rally point when
that is nearer (at no less than its altitude; :meth:`CopterRtl.destination`). A plane
and a rover return their own way (:mod:`sitl.plane`, :mod:`sitl.rover`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from sitl.missions import RALLY

if TYPE_CHECKING:
    from sitl.model import VehicleModel

Vector = tuple[float, float, float]
RTL_ALT_MIN = 2.0  # m, ArduCopter's lowest RTL return altitude


class CopterRtl:
    """The RTL in progress: its ``phase`` ("" when none, "climb", "return", "loiter",
    "land"), where it lands, and since when it loiters."""

    def __init__(self) -> None:
        self.phase = ""
        self._to: Vector = (0.0, 0.0, 0.0)  # where the RTL in progress lands
        self._since = 0.0

    def start(self, v: VehicleModel) -> None:
        """Begin the return of ``v`` from where it can stop."""
        p, here = v.params, v._stopping_point(keep_altitude=True)
        home, rally_altitude = self.destination(v, here)
        self._to = home
        lowest = max(RTL_ALT_MIN, here[2] + max(0.0, p["RTL_CLIMB_MIN"] / 100.0))
        altitude = max(p["RTL_ALT"] / 100.0, lowest)
        distance = math.hypot(home[0] - here[0], home[1] - here[1])
        if p["RTL_CONE_SLOPE"] >= 0.5:
            altitude = min(altitude, max(distance * p["RTL_CONE_SLOPE"], lowest))
        altitude = max(altitude, here[2], rally_altitude)
        self.phase = "climb"
        v._fly_legs((here[0], here[1], altitude), (home[0], home[1], altitude))

    @staticmethod
    def destination(v: VehicleModel, here: Vector) -> tuple[Vector, float]:
        """Where RTL returns to, and the least altitude there: ArduCopter's
        ``AP_Rally::calc_best_rally_or_home_location``. The rally point nearest to ``here``
        (one within ``RALLY_LIMIT_KM`` of home, when that is above 0), unless home is nearer
        and ``RALLY_INCL_HOME`` is set; else home (0: no least altitude)."""
        home = v.home_local()
        best: tuple[float, Vector, float] | None = None
        limit = v.params["RALLY_LIMIT_KM"] * 1000.0
        for item in v.missions.items(RALLY):
            point = v._local(item.x / 1e7, item.y / 1e7, v.origin.altitude)
            if limit > 0 and math.hypot(point[0] - home[0], point[1] - home[1]) > limit:
                continue
            distance = math.hypot(point[0] - here[0], point[1] - here[1])
            if best is None or distance < best[0]:
                best = (distance, (point[0], point[1], home[2]), home[2] + item.z)
        if best is None or (v.params["RALLY_INCL_HOME"] and math.hypot(
                home[0] - here[0], home[1] - here[1]) <= best[0]):
            return home, 0.0
        return best[1], best[2]

    def update(self, v: VehicleModel) -> None:
        """Move on to the next phase once ``v`` has done this one."""
        if not self.phase or not v.armed:
            return
        if self.phase == "climb" and v._leg_reached():
            self.phase = "return"
            track = v._track
            assert track is not None
            if track.next is not None:
                v._fly_legs(track.next.destination)
        elif self.phase == "return" and v._leg_reached():
            self.phase, self._since = "loiter", v.time
        elif self.phase == "loiter" and (
            v.time - self._since >= v.params["RTL_LOIT_TIME"] / 1000.0
        ):
            self.phase = "land"
            v.land_at(self._to[0], self._to[1])
