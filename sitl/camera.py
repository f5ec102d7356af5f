"""The vehicle's camera: when pictures are taken, as ArduPilot's AP_Camera takes them.

A camera is fitted when ``CAM1_TYPE`` is not 0 at boot (ArduPilot 4.5+ reads it then
only: a change counts from the next reboot). Pictures are taken on command
(DO_DIGICAM_CONTROL with param5 = 1), in series (IMAGE_START_CAPTURE: param2 seconds
apart, param3 pictures, 0 = until IMAGE_STOP_CAPTURE) and by distance:
DO_SET_CAM_TRIGG_DIST sets the ``CAM1_TRIGG_DIST`` parameter (so a ground station may
also set it directly), and while it is above zero a picture is taken each time the
vehicle has moved that many metres horizontally since the last one (a series, while it
runs, takes the place of the distance trigger, as in AP_Camera_Backend::update). param3
= 1 also takes one at once. The camera only counts; the vehicle sends CAMERA_FEEDBACK
for each picture.

Without a camera, as ArduPilot SITL answers (measured): DO_DIGICAM_CONTROL,
DO_SET_CAM_TRIGG_DIST and IMAGE_STOP_CAPTURE are ACCEPTED and do nothing (the
parameter is left as it is), IMAGE_START_CAPTURE is FAILED; no STATUSTEXT.

The shutter is held ``CAM1_DURATION`` s (0.1) after each picture, and no picture can be
taken meanwhile (AP_Camera_Servo): DO_DIGICAM_CONTROL is still ACCEPTED but takes none,
IMAGE_START_CAPTURE of one picture is FAILED, and a series or the distance trigger takes
its picture as soon as the shutter is free.
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.params import Params
from sitl.results import Result

Vector = tuple[float, float, float]
COMMANDS = frozenset({
    mavlink.MAV_CMD_DO_DIGICAM_CONTROL, mavlink.MAV_CMD_IMAGE_START_CAPTURE,
    mavlink.MAV_CMD_IMAGE_STOP_CAPTURE, mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST,
})
MIN_INTERVAL = 0.1  # seconds between pictures of a series, at the shortest


class Camera:
    """Decides when pictures are taken; ``params`` holds ``CAM1_TYPE`` and
    ``CAM1_TRIGG_DIST`` (metres)."""

    def __init__(self, params: Params) -> None:
        self.params = params
        self.fitted = params["CAM1_TYPE"] != 0  # read at boot, as ArduPilot does
        self._series: tuple[float, int, float] | None = None  # (interval, left or -1, next)
        self._last_trigger: Vector | None = None
        self._shutter_free = -math.inf  # when the shutter held for the last picture is free

    def command(self, command: int, p: list[float], now: float, position: Vector
                ) -> tuple[Result, int]:
        """Run a camera command (params 1-7 in ``p``): its result and the pictures to
        take now."""
        if not self.fitted:
            failed = command == mavlink.MAV_CMD_IMAGE_START_CAPTURE
            return (Result.FAILED if failed else Result.ACCEPTED), 0
        if command == mavlink.MAV_CMD_DO_DIGICAM_CONTROL:
            return Result.ACCEPTED, self._shot(now, position) if p[4] >= 0.5 else 0
        if command == mavlink.MAV_CMD_IMAGE_START_CAPTURE:
            interval, count = max(p[1], MIN_INTERVAL), round(p[2])
            if count != 1:  # the first of the series is taken as soon as the shutter is free
                self._series = (interval, count if count > 1 else -1, now)
                return Result.ACCEPTED, self.update(now, position)
            taken = self._shot(now, position)
            return (Result.ACCEPTED if taken else Result.FAILED), taken
        if command == mavlink.MAV_CMD_IMAGE_STOP_CAPTURE:
            self._series = None
            return Result.ACCEPTED, 0
        # DO_SET_CAM_TRIGG_DIST
        distance = self.params.set("CAM1_TRIGG_DIST", max(p[0], 0.0))
        self._last_trigger = position
        return Result.ACCEPTED, self._shot(now, position) if p[2] >= 0.5 and distance > 0 else 0

    def _shot(self, now: float, position: Vector) -> int:
        """One picture at ``now`` and ``position`` if the shutter is free (1), else none;
        the distance trigger counts from where the last one was taken."""
        if now < self._shutter_free - 1e-9:
            return 0
        self._shutter_free = now + self.params["CAM1_DURATION"]
        self._last_trigger = position
        return 1

    def update(self, now: float, position: Vector) -> int:
        """Pictures due at ``now`` with the vehicle at ``position``."""
        if not self.fitted:
            return 0
        if self._series is not None:
            interval, left, due = self._series
            if now < due - 1e-9 or not self._shot(now, position):
                return 0
            left -= 1 if left > 0 else 0
            self._series = None if left == 0 else (interval, left, now + interval)
            return 1
        distance = self.params["CAM1_TRIGG_DIST"]
        if distance <= 0:
            self._last_trigger = None
        elif self._last_trigger is None:
            self._last_trigger = position
        elif math.dist(position[:2], self._last_trigger[:2]) >= distance:
            return self._shot(now, position)
        return 0
