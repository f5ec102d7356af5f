"""The interoperability suite: tml against ArduPilot's real Copter, Plane and Rover (SITL).

Every test here is marked ``interop`` and skips, with the reason, when no ArduPilot SITL is
found (see tests/interop/ardupilot_sitl.py and docs/interop.md). Run it with ``pytest -m interop``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import ExitStack
from pathlib import Path

import pytest
from ardupilot_sitl import Launcher, SitlVehicle, find_launcher, vehicles

INTEROP_DIR = Path(__file__).parent
# The interop tests fly the regular suite's missions with its expectations
# (tests/test_flights.py), one table for both.
sys.path.insert(0, str(INTEROP_DIR.parent))


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if INTEROP_DIR in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.interop)


@pytest.fixture(scope="session")
def launcher() -> Launcher:
    """The ArduPilot SITL launcher; skips the test when there is none."""
    found, reason = find_launcher()
    if found is None:
        pytest.skip(reason)
    return found


StartVehicles = Callable[..., list[SitlVehicle]]


@pytest.fixture
def ardupilot(launcher: Launcher, tmp_path: Path) -> Iterator[StartVehicles]:
    """``ardupilot(count=1, vehicle="copter", speedup=10, params={...})`` starts vehicles
    that are stopped by their pids when the test ends."""
    with ExitStack() as stack:
        def start(count: int = 1, vehicle: str = "copter", **options: object
                  ) -> list[SitlVehicle]:
            return stack.enter_context(vehicles(launcher, count, vehicle, **options))

        yield start
