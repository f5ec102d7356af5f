"""Waypoint legs flown as ArduCopter flies them: S-curves, blended at corners.

ArduCopter's waypoint navigator (``AC_WPNav`` with ``AP_Math/SCurve``) flies every straight
leg, in AUTO and in RTL, as a jerk-limited S-curve from rest to rest: the acceleration
ramps at ``WPNAV_JERK`` (1 m/s³ by default) up to ``WPNAV_ACCEL``, the speed up to
``WPNAV_SPEED`` (``WPNAV_SPEED_UP``/``_DN`` and ``WPNAV_ACCEL_Z`` bound the vertical part of
a leg that climbs or descends), and everything mirrors down to rest at the destination.
A 40 m leg from the hover so peaks near 7 m/s and takes about 11 s, not the 5 s a
vehicle that only respects the acceleration limit would take.

When the next waypoint is known ahead (a "fast waypoint": a NAV_WAYPOINT without a hold
time followed by another waypoint, or RTL's climb followed by its return), the next leg's
S-curve starts before this one has ended, once ArduPilot's conditions hold (this leg past
half way and in its last half of the next leg's duration, the point where the two would
meet within ``WPNAV_RADIUS`` of the corner, not faster there than either leg's top speed).
The target is the sum of both curves, so the corner is rounded and flown at about 3 m/s for
a right angle; this leg counts as reached (MISSION_ITEM_REACHED) when the next one has run
as long as this one had left, the apex of the turn. A last leg is reached when its curve
ends at the destination.

The jerk itself rises and falls along raised cosines (ArduPilot limits the snap, the jerk's
rate of change) over twice ``ATC_INPUT_TC``, 0.3 s, which slows each leg by about as much.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sitl.physics import ZERO, Limits, Vector


def kinematic_limit(unit: Vector, horizontal: float, up: float, down: float) -> float:
    """The largest value along the direction ``unit`` whose horizontal and vertical parts
    stay within their limits (ArduPilot's ``kinematic_limit``)."""
    across = math.hypot(unit[0], unit[1])
    vertical = up if unit[2] > 0 else down
    if across < 1e-9:
        return vertical
    if abs(unit[2]) < 1e-9:
        return horizontal
    return min(horizontal / across, vertical / abs(unit[2]))


# Segment kinds: the jerk rises from 0 to its value along a raised cosine (ArduPilot's
# snap limit), holds it, or falls back to 0 along a raised cosine.
RISE, HOLD, FALL = 1, 0, -1


class SCurve:
    """Motion over ``length`` metres to rest, starting at ``initial`` m/s: jerk ``jerk``,
    within ``accel`` and ``speed``. Each change of speed ramps the acceleration up, holds
    it, and ramps it down; a ramp's jerk rises and falls along raised cosines lasting
    ``jerk_time`` seconds (ArduPilot's snap limit; 0 for instant jerk changes).
    The curve accelerates to its top speed, cruises, and brakes to rest."""

    def __init__(self, length: float, speed: float, accel: float, jerk: float,
                 initial: float = 0.0, jerk_time: float = 0.0) -> None:
        self.length = length
        self.duration = 0.0
        # start time, distance, speed, acceleration, jerk, kind, span
        self._segments: list[tuple[float, float, float, float, float, int, float]] = []
        if length <= 0.0 or speed <= 0.0:
            return
        self._accel, self._jerk, self._jerk_time = accel, jerk, jerk_time
        peak = self._peak(length, speed, initial)
        cruise = max(0.0, length - self._distance(initial, peak) - self._distance(peak, 0.0))
        t, s, v, a = 0.0, 0.0, initial, 0.0
        plan = (*self._change(initial, peak), (0.0, HOLD, cruise / peak if peak > 0 else 0.0),
                *self._change(peak, 0.0))
        for j, kind, span in plan:
            if span <= 0.0:
                continue
            self._segments.append((t, s, v, a, j, kind, span))
            s, v, a = _advance(s, v, a, j, kind, span, span)
            t += span
        self.duration = t

    def _ramp(self, change: float) -> tuple[float, float, float]:
        """(jerk, constant-jerk time, time at the peak acceleration) of a change of speed by
        ``change`` m/s: the acceleration limit when there is room to reach it, less when
        there is not."""
        change = abs(change)
        tj, jerk, accel = self._jerk_time, self._jerk, self._accel

        def shape(peak: float) -> tuple[float, float]:  # jerk, constant-jerk time
            if peak >= jerk * tj:
                return jerk, peak / jerk - tj
            return peak / tj, 0.0

        j, t2 = shape(accel)
        if change >= accel * (2.0 * tj + t2):
            return j, t2, change / accel - (2.0 * tj + t2)
        peak = jerk / 2.0 * (-tj + math.sqrt(tj * tj + 4.0 * change / jerk))
        if peak < jerk * tj:
            peak = change / (2.0 * tj)
        j, t2 = shape(peak)
        return j, t2, 0.0

    def _change(self, start: float, end: float) -> tuple[tuple[float, int, float], ...]:
        """(jerk, kind, span) of the segments that take the speed from ``start`` to ``end``."""
        j, t2, hold = self._ramp(end - start)
        j = j if end > start else -j
        tj = self._jerk_time
        return ((j, RISE, tj), (j, HOLD, t2), (j, FALL, tj), (0.0, HOLD, hold),
                (-j, RISE, tj), (-j, HOLD, t2), (-j, FALL, tj))

    def _distance(self, start: float, end: float) -> float:
        """Metres covered changing speed from ``start`` to ``end``: the ramps are symmetric,
        so the mean speed is the middle one."""
        _, t2, hold = self._ramp(end - start)
        return (start + end) / 2.0 * (2.0 * (2.0 * self._jerk_time + t2) + hold)

    def _peak(self, length: float, speed: float, initial: float) -> float:
        """The top speed of the curve: the highest within ``speed`` that still stops in
        ``length`` (found by bisection; the distance grows with the top speed)."""
        low = min(initial, speed)
        if self._distance(initial, low) + self._distance(low, 0.0) >= length:
            return low  # already too fast to stop in time: brake at once
        if self._distance(initial, speed) + self._distance(speed, 0.0) <= length:
            return speed
        high = speed
        for _ in range(40):
            middle = (low + high) / 2.0
            if self._distance(initial, middle) + self._distance(middle, 0.0) <= length:
                low = middle
            else:
                high = middle
        return low

    def at(self, elapsed: float) -> tuple[float, float, float]:
        """Distance along, speed and acceleration ``elapsed`` seconds after the start."""
        if elapsed <= 0.0 or not self._segments:
            return 0.0, (self._segments[0][2] if self._segments else 0.0), 0.0
        if elapsed >= self.duration:
            return self.length, 0.0, 0.0
        for start, s, v, a, j, kind, span in reversed(self._segments):
            if elapsed >= start:
                return _advance(s, v, a, j, kind, span, elapsed - start)
        return 0.0, 0.0, 0.0  # pragma: no cover - the first segment starts at 0


def _advance(s: float, v: float, a: float, j: float, kind: int, span: float, t: float
             ) -> tuple[float, float, float]:
    """Distance, speed and acceleration ``t`` seconds into a segment."""
    if kind == HOLD:
        return (s + v * t + a * t * t / 2.0 + j * t ** 3 / 6.0, v + a * t + j * t * t / 2.0,
                a + j * t)
    # Jerk j/2 (1 - kind cos(pi t / span)): rising from 0 (RISE) or falling to 0 (FALL).
    k = span / math.pi
    sine, cosine = math.sin(t / k), math.cos(t / k)
    half = j / 2.0
    return (s + v * t + a * t * t / 2.0 + half * (t ** 3 / 6.0 + kind * k * k * (k * sine - t)),
            v + a * t + half * (t * t / 2.0 + kind * k * k * (cosine - 1.0)),
            a + half * (t - kind * k * sine))


@dataclass
class Leg:
    """One straight leg: where it goes, its curve, and when it started (None: not yet)."""

    origin: Vector
    destination: Vector
    unit: Vector
    curve: SCurve
    speed: float
    limits: Limits
    start: float | None = None

    def at(self, time: float) -> tuple[float, float, float]:
        """(distance, speed, acceleration) along the leg at ``time``."""
        return self.curve.at(time - self.start) if self.start is not None else (0.0, 0.0, 0.0)

    def remaining(self, time: float) -> float:
        """Seconds of the curve left at ``time``."""
        if self.start is None:
            return self.curve.duration
        return max(0.0, self.curve.duration - (time - self.start))


@dataclass(frozen=True)
class Shape:
    """The S-curves' own limits: ``WPNAV_JERK`` (m/s³), and the time the jerk takes to
    rise or fall, ArduPilot's snap limit: twice ``ATC_INPUT_TC`` (at least 0.2 s)."""

    jerk: float = 1.0
    jerk_time: float = 0.3


def _along(origin: Vector, unit: Vector, distance: float) -> Vector:
    """The point ``distance`` metres from ``origin`` along ``unit``."""
    return (origin[0] + unit[0] * distance, origin[1] + unit[1] * distance,
            origin[2] + unit[2] * distance)


def make_leg(origin: Vector, destination: Vector, limits: Limits, shape: Shape,
             initial: float = 0.0) -> Leg:
    """A leg from ``origin`` to ``destination`` within ``limits`` and ``shape``, starting at
    ``initial`` m/s along it."""
    delta = tuple(b - a for a, b in zip(origin, destination, strict=True))
    length = math.sqrt(sum(d * d for d in delta))
    unit: Vector = (delta[0] / length, delta[1] / length, delta[2] / length) if (
        length > 1e-9) else ZERO
    speed = kinematic_limit(unit, limits.speed, limits.climb, limits.descent)
    accel = kinematic_limit(unit, limits.accel, limits.accel_z, limits.accel_z)
    curve = SCurve(length, speed, accel, shape.jerk, initial, shape.jerk_time)
    return Leg(origin, destination, unit, curve, speed, limits)


class Track:
    """The waypoint navigator's target: the leg in progress, the next one once it has
    begun, and the rest of legs already counted as reached."""

    def __init__(self, leg: Leg, time: float, radius: float) -> None:
        leg.start = time
        self.leg = leg
        self.next: Leg | None = None
        self.radius = radius
        self.reached = False
        self._tails: list[Leg] = []  # legs reached whose curves still run
        self._base = leg.origin  # where the curves still running started from

    @property
    def destination(self) -> Vector:
        """Where the leg in progress ends."""
        return self.leg.destination

    def set_next(self, leg: Leg | None) -> None:
        """The leg to blend into at the end of this one (None: stop at the destination)."""
        if self.next is None or self.next.start is None:
            self.next = leg

    def promote(self) -> bool:
        """Make the next leg the one in progress, once this one is reached; False if there
        is no next leg to go on with."""
        if not self.reached or self.next is None:
            return False
        if self.next.start is None:
            self._fold(self.leg)
        else:
            self._tails.append(self.leg)
        self.leg, self.next, self.reached = self.next, None, False
        if self.leg.start is None:
            self.leg.start = self._now
        return True

    def replan(self, limits: Limits, shape: Shape, time: float) -> None:
        """Plan the leg in progress again within new ``limits`` from where its curve is
        (ArduCopter recalculates its leg when the speed changes), and the next leg too if
        it has not begun."""
        leg = self.leg
        if leg.start is not None and not self.reached and leg.limits != limits:
            s, v, _ = leg.at(time)
            here = _along(leg.origin, leg.unit, s)
            self._base = _along(self._base, leg.unit, s)
            self.leg = make_leg(here, leg.destination, limits, shape, v)
            self.leg.start = time
        following = self.next
        if following is not None and following.start is None and following.limits != limits:
            self.next = make_leg(following.origin, following.destination, limits, shape)

    def update(self, time: float) -> tuple[Vector, Vector, Vector]:
        """The target's position, velocity and acceleration at ``time``."""
        self._now = time
        leg, following = self.leg, self.next
        if following is not None and following.start is None and self._may_turn(time):
            following.start = time
        if not self.reached:
            if following is not None and following.start is not None:
                self.reached = time - following.start >= leg.remaining(time)
            else:
                self.reached = leg.remaining(time) <= 0.0
        for tail in [t for t in self._tails if t.remaining(time) <= 0.0]:
            self._tails.remove(tail)
            self._fold(tail)
        position, velocity, accel = list(self._base), [0.0] * 3, [0.0] * 3
        for each in (*self._tails, leg, following):
            if each is None or each.start is None:
                continue
            s, v, a = each.at(time)
            for axis in range(3):
                position[axis] += each.unit[axis] * s
                velocity[axis] += each.unit[axis] * v
                accel[axis] += each.unit[axis] * a
        return (position[0], position[1], position[2]), (velocity[0], velocity[1], velocity[2]), (
            accel[0], accel[1], accel[2])

    _now = 0.0

    def _fold(self, leg: Leg) -> None:
        self._base = _along(self._base, leg.unit, leg.curve.length)

    def _may_turn(self, time: float) -> bool:
        """ArduPilot's conditions for starting the next leg of a fast waypoint."""
        leg, following = self.leg, self.next
        assert following is not None and leg.start is not None
        left = leg.remaining(time)
        s, _, _ = leg.at(time)
        if left >= following.curve.duration / 2.0 or s < leg.curve.length / 2.0:
            return False
        # Where and how fast the two curves would meet half-way through the overlap.
        s_this, v_this, _ = leg.curve.at(time - leg.start + left / 2.0)
        s_next, v_next, _ = following.curve.at(left / 2.0)
        offset = [following.unit[i] * s_next - leg.unit[i] * (leg.curve.length - s_this)
                  for i in range(3)]
        speed = math.hypot(*(leg.unit[i] * v_this + following.unit[i] * v_next
                             for i in range(2)))
        return math.sqrt(sum(o * o for o in offset)) < self.radius and speed < min(
            leg.speed, following.speed)
