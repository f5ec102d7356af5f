"""Kinematics and battery of a simulated multicopter.

A point mass with a heading, flown the way ArduCopter's position controller flies it:
the demanded velocity toward a target is capped by the speed limit and by a square-root
braking curve (v <= sqrt(2 a d)), and the actual velocity approaches the demand no faster
than the acceleration limit; yaw turns toward its target no faster than the yaw-rate limit.
A position-holding copter leans into the wind, so wind costs current but moves the vehicle
only when nothing holds its position (``hold=False``).

The battery integrates current over time, drawn as ArduCopter SITL draws it: nothing on
the ground, a hover load in flight, more to climb and to fly fast, less to descend. Its
voltage stays at the full value as ArduCopter SITL's does, unless a simulated cell
capacity is given: then it falls linearly from full to empty with the charge and sags with
the current through an internal resistance. On a charging pad the charge flows back in at
the charger's current until the pack is full; the current is then reported negative, as a
battery monitor shows a pack being charged.
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
    """Charge in mAh, terminal voltage, and the current drawn (A).

    ``capacity_mah`` is the battery monitor's capacity (``BATT_CAPACITY``): the percentage
    left counts down from it, and the consumed charge goes on counting past it, as on
    ArduPilot. ``cell_capacity_mah`` is the simulated pack's (``SIM_BATT_CAP_AH`` x 1000):
    0, ArduPilot SITL's default, keeps the voltage at ``full_volts`` whatever is drawn (as
    ArduCopter SITL shows it); above 0 the voltage falls linearly to :attr:`EMPTY_VOLTS`
    as that charge is used and sags with the current through an internal resistance.
    """

    EMPTY_VOLTS = 10.5  # a 3S pack at 3.5 V per cell
    RESISTANCE = 0.015  # ohm: sag under load

    def __init__(self, capacity_mah: float, full_volts: float = 12.6,
                 cell_capacity_mah: float = 0.0) -> None:
        self.capacity_mah = capacity_mah
        self.cell_capacity_mah = cell_capacity_mah
        self.full_volts = full_volts
        self.consumed_mah = 0.0
        self.current = 0.0
        self.failed = False

    def drain(self, dt: float, current: float) -> None:
        """Draw ``current`` amperes for ``dt`` seconds."""
        self.current = current
        self.consumed_mah += current * dt / 3.6

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
        if self.cell_capacity_mah <= 0:
            return self.full_volts
        fraction = max(0.0, 1.0 - self.consumed_mah / self.cell_capacity_mah)
        return self.EMPTY_VOLTS + (self.full_volts - self.EMPTY_VOLTS) * fraction - (
            self.current * self.RESISTANCE
        )


# ArduCopter SITL's current (copter.parm, its default quadcopter), measured in GUIDED with
# velocity targets at 30 m (docs/simulator.md): nothing while disarmed or armed on the ground,
# 28.1 A hovering, about 0.96 A more per m/s of climb and 0.8 A less per m/s of descent,
# and a level-flight term that grows with the cube of the speed (+0.2 A at 5 m/s, +0.7 A
# at 7.5 m/s, +2.2 A at 10 m/s).
HOVER_AMPS = 28.1
CLIMB_AMPS = 0.96  # per m/s up
DESCENT_AMPS = 0.8  # per m/s down
SPEED_AMPS = 0.0022  # per (m/s)^3 of horizontal speed
WIND_AMPS = 0.014  # per m/s of wind, hovering against it (+0.03 A at 5 m/s, +0.14 A at 10)


def flight_current(armed: bool, flying: bool, velocity: Vector, wind_speed: float) -> float:
    """Amperes drawn, as ArduCopter SITL draws them: only the motors of a flying vehicle."""
    if not (armed and flying):
        return 0.0
    horizontal = math.hypot(velocity[0], velocity[1])
    vertical = velocity[2] * (CLIMB_AMPS if velocity[2] > 0 else DESCENT_AMPS)
    return HOVER_AMPS + SPEED_AMPS * horizontal ** 3 + vertical + WIND_AMPS * wind_speed
