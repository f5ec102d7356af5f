"""The simulator's Rover (sitl/rover.py), stepped by hand: what Rover SITL does."""

from __future__ import annotations

import math

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M
from test_sitl_model import command, run_until, texts
from test_sitl_plane import _item, _upload

from sitl import messages
from sitl.rover import RoverModel
from tml.geo import to_global
from tml.world import DEFAULT_HOME

FAST = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2}
H = DEFAULT_HOME


def rover() -> RoverModel:
    v = RoverModel(1, H, params=FAST)
    v.step(3)
    return v


def armed_in_guided() -> RoverModel:
    v = rover()
    assert v.set_mode("GUIDED")
    assert command(v, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)[0] == M.MAV_RESULT_ACCEPTED
    return v


def target(v: RoverModel, north: float, east: float) -> list:
    lat, lon, _ = to_global(north, east, 0.0, H.latitude, H.longitude, H.altitude)
    return v.handle(M.MAVLink_set_position_target_global_int_message(
        0, 1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000, round(lat * 1e7),
        round(lon * 1e7), 10, 0, 0, 0, 0, 0, 0, 0, 0))


def test_heartbeat_is_a_ground_rover_with_rover_s_modes_and_no_landed_state() -> None:
    v = rover()
    beat = messages.heartbeat(v)
    assert beat.type == M.MAV_TYPE_GROUND_ROVER
    assert mavutil.mode_mapping_bynumber(beat.type)[beat.custom_mode] == "MANUAL"
    assert messages.extended_sys_state(v).landed_state == M.MAV_LANDED_STATE_UNDEFINED
    assert v.params["WP_RADIUS"] == 3 and "WPNAV_SPEED" not in v.params


@pytest.mark.parametrize("cmd", [M.MAV_CMD_NAV_TAKEOFF, M.MAV_CMD_NAV_LAND,
                                 M.MAV_CMD_CONDITION_YAW])
def test_what_a_rover_cannot_do_is_unsupported(cmd: int) -> None:
    assert command(armed_in_guided(), cmd, 90, 0, 1, 0, 0, 0, 10)[0] == \
        M.MAV_RESULT_UNSUPPORTED


def test_guided_drives_to_the_point_at_ground_level_and_stops() -> None:
    v = armed_in_guided()
    target(v, 30, 20)
    out = run_until(v, lambda: math.dist(v.position[:2], (30, 20)) < 0.5
                    and math.hypot(*v.velocity[:2]) < 0.05, 60)
    assert [m.seq for m in out if m.get_type() == "MISSION_ITEM_REACHED"] == [0]
    assert v.position[2] == 0.0 and v.mode == "GUIDED" and v.armed


def test_a_speed_is_taken_only_while_driving_to_a_point() -> None:
    v = armed_in_guided()
    assert command(v, M.MAV_CMD_DO_CHANGE_SPEED, 1, 2, -1)[0] == M.MAV_RESULT_FAILED
    target(v, 60, 0)
    assert command(v, M.MAV_CMD_DO_CHANGE_SPEED, 1, 2, -1)[0] == M.MAV_RESULT_ACCEPTED
    run_until(v, lambda: v.position[0] > 20, 60)
    assert math.hypot(*v.velocity[:2]) == pytest.approx(2.0, abs=0.05)
    # A new mode starts again at WP_SPEED.
    assert v.set_mode("HOLD") and v.set_mode("GUIDED")
    target(v, 120, 0)
    run_until(v, lambda: v.position[0] > 80, 60)
    assert math.hypot(*v.velocity[:2]) == pytest.approx(5.0, abs=0.05)


def test_hold_brakes_gently_and_stops() -> None:
    v = armed_in_guided()
    target(v, 100, 0)
    run_until(v, lambda: v.position[0] > 40, 60)
    assert v.set_mode("HOLD")
    start, stopped_at = v.time, v.position[0]
    run_until(v, lambda: math.hypot(*v.velocity[:2]) == 0.0, 30)
    assert v.time - start == pytest.approx(5.0 / 0.6, abs=0.2)  # 5 m/s at 0.6 m/s²
    assert v.position[0] - stopped_at == pytest.approx(5.0 ** 2 / 1.2, abs=0.5)


def test_rtl_drives_home_and_stops_there_still_armed() -> None:
    v = armed_in_guided()
    target(v, 20, -10)
    run_until(v, lambda: math.dist(v.position[:2], (20, -10)) < 0.5, 60)
    assert command(v, M.MAV_CMD_NAV_RETURN_TO_LAUNCH)[0] == M.MAV_RESULT_ACCEPTED
    out = run_until(v, lambda: v.returned(), 60)
    assert "Reached destination" in texts(out)
    assert math.dist(v.position[:2], (0, 0)) < 0.6
    v.step(30)
    assert v.armed and v.mode == "RTL"  # Rover never disarms by itself


def test_auto_needs_a_mission_then_drives_it_and_stays_stopped_in_auto() -> None:
    v = armed_in_guided()
    _, replies = command(v, M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 10)
    assert "No Mission. Can't set AUTO." in texts(replies) and v.mode == "GUIDED"
    _upload(v, [_item(1, M.MAV_CMD_NAV_WAYPOINT, 30, 0, 0),
                _item(2, M.MAV_CMD_NAV_LOITER_TIME, 30, 20, 0, 5),
                _item(3, M.MAV_CMD_NAV_RETURN_TO_LAUNCH)])
    assert v.set_mode("AUTO")
    out = run_until(v, lambda: v.auto is not None and v.auto.finished, 200)
    assert [m.seq for m in out if m.get_type() == "MISSION_ITEM_REACHED"] == [1, 2, 3]
    v.step(5)
    assert math.dist(v.position[:2], (0, 0)) < 1.0 and v.mode == "AUTO" and v.armed


def test_it_draws_rover_s_current_driving_and_none_stopped() -> None:
    v = armed_in_guided()
    v.step(1)
    assert v.battery.current == 0.0
    target(v, 200, 0)
    run_until(v, lambda: v.position[0] > 50, 60)
    assert v.battery.current == pytest.approx(12.5, abs=0.3)  # measured on Rover SITL at 5 m/s


def test_an_roi_is_accepted_but_does_not_steer_the_rover() -> None:
    # Rover hands DO_SET_ROI to its camera mount (mode_auto's do_set_roi), not its steering.
    v = armed_in_guided()
    lat, lon, _ = to_global(0.0, 50.0, 0.0, H.latitude, H.longitude, H.altitude)
    heading = v.heading
    assert command(v, M.MAV_CMD_DO_SET_ROI_LOCATION, 0, 0, 0, 0, lat, lon, 0)[0] == (
        M.MAV_RESULT_ACCEPTED)
    v.step(5)
    assert v.heading == pytest.approx(heading)
    target(v, 30.0, 0.0)
    run_until(v, lambda: v.position[0] > 20.0, 60)
    assert abs((v.heading + 180) % 360 - 180) < 5.0  # driving north, not toward the ROI


def test_loiter_turns_drives_round_and_goes_on_saying_no_circles() -> None:
    # ArduPilot Rover 4.7 SITL (measured): "Mission: 2 LoitTurns", one turn of 10 m, then on
    # to the next item; unlike ArduCopter it says nothing per circle.
    from test_sitl_auto import item, load

    v = rover()
    load(v, [item(16, north=20, alt=0), item(18, 1, 0, 10, north=20, alt=0),
             item(16, north=0, east=20, alt=0)])
    assert v.set_mode("GUIDED")
    assert command(v, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)[0] == M.MAV_RESULT_ACCEPTED
    assert v.set_mode("AUTO")
    said: list[str] = []
    while "Mission: 3 WP" not in said:
        assert v.time < 120
        said += texts(v.step(0.05))
    assert "Mission: 2 LoitTurns" in said and not [t for t in said if "circle" in t]
