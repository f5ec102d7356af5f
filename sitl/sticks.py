"""The pilot's sticks as ArduCopter reads them: SITL's idle radio, or a ground station's
RC_CHANNELS_OVERRIDE while it is fresh.

As ArduPilot, only the ground station named by ``MAV_GCS_SYSID`` may hold the sticks;
channels 1-8 of an override take its values, UINT16_MAX leaving a channel as it is and 0
giving it back to the radio. An override counts for ``RC_OVERRIDE_TIME`` seconds (0:
overrides off, -1: no time limit). The roll and pitch sticks read as ArduCopter's
``control_in`` (centidegrees, ``STICK_DEADZONE`` around mid-stick), the throttle as the
climb rate ALT_HOLD flies (``get_pilot_desired_climb_rate``).
"""

from __future__ import annotations

import math
from typing import Any

from sitl.params import Params

RC_RADIO = (1500, 1500, 1000, 1500)  # SITL radio, nobody at the sticks: centred, throttle down
STICK_DEADZONE = 20  # microseconds around 1500 where roll and pitch read 0 (RCn_DZ)
THROTTLE_DEADZONE = 30  # microseconds above 1000 where the throttle reads 0 (RC3_DZ)


class Sticks:
    """The RC input of one vehicle, read from ``params`` at the time given."""

    def __init__(self, params: Params) -> None:
        self.params = params
        self._override: dict[int, int] = {}  # channel (1-based) -> PWM
        self._override_at = -math.inf

    def rc(self, channel: int, now: float) -> int:
        """The PWM of RC ``channel`` (1-based) at ``now``."""
        limit = self.params["RC_OVERRIDE_TIME"]
        fresh = limit < 0 or (limit > 0 and now - self._override_at <= limit)
        if fresh and channel in self._override:
            return self._override[channel]
        return RC_RADIO[channel - 1] if channel <= len(RC_RADIO) else 1500

    @property
    def overridden(self) -> frozenset[int]:
        """The RC channels a ground station holds (given back ones are not)."""
        return frozenset(self._override)

    def override(self, msg: Any, now: float) -> None:
        """Take an RC_CHANNELS_OVERRIDE received at ``now``."""
        if msg.get_srcSystem() != round(self.params["MAV_GCS_SYSID"]):
            return
        for channel in range(1, 9):
            value = getattr(msg, f"chan{channel}_raw")
            if value == 0:
                self._override.pop(channel, None)
            elif value != 65535:
                self._override[channel] = value
        self._override_at = now

    def stick(self, channel: int, now: float) -> float:
        """Roll (1) or pitch (2) stick in centidegrees, as ArduCopter's control_in."""
        offset = self.rc(channel, now) - 1500
        if abs(offset) <= STICK_DEADZONE:
            return 0.0
        return math.copysign(abs(offset) - STICK_DEADZONE, offset) / (500 - STICK_DEADZONE) * 4500

    def climb_rate(self, now: float) -> float:
        """m/s up the throttle stick asks for in ALT_HOLD (THR_DZ around mid-stick holds
        the altitude)."""
        throttle = min(max(self.rc(3, now) - 1000, 0), 1000)
        top, bottom = 500 + self.params["THR_DZ"], 500 - self.params["THR_DZ"]
        up = self.params["PILOT_SPEED_UP"] / 100.0
        down = (self.params["PILOT_SPEED_DN"] or self.params["PILOT_SPEED_UP"]) / 100.0
        if throttle > top:
            return up * (throttle - top) / (1000 - top)
        if throttle < bottom:
            return down * (throttle - bottom) / bottom
        return 0.0
