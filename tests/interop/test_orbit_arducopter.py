"""ArduCopter SITL flies missions/orbit.xml's two ORBITs round their points, facing them.

``tml run missions/orbit.xml`` flies from a child process on the vehicle's first port: one
ORBIT with commands (GUIDED: a turn of 12 m round a mast 30 m north of home, each target
with the heading toward it), one as mission items (AUTO: DO_SET_ROI_LOCATION,
NAV_LOITER_TURNS of 10 m round a point 30 m north, DO_SET_ROI_NONE), then home and land.
A plain pymavlink client on the vehicle's second port (SERIAL1) judges it from
GLOBAL_POSITION_INT and HEARTBEAT alone: in each mode, once on the circle, the vehicle's
distance to the point stays at the radius, its heading points at the point, and it goes
round the whole turn.
"""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from ground_station import watch_run
from pymavlink import mavutil

from tml.geo import to_local

M = mavutil.mavlink
MISSION = Path(__file__).resolve().parents[2] / "missions" / "orbit.xml"
GUIDED, AUTO = 4, 3
MAST = (30.0, 0.0)  # the first ORBIT's point, metres north and east of the vehicle's home
FIELD = (-35.362990, 149.165230)  # the second's, WGS84
DISTANCE_TOLERANCE = 2.0  # m from the radius, once on the circle
HEADING_TOLERANCE = 30.0  # degrees: GUIDED targets are 22.5 degrees of the circle apart


@dataclass(frozen=True)
class Sample:
    mode: int
    north: float
    east: float
    up: float
    heading: float


def _observe(address: str, run: subprocess.Popen[bytes]) -> tuple[list[Sample], Any]:
    """Every position the vehicle reports on SERIAL1 until the run ends, with the mode of
    the latest HEARTBEAT; and the vehicle's home (its first position, on the ground)."""
    home, samples = None, []
    for mode, msg in watch_run(address, run, ["GLOBAL_POSITION_INT"]):
        if msg.lat != 0:
            if home is None:
                home = (msg.lat / 1e7, msg.lon / 1e7, msg.alt / 1000)
            north, east, _ = to_local(msg.lat / 1e7, msg.lon / 1e7, home[2], *home)
            samples.append(Sample(mode, north, east, msg.relative_alt / 1000, msg.hdg / 100))
    return samples, home


def _judge(samples: list[Sample], mode: int, point: tuple[float, float], radius: float,
           altitude: float) -> tuple[float, float, float]:
    """The circle flown in ``mode`` round ``point``: (largest distance error, largest
    heading error, degrees swept round the point) from the first sample on the circle at
    its altitude to the last in that mode."""
    flown = [s for s in samples if s.mode == mode]
    on = next(i for i, s in enumerate(flown)
              if abs(math.hypot(s.north - point[0], s.east - point[1]) - radius) < 1.0
              and abs(s.up - altitude) < 1.0)
    circle = flown[on:]
    distance = max(abs(math.hypot(s.north - point[0], s.east - point[1]) - radius)
                   for s in circle)
    heading = 0.0
    swept, last = 0.0, None
    for s in circle:
        toward = math.degrees(math.atan2(point[1] - s.east, point[0] - s.north)) % 360
        heading = max(heading, abs((s.heading - toward + 180) % 360 - 180))
        bearing = math.degrees(math.atan2(s.east - point[1], s.north - point[0]))
        if last is not None:
            swept += (bearing - last + 180) % 360 - 180
        last = bearing
    return distance, heading, swept


@pytest.mark.timeout(900)
def test_arducopter_orbits_both_points_facing_them(ardupilot, tmp_path: Path) -> None:
    (sitl,) = ardupilot()
    log = tmp_path / "orbit.jsonl"
    run = subprocess.Popen([sys.executable, "-m", "tml", "run", str(MISSION), "--connect",
                            sitl.address, "--clock", "vehicle", "-q", "--log", str(log)],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        samples, home = _observe(sitl.companion_address, run)
    finally:
        if run.poll() is None:
            run.kill()
        run.wait()
    assert run.returncode == 0
    assert home is not None
    guided = _judge(samples, GUIDED, MAST, 12.0, 15.0)
    field = to_local(*FIELD, home[2], *home)[:2]
    auto = _judge(samples, AUTO, field, 10.0, 20.0)
    print(f"GUIDED: {guided}, AUTO: {auto} (distance error m, heading error deg, swept deg)")
    for distance, heading, swept in (guided, auto):
        assert distance <= DISTANCE_TOLERANCE
        assert heading <= HEADING_TOLERANCE
        assert abs(swept) >= 330.0
