"""The vehicle's camera: when pictures are taken.

Pictures are taken on command (DO_DIGICAM_CONTROL with param5 = 1), in series
(IMAGE_START_CAPTURE: param2 seconds apart, param3 pictures, 0 = until
IMAGE_STOP_CAPTURE) and by distance, as ArduPilot's AP_Camera does: DO_SET_CAM_TRIGG_DIST
sets the ``CAM_TRIGG_DIST`` parameter (so a ground station may also set it directly), and
while it is above zero and the vehicle flies, a picture is taken each time the vehicle
has moved that many metres horizontally since the last one. param3 = 1 also takes one at
once. The camera only counts; the vehicle sends CAMERA_IMAGE_CAPTURED for each picture.
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.params import Params

Vector = tuple[float, float, float]
COMMANDS = frozenset({
    mavlink.MAV_CMD_DO_DIGICAM_CONTROL, mavlink.MAV_CMD_IMAGE_START_CAPTURE,
    mavlink.MAV_CMD_IMAGE_STOP_CAPTURE, mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST,
})
MIN_INTERVAL = 0.1  # seconds between pictures of a series, at the shortest


class Camera:
    """Decides when pictures are taken; ``params`` holds ``CAM_TRIGG_DIST`` (metres)."""

    def __init__(self, params: Params) -> None:
        self.params = params
        self._series: tuple[float, int, float] | None = None  # (interval, left or -1, next)
        self._last_trigger: Vector | None = None

    def command(self, command: int, p: list[float], now: float, position: Vector) -> int:
        """Run a camera command (params 1-7 in ``p``); returns the pictures to take now."""
        if command == mavlink.MAV_CMD_DO_DIGICAM_CONTROL:
            return 1 if p[4] >= 0.5 else 0
        if command == mavlink.MAV_CMD_IMAGE_START_CAPTURE:
            interval, count = max(p[1], MIN_INTERVAL), round(p[2])
            self._series = None if count == 1 else (
                interval, count - 1 if count > 1 else -1, now + interval)
            return 1
        if command == mavlink.MAV_CMD_IMAGE_STOP_CAPTURE:
            self._series = None
            return 0
        # DO_SET_CAM_TRIGG_DIST
        distance = self.params.set("CAM_TRIGG_DIST", max(p[0], 0.0))
        self._last_trigger = position
        return 1 if p[2] >= 0.5 and distance > 0 else 0

    def update(self, now: float, position: Vector, flying: bool) -> int:
        """Pictures due at ``now`` with the vehicle at ``position``."""
        pictures = 0
        if self._series is not None and now >= self._series[2] - 1e-9:
            interval, left, _ = self._series
            pictures += 1
            left -= 1 if left > 0 else 0
            self._series = None if left == 0 else (interval, left, now + interval)
        distance = self.params["CAM_TRIGG_DIST"]
        if distance <= 0:
            self._last_trigger = None
        elif self._last_trigger is None:
            self._last_trigger = position
        elif flying and math.dist(position[:2], self._last_trigger[:2]) >= distance:
            self._last_trigger = position
            pictures += 1
        return pictures
