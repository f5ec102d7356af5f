"""The simulator's ArduPlane (sitl/plane.py), stepped by hand: what ArduPlane SITL does."""

from __future__ import annotations

import math

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M
from test_sitl_model import command, run_until, texts

from sitl import messages
from sitl.model import TICK
from sitl.plane import PlaneModel
from tml.geo import to_global
from tml.mavlink.mission import MissionItem
from tml.world import DEFAULT_HOME

FAST = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2}
H = DEFAULT_HOME


def plane(**params: float) -> PlaneModel:
    v = PlaneModel(1, H, params={**FAST, **params})
    v.step(3)
    return v


def airborne(altitude: float = 40.0) -> PlaneModel:
    v = plane(TKOFF_ALT=altitude)
    assert v.set_mode("TAKEOFF")
    assert command(v, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)[0] == M.MAV_RESULT_ACCEPTED
    run_until(v, lambda: v.position[2] >= altitude - 0.01, 60)
    return v


def reposition(v: PlaneModel, north: float, east: float, up: float, radius: float = 0.0,
               ccw: bool = False) -> int:
    lat, lon, _ = to_global(north, east, 0.0, H.latitude, H.longitude, H.altitude)
    result, _ = command(v, M.MAV_CMD_DO_REPOSITION, -1, M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE,
                        radius, 1.0 if ccw else math.nan, lat, lon, up)
    return result


def distances(v: PlaneModel, centre: tuple[float, float], seconds: float) -> list[float]:
    found = []
    for _ in range(round(seconds / TICK)):
        v.step(TICK)
        found.append(math.dist(v.position[:2], centre))
    return found


def test_heartbeat_is_a_fixed_wing_with_arduplane_s_modes() -> None:
    v = plane()
    beat = messages.heartbeat(v)
    assert beat.type == M.MAV_TYPE_FIXED_WING
    assert mavutil.mode_mapping_bynumber(beat.type)[beat.custom_mode] == "MANUAL"
    assert "WPNAV_SPEED" not in v.params and v.params["AIRSPEED_CRUISE"] == 22


def test_no_take_off_in_guided_nor_a_land_mode() -> None:
    v = plane()
    assert v.set_mode("GUIDED")
    assert command(v, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)[0] == M.MAV_RESULT_ACCEPTED
    assert command(v, M.MAV_CMD_NAV_TAKEOFF, *[0] * 6, 40)[0] == M.MAV_RESULT_FAILED
    assert command(v, M.MAV_CMD_NAV_LAND)[0] == M.MAV_RESULT_UNSUPPORTED
    assert command(v, M.MAV_CMD_CONDITION_YAW, 90, 0, 1, 0)[0] == M.MAV_RESULT_UNSUPPORTED
    assert reposition(v, 300, 0, 50) == M.MAV_RESULT_ACCEPTED  # taken; nothing moves
    v.step(20)
    assert v.landed and v.position == (0.0, 0.0, 0.0)


def test_takeoff_mode_climbs_along_the_heading_then_circles_ahead() -> None:
    v = plane(TKOFF_ALT=40)
    assert v.set_mode("TAKEOFF")
    _, replies = command(v, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert any(t.startswith("Takeoff to 40m for 200.0m heading") for t in texts(replies))
    out = run_until(v, lambda: v.position[2] >= 40 - 0.01, 60)
    assert "Takeoff" in texts(out) and not v.landed
    heading = math.radians(H.heading)
    ahead = (200 * math.cos(heading), 200 * math.sin(heading))
    circle = distances(v, ahead, 60)[-400:]
    assert max(circle) < 100 and min(circle) > 60  # WP_LOITER_RAD 80
    assert v.position[2] == pytest.approx(40.0, abs=0.5)


def test_it_never_hovers_and_turns_no_tighter_than_its_bank_allows() -> None:
    v = airborne()
    # Asked for a 5 m circle, it flies the tightest it can at 22 m/s and 65 degrees of bank.
    assert reposition(v, 0, 300, 40, radius=5) == M.MAV_RESULT_ACCEPTED
    run_until(v, lambda: math.dist(v.position[:2], (0, 300)) < 40, 60)
    circle = distances(v, (0, 300), 30)
    tightest = 22 ** 2 / (9.81 * math.tan(math.radians(65)))
    assert min(circle) > tightest - 3
    speeds = []
    for _ in range(20):
        v.step(1)
        speeds.append(math.hypot(*v.velocity[:2]))
    assert min(speeds) > 20


@pytest.mark.parametrize("ccw", [False, True])
def test_do_reposition_circles_the_point_at_the_radius_asked(ccw: bool) -> None:
    v = airborne()
    assert reposition(v, 400, 0, 60, radius=100, ccw=ccw) == M.MAV_RESULT_ACCEPTED
    assert v.mode == "GUIDED"
    run_until(v, lambda: math.dist(v.position[:2], (400, 0)) < 120, 90)
    v.step(30)
    before = math.atan2(v.position[1], v.position[0] - 400)
    circle = distances(v, (400, 0), 4)
    after = math.atan2(v.position[1], v.position[0] - 400)
    assert all(85 < d < 115 for d in circle) and v.position[2] == pytest.approx(60, abs=1)
    turning = (after - before + math.pi) % (2 * math.pi) - math.pi
    assert (turning < 0) == ccw  # clockwise: the bearing from the centre grows


def test_a_position_target_changes_only_the_altitude() -> None:
    v = airborne()
    assert v.set_mode("GUIDED")
    here = v.position
    lat, lon, _ = to_global(0, 600, 0, H.latitude, H.longitude, H.altitude)
    v.handle(M.MAVLink_set_position_target_global_int_message(
        0, 1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000, round(lat * 1e7),
        round(lon * 1e7), 55, 0, 0, 0, 0, 0, 0, 0, 0))
    run_until(v, lambda: v.position[2] > 54.9, 30)
    assert math.dist(v.position[:2], here[:2]) < 200


def test_rtl_climbs_to_rtl_altitude_and_circles_home_without_landing() -> None:
    v = airborne()
    assert v.set_mode("RTL")
    run_until(v, lambda: v.position[2] > 99.9, 90)
    circle = distances(v, (0, 0), 60)[-300:]
    assert max(circle) < 100 and v.armed and not v.landed


def _item(seq: int, command: int, north: float = 0.0, east: float = 0.0, up: float = 0.0,
          *params: float) -> MissionItem:
    lat, lon, _ = to_global(north, east, 0.0, H.latitude, H.longitude, H.altitude)
    p = [*params, 0.0, 0.0, 0.0, 0.0][:4]
    return MissionItem(seq, M.MAV_FRAME_GLOBAL_RELATIVE_ALT, command, 0, 1, *p,
                       x=round(lat * 1e7), y=round(lon * 1e7), z=up)


def _upload(v: PlaneModel, items: list[MissionItem]) -> None:
    v.handle(M.MAVLink_mission_count_message(1, 1, len(items) + 1, 0))
    for item in [_item(0, M.MAV_CMD_NAV_WAYPOINT), *items]:
        v.handle(M.MAVLink_mission_item_int_message(
            1, 1, item.seq, item.frame, item.command, 0, 1, item.param1, item.param2,
            item.param3, item.param4, item.x, item.y, item.z, 0))
    assert len(v.mission_items) == len(items) + 1


def test_an_auto_mission_takes_off_circles_and_glides_down_to_its_touchdown() -> None:
    v = plane()
    _upload(v, [_item(1, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 40, 15),
                _item(2, M.MAV_CMD_NAV_WAYPOINT, 400, 0, 40),
                _item(3, M.MAV_CMD_NAV_LOITER_TURNS, 400, 300, 40, 1, 0, 60),
                _item(4, M.MAV_CMD_NAV_WAYPOINT, -300, 0, 30),
                _item(5, M.MAV_CMD_NAV_LAND, 0, 0, 0)])
    assert v.set_mode("AUTO")
    assert command(v, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)[0] == M.MAV_RESULT_ACCEPTED
    out = run_until(v, lambda: not v.armed, 600)
    reached = [m.seq for m in out if m.get_type() == "MISSION_ITEM_REACHED"]
    assert reached == [1, 2, 3, 4, 5]
    assert "Auto disarmed" in texts(out)
    assert math.dist(v.position[:2], (0, 0)) < 120  # a float and a roll-out past it
    # Home follows the disarmed plane, as ArduPlane resets it until it is armed again.
    v.step(1)
    home = v.home_local()
    assert math.dist(home[:2], v.position[:2]) <= 1.0


def test_it_disarms_land_disarmdelay_after_stopping_on_the_ground() -> None:
    v = airborne(30)
    _upload(v, [_item(1, M.MAV_CMD_NAV_WAYPOINT, *v.position[:2], 30),
                _item(2, M.MAV_CMD_NAV_LAND, v.position[0] + 300, v.position[1], 0)])
    assert v.set_mode("AUTO")
    run_until(v, lambda: v.landed, 120)
    touchdown = v.position
    run_until(v, lambda: v.velocity == (0.0, 0.0, 0.0), 60)
    stopped = v.time
    run_until(v, lambda: not v.armed, 60)
    assert v.time - stopped == pytest.approx(20.0, abs=0.2)
    assert math.dist(touchdown[:2], (v.position[0], v.position[1])) < 120


def test_a_mission_ending_in_the_air_switches_to_rtl() -> None:
    v = airborne(30)
    _upload(v, [_item(1, M.MAV_CMD_NAV_WAYPOINT, 300, 0, 30)])
    assert v.set_mode("AUTO")
    out = run_until(v, lambda: v.mode == "RTL", 120)
    assert "Mission complete, changing mode to RTL" in texts(out)


def test_it_draws_arduplane_s_current_in_cruise() -> None:
    v = airborne(40)
    v.step(10)
    assert v.battery.current == pytest.approx(11.4, abs=0.3)  # measured on ArduPlane SITL
