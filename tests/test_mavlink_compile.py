"""Compiling dispatch="mission" actions to MISSION_ITEM_INT items, and flying them in AUTO."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.model import TICK, VehicleModel
from tml.errors import Location
from tml.geo import to_global, to_local
from tml.language.actions import BoundAction, bind
from tml.language.kinds import Kind
from tml.language.model import Action, Argument
from tml.mavlink.compile import (
    CompileError,
    compile_mission,
    glide_items,
)
from tml.mavlink.mission import MissionItem, with_home_placeholder
from tml.patterns import expanding_square
from tml.world import DEFAULT_HOME

H = DEFAULT_HOME
HERE = Location("test.xml", 1)


def act(name: str, **values: str) -> BoundAction:
    return bind(Action(name, tuple(Argument(k, v, None, HERE) for k, v in values.items()),
                       HERE))


def local(item: MissionItem) -> tuple[float, float, float]:
    """Where an item points, back in the local frame (altitude above home)."""
    amsl = item.z if item.frame == M.MAV_FRAME_GLOBAL_INT else H.altitude + item.z
    n, e, u = to_local(item.x / 1e7, item.y / 1e7, amsl, H.latitude, H.longitude, H.altitude)
    return round(n, 1), round(e, 1), round(u, 1)  # 1e-7 degree is about 1 cm


def compiled(*actions: BoundAction, start=(0.0, 0.0, 10.0), heading=0.0):
    return compile_mission(list(actions), H, start, heading)


def test_items_are_numbered_and_mapped_to_their_actions() -> None:
    plan = compiled(act("TAKE_OFF", altitude="15"), act("SET_SPEED", speed="4"),
                    act("SURVEY_AREA", length="10", width="4", spacing="2"),
                    act("RETURN_HOME_AND_LAND"), start=(0, 0, 0))
    assert [i.seq for i in plan.items] == list(range(len(plan.items)))
    commands = [i.command for i in plan.items]
    assert commands == [M.MAV_CMD_NAV_TAKEOFF, M.MAV_CMD_DO_CHANGE_SPEED,
                        *[M.MAV_CMD_NAV_WAYPOINT] * 6, M.MAV_CMD_NAV_RETURN_TO_LAUNCH]
    assert plan.action_index == (0, 1, 2, 2, 2, 2, 2, 2, 3)
    assert plan.action_at(5) == 2 and plan.action_at(99) is None


def test_take_off_climbs_where_the_vehicle_is() -> None:
    item = compiled(act("TAKE_OFF", altitude="15"), start=(3, 4, 0)).items[0]
    assert (item.command, item.frame, item.x, item.y, item.z) == (
        M.MAV_CMD_NAV_TAKEOFF, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0, 0, 15.0)


def test_frame_encoding_float_names_the_frames_without_int() -> None:
    plan = compiled(act("TAKE_OFF", altitude="15", frame_encoding="float"),
                    act("GO_TO_POSITION", latitude="-35.36", longitude="149.16", altitude="600",
                        altitude_reference="amsl", frame_encoding="float"),
                    act("LOITER", turns="2", frame_encoding="float"),
                    act("GO_TO_POSITION", latitude="-35.36", longitude="149.16", altitude="20"),
                    act("SET_SPEED", speed="4"), start=(0, 0, 0))
    assert [i.frame for i in plan.items] == [
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_FRAME_MISSION]
    assert (plan.items[1].x, plan.items[1].y, plan.items[1].z) == (-353600000, 1491600000, 600)


def test_local_points_are_converted_against_home() -> None:
    items = compiled(act("GO_TO_POINT", coordinates="(10, -5, 12)"),
                     act("GO_TO_POINT", relative_coordinates="(1, 1, 1)"),
                     act("MOVE_FROM_HOME", coordinates="(0, 20, 8)")).items
    assert [local(i) for i in items] == [(10, -5, 12), (11, -4, 13), (0, 20, 8)]
    assert {i.frame for i in items} == {M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT}


def test_moves_follow_the_heading_and_yaw_items() -> None:
    items = compiled(act("MOVE_FORWARDS", distance="10"),
                     act("ROTATE_YAW", angle="90"),
                     act("MOVE", direction="left", distance="5"),
                     act("MOVE", coordinates="(0, 0, 5)"), heading=0.0).items
    assert local(items[0]) == (10, 0, 10)
    yaw = items[1]
    assert (yaw.command, yaw.param1, yaw.param3, yaw.param4) == (M.MAV_CMD_CONDITION_YAW,
                                                                 90, 1, 1)
    assert local(items[2]) == (15, 0, 10)  # facing east, left is north
    assert local(items[3]) == (15, 0, 15)


def test_absolute_yaw_and_counter_clockwise_turn() -> None:
    items = compiled(act("ROTATE_YAW", orientation_angle="270"),
                     act("ROTATE_YAW", angle="-45"), act("MOVE_FORWARDS", distance="10")).items
    assert (items[0].param1, items[0].param4) == (270, 0)
    assert (items[1].param1, items[1].param3, items[1].param4) == (45, -1, 1)
    n, e, _ = local(items[2])
    assert (n, e) == pytest.approx((-7.07, -7.07), abs=0.05)  # heading 225: south-west


def test_global_position_frames() -> None:
    lat, lon, _ = to_global(30, 40, 0, H.latitude, H.longitude, H.altitude)
    rel, amsl = compiled(
        act("GO_TO_POSITION", latitude=str(lat), longitude=str(lon), altitude="20"),
        act("GO_TO_POSITION", latitude=str(lat), longitude=str(lon), altitude="610",
            altitude_reference="amsl")).items
    assert (rel.frame, rel.z) == (M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 20)
    assert (amsl.frame, amsl.z) == (M.MAV_FRAME_GLOBAL_INT, pytest.approx(610, abs=1e-3))
    assert abs(rel.x - round(lat * 1e7)) <= 1 and abs(rel.y - round(lon * 1e7)) <= 1


def test_loiter_variants() -> None:
    items = compiled(act("LOITER", turns="2", radius="10"),
                     act("LOITER", coordinates="(5, 5, 20)", duration="30"),
                     act("LOITER", from_home="(0, 10, 15)"),
                     act("RETURN_HOME_AND_LOITER", radius="7")).items
    assert [(i.command, i.param1, i.param3) for i in items] == [
        (M.MAV_CMD_NAV_LOITER_TURNS, 2, 10), (M.MAV_CMD_NAV_LOITER_TIME, 30, 15),
        (M.MAV_CMD_NAV_LOITER_UNLIM, 0, 15), (M.MAV_CMD_NAV_LOITER_UNLIM, 0, 7)]
    assert [local(i) for i in items] == [(0, 0, 10), (5, 5, 20), (0, 10, 15), (0, 0, 15)]


def test_more_turns_than_ardupilot_keeps_in_an_item_are_several_items() -> None:
    plan = compiled(act("LOITER", turns="600", radius="10"), act("LAND"))
    loiters = [i for i in plan.items if i.command == M.MAV_CMD_NAV_LOITER_TURNS]
    assert [(i.param1, local(i)) for i in loiters] == [(255, (0, 0, 10))] * 2 + [(90, (0, 0, 10))]
    assert plan.action_index == (0, 0, 0, 1)


@pytest.mark.parametrize(("arguments", "params"), [
    ({"angle": "-45"}, (45, -1, 1)),  # by an angle: its sign's way
    ({"angle": "270"}, (270, 1, 1)),
    ({"orientation_angle": "315"}, (315, 0, 0)),  # a heading: the shorter way
])
def test_a_yaw_item_turns_by_an_angle_its_way_and_to_a_heading_the_shorter_way(
        arguments: dict[str, str], params: tuple[float, float, float]) -> None:
    # ArduCopter keeps to param3's direction even for a heading (AutoYaw::set_fixed_yaw):
    # clockwise to a heading 45 degrees anticlockwise would turn 315 degrees.
    (yaw,) = compiled(act("ROTATE_YAW", **arguments)).items
    assert yaw.command == M.MAV_CMD_CONDITION_YAW
    assert (yaw.param1, yaw.param3, yaw.param4) == params


def test_landing_point_with_yaw_and_precision() -> None:
    items = compiled(act("LANDING_POINT", coordinates="(8, 2, 5)", yaw="90",
                         precision_mode="opportunistic")).items
    yaw, land = items
    assert (yaw.command, yaw.param1, yaw.param4) == (M.MAV_CMD_CONDITION_YAW, 90, 0)
    assert (land.command, land.param2, land.param4) == (M.MAV_CMD_NAV_LAND, 1, 90)
    assert local(land) == (8, 2, 10)  # at the approach altitude: ArduCopter ignores it


def test_return_home_and_land_is_rtl_unless_yaw_or_precision_is_asked() -> None:
    plain = compiled(act("RETURN_HOME_AND_LAND")).items
    assert [i.command for i in plain] == [M.MAV_CMD_NAV_RETURN_TO_LAUNCH]
    precise = compiled(act("RETURN_HOME_AND_LAND", precision_mode="required")).items
    assert [i.command for i in precise] == [M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LAND]
    assert precise[1].param2 == 2 and local(precise[1]) == (0, 0, 10)


def test_speed_altitude_wait_and_camera_items() -> None:
    items = compiled(act("SET_SPEED", speed="3", speed_type="climb"),
                     act("SET_ALTITUDE", altitude="25"), act("WAIT", duration="4"),
                     act("CAPTURE_PHOTO"), act("CAPTURE_PHOTOS", count="5", interval="1"),
                     act("START_CAPTURING", interval="2"), act("STOP_CAPTURING"),
                     act("STABILIZE"), start=(4, 4, 10)).items
    speed, altitude, wait, photo, photos, start, stop, hold = items
    assert (speed.command, speed.param1, speed.param2) == (M.MAV_CMD_DO_CHANGE_SPEED, 2, 3)
    assert altitude.command == M.MAV_CMD_NAV_WAYPOINT and local(altitude) == (4, 4, 25)
    assert (wait.command, wait.param1) == (M.MAV_CMD_NAV_DELAY, 4)
    assert (photo.command, photo.x) == (M.MAV_CMD_DO_DIGICAM_CONTROL, 1)
    assert (photos.command, photos.param2, photos.param3) == (M.MAV_CMD_IMAGE_START_CAPTURE, 1, 5)
    assert (start.param2, start.param3) == (2, 0)
    assert stop.command == M.MAV_CMD_IMAGE_STOP_CAPTURE
    assert (hold.command, hold.param1) == (M.MAV_CMD_NAV_DELAY, 0)


def test_set_home_here_and_elsewhere() -> None:
    here, there = compiled(act("SET_HOME"), act("SET_HOME", latitude="-35.1",
                                                 longitude="149.2", altitude="600")).items
    assert (here.command, here.param1) == (M.MAV_CMD_DO_SET_HOME, 1)
    assert (there.param1, there.frame, there.x, there.y, there.z) == (
        0, M.MAV_FRAME_GLOBAL_INT, -351000000, 1492000000, 600)


def test_gripper_items() -> None:
    grab, release = compiled(act("PICK_UP_ITEM"), act("DROP_ITEM")).items
    assert (grab.command, grab.param2) == (M.MAV_CMD_DO_GRIPPER, M.GRIPPER_ACTION_GRAB)
    assert release.param2 == M.GRIPPER_ACTION_RELEASE


def test_survey_from_a_base_point_and_altitude() -> None:
    items = compiled(act("SURVEY_AREA", length="10", width="10", spacing="10",
                         direction="SOUTH_EAST", coordinates="(5, 5, 0)", altitude="40")).items
    assert [local(i) for i in items] == [(5, 5, 40), (-5, 5, 40), (-5, 15, 40), (5, 15, 40)]


def test_survey_from_a_global_base_point_is_relative_to_home() -> None:
    # SURVEY_AREA has no altitude_reference: its altitude is above home.
    lat, lon, _ = to_global(5, 5, 0, H.latitude, H.longitude, H.altitude)
    items = compiled(act("SURVEY_AREA", length="10", width="10", spacing="10",
                         direction="SOUTH_EAST", latitude=str(lat), longitude=str(lon),
                         altitude="40")).items
    assert {i.frame for i in items} == {M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT}
    assert [local(i) for i in items] == [(5, 5, 40), (-5, 5, 40), (-5, 15, 40), (5, 15, 40)]


def test_explore_space_flies_the_expanding_square_and_returns() -> None:
    items = compiled(act("EXPLORE_SPACE", radius="3", spacing="1"), start=(1, 1, 2)).items
    assert [local(i) for i in items] == [
        (p[0], p[1], p[2]) for p in expanding_square((1.0, 1.0, 2.0), 3.0, 1.0)]
    assert local(items[-1]) == (1, 1, 2)


def test_actions_without_items_and_unresolved_labels_are_refused() -> None:
    with pytest.raises(CompileError, match="MEMORIZE_POINT cannot be flown"):
        compiled(act("MEMORIZE_POINT", coordinates="(0, 0, 0)"))
    labelled = bind(Action("GO_TO_POINT", (Argument("coordinates", None, "door", HERE),), HERE))
    with pytest.raises(CompileError, match="label 'door'"):
        compiled(labelled)


# --- the items fly on the simulator's AUTO executor ----------------------------------------

FAST = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2}


def fly(items: tuple[MissionItem, ...], limit: float = 400.0,
        until_disarmed: bool = True) -> tuple[VehicleModel, list]:
    """Upload and fly ``items`` in AUTO until the vehicle disarms (or for ``limit`` s)."""
    v = VehicleModel(1, H, params=FAST)
    v.step(3)
    everything = with_home_placeholder(list(items))
    replies = v.handle(M.MAVLink_mission_count_message(1, 1, len(everything), 0))
    while replies[-1].get_type() == "MISSION_REQUEST":
        i = everything[replies[-1].seq]
        replies = v.handle(M.MAVLink_mission_item_int_message(
            1, 1, i.seq, i.frame, i.command, 0, 1, i.param1, i.param2, i.param3, i.param4,
            i.x, i.y, i.z, 0))
    assert replies[-1].type == M.MAV_MISSION_ACCEPTED
    assert v.set_mode("GUIDED")
    v.handle(M.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    assert v.armed and v.set_mode("AUTO")
    out: list = []
    while v.armed if until_disarmed else v.time < limit:
        assert v.time < limit
        out += v.step(TICK)
    return v, out


def test_compiled_survey_flies_and_lands_at_the_pad() -> None:
    plan = compiled(act("TAKE_OFF", altitude="10"),
                    act("SURVEY_AREA", length="20", width="10", spacing="5",
                        direction="NORTH_EAST"),
                    act("LANDING_POINT", coordinates="(-5, -5, 0)"), start=(0, 0, 0))
    v, out = fly(plan.items)
    reached = [m.seq - 1 for m in out if m.get_type() == "MISSION_ITEM_REACHED"]
    assert [plan.action_at(s) for s in reached] == [0, *[1] * 6, 2]
    assert v.landed and math.dist(v.position[:2], (-5, -5)) < 1.0


def test_docs_table_names_every_action() -> None:
    from pathlib import Path

    from tml.language.actions import CATALOGUE

    doc = (Path(__file__).parent.parent / "docs" / "run.md").read_text()
    table = doc[doc.index("## `dispatch=\"mission\"`"):]
    missing = [spec.name for spec in CATALOGUE if spec.name not in table]
    assert not missing, f"docs/run.md's item table misses {missing}"


def test_several_trailing_commands_get_a_closing_waypoint_so_all_of_them_run() -> None:
    # ArduPilot ends a mission at the first DO item after the last NAV item.
    two = compiled(act("GO_TO_POINT", coordinates="(10, 0, 10)"), act("CAPTURE_PHOTO"),
                   act("SET_SPEED", speed="3"))
    commands = [i.command for i in two.items]
    assert commands == [M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_DO_DIGICAM_CONTROL,
                        M.MAV_CMD_DO_CHANGE_SPEED, M.MAV_CMD_NAV_WAYPOINT]
    assert local(two.items[-1]) == (10.0, 0.0, 10.0) and two.action_index[-1] == 2
    one = compiled(act("GO_TO_POINT", coordinates="(10, 0, 10)"), act("CAPTURE_PHOTO"))
    assert [i.command for i in one.items] == [M.MAV_CMD_NAV_WAYPOINT,
                                              M.MAV_CMD_DO_DIGICAM_CONTROL]


def test_trailing_commands_all_run_in_the_simulator() -> None:
    plan = compiled(act("TAKE_OFF", altitude="5"), act("CAPTURE_PHOTO"),
                    act("CAPTURE_PHOTO"), act("CAPTURE_PHOTO"), start=(0, 0, 0))
    _, out = fly(plan.items, until_disarmed=False, limit=60.0)
    said = [m.text for m in out if m.get_type() == "STATUSTEXT"]
    assert [t for t in said if t.endswith("DigiCamCtrl")] == [
        "Mission: 2 DigiCamCtrl", "Mission: 3 DigiCamCtrl", "Mission: 4 DigiCamCtrl"]
    # One picture only, as on ArduCopter SITL: the shutter is held 0.1 s after a picture
    # and the next two items come within it (docs/simulator.md, "Camera").
    assert sum(m.get_type() == "CAMERA_FEEDBACK" for m in out) == 1


# --- a fixed-wing lands along an approach, as ArduPlane does -------------------------------

def test_a_fixed_wing_lands_straight_ahead_with_a_landing_sequence() -> None:
    mission = compile_mission([act("LAND")], H, (100.0, 0.0, 40.0), 90.0, Kind.FIXED_WING)
    waypoint, land = mission.items
    assert (waypoint.command, land.command) == (M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LAND)
    assert local(waypoint) == (100.0, 0.0, 40.0)
    assert local(land) == (100.0, 320.0, 0.0)  # 8 m along for each metre down


@pytest.mark.parametrize(("action", "touchdown"), [
    (act("RETURN_HOME_AND_LAND"), (0.0, 0.0, 0.0)),
    (act("LANDING_POINT", coordinates="(50, 0, 0)"), (50.0, 0.0, 0.0))])
def test_a_fixed_wing_lands_at_a_point_from_the_side_it_comes_from(action, touchdown) -> None:
    mission = compile_mission([action], H, (600.0, 0.0, 30.0), 0.0, Kind.FIXED_WING)
    approach, land = (local(item) for item in mission.items)
    assert land == touchdown
    assert approach == (touchdown[0] + 240.0, 0.0, 30.0)
    assert M.MAV_CMD_NAV_RETURN_TO_LAUNCH not in [i.command for i in mission.items]


def test_glide_items_are_the_adapter_s_landing_sequence() -> None:
    items = glide_items(H, (0.0, 300.0, 50.0), 0.0, (0.0, 0.0, 0.0))
    assert [local(i) for i in items] == [(0.0, 400.0, 50.0), (0.0, 0.0, 0.0)]
    assert [i.seq for i in items] == [0, 1]


def test_a_ground_vehicle_returns_with_rtl() -> None:
    mission = compile_mission([act("RETURN_HOME_AND_LAND")], H, (10.0, 0.0, 0.0), 0.0,
                              Kind.GROUND)
    assert [i.command for i in mission.items] == [M.MAV_CMD_NAV_RETURN_TO_LAUNCH]


def test_a_position_far_from_home_is_the_one_written() -> None:
    # Through the local frame a point 8,000 km from home moved by 3,000 km; the item
    # carries the 1e-7-degree integers of what was written.
    go = act("GO_TO_POSITION", latitude="36.3244251", longitude="138.6379423",
                       altitude="20", altitude_reference="amsl")
    loiter = act("LOITER", latitude="-35.1234567", longitude="150.7654321",
                           altitude="30", turns="2")
    items = compiled(go, loiter).items
    assert [(i.x, i.y, i.z) for i in items] == [(363244251, 1386379423, 20.0),
                                                (-351234567, 1507654321, 30.0)]


def test_a_raw_mission_item_is_that_item() -> None:
    raw = act("MISSION_ITEM", command="MAV_CMD_NAV_SPLINE_WAYPOINT",
                        frame="GLOBAL_TERRAIN_ALT", param1="5", param4="NaN",
                        param5="-35.3632621", param6="149.1652374", param7="NaN",
                        autocontinue="no")
    jump = act("MISSION_ITEM", command="177", frame="2", param1="1", param2="3")
    first, second = compiled(raw, jump).items
    assert (first.command, first.frame, first.param1, first.x, first.y, first.autocontinue) \
        == (82, 10, 5.0, -353632621, 1491652374, 0)
    assert math.isnan(first.param4) and math.isnan(first.z)
    assert (second.command, second.frame, second.param1, second.param2, second.x) \
        == (177, 2, 1.0, 3.0, 0)


def test_trailing_raw_items_are_not_closed_with_a_waypoint() -> None:
    take_off = act("TAKE_OFF")
    servo = [act("MISSION_ITEM", command="DO_SET_SERVO", frame="MISSION",
                           param1="9", param2=str(pwm)) for pwm in (1100, 1900)]
    items = compiled(take_off, *servo, start=(0, 0, 0)).items
    assert [i.command for i in items] == [22, 183, 183]
