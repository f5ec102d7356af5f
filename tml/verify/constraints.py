"""The constraints of the feasibility model, grouped by action category, and the check the
interpreter runs before each action.

As in the TML paper, an action is checked only against the constraints of its category
(:data:`BY_CATEGORY`): a camera action is not held to the geofence, a rotation is not held
to c1. The paper's three constraints, with x1 the current point, x2 the destination, x3 the
battery charge and x4 the planned arrival time:

- c1: DistanceObstacle(x2) >= k2 (the minimum clearance);
- c2: Length(Trajectory(x1, x2)) <= DistanceBattery(x3, k1);
- c3: Speed(x1, x2, x4) <= k3 (the maximum speed), and a SET_SPEED within the vehicle's.

and the others: a collision-free path exists (``path``), the geofence polygon and the
altitude limits hold (``geofence``, ``altitude``), the vehicle stays within its range of
home (``range``), at every point of the path there is battery to come home and land with
the reserve left (``return-reserve``; not asked of the actions that go home, which are what
the reserve is for), the flight time and deadlines are met (``time``),
motion needs a flying vehicle (``airborne``), loiter circles are not tighter than the
vehicle can fly (``turn-radius``), labels read hold a point (``label``), and the vehicle
can do the action at all (``vehicle``: a rover does not take off, a fixed-wing does not
turn in place; :func:`tml.language.kinds.refusal`), whatever its category.

:func:`check_before_action` and :func:`assess_action` are pure: the interpreter gives the
live state and gets the violations, from which it raises ACTION_FAILURE = infeasible.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from functools import lru_cache

from tml.errors import Location
from tml.language.actions import BoundAction, Category
from tml.language.kinds import Kind, refusal
from tml.verify import functions
from tml.verify.motion import FlightModel, Labels, PredictedState, Step
from tml.verify.planner import Point3, straight
from tml.verify.profile import VehicleProfile
from tml.world import World


class Constraint(StrEnum):
    """Names of the constraints, as printed and in JSON."""

    C1 = "c1"
    C2 = "c2"
    C3 = "c3"
    PATH = "path"
    GEOFENCE = "geofence"
    ALTITUDE = "altitude"
    RANGE = "range"
    RETURN_RESERVE = "return-reserve"
    TIME = "time"
    AIRBORNE = "airborne"
    TURN_RADIUS = "turn-radius"
    LABEL = "label"
    VEHICLE = "vehicle"
    TERRAIN = "terrain"  # judged over terrain data when given (tml.verify.terrain)


_C = Constraint
_MOVING = frozenset({_C.LABEL, _C.C1, _C.PATH, _C.C2, _C.GEOFENCE, _C.ALTITUDE, _C.RANGE,
                     _C.RETURN_RESERVE, _C.TIME})
BY_CATEGORY: dict[Category, frozenset[Constraint]] = {
    Category.TRANSLATION: _MOVING | {_C.AIRBORNE, _C.C3},
    Category.TAKE_OFF_LANDING: _MOVING,
    Category.HOVER: _MOVING | {_C.AIRBORNE, _C.TURN_RADIUS},
    Category.ROTATION: frozenset({_C.AIRBORNE, _C.C2, _C.RETURN_RESERVE, _C.TIME}),
    Category.PAYLOAD: frozenset({_C.AIRBORNE, _C.C2, _C.RETURN_RESERVE, _C.TIME}),
    Category.CAMERA: frozenset({_C.C2, _C.TIME}),
    Category.MEMORY: frozenset(),
    Category.CONFIGURATION: frozenset({_C.C3}),
}

# How the checks below report: (constraint, message, value, relation, limit, unit).
_Fail = Callable[[Constraint, str, float, str, float, str], None]


@dataclass(frozen=True)
class Violation:
    """A constraint that does not hold: ``value`` should be ``relation`` ``limit``.

    A ``vehicle`` violation has no numbers (``relation`` is empty): the message says what
    the vehicle cannot do.
    """

    constraint: Constraint
    message: str
    value: float
    relation: str  # the relation that must hold between value and limit: "<=" or ">="
    limit: float
    unit: str
    action: str
    location: Location | None = None
    task: str = ""
    role: str = ""  # the role whose vehicles break it, in a mission that declares roles
    vehicles: tuple[int, ...] = ()  # which of the role's vehicles (1, 2 ... in pick order)

    @property
    def excess(self) -> float:
        """How far the value is on the wrong side of the limit (for ranking)."""
        if not self.relation or math.isinf(self.value) or math.isinf(self.limit):
            return math.inf
        return self.value - self.limit if self.relation == "<=" else self.limit - self.value

    def __str__(self) -> str:
        where = f"{self.location}: " if self.location else ""
        if not self.relation:
            return f"{where}{self.constraint.value}: {self.action}: {self.message}"
        return (f"{where}{self.constraint.value}: {self.action}: {self.message}: "
                f"{_number(self.value)} {self.unit}, must be {self.relation} "
                f"{_number(self.limit)} {self.unit}")

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready dictionary (infinite numbers as null)."""
        return {
            "constraint": self.constraint.value, "action": self.action, "task": self.task,
            "file": self.location.file if self.location else None,
            "line": self.location.line if self.location else None,
            "message": self.message, "value": _finite(self.value),
            "relation": self.relation or None, "limit": _finite(self.limit),
            "unit": self.unit or None,
        }


def _number(value: float) -> str:
    return "inf" if math.isinf(value) else f"{value:.1f}"


def _finite(value: float) -> float | None:
    return None if math.isinf(value) or math.isnan(value) else round(value, 3)


def check_step(bound: BoundAction, step: Step, model: FlightModel,
               deadline: float | None = None,
               unasked: frozenset[Constraint] = frozenset()) -> list[Violation]:
    """Every constraint of the action's category that ``step`` breaks.

    ``deadline`` (s, mission time) is when the action must be over, if it has to be.
    ``unasked``: constraints the caller does not want judged (not even computed: the
    reserve check plans ways home).
    """
    wanted = BY_CATEGORY[bound.spec.category] - unasked
    location = bound.action.location
    found: list[Violation] = []

    def fail(constraint: Constraint, message: str, value: float, relation: str, limit: float,
             unit: str) -> None:
        if constraint in wanted:
            found.append(Violation(constraint, message, value, relation, limit, unit,
                                   bound.name, location))

    profile, before, after = model.profile, step.before, step.after
    cannot = refusal(bound, profile.kind, profile.vehicle_type)
    if cannot is not None:
        found.append(Violation(_C.VEHICLE, cannot, math.nan, "", math.nan, "", bound.name,
                               location))
    # A ground vehicle is not airborne, ever: its first move arms it.
    if not before.flying and profile.kind is not Kind.GROUND and \
            (step.legs or step.loiter or (step.duration > 0 and not step.grounded)):
        fail(_C.AIRBORNE, "the vehicle is on the ground; take off first",
             before.position[2], ">", 0.0, "m")
    if step.unknown_label:
        fail(_C.LABEL, f"label {step.unknown_label!r} holds no point on some way to here",
             0.0, ">=", 1.0, "points")
    _obstacles(step, model, fail)
    # Going home is what the reserve is kept for.
    _battery(step, model, _C.RETURN_RESERVE in wanted
             and not bound.name.startswith("RETURN_HOME"), fail)
    _speed(step, model, deadline, fail)
    _limits(step, model, fail)
    if profile.max_flight_time > 0 and after.time > profile.max_flight_time:
        fail(_C.TIME, "the flight lasts longer than the profile allows", after.time, "<=",
             profile.max_flight_time, "s")
    if deadline is not None and after.time > deadline:
        fail(_C.TIME, "the action ends after its deadline", after.time, "<=", deadline, "s")
    return found


def _obstacles(step: Step, model: FlightModel, fail: _Fail) -> None:
    planner, k2 = model.planner, model.profile.min_clearance
    if step.loiter is not None:
        clear = planner.clearance_of(step.loiter.points())
        if clear < k2:
            fail(_C.C1, "DistanceObstacle(loiter circle) is below the clearance", clear, ">=",
                 k2, "m")
    elif step.destination is not None:
        clear, name = planner.nearest(step.destination)
        if clear < k2:
            fail(_C.C1, f"DistanceObstacle(destination) to {name!r} is below the clearance",
                 clear, ">=", k2, "m")
    for start, end in step.blocked:
        clear = planner.clearance_of(straight(start, end).points)
        fail(_C.PATH, f"no collision-free path from {_point(start)} to {_point(end)}; the "
                      "straight line passes too close", clear, ">=", k2, "m")


def _battery(step: Step, model: FlightModel, reserve: bool, fail: _Fail) -> None:
    profile, before, after = model.profile, step.before, step.after
    if step.energy > max(before.battery, 0.0) + 1e-9:
        if step.distance > 0:
            rate = step.energy / step.distance
            fail(_C.C2, f"Length(Trajectory) exceeds DistanceBattery(battery "
                        f"{before.battery:.1f}%, {rate:.4f}%/m)", step.distance, "<=",
                 functions.distance_battery(before.battery, rate), "m")
        else:
            fail(_C.C2, f"the action needs more than the {before.battery:.1f}% battery left",
                 step.energy, "<=", before.battery, "%")
    if not reserve:
        return
    points = step.waypoints()
    if not after.flying and points:
        points = points[:-1]  # the action ends on the ground: no need to come home
    if after.flying:
        points.append((after.position, after.battery))
    # The point the action starts from was judged with the action before.
    points = [(p, b) for p, b in dict(points).items()
              if p != before.position and _airborne(p, before, after)]
    # Straight lines home cost a lower bound of the planned way: the margin they leave is
    # an upper bound, so once it is above the worst planned margin found, no point further
    # down the list can be worse and planning stops.
    bounds = sorted((b - model.return_home_energy(p, after.home, planned=False), p, b)
                    for p, b in points)
    worst: tuple[float, Point3] | None = None
    empty = min(0.0, profile.battery_reserve - 1e-9)
    for bound, point, battery in bounds:
        if worst is not None and bound >= worst[0]:
            break
        if len(bounds) == 1 and bound < empty:
            # The one point: the battery runs out even on the straight way home, so it
            # does on the planned one, and what is reported (that it runs out, from this
            # point) does not depend on how much longer that way is.
            worst = (bound, point)
            break
        left = battery - model.return_home_energy(point, after.home)
        if worst is None or left < worst[0]:
            worst = (left, point)
    if worst is not None and worst[0] < profile.battery_reserve - 1e-9:
        if worst[0] < 0:  # no negative charge: the battery is empty before home
            fail(_C.RETURN_RESERVE, f"the battery runs out on the way home from "
                                    f"{_point(worst[1])}", 0.0, ">=",
                 profile.battery_reserve, "%")
        else:
            fail(_C.RETURN_RESERVE, f"battery left after coming home from {_point(worst[1])}",
                 worst[0], ">=", profile.battery_reserve, "%")


def _airborne(point: Point3, before: PredictedState, after: PredictedState) -> bool:
    return before.flying or after.flying or point[2] > 0


def _speed(step: Step, model: FlightModel, deadline: float | None, fail: _Fail) -> None:
    profile = model.profile
    if step.requested_speed is not None:
        kind, value = step.requested_speed
        limit = {"climb": profile.climb_rate, "descent": profile.descent_rate}.get(
            kind, profile.max_speed)
        if value > limit:
            fail(_C.C3, f"the {kind} speed asked for is above the vehicle's", value, "<=",
                 limit, "m/s")
    if deadline is not None and step.distance > 0:
        needed = functions.speed(step.distance, step.before.time, deadline)
        if needed > profile.max_speed:
            fail(_C.C3, "Speed(x1, x2, deadline) is above the maximum speed", needed, "<=",
                 profile.max_speed, "m/s")


def _limits(step: Step, model: FlightModel, fail: _Fail) -> None:
    profile, fence = model.profile, model.world.geofence
    # The point the action starts from was judged with the action before.
    points = [p for p in step.path_points() if p != step.before.position]
    if step.loiter is not None and step.loiter.radius < profile.min_turn_radius:
        fail(_C.TURN_RADIUS, "the loiter circle is tighter than the vehicle can turn",
             step.loiter.radius, ">=", profile.min_turn_radius, "m")
    if not points:
        return
    ceiling = profile.max_altitude
    floor = profile.min_altitude
    if fence is not None:
        ceiling = min(ceiling, fence.max_altitude if fence.max_altitude is not None else ceiling)
        floor = max(floor, fence.min_altitude if fence.min_altitude is not None else floor)
    highest = max(p[2] for p in points)
    if highest > ceiling:
        fail(_C.ALTITUDE, "the path climbs above the altitude limit", highest, "<=", ceiling,
             "m")
    if step.cruise and step.destination is not None and step.destination[2] < floor:
        fail(_C.ALTITUDE, "the destination is below the lowest cruise altitude",
             step.destination[2], ">=", floor, "m")
    home = step.after.home
    farthest = max(math.hypot(p[0] - home[0], p[1] - home[1]) for p in points)
    if farthest > profile.max_range:
        fail(_C.RANGE, "the path goes farther from home than the vehicle's range", farthest,
             "<=", profile.max_range, "m")
    if fence is not None and len(fence.polygon) >= 3:
        # Imported here: a mission without a geofence or obstacles needs neither shapely
        # nor numpy, and a third of tml run's start-up was importing them.
        import numpy as np
        import shapely
        from shapely.geometry import LineString, Point, Polygon

        polygon = Polygon(fence.polygon)
        path = LineString([p[:2] for p in points]) if len(points) > 1 else Point(points[0][:2])
        outside = path.difference(polygon)
        if not outside.is_empty:
            corners = shapely.points(shapely.get_coordinates(outside))
            beyond = float(np.max(shapely.distance(corners, polygon)))
            fail(_C.GEOFENCE, "the path leaves the geofence polygon", beyond, "<=", 0.0, "m")


def _point(point: Point3) -> str:
    return "(" + ", ".join(f"{v:.1f}" for v in point) + ")"


@dataclass(frozen=True)
class Assessment:
    """The predicted outcome of an action and the constraints it breaks."""

    step: Step
    violations: tuple[Violation, ...]

    @property
    def feasible(self) -> bool:
        """True when no constraint is broken."""
        return not self.violations


@lru_cache(maxsize=8)
def flight_model(profile: VehicleProfile, world: World | None) -> FlightModel:
    """The flight model of a profile and a world, kept for the next call with the same."""
    return FlightModel(profile, world)


def assess_action(bound: BoundAction, state: PredictedState, profile: VehicleProfile,
                  world: World | None = None, labels: Labels | None = None,
                  deadline: float | None = None) -> Assessment:
    """Predict ``bound`` from the live ``state`` and check its category's constraints.

    Pure: no I/O, no clock; the same arguments give the same answer. ``labels`` are the
    points memorized so far, ``deadline`` the mission time (s) the action must end by.
    """
    model = flight_model(profile, world)
    step = model.step(bound, state, labels)
    return Assessment(step, tuple(check_step(bound, step, model, deadline)))


def check_before_action(bound: BoundAction, state: PredictedState, profile: VehicleProfile,
                        world: World | None = None, labels: Labels | None = None,
                        deadline: float | None = None) -> list[Violation]:
    """The constraints ``bound`` would break if started now from ``state`` (empty: go).

    The interpreter calls it before each action with live telemetry and raises
    ACTION_FAILURE = infeasible when the list is not empty.
    """
    return list(assess_action(bound, state, profile, world, labels, deadline).violations)
