"""DO_PAUSE_CONTINUE in GUIDED, on ArduCopter SITL and on the simulator, by a plain pymavlink
client: told to pause at 8.5 m/s while speeding up toward a target 400 m north, the copter
stops (ArduCopter's velocity controller is not started afresh: about 24 m on), flies no
target it is sent while paused, and flies the latest once continued; continuing when not
paused is accepted, and LOITER refuses to pause. Distances are read from GLOBAL_POSITION_INT;
the runs wait for states, with hang guards."""

from __future__ import annotations

import math
from typing import Any

import pytest
from ground_station import EARTH_RADIUS, GUIDED, GroundStation, M, on_both

LOITER = 5


def _north(station: GroundStation, origin: Any) -> float:
    return math.radians((station.position.lat - origin.lat) / 1e7) * EARTH_RADIUS


def _speed(msg: Any) -> float:
    return math.hypot(msg.vx, msg.vy) / 100.0


def _fly(address: str) -> dict[str, float]:
    station = GroundStation(address)
    try:
        station.connect()
        station.set_mode(GUIDED)
        station.arm()
        station.take_off()
        origin = station.position

        def go(north: float) -> None:
            lat = origin.lat + round(math.degrees(north / EARTH_RADIUS) * 1e7)
            station.conn.mav.set_position_target_global_int_send(
                0, station.target, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000,
                lat, origin.lon, 10, 0, 0, 0, 0, 0, 0, 0, 0)

        def stopped(msg: Any) -> bool:
            return msg.get_type() == "GLOBAL_POSITION_INT" and _speed(msg) < 0.2

        def pause(value: float) -> int:
            station.command(M.MAV_CMD_DO_PAUSE_CONTINUE, value)
            return station.ack(M.MAV_CMD_DO_PAUSE_CONTINUE)

        go(400.0)
        station.wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT" and _speed(m) > 8.5,
                     "8.5 m/s")
        told = _north(station, origin)
        out = {"paused": pause(0)}
        station.wait(stopped, "stopped")
        out["braked"] = _north(station, origin) - told
        go(100.0)
        boot = station.position.time_boot_ms
        station.wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT"
                     and m.time_boot_ms > boot + 5000, "5 s paused")
        out["moved_paused"] = abs(_north(station, origin) - told - out["braked"])
        out["continued"] = pause(1)
        station.wait(lambda m: stopped(m) and abs(_north(station, origin) - 100.0) < 1.0,
                     "at the latest target")
        out["continued_again"] = pause(1)
        station.set_mode(LOITER)
        out["loiter"] = pause(0)
        return out
    finally:
        station.close()


@pytest.mark.timeout(600)
def test_a_guided_pause_is_arducopters(ardupilot: Any) -> None:
    arducopter, simulator = on_both(ardupilot, _fly)
    for flown in (arducopter, simulator):
        assert flown["paused"] == flown["continued"] == flown["continued_again"] == \
            M.MAV_RESULT_ACCEPTED
        assert flown["loiter"] == M.MAV_RESULT_FAILED
        assert flown["moved_paused"] < 1.0
    # The simulator may stop short by as far as ArduCopter flies in its lag (0.3 s).
    assert arducopter["braked"] - 8.5 * 0.3 <= simulator["braked"] <= 1.1 * arducopter["braked"]
