"""An independent pymavlink ground station flies ``python -m sitl`` as it flies ArduCopter.

The client (tests/interop/ground_station.py, plain pymavlink, none of tml's code) is the one
the interoperability suite flies against ArduCopter SITL: select GUIDED, arm with retries
until accepted, take off, upload three waypoints and an RTL, read them back, AUTO, land. The
simulator runs with its default parameters, ArduCopter's start-up delays included: it
must refuse the arm as ArduCopter does until it can take off, and then fly the same way.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

from interop.ground_station import fly, same_mission

ROOT = Path(__file__).resolve().parents[1]


def test_an_independent_ground_station_flies_the_simulator_as_it_flies_arducopter() -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "sitl", "--tcp-base-port", "0", "--speedup", "20"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline() if process.stdout else ""
        assert line.startswith("vehicle 1: tcp:127.0.0.1:"), process.stderr
        address = line.split()[2]
        flight = fly(address, timeout=60.0)
    finally:
        os.kill(process.pid, signal.SIGTERM)
        process.communicate(timeout=10)
    # Refused until the EKF uses GPS, with ArduCopter's reason; then flown like ArduCopter.
    assert "Arm: Need Position Estimate" in flight.arm_refusals
    assert flight.takeoff_result == 0
    assert same_mission(flight.uploaded, flight.read_back)
    assert flight.reached[:3] == [1, 2, 3]
    assert flight.landed_disarmed
