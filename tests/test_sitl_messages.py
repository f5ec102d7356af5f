"""The message builders, fed a fake vehicle state: what a ground station reads from them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl import messages
from sitl.modes import COPTER, PLANE, ROVER, ModeTable
from sitl.physics import Battery
from tml.geo import to_global
from tml.world import DEFAULT_HOME, Home

H = DEFAULT_HOME


@dataclass
class State:
    """A vehicle state with everything :class:`sitl.messages.Source` reads."""

    system_id: int = 1
    mav_type: int = M.MAV_TYPE_QUADROTOR
    mode_table: ModeTable = COPTER
    reports_landed_state: bool = True
    time: float = 50.0
    mode: str = "STABILIZE"
    armed: bool = False
    landed: bool = True
    origin: Home = H
    home: Home = H
    battery: Battery = field(default_factory=lambda: Battery(3300.0))
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    heading: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    gps_fixed: bool = True
    booted: bool = True
    origin_set: bool = True
    position_ok: bool = True
    prearm_ok: bool = True
    landing: bool = False
    in_failsafe: bool = False
    mission: tuple[int, int, int] = (0, 0, M.MISSION_STATE_NO_MISSION)
    target: tuple | None = None  # what guided_target() gives

    def global_position(self) -> tuple[float, float, float]:
        return to_global(*self.position, H.latitude, H.longitude, H.altitude)

    def home_local(self) -> tuple[float, float, float]:
        return (0.0, 0.0, self.home.altitude - H.altitude)

    def gps_noise(self) -> float:
        return 0.0

    def mission_status(self) -> tuple[int, int, int]:
        return self.mission

    def guided_target(self) -> tuple | None:
        return self.target


def test_heartbeat_of_a_plane_and_a_rover_has_their_type_and_mode_numbers():
    plane = messages.heartbeat(State(mav_type=M.MAV_TYPE_FIXED_WING, mode_table=PLANE,
                                     mode="TAKEOFF"))
    assert plane.type == M.MAV_TYPE_FIXED_WING
    assert mavutil.mode_mapping_bynumber(plane.type)[plane.custom_mode] == "TAKEOFF"
    rover = messages.heartbeat(State(mav_type=M.MAV_TYPE_GROUND_ROVER, mode_table=ROVER,
                                     mode="HOLD"))
    assert mavutil.mode_mapping_bynumber(rover.type)[rover.custom_mode] == "HOLD"


def test_a_rover_reports_no_landed_state():
    state = messages.extended_sys_state(State(reports_landed_state=False, armed=True))
    assert state.landed_state == M.MAV_LANDED_STATE_UNDEFINED


def test_heartbeat_names_the_mode_and_shows_armed_guided_and_failsafe():
    beat = messages.heartbeat(State(mode="GUIDED", armed=True))
    assert mavutil.mode_mapping_acm[beat.custom_mode] == "GUIDED"
    assert beat.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
    assert beat.base_mode & M.MAV_MODE_FLAG_GUIDED_ENABLED
    assert beat.system_status == M.MAV_STATE_ACTIVE
    idle = messages.heartbeat(State())
    assert not idle.base_mode & (M.MAV_MODE_FLAG_SAFETY_ARMED | M.MAV_MODE_FLAG_GUIDED_ENABLED)
    assert idle.system_status == M.MAV_STATE_STANDBY
    assert messages.heartbeat(State(in_failsafe=True)).system_status == M.MAV_STATE_CRITICAL


def test_global_position_is_zero_before_the_fix_and_relative_to_home_after():
    early = messages.global_position_int(State(gps_fixed=False, origin_set=False,
                                               position_ok=False, position=(5.0, 0.0, 3.0)))
    assert (early.lat, early.lon) == (0, 0) and early.relative_alt == 3000
    fixed = messages.global_position_int(State(origin_set=False, position_ok=False))
    assert fixed.lat == round(H.latitude * 1e7)  # ArduCopter: from the GPS fix on
    north = messages.global_position_int(State(position=(100.0, 0.0, 12.0), heading=90.0,
                                               home=Home(H.latitude, H.longitude,
                                                         H.altitude + 2.0)))
    assert north.lat > round(H.latitude * 1e7) and north.lon == pytest.approx(
        H.longitude * 1e7, abs=2)
    assert north.relative_alt == 10000 and north.hdg == 9000
    assert north.alt == pytest.approx((H.altitude + 12.0) * 1000, abs=2)  # mm; the curvature


def test_gps_has_no_fix_until_it_locks():
    assert messages.gps_raw_int(State(gps_fixed=False)).fix_type == 0  # as ArduCopter SITL
    fix = messages.gps_raw_int(State(velocity=(0.0, 2.0, 0.0)))
    assert fix.fix_type == 3 and fix.vel == 200 and fix.cog == 9000
    assert not messages.sys_status(State(gps_fixed=False)).onboard_control_sensors_health & (
        M.MAV_SYS_STATUS_SENSOR_GPS)
    prearm = M.MAV_SYS_STATUS_PREARM_CHECK
    assert messages.sys_status(State()).onboard_control_sensors_health & prearm
    waiting = messages.sys_status(State(prearm_ok=False))
    assert waiting.onboard_control_sensors_present & prearm
    assert not waiting.onboard_control_sensors_health & prearm


def test_local_position_and_attitude_use_ned_and_signed_yaw():
    local = messages.local_position_ned(State(position=(1.0, 2.0, 3.0), velocity=(0, 0, 1.5)))
    assert (local.x, local.y, local.z, local.vz) == (1.0, 2.0, -3.0, -1.5)
    att = messages.attitude(State(heading=270.0, roll=0.5, pitch=-0.25))
    assert att.yaw == pytest.approx(-math.pi / 2) and (att.roll, att.pitch) == (0.5, -0.25)


@pytest.mark.parametrize("state, landed_state", [
    (State(), M.MAV_LANDED_STATE_ON_GROUND),
    (State(landed=False, landing=True, position=(0, 0, 5)), M.MAV_LANDED_STATE_LANDING),
    (State(landed=False, position=(0, 0, 1), velocity=(0, 0, 1)), M.MAV_LANDED_STATE_TAKEOFF),
    (State(landed=False, position=(0, 0, 10)), M.MAV_LANDED_STATE_IN_AIR),
])
def test_landed_state(state, landed_state):
    assert messages.extended_sys_state(state).landed_state == landed_state


def test_home_and_origin_exist_once_the_ekf_has_its_origin():
    for builder in (messages.home_position, messages.gps_global_origin):
        assert builder(State(origin_set=False, position_ok=False)) is None
        found = builder(State(position_ok=False))
        assert (found.latitude, found.longitude) == (round(H.latitude * 1e7),
                                                     round(H.longitude * 1e7))
    assert messages.ekf_status_report(State()).flags & M.EKF_POS_HORIZ_ABS
    assert not messages.ekf_status_report(State(position_ok=False)).flags & M.EKF_POS_HORIZ_ABS


def test_battery_and_mission_state_are_reported_as_they_are():
    state = State(mission=(3, 5, M.MISSION_STATE_ACTIVE))
    state.battery.drain(360.0, 16.5)  # 1650 mAh of 3300
    status = messages.battery_status(state)
    assert status.battery_remaining == 50 and status.current_consumed == 1650
    assert messages.sys_status(state).battery_remaining == 50
    current = messages.mission_current(state)
    assert (current.seq, current.total, current.mission_state) == (3, 5, M.MISSION_STATE_ACTIVE)


def test_build_serves_requests_by_id_and_pictures_say_where_they_were_taken():
    assert messages.build(M.MAVLINK_MSG_ID_HEARTBEAT, State()).get_type() == "HEARTBEAT"
    assert messages.build(M.MAVLINK_MSG_ID_HOME_POSITION, State(origin_set=False)) is None
    assert messages.build(M.MAVLINK_MSG_ID_SYSTEM_TIME, State()).time_boot_ms == 50000
    assert messages.build(99999, State()) is None
    version = messages.build(M.MAVLINK_MSG_ID_AUTOPILOT_VERSION, State())
    assert version.capabilities & M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    picture = messages.camera_feedback(State(position=(0.0, 0.0, 20.0), heading=-90.0), 4)
    assert (picture.img_idx, picture.cam_idx, picture.alt_rel, picture.yaw) == (4, 0, 20.0, 270.0)
    assert (picture.lat, picture.lng) == (round(H.latitude * 1e7), round(H.longitude * 1e7))
    assert picture.alt_msl == pytest.approx(H.altitude + 20.0)
    assert (picture.flags, picture.completed_captures) == (M.CAMERA_FEEDBACK_PHOTO, 0)


def test_addressing_helpers():
    text = messages.statustext(6, "x" * 80)
    assert len(text.text) == 50
    stamped = messages.stamp(text, 3, 191)
    assert (stamped.get_srcSystem(), stamped.get_srcComponent()) == (3, 191)
    for target, expected in (((0, 0), True), ((3, 1), True), ((3, 191), False), ((4, 1), False)):
        msg = M.MAVLink_command_long_message(*target, 400, 0, 0, 0, 0, 0, 0, 0, 0)
        assert messages.targets(msg, 3, 1) is expected


def test_position_targets_carry_guideds_point_or_velocity_and_nothing_without_one():
    none = State(mode="GUIDED")
    assert messages.position_target_global_int(none) is None
    assert messages.position_target_local_ned(none) is None
    point = State(target=((30.0, -20.0, 15.0), (47.5, 8.5, 615.0)))
    glob = messages.position_target_global_int(point)
    assert (glob.coordinate_frame, glob.type_mask, glob.lat_int, glob.lon_int, glob.alt) == (
        M.MAV_FRAME_GLOBAL, 65016, 475_000_000, 85_000_000, 615.0)
    local = messages.position_target_local_ned(point)
    assert (local.type_mask, local.x, local.y, local.z) == (3576, 30.0, -20.0, -15.0)
    moving = State(target=((3.0, 4.0, 1.0), None))
    assert messages.position_target_global_int(moving) is None
    local = messages.position_target_local_ned(moving)
    assert (local.type_mask, local.vx, local.vy, local.vz) == (3079, 3.0, 4.0, -1.0)
