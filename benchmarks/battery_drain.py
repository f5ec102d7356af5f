"""How fast ArduCopter SITL drains its battery: hovering, and per metre at cruise speed.

Starts one ArduCopter SITL (ArduPilot's ``copter.parm``, see tests/interop/ardupilot_sitl.py
for where it is found) at ``--speedup``, and flies it with a bare pymavlink ground station:
GUIDED, arm (retried until the EKF allows it), take off to ``--altitude``, hover
``--hover`` seconds, fly ``--legs`` straight legs of ``--leg`` metres (out and back, at the
vehicle's WPNAV_SPEED), hover again, land. BATTERY_STATUS (``current_consumed`` in mAh,
``battery_remaining`` in percent, ``current_battery``) is read at 10 Hz and timed with its
own ``time_boot_ms`` stamps from SYSTEM_TIME, so the rates are per second of vehicle time
whatever the speed-up. Prints:

- the hover drain in percent of BATT_CAPACITY per second (and in amperes),
- the cruise drain per metre flown (climb and descent excluded) and per second of cruise,
- the same as the verifier profile keys ``battery_per_second`` and ``battery_per_metre``
  for BATT_CAPACITY, the values tml/verify/profiles/quadcopter.toml holds.

    .venv/bin/python benchmarks/battery_drain.py [--speedup 10] [--hover 60] [--leg 300]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "interop"))
os.environ.setdefault("MAVLINK20", "1")

from ardupilot_sitl import find_launcher, vehicles  # noqa: E402
from pymavlink import mavutil  # noqa: E402

M = mavutil.mavlink
STREAMS = {M.MAVLINK_MSG_ID_BATTERY_STATUS: 10, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10,
           M.MAVLINK_MSG_ID_SYSTEM_TIME: 10, M.MAVLINK_MSG_ID_HEARTBEAT: 1,
           M.MAVLINK_MSG_ID_EKF_STATUS_REPORT: 2}
GUIDED, LAND = 4, 9


@dataclass
class Sample:
    """One BATTERY_STATUS with the vehicle's time and position when it came."""

    time: float  # s of vehicle time
    consumed: float  # mAh
    remaining: int  # percent
    current: float  # A
    north: float  # m from the start
    east: float
    up: float


class Station:
    """A pymavlink ground station that keeps the latest state of one vehicle."""

    def __init__(self, address: str) -> None:
        self.conn = mavutil.mavlink_connection(address, source_system=250,
                                               source_component=190)
        beat = self.conn.wait_heartbeat(timeout=60)
        if beat is None:
            raise SystemExit(f"no heartbeat from {address}")
        self.sysid = beat.get_srcSystem()
        self.time = 0.0
        self.origin: tuple[float, float] | None = None
        self.position = (0.0, 0.0, 0.0)
        self.samples: list[Sample] = []
        for msg_id, rate in STREAMS.items():
            self.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / rate, wait=False)

    def command(self, command: int, *params: float, wait: bool = True) -> int | None:
        p = [*params, 0, 0, 0, 0, 0, 0, 0][:7]
        self.conn.mav.command_long_send(self.sysid, 1, command, 0, *p)
        if not wait:
            return None
        end = time.monotonic() + 3
        while time.monotonic() < end:
            msg = self.pump("COMMAND_ACK")
            if msg is not None and msg.command == command:
                return int(msg.result)
        return None

    def pump(self, wanted: str | None = None, timeout: float = 0.2) -> Any:
        """Read messages for up to ``timeout`` s, updating the state; the first ``wanted``."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            msg = self.conn.recv_match(blocking=True, timeout=max(0.0, end - time.monotonic()))
            if msg is None:
                return None
            kind = msg.get_type()
            if kind == "SYSTEM_TIME":
                self.time = msg.time_boot_ms / 1000.0
            elif kind == "GLOBAL_POSITION_INT" and msg.lat != 0:
                lat, lon = msg.lat / 1e7, msg.lon / 1e7
                if self.origin is None:
                    self.origin = (lat, lon)
                north = math.radians(lat - self.origin[0]) * 6378137.0
                east = math.radians(lon - self.origin[1]) * 6378137.0 * math.cos(
                    math.radians(lat))
                self.position = (north, east, msg.relative_alt / 1000.0)
                self.time = max(self.time, msg.time_boot_ms / 1000.0)
            elif kind == "BATTERY_STATUS":
                self.samples.append(Sample(self.time, float(msg.current_consumed),
                                           msg.battery_remaining, msg.current_battery / 100.0,
                                           *self.position))
            if wanted is not None and kind == wanted:
                return msg
        return None

    def wait_until(self, done: Callable[[], bool], limit: float) -> None:
        """Pump until ``done()`` or ``limit`` s of vehicle time from now."""
        end = self.time + limit
        while not done():
            self.pump()
            if self.time > end:
                raise SystemExit(f"not reached within {limit:g} s of vehicle time")

    def param(self, name: str) -> float:
        self.conn.mav.param_request_read_send(self.sysid, 1, name.encode(), -1)
        for _ in range(50):
            msg = self.pump("PARAM_VALUE")
            if msg is not None and msg.param_id == name:
                return float(msg.param_value)
        raise SystemExit(f"parameter {name} not read")

    def goto(self, north: float, east: float, up: float) -> None:
        assert self.origin is not None
        lat = self.origin[0] + math.degrees(north / 6378137.0)
        lon = self.origin[1] + math.degrees(east / (6378137.0 * math.cos(
            math.radians(self.origin[0]))))
        self.conn.mav.set_position_target_global_int_send(
            0, self.sysid, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000,
            round(lat * 1e7), round(lon * 1e7), up, 0, 0, 0, 0, 0, 0, 0, 0)

    def near(self, north: float, east: float, up: float, within: float = 1.0) -> bool:
        n, e, u = self.position
        return math.dist((n, e, u), (north, east, up)) < within


def take_off(gcs: Station, altitude: float) -> None:
    """GUIDED, arm (refused until the EKF uses GPS) and NAV_TAKEOFF, again until it climbs
    (an armed vehicle that is not told to take off soon enough disarms by itself)."""
    start = gcs.time
    while gcs.time - start < 180:
        gcs.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED)
        if gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) != M.MAV_RESULT_ACCEPTED or \
                gcs.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, altitude) \
                != M.MAV_RESULT_ACCEPTED:
            gcs.pump(timeout=1.0)
            continue
        climbing = gcs.time + 10.0
        while gcs.time < climbing and gcs.position[2] < 1.0:
            gcs.pump()
        if gcs.position[2] >= 1.0:
            return
    raise SystemExit("the vehicle never took off")


def window(samples: list[Sample], start: float, end: float) -> tuple[float, float, float]:
    """(mAh used, seconds, horizontal metres flown) between two vehicle times."""
    inside = [s for s in samples if start <= s.time <= end]
    if len(inside) < 2:
        raise SystemExit("too few battery samples in a window")
    metres = sum(math.dist((a.north, a.east), (b.north, b.east))
                 for a, b in pairwise(inside))
    return inside[-1].consumed - inside[0].consumed, inside[-1].time - inside[0].time, metres


def fly(args: argparse.Namespace) -> None:
    launcher, reason = find_launcher()
    if launcher is None:
        raise SystemExit(reason)
    with vehicles(launcher, 1, speedup=args.speedup) as (sitl,):
        gcs = Station(sitl.address)
        capacity = gcs.param("BATT_CAPACITY")
        speed = gcs.param("WPNAV_SPEED") / 100.0
        take_off(gcs, args.altitude)
        gcs.wait_until(lambda: gcs.position[2] > args.altitude - 0.3, 120)
        gcs.pump(timeout=5.0 / args.speedup)  # settle
        hover_start = gcs.time
        gcs.wait_until(lambda: gcs.time - hover_start >= args.hover, args.hover + 10)
        hover = window(gcs.samples, hover_start, gcs.time)
        cruise_mah = cruise_s = cruise_m = 0.0
        for leg in range(args.legs):
            target = (args.leg if leg % 2 == 0 else 0.0, 0.0, args.altitude)
            start = gcs.time
            gcs.goto(*target)
            gcs.wait_until(lambda t=target: gcs.near(*t), 4 * args.leg / speed + 60)
            used, seconds, metres = window(gcs.samples, start, gcs.time)
            cruise_mah, cruise_s, cruise_m = cruise_mah + used, cruise_s + seconds, \
                cruise_m + metres
        gcs.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, LAND)
        gcs.wait_until(lambda: gcs.position[2] < 0.2, 120)
        report(capacity, speed, hover, (cruise_mah, cruise_s, cruise_m), gcs.samples)


def report(capacity: float, speed: float, hover: tuple[float, float, float],
           cruise: tuple[float, float, float], samples: list[Sample]) -> None:
    hover_mah, hover_s, _ = hover
    cruise_mah, cruise_s, cruise_m = cruise
    per_second = 100.0 * hover_mah / capacity / hover_s
    per_metre = 100.0 * cruise_mah / capacity / cruise_m
    first, last = samples[0], samples[-1]
    print(f"BATT_CAPACITY {capacity:g} mAh, WPNAV_SPEED {speed:g} m/s")
    print(f"hover:  {hover_mah:.1f} mAh in {hover_s:.1f} s = {hover_mah * 3.6 / hover_s:.1f} A"
          f" = {per_second:.4f} %/s")
    print(f"cruise: {cruise_mah:.1f} mAh in {cruise_s:.1f} s over {cruise_m:.0f} m = "
          f"{cruise_mah * 3.6 / cruise_s:.1f} A = {100 * cruise_mah / capacity / cruise_s:.4f}"
          f" %/s = {per_metre:.5f} %/m ({cruise_m / cruise_s:.1f} m/s on average)")
    print(f"whole flight: {first.remaining} % -> {last.remaining} % "
          f"({last.consumed - first.consumed:.0f} mAh) in {last.time - first.time:.0f} s")
    print(f"profile (battery_capacity = {capacity:g}): battery_per_second = {per_second:.4f},"
          f" battery_per_metre = {per_metre:.5f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speedup", type=float, default=10.0)
    parser.add_argument("--altitude", type=float, default=15.0)
    parser.add_argument("--hover", type=float, default=60.0, help="seconds of hover")
    parser.add_argument("--leg", type=float, default=300.0, help="metres per cruise leg")
    parser.add_argument("--legs", type=int, default=2)
    fly(parser.parse_args())


if __name__ == "__main__":
    main()
