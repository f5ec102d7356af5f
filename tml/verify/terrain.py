"""Verify above the ground: the clearance of the predicted paths over terrain data.

A pass over the paths the flight model predicts (:class:`tml.verify.motion.Step`), apart
from the model itself. Each straight segment of a path is sampled at least every half
sample spacing of the data (:meth:`tml.terrain.Terrain.along`); the vehicle's altitude
there is home's altitude AMSL plus its predicted height above home, varying linearly along
the segment, and its clearance that altitude less the ground's height (both above the
EGM96 geoid). The lowest clearance of an action is shown in verify's table; one below the
profile's ``min_terrain_clearance`` is a ``terrain`` violation naming the action's line
and the place (latitude, longitude). A place the data does not cover, or a void, is a
``terrain`` violation too, naming the missing tile.

The climb from the ground of a take-off and the last descent of a landing come close to
the ground by design: a segment that starts on the ground (the action starts landed) or
ends on it (the action ends landed) is not sampled, though the point a take-off climbs to
is. An action that does not move (WAIT, SET_SPEED ...) is not judged again where the
action before it left the vehicle.

``altitude_reference="terrain"`` positions are placed at the ground's height there plus
their altitude (the flight model's ``ground`` hook, set by :func:`ground_check`), so their
climbs and descents cost time and battery.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import pairwise

from tml import geo
from tml.errors import Location, TerrainNotCovered
from tml.terrain import Terrain
from tml.verify.constraints import Constraint, Violation
from tml.verify.motion import FlightModel, Step
from tml.verify.planner import Point3
from tml.world import Home

HOME_TOLERANCE = 10.0
"""Metres by which ``<home>``'s altitude may differ from the ground's height under it before
the report warns (SRTM's heights are good to about this, 90 % of the time)."""


@dataclass(frozen=True)
class Lowest:
    """The lowest clearance of a path over the ground, and where it is."""

    clearance: float  # m above the ground
    latitude: float
    longitude: float
    ground: float  # m AMSL there

    @property
    def place(self) -> str:
        return f"{self.latitude:.6f}, {self.longitude:.6f}"


class GroundCheck:
    """The clearance of a vehicle's paths over ``terrain``, from ``home``."""

    def __init__(self, terrain: Terrain, home: Home, minimum: float) -> None:
        self.terrain = terrain
        self.home = home
        self.minimum = minimum

    def height(self, latitude: float, longitude: float) -> float | None:
        """The ground's height AMSL, or None where the data does not say."""
        try:
            return self.terrain.height(latitude, longitude)
        except TerrainNotCovered:
            return None

    def place(self, point: Point3) -> tuple[float, float, float]:
        """Latitude, longitude and altitude AMSL of a local point (its height is above
        home's altitude: the vehicle holds it, it does not follow the Earth's curve)."""
        latitude, longitude, _ = geo.to_global(point[0], point[1], 0.0, self.home.latitude,
                                               self.home.longitude, self.home.altitude)
        return latitude, longitude, self.home.altitude + point[2]

    def lowest(self, step: Step) -> Lowest | None:
        """The lowest clearance along ``step``'s path (None: nothing sampled, e.g. on the
        ground); raises :class:`TerrainNotCovered` where the data stops or has a void."""
        segments = _segments(step)
        found: Lowest | None = None
        for start, end in segments:
            a, b = self.place(start), self.place(end)
            metres = geo.horizontal_distance(start, end)
            fractions, ground = self.terrain.along(a[:2], b[:2], metres)
            clearance = a[2] + fractions * (b[2] - a[2]) - ground
            i = int(clearance.argmin())
            if found is None or clearance[i] < found.clearance:
                f = float(fractions[i])
                found = Lowest(float(clearance[i]), a[0] + f * (b[0] - a[0]),
                               a[1] + f * (b[1] - a[1]), float(ground[i]))
        return found

    def violation(self, step: Step, action: str, location: Location | None
                  ) -> Violation | None:
        """A ``terrain`` violation of ``step``, if it has one."""
        try:
            lowest = self.lowest(step)
        except TerrainNotCovered as exc:
            return Violation(Constraint.TERRAIN, str(exc), math.nan, "", math.nan, "",
                             action, location)
        if lowest is None or lowest.clearance >= self.minimum:
            return None
        return Violation(Constraint.TERRAIN,
                         f"clearance above the ground at {lowest.place} (ground "
                         f"{lowest.ground:.0f} m AMSL)", lowest.clearance, ">=",
                         self.minimum, "m", action, location)

    def table_value(self, steps: list[Step]) -> float | None:
        """The lowest clearance of any of ``steps`` (the ways an action is flown) for the
        table: None when nothing was sampled, NaN where the data does not cover a path."""
        values = []
        for step in steps:
            try:
                lowest = self.lowest(step)
            except TerrainNotCovered:
                return math.nan
            if lowest is not None:
                values.append(lowest.clearance)
        return min(values, default=None)

    def home_warning(self) -> str | None:
        """A warning when ``<home>``'s altitude is not the ground's height under it."""
        ground = self.height(self.home.latitude, self.home.longitude)
        if ground is None:
            return "the terrain data does not cover home: nothing near it can be verified " \
                   "above the ground"
        if abs(ground - self.home.altitude) <= HOME_TOLERANCE:
            return None
        off = ground - self.home.altitude
        return (f"the ground under home is {ground:.0f} m above the EGM96 geoid (the terrain "
                f"data's datum), {abs(off):.0f} m {'above' if off > 0 else 'below'} <home>'s "
                f"altitude {self.home.altitude:g} m: heights above home are off by as much; "
                "give <home> the ground's altitude")


def _segments(step: Step) -> list[tuple[Point3, Point3]]:
    """The straight segments of a step's path that are held above the ground: not the
    first when it starts on the ground (a take-off's climb: the point it climbs to is held,
    as a segment of no length), nor the last when it ends there (a landing's descent). An
    action that does not move is not judged again where the action before left it."""
    points = step.path_points()
    segments = list(pairwise(points))
    if segments and not step.before.flying:
        segments = segments[1:] if len(segments) > 1 or not step.after.flying else \
            [(points[-1], points[-1])]
    if segments and not step.after.flying:
        segments = segments[:-1]
    return segments


def ground_check(model: FlightModel, terrain: Terrain | None) -> GroundCheck | None:
    """The check of a flight model's paths over ``terrain`` (None: no terrain, or a ground
    vehicle, which drives on it), with the model's terrain-relative positions placed on it."""
    from tml.language.kinds import Kind

    if terrain is None or model.profile.kind is Kind.GROUND:
        return None
    check = GroundCheck(terrain, model.home, model.profile.min_terrain_clearance)
    model.ground = check.height
    return check
