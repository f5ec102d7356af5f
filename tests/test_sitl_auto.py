"""The AUTO executor, through the vehicle model: upload, arm, fly, watch what it reports."""

from __future__ import annotations

import itertools
import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.model import TICK, VehicleModel
from tml.geo import to_global, to_local
from tml.world import DEFAULT_HOME

FAST = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2}
H = DEFAULT_HOME


def at(north: float, east: float) -> tuple[int, int]:
    lat, lon, _ = to_global(north, east, 0.0, H.latitude, H.longitude, H.altitude)
    return round(lat * 1e7), round(lon * 1e7)


def item(command: int, *params: float, north: float | None = None, east: float = 0.0,
         alt: float = 10.0, frame: int = 6) -> tuple:
    x, y = at(north, east) if north is not None else (0, 0)
    values = [*params, *[0.0] * (4 - len(params))]
    return frame, command, values, x, y, alt


def load(v: VehicleModel, items: list[tuple]) -> None:
    everything = [item(16, alt=0), *items]  # seq 0: home, replaced by the vehicle
    replies = v.handle(M.MAVLink_mission_count_message(1, 1, len(everything), 0))
    while replies[-1].get_type() == "MISSION_REQUEST":
        frame, command, p, x, y, z = everything[replies[-1].seq]
        replies = v.handle(M.MAVLink_mission_item_int_message(
            1, 1, replies[-1].seq, frame, command, 0, 1, *p, x, y, z, 0))
    assert replies[-1].type == M.MAV_MISSION_ACCEPTED


def fly(items: list[tuple], limit: float = 300.0, until=None) -> tuple[VehicleModel, list]:
    """Fly ``items`` in AUTO until the vehicle disarms (or ``until(v)``); all it sent."""
    v = VehicleModel(1, H, params=FAST)
    v.handle(M.MAVLink_request_data_stream_message(1, 1, M.MAV_DATA_STREAM_ALL, 4, 1))
    v.step(3)
    load(v, items)
    assert v.set_mode("GUIDED")
    v.handle(M.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    assert v.armed and v.set_mode("AUTO")
    out: list = []
    while not until(v) if until else v.armed:
        assert v.time < limit
        out += v.step(TICK)
    return v, out


def reached(out: list) -> list[int]:
    return [m.seq for m in out if m.get_type() == "MISSION_ITEM_REACHED"]


def texts(out: list) -> list[str]:
    return [m.text for m in out if m.get_type() == "STATUSTEXT"]


def test_takeoff_waypoints_land_reports_every_item_and_disarms():
    v, out = fly([
        item(22, alt=10), item(16, north=40), item(16, north=40, east=40),
        item(16, north=0, east=40), item(21, north=0, east=40, alt=0),
    ])
    assert reached(out) == [1, 2, 3, 4, 5]
    assert "Mission: 2 WP" in texts(out) and "Mission: 5 Land" in texts(out)
    assert math.dist(v.position, (0.0, 40.0, 0.0)) < 0.5 and v.landed and not v.armed
    currents = {m.seq for m in out if m.get_type() == "MISSION_CURRENT"}
    assert currents >= {1, 2, 3, 4, 5}


def test_waypoints_turn_their_corners_without_stopping_in_arducopters_time():
    # ArduCopter SITL, a 40 m square at 10 m then RTL (docs/simulator.md): the waypoints are
    # reached 9.7, 7.1, 7.0 and 9.2 s apart, the corners at about 3 m/s, the last one stops.
    v, out = fly([item(22, alt=10), item(16, north=40), item(16, north=40, east=40),
                  item(16, north=0, east=40), item(16, north=0, east=0), item(20)], limit=400)
    assert reached(out) == [1, 2, 3, 4, 5, 6]
    times = {}
    speeds = {}
    now = 0.0
    for m in out:
        if m.get_type() == "GLOBAL_POSITION_INT":
            now, speed = m.time_boot_ms / 1000, math.hypot(m.vx, m.vy) / 100
        elif m.get_type() == "MISSION_ITEM_REACHED":
            times[m.seq], speeds[m.seq] = now, speed
    for seq, gap in ((2, 9.7), (3, 7.1), (4, 7.0), (5, 9.2)):
        assert times[seq] - times[seq - 1] == pytest.approx(gap, rel=0.1)
    assert [round(speeds[seq]) for seq in (2, 3, 4)] == [3, 3, 3]
    assert speeds[5] < 0.2 and not v.armed


def test_do_jump_repeats_and_items_a_copter_cannot_fly_are_skipped():
    _, out = fly([
        item(22, alt=5), item(16, north=10, alt=5), item(16, north=0, alt=5),
        item(177, 2, 2), item(84), item(21, alt=0),  # 84: NAV_VTOL_TAKEOFF, stored, not flown
    ])
    assert reached(out) == [1, 2, 3, 2, 3, 2, 3, 6]
    assert "Skipping invalid cmd #84" in texts(out)


def test_hold_time_delays_and_conditions():
    _, out = fly([
        item(22, alt=5), item(112, 4), item(2000, 0, 1, 1), item(16, 3, north=5, alt=5),
        item(93, 2), item(21, alt=0),
    ])
    assert reached(out) == [1, 4, 5, 6]
    assert texts(out).index("Mission: 2 CondDelay") < texts(out).index("Mission: 3 ImageStart")
    assert sum(m.get_type() == "CAMERA_FEEDBACK" for m in out) == 1


def test_loiter_turns_circles_and_rtl_ends_the_mission():
    v, out = fly([item(22, alt=10), item(18, 1, 0, 8, north=20), item(20)], limit=400)
    assert reached(out) == [1, 2, 3]
    assert math.hypot(*v.position[:2]) < 1.0 and not v.armed


def test_auto_needs_a_takeoff_first_when_on_the_ground():
    v = VehicleModel(1, H, params=FAST)
    v.step(3)
    load(v, [item(16, north=10)])
    v.set_mode("GUIDED")
    v.handle(M.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    assert v.set_mode("AUTO") is False and v.mode == "GUIDED"
    assert "Auto: Missing Takeoff Cmd" in texts(v.step(TICK))


def local(msg) -> tuple[float, float]:
    lon = msg.lng if msg.get_type() == "CAMERA_FEEDBACK" else msg.lon
    north, east, _ = to_local(msg.lat / 1e7, lon / 1e7, H.altitude, H.latitude,
                              H.longitude, H.altitude)
    return north, east


def test_cam_trigg_dist_takes_a_picture_every_n_metres_of_the_leg():
    _, out = fly([
        item(22, alt=10), item(206, 10), item(16, 2, north=50), item(206, 0),
        item(16, north=50, east=30), item(21, north=50, east=30, alt=0),
    ])
    spots = [local(m) for m in out if m.get_type() == "CAMERA_FEEDBACK"]
    # Every 10 m (and up to one control step's travel, 0.5 m at 10 m/s, as the check runs
    # once a step) along the 50 m leg north, none on the leg east: a DO item acts on the leg
    # that follows it, so the one after the northern waypoint turns the camera off there.
    norths = [0.0] + [north for north, _ in spots]
    assert [round(b - a) for a, b in itertools.pairwise(norths)] == [10, 10, 10, 10]
    assert all(10.0 <= b - a <= 10.6 for a, b in itertools.pairwise(norths))
    assert all(abs(east) < 0.5 for _, east in spots)


def test_set_home_item_moves_where_the_mission_returns_to():
    lat, lon = at(20, 30)
    v, out = fly([
        item(22, alt=10), item(16, north=20), (0, 179, [0, 0, 0, 0], lat, lon, H.altitude),
        item(20),
    ], limit=400)
    assert reached(out) == [1, 2, 4]
    assert math.dist(v.position[:2], (20.0, 30.0)) < 1.0  # landed at the new home
    homes = [m for m in out if m.get_type() == "HOME_POSITION"]
    assert homes and homes[-1].latitude == lat and homes[-1].longitude == lon


def shoot(frame: int = 2) -> tuple:
    """DO_DIGICAM_CONTROL that takes one picture (param5 = shoot, in the x field)."""
    return frame, M.MAV_CMD_DO_DIGICAM_CONTROL, [0.0] * 4, 1, 0, 0.0


def pictures(out: list) -> list[tuple[float, float]]:
    return [local(m) for m in out if m.get_type() == "CAMERA_FEEDBACK"]


def test_each_do_item_runs_once_per_pass_on_the_leg_after_the_waypoint_before_it():
    _, out = fly([
        item(22, alt=10), item(16, north=10), shoot(), item(16, north=20),
        item(177, 2, 1), item(21, alt=0),
    ])
    assert reached(out) == [1, 2, 4, 2, 4, 6]
    assert texts(out).count("Mission: 3 DigiCamCtrl") == 2  # once in each of the two passes
    spots = pictures(out)
    assert len(spots) == 2  # one picture per pass, not one per item and per NAV command
    # ArduPilot runs the DO items after a waypoint when that waypoint is reached: first the
    # DO item, then the next waypoint starts.
    assert all(abs(north - 10.0) <= 2.1 for north, _ in spots)  # within WPNAV_RADIUS
    said = texts(out)
    assert said.index("Mission: 2 WP") < said.index("Mission: 3 DigiCamCtrl") < said.index(
        "Mission: 4 WP")


def test_only_the_first_do_item_after_the_last_nav_item_runs():
    v, out = fly([item(22, alt=5), item(16, north=5, alt=5), shoot(), shoot()],
                 until=lambda v: v.auto is not None and v.auto.finished)
    out += v.step(2)
    # AP_Mission starts the first and finds no NAV command after it: the mission is complete.
    assert len(pictures(out)) == 1
    assert "Mission: 3 DigiCamCtrl" in texts(out) and "Mission: 4 DigiCamCtrl" not in texts(out)
    assert v.mode == "AUTO" and v.armed and v.position[2] > 4.5  # holds where it ended
    replies = v.handle(M.MAVLink_command_long_message(1, 1, 300, 0, 0, 0, 0, 0, 0, 0, 0))
    assert replies[0].result == M.MAV_RESULT_ACCEPTED  # MISSION_START: it runs again
    assert "Mission: 1 Takeoff" in texts(replies + v.step(1))


def test_mission_start_with_a_first_or_last_item_is_denied_as_on_arducopter():
    v, _ = fly([item(22, alt=5), item(16, north=5, alt=5), item(21, alt=0)],
               until=lambda v: v.auto is not None and v.auto.current == 2)
    for first, last in ((2, 0), (0, 3)):
        (ack, *_) = v.handle(M.MAVLink_command_long_message(1, 1, 300, 0, first, last, 0, 0,
                                                            0, 0, 0))
        assert ack.result == M.MAV_RESULT_DENIED
    assert v.auto.current == 2  # still flying what it flew


def legs(out: list) -> dict[int, list]:
    """GLOBAL_POSITION_INT samples by the NAV item being flown (between two REACHED)."""
    flown: dict[int, list] = {}
    previous = 0
    for m in out:
        if m.get_type() == "MISSION_ITEM_REACHED":
            flown[m.seq], previous = flown.pop(-1, []), m.seq
        elif m.get_type() == "GLOBAL_POSITION_INT" and previous:
            flown.setdefault(-1, []).append(m)
    return flown


def test_change_speed_sets_the_speed_its_type_names():
    change = M.MAV_CMD_DO_CHANGE_SPEED
    _, out = fly([
        item(22, alt=10),
        item(change, 3, 0.5, -1, frame=2), item(16, north=100, alt=10),  # descent speed
        item(change, 1, -1, -1, frame=2), item(16, north=100, alt=4),  # -1: no change
        item(change, 2, 1.0, -1, frame=2), item(16, north=100, alt=14),  # climb speed
        item(change, 0, 3.0, -1, frame=2), item(16, north=0, alt=14),  # horizontal speed
        item(21, alt=0),
    ], limit=400)
    assert reached(out) == [1, 3, 5, 7, 9, 10]
    flown = legs(out)

    def fastest(seq: int) -> tuple[float, float, float]:
        samples = flown[seq]
        return (max(math.hypot(m.vx, m.vy) for m in samples) / 100,
                max(-m.vz for m in samples) / 100, max(m.vz for m in samples) / 100)

    assert fastest(3)[0] == pytest.approx(10.0, abs=0.2)  # WPNAV_SPEED: the descent one is apart
    assert fastest(5)[2] == pytest.approx(0.5, abs=0.02)  # descends at the new descent speed
    # climbs at the new climb speed (the turn up from the descent blends in a little)
    assert fastest(7)[1] == pytest.approx(1.0, abs=0.05)
    assert fastest(9)[0] == pytest.approx(3.0, abs=0.05)  # flies at the new horizontal speed


def test_land_at_a_point_flies_there_at_the_present_altitude_then_descends():
    v, out = fly([item(22, alt=20), item(21, north=30, east=10, alt=0)])
    assert reached(out) == [1, 2]
    approach = [m for m in legs(out)[2] if math.dist(local(m), (30.0, 10.0)) > 1.5]
    assert approach and min(m.relative_alt for m in approach) / 1000 > 19.5
    assert math.dist(v.position, (30.0, 10.0, 0.0)) < 0.5 and v.landed and not v.armed


def test_land_without_a_point_lands_where_the_vehicle_is():
    v, out = fly([item(22, alt=10), item(16, 1, 0.3, north=15, east=-5), item(21, alt=3)])
    assert reached(out) == [1, 2, 3]
    assert math.dist(v.position, (15.0, -5.0, 0.0)) < 0.5 and v.landed and not v.armed


def test_an_roi_item_points_the_nose_at_it_across_waypoints_until_roi_none():
    # As measured on ArduCopter 4.7 SITL: the heading follows the bearing to the ROI along
    # both legs after DO_SET_ROI_LOCATION, and the course again after DO_SET_ROI_NONE.
    north_east = (0.0, 50.0)
    v = VehicleModel(1, H, params=FAST)
    v.step(3)
    load(v, [item(22, alt=10), item(195, north=0, east=50, alt=0), item(16, north=40),
             item(16, north=40, east=-30), item(197, frame=2), item(16, north=0, east=-30),
             item(21, north=0, east=-30, alt=0)])
    assert v.set_mode("GUIDED")
    v.handle(M.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    assert v.set_mode("AUTO")
    off: dict[int, list[float]] = {}  # per item flown: degrees off the bearing to the ROI
    out: list = []
    while v.armed:
        assert v.time < 300
        out += v.step(TICK)
        if math.hypot(*v.velocity[:2]) > 2.0:  # along a leg
            bearing = math.degrees(math.atan2(north_east[1] - v.position[1],
                                              north_east[0] - v.position[0]))
            off.setdefault(v.mission_status()[0], []).append(
                abs((v.heading - bearing + 180) % 360 - 180))
    said = texts(out)
    assert "Mission: 2 SetROILocation" in said and "Mission: 5 SetROINone" in said
    assert max(off[3][5:]) < 5.0 and max(off[4][5:]) < 5.0  # both legs: facing the ROI
    assert min(off[6][10:]) > 20.0  # the leg south after ROI_NONE: its course again


def test_loiter_turns_goes_round_from_the_nearest_edge_facing_the_centre_as_arducopter():
    # ArduCopter 4.7 SITL, the same mission (measured): from the centre it moved out north
    # (its heading) as it went round anticlockwise (param3 -15), at 14.4 m, facing the centre;
    # said "starting circle 1/2", "2/2", "3/2", about 24 s a turn, and left from the edge.
    centre = (40.0, 0.0)
    v = VehicleModel(1, H, params=FAST)
    v.step(3)
    load(v, [item(22, alt=20), item(16, north=40, alt=20), item(18, 2, 0, -15, north=40, alt=20),
             item(16, north=0, east=30, alt=20), item(20)])
    assert v.set_mode("GUIDED")
    v.handle(M.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    assert v.set_mode("AUTO")
    out: list = []
    circling: list[tuple[float, float, float, float]] = []  # time, distance, bearing, off
    while v.mission_status()[0] <= 3:
        assert v.time < 200
        step = v.step(TICK)
        out += step
        said = texts(step)
        if "Mission: starting circle 1/2" in said:
            started = v.time
        if "Mission: starting circle 3/2" in said:
            ended, left_at = v.time, v.position
        if v.mission_status()[0] == 3 and "Mission: starting circle 1/2" in texts(out):
            dn, de = v.position[0] - centre[0], v.position[1] - centre[1]
            facing = math.degrees(math.atan2(-de, -dn))
            circling.append((v.time, math.hypot(dn, de), math.degrees(math.atan2(de, dn)),
                             abs((v.heading - facing + 180) % 360 - 180)))
    assert [t for t in texts(out) if "circle" in t] == [
        "Mission: starting circle 1/2", "Mission: starting circle 2/2",
        "Mission: starting circle 3/2"]
    assert 40.0 < ended - started < 50.0  # 2 turns: 21.8 s each here, about 24 on ArduCopter
    steady = [c for c in circling if c[0] > started + 5.0]
    # 14.1 m here, 14.4 m on ArduCopter: both lag inside the 15 m circle they are given
    assert all(13.5 < c[1] < 15.0 for c in steady) and all(c[3] < 10.0 for c in steady)
    turned = sum((b[2] - a[2] + 180) % 360 - 180 for a, b in itertools.pairwise(steady))
    assert turned < -600.0  # anticlockwise: the bearing from the centre goes down
    assert math.hypot(left_at[0] - centre[0], left_at[1] - centre[1]) > 13.5  # from the edge


def test_loiter_turns_from_outside_flies_to_the_nearest_edge_first():
    # ArduCopter's circle_movetoedge_start: more than 3 m outside, to the closest point.
    v = VehicleModel(1, H, params=FAST)
    v.step(3)
    load(v, [item(22, alt=20), item(18, 1, 0, 15, north=40, east=40, alt=20), item(20)])
    assert v.set_mode("GUIDED")
    v.handle(M.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    assert v.set_mode("AUTO")
    while "Mission: starting circle 1/1" not in texts(v.step(TICK)):
        assert v.time < 100
    edge = (40.0 - 15.0 / math.sqrt(2), 40.0 - 15.0 / math.sqrt(2))  # towards home
    assert math.dist(v.position[:2], edge) < 1.5
