"""What ArduPlane and Rover SITL do, held against the embedded simulator's plane and rover.

tml flies a fixed-wing and a rover the way these behave (tml/language/kinds.py, the adapter), and
the simulator imitates them (sitl/plane.py, sitl/rover.py). Each fact here is checked with
the same plain pymavlink ground station on ArduPilot SITL and on ``python -m sitl``'s
frame, so that a difference shows on one side or the other. The missions themselves are
flown by tests/interop/test_ardupilot_missions.py.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from pymavlink import mavutil

from sitl.server import Simulator
from tml.geo import to_global, to_local

M = mavutil.mavlink
SPEEDUP = 10.0
FAST_START = {"SIM_GPS_LOCKTIME": 1.0, "SIM_EKF_GPS_TIME": 2.0}


class Station:
    """A minimal ground station on one vehicle: streams, commands, the latest messages."""

    def __init__(self, address: str) -> None:
        self.conn = mavutil.mavlink_connection(address, source_system=245,
                                               source_component=190)
        beat = self.conn.wait_heartbeat(timeout=30)
        assert beat is not None, f"no HEARTBEAT from {address}"
        self.system_id = beat.get_srcSystem()
        self.last: dict[str, Any] = {"HEARTBEAT": beat}
        for name, hz in (("GLOBAL_POSITION_INT", 10), ("HOME_POSITION", 1), ("VFR_HUD", 5),
                         ("EXTENDED_SYS_STATE", 2), ("SYS_STATUS", 2), ("GPS_RAW_INT", 2)):
            self.command(M.MAV_CMD_SET_MESSAGE_INTERVAL,
                         getattr(M, f"MAVLINK_MSG_ID_{name}"), 1e6 / hz)

    def close(self) -> None:
        self.conn.close()

    def pump(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            msg = self.conn.recv_match(blocking=True, timeout=0.05)
            if msg is not None and msg.get_srcSystem() == self.system_id \
                    and msg.get_srcComponent() == 1:
                self.last[msg.get_type()] = msg

    def wait(self, what: str, predicate: Callable[[Station], bool],
             vehicle_seconds: float) -> None:
        """Until ``predicate`` holds, within ``vehicle_seconds`` at the speed-up (doubled)."""
        end = time.monotonic() + 2 * vehicle_seconds / SPEEDUP + 5.0
        while time.monotonic() < end:
            self.pump(0.1)
            if predicate(self):
                return
        raise AssertionError(f"not within {vehicle_seconds:g} s of vehicle time: {what}")

    def command(self, command: int, *params: float) -> int:
        """COMMAND_LONG until its ACK; the MAV_RESULT."""
        values = list(params) + [0.0] * (7 - len(params))
        for _ in range(5):
            self.conn.mav.command_long_send(self.system_id, 1, command, 0, *values)
            end = time.monotonic() + 1.0
            while time.monotonic() < end:
                msg = self.conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.1)
                if msg is not None and msg.command == command:
                    return int(msg.result)
        raise AssertionError(f"no COMMAND_ACK for command {command}")

    def reposition(self, north: float, east: float, up: float, radius: float) -> int:
        lat, lon = self.point(north, east)
        for _ in range(5):
            self.conn.mav.command_int_send(
                self.system_id, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_CMD_DO_REPOSITION,
                0, 0, -1, M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, radius, math.nan,
                round(lat * 1e7), round(lon * 1e7), up)
            msg = self.conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=1.0)
            if msg is not None and msg.command == M.MAV_CMD_DO_REPOSITION:
                return int(msg.result)
        raise AssertionError("no COMMAND_ACK for DO_REPOSITION")

    def set_mode(self, name: str) -> int:
        number = mavutil.mode_mapping_byname(self.last["HEARTBEAT"].type)[name]
        return self.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, number)

    def mode(self) -> str:
        beat = self.last["HEARTBEAT"]
        return mavutil.mode_mapping_bynumber(beat.type).get(beat.custom_mode, "")

    def armed(self) -> bool:
        return bool(self.last["HEARTBEAT"].base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)

    def arm(self) -> None:
        """Arm, retrying while the pre-arm checks refuse (as any ground station must)."""
        end = time.monotonic() + 60.0
        while self.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) != M.MAV_RESULT_ACCEPTED:
            assert time.monotonic() < end, "never armable"
            self.pump(0.5)

    def ready(self) -> None:
        self.wait("a 3D fix and home", lambda s: "HOME_POSITION" in s.last
                  and "GPS_RAW_INT" in s.last and s.last["GPS_RAW_INT"].fix_type >= 3, 120)

    def point(self, north: float, east: float) -> tuple[float, float]:
        home = self.last["HOME_POSITION"]
        lat, lon, _ = to_global(north, east, 0.0, home.latitude / 1e7, home.longitude / 1e7,
                                0.0)
        return lat, lon

    def local(self) -> tuple[float, float, float]:
        """(north, east, relative altitude) from home."""
        home, here = self.last["HOME_POSITION"], self.last["GLOBAL_POSITION_INT"]
        north, east, _ = to_local(here.lat / 1e7, here.lon / 1e7, 0.0, home.latitude / 1e7,
                                  home.longitude / 1e7, 0.0)
        return north, east, here.relative_alt / 1000.0

    def speed(self) -> float:
        return float(self.last["VFR_HUD"].groundspeed)


@contextmanager
def on(where: str, frame: str, ardupilot: Any) -> Iterator[Station]:
    """A station on ArduPilot SITL's vehicle or on the simulator's ``frame``."""
    if where == "ardupilot":
        (sitl,) = ardupilot(vehicle=frame)
        station = Station(sitl.address)
        try:
            yield station
        finally:
            station.close()
        return
    with Simulator(frames=[frame], tcp_base_port=0, speedup=SPEEDUP, params=FAST_START) as sim:
        station = Station(f"tcp:127.0.0.1:{sim.tcp_ports[0]}")
        try:
            yield station
        finally:
            station.close()


@pytest.fixture(params=["ardupilot", "simulator"])
def where(request: pytest.FixtureRequest) -> str:
    return str(request.param)


def test_a_plane_takes_off_only_in_takeoff_mode_and_never_hovers(where: str, ardupilot) -> None:
    with on(where, "plane", ardupilot) as gcs:
        assert gcs.last["HEARTBEAT"].type == M.MAV_TYPE_FIXED_WING
        gcs.ready()
        assert gcs.set_mode("GUIDED") == M.MAV_RESULT_ACCEPTED
        gcs.arm()
        # No take-off in GUIDED: NAV_TAKEOFF is refused and the plane stays on the ground.
        assert gcs.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 40) == M.MAV_RESULT_FAILED
        gcs.pump(5 / SPEEDUP + 0.5)
        assert gcs.local()[2] < 1.0
        # ArduPlane has no LAND mode to send it to.
        assert gcs.command(M.MAV_CMD_NAV_LAND) == M.MAV_RESULT_UNSUPPORTED
        gcs.conn.mav.param_set_send(gcs.system_id, 1, b"TKOFF_ALT", 40,
                                    M.MAV_PARAM_TYPE_REAL32)
        gcs.conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=2)
        assert gcs.set_mode("TAKEOFF") == M.MAV_RESULT_ACCEPTED
        gcs.wait("the climb to 40 m", lambda s: s.local()[2] > 38, 90)
        assert gcs.speed() > 15  # a wing flies at its airspeed
        # A position target changes only the altitude: the plane stays where it circles.
        lat, lon = gcs.point(0, 600)
        assert gcs.set_mode("GUIDED") == M.MAV_RESULT_ACCEPTED
        gcs.conn.mav.set_position_target_global_int_send(
            0, gcs.system_id, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000,
            round(lat * 1e7), round(lon * 1e7), 60, 0, 0, 0, 0, 0, 0, 0, 0)
        gcs.wait("the climb to 60 m", lambda s: s.local()[2] > 57, 60)
        assert math.dist(gcs.local()[:2], (0, 600)) > 300
        # DO_REPOSITION moves it, and it circles the point at about the radius asked.
        assert gcs.reposition(0, 600, 60, 60) == M.MAV_RESULT_ACCEPTED
        gcs.wait("the circle around (0, 600)",
                 lambda s: math.dist(s.local()[:2], (0, 600)) < 110, 120)
        distances = []
        for _ in range(20):
            gcs.pump(2 / SPEEDUP)
            distances.append(math.dist(gcs.local()[:2], (0, 600)))
            assert gcs.speed() > 15
        assert min(distances) > 40 and max(distances) < 110, distances


def test_a_rover_stays_on_the_ground_drives_and_stops(where: str, ardupilot) -> None:
    with on(where, "rover", ardupilot) as gcs:
        assert gcs.last["HEARTBEAT"].type == M.MAV_TYPE_GROUND_ROVER
        gcs.ready()
        gcs.wait("EXTENDED_SYS_STATE", lambda s: "EXTENDED_SYS_STATE" in s.last, 20)
        assert gcs.last["EXTENDED_SYS_STATE"].landed_state == M.MAV_LANDED_STATE_UNDEFINED
        for command in (M.MAV_CMD_NAV_TAKEOFF, M.MAV_CMD_NAV_LAND, M.MAV_CMD_CONDITION_YAW):
            assert gcs.command(command, 90, 0, 1, 0, 0, 0, 10) == M.MAV_RESULT_UNSUPPORTED
        assert gcs.set_mode("GUIDED") == M.MAV_RESULT_ACCEPTED
        gcs.arm()
        # A speed is taken only while the rover drives to a point.
        assert gcs.command(M.MAV_CMD_DO_CHANGE_SPEED, 1, 2, -1) == M.MAV_RESULT_FAILED
        lat, lon = gcs.point(30, 20)
        gcs.conn.mav.set_position_target_global_int_send(
            0, gcs.system_id, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000,
            round(lat * 1e7), round(lon * 1e7), 0, 0, 0, 0, 0, 0, 0, 0, 0)
        gcs.wait("(30, 20), stopped", lambda s: math.dist(s.local()[:2], (30, 20)) < 1.0
                 and s.speed() < 0.2, 90)
        # RTL drives home and stops there, still armed and in RTL.
        assert gcs.command(M.MAV_CMD_NAV_RETURN_TO_LAUNCH) == M.MAV_RESULT_ACCEPTED
        gcs.wait("home, stopped", lambda s: math.dist(s.local()[:2], (0, 0)) < 1.5
                 and s.speed() < 0.2, 90)
        gcs.pump(5 / SPEEDUP)
        assert gcs.armed() and gcs.mode() == "RTL"
