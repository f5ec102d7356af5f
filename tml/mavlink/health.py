"""A vehicle's link health: ``ok``, ``degraded`` or ``lost``, from what arrives.

Theory of operation
-------------------
:class:`LinkHealth` is pure: the link's listener tells it of every message of the vehicle
(:meth:`LinkHealth.heard`), and :meth:`LinkHealth.state` answers at any time. The link is
``lost`` after ``lost_after`` seconds without a HEARTBEAT, ``degraded`` after
``degraded_after`` seconds or when more than :data:`DEGRADED_LOSS` of the messages of the
last second (by their sequence numbers) went missing.

How long since the last HEARTBEAT is the sum of two spans:

* the vehicle's own time from the last HEARTBEAT to its latest message, read from the
  ``time_boot_ms`` stamps of its messages (a HEARTBEAT carries none: it takes the latest
  stamp heard before it, plus the caller's time since that stamp arrived); and
* the time since that latest message arrived, on the caller's clock.

Counting the first span in the vehicle's stamps keeps a ground station that falls behind
in *reading* (a busy machine, a simulator sped up fifty times) from taking its own delay
for the vehicle's silence: the messages it reads late carry their HEARTBEATs with them.
A vehicle that falls silent stops both the stamps and the arrivals, and the second span
grows. Before the vehicle has sent any stamp, the first span is taken on the caller's
clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

DEGRADED_LOSS = 0.2
"""Fraction of messages missing in the last second above which the link is degraded."""
LOSS_WINDOW = 1.0
"""Seconds (the caller's clock) over which the fraction of missing messages is measured."""


@dataclass
class LinkHealth:
    """The health of one vehicle's link; see the module docstring."""

    lost_after: float = 5.0
    degraded_after: float = 2.5
    loss: float = 0.0
    _heartbeat_at: float | None = None  # caller's clock
    _heartbeat_stamp: float | None = None  # vehicle's stamp before the last HEARTBEAT
    _latest_stamp: float | None = None
    _stamp_arrived_at: float = 0.0  # caller's clock when the latest stamp arrived
    _arrived_at: float | None = None
    _window: tuple[float, int, int] | None = None  # (start, received, lost)

    def heard(self, now: float, heartbeat: bool, stamp: float | None,
              received: int, lost: int) -> None:
        """A message of the vehicle arrived at ``now``: a HEARTBEAT or not, the vehicle's
        latest ``time_boot_ms`` stamp in seconds (None before any), and the link's counts
        of messages received and lost so far."""
        self._arrived_at = now
        if stamp is not None:
            if self._latest_stamp is not None and stamp < self._latest_stamp - 1.0:
                self._heartbeat_stamp = None  # the vehicle rebooted: stamps start again
            if stamp != self._latest_stamp:
                self._latest_stamp, self._stamp_arrived_at = stamp, now
        if not heartbeat:
            return
        self._heartbeat_at = now
        self._heartbeat_stamp = None if stamp is None else \
            stamp + max(0.0, now - self._stamp_arrived_at)
        if self._window is None:
            self._window = (now, received, lost)
        start, was_received, was_lost = self._window
        if now - start >= LOSS_WINDOW:
            total = (received - was_received) + (lost - was_lost)
            self.loss = (lost - was_lost) / total if total else 0.0
            self._window = (now, received, lost)

    def silence(self, now: float) -> float:
        """Seconds since the last HEARTBEAT (infinite before the first)."""
        if self._heartbeat_at is None or self._arrived_at is None:
            return math.inf
        if self._heartbeat_stamp is None or self._latest_stamp is None:
            return now - self._heartbeat_at
        latest = self._latest_stamp + max(0.0, self._arrived_at - self._stamp_arrived_at)
        return max(0.0, latest - self._heartbeat_stamp) + max(0.0, now - self._arrived_at)

    def calm(self, now: float) -> float:
        """Seconds from ``now`` in which :meth:`state` stays as it is if nothing arrives:
        until the silence passes ``degraded_after``, then ``lost_after``; infinite once
        lost (only a message changes it then)."""
        age = self.silence(now)
        for limit in (self.degraded_after, self.lost_after):
            if age <= limit:
                return limit - age
        return math.inf

    def state(self, now: float) -> str:
        """``ok``, ``degraded`` or ``lost`` at ``now``."""
        age = self.silence(now)
        if age > self.lost_after:
            return "lost"
        if age > self.degraded_after or self.loss > DEGRADED_LOSS:
            return "degraded"
        return "ok"
