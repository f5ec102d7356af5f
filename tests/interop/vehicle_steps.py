"""Steps of a test that drives tml's MavlinkVehicle on ArduPilot SITL directly: wait for a
state, carry out a request. Both wait for what they want with a hang guard."""

from __future__ import annotations

import time
from collections.abc import Callable

from tml.mavlink.adapter import MavlinkVehicle
from tml.vehicle import Request, RequestResult, VehicleState

WALL_LIMIT = 120.0  # wall s: a hang guard, not a time limit of the verdict


def until(vehicle: MavlinkVehicle, what: Callable[[VehicleState], bool], label: str
          ) -> VehicleState:
    """The vehicle's first state for which ``what`` holds."""
    end = time.monotonic() + WALL_LIMIT
    while time.monotonic() < end:
        state = vehicle.state()
        if what(state):
            return state
        time.sleep(0.05)
    raise AssertionError(f"never: {label}; last state {vehicle.state()}")


def do(vehicle: MavlinkVehicle, request: Request) -> RequestResult:
    """Submit ``request`` and wait for its result."""
    vehicle.submit(request)
    end = time.monotonic() + WALL_LIMIT
    while time.monotonic() < end:
        for result in vehicle.poll():
            return result
        time.sleep(0.02)
    raise AssertionError(f"no result for {request}")
