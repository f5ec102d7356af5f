"""How each action of the catalogue is flown with commands (``dispatch="command"``).

An action is a generator that yields steps to the interpreter and never does I/O:

- :class:`Send` a request and wait for its result (a refusal fails the action);
- :class:`Until` a predicate on the vehicle state holds, within a time limit derived from
  distance and speed (running out fails the action with ACTION_FAILURE ``timeout``);
- :class:`Sleep` for a time.

A script fails the action by raising :class:`ActionFailed` with an ACTION_FAILURE reason
(``rejected``, ``timeout``, ``unsupported``, ``infeasible``, ``general``). Completion is
always observed in telemetry: position within the acceptance radius, altitude reached,
heading reached, landed and disarmed. The points of a pattern (SURVEY_AREA's lawnmower,
EXPLORE_SPACE's expanding square, a LOITER's circle, a MOVE in the body frame) come from
:mod:`tml.patterns`, as the mission compiler and the verifier take them.

Each script flies the action the way the vehicle's kind can (:mod:`tml.language.kinds`, from the
type the vehicle reports): a multicopter as ArduCopter in GUIDED; a fixed-wing as
ArduPlane (it takes off in TAKEOFF mode, circles the points it is sent to, circles
natively for LOITER, holds by circling, and lands along an approach); a ground vehicle as
ArduPilot Rover (it arms itself for its first move, drives at 0 m, and its
RETURN_HOME_AND_LAND drives home, stops and disarms). :func:`script_for` picks the script,
or refuses the action with ACTION_FAILURE ``infeasible`` when the kind cannot do it at
all (:func:`tml.language.kinds.refusal`), before anything is sent.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from dataclasses import dataclass
from itertools import pairwise
from typing import Protocol

from tml import geo
from tml.geo import Point
from tml.language.actions import BoundAction, Category
from tml.language.failures import FailureReason
from tml.language.kinds import HANDLING, Kind, final_length, kind_of, refusal
from tml.patterns import (
    CIRCLE_POINTS_PER_TURN,
    circle_entry,
    circle_point,
    displaced,
    expanding_square,
    stop_to_stop,
    survey,
)
from tml.vehicle import (
    SHOWN_FIELDS,
    Arm,
    Camera,
    Circle,
    Disarm,
    Flip,
    GoTo,
    Gripper,
    Hold,
    Land,
    Request,
    ReturnToLaunch,
    SetHome,
    SetMode,
    SetSpeed,
    SetYaw,
    TakeOff,
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


# --- shared steps ---------------------------------------------------------------------------


def _position(ctx: Context) -> Point:
    if ctx.state.position is None:
        raise ActionFailed("general", "the vehicle's position is not known yet")
    return ctx.state.position


def _kind(ctx: Context) -> Kind:
    return kind_of(ctx.state.vehicle_type)


def _tolerances(ctx: Context) -> tuple[float, float]:
    """(horizontal, vertical) metres within which a move has arrived, for this vehicle."""
    handling = HANDLING[_kind(ctx)]
    radius = ctx.limits.acceptance_radius
    return handling.arrival_radius or radius, handling.vertical_tolerance or radius


def _reference(ctx: Context) -> Point:
    """Where relative moves start: the last move's target when the vehicle reached it.

    Moves complete within the acceptance radius; measuring the next relative move from the
    target rather than from where the vehicle stopped keeps a chain of relative moves from
    adding up those errors (Dolphin's "relative to its last position").
    """
    here = _position(ctx)
    target = ctx.last_target
    if target is not None and math.dist(here, target) <= 2 * _tolerances(ctx)[0]:
        return target
    return here


def _require_flying(ctx: Context, action: str) -> Point:
    """Where the vehicle is; it must be flying, unless it is a ground vehicle (its moves
    arm it first, see :func:`script_for`)."""
    position = _position(ctx)
    if not ctx.state.flying and _kind(ctx) is not Kind.GROUND:
        raise ActionFailed("infeasible", f"{action} needs a flying vehicle; take off first")
    return position


def _start_driving(ctx: Context) -> Script:
    """Arm a ground vehicle in GUIDED for its first move (ArduPilot Rover: nothing to take
    off from, so the first move is its start)."""
    yield Until(lambda s: s.ready, ctx.limits.ready_timeout,
                "a position estimate to arm with (EKF using GPS)")
    yield Send(SetMode(ctx.vehicle_id, "GUIDED"))
    yield Send(Arm(ctx.vehicle_id))
    ctx.note("armed to drive")


def _travel_time(ctx: Context, start: Point, end: Point) -> float:
    limits = ctx.limits
    horizontal = limits.leg_seconds(ctx.state.vehicle_type,
                                    math.hypot(end[0] - start[0], end[1] - start[1]))
    rate = limits.climb_rate if end[2] >= start[2] else limits.descent_rate
    vertical = abs(end[2] - start[2]) / rate
    return limits.factor * max(horizontal, vertical) + limits.slack


def _arrived(ctx: Context, target: Point) -> Callable[[VehicleState], bool]:
    radius, vertical = _tolerances(ctx)

    def arrived(state: VehicleState) -> bool:
        p = state.position
        return p is not None and math.hypot(p[0] - target[0], p[1] - target[1]) <= radius \
            and abs(p[2] - target[2]) <= vertical

    return arrived


def fly_to(ctx: Context, target: Point, what: str) -> Script:
    """Fly to a local point and wait until within the acceptance radius.

    With a router, the vehicle follows the collision-free path around known obstacles,
    one waypoint after the other; without one, a straight line.
    """
    start = _require_flying(ctx, what)
    if _kind(ctx) is Kind.GROUND:
        target = (target[0], target[1], 0.0)  # driven on the ground whatever the point says
    elif target[2] < 0:
        raise ActionFailed("infeasible", f"{what}: target altitude {target[2]:.1f} m is "
                                         "below home")
    path = [start, target]
    if ctx.route is not None:
        planned = ctx.route(start, target)
        if planned is None:
            raise ActionFailed("infeasible", f"{what}: no collision-free path to "
                                             f"{_fmt(target)} around the known obstacles")
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

        yield Send(GoTo(ctx.vehicle_id, point))
        yield Until(_arrived(ctx, point), _travel_time(ctx, path[index], point),
                    f"reach {_fmt(point)}", progress)
    ctx.last_target = target


def _fmt(point: Point) -> str:
    return "(" + ", ".join(f"{v:.1f}" for v in point) + ")"


def _landed_and_disarmed(state: VehicleState) -> bool:
    return state.landed and not state.armed


LANDED_READS = frozenset(("landed", "armed", "current"))
"""What :func:`_landed_and_disarmed` reads (and whether the picture is current)."""


def _local(ctx: Context, bound: BoundAction, altitude_key: str = "altitude") -> Point:
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


def _point(ctx: Context, bound: BoundAction, name: str) -> Point | None:
    """A point argument given as a value or as a memorized label."""
    if name in bound.labels:
        label = bound.labels[name]
        if label not in ctx.labels:
            raise ActionFailed("infeasible", f"label {label!r} has not been memorized")
        return ctx.labels[label]
    return bound.point(name, None)


def _circle(ctx: Context, centre: Point, radius: float, turns: float | None,
            duration: float | None) -> Script:
    """Circle ``centre`` clockwise: a number of turns, for a time, or until stopped (neither).

    As ArduPilot's loiter items do, the vehicle joins the circle at its nearest point (the
    centre itself may be what it circles, a mast or a tower) and goes round from there. A
    fixed-wing circles natively (:func:`_orbit`).
    """
    if _kind(ctx) is Kind.FIXED_WING:
        yield from _orbit(ctx, centre, radius, turns, duration)
        return
    start = circle_entry(centre, _position(ctx))
    started = None
    step = 0
    while True:
        if turns is not None and step > turns * CIRCLE_POINTS_PER_TURN:
            return
        if duration is not None and started is not None and \
                ctx.now - started >= duration:
            return
        yield from fly_to(ctx, circle_point(centre, radius, start, step), "loiter")
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
    here = _position(ctx)

    def on_circle(state: VehicleState) -> bool:
        p = state.position
        return p is not None and abs(math.hypot(p[0] - centre[0], p[1] - centre[1])
                                     - radius) <= margin \
            and abs(p[2] - centre[2]) <= handling.vertical_tolerance

    yield Until(on_circle, _travel_time(ctx, here, centre),
                f"reach the circle around {_fmt(centre)}")
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


def _refused(reason: str) -> Script:
    raise ActionFailed("infeasible", reason)
    yield  # a generator that fails when it is first run


def _driven(ctx: Context, bound: BoundAction) -> Script:
    """A ground vehicle's move: armed first (it may not even know where it is before)."""
    if not ctx.state.armed:
        yield from _start_driving(ctx)
    yield from SCRIPTS[bound.name](ctx, bound)


def script_for(ctx: Context, bound: BoundAction, resumed: bool = False) -> Script:
    """The script flying ``bound`` on the vehicle of ``ctx``; for an action the vehicle's
    kind cannot do at all, one that fails with ACTION_FAILURE ``infeasible`` at once.
    ``resumed``: the action was running when the run was interrupted (tml.engine.resume)."""
    kind = _kind(ctx)
    cannot = refusal(bound, kind, ctx.state.vehicle_type)
    if cannot is not None:
        return _refused(cannot)
    if resumed and bound.name == "TAKE_OFF" and ctx.state.flying:
        return _climb_on(ctx, bound)
    if kind is Kind.GROUND and (bound.spec.category is Category.TRANSLATION
                                or bound.name in ("LOITER", "RETURN_HOME_AND_LOITER")):
        return _driven(ctx, bound)
    return SCRIPTS[bound.name](ctx, bound)


# --- the actions ----------------------------------------------------------------------------


def take_off(ctx: Context, bound: BoundAction) -> Script:
    """Arm in GUIDED and climb; ignored (as the paper says) when already flying.

    A fixed-wing cannot take off in GUIDED: its TakeOff request is ArduPlane's TAKEOFF mode
    (a climb along its heading to the altitude, then a circle), which arms it too.
    """
    altitude = bound.number("altitude")
    if ctx.state.flying:
        ctx.note("TAKE_OFF ignored: the vehicle is already flying", altitude=ctx.state.altitude)
        return
    yield Until(lambda s: s.ready, ctx.limits.ready_timeout,
                "a position estimate to arm with (EKF using GPS)")
    if _kind(ctx) is not Kind.FIXED_WING:
        yield Send(SetMode(ctx.vehicle_id, "GUIDED"))
        yield Send(Arm(ctx.vehicle_id))
    yield Send(TakeOff(ctx.vehicle_id, altitude))
    tolerance = _tolerances(ctx)[1]
    yield Until(lambda s: s.altitude >= altitude - tolerance,
                ctx.limits.factor * altitude / ctx.limits.climb_rate + ctx.limits.slack,
                f"climb to {altitude:g} m", lambda s: max(0.0, min(1.0, s.altitude / altitude)),
                frozenset(("position", "current")))


def _climb_on(ctx: Context, bound: BoundAction) -> Script:
    """A TAKE_OFF the interrupted run began, resumed with the vehicle in the air: it is not
    ignored as a fresh one would be (the next action's hold would stop the climb short of
    the altitude it was given), the climb goes on to that altitude -- a position target
    there, above where the vehicle is (a fixed-wing's TAKEOFF mode climbs on by itself) --
    and is done when the telemetry shows it."""
    altitude = bound.number("altitude")
    here = _position(ctx)
    tolerance = _tolerances(ctx)[1]
    if here[2] >= altitude - tolerance:
        ctx.note(f"TAKE_OFF resumed: the vehicle is at its altitude ({altitude:g} m) already",
                 altitude=ctx.state.altitude)
        return
    ctx.note(f"TAKE_OFF resumed in the air at {here[2]:.1f} m: climbing on to {altitude:g} m",
             altitude=ctx.state.altitude)
    if _kind(ctx) is not Kind.FIXED_WING:
        yield from fly_to(ctx, (here[0], here[1], altitude), "TAKE_OFF")
        return
    yield Until(lambda s: s.altitude >= altitude - tolerance,
                ctx.limits.factor * (altitude - here[2]) / ctx.limits.climb_rate
                + ctx.limits.slack, f"climb to {altitude:g} m",
                lambda s: max(0.0, min(1.0, s.altitude / altitude)),
                frozenset(("position", "current")))


def land(ctx: Context, bound: BoundAction) -> Script:
    """Land where the vehicle is and wait until it is down and disarmed (a fixed-wing:
    along an approach straight ahead)."""
    if not ctx.state.possibly_flying:  # seen on the ground since it was last asked to fly
        ctx.note("LAND: the vehicle is already on the ground")
        return
    if _kind(ctx) is Kind.FIXED_WING:
        yield from _glide(ctx, None, "LAND")
        return
    start = ctx.state.altitude
    yield Send(Land(ctx.vehicle_id))
    yield Until(_landed_and_disarmed,
                ctx.limits.factor * start / ctx.limits.land_rate + ctx.limits.slack,
                "land and disarm", lambda s: max(0.0, min(1.0, 1 - s.altitude / max(start, 1))),
                LANDED_READS)


LAND_DISARM_DELAY = 30.0
"""Seconds a fixed-wing may take to disarm after touching down (ArduPlane's
LAND_DISARMDELAY is 20 s)."""


def _glide(ctx: Context, touchdown: Point | None, what: str) -> Script:
    """A fixed-wing lands along its approach (the Land request; the adapter uploads it as a
    landing sequence and flies it in AUTO); done once down and disarmed."""
    here = _position(ctx)
    yield Send(Land(ctx.vehicle_id, touchdown))
    way = final_length(here[2])
    if touchdown is not None:
        way += math.hypot(here[0] - touchdown[0], here[1] - touchdown[1])
    speed = ctx.limits.move_speed(ctx.state.vehicle_type)
    limit = ctx.limits.factor * (way / speed + here[2] / ctx.limits.descent_rate) \
        + ctx.limits.slack + LAND_DISARM_DELAY
    yield Until(_landed_and_disarmed, limit, f"{what}: land and disarm",
                lambda s: max(0.0, min(1.0, 1 - s.altitude / max(here[2], 1))), LANDED_READS)


def go_to_point(ctx: Context, bound: BoundAction) -> Script:
    """Fly to a local point, a memorized label, or a point relative to the vehicle."""
    here = _reference(ctx)
    target = _point(ctx, bound, "coordinates")
    if target is None:
        dn, de, du = bound.point("relative_coordinates")
        target = (here[0] + dn, here[1] + de, here[2] + du)
    yield from fly_to(ctx, target, "GO_TO_POINT")


def move(ctx: Context, bound: BoundAction) -> Script:
    """Move by a displacement, or a distance in a direction relative to the heading."""
    here = _reference(ctx)
    if "coordinates" in bound.values:
        dn, de, du = bound.point("coordinates")
        target = (here[0] + dn, here[1] + de, here[2] + du)
    else:
        target = displaced(here, ctx.state.heading, bound.choice("direction"),
                           bound.number("distance"))
    yield from fly_to(ctx, target, bound.name)


def move_forwards(ctx: Context, bound: BoundAction) -> Script:
    """Move straight ahead along the heading."""
    here = _reference(ctx)
    target = displaced(here, ctx.state.heading, "forward", bound.number("distance"))
    yield from fly_to(ctx, target, "MOVE_FORWARDS")


def move_from_home(ctx: Context, bound: BoundAction) -> Script:
    """Fly to an offset from home (the local frame's origin)."""
    yield from fly_to(ctx, bound.point("coordinates"), "MOVE_FROM_HOME")


def go_to_position(ctx: Context, bound: BoundAction) -> Script:
    """Fly to a WGS84 position."""
    yield from fly_to(ctx, _local(ctx, bound), "GO_TO_POSITION")


def set_altitude(ctx: Context, bound: BoundAction) -> Script:
    """Climb or descend where the vehicle is."""
    here = _reference(ctx)
    altitude = bound.number("altitude")
    if bound.choice("altitude_reference") == "amsl" and ctx.state.home is not None:
        altitude -= ctx.state.home.altitude
    yield from fly_to(ctx, (here[0], here[1], altitude), "SET_ALTITUDE")


def rotate_yaw(ctx: Context, bound: BoundAction) -> Script:
    """Turn by an angle, or to a heading; done when the heading is within tolerance."""
    _require_flying(ctx, "ROTATE_YAW")
    heading = ctx.state.heading
    angle = bound.number("angle", None)
    if angle is not None:
        target = (heading + angle) % 360
    else:
        target = bound.number("orientation_angle") % 360
    # Sent as a heading, not a turn: a resent request (after an event) must not turn again.
    yield Send(SetYaw(ctx.vehicle_id, target))
    turn = abs((target - heading + 540) % 360 - 180)
    tolerance = ctx.limits.heading_tolerance
    yield Until(lambda s: abs((target - s.heading + 540) % 360 - 180) <= tolerance,
                ctx.limits.factor * turn / ctx.limits.yaw_rate + ctx.limits.slack,
                f"face {target:.0f} deg")


def stabilize(ctx: Context, bound: BoundAction) -> Script:
    """Stop all motion and hold (a fixed-wing cannot stop: it circles where it is)."""
    _require_flying(ctx, "STABILIZE")
    yield Send(Hold(ctx.vehicle_id))
    if _kind(ctx) is Kind.FIXED_WING:
        ctx.note("STABILIZE: a fixed-wing cannot stop; it circles where it is")
        return
    yield Until(lambda s: s.ground_speed <= 0.3, ctx.limits.slack, "come to a stop")


def wait(ctx: Context, bound: BoundAction) -> Script:
    """Hold position (when flying) for a time."""
    if ctx.state.possibly_flying:
        yield Send(Hold(ctx.vehicle_id))
    yield Sleep(bound.number("duration"))


def flip(ctx: Context, bound: BoundAction) -> Script:
    """One flip as ArduCopter makes it (:class:`~tml.vehicle.Flip`), then back where it began.

    A flip costs ArduCopter about 4 m of height, so below ``flip_altitude`` the vehicle
    climbs there first; afterwards it flies back to the point it started from.
    """
    start = _require_flying(ctx, "FLIP")
    if "flip" not in ctx.state.capabilities:
        raise ActionFailed("unsupported", "this vehicle has no FLIP mode")
    high = max(start[2], ctx.limits.flip_altitude)
    if high - start[2] > ctx.limits.acceptance_radius:
        ctx.note(f"FLIP: climbing to {high:g} m first, a flip costs about 4 m",
                 altitude=high)
        yield from fly_to(ctx, (start[0], start[1], high), "FLIP")
    yield Send(Flip(ctx.vehicle_id, bound.choice("direction")))
    yield from fly_to(ctx, start, "FLIP")


def memorize_point(ctx: Context, bound: BoundAction) -> Script:
    """Store the current position under a label."""
    label = bound.labels["coordinates"]
    ctx.labels[label] = _position(ctx)
    ctx.note(f"memorized {label!r}", label=label, point=list(ctx.labels[label]))
    yield from ()


def go_to_rectangle(ctx: Context, bound: BoundAction) -> Script:
    """Fly to the coloured frame known in the environment, 1 m in front of it."""
    colour = bound.text("frame_color").lower()
    frames = [o for o in (ctx.world.objects if ctx.world else ())
              if o.kind == "frame" and o.color.lower() == colour]
    if not frames:
        raise ActionFailed("infeasible", f"no {colour} frame is known in the environment")
    here = _position(ctx)
    frame = min(frames, key=lambda o: math.hypot(o.north - here[0], o.east - here[1]))
    distance = math.hypot(frame.north - here[0], frame.east - here[1])
    back = min(1.0, distance) / max(distance, 1e-6)
    target = (frame.north - (frame.north - here[0]) * back,
              frame.east - (frame.east - here[1]) * back, frame.altitude or here[2])
    yield from fly_to(ctx, target, "GO_TO_RECTANGLE")


def explore_space(ctx: Context, bound: BoundAction) -> Script:
    """An expanding square around the start out to ``radius``, passes ``spacing`` apart,
    then back to the start (:func:`tml.patterns.expanding_square`)."""
    here = _require_flying(ctx, "EXPLORE_SPACE")
    for point in expanding_square(here, bound.number("radius"), bound.number("spacing")):
        yield from fly_to(ctx, point, "EXPLORE_SPACE")


def pick_up_item(ctx: Context, bound: BoundAction) -> Script:
    """Descend to 1 m, close the gripper, climb back."""
    here = _require_flying(ctx, "PICK_UP_ITEM")
    if "gripper" not in ctx.state.capabilities:
        raise ActionFailed("unsupported", "this vehicle has no gripper")
    yield from fly_to(ctx, (here[0], here[1], min(here[2], 1.0)), "PICK_UP_ITEM")
    yield Send(Gripper(ctx.vehicle_id, grab=True))
    yield Sleep(1.0)
    yield from fly_to(ctx, here, "PICK_UP_ITEM")


def drop_item(ctx: Context, bound: BoundAction) -> Script:
    """Open the gripper."""
    if "gripper" not in ctx.state.capabilities:
        raise ActionFailed("unsupported", "this vehicle has no gripper")
    yield Send(Gripper(ctx.vehicle_id, grab=False))
    yield Sleep(1.0)


def loiter(ctx: Context, bound: BoundAction) -> Script:
    """Fly to the centre and circle it: turns, a time, or until an event stops it."""
    here = _require_flying(ctx, "LOITER")
    centre = _point(ctx, bound, "coordinates")
    relative = bound.point("relative_coordinates", None)
    if centre is None and relative is not None:
        dn, de, du = relative
        centre = (here[0] + dn, here[1] + de, here[2] + du)
    if centre is None:
        centre = bound.point("from_home", None)
    if centre is None and "latitude" in bound.values:
        centre = _local(ctx, bound)
    centre = centre or here
    yield from _circle(ctx, centre, bound.number("radius"), bound.number("turns", None),
                       bound.number("duration", None))


def landing_point(ctx: Context, bound: BoundAction) -> Script:
    """Fly over the landing point, face the yaw if given, and land; nothing when the
    vehicle is down there already (a run resumed after it landed, as LAND)."""
    point = _point(ctx, bound, "coordinates")
    if point is None:
        point = _local(ctx, bound)
    if not ctx.state.flying and _kind(ctx) is not Kind.GROUND and \
            math.dist(_position(ctx)[:2], point[:2]) <= 2 * _tolerances(ctx)[0]:
        ctx.note("LANDING_POINT: the vehicle is already down at the landing point")
        return
    here = _require_flying(ctx, "LANDING_POINT")
    yaw = bound.number("yaw", None)
    precision = bound.choice("precision_mode") != "disabled"
    if _kind(ctx) is Kind.FIXED_WING:
        if yaw is not None or precision:
            ctx.note("LANDING_POINT: a fixed-wing lands along its approach; yaw and "
                     "precision landing are not applied")
        yield from _glide(ctx, (point[0], point[1], 0.0), "LANDING_POINT")
        return
    yield from fly_to(ctx, (point[0], point[1], max(here[2], point[2])), "LANDING_POINT")
    if yaw is not None:
        yield Send(SetYaw(ctx.vehicle_id, yaw % 360))
    if precision:
        ctx.note("precision landing is applied only to dispatch=\"mission\" (NAV_LAND)")
    yield from land(ctx, bound)


def return_home(ctx: Context, bound: BoundAction) -> Script:
    """Fly back over home at the current altitude and hold."""
    here = _require_flying(ctx, "RETURN_HOME")
    yield from fly_to(ctx, (0.0, 0.0, here[2]), "RETURN_HOME")


def return_home_and_loiter(ctx: Context, bound: BoundAction) -> Script:
    """Fly back over home and circle it until an event stops it."""
    here = _require_flying(ctx, "RETURN_HOME_AND_LOITER")
    yield from _circle(ctx, (0.0, 0.0, here[2]), bound.number("radius"), None, None)


def return_home_and_land(ctx: Context, bound: BoundAction) -> Script:
    """ArduPilot RTL: return, descend and land at home; done when disarmed.

    RTL flies a straight line home. When known obstacles stand on that line, the vehicle
    first flies the planned path home in GUIDED, and RTL then only descends.
    """
    here = _require_flying(ctx, "RETURN_HOME_AND_LAND")
    kind = _kind(ctx)
    if kind is Kind.FIXED_WING:
        yield from _glide(ctx, (0.0, 0.0, 0.0), "RETURN_HOME_AND_LAND")
        return
    if kind is Kind.GROUND and not ctx.state.armed:
        ctx.note("RETURN_HOME_AND_LAND: the vehicle is already stopped and disarmed")
        return
    above_home = (0.0, 0.0, here[2])
    if ctx.route is not None:
        path = ctx.route(here, above_home)
        if path is not None and len(path) > 2:
            yield from fly_to(ctx, above_home, "RETURN_HOME_AND_LAND")
            here = _position(ctx)
    yield Send(ReturnToLaunch(ctx.vehicle_id))
    if kind is Kind.GROUND:
        # Rover's RTL drives home and stops there, armed: then tml disarms it.
        home = _arrived(ctx, (0.0, 0.0, 0.0))
        yield Until(lambda s: home(s) and s.ground_speed <= 0.3,
                    _travel_time(ctx, here, (0.0, 0.0, 0.0)), "drive home and stop",
                    lambda s: 1.0 - min(1.0, math.dist(s.position or here, (0, 0, 0))
                                        / max(math.dist(here, (0, 0, 0)), 1.0)))
        yield Send(Disarm(ctx.vehicle_id))
        yield Until(lambda s: not s.armed, ctx.limits.slack, "disarm")
        return
    limit = _travel_time(ctx, here, (0.0, 0.0, 0.0)) + ctx.limits.factor * max(
        here[2], 15.0) / ctx.limits.land_rate
    yield Until(_landed_and_disarmed, limit, "return home and land",
                lambda s: 1.0 - min(1.0, math.dist(s.position or here, (0, 0, 0))
                                    / max(math.dist(here, (0, 0, 0)), 1.0)), LANDED_READS)


def set_speed(ctx: Context, bound: BoundAction) -> Script:
    """Change the speed of the following moves."""
    speed = bound.number("speed")
    kind = bound.choice("speed_type")
    yield Send(SetSpeed(ctx.vehicle_id, speed, kind))
    if kind in ("airspeed", "ground"):
        ctx.limits.speed = speed
    elif kind == "climb":
        ctx.limits.climb_rate = speed
    else:
        ctx.limits.descent_rate = speed


def survey_area(ctx: Context, bound: BoundAction) -> Script:
    """Lawnmower passes over the area, each along its length, ``spacing`` apart, the last
    on the far edge (:func:`tml.patterns.survey`)."""
    here = _require_flying(ctx, "SURVEY_AREA")
    base = _point(ctx, bound, "coordinates")
    if base is None and "latitude" in bound.values:
        base = _local(ctx, bound)
    base = base or here
    altitude = bound.number("altitude", here[2])
    for point in survey((base[0], base[1], altitude), bound.number("length"),
                        bound.number("width"), bound.number("spacing"),
                        bound.choice("direction")):
        yield from fly_to(ctx, point, "SURVEY_AREA")


def camera(ctx: Context, bound: BoundAction) -> Script:
    """The camera actions."""
    if bound.name == "CAPTURE_PHOTO":
        yield Send(Camera(ctx.vehicle_id, "photo", 1))
    elif bound.name == "CAPTURE_PHOTOS":
        count = bound.integer("count")
        interval = bound.number("interval")
        yield Send(Camera(ctx.vehicle_id, "photo", count, interval))
        yield Sleep(interval * (count - 1))
    elif bound.name == "START_CAPTURING":
        yield Send(Camera(ctx.vehicle_id, "start", 0, bound.number("interval")))
    else:
        yield Send(Camera(ctx.vehicle_id, "stop"))


def set_home(ctx: Context, bound: BoundAction) -> Script:
    """Home at the current position, or at a WGS84 position."""
    position = None
    if "latitude" in bound.values:
        position = (bound.number("latitude"), bound.number("longitude"),
                    bound.number("altitude"))
    yield Send(SetHome(ctx.vehicle_id, position))


SCRIPTS: dict[str, Callable[[Context, BoundAction], Script]] = {
    "TAKE_OFF": take_off, "LAND": land, "GO_TO_POINT": go_to_point, "MOVE": move,
    "MOVE_FORWARDS": move_forwards, "MOVE_FROM_HOME": move_from_home,
    "ROTATE_YAW": rotate_yaw, "STABILIZE": stabilize, "WAIT": wait, "FLIP": flip,
    "MEMORIZE_POINT": memorize_point, "GO_TO_RECTANGLE": go_to_rectangle,
    "EXPLORE_SPACE": explore_space, "PICK_UP_ITEM": pick_up_item, "DROP_ITEM": drop_item,
    "GO_TO_POSITION": go_to_position, "LOITER": loiter, "LANDING_POINT": landing_point,
    "RETURN_HOME": return_home, "RETURN_HOME_AND_LOITER": return_home_and_loiter,
    "RETURN_HOME_AND_LAND": return_home_and_land, "SET_SPEED": set_speed,
    "SET_ALTITUDE": set_altitude, "SURVEY_AREA": survey_area, "CAPTURE_PHOTO": camera,
    "CAPTURE_PHOTOS": camera, "START_CAPTURING": camera, "STOP_CAPTURING": camera,
    "SET_HOME": set_home,
}
