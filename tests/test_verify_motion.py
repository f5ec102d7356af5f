"""Abstract execution of single actions: positions, times and battery predicted."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from tml import geo
from tml.errors import Location
from tml.language.actions import BoundAction, bind
from tml.language.model import Action, Argument
from tml.patterns import circle_chord, stop_to_stop
from tml.verify.motion import (
    FlightModel,
    PredictedState,
)
from tml.verify.profile import load_profile
from tml.world import DEFAULT_HOME, World

# Round numbers: 5 m/s, climb 2.5 m/s, descent 1.5 m/s, yaw 90 deg/s; moves start and stop
# at once, landings at the descent rate, no wait over home (tested apart below).
PROFILE = replace(load_profile("quadcopter"), cruise_speed=5.0, acceleration=0.0,
                  land_speed=0.0, land_altitude=0.0, return_hover=0.0)
MODEL = FlightModel(PROFILE, World())
HERE = Location("test.xml", 3)
FLYING = PredictedState(position=(0.0, 0.0, 10.0), flying=True)


def action(name: str, labels: dict[str, str] | None = None, **values: str) -> BoundAction:
    arguments = [Argument(k, v, None, HERE) for k, v in values.items()]
    arguments += [Argument(k, None, v, HERE) for k, v in (labels or {}).items()]
    return bind(Action(name, tuple(arguments), HERE))


def test_take_off_climbs_to_the_profile_altitude_at_the_climb_rate() -> None:
    step = MODEL.step(action("TAKE_OFF"), PredictedState())
    assert step.after.position == (0.0, 0.0, PROFILE.takeoff_altitude)
    assert step.after.flying
    assert step.duration == pytest.approx(PROFILE.takeoff_altitude / PROFILE.climb_rate)
    assert step.energy == pytest.approx(max(PROFILE.battery_per_metre * 10,
                                            PROFILE.battery_per_second * step.duration))


def test_take_off_with_an_altitude_and_when_flying() -> None:
    assert MODEL.step(action("TAKE_OFF", altitude="25"), PredictedState()).after.position[2] == 25
    step = MODEL.step(action("TAKE_OFF", altitude="25"), FLYING)
    assert step.after == FLYING and step.notes


def test_go_to_point_costs_per_metre_or_per_second_whichever_is_more() -> None:
    step = MODEL.step(action("GO_TO_POINT", coordinates="(30, 40, 10)"), FLYING)
    assert step.after.position == (30.0, 40.0, 10.0)
    assert step.distance == pytest.approx(50.0)
    assert step.duration == pytest.approx(50.0 / PROFILE.cruise_speed)
    assert step.energy == pytest.approx(max(50.0 * PROFILE.battery_per_metre,
                                            step.duration * PROFILE.battery_per_second))
    per_metre = FlightModel(replace(PROFILE, battery_per_metre=1.0))
    assert per_metre.step(action("GO_TO_POINT", coordinates="(30, 40, 10)"),
                          FLYING).energy == pytest.approx(50.0)


def test_set_speed_changes_the_following_legs_capped_at_max_speed() -> None:
    fast = MODEL.step(action("SET_SPEED", speed="100"), FLYING).after
    step = MODEL.step(action("GO_TO_POINT", relative_coordinates="(150, 0, 0)"), fast)
    assert step.duration == pytest.approx(150.0 / PROFILE.max_speed)


def test_move_directions_follow_the_heading() -> None:
    facing_east = PredictedState(position=(0.0, 0.0, 10.0), flying=True, heading=90.0)
    ahead = MODEL.step(action("MOVE_FORWARDS", distance="10"), facing_east).after.position
    left = MODEL.step(action("MOVE", direction="left", distance="10"), facing_east).after.position
    up = MODEL.step(action("MOVE", direction="up", distance="5"), facing_east).after.position
    assert ahead == pytest.approx((0.0, 10.0, 10.0))
    assert left == pytest.approx((10.0, 0.0, 10.0))
    assert up == pytest.approx((0.0, 0.0, 15.0))


def test_rotate_yaw_takes_the_short_way_at_the_yaw_rate() -> None:
    state = PredictedState(position=(0.0, 0.0, 10.0), flying=True, heading=350.0)
    step = MODEL.step(action("ROTATE_YAW", orientation_angle="10"), state)
    assert step.after.heading == pytest.approx(10.0)
    assert step.duration == pytest.approx(20.0 / PROFILE.yaw_rate)


def test_wait_hovers() -> None:
    step = MODEL.step(action("WAIT", duration="60"), FLYING)
    assert step.duration == 60.0
    assert step.energy == pytest.approx(60.0 * PROFILE.battery_per_second)


def test_labels_are_memorized_and_read() -> None:
    here = PredictedState(position=(20.0, 5.0, 10.0), flying=True)
    memorized = MODEL.step(action("MEMORIZE_POINT", labels={"coordinates": "spot"}), here)
    assert memorized.labels == {"spot": (20.0, 5.0, 10.0)}
    back = MODEL.step(action("GO_TO_POINT", labels={"coordinates": "spot"}), FLYING,
                      memorized.labels)
    assert back.after.position == (20.0, 5.0, 10.0)
    unknown = MODEL.step(action("GO_TO_POINT", labels={"coordinates": "spot"}), FLYING, {})
    assert unknown.unknown_label == "spot"
    assert unknown.after == FLYING


def test_go_to_position_converts_from_wgs84() -> None:
    latitude, longitude, _ = geo.to_global(100.0, -50.0, 0.0, DEFAULT_HOME.latitude,
                                           DEFAULT_HOME.longitude, DEFAULT_HOME.altitude)
    step = MODEL.step(action("GO_TO_POSITION", latitude=str(latitude), longitude=str(longitude),
                             altitude="20"), FLYING)
    assert step.after.position == pytest.approx((100.0, -50.0, 20.0), abs=0.01)


def test_go_to_position_with_a_hold_hovers_that_long_at_the_position() -> None:
    latitude, longitude, _ = geo.to_global(100.0, -50.0, 0.0, DEFAULT_HOME.latitude,
                                           DEFAULT_HOME.longitude, DEFAULT_HOME.altitude)
    where = {"latitude": str(latitude), "longitude": str(longitude), "altitude": "20"}
    moved = MODEL.step(action("GO_TO_POSITION", **where), FLYING)
    held = MODEL.step(action("GO_TO_POSITION", hold="30", **where), FLYING)
    assert held.after.position == moved.after.position
    assert held.duration == pytest.approx(moved.duration + 30)
    assert held.after.battery < moved.after.battery


def test_return_home_and_land_climbs_to_the_return_altitude_first() -> None:
    state = PredictedState(position=(100.0, 0.0, 10.0), flying=True)
    step = MODEL.step(action("RETURN_HOME_AND_LAND"), state)
    assert not step.after.flying
    assert step.after.position == (0.0, 0.0, 0.0)
    rise = PROFILE.return_altitude - 10.0
    assert step.distance == pytest.approx(rise + 100.0 + PROFILE.return_altitude)


def test_set_home_moves_where_return_home_goes() -> None:
    state = PredictedState(position=(40.0, 40.0, 10.0), flying=True)
    moved = MODEL.step(action("SET_HOME"), state).after
    away = MODEL.step(action("GO_TO_POINT", coordinates="(0, 0, 10)"), moved).after
    assert MODEL.step(action("RETURN_HOME"), away).after.position == (40.0, 40.0, 10.0)


def test_loiter_enters_the_circle_at_its_nearest_point_and_flies_the_turns() -> None:
    step = MODEL.step(action("LOITER", coordinates="(50, 0, 10)", radius="10", turns="2"),
                      FLYING)
    assert step.legs[0].points[-1] == pytest.approx((40.0, 0.0, 10.0))
    # Flown as the interpreter flies it: 16 targets a turn.
    assert step.distance == pytest.approx(40.0 + 2 * 16 * circle_chord(10.0))
    assert circle_chord(10.0) * 16 == pytest.approx(2 * math.pi * 10, rel=0.01)


def test_loiter_without_an_end_counts_only_the_way_to_the_circle() -> None:
    step = MODEL.step(action("LOITER", radius="15"), FLYING)
    assert step.loiter is not None and step.loiter.centre == FLYING.position
    assert step.duration == pytest.approx(15.0 / PROFILE.cruise_speed)
    assert step.notes


def test_moves_speed_up_and_brake_at_each_waypoint() -> None:
    assert stop_to_stop(100.0, 10.0, 0.0) == pytest.approx(10.0)
    # 100 m at 10 m/s with 2.5 m/s²: 4 s up to speed (20 m), 6 s cruising, 4 s braking.
    assert stop_to_stop(100.0, 10.0, 2.5) == pytest.approx(14.0)
    # 10 m never reaches 10 m/s: 2 s speeding up over 5 m, 2 s braking.
    assert stop_to_stop(10.0, 10.0, 2.5) == pytest.approx(4.0)
    braking = FlightModel(replace(PROFILE, cruise_speed=10.0, acceleration=2.5))
    step = braking.step(action("GO_TO_POINT", coordinates="(100, 0, 10)"), FLYING)
    assert step.duration == pytest.approx(14.0)
    turn = braking.step(action("LOITER", coordinates="(10, 0, 10)", radius="10", turns="1"),
                        FLYING)
    chord = circle_chord(10.0)
    assert turn.duration == pytest.approx(16 * 2 * math.sqrt(chord / 2.5))


def test_landings_slow_down_near_the_ground_and_rtl_waits_over_home() -> None:
    arducopter = FlightModel(replace(PROFILE, descent_rate=1.5, land_speed=0.5,
                                     land_altitude=10.0, return_hover=5.0))
    high = PredictedState(position=(0.0, 0.0, 25.0), flying=True)
    # 15 m at 1.5 m/s, then 10 m at 0.5 m/s.
    assert arducopter.step(action("LAND"), high).duration == pytest.approx(30.0)
    assert arducopter.step(action("LAND"), FLYING).duration == pytest.approx(20.0)
    # A descent that is not a landing keeps the descent rate.
    lower = arducopter.step(action("SET_ALTITUDE", altitude="1"), high)
    assert lower.duration == pytest.approx(24.0 / 1.5)
    # RTL from home at 25 m: the 5 s wait over home, then the landing.
    rtl = arducopter.step(action("RETURN_HOME_AND_LAND"), high)
    assert rtl.duration == pytest.approx(35.0)
    assert rtl.after.flying is False and rtl.after.position == (0.0, 0.0, 0.0)
    assert arducopter.return_home_energy((0.0, 0.0, 25.0), (0.0, 0.0, 0.0)) == \
        pytest.approx(35.0 * PROFILE.battery_per_second)


def test_survey_area_flies_to_the_base_then_the_passes() -> None:
    step = MODEL.step(action("SURVEY_AREA", length="100", width="40", spacing="20",
                             direction="NORTH_EAST", coordinates="(0, 30, 10)"), FLYING)
    # 30 m to the base, three passes of 100 m, two 20 m steps across.
    assert step.distance == pytest.approx(30 + 300 + 40)


def test_capture_photos_hovers_between_photos() -> None:
    step = MODEL.step(action("CAPTURE_PHOTOS", count="5", interval="3"), FLYING)
    assert step.duration == pytest.approx(12.0)


def test_go_to_rectangle_uses_a_known_frame() -> None:
    from tml.world import WorldObject

    world = World(objects=(WorldObject("frame", "1", 30.0, 0.0, 3.0, "red"),))
    step = FlightModel(PROFILE, world).step(action("GO_TO_RECTANGLE", frame_color="red"),
                                            FLYING)
    assert step.after.position == (30.0, 0.0, 3.0)
    unknown = MODEL.step(action("GO_TO_RECTANGLE", frame_color="red"), FLYING)
    assert unknown.after == FLYING and unknown.notes


def test_blocked_leg_is_flown_straight_and_reported() -> None:
    from tml.world import Prism

    walls = (Prism("n", ((20, -20), (22, -20), (22, 22), (20, 22))),
             Prism("s", ((-22, -22), (-20, -22), (-20, 20), (-22, 20))),
             Prism("e", ((-20, 20), (22, 20), (22, 22), (-20, 22))),
             Prism("w", ((-22, -22), (20, -22), (20, -20), (-22, -20))))
    model = FlightModel(PROFILE, World(obstacles=walls))
    start = PredictedState(position=(100.0, 0.0, 10.0), flying=True)
    step = model.step(action("GO_TO_POINT", coordinates="(0, 0, 10)"), start)
    assert step.blocked == (((100.0, 0.0, 10.0), (0.0, 0.0, 10.0)),)
    assert step.distance == pytest.approx(100.0)


FIXED_WING = FlightModel(load_profile("fixed-wing"), World())
ROVER = FlightModel(load_profile("rover"), World())


def test_a_fixed_wing_takes_off_along_its_heading() -> None:
    profile = FIXED_WING.profile
    step = FIXED_WING.step(action("TAKE_OFF", altitude="40"), PredictedState(heading=90.0))
    north, east, up = step.after.position
    assert up == 40.0 and abs(north) < 1e-9
    assert east == pytest.approx(40.0 / profile.climb_rate * profile.cruise_speed)


def test_a_fixed_wing_lands_straight_ahead_along_its_glide() -> None:
    step = FIXED_WING.step(action("LAND"), PredictedState(position=(0.0, 0.0, 50.0),
                                                        flying=True, heading=0.0))
    assert step.after.position == pytest.approx((400.0, 0.0, 0.0))
    assert not step.after.flying


def test_a_fixed_wing_comes_home_along_its_approach() -> None:
    state = PredictedState(position=(600.0, 0.0, 50.0), flying=True)
    step = FIXED_WING.step(action("RETURN_HOME_AND_LAND"), state)
    assert [leg.points[-1] for leg in step.legs] == [(400.0, 0.0, 50.0), (0.0, 0.0, 0.0)]
    assert step.distance == pytest.approx(200.0 + math.hypot(400.0, 50.0))


def test_a_ground_vehicle_drives_every_point_at_ground_level_and_is_then_underway() -> None:
    step = ROVER.step(action("GO_TO_POINT", coordinates="(30, 40, 12)"), PredictedState())
    assert step.after.position == (30.0, 40.0, 0.0)
    assert step.after.flying and not step.before.flying
    assert step.distance == pytest.approx(50.0)


def test_a_ground_vehicle_returns_home_and_stops() -> None:
    state = PredictedState(position=(30.0, 40.0, 0.0), flying=True)
    step = ROVER.step(action("RETURN_HOME_AND_LAND"), state)
    assert step.after.position == (0.0, 0.0, 0.0) and not step.after.flying
    assert step.distance == pytest.approx(50.0)


def test_raw_mission_items_are_flown_as_the_autopilot_flies_their_commands() -> None:
    from tml.language.validation import validate_file
    from tml.verify.static import verify_mission

    items = "".join(
        f'<task name="i{n}"><mission_item {attributes}/></task>' for n, attributes in enumerate([
            'command="NAV_TAKEOFF" frame="GLOBAL_RELATIVE_ALT" param7="20"',
            'command="NAV_WAYPOINT" frame="GLOBAL_RELATIVE_ALT" param1="5" '
            'param5="-35.3623621" param6="149.1652300" param7="20"',  # 100 m north, hold 5 s
            'command="DO_JUMP" frame="MISSION" param1="2" param2="1"',
            'command="NAV_LAND" frame="GLOBAL_RELATIVE_ALT"']))
    text = ('<mission name="m"><environment><home latitude="-35.3632621" '
            'longitude="149.16523" altitude="584"/></environment>'
            f'<task name="p" dispatch="mission">{items}</task></mission>')
    mission = validate_file("m.xml", text.encode()).mission
    report = verify_mission(mission, load_profile("quadcopter"))
    distances = [round(row.distance) for row in report.rows]
    assert distances == [20, 100, 0, 20]
    assert report.rows[1].time > 100 / load_profile("quadcopter").cruise_speed + 5 - 1e-6
