"""A vehicle's own clock, read from the ``time_boot_ms`` of its messages.

Theory of operation
-------------------
ArduPilot SITL run with ``--speedup K`` lives K seconds for each second of the ground
station's; a real autopilot's clock drifts a little from the ground station's. A mission's
time limits and elapsed-time conditions are meant in the vehicle's seconds, so ``tml run
--clock vehicle`` reads the mission's time from the vehicle.

:class:`VehicleClockEstimator` is pure: it is fed (boot time, local time) pairs -- the
``time_boot_ms`` of a message and the local monotonic time it arrived -- and answers the
vehicle's time at any local time. Between messages the vehicle's time is extrapolated with
the rate measured over the last :data:`RATE_WINDOW` local seconds (1 until two stamps span
at least :data:`MIN_RATE_SPAN`), so a clock asked between two stamps moves smoothly, and a
vehicle that falls silent keeps ageing at the rate it had (a lost link must still look
lost after the run's limits). The answer never goes backwards: a stamp that arrives late
does not pull the clock back, and a reboot (``time_boot_ms`` smaller than before) restarts
the count from where the clock stood.

:class:`VehicleClock` wires the estimator to a link's telemetry for one vehicle.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

from tml.mavlink.link import Link

RATE_WINDOW = 5.0
"""Local seconds of stamps the rate is measured over."""
MIN_RATE_SPAN = 0.5
"""Local seconds two stamps must span before their rate is believed."""


class VehicleClockEstimator:
    """The vehicle's time from (boot time, local time) stamps; see the module docstring."""

    def __init__(self) -> None:
        self._stamps: deque[tuple[float, float]] = deque()  # (local, vehicle), oldest first
        self._offset = 0.0  # added to boot times after a reboot, so that time goes on
        self._last_answer = 0.0
        self.rate = 1.0

    @property
    def started(self) -> bool:
        """Whether a stamp has arrived."""
        return bool(self._stamps)

    def feed(self, boot_time: float, local: float) -> None:
        """Take one message's boot time (s) that arrived at local time ``local`` (s)."""
        if self._stamps:
            last_local, last_vehicle = self._stamps[-1]
            if local < last_local:
                return
            if boot_time + self._offset < last_vehicle - 1.0:  # the vehicle rebooted
                self._offset = last_vehicle - boot_time
                self._stamps.clear()
        self._stamps.append((local, boot_time + self._offset))
        while len(self._stamps) > 2 and local - self._stamps[0][0] > RATE_WINDOW:
            self._stamps.popleft()
        first_local, first_vehicle = self._stamps[0]
        if local - first_local >= MIN_RATE_SPAN:
            self.rate = max(0.0, (boot_time + self._offset - first_vehicle) /
                            (local - first_local))

    def now(self, local: float) -> float:
        """The vehicle's time at local time ``local`` (0 before the first stamp)."""
        if not self._stamps:
            return self._last_answer
        last_local, last_vehicle = self._stamps[-1]
        answer = last_vehicle + max(0.0, local - last_local) * self.rate
        self._last_answer = max(self._last_answer, answer)
        return self._last_answer


class VehicleClock:
    """The clock of vehicle ``system_id`` on ``link``, in seconds since it booted.

    Call it for the time. ``local`` is the clock the link stamps messages with (the
    monotonic clock). Before the vehicle has sent a time stamp it answers 0.
    """

    def __init__(self, link: Link, system_id: int,
                 local: Callable[[], float] = time.monotonic) -> None:
        self.link = link
        self.system_id = system_id
        self.local = local
        self.estimator = VehicleClockEstimator()
        self._fed: float | None = None

    def wait_started(self, timeout: float, wake: Callable[[float], object] = time.sleep
                     ) -> bool:
        """Wait up to ``timeout`` local seconds for the vehicle's first time stamp, so that
        a mission is never timed from 0 before the vehicle has said what time it is.
        ``wake(seconds)`` waits between looks. Returns whether the clock has started."""
        deadline = self.local() + timeout
        while True:
            self()
            if self.estimator.started or self.local() >= deadline:
                return self.estimator.started
            wake(0.02)

    def __call__(self) -> float:
        t = self.link.telemetry(self.system_id)
        if t.boot_time is not None and t.boot_time_received is not None \
                and t.boot_time_received != self._fed:
            self._fed = t.boot_time_received
            self.estimator.feed(t.boot_time, t.boot_time_received)
        return self.estimator.now(self.local())
