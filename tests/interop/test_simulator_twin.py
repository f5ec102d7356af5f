"""What the simulator imitates, measured again on ArduCopter SITL: streams, arming, current.

Each test measures ArduCopter and compares with the simulator's own constants and models
(sitl/streams.py, sitl/arming.py, sitl/physics.py), so a change on either side shows here.
Run with ``-s`` to see the numbers docs/simulator.md quotes.
"""

from __future__ import annotations

import time
from collections import Counter

import pytest
from ground_station import GUIDED, GroundStation, M

from sitl.physics import flight_current
from sitl.streams import DEFAULT_RATES


def test_a_new_link_gets_only_what_the_simulator_sends_unasked(ardupilot) -> None:
    (sitl,) = ardupilot()
    station = GroundStation(sitl.address, 60.0)
    try:
        seen: Counter[str] = Counter()
        end = time.monotonic() + 4.0  # about 40 s of vehicle time at speed-up 10
        while time.monotonic() < end:
            msg = station._receive(0.05)
            if msg is not None:
                seen[msg.get_type()] += 1
    finally:
        station.close()
    print("unasked:", dict(seen))
    streamed = {name for name in seen if name not in (
        "STATUSTEXT", "PARAM_VALUE", "TIMESYNC", "GPS_GLOBAL_ORIGIN", "HOME_POSITION")}
    assert streamed == {"HEARTBEAT"}
    assert {M.mavlink_map[msg_id].msgname for msg_id, rate in DEFAULT_RATES.items()
            if rate > 0} == {"HEARTBEAT"}
    assert seen["HOME_POSITION"] == seen["GPS_GLOBAL_ORIGIN"] == 1  # when the origin is set


def hold_velocity(station: GroundStation, north: float, up: float, seconds: float) -> list:
    """Fly a velocity target for ``seconds`` (wall); the BATTERY_STATUS of the last half."""
    samples = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        station.conn.mav.set_position_target_local_ned_send(
            0, station.target, 1, M.MAV_FRAME_LOCAL_NED, 0b110111000111,
            0, 0, 0, north, 0, -up, 0, 0, 0, 0, 0)
        msg = station._receive(0.05)
        if msg is not None and msg.get_type() == "BATTERY_STATUS" and \
                end - time.monotonic() < seconds / 2:
            samples.append(msg.current_battery / 100)
    return samples


def test_the_current_drawn_is_the_simulators(ardupilot) -> None:
    (sitl,) = ardupilot()
    station = GroundStation(sitl.address, 120.0)
    measured = {}
    try:
        station.connect()
        station.set_mode(GUIDED)
        measured[(0.0, 0.0, False)] = hold_velocity(station, 0, 0, 1.0)  # on the ground
        station.arm()
        station.take_off()
        for north, up in ((0.0, 0.0), (0.0, 2.5), (0.0, -1.5), (5.0, 0.0), (10.0, 0.0)):
            measured[(north, up, True)] = hold_velocity(station, north, up, 3.0)  # 30 s
    finally:
        station.close()
    for (north, up, flying), current in measured.items():
        mean = sum(current) / len(current)
        model = flight_current(flying, flying, (north, 0.0, up), 0.0)
        print(f"north {north:4} m/s, up {up:4} m/s: {mean:5.2f} A (simulator {model:5.2f} A)")
        assert mean == pytest.approx(model, abs=0.4)
