"""ArduCopter's FLIP mode: one turn about the roll (or pitch) axis, then back.

As ArduCopter's ModeFlip: entered only from a pilot mode (:data:`sitl.modes.FLIP_FROM`;
in ACRO and STABILIZE with the throttle up), armed, off the ground and with the roll
stick under :data:`FLIP_STICK`; the pitch stick pushed past :data:`FLIP_DIRECTION_STICK`
makes it a pitch flip that way, else it rolls to the side the roll stick leans (right
when centred). It turns at :data:`FLIP_RATE` and sinks :data:`FLIP_ALTITUDE_LOSS` metres
over the turn; a full turn, a disarm, :data:`FLIP_TIMEOUT` or a stick past
:data:`FLIP_STICK` ends it, back in the mode it started from (else STABILIZE).
"""

from __future__ import annotations

import math

from sitl.modes import FLIP_FROM, FLIP_NEEDS_THROTTLE
from sitl.sticks import RC_RADIO, THROTTLE_DEADZONE, Sticks

FLIP_RATE = 400.0  # degrees per second of roll, ArduCopter's FLIP_ROTATION_RATE
FLIP_TIMEOUT = 2.5  # seconds: ArduCopter abandons a flip not over by then (FLIP_TIMEOUT_MS)
FLIP_ALTITUDE_LOSS = 4.0  # metres a flip costs (ArduCopter SITL: 3.9 and 4.4 m, mid throttle)
FLIP_STICK = 4000  # centidegrees of roll or pitch stick at which ArduCopter abandons a flip
FLIP_DIRECTION_STICK = 300  # centidegrees of pitch stick that make it a pitch flip
SINK_RATE = FLIP_ALTITUDE_LOSS * FLIP_RATE / 360.0  # m/s down while flipping


class Flip:
    """One vehicle's flip: where it may start, and how far it has turned."""

    def __init__(self, sticks: Sticks) -> None:
        self.sticks = sticks
        self.previous = ""  # the mode to return to
        self._turned = 0.0  # degrees
        self._axis = "roll"  # or "pitch"
        self._direction = 1  # +1 or -1
        self._start = 0.0

    def allowed(self, mode: str, flying: bool, now: float) -> bool:
        """ArduCopter's ModeFlip::init, in ``mode`` (``flying``: armed, off the ground)."""
        if mode not in FLIP_FROM or not flying:
            return False
        if mode in FLIP_NEEDS_THROTTLE and self.sticks.rc(3, now) <= (
                RC_RADIO[2] + THROTTLE_DEADZONE):
            return False
        return abs(self.sticks.stick(1, now)) < FLIP_STICK

    def start(self, previous: str, now: float) -> None:
        """Begin a flip at ``now``, to return to ``previous``."""
        pitch = self.sticks.stick(2, now)
        if abs(pitch) > FLIP_DIRECTION_STICK:
            self._axis, self._direction = "pitch", 1 if pitch > 0 else -1
        else:
            self._axis, self._direction = "roll", 1 if self.sticks.stick(1, now) >= 0 else -1
        self.previous, self._turned, self._start = previous, 0.0, now

    def turn(self, dt: float, armed: bool, now: float) -> tuple[float, float] | None:
        """Turn on for ``dt`` seconds: the (roll, pitch) in radians, or None once over."""
        turned = self._turned + FLIP_RATE * dt
        abandon = not armed or now - self._start > FLIP_TIMEOUT or max(
            abs(self.sticks.stick(1, now)), abs(self.sticks.stick(2, now))) >= FLIP_STICK
        if turned >= 360.0 or abandon:
            return None
        self._turned = turned
        angle = self._direction * math.radians(turned - 360.0 if turned > 180.0 else turned)
        return (angle, 0.0) if self._axis == "roll" else (0.0, angle)
