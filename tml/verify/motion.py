"""Abstract execution of one action: where the vehicle goes, how long it takes, what it costs.

The variables of the feasibility model (the paper's x_i) are a :class:`PredictedState`:
position, battery, time, heading, the speeds set so far, whether the vehicle is flying and
where home is. :meth:`FlightModel.step` takes a state and a bound action and predicts the
state after it, with the paths flown, without looking at any constraint; the constraints
(:mod:`tml.verify.constraints`) judge the :class:`Step` it returns.

Energy model: a leg costs the larger of ``battery_per_metre`` times its length and
``battery_per_second`` times its duration (a multicopter draws at least its hover power);
hovering costs ``battery_per_second``. Time: each straight segment takes the longer of its
ground distance and its climb or descent at the profile's rates; the ground distance is
flown as the interpreter flies it, from a stop to a stop (every waypoint is a GUIDED
target reached before the next is sent): speeding up and braking at ``acceleration`` around
a cruise at the current speed, or, on a segment too short to reach it, speeding up half
way and braking the other half. A circle is flown as the interpreter flies it too, as
:data:`~tml.patterns.CIRCLE_POINTS_PER_TURN` such segments a turn. Turning in place takes
the angle at ``yaw_rate``. The points of the patterns (the survey's lawnmower, the
expanding square, the circle, moves in the body frame) come from :mod:`tml.patterns`,
which the scripts and the mission compiler fly too: the path predicted is the path flown.

Kinds of vehicle (:mod:`tml.language.kinds`, from the profile's ``vehicle_type``): a fixed-wing
takes off in a climb along its heading and lands along an approach
(:func:`tml.language.kinds.landing_approach`), gliding to a touchdown ahead of it or at the point
it lands on; a ground vehicle drives every point at 0 m, is underway (armed) from its first
move on, and its RETURN_HOME_AND_LAND drives home and stops.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from itertools import pairwise

from tml import geo
from tml.language.actions import GLOBAL_FRAME_NUMBERS, BoundAction, table_entry
from tml.language.kinds import Kind, landing_approach
from tml.language.mavlink_tables import MAV_FRAME
from tml.patterns import (
    CIRCLE_POINTS_PER_TURN,
    circle,
    circle_chord,
    circle_entry,
    circle_point,
    displaced,
    expanding_square,
    stop_to_stop,
    survey,
)
from tml.verify.planner import Planner, Point3, Trajectory, straight
from tml.verify.profile import VehicleProfile
from tml.world import DEFAULT_HOME, World

Labels = dict[str, Point3]


@dataclass(frozen=True)
class PredictedState:
    """The variables: what the vehicle is predicted to be and have at one moment.

    Not the vehicle's state as the engine reads it in flight
    (:class:`tml.vehicle.VehicleState`, from telemetry): a prediction holds only what the
    feasibility model reasons about, with no link, mode or sensor in it, and always a
    position (:func:`tml.verify.inflight.live_variables` makes one from the other)."""

    position: Point3 = (0.0, 0.0, 0.0)  # local metres from home
    battery: float = 100.0  # percent
    time: float = 0.0  # s since the mission started
    heading: float = 0.0  # degrees clockwise from north
    flying: bool = False
    home: Point3 = (0.0, 0.0, 0.0)  # where RETURN_HOME goes (SET_HOME moves it)
    speed: float | None = None  # m/s set by SET_SPEED; None: the profile's cruise speed
    climb_rate: float | None = None  # m/s set by SET_SPEED speed_type=climb
    descent_rate: float | None = None  # m/s set by SET_SPEED speed_type=descent


@dataclass(frozen=True)
class Loiter:
    """A circle flown around a centre, joined at the bearing ``start`` (radians)."""

    centre: Point3
    radius: float
    start: float = 0.0

    def points(self) -> list[Point3]:
        """One turn of the circle as it is flown (:func:`tml.patterns.circle`): a closed
        polygonal line through the targets, at the centre's altitude."""
        return circle(self.centre, self.radius, self.start)


@dataclass(frozen=True)
class Step:
    """What one action does, as predicted from the state before it."""

    before: PredictedState
    after: PredictedState
    legs: tuple[Trajectory, ...] = ()  # paths flown, in order
    blocked: tuple[tuple[Point3, Point3], ...] = ()  # legs with no collision-free path
    destination: Point3 | None = None  # the point the action flies to (checked by c1)
    loiter: Loiter | None = None
    circle_metres: float = 0.0  # metres flown around the loiter circle
    requested_speed: tuple[str, float] | None = None  # (speed_type, m/s) of SET_SPEED
    cruise: bool = False  # a translation leg, held to the cruise altitude limits
    labels: Labels = field(default_factory=dict)  # labels after the action
    unknown_label: str = ""  # a label read that holds no point at this point
    notes: tuple[str, ...] = ()

    @property
    def distance(self) -> float:
        """Metres flown (loiter circles included)."""
        return sum(leg.length for leg in self.legs) + self.circle_metres

    @property
    def duration(self) -> float:
        """Seconds the action takes."""
        return self.after.time - self.before.time

    @property
    def energy(self) -> float:
        """Percent of the battery the action uses."""
        return self.before.battery - self.after.battery

    def path_points(self) -> list[Point3]:
        """Every vertex of the paths flown and of the loiter circle."""
        points = [p for leg in self.legs for p in leg.points]
        return points + (self.loiter.points() if self.loiter is not None else [])

    def waypoints(self) -> list[tuple[Point3, float]]:
        """Every vertex of the paths flown with the battery predicted there; the battery
        falls in proportion to the distance flown along the legs."""
        total = sum(leg.length for leg in self.legs)
        flown = 0.0
        found: list[tuple[Point3, float]] = []
        for leg in self.legs:
            previous = leg.points[0]
            for point in leg.points:
                flown += math.dist(previous, point)
                previous = point
                share = flown / total if total else 1.0
                found.append((point, self.before.battery - self.energy * share))
        return found


class FlightModel:
    """The vehicle profile and the world, ready to predict actions (the paper's k_i)."""

    def __init__(self, profile: VehicleProfile, world: World | None = None) -> None:
        self.profile = profile
        self.world = world or World()
        self.home = self.world.home_or_default
        self.planner = Planner(self.world.obstacles, profile.min_clearance)

    # --- the pieces every action is made of --------------------------------------------------

    def leg_time(self, state: PredictedState, trajectory: Trajectory,
                 landing: bool = False) -> float:
        """Seconds to fly a trajectory from ``state`` at its speed and climb/descent rates;
        ``landing``: its last segment is a landing (LAND, RTL), slower near the ground."""
        speed = min(state.speed or self.profile.cruise_speed, self.profile.max_speed)
        climb = state.climb_rate or self.profile.climb_rate
        descent = state.descent_rate or self.profile.descent_rate
        seconds = 0.0
        segments = list(pairwise(trajectory.points))
        for index, (a, b) in enumerate(segments):
            ground = stop_to_stop(math.hypot(b[0] - a[0], b[1] - a[1]), speed,
                                  self.profile.acceleration)
            rise = b[2] - a[2]
            if rise > 0:
                vertical = rise / climb
            elif landing and index == len(segments) - 1:
                vertical = self.landing_time(-rise, descent)
            else:
                vertical = -rise / descent
            seconds += max(ground, vertical)
        return seconds

    def landing_time(self, height: float, descent: float) -> float:
        """Seconds to land from ``height`` m: at ``descent`` m/s, and the last
        ``land_altitude`` metres at ``land_speed`` (ArduPilot's LAND_ALT_LOW, LAND_SPEED)."""
        slow = min(height, self.profile.land_altitude) if self.profile.land_speed > 0 else 0.0
        return (height - slow) / descent + (slow / self.profile.land_speed if slow else 0.0)

    def energy(self, metres: float, seconds: float) -> float:
        """Percent of the battery used to fly ``metres`` in ``seconds``."""
        return max(self.profile.battery_per_metre * metres,
                   self.profile.battery_per_second * seconds)

    def plan(self, start: Point3, end: Point3) -> tuple[Trajectory, bool]:
        """The planned path from ``start`` to ``end``; the straight line and False when the
        obstacles leave no way (so that prediction can go on)."""
        found = self.planner.trajectory(start, end)
        return (found, True) if found is not None else (straight(start, end), False)

    def fly(self, state: PredictedState, targets: list[Point3], planned: bool = True,
            landing: bool = False) -> tuple[
            PredictedState, list[Trajectory], list[tuple[Point3, Point3]]]:
        """Fly through ``targets`` in order; the state at the end, the legs and the legs
        that had no collision-free path. Not ``planned``: straight lines, which cost a
        lower bound of what the planned legs cost. ``landing``: the last target is a
        touch-down."""
        legs: list[Trajectory] = []
        blocked: list[tuple[Point3, Point3]] = []
        position, seconds, energy = state.position, 0.0, 0.0
        ground = self.profile.kind is Kind.GROUND
        if ground:  # on the ground whatever the points say
            targets = [(t[0], t[1], 0.0) for t in targets]
        for number, target in enumerate(targets, start=1):
            leg, found = self.plan(position, target) if planned else \
                (straight(position, target), True)
            if not found:
                blocked.append((position, target))
            leg_seconds = self.leg_time(state, leg, landing and number == len(targets))
            seconds += leg_seconds
            energy += self.energy(leg.length, leg_seconds)
            legs.append(leg)
            position = target
        after = replace(state, position=position, time=state.time + seconds,
                        battery=state.battery - energy, flying=state.flying or (
                            ground and bool(targets)))
        return after, legs, blocked

    def hover(self, state: PredictedState, seconds: float) -> PredictedState:
        """The state after hovering in place."""
        return replace(state, time=state.time + seconds,
                       battery=state.battery - self.profile.battery_per_second * seconds)

    def return_home_energy(self, point: Point3, home: Point3, planned: bool = True) -> float:
        """Percent of the battery needed to come home from ``point`` and land there the way
        ArduPilot's RTL does: climb to the return altitude if lower, fly home, wait
        ``return_hover`` s, descend. Not ``planned``: along straight lines, a lower bound.
        A fixed-wing comes home along its landing approach."""
        probe = PredictedState(position=point, flying=True)
        if self.profile.kind is Kind.FIXED_WING:
            approach, touchdown = landing_approach(point, 0.0, home)
            after, _, _ = self.fly(probe, [approach, touchdown], planned, landing=True)
            return probe.battery - after.battery
        after, _, _ = self.fly_home_and_land(probe, home, planned)
        return probe.battery - after.battery

    def fly_home_and_land(self, state: PredictedState, home: Point3, planned: bool = True
                          ) -> tuple[PredictedState, list[Trajectory], list[tuple[Point3, Point3]]]:
        """ArduPilot's RTL from ``state``: climb to the return altitude if lower, fly home,
        hover ``return_hover`` s, land; as :meth:`fly` returns."""
        point = state.position
        altitude = max(point[2], self.profile.return_altitude)
        above = [(point[0], point[1], altitude), (home[0], home[1], altitude)]
        over, legs, blocked = self.fly(state, above, planned)
        over = self.hover(over, self.profile.return_hover)
        after, down, stuck = self.fly(over, [home], planned, landing=True)
        return after, legs + down, blocked + stuck

    def local(self, latitude: float, longitude: float, altitude: float,
              reference: str) -> Point3:
        """A WGS84 position as a local point; ``reference`` says what ``altitude`` is
        measured from (terrain is taken as home: no terrain model)."""
        home = self.home if self.home is not None else DEFAULT_HOME
        north, east, _ = geo.to_local(latitude, longitude, home.altitude,
                                      home.latitude, home.longitude, home.altitude)
        up = altitude - home.altitude if reference == "amsl" else altitude
        return (north, east, up)

    # --- the actions ----------------------------------------------------------------------

    def step(self, bound: BoundAction, state: PredictedState,
             labels: Labels | None = None) -> Step:
        """Predict one action from ``state`` (pure: neither argument is changed)."""
        labels = dict(labels or {})
        handler: Callable[[BoundAction, PredictedState, Labels], Step] | None = getattr(
            self, "_" + bound.name.lower(), None)
        if handler is None:
            return Step(state, state, labels=labels,
                        notes=(f"{bound.name} takes no time or battery in the model",))
        return handler(bound, state, labels)

    def _point(self, bound: BoundAction, labels: Labels, name: str = "coordinates") -> tuple[
            Point3 | None, str]:
        """The point an argument gives (value or label); (None, label) for an unknown label."""
        if name in bound.labels:
            label = bound.labels[name]
            return labels.get(label), ("" if label in labels else label)
        return bound.point(name, None), ""

    def _global(self, bound: BoundAction) -> Point3:
        """The local point of the action's latitude, longitude, altitude and reference."""
        return self.local(bound.number("latitude"), bound.number("longitude"),
                          bound.number("altitude"), bound.choice("altitude_reference"))

    def _go(self, bound: BoundAction, state: PredictedState, labels: Labels,
            targets: list[Point3], landing: bool = False, cruise: bool = True) -> Step:
        after, legs, blocked = self.fly(state, targets, landing=landing)
        destination = targets[-1] if targets else None
        return Step(state, after, tuple(legs), tuple(blocked), labels=labels,
                    destination=destination, cruise=cruise)

    def _unknown(self, state: PredictedState, labels: Labels, label: str) -> Step:
        return Step(state, state, labels=labels, unknown_label=label,
                    notes=(f"label {label!r} holds no point here; the move is not predicted",))

    def _take_off(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        if state.flying:
            return Step(state, state, labels=labels, notes=("already flying: ignored",))
        if self.profile.kind is Kind.GROUND:
            return Step(state, state, labels=labels)  # refused: see the vehicle constraint
        written = bound.action.argument("altitude", "height") is not None
        altitude = bound.number("altitude") if written else self.profile.takeoff_altitude
        target = (state.position[0], state.position[1], altitude)
        if self.profile.kind is Kind.FIXED_WING:  # a climb along the heading
            run = altitude / self.profile.climb_rate * self.profile.cruise_speed
            target = (*displaced(state.position, state.heading, "forward", run)[:2], altitude)
        step = self._go(bound, replace(state, flying=True), labels, [target], cruise=False)
        return replace(step, before=state)

    def _landing(self, bound: BoundAction, state: PredictedState, labels: Labels,
                 touchdown: Point3 | None) -> Step:
        """A fixed-wing's approach and glide to ``touchdown`` (None: straight ahead)."""
        approach, ground = landing_approach(state.position, state.heading, touchdown)
        targets = [ground] if approach == state.position else [approach, ground]
        step = self._go(bound, state, labels, targets, cruise=False)
        return replace(step, after=replace(step.after, flying=False))

    def _land(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        if self.profile.kind is Kind.FIXED_WING:
            return self._landing(bound, state, labels, None)
        if self.profile.kind is Kind.GROUND:
            return Step(state, state, labels=labels)  # refused: see the vehicle constraint
        target = (state.position[0], state.position[1], 0.0)
        step = self._go(bound, state, labels, [target], landing=True, cruise=False)
        return replace(step, after=replace(step.after, flying=False))

    def _go_to_point(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        point, unknown = self._point(bound, labels)
        if unknown:
            return self._unknown(state, labels, unknown)
        if point is None:
            point = _add(state.position, bound.point("relative_coordinates"))
        return self._go(bound, state, labels, [point])

    def _move(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        offset = bound.point("coordinates", None)
        if offset is not None:
            return self._go(bound, state, labels, [_add(state.position, offset)])
        target = displaced(state.position, state.heading, bound.choice("direction"),
                           bound.number("distance"))
        return self._go(bound, state, labels, [target])

    def _move_forwards(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        target = displaced(state.position, state.heading, "forward", bound.number("distance"))
        return self._go(bound, state, labels, [target])

    def _move_from_home(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        return self._go(bound, state, labels, [_add(state.home, bound.point("coordinates"))])

    def _go_to_position(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        return self._go(bound, state, labels, [self._global(bound)])

    def _set_altitude(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        altitude = bound.number("altitude")
        if bound.choice("altitude_reference") == "amsl":
            altitude -= self.home.altitude
        return self._go(bound, state, labels, [(*state.position[:2], altitude)])

    def _return_home(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        return self._go(bound, state, labels, [(*state.home[:2], state.position[2])])

    def _return_home_and_land(self, bound: BoundAction, state: PredictedState,
                              labels: Labels) -> Step:
        if self.profile.kind is Kind.FIXED_WING:
            return self._landing(bound, state, labels, state.home)
        after, legs, blocked = self.fly_home_and_land(state, state.home)
        return Step(state, replace(after, flying=False), tuple(legs), tuple(blocked),
                    labels=labels, destination=state.home)

    def _return_home_and_loiter(self, bound: BoundAction, state: PredictedState,
                                labels: Labels) -> Step:
        step = self._circle(bound, state, labels, (*state.home[:2], state.position[2]),
                            bound.number("radius"))
        return replace(step, notes=(
            "circles home until an event ends it; no time counted for it",))

    def _landing_point(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        point, unknown = self._point(bound, labels)
        if unknown:
            return self._unknown(state, labels, unknown)
        if point is None:
            point = self._global(bound)
        if self.profile.kind is Kind.FIXED_WING:
            return self._landing(bound, state, labels, (point[0], point[1], 0.0))
        targets = [(point[0], point[1], state.position[2]), (point[0], point[1], 0.0)]
        step = self._go(bound, state, labels, targets, landing=True, cruise=False)
        return replace(step, after=replace(step.after, flying=False))

    def _loiter(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        centre, unknown = self._point(bound, labels)
        if unknown:
            return self._unknown(state, labels, unknown)
        relative = bound.point("relative_coordinates", None)
        from_home = bound.point("from_home", None)
        if centre is None and relative is not None:
            centre = _add(state.position, relative)
        elif centre is None and from_home is not None:
            centre = _add(state.home, from_home)
        elif centre is None and "latitude" in bound.values:
            centre = self._global(bound)
        return self._circle(bound, state, labels, centre or state.position,
                            bound.number("radius"), bound.integer("turns", None),
                            bound.number("duration", None))

    def _circle(self, bound: BoundAction, state: PredictedState, labels: Labels,
                centre: Point3, radius: float, turns: int | None = None,
                duration: float | None = None) -> Step:
        """Join the circle around ``centre`` and go round it, as the scripts fly it: to its
        nearest point (not to its centre, often the very thing it circles around), then
        from target to target (:mod:`tml.patterns`) for ``turns`` or ``duration`` seconds
        (neither: until an event ends it)."""
        start = circle_entry(centre, state.position)
        entry = circle_point(centre, radius, start, 0)
        step = self._go(bound, state, labels, [entry] if entry != state.position else [])
        step = replace(step, destination=centre, loiter=Loiter(centre, radius, start))
        speed = min(state.speed or self.profile.cruise_speed, self.profile.max_speed)
        chord = circle_chord(radius)
        chord_seconds = stop_to_stop(chord, speed, self.profile.acceleration)
        if turns is not None:
            chords = CIRCLE_POINTS_PER_TURN * turns
            metres, seconds = chords * chord, chords * chord_seconds
        elif duration is not None:
            seconds = duration
            metres = chord * seconds / chord_seconds if chord_seconds else 0.0
        else:
            return replace(step, notes=("circles until an event ends it; no time counted",))
        after = replace(step.after, time=step.after.time + seconds,
                        battery=step.after.battery - self.energy(metres, seconds))
        return replace(step, after=after, circle_metres=metres)

    def _survey_area(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        base, unknown = self._point(bound, labels)
        if unknown:
            return self._unknown(state, labels, unknown)
        if base is None and "latitude" in bound.values:
            base = self.local(bound.number("latitude"), bound.number("longitude"), 0.0,
                              "relative")
        base = base or state.position
        altitude = bound.number("altitude", None) or state.position[2]
        targets = survey((base[0], base[1], altitude), bound.number("length"),
                         bound.number("width"), bound.number("spacing"),
                         bound.choice("direction"))
        return self._go(bound, state, labels, targets)

    def _explore_space(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        targets = expanding_square(state.position, bound.number("radius"),
                                   bound.number("spacing"))
        return self._go(bound, state, labels, targets)

    def _go_to_rectangle(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        colour = bound.text("frame_color").lower()
        frames = [o for o in self.world.objects if o.kind == "frame" and o.color.lower() == colour]
        if not frames:
            return Step(state, state, labels=labels, notes=(
                f"no {colour} frame in the world: where it is is known only in flight",))
        frame = frames[0]
        return self._go(bound, state, labels, [(frame.north, frame.east, frame.altitude)])

    def _rotate_yaw(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        angle = bound.number("angle", None)
        if angle is not None:
            turn = angle
        else:
            turn = (bound.number("orientation_angle") - state.heading + 180.0) % 360.0 - 180.0
        after = self.hover(state, abs(turn) / self.profile.yaw_rate)
        return Step(state, replace(after, heading=(state.heading + turn) % 360.0), labels=labels)

    def _mission_item(self, bound: BoundAction, state: PredictedState,
                      labels: Labels) -> Step:
        """A raw mission item, as the autopilot flies its command: a take-off climbs, a
        navigation item with a position flies there (and holds or loiters its param1
        seconds where the command says so), a landing lands, a return to launch comes
        home; other commands (DO_, CONDITION_) take no time. A DO_JUMP's repeats are not
        predicted."""
        command = bound.text("command").removeprefix("MAV_CMD_")
        frame = table_entry(MAV_FRAME, bound.text("frame"))
        hold = bound.number("param1")
        altitude = bound.number("param7")
        if not math.isfinite(altitude):
            altitude = state.position[2]
        elif frame is not None and frame[0] in (0, 5):  # above sea level
            altitude -= self.home.altitude if self.home is not None else DEFAULT_HOME.altitude
        latitude, longitude = bound.number("param5"), bound.number("param6")
        placed = frame is not None and frame[0] in GLOBAL_FRAME_NUMBERS \
            and (latitude or longitude)
        if bound.number("param7") == 0:  # ArduCopter: an altitude of 0 is the current one
            altitude = state.position[2]
        here = self.local(latitude, longitude, altitude, "relative") if placed \
            else (*state.position[:2], altitude)
        if command in ("NAV_TAKEOFF", "NAV_VTOL_TAKEOFF"):
            if state.flying or self.profile.kind is Kind.GROUND:
                return Step(state, state, labels=labels)
            step = self._go(bound, replace(state, flying=True), labels,
                            [(*state.position[:2], altitude)], cruise=False)
            return replace(step, before=state)
        if command in ("NAV_LAND", "NAV_VTOL_LAND"):
            if self.profile.kind is Kind.GROUND:
                return Step(state, state, labels=labels)
            target = (*here[:2], 0.0) if placed else (*state.position[:2], 0.0)
            if self.profile.kind is Kind.FIXED_WING:
                return self._landing(bound, state, labels, target)
            targets = [(*here[:2], state.position[2]), target] if placed else [target]
            step = self._go(bound, state, labels, targets, landing=True, cruise=False)
            return replace(step, after=replace(step.after, flying=False))
        if command == "NAV_RETURN_TO_LAUNCH":
            return self._return_home_and_land(bound, state, labels)
        if command == "NAV_DELAY" and hold > 0:
            return Step(state, self.hover(state, hold), labels=labels)
        if command.startswith("NAV_") and command not in ("NAV_DELAY",):
            step = self._go(bound, state, labels, [here])
            if command in ("NAV_WAYPOINT", "NAV_LOITER_TIME") and hold > 0 \
                    and math.isfinite(hold):
                step = replace(step, after=self.hover(step.after, hold))
            return step
        notes = ("DO_JUMP: its repeats are not predicted",) if command == "DO_JUMP" else ()
        return Step(state, state, labels=labels, notes=notes)

    def _wait(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        return Step(state, self.hover(state, bound.number("duration")), labels=labels)

    def _capture_photos(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        seconds = (bound.integer("count") - 1) * bound.number("interval")
        return Step(state, self.hover(state, seconds), labels=labels)

    def _memorize_point(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        label = bound.labels.get("coordinates")
        if label:
            labels[label] = state.position
        return Step(state, state, labels=labels)

    def _set_speed(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        kind, value = bound.choice("speed_type"), bound.number("speed")
        if kind == "climb":
            after = replace(state, climb_rate=min(value, self.profile.climb_rate))
        elif kind == "descent":
            after = replace(state, descent_rate=min(value, self.profile.descent_rate))
        else:
            after = replace(state, speed=value)
        return Step(state, after, labels=labels, requested_speed=(kind, value))

    def _set_home(self, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
        if "latitude" not in bound.values:
            home = state.position
        else:
            home = self.local(bound.number("latitude"), bound.number("longitude"),
                              bound.number("altitude"), "amsl")
        return Step(state, replace(state, home=home), labels=labels)


def _add(a: Point3, b: tuple[float, ...]) -> Point3:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])
