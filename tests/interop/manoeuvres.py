"""Motion profiles of a copter, flown by a plain pymavlink client (none of tml's code).

The same manoeuvres fly ArduCopter SITL and ``python -m sitl``, so their timings compare:
take-off to 10 m, GUIDED position targets 20 m and 100 m away, braking from 10 m/s to a
position target at the vehicle's own position, stopping with a velocity target of zero (what
tml's HOLD sends) from 10 m/s and while still speeding up, a climb to 30 m,
LAND from 10 m and from 30 m, RTL from 50 m away at 10 m (it climbs to RTL_ALT first), and
an AUTO mission of four waypoints with corners. Every time is vehicle time, read from
GLOBAL_POSITION_INT's ``time_boot_ms`` (requested at 10 Hz), counted from the first sample
after the command was sent; the client does not need to know the vehicle's speed-up.

    python tests/interop/manoeuvres.py tcp:127.0.0.1:5960      # prints the timings as JSON

docs/simulator.md quotes these numbers; tests/interop/test_simulator_twin.py compares them.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ground_station import EARTH_RADIUS, GUIDED, GroundStation, M

LAND = 9
RTL = 6
SAMPLE_US = 100_000  # GLOBAL_POSITION_INT every 0.1 s of vehicle time
SQUARE = ((40.0, 0.0), (40.0, 40.0), (0.0, 40.0), (0.0, 0.0))  # AUTO waypoints, m N/E


@dataclass(frozen=True)
class Sample:
    """One GLOBAL_POSITION_INT: vehicle seconds, metres from the reference, speeds in m/s."""

    t: float
    north: float
    east: float
    up: float
    speed: float  # horizontal
    climb: float  # vertical, up positive


class Flyer(GroundStation):
    """A ground station that records samples while the vehicle manoeuvres.

    Every message received goes through :meth:`_receive`, which keeps the latest sample;
    before each timed command the link is drained, so that a backlog of messages in the
    socket does not make the command look later than it was."""

    def __init__(self, address: str, timeout: float = 120.0) -> None:
        super().__init__(address, timeout)
        self.reference: tuple[float, float] | None = None  # lat, lon where it last armed
        self.last: Sample | None = None
        self.reached: list[tuple[int, float]] = []  # (seq, vehicle s) of MISSION_ITEM_REACHED
        self._recording: list[Sample] | None = None

    # -- samples ------------------------------------------------------------------------
    def _sample(self, msg: Any) -> Sample:
        lat0, lon0 = self.reference or (msg.lat / 1e7, msg.lon / 1e7)
        north = math.radians(msg.lat / 1e7 - lat0) * EARTH_RADIUS
        east = math.radians(msg.lon / 1e7 - lon0) * EARTH_RADIUS * math.cos(math.radians(lat0))
        return Sample(msg.time_boot_ms / 1000.0, north, east, msg.relative_alt / 1000.0,
                      math.hypot(msg.vx, msg.vy) / 100.0, -msg.vz / 100.0)

    def _receive(self, wait: float) -> Any:
        msg = super()._receive(wait)
        if msg is not None and msg.get_type() == "GLOBAL_POSITION_INT":
            self.last = self._sample(msg)
            if self._recording is not None:
                self._recording.append(self.last)
        elif msg is not None and msg.get_type() == "MISSION_ITEM_REACHED" and self.last:
            self.reached.append((msg.seq, self.last.t))
        return msg

    def drain(self) -> Sample:
        """Read what is waiting; the latest sample (the vehicle's time now)."""
        while self._receive(0.001) is not None:
            pass
        if self.last is None:
            self.wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT", "a sample")
        assert self.last is not None
        return self.last

    def record(self, done: Callable[[Sample], bool], what: str, limit: float = 120.0,
               every: Callable[[], None] | None = None, send: Callable[[], None] | None = None,
               ) -> list[Sample]:
        """Drain, ``send()`` the command, then samples from the latest before it until
        ``done(sample)`` (at most ``limit`` vehicle seconds); ``every()`` each 0.5 s."""
        start = self.drain()
        if send is not None:
            send()
        samples = self._recording = [start]
        due = 0.0
        try:
            while not done(samples[-1]) or len(samples) == 1:
                if every is not None and self.last is not None and self.last.t >= due:
                    due = self.last.t + 0.5
                    every()
                self._receive(0.05)
                if samples[-1].t - start.t > limit:
                    raise AssertionError(f"{what}: not within {limit:g} vehicle seconds")
        finally:
            self._recording = None
        return samples

    def settle(self, seconds: float) -> None:
        """Let ``seconds`` of vehicle time pass."""
        end = self.drain().t + seconds
        self.record(lambda s: s.t >= end, "settling", seconds + 10)

    # -- commands -----------------------------------------------------------------------
    def connect(self) -> None:
        """Connect and ask for GLOBAL_POSITION_INT at 10 Hz."""
        super().connect()
        self.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                     SAMPLE_US)
        self.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL)

    def go(self, north: float, east: float, up: float) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT to a point relative to the reference."""
        lat, lon = self._global(north, east)
        self.conn.mav.set_position_target_global_int_send(
            0, self.target, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000,
            lat, lon, up, 0, 0, 0, 0, 0, 0, 0, 0)

    def _global(self, north: float, east: float) -> tuple[int, int]:
        assert self.reference is not None
        lat0, lon0 = self.reference
        lat = lat0 + math.degrees(north / EARTH_RADIUS)
        lon = lon0 + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(lat0))))
        return round(lat * 1e7), round(lon * 1e7)

    def velocity(self, north: float) -> None:
        """SET_POSITION_TARGET_LOCAL_NED with a velocity north only (0: stop there)."""
        self.conn.mav.set_position_target_local_ned_send(
            0, self.target, 1, M.MAV_FRAME_LOCAL_NED, 0b110111000111,
            0, 0, 0, north, 0, 0, 0, 0, 0, 0, 0)

    def switch(self, mode: int) -> None:
        """DO_SET_MODE, not waited for (the samples show when it took effect)."""
        self.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode)

    def arm_here(self) -> None:
        """GUIDED and arm; positions are then metres from here (home)."""
        self.set_mode(GUIDED)
        self.arm()
        here = self.drain()
        assert self.position is not None and here is not None
        self.reference = (self.position.lat / 1e7, self.position.lon / 1e7)

    def take_off(self, altitude: float) -> list[Sample]:
        """GUIDED, arm, NAV_TAKEOFF: samples until within 0.1 m of ``altitude``."""
        self.arm_here()
        return self.record(lambda s: s.up >= altitude - 0.1, "take-off", send=lambda: (
            self.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, altitude)))

    def fly_to(self, north: float, east: float, up: float) -> list[Sample]:
        """A GUIDED position target; samples until within 0.2 m and below 0.2 m/s."""
        return self.record(lambda s: math.dist((s.north, s.east, s.up), (north, east, up)) < 0.2
                           and s.speed < 0.2 and abs(s.climb) < 0.2, f"to {north, east, up}",
                           send=lambda: self.go(north, east, up))

    def landing(self, mode: int) -> list[Sample]:
        """LAND or RTL: samples until the vehicle is down and disarmed."""
        return self.record(lambda s: s.up < 0.3 and not self.armed, "landing", 300,
                           send=lambda: self.switch(mode))

    def upload(self, items: list[tuple[int, float, float, float]]) -> None:
        """Upload a mission of (command, north, east, up) items after home."""
        station = self
        rows = [(M.MAV_CMD_NAV_WAYPOINT, 0, 0, 0.0)]
        for command, north, east, up in items:
            rows.append((command, *self._global(north, east), up))

        def answer(msg: Any) -> bool:
            if msg.get_type() in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
                command, lat, lon, up = rows[msg.seq]
                station.conn.mav.mission_item_int_send(
                    station.target, 1, msg.seq, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, command,
                    0, 1, 0, 0, 0, 0, lat, lon, up, M.MAV_MISSION_TYPE_MISSION)
            return msg.get_type() == "MISSION_ACK"

        station.conn.mav.mission_count_send(station.target, 1, len(rows),
                                            M.MAV_MISSION_TYPE_MISSION)
        station.wait(answer, "MISSION_ACK", 30.0)


# -- the manoeuvres, and their timings --------------------------------------------------
def first(samples: list[Sample], test: Callable[[Sample], bool]) -> float:
    """Vehicle seconds from the first sample to the first that passes ``test``."""
    return next(s.t for s in samples if test(s)) - samples[0].t


def fly_all(address: str) -> dict[str, Any]:
    """Fly every manoeuvre; the profiles (lists of samples) by name."""
    flyer = Flyer(address)
    profiles: dict[str, list[Sample]] = {}
    try:
        flyer.connect()
        profiles["takeoff"] = flyer.take_off(10.0)
        flyer.settle(2.0)
        profiles["guided_20"] = flyer.fly_to(20.0, 0.0, 10.0)
        profiles["guided_100"] = flyer.fly_to(120.0, 0.0, 10.0)
        flyer.settle(1.0)
        # Braking: a velocity target of 10 m/s south until the speed is steady, then a
        # position target where the vehicle is, as tml's HOLD sends it.
        profiles["accelerate"] = flyer.record(
            lambda s: s.speed >= 9.9, "10 m/s", 30, every=lambda: flyer.velocity(-10.0),
            send=lambda: flyer.velocity(-10.0))
        steady = flyer.drain().t + 2.0
        flyer.record(lambda s: s.t >= steady, "10 m/s steady", 10,
                     every=lambda: flyer.velocity(-10.0))
        here = flyer.drain()
        profiles["brake"] = flyer.record(
            lambda s: abs(s.north - here.north) < 0.3 and s.speed < 0.2, "braking", 60,
            send=lambda: flyer.go(here.north, here.east, 10.0))
        # tml's HOLD: a velocity target of zero, from 10 m/s steady, and at 8.5 m/s while
        # speeding up toward a position target 300 m away.
        flyer.record(lambda s: s.speed >= 9.9, "10 m/s", 30, every=lambda: flyer.velocity(-10.0),
                     send=lambda: flyer.velocity(-10.0))
        steady = flyer.drain().t + 2.0
        flyer.record(lambda s: s.t >= steady, "10 m/s steady", 10,
                     every=lambda: flyer.velocity(-10.0))
        profiles["stop"] = flyer.record(lambda s: s.speed < 0.2, "stopping", 60,
                                        send=lambda: flyer.velocity(0.0))
        flyer.settle(2.0)
        start = flyer.drain()
        flyer.record(lambda s: s.speed >= 8.5, "8.5 m/s", 60,
                     send=lambda: flyer.go(start.north + 300.0, start.east, 10.0))
        profiles["stop_speeding_up"] = flyer.record(lambda s: s.speed < 0.2, "stopping", 60,
                                                    send=lambda: flyer.velocity(0.0))
        profiles["stopped"] = flyer.record(lambda s: s.t >= profiles["stop_speeding_up"][-1].t
                                           + 3.0, "stopped", 20)
        profiles["land_10"] = flyer.landing(LAND)
        # RTL from 50 m north at 10 m: climb to RTL_ALT, return, loiter, land.
        flyer.take_off(10.0)
        flyer.fly_to(50.0, 0.0, 10.0)
        profiles["rtl_50"] = flyer.landing(RTL)
        # Climb to 30 m and land from there.
        flyer.take_off(10.0)
        profiles["climb_30"] = flyer.fly_to(0.0, 0.0, 30.0)
        profiles["land_30"] = flyer.landing(LAND)
        # AUTO: take off, a square of 40 m legs with corners, RTL. ArduCopter starts a
        # mission on the ground at MISSION_START (which also selects AUTO).
        flyer.upload([(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 10.0),
                      *[(M.MAV_CMD_NAV_WAYPOINT, n, e, 10.0) for n, e in SQUARE],
                      (M.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0.0)])
        flyer.arm_here()
        flyer.reached.clear()
        profiles["auto"] = flyer.record(
            lambda s: s.up < 0.3 and not flyer.armed and len(flyer.reached) > 3, "the mission",
            300, send=lambda: flyer.command(M.MAV_CMD_MISSION_START))
        reached = list(flyer.reached)
    finally:
        flyer.close()
    return {"profiles": profiles, "reached": reached}


def timings(flown: dict[str, Any]) -> dict[str, float]:
    """The numbers compared: vehicle seconds of each phase, and peak speeds (m/s)."""
    p = flown["profiles"]
    out: dict[str, float] = {}
    takeoff = p["takeoff"]
    out["takeoff_leaves_ground"] = first(takeoff, lambda s: s.up > 0.2)
    out["takeoff_5m"] = first(takeoff, lambda s: s.up >= 5.0)
    out["takeoff_10m"] = first(takeoff, lambda s: s.up >= 9.9)
    out["takeoff_peak_climb"] = max(s.climb for s in takeoff)
    for name, distance in (("guided_20", 20.0), ("guided_100", 100.0)):
        leg = p[name]
        start = leg[0].north
        out[f"{name}_half"] = first(leg, lambda s, d=distance, o=start: s.north - o >= d / 2)
        out[f"{name}_within_1m"] = first(leg, lambda s, d=distance, o=start: s.north - o >= d - 1)
        out[f"{name}_within_half_m"] = first(  # tml's acceptance radius
            leg, lambda s, d=distance, o=start: s.north - o >= d - 0.5)
        out[f"{name}_settled"] = leg[-1].t - leg[0].t
        out[f"{name}_peak_speed"] = max(s.speed for s in leg)
    out["accelerate_to_9"] = first(p["accelerate"], lambda s: s.speed >= 9.0)
    out["accelerate_to_9_5"] = first(p["accelerate"], lambda s: s.speed >= 9.5)
    brake = p["brake"]
    out["brake_below_5"] = first(brake, lambda s: s.speed < 5.0)
    out["brake_below_1"] = first(brake, lambda s: s.speed < 1.0)
    out["brake_distance"] = max(abs(s.north - brake[0].north) for s in brake)
    out["brake_back"] = brake[-1].t - brake[0].t
    for name in ("stop", "stop_speeding_up"):
        stop = p[name]
        out[f"{name}_from"] = stop[0].speed
        out[f"{name}_below_1"] = first(stop, lambda s: s.speed < 1.0)
        out[f"{name}_distance"] = math.dist((stop[0].north, stop[0].east),
                                            (stop[-1].north, stop[-1].east))
    last = p["stop_speeding_up"][-1]
    out["stopped_drift"] = max(math.dist((s.north, s.east), (last.north, last.east))
                               for s in p["stopped"])
    out["climb_30_time"] = first(p["climb_30"], lambda s: s.up >= 29.9)
    out["climb_30_peak"] = max(s.climb for s in p["climb_30"])
    for name in ("land_10", "land_30"):
        land = p[name]
        out[f"{name}_down"] = first(land, lambda s: s.up < 0.2)
        out[f"{name}_below_10m"] = first(land, lambda s: s.up < 9.8)
        out[f"{name}_peak_descent"] = -min(s.climb for s in land)
        out[f"{name}_final_descent"] = -min(s.climb for s in land if s.up < 5.0)
    rtl = p["rtl_50"]
    out["rtl_climbed"] = first(rtl, lambda s: s.up >= 14.8)
    out["rtl_home"] = first(rtl, lambda s: s.north < 1.0)
    out["rtl_descent_starts"] = first(
        rtl, lambda s: s.north < 1.0 and s.up < 14.5)
    out["rtl_down"] = first(rtl, lambda s: s.up < 0.2)
    out["rtl_peak_speed"] = max(s.speed for s in rtl)
    auto = p["auto"]
    start = auto[0].t
    for seq, t in flown["reached"]:
        out[f"auto_reached_{seq}"] = t - start
    out["auto_down"] = first(auto, lambda s: s.up < 0.2 and s.t - start > 20)
    # The slowest between the first corner and the third: the speed through the corners.
    when = dict(flown["reached"])
    out["auto_corner_speed"] = min(s.speed for s in auto if when[2] <= s.t <= when[4])
    return out


def as_json(flown: dict[str, Any]) -> dict[str, Any]:
    """The profiles as plain lists, for a file."""
    return {"reached": flown["reached"], "profiles": {
        name: [[round(v, 3) for v in (s.t, s.north, s.east, s.up, s.speed, s.climb)]
               for s in samples] for name, samples in flown["profiles"].items()}}


if __name__ == "__main__":
    result = fly_all(sys.argv[1])
    if len(sys.argv) > 2:
        with open(sys.argv[2], "w") as out:
            json.dump(as_json(result), out)
    print(json.dumps(timings(result), indent=1))
