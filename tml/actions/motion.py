"""The motion toolkit: what the action modules' motion models for ``tml verify`` are made of.

A motion model (the ``motion`` part of an :class:`~tml.actions.definition.ActionDef`)
predicts one action: from a :class:`PredictedState` before it, the :class:`Step` it takes,
without looking at any constraint. It reads the vehicle's profile, the world and the pieces
every action is made of (flying through targets, hovering, circling, landing ...) from a
:class:`Motion`, which :class:`tml.verify.motion.FlightModel` is; the theory of the model
(time, energy, kinds of vehicle) is told there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Protocol

from tml.language.actions import BoundAction
from tml.language.kinds import Kind
from tml.patterns import circle
from tml.world import Home, World

Point3 = tuple[float, float, float]  # (north, east, up) in metres from home
Labels = dict[str, Point3]


@dataclass(frozen=True)
class Trajectory:
    """A path of straight segments in the local frame, from its first point to its last."""

    points: tuple[Point3, ...]

    @property
    def length(self) -> float:
        """Length in metres, climbs and descents included (the paper's Length)."""
        return sum(math.dist(a, b) for a, b in pairwise(self.points))

    @property
    def horizontal_length(self) -> float:
        """Length in metres over the ground."""
        return sum(math.hypot(b[0] - a[0], b[1] - a[1])
                   for a, b in pairwise(self.points))


def straight(a: Point3, b: Point3) -> Trajectory:
    """The straight segment from ``a`` to ``b``."""
    return Trajectory((a, b)) if a != b else Trajectory((a,))


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
    grounded: bool = False  # time spent on the ground by design (a WAIT there), no flight
    notes: tuple[str, ...] = ()
    photos: tuple[Point3, ...] = ()  # where the camera is predicted to take photos

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


def add(a: Point3, b: tuple[float, ...]) -> Point3:
    """``a`` moved by ``b``."""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


class Profile(Protocol):
    """What the action models read of the vehicle's profile
    (:class:`tml.verify.profile.VehicleProfile`)."""

    @property
    def kind(self) -> Kind: ...
    @property
    def takeoff_altitude(self) -> float: ...
    @property
    def climb_rate(self) -> float: ...
    @property
    def descent_rate(self) -> float: ...
    @property
    def cruise_speed(self) -> float: ...
    @property
    def yaw_rate(self) -> float: ...


class Motion(Protocol):
    """The flight model as the action models use it (:class:`tml.verify.motion.FlightModel`)."""

    @property
    def profile(self) -> Profile: ...
    @property
    def world(self) -> World: ...
    @property
    def home(self) -> Home: ...

    def go(self, bound: BoundAction, state: PredictedState, labels: Labels,
           targets: list[Point3], landing: bool = False, cruise: bool = True) -> Step:
        """Fly through ``targets``; ``landing``: the last is a touch-down; ``cruise``: a
        translation held to the cruise altitude limits."""
        ...

    def hover(self, state: PredictedState, seconds: float) -> PredictedState:
        """The state after hovering in place."""
        ...

    def point_of(self, bound: BoundAction, labels: Labels,
                 name: str = "coordinates") -> tuple[Point3 | None, str]:
        """The point an argument gives (value or label); (None, label) for an unknown label."""
        ...

    def unknown(self, state: PredictedState, labels: Labels, label: str) -> Step:
        """The step of a move to a label that holds no point."""
        ...

    def global_point(self, bound: BoundAction) -> Point3:
        """The local point of the action's latitude, longitude, altitude and reference."""
        ...

    def local(self, latitude: float, longitude: float, altitude: float,
              reference: str) -> Point3:
        """A WGS84 position as a local point."""
        ...

    def landing(self, bound: BoundAction, state: PredictedState, labels: Labels,
                touchdown: Point3 | None) -> Step:
        """A fixed-wing's approach and glide to ``touchdown`` (None: straight ahead)."""
        ...

    def circle(self, bound: BoundAction, state: PredictedState, labels: Labels,
               centre: Point3, radius: float, turns: int | None = None,
               duration: float | None = None) -> Step:
        """Join the circle around ``centre`` and go round it."""
        ...

    def fly_home_and_land(self, state: PredictedState, home: Point3, planned: bool = True
                          ) -> tuple[PredictedState, list[Trajectory],
                                     list[tuple[Point3, Point3]]]:
        """ArduPilot's RTL from ``state``."""
        ...


def instant(model: Motion, bound: BoundAction, state: PredictedState, labels: Labels) -> Step:
    """The model of an action that takes no time or battery in the model (a photo, the
    gripper, STABILIZE's brake): it says so in a note."""
    return Step(state, state, labels=labels,
                notes=(f"{bound.name} takes no time or battery in the model",))
