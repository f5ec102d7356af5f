"""The GUIDED toolkit: what the action procedures flying with commands are made of.

An action flown with ``dispatch="command"`` is a generator (its procedure, the ``guided``
part of its :class:`~tml.actions.definition.ActionDef`) that yields steps to the
interpreter and never does I/O:

- :class:`Send` a request and wait for its result (a refusal fails the action);
- :class:`Until` a predicate on the vehicle state holds, within a time limit derived from
  distance and speed (running out fails the action with ACTION_FAILURE ``timeout``);
- :class:`Sleep` for a time.

A procedure fails the action by raising :class:`ActionFailed` with an ACTION_FAILURE reason
(``rejected``, ``timeout``, ``unsupported``, ``infeasible``, ``general``). Completion is
always observed in telemetry: position within the acceptance radius, altitude reached,
heading reached, landed and disarmed. The points of a pattern (SURVEY_AREA's lawnmower,
EXPLORE_SPACE's expanding square, a LOITER's circle, a MOVE in the body frame) come from
:mod:`tml.patterns`, as the mission compiler and the verifier take them.

Each procedure flies the action the way the vehicle's kind can (:mod:`tml.language.kinds`, from
the type the vehicle reports): a multicopter as ArduCopter in GUIDED; a fixed-wing as
ArduPlane (it takes off in TAKEOFF mode, circles the points it is sent to, circles
natively for LOITER, holds by circling, and lands along an approach); a ground vehicle as
ArduPilot Rover (it arms itself for its first move, drives at 0 m, and its
RETURN_HOME_AND_LAND drives home, stops and disarms). :func:`tml.engine.scripts.script_for`
picks the procedure, or refuses the action with ACTION_FAILURE ``infeasible`` when the kind
cannot do it at all (:func:`tml.language.kinds.refusal`), before anything is sent.

The steps shared by several actions live here (:func:`fly_to`, :func:`circle`,
:func:`glide` ...); each action's own procedure lives in its module of :mod:`tml.actions`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from dataclasses import dataclass
from itertools import pairwise
from typing import Protocol

from tml import geo
from tml.geo import Point
from tml.language.actions import BoundAction
from tml.language.failures import FailureReason
from tml.language.kinds import HANDLING, Kind, final_length, kind_of
from tml.patterns import CIRCLE_POINTS_PER_TURN, circle_entry, circle_point, stop_to_stop
from tml.vehicle import (
    SHOWN_FIELDS,
    Arm,
    Circle,
    GoTo,
    Land,
    Request,
    SetMode,
    SetYaw,
    VehicleState,
)
from tml.world import World


class ActionFailed(Exception):
    """An action could not be completed; ``reason`` is the ACTION_FAILURE value."""

    def __init__(self, reason: FailureReason | str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = FailureReason(reason)
        self.detail = detail


@dataclass(frozen=True)
class Send:
    """Submit a request; the script resumes when the vehicle has accepted it."""

    request: Request


UNTIL_READS = frozenset(SHOWN_FIELDS)
"""What an :class:`Until` that does not say reads of its vehicle's state: any field that
says what the vehicle shows, and whether the picture is newer than the latest request
(``current``, which no compared field tells)."""


@dataclass(frozen=True)
class Until:
    """Wait until ``predicate(state)`` holds; fail with ``timeout`` after ``limit`` s.
    ``reads``: the fields of the state the predicate reads (``current`` is judged too;
    by default :data:`UNTIL_READS`). The wait is looked at again only when one of them
    changes, or at its limit (:mod:`tml.engine.wake`)."""

    predicate: Callable[[VehicleState], bool]
    limit: float
    what: str
    progress: Callable[[VehicleState], float] | None = None
    reads: frozenset[str] = UNTIL_READS


@dataclass(frozen=True)
class Sleep:
    """Wait ``seconds`` of mission time."""

    seconds: float


Step = Send | Until | Sleep


Script = Generator[Step, None, None]


Cruise = tuple[float, float]
"""How a vehicle moves from point to point, as its profile says: its speed until SET_SPEED
changes it (m/s) and its acceleration speeding up and braking at each point (m/s²; 0: at
once)."""


NO_PROFILE: Cruise = (5.0, 0.0)
"""How a vehicle is taken to move when no profile says (engine tests)."""


def _no_profile(vehicle_type: str) -> Cruise:
    return NO_PROFILE


@dataclass
class Limits:
    """What the scripts assume of the vehicle when they set time limits and tolerances."""

    speed: float | None = None  # m/s horizontal set by SET_SPEED; None: the cruise speed
    # How a vehicle of a type ("" while not known) moves until SET_SPEED: its profile's
    # cruise speed and acceleration (tml.verify.inflight.cruise, read with a profile).
    cruise: Callable[[str], Cruise] = _no_profile
    climb_rate: float = 2.5  # m/s
    descent_rate: float = 1.5  # m/s
    land_rate: float = 0.5  # m/s: ArduCopter lands at LAND_SPEED (50 cm/s) near the ground
    yaw_rate: float = 45.0  # deg/s
    acceptance_radius: float = 0.5  # m, horizontal and vertical
    heading_tolerance: float = 5.0  # deg
    ready_timeout: float = 120.0  # s for a position estimate before arming (ArduPilot EKF)
    flip_altitude: float = 10.0  # m above home a flip starts from: one costs ArduCopter ~4 m
    slack: float = 15.0  # s added to every time limit
    factor: float = 2.0  # time limits are this many times the nominal time

    def move_speed(self, vehicle_type: str) -> float:
        """m/s a vehicle of ``vehicle_type`` moves at now: the speed SET_SPEED put in
        force, else its profile's cruise speed."""
        return self.speed if self.speed is not None else self.cruise(vehicle_type)[0]

    def leg_seconds(self, vehicle_type: str, metres: float) -> float:
        """Seconds a vehicle of ``vehicle_type`` takes to move ``metres`` from a stop to a
        stop, at the speed in force (:meth:`move_speed`) and its profile's acceleration."""
        return stop_to_stop(metres, self.move_speed(vehicle_type), self.cruise(vehicle_type)[1])


class Context(Protocol):
    """What a script may read and change while it runs."""

    vehicle_id: int
    limits: Limits
    labels: dict[str, Point]
    world: World | None
    last_target: Point | None  # where the last completed move was sent
    # Collision-free waypoints from a point to another around known obstacles (the first
    # and last being the two points), None when no path exists; absent: straight lines.
    route: Callable[[Point, Point], list[Point] | None] | None

    @property
    def state(self) -> VehicleState:
        """The latest vehicle state."""
        ...

    @property
    def now(self) -> float:
        """The mission's clock: it stands still while the run is paused."""
        ...

    def note(self, message: str, **data: object) -> None:
        """Write a decision to the flight log."""
        ...


def current_position(ctx: Context) -> Point:
    if ctx.state.position is None:
        raise ActionFailed("general", "the vehicle's position is not known yet")
    return ctx.state.position


def vehicle_kind(ctx: Context) -> Kind:
    return kind_of(ctx.state.vehicle_type)


def tolerances(ctx: Context) -> tuple[float, float]:
    """(horizontal, vertical) metres within which a move has arrived, for this vehicle."""
    handling = HANDLING[vehicle_kind(ctx)]
    radius = ctx.limits.acceptance_radius
    return handling.arrival_radius or radius, handling.vertical_tolerance or radius


def reference(ctx: Context) -> Point:
    """Where relative moves start: the last move's target when the vehicle reached it.

    Moves complete within the acceptance radius; measuring the next relative move from the
    target rather than from where the vehicle stopped keeps a chain of relative moves from
    adding up those errors (Dolphin's "relative to its last position").
    """
    here = current_position(ctx)
    target = ctx.last_target
    if target is not None and math.dist(here, target) <= 2 * tolerances(ctx)[0]:
        return target
    return here


def require_flying(ctx: Context, action: str) -> Point:
    """Where the vehicle is; it must be flying, unless it is a ground vehicle (its moves
    arm it first, see :func:`script_for`)."""
    position = current_position(ctx)
    if not ctx.state.flying and vehicle_kind(ctx) is not Kind.GROUND:
        raise ActionFailed("infeasible", f"{action} needs a flying vehicle; take off first")
    return position


def start_driving(ctx: Context) -> Script:
    """Arm a ground vehicle in GUIDED for its first move (ArduPilot Rover: nothing to take
    off from, so the first move is its start)."""
    yield Until(lambda s: s.ready, ctx.limits.ready_timeout,
                "a position estimate to arm with (EKF using GPS)")
    yield Send(SetMode(ctx.vehicle_id, "GUIDED"))
    yield Send(Arm(ctx.vehicle_id))
    ctx.note("armed to drive")


def travel_time(ctx: Context, start: Point, end: Point) -> float:
    limits = ctx.limits
    horizontal = limits.leg_seconds(ctx.state.vehicle_type,
                                    math.hypot(end[0] - start[0], end[1] - start[1]))
    rate = limits.climb_rate if end[2] >= start[2] else limits.descent_rate
    vertical = abs(end[2] - start[2]) / rate
    return limits.factor * max(horizontal, vertical) + limits.slack


def arrived(ctx: Context, target: Point,
            within: float | None = None) -> Callable[[VehicleState], bool]:
    """Whether a state is at ``target``: within the vehicle's tolerances, or horizontally
    within ``within`` metres when given (a waypoint's acceptance radius)."""
    radius, vertical = tolerances(ctx)
    radius = within if within is not None else radius

    def arrived(state: VehicleState) -> bool:
        p = state.position
        return p is not None and math.hypot(p[0] - target[0], p[1] - target[1]) <= radius \
            and abs(p[2] - target[2]) <= vertical

    return arrived


def fly_to(ctx: Context, target: Point, what: str, facing: Point | None = None,
           within: float | None = None) -> Script:
    """Fly to a local point and wait until within the acceptance radius (``within`` metres
    horizontally when given).

    With a router, the vehicle follows the collision-free path around known obstacles,
    one waypoint after the other; without one, a straight line. With ``facing``, each
    target carries the heading from it toward that point.
    """
    start = require_flying(ctx, what)
    if vehicle_kind(ctx) is Kind.GROUND:
        target = (target[0], target[1], 0.0)  # driven on the ground whatever the point says
    elif target[2] < 0:
        raise ActionFailed("infeasible", f"{what}: target altitude {target[2]:.1f} m is "
                                         "below home")
    path = [start, target]
    if ctx.route is not None:
        planned = ctx.route(start, target)
        if planned is None:
            raise ActionFailed("infeasible", f"{what}: no collision-free path to "
                                             f"{fmt(target)} around the known obstacles")
        path = [start, *planned[1:-1], target]
        if len(path) > 2:
            ctx.note(f"{what}: around obstacles by {len(path) - 2} waypoint(s)",
                     waypoints=[list(p) for p in path[1:-1]])
    legs = [math.dist(a, b) for a, b in pairwise(path)]
    total = max(sum(legs), 1e-6)
    for index, point in enumerate(path[1:]):
        done = sum(legs[:index])

        def progress(state: VehicleState, point: Point = point, done: float = done,
                     leg: float = legs[index]) -> float:
            here = state.position or start
            covered = done + max(0.0, leg - math.dist(here, point))
            return max(0.0, min(1.0, covered / total))

        yaw = None if facing is None else heading_toward(point, facing)
        yield Send(GoTo(ctx.vehicle_id, point, yaw=yaw))
        last = index == len(path) - 2
        yield Until(arrived(ctx, point, within if last else None),
                    travel_time(ctx, path[index], point),
                    f"reach {fmt(point)}", progress)
    ctx.last_target = target


def heading_toward(here: Point, there: Point) -> float:
    """Degrees clockwise from north from ``here`` toward ``there`` (0 when above it)."""
    return math.degrees(math.atan2(there[1] - here[1], there[0] - here[0])) % 360.0


def face(ctx: Context, target: float) -> Script:
    """Turn to the heading ``target`` (degrees from north) and wait until facing it."""
    heading = ctx.state.heading
    # Sent as a heading, not a turn: a resent request (after an event) must not turn again.
    yield Send(SetYaw(ctx.vehicle_id, target))
    turn = abs((target - heading + 540) % 360 - 180)
    tolerance = ctx.limits.heading_tolerance
    yield Until(lambda s: abs((target - s.heading + 540) % 360 - 180) <= tolerance,
                ctx.limits.factor * turn / ctx.limits.yaw_rate + ctx.limits.slack,
                f"face {target:.0f} deg")


def fmt(point: Point) -> str:
    return "(" + ", ".join(f"{v:.1f}" for v in point) + ")"


def landed_and_disarmed(state: VehicleState) -> bool:
    return state.landed and not state.armed


LANDED_READS = frozenset(("landed", "armed", "current"))
"""What :func:`landed_and_disarmed` reads (and whether the picture is current)."""


def local(ctx: Context, bound: BoundAction, altitude_key: str = "altitude") -> Point:
    """The local point of an action's latitude/longitude/altitude arguments."""
    home = ctx.state.home
    if home is None:
        raise ActionFailed("general", "the vehicle's home position is not known yet")
    altitude = bound.number(altitude_key, ctx.state.altitude)
    if bound.values.get("altitude_reference") == "amsl":
        altitude -= home.altitude
    north, east, _ = geo.to_local(bound.number("latitude"), bound.number("longitude"),
                                  home.altitude, home.latitude, home.longitude, home.altitude)
    return (north, east, altitude)


def point_argument(ctx: Context, bound: BoundAction, name: str) -> Point | None:
    """A point argument given as a value or as a memorized label."""
    if name in bound.labels:
        label = bound.labels[name]
        if label not in ctx.labels:
            raise ActionFailed("infeasible", f"label {label!r} has not been memorized")
        return ctx.labels[label]
    return bound.point(name, None)


def circle(ctx: Context, centre: Point, radius: float, turns: float | None,
           duration: float | None, facing: Point | None = None) -> Script:
    """Circle ``centre`` clockwise: a number of turns, for a time, or until stopped (neither).

    As ArduPilot's loiter items do, the vehicle joins the circle at its nearest point (the
    centre itself may be what it circles, a mast or a tower) and goes round from there. A
    fixed-wing circles natively (:func:`_orbit`), heading along its circle whatever
    ``facing`` says; a multicopter given ``facing`` turns toward that point at each target.
    """
    if vehicle_kind(ctx) is Kind.FIXED_WING:
        yield from _orbit(ctx, centre, radius, turns, duration)
        return
    start = circle_entry(centre, current_position(ctx))
    started = None
    step = 0
    while True:
        if turns is not None and step > turns * CIRCLE_POINTS_PER_TURN:
            return
        if duration is not None and started is not None and \
                ctx.now - started >= duration:
            return
        yield from fly_to(ctx, circle_point(centre, radius, start, step), "loiter", facing)
        if started is None:
            started = ctx.now  # the time and the turns count once on the circle
        step += 1


def _orbit(ctx: Context, centre: Point, radius: float, turns: float | None,
           duration: float | None) -> Script:
    """A fixed-wing's circle: ArduPlane loiters around a GUIDED target at the radius asked.

    The vehicle is on the circle once its distance from the centre is within the
    fixed-wing's arrival margin of the radius (ArduPlane flies a little wide of it); turns
    are counted from its bearing around the centre, the time from then on.
    """
    handling = HANDLING[Kind.FIXED_WING]
    margin = handling.arrival_radius - handling.loiter_radius
    yield Send(Circle(ctx.vehicle_id, centre, radius))
    here = current_position(ctx)

    def on_circle(state: VehicleState) -> bool:
        p = state.position
        return p is not None and abs(math.hypot(p[0] - centre[0], p[1] - centre[1])
                                     - radius) <= margin \
            and abs(p[2] - centre[2]) <= handling.vertical_tolerance

    yield Until(on_circle, travel_time(ctx, here, centre),
                f"reach the circle around {fmt(centre)}")
    if duration is not None:
        yield Sleep(duration)
    elif turns is not None:
        swept = [0.0, _bearing(ctx.state.position or here, centre)]

        def around(state: VehicleState) -> bool:
            bearing = _bearing(state.position or here, centre)
            swept[0] += (bearing - swept[1] + 540.0) % 360.0 - 180.0
            swept[1] = bearing
            return abs(swept[0]) >= 360.0 * turns

        speed = ctx.limits.move_speed(ctx.state.vehicle_type)
        yield Until(around, ctx.limits.factor * 2 * math.pi * radius * turns / speed
                    + ctx.limits.slack, f"circle {turns:g} times",
                    lambda s: min(1.0, abs(swept[0]) / (360.0 * turns)))
    else:
        yield Until(lambda s: False, math.inf, "circle until stopped")
    ctx.last_target = centre


def _bearing(point: Point, centre: Point) -> float:
    return math.degrees(math.atan2(point[1] - centre[1], point[0] - centre[0]))


LAND_DISARM_DELAY = 30.0
"""Seconds a fixed-wing may take to disarm after touching down (ArduPlane's
LAND_DISARMDELAY is 20 s)."""


def glide(ctx: Context, touchdown: Point | None, what: str) -> Script:
    """A fixed-wing lands along its approach (the Land request; the adapter uploads it as a
    landing sequence and flies it in AUTO); done once down and disarmed."""
    here = current_position(ctx)
    yield Send(Land(ctx.vehicle_id, touchdown))
    way = final_length(here[2])
    if touchdown is not None:
        way += math.hypot(here[0] - touchdown[0], here[1] - touchdown[1])
    speed = ctx.limits.move_speed(ctx.state.vehicle_type)
    limit = ctx.limits.factor * (way / speed + here[2] / ctx.limits.descent_rate) \
        + ctx.limits.slack + LAND_DISARM_DELAY
    yield Until(landed_and_disarmed, limit, f"{what}: land and disarm",
                lambda s: max(0.0, min(1.0, 1 - s.altitude / max(here[2], 1))), LANDED_READS)
