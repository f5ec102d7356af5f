"""Kinematics and battery of a simulated multicopter.

A point mass with a heading, flown the way ArduCopter's position controller flies it
(``AC_PosControl`` and ``AP_Math/control.cpp``): the controller shapes a *target* that
moves toward the goal, and the simulated vehicle is that target. The shaping is
ArduPilot's, per control tick: a square-root controller turns the position error into a
velocity (linear near the goal, ``sqrt(2 a d)`` farther away, with half the acceleration
limit so that braking never overshoots), a second one turns the velocity error into an
acceleration within the acceleration limit, and the acceleration changes no faster than
the jerk limit. Horizontal and vertical axes are shaped apart, each with its own limits
(``WPNAV_SPEED``/``WPNAV_ACCEL``/``PSC_JERK_XY`` and ``WPNAV_SPEED_UP``/``_DN``/
``WPNAV_ACCEL_Z``/``PSC_JERK_Z``). A feed-forward velocity and acceleration let the same
controller follow a moving target: the S-curve legs of :mod:`sitl.track` (AUTO and RTL).
Yaw turns toward its target no faster than the yaw-rate limit.
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
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sitl.params import Params

Vector = tuple[float, float, float]
ZERO: Vector = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Limits:
    """Speeds in m/s, accelerations in m/s², jerks in m/s³, yaw rate in degrees per second.

    The defaults are ArduCopter's: ``WPNAV_SPEED``, ``WPNAV_SPEED_UP``, ``WPNAV_SPEED_DN``,
    ``WPNAV_ACCEL``, ``WPNAV_ACCEL_Z``, ``PSC_JERK_XY``, ``PSC_JERK_Z``.
    """

    speed: float = 10.0
    climb: float = 2.5
    descent: float = 1.5
    accel: float = 2.5
    accel_z: float = 1.0
    yaw_rate: float = 90.0
    jerk: float = 5.0
    jerk_z: float = 5.0


def sqrt_controller(error: float, gain: float, limit: float, dt: float) -> float:
    """ArduPilot's ``sqrt_controller``: ``gain * error`` near zero, ``sqrt(2 limit error)``
    beyond ``limit / gain²``, never more than would cross zero within ``dt``."""
    linear = limit / (gain * gain)
    if error > linear:
        correction = math.sqrt(2.0 * limit * (error - linear / 2.0))
    elif error < -linear:
        correction = -math.sqrt(2.0 * limit * (-error - linear / 2.0))
    else:
        correction = error * gain
    step = abs(error) / dt
    # max(-step, min(step, correction)), without the two calls (the same comparisons)
    correction = correction if correction < step else step
    return correction if correction > -step else -step


def _limit(x: float, y: float, length: float) -> tuple[float, float]:
    size = math.hypot(x, y)
    if size > length:
        return x / size * length, y / size * length
    return x, y


def _corner_limit(vn: float, ve: float, an: float, ae: float, accel: float
                  ) -> tuple[float, float]:
    """ArduPilot's ``limit_accel_corner_xy``: within ``accel``, keeping at least 1/sqrt(2)
    of it across the direction of travel so that a turn is never starved by braking."""
    speed = math.hypot(vn, ve)
    if speed < 1e-9:
        return _limit(an, ae, accel)
    un, ue = vn / speed, ve / speed
    along = un * an + ue * ae
    cn, ce = an - un * along, ae - ue * along
    if along * along <= cn * cn + ce * ce:
        return _limit(an, ae, accel)
    cn, ce = _limit(cn, ce, accel / math.sqrt(2.0))
    room = math.sqrt(max(0.0, accel * accel - cn * cn - ce * ce))
    along = max(-room, min(room, along))
    return cn + un * along, ce + ue * along


def wrap_degrees(angle: float) -> float:
    """``angle`` in [0, 360)."""
    return angle % 360.0


class Body:
    """Position (north, east, up) in metres from the origin, velocity, acceleration, and
    heading in degrees."""

    def __init__(self, heading: float = 0.0) -> None:
        self.position: Vector = ZERO
        self.velocity: Vector = ZERO
        self.accel: Vector = ZERO
        self.heading = wrap_degrees(heading)

    def shape(self, target: Vector, limits: Limits, dt: float, velocity: Vector = ZERO,
              accel: Vector = ZERO, climb_rate: float | None = None) -> None:
        """Advance ``dt`` seconds toward ``target`` (ArduPilot's ``shape_pos_vel_accel``),
        with ``velocity`` and ``accel`` fed forward when the target itself moves; with a
        ``climb_rate`` the vertical axis holds that rate instead of the target's altitude
        (a landing).

        Every control step of every flying vehicle comes here: the small helpers above
        (``_limit``, ``min``, ``max``) are written out in place (the same operations in the
        same order, so the same floats), which saves several Python calls a step; the
        square-root controllers are :func:`sqrt_controller`'s, called once each."""
        n, e, u = self.position
        speed = limits.speed
        # Half the acceleration for the approach: braking never overshoots the goal.
        # The position error through a square-root controller (within ``half``), the
        # velocity this asks for within the speed limit (_limit)
        half, gain = 0.5 * limits.accel, 0.5 * limits.jerk / limits.accel
        x, y = target[0] - n, target[1] - e
        size = math.hypot(x, y)
        if size < 1e-9:
            cn = ce = 0.0
        else:
            scale = sqrt_controller(size, gain, half, dt) / size
            cn, ce = x * scale, y * scale
        size = math.hypot(cn, ce)
        if size > speed:
            cn, ce = cn / size * speed, ce / size * speed
        cn, ce = cn + velocity[0], ce + velocity[1]  # _limit(..., speed)
        size = math.hypot(cn, ce)
        if size > speed:
            cn, ce = cn / size * speed, ce / size * speed
        if climb_rate is None:
            half_z, gain_z = 0.5 * limits.accel_z, 0.5 * limits.jerk_z / limits.accel_z
            cu = sqrt_controller(target[2] - u, gain_z, half_z, dt) + velocity[2]
        else:
            cu = climb_rate
        climb, descent = limits.climb, -limits.descent
        cu = cu if cu < climb else climb  # max(-limits.descent, min(limits.climb, cu))
        cu = cu if cu > descent else descent
        self._accelerate(cn, ce, cu, accel, limits, dt)

    def shape_velocity(self, demand: Vector, limits: Limits, dt: float,
                       wind: tuple[float, float] = (0.0, 0.0), hold: bool = True) -> None:
        """Advance ``dt`` seconds approaching the velocity ``demand`` (ArduPilot's
        ``shape_vel_accel``); without ``hold`` the wind carries the body along."""
        self._accelerate(demand[0], demand[1], demand[2], ZERO, limits, dt)
        if not hold:
            n, e, u = self.position
            self.position = (n + wind[0] * dt, e + wind[1] * dt, u)

    def _accelerate(self, dn: float, de: float, du: float, feed: Vector, limits: Limits,
                    dt: float) -> None:
        """Toward the velocity demand (``dn``, ``de``, ``du``) with the acceleration
        ``feed`` fed forward (ArduPilot's ``shape_vel_accel``)."""
        (vn, ve, vu), (an, ae, au) = self.velocity, self.accel
        accel, jerk = limits.accel, limits.jerk
        # The velocity error through a square-root controller (within the jerk)
        x, y = dn - vn, de - ve
        size = math.hypot(x, y)
        if size < 1e-9:
            tn = te = 0.0
        else:
            scale = sqrt_controller(size, jerk / accel, jerk, dt) / size
            tn, te = x * scale, y * scale
        tn, te = _corner_limit(dn, de, tn, te, accel)
        tn, te = tn + feed[0], te + feed[1]  # _limit(..., accel)
        size = math.hypot(tn, te)
        if size > accel:
            tn, te = tn / size * accel, te / size * accel
        x, y = tn - an, te - ae  # _limit(..., jerk * dt)
        size, most = math.hypot(x, y), jerk * dt
        if size > most:
            x, y = x / size * most, y / size * most
        an, ae = an + x, ae + y
        # The vertical acceleration (ArduPilot's shape_vel_accel on one axis)
        limit, jerk = limits.accel_z, limits.jerk_z
        target = sqrt_controller(du - vu, jerk / limit, jerk, dt)
        # max(-limit, min(limit, max(-limit, min(limit, target)) + feed)), and the change
        # of acceleration within the jerk, each min and max written as its comparison
        target = target if target < limit else limit
        target = (target if target > -limit else -limit) + feed[2]
        target = target if target < limit else limit
        target = target if target > -limit else -limit
        most = jerk * dt
        change = target - au
        change = change if change < most else most
        au = au + (change if change > -most else -most)
        n, e, u = self.position
        half_dt2 = 0.5 * dt * dt
        self.position = (n + vn * dt + an * half_dt2, e + ve * dt + ae * half_dt2,
                         u + vu * dt + au * half_dt2)
        self.velocity = (vn + an * dt, ve + ae * dt, vu + au * dt)
        self.accel = (an, ae, au)

    def turn(self, heading: float, rate: float, dt: float, direction: int = 0) -> None:
        """Turn toward ``heading`` (degrees) at most ``rate`` degrees per second: the
        shorter way, or clockwise (``direction`` 1) or anticlockwise (-1) however far."""
        error = (heading - self.heading + 180.0) % 360.0 - 180.0
        if direction > 0 and error < 0.0:
            error += 360.0
        elif direction < 0 and error > 0.0:
            error -= 360.0
        most = rate * dt  # max(-most, min(most, error))
        error = error if error < most else most
        self.heading = wrap_degrees(self.heading + (error if error > -most else -most))

    def restart_shaping(self) -> None:
        """Start shaping afresh from the velocity it has: ArduCopter's ``init_xy_controller``
        sets the desired horizontal acceleration to zero (the measured one is too noisy)."""
        self.accel = (0.0, 0.0, self.accel[2])

    def stop(self) -> None:
        """Zero velocity and acceleration (touchdown, collision)."""
        self.velocity = ZERO
        self.accel = ZERO


def stopping_distance(speed: float, gain: float, accel: float) -> float:
    """Where ArduCopter's position controller says a vehicle at ``speed`` stops
    (``AC_PosControl`` ``stopping_distance``, ``gain`` is ``PSC_POSXY_P``)."""
    if speed <= accel / gain:
        return speed / gain
    return accel / (2.0 * gain * gain) + speed * speed / (2.0 * accel)


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

    @classmethod
    def from_params(cls, params: Params) -> Battery:
        """The battery ``params`` describe at boot: the monitor's ``BATT_CAPACITY``, the
        simulated pack's ``SIM_BATT_VOLTAGE`` and ``SIM_BATT_CAP_AH``, and a pack not
        full at boot (``SIM_BATT_START`` percent) having used the rest of its capacity."""
        battery = cls(params["BATT_CAPACITY"], params["SIM_BATT_VOLTAGE"],
                      params["SIM_BATT_CAP_AH"] * 1000.0)
        start = min(max(params["SIM_BATT_START"], 0.0), 100.0)
        battery.consumed_mah = battery.capacity_mah * (100.0 - start) / 100.0
        return battery

    def configure(self, params: Params) -> None:
        """Take the capacities ``params`` give now (after a parameter write)."""
        self.capacity_mah = params["BATT_CAPACITY"]
        self.cell_capacity_mah = params["SIM_BATT_CAP_AH"] * 1000.0

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
