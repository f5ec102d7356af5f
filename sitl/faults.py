"""Fault injection: a bad link, a refusing autopilot, a lost GPS, a failing battery.

:class:`Faults` only describes what goes wrong. The server applies the link faults with
one :class:`WireChannel` per vehicle and direction; the vehicle model applies command
rejection, GPS loss and battery failure itself. Every random draw comes from a
``random.Random`` seeded with (seed, system id, direction), and every time is vehicle
time (seconds since boot), so a run with the same seed and the same traffic loses,
delays, duplicates and reorders the same packets.
"""

from __future__ import annotations

import heapq
import random
from dataclasses import dataclass, field
from typing import Generic, TypeVar

Packet = TypeVar("Packet")


@dataclass(frozen=True)
class Faults:
    """What goes wrong, and from which seed the dice are thrown.

    ``loss_in``/``loss_out``: probability that a message to/from the vehicle is dropped.
    ``latency``/``jitter``: seconds of delay added to every message (jitter: uniform extra).
    ``duplicate``: probability that a message is delivered twice.
    ``reorder``: probability that a message is held back ``reorder_delay`` seconds, so that
    the messages after it overtake it.
    ``outages``: (start, end) windows of vehicle time in which nothing gets through.
    ``reject_commands``: command id -> MAV_RESULT the vehicle answers instead of executing.
    ``gps_loss_at``/``battery_failure_at``: vehicle time at which the GPS loses its fix /
    the battery collapses to its critical voltage.
    ``reboot_at``: vehicle time at which the autopilot reboots (its clock starts again from
    zero, disarmed, on the ground where it booted: :meth:`sitl.model.VehicleModel.rebooted`).
    """

    seed: int = 0
    loss_in: float = 0.0
    loss_out: float = 0.0
    latency: float = 0.0
    jitter: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0
    reorder_delay: float = 0.05
    outages: tuple[tuple[float, float], ...] = ()
    reject_commands: dict[int, int] = field(default_factory=dict)
    gps_loss_at: float | None = None
    battery_failure_at: float | None = None
    reboot_at: float | None = None

    def __post_init__(self) -> None:
        for name in ("loss_in", "loss_out", "duplicate", "reorder"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} must be a probability in [0, 1], not {value}")
        for name in ("latency", "jitter", "reorder_delay"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must not be negative")
        for start, end in self.outages:
            if end < start:
                raise ValueError(f"outage ({start}, {end}) ends before it starts")
        object.__setattr__(self, "outages", tuple(tuple(w) for w in self.outages))

    @property
    def affects_wire(self) -> bool:
        """True when any link fault is set (the server can skip the channels otherwise)."""
        return bool(
            self.loss_in or self.loss_out or self.latency or self.jitter or self.duplicate
            or self.reorder or self.outages
        )

    def in_outage(self, time: float) -> bool:
        """True when ``time`` falls inside an outage window."""
        return any(start <= time < end for start, end in self.outages)


class WireChannel(Generic[Packet]):
    """One direction of one vehicle's link: packets in at a time, due packets out.

    Sans-IO: ``send(time, packet)`` decides the packet's fate with the channel's own random
    generator; ``due(time)`` returns, in delivery order, the packets whose time has come.
    """

    def __init__(self, faults: Faults, loss: float, stream: str) -> None:
        self._faults = faults
        self._loss = loss
        self._rng = random.Random(f"{faults.seed}/{stream}")
        self._queue: list[tuple[float, int, Packet]] = []
        self._order = 0  # tie-breaker: equal times keep sending order

    def send(self, time: float, packet: Packet) -> None:
        """Offer ``packet`` at vehicle ``time``; it may be dropped, delayed or duplicated."""
        faults = self._faults
        # Draw every number for every packet so one fault's setting does not shift the
        # dice of another: the same seed loses the same packets whatever the latency.
        lost, duplicated, reordered = self._rng.random(), self._rng.random(), self._rng.random()
        delays = (self._rng.uniform(0.0, faults.jitter), self._rng.uniform(0.0, faults.jitter))
        if faults.in_outage(time) or lost < self._loss:
            return
        copies = 2 if duplicated < faults.duplicate else 1
        for copy in range(copies):
            when = time + faults.latency + delays[copy]
            if reordered < faults.reorder and copy == 0:
                when += faults.reorder_delay
            self._order += 1
            heapq.heappush(self._queue, (when, self._order, packet))

    def due(self, time: float) -> list[Packet]:
        """Packets whose delivery time is at or before ``time``, in delivery order."""
        out: list[Packet] = []
        while self._queue and self._queue[0][0] <= time:
            out.append(heapq.heappop(self._queue)[2])
        return out
