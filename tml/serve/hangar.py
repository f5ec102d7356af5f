"""The vehicles a service keeps open, the clock they fly by, and which run holds each.

Theory of operation
-------------------
``tml serve`` opens its vehicle links once, at start, and keeps them open for every run
(:mod:`tml.commands.serve` starts the simulator or connects, as ``tml run`` does). A
vehicle belongs to at most one run at a time: :meth:`Hangar.claim` takes every vehicle a
run asks for, or none of them when one is already held (:class:`VehicleTaken`, which the
API answers with 409), and :meth:`Hangar.release` frees them when the run has ended and
its vehicles are safe.

Each run's loop sleeps on its own event between steps. The vehicles call
:meth:`Hangar.notify` on every request result, which wakes every run at once (the runner's
``wake``, and an operator's command waiting for its answer); a run's own vehicles wake it
on every change of a field it reads (:meth:`tml.mavlink.adapter.MavlinkVehicle.watch`), so
an event still reacts to the message that made it true.
:meth:`Hangar.wait` is how a run's loop waits; a hangar of fake vehicles for the tests
moves its vehicles there instead, with its own clock.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Sequence

from tml.errors import TmlError
from tml.vehicle import Vehicle


class VehicleTaken(TmlError):
    """A vehicle a run asked for is held by another run."""

    def __init__(self, vehicle_id: int, run_id: str) -> None:
        super().__init__(f"vehicle {vehicle_id} is held by run {run_id}")
        self.vehicle_id, self.run_id = vehicle_id, run_id


class Hangar:
    """Vehicles with one clock; see the module docstring."""

    def __init__(self, vehicles: Sequence[Vehicle], clock: Callable[[], float]) -> None:
        self.vehicles = {v.vehicle_id: v for v in vehicles}
        self.clock = clock
        self._holders: dict[int, str] = {}
        self._wakes: set[threading.Event] = set()
        self._lock = threading.Lock()

    # --- ownership -----------------------------------------------------------------------

    def holder(self, vehicle_id: int) -> str | None:
        """The run that holds a vehicle, or None."""
        with self._lock:
            return self._holders.get(vehicle_id)

    def claim(self, vehicle_ids: Iterable[int], run_id: str) -> None:
        """Give every one of ``vehicle_ids`` to ``run_id``, or none (VehicleTaken)."""
        wanted = list(vehicle_ids)
        with self._lock:
            for vid in wanted:
                if vid in self._holders:
                    raise VehicleTaken(vid, self._holders[vid])
            for vid in wanted:
                self._holders[vid] = run_id

    def claim_free(self, run_id: str, every: bool = False) -> list[int]:
        """Give ``run_id`` the first free vehicle (``every``: every free one), chosen and
        taken at once, so that two runs asking at the same time never pick the same one;
        the vehicles taken (none when every vehicle is held)."""
        with self._lock:
            free = [vid for vid in sorted(self.vehicles) if vid not in self._holders]
            chosen = free if every else free[:1]
            for vid in chosen:
                self._holders[vid] = run_id
            return chosen

    def release(self, run_id: str) -> None:
        """Free the vehicles ``run_id`` holds."""
        with self._lock:
            for vid in [v for v, holder in self._holders.items() if holder == run_id]:
                del self._holders[vid]

    # --- waking the runs -----------------------------------------------------------------

    def subscribe(self, wake: threading.Event) -> None:
        """Set ``wake`` whenever a vehicle has news."""
        with self._lock:
            self._wakes.add(wake)

    def unsubscribe(self, wake: threading.Event) -> None:
        """Stop setting ``wake``."""
        with self._lock:
            self._wakes.discard(wake)

    def notify(self) -> None:
        """A vehicle has news (called by the links' threads): wake every run."""
        with self._lock:
            wakes = list(self._wakes)
        for wake in wakes:
            wake.set()

    def wait(self, wake: threading.Event, timeout: float) -> None:
        """How a run's loop waits for news, at most ``timeout`` seconds."""
        wake.wait(timeout)
        wake.clear()
