"""How fast the navigation flies: the parameters' speeds and accelerations, and the
DO_CHANGE_SPEED (or DO_REPOSITION) overrides of them, as ArduCopter's position
controller and waypoint navigator take them.

The horizontal speed is ``WPNAV_SPEED`` (``RTL_SPEED`` in RTL when set), the climb and
descent ``WPNAV_SPEED_UP`` and ``WPNAV_SPEED_DN``, each until an override replaces it;
BRAKE decelerates at :data:`BRAKE_DECEL` instead of ``WPNAV_ACCEL``; in the pilot's modes
the vertical limits are the stick's (``PILOT_SPEED_UP``, ``PILOT_SPEED_DN``,
``PILOT_ACCEL_Z``). The :class:`sitl.physics.Limits` are asked for at every control step
and kept until a parameter write, a mode change or a speed override changes them.
"""

from __future__ import annotations

from typing import Any

from sitl.auto import SPEED_CLIMB, SPEED_DESCENT
from sitl.modes import PILOT_MODES
from sitl.params import Params
from sitl.physics import Limits
from sitl.track import Shape

# m/s², ArduCopter's BRAKE_MODE_DECEL_RATE; reached at PSC_JERK_XY, so that from 10 m/s
# BRAKE stops in about 20 m as ArduCopter SITL does, no shorter than GUIDED's stop.
BRAKE_DECEL = 7.5


class Speeds:
    """One vehicle's navigation limits from ``params`` and the overrides in force
    (``horizontal``, ``climb``, ``descent`` in m/s; None: the parameter's)."""

    def __init__(self, params: Params) -> None:
        self.params = params
        self.horizontal: float | None = None
        self.climb: float | None = None
        self.descent: float | None = None
        self._key: tuple[Any, ...] = ()
        self._kept = Limits()

    def set(self, speed_type: int, speed: float) -> None:
        """Override one speed: ``speed_type`` 0 or 1 the horizontal speed, 2 the climb
        speed, 3 the descent speed (MAVLink SPEED_TYPE)."""
        if speed_type == SPEED_CLIMB:
            self.climb = speed
        elif speed_type == SPEED_DESCENT:
            self.descent = speed
        else:
            self.horizontal = speed

    def limits(self, mode: str) -> Limits:
        """The limits the navigation flies at in ``mode``."""
        key = (self.params.version, mode, self.horizontal, self.climb, self.descent)
        if key == self._key:
            return self._kept
        self._key, self._kept = key, self._new_limits(mode)
        return self._kept

    def _new_limits(self, mode: str) -> Limits:
        p = self.params
        speed = self.horizontal or p["WPNAV_SPEED"] / 100.0
        if mode == "RTL" and p["RTL_SPEED"] > 0:
            speed = p["RTL_SPEED"] / 100.0
        accel = BRAKE_DECEL if mode == "BRAKE" else p["WPNAV_ACCEL"] / 100.0
        climb = self.climb or p["WPNAV_SPEED_UP"] / 100.0
        descent = self.descent or p["WPNAV_SPEED_DN"] / 100.0
        accel_z = p["PILOT_ACCEL_Z" if mode in PILOT_MODES else "WPNAV_ACCEL_Z"] / 100.0
        if mode in PILOT_MODES:  # the stick's rate, not the navigation's limits
            climb = p["PILOT_SPEED_UP"] / 100.0
            descent = (p["PILOT_SPEED_DN"] or p["PILOT_SPEED_UP"]) / 100.0
        return Limits(speed, climb, descent, accel, accel_z, p["ATC_RATE_Y_MAX"], p["PSC_JERK_XY"],
                      p["PSC_JERK_Z"])

    def shape(self) -> Shape:
        """The S-curves' jerk and snap time (``WPNAV_JERK``, ``ATC_INPUT_TC``)."""
        p = self.params
        return Shape(p["WPNAV_JERK"], 2.0 * max(p["ATC_INPUT_TC"], 0.1))
