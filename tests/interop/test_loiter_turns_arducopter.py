"""NAV_LOITER_TURNS in AUTO on ArduCopter SITL and on the simulator.

A plain pymavlink client takes off in GUIDED, uploads a waypoint 40 m north, two
anticlockwise turns of 15 m (param3 -15) round it and a waypoint back, and flies them in
AUTO; while the turns are flown it records the distance from the centre, the bearing from
it and how far the nose is off the centre. Both vehicles must say "Mission: starting
circle 1/2", "2/2" and, once the item is reached, "3/2", go round anticlockwise nearly
twice, at the circle's radius (less the lag of the position controller), facing the centre.
Measured: ArduCopter 14.4 m, 550 degrees after the first quarter, at most 2 degrees off the
centre; the simulator 14.2 m, 537 degrees, 0 degrees.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

from ground_station import ALTITUDE, AUTO, EARTH_RADIUS, GUIDED, GroundStation, M, on_both

NORTH, RADIUS = 40.0, 15.0


def _circle(address: str) -> dict[str, Any]:
    station = GroundStation(address, timeout=120.0)
    try:
        station.connect()
        station.set_mode(GUIDED)
        station.arm()
        station.take_off()
        home_lat, home_lon = station.position.lat / 1e7, station.position.lon / 1e7
        centre = (round((home_lat + math.degrees(NORTH / EARTH_RADIUS)) * 1e7),
                  round(home_lon * 1e7))
        items = [(M.MAV_CMD_NAV_WAYPOINT, 0, 0, 0, 0, 0.0),
                 (M.MAV_CMD_NAV_WAYPOINT, 0, 0, *centre, ALTITUDE),
                 (M.MAV_CMD_NAV_LOITER_TURNS, 2, -RADIUS, *centre, ALTITUDE),
                 (M.MAV_CMD_NAV_WAYPOINT, 0, 0, round(home_lat * 1e7), round(home_lon * 1e7),
                  ALTITUDE)]

        def send(seq: int) -> None:
            command, p1, p3, lat, lon, alt = items[seq]
            station.conn.mav.mission_item_int_send(
                station.target, 1, seq, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, command, 0, 1,
                p1, 0, p3, 0, lat, lon, alt, M.MAV_MISSION_TYPE_MISSION)

        station.conn.mav.mission_count_send(station.target, 1, len(items))
        station.wait(lambda m: (m.get_type() in ("MISSION_REQUEST_INT", "MISSION_REQUEST")
                                and send(m.seq)) or m.get_type() == "MISSION_ACK",
                     "mission uploaded")
        station.set_mode(AUTO)
        samples: list[tuple[float, float, float]] = []
        metres = EARTH_RADIUS * math.pi / 180 / 1e7

        def record(m: Any) -> bool:
            if m.get_type() == "GLOBAL_POSITION_INT" and 2 not in station.flight.reached \
                    and any("starting circle" in t for t in station.flight.texts):
                north = (m.lat - centre[0]) * metres
                east = (m.lon - centre[1]) * metres * math.cos(math.radians(home_lat))
                facing = math.degrees(math.atan2(-east, -north))
                samples.append((math.hypot(north, east), math.degrees(math.atan2(east, north)),
                                abs((m.hdg / 100 - facing + 180) % 360 - 180)))
            return m.get_type() == "STATUSTEXT" and m.text.endswith("3/2")

        station.wait(record, "the loiter turns done")
        said = [t for t in station.flight.texts if "starting circle" in t]
    finally:
        station.close()
    steady = samples[len(samples) // 4:]  # once it is out on the circle
    turned = sum((b[1] - a[1] + 180) % 360 - 180 for a, b in itertools.pairwise(steady))
    radius = sum(s[0] for s in steady) / len(steady)
    return {"said": said, "turned": round(turned), "radius": round(radius, 1),
            "off_centre": round(max(s[2] for s in steady))}


def test_loiter_turns_are_flown_alike_on_arducopter_and_the_simulator(ardupilot: Any) -> None:
    arducopter, simulator = on_both(ardupilot, _circle, speedup=5.0)
    for flown in (arducopter, simulator):
        assert flown["said"] == ["Mission: starting circle 1/2", "Mission: starting circle 2/2",
                                 "Mission: starting circle 3/2"]
        assert -720.0 < flown["turned"] < -450.0  # anticlockwise, less the first quarter
        assert RADIUS - 1.5 < flown["radius"] < RADIUS + 0.5
        assert flown["off_centre"] < 15.0
