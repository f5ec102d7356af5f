"""Kinematics and battery of a simulated multicopter.

A point mass with a heading, flown the way ArduCopter's position controller flies it:
the demanded velocity toward a target is capped by the speed limit and by a square-root
braking curve (v <= sqrt(2 a d)), and the actual velocity approaches the demand no faster
than the acceleration limit; yaw turns toward its target no faster than the yaw-rate limit.
A position-holding copter leans into the wind, so wind costs current but moves the vehicle
only when nothing holds its position (``hold=False``).

The battery integrates current over time: a base load, a hover load while flying and an
effort term growing with speed, climb and wind. Voltage falls linearly from full to empty
with the charge and sags with the current through an internal resistance. On a charging
pad the charge flows back in at the charger's current until the pack is full; the current
is then reported negative, as a battery monitor shows a pack being charged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Vector = tuple[float, float, float]


@dataclass(frozen=True)
class Limits:
    """Speeds in m/s, accelerations in m/s², yaw rate in degrees per second."""

    speed: float = 10.0
    climb: float = 2.5
    descent: float = 1.5
    accel: float = 2.5
    accel_z: float = 1.0
    yaw_rate: float = 90.0


def _toward(current: float, desired: float, step: float) -> float:
    if abs(desired - current) <= step:
        return desired
    return current + math.copysign(step, desired - current)


def wrap_degrees(angle: float) -> float:
    """``angle`` in [0, 360)."""
    return angle % 360.0


class Body:
    """Position (north, east, up) in metres from the origin, velocity, heading in degrees."""

    def __init__(self, heading: float = 0.0) -> None:
        self.position: Vector = (0.0, 0.0, 0.0)
        self.velocity: Vector = (0.0, 0.0, 0.0)
        self.heading = wrap_degrees(heading)

    def velocity_toward(self, target: Vector, limits: Limits) -> Vector:
        """The velocity demand that brings the body to ``target`` and stops it there."""
        dn, de = target[0] - self.position[0], target[1] - self.position[1]
        du = target[2] - self.position[2]
        horizontal = math.hypot(dn, de)
        speed = min(limits.speed, math.sqrt(2.0 * limits.accel * horizontal))
        vn, ve = (dn / horizontal * speed, de / horizontal * speed) if horizontal > 1e-6 else (0, 0)
        vertical_limit = limits.climb if du > 0 else limits.descent
        vu = math.copysign(min(vertical_limit, math.sqrt(2.0 * limits.accel_z * abs(du))), du)
        return vn, ve, vu

    def move(
        self, demand: Vector, limits: Limits, dt: float,
        wind: tuple[float, float] = (0.0, 0.0), hold: bool = True, target: Vector | None = None,
    ) -> None:
        """Advance ``dt`` seconds chasing the velocity ``demand``.

        With a ``target``, a step that would cross it ends on it, so the discrete step does
        not oscillate around the point the square-root curve stops at; the speed left over
        from the acceleration limit's lag may still carry the body a few centimetres past
        before it settles back.
        """
        step_h, step_v = limits.accel * dt, limits.accel_z * dt
        vn, ve, vu = self.velocity
        dvn, dve = demand[0] - vn, demand[1] - ve
        change = math.hypot(dvn, dve)
        if change > step_h:
            dvn, dve = dvn / change * step_h, dve / change * step_h
        vn, ve, vu = vn + dvn, ve + dve, _toward(vu, demand[2], step_v)
        if not hold:
            vn, ve = vn + wind[0], ve + wind[1]
        n, e, u = self.position
        n, e, u = n + vn * dt, e + ve * dt, u + vu * dt
        if target is not None:
            n, e, u = _clamp_past(self.position, (n, e, u), target)
        if not hold:
            vn, ve = vn - wind[0], ve - wind[1]
        self.position = (n, e, u)
        self.velocity = (vn, ve, vu)

    def turn(self, heading: float, rate: float, dt: float) -> None:
        """Turn toward ``heading`` (degrees) at most ``rate`` degrees per second."""
        error = (heading - self.heading + 180.0) % 360.0 - 180.0
        self.heading = wrap_degrees(self.heading + max(-rate * dt, min(rate * dt, error)))

    def stop(self) -> None:
        """Zero velocity (touchdown, collision)."""
        self.velocity = (0.0, 0.0, 0.0)


def _clamp_past(start: Vector, end: Vector, target: Vector) -> Vector:
    """``end``, or the target on each axis group the step would have crossed."""
    n, e, u = end
    to_target = (target[0] - start[0], target[1] - start[1])
    moved = (end[0] - start[0], end[1] - start[1])
    if to_target[0] * moved[0] + to_target[1] * moved[1] > 0 and math.hypot(*moved) >= math.hypot(
        *to_target
    ):
        n, e = target[0], target[1]
    if (target[2] - start[2]) * (end[2] - start[2]) > 0 and abs(end[2] - start[2]) >= abs(
        target[2] - start[2]
    ):
        u = target[2]
    return n, e, u


class Battery:
    """Charge in mAh, terminal voltage, and the current drawn (A)."""

    EMPTY_VOLTS = 10.5  # a 3S pack at 3.5 V per cell
    RESISTANCE = 0.015  # ohm: sag under load

    def __init__(self, capacity_mah: float, full_volts: float = 12.6) -> None:
        self.capacity_mah = capacity_mah
        self.full_volts = full_volts
        self.consumed_mah = 0.0
        self.current = 0.0
        self.failed = False

    def drain(self, dt: float, current: float) -> None:
        """Draw ``current`` amperes for ``dt`` seconds."""
        self.current = current
        self.consumed_mah = min(self.capacity_mah, self.consumed_mah + current * dt / 3.6)

    def charge(self, dt: float, current: float) -> None:
        """Take ``current`` amperes from a charger for ``dt`` seconds, stopping when full.

        A failed battery takes no charge. The current is the one that actually flowed
        (negative), so a full pack on the charger shows zero.
        """
        taken = 0.0 if self.failed else min(self.consumed_mah, current * dt / 3.6)
        self.consumed_mah -= taken
        self.current = -taken * 3.6 / dt

    @property
    def remaining(self) -> int:
        """Percent of capacity left (0 after a battery failure)."""
        if self.failed:
            return 0
        return max(0, round(100.0 * (1.0 - self.consumed_mah / self.capacity_mah)))

    @property
    def voltage(self) -> float:
        """Terminal voltage under the present load."""
        if self.failed:
            return self.EMPTY_VOLTS - 1.0
        fraction = 1.0 - self.consumed_mah / self.capacity_mah
        return self.EMPTY_VOLTS + (self.full_volts - self.EMPTY_VOLTS) * fraction - (
            self.current * self.RESISTANCE
        )


def flight_current(armed: bool, flying: bool, velocity: Vector, wind_speed: float) -> float:
    """Amperes drawn: electronics, spinning motors, hovering, and effort."""
    if not armed:
        return 0.5
    if not flying:
        return 3.0
    horizontal = math.hypot(velocity[0], velocity[1])
    return 12.0 + 0.4 * horizontal + 3.0 * max(velocity[2], 0.0) + 0.6 * wind_speed
