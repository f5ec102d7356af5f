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

What each action does in the model is the ``motion`` part of its definition in the action
registry (:mod:`tml.actions`), made of the pieces :class:`FlightModel` offers (fly, hover,
circle, land ...); the state and the step are :mod:`tml.actions.motion`'s.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from itertools import pairwise

from tml import geo
from tml.actions.motion import Labels, Loiter, PredictedState, Step
from tml.actions.registry import definition
from tml.language.actions import BoundAction
from tml.language.kinds import Kind, landing_approach
from tml.patterns import (
    CIRCLE_POINTS_PER_TURN,
    circle_chord,
    circle_entry,
    circle_point,
    stop_to_stop,
)
from tml.verify.planner import Planner, Point3, Trajectory, straight
from tml.verify.profile import VehicleProfile
from tml.world import DEFAULT_HOME, World

__all__ = ["FlightModel", "Labels", "Loiter", "PredictedState", "Step"]


class FlightModel:
    """The vehicle profile and the world, ready to predict actions (the paper's k_i)."""

    def __init__(self, profile: VehicleProfile, world: World | None = None) -> None:
        self.profile = profile
        self.world = world or World()
        self.home = self.world.home_or_default
        self.planner = Planner(self.world.obstacles, profile.min_clearance)
        # The ground's height AMSL at a latitude/longitude, or None where it is not known
        # (tml.verify.terrain sets it when terrain data is given).
        self.ground: Callable[[float, float], float | None] | None = None

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
        measured from (terrain: the ground's height there when terrain data is given, else
        taken as home's)."""
        home = self.home if self.home is not None else DEFAULT_HOME
        north, east, _ = geo.to_local(latitude, longitude, home.altitude,
                                      home.latitude, home.longitude, home.altitude)
        up = altitude - home.altitude if reference == "amsl" else altitude
        ground = self.ground(latitude, longitude) \
            if reference == "terrain" and self.ground is not None else None
        if ground is not None:
            up = ground + altitude - home.altitude
        return (north, east, up)

    # --- the actions: each one's model is in its module of tml.actions ----------------------

    def step(self, bound: BoundAction, state: PredictedState,
             labels: Labels | None = None) -> Step:
        """Predict one action from ``state`` (pure: neither argument is changed)."""
        return definition(bound).motion(self, bound, state, dict(labels or {}))

    # --- the pieces the action models (tml.actions) are made of ---------------------------

    def point_of(self, bound: BoundAction, labels: Labels, name: str = "coordinates") -> tuple[
            Point3 | None, str]:
        """The point an argument gives (value or label); (None, label) for an unknown label."""
        if name in bound.labels:
            label = bound.labels[name]
            return labels.get(label), ("" if label in labels else label)
        return bound.point(name, None), ""

    def global_point(self, bound: BoundAction) -> Point3:
        """The local point of the action's latitude, longitude, altitude and reference."""
        return self.local(bound.number("latitude"), bound.number("longitude"),
                          bound.number("altitude"), bound.choice("altitude_reference"))

    def go(self, bound: BoundAction, state: PredictedState, labels: Labels,
           targets: list[Point3], landing: bool = False, cruise: bool = True) -> Step:
        """Fly through ``targets`` (planned around the obstacles); ``landing``: the last is
        a touch-down; ``cruise``: a translation held to the cruise altitude limits."""
        after, legs, blocked = self.fly(state, targets, landing=landing)
        destination = targets[-1] if targets else None
        return Step(state, after, tuple(legs), tuple(blocked), labels=labels,
                    destination=destination, cruise=cruise)

    def unknown(self, state: PredictedState, labels: Labels, label: str) -> Step:
        """The step of a move to a label that holds no point: not predicted, noted."""
        return Step(state, state, labels=labels, unknown_label=label,
                    notes=(f"label {label!r} holds no point here; the move is not predicted",))

    def landing(self, bound: BoundAction, state: PredictedState, labels: Labels,
                touchdown: Point3 | None) -> Step:
        """A fixed-wing's approach and glide to ``touchdown`` (None: straight ahead)."""
        approach, ground = landing_approach(state.position, state.heading, touchdown)
        targets = [ground] if approach == state.position else [approach, ground]
        step = self.go(bound, state, labels, targets, cruise=False)
        return replace(step, after=replace(step.after, flying=False))

    def circle(self, bound: BoundAction, state: PredictedState, labels: Labels,
               centre: Point3, radius: float, turns: int | None = None,
               duration: float | None = None) -> Step:
        """Join the circle around ``centre`` and go round it, as the scripts fly it: to its
        nearest point (not to its centre, often the very thing it circles around), then
        from target to target (:mod:`tml.patterns`) for ``turns`` or ``duration`` seconds
        (neither: until an event ends it)."""
        start = circle_entry(centre, state.position)
        entry = circle_point(centre, radius, start, 0)
        step = self.go(bound, state, labels, [entry] if entry != state.position else [])
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


