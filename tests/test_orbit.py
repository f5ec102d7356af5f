"""ORBIT (tml.actions.orbit): the GUIDED circle facing the point, the mission items, the
item time, the motion model, the refusals by kind and the import of its items."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from fake_vehicle import FakeVehicle
from pymavlink.dialects.v20 import ardupilotmega as M
from test_engine_interpreter import Flight
from test_imported_actions import imported_and_back
from test_mavlink_compile import act, compiled, fly, local

from tml.actions import orbit
from tml.actions.guided import Limits
from tml.actions.motion import PredictedState
from tml.engine import Status
from tml.language.kinds import Kind, refusal
from tml.language.validation import validate_file
from tml.mavlink.mission import MissionItem
from tml.plans.imported import import_plan
from tml.plans.planned import plan_mission
from tml.plans.qgc import read_plan, write_plan
from tml.plans.wpl import read_wpl
from tml.verify.constraints import assess_action
from tml.verify.profile import load_profile

TAKE_OFF_20 = '<task name="Up"><action name="TAKE_OFF"><argument name="altitude" ' \
              'value="20"/></action></task>'


def _orbit_task(**arguments: str) -> str:
    written = "".join(f'<argument name="{k}" value="{v}"/>' for k, v in arguments.items())
    return f'<task name="Orbit"><action name="ORBIT">{written}</action></task>'


# --- GUIDED -------------------------------------------------------------------------------

def test_each_target_of_the_circle_carries_the_heading_toward_the_point() -> None:
    body = TAKE_OFF_20 + _orbit_task(coordinates="(30, 10, 5)", radius="8", turns="2",
                                     altitude="12")
    flight = Flight(body).run(600)
    assert flight.interp.status is Status.COMPLETED
    targets = [r for r in flight.requests if type(r).__name__ == "GoTo"]
    assert len(targets) == 2 * 16 + 1  # the entry point, then 16 a turn
    for target in targets:
        n, e, u = target.target
        assert math.hypot(n - 30, e - 10) == pytest.approx(8) and u == 12
        toward = math.degrees(math.atan2(10 - e, 30 - n)) % 360
        assert target.yaw == pytest.approx(toward)
    # The vehicle ends on the circle, not at the point of interest.
    n, e, u = flight.vehicle.position
    assert math.hypot(n - 30, e - 10) == pytest.approx(8, abs=0.6)
    assert u == pytest.approx(12, abs=0.6)


def test_a_time_is_flown_round_the_circle_until_it_is_over() -> None:
    body = TAKE_OFF_20 + _orbit_task(coordinates="(0, 20, 0)", radius="10", duration="30")
    flight = Flight(body).run(600)
    assert flight.interp.status is Status.COMPLETED
    orbit_times = [r.time for r in flight.records if r.kind == "action"
                   and r.data.get("action") == "ORBIT"
                   and r.data["message"].split()[-1] in ("started", "done")]
    assert orbit_times[1] - orbit_times[0] >= 30


def test_a_fixed_wing_circles_the_point_natively() -> None:
    plane = FakeVehicle(vehicle_type="fixed-wing", speed=20.0, climb_rate=5.0)  # type: ignore[arg-type]
    body = TAKE_OFF_20 + _orbit_task(coordinates="(300, 0, 0)", radius="80", turns="1")
    flight = Flight(body, vehicle=plane).run(600)
    assert flight.interp.status is Status.COMPLETED
    circles = [r for r in flight.requests if type(r).__name__ == "Circle"]
    assert len(circles) == 1 and circles[0].radius == 80
    assert circles[0].centre[:2] == (300, 0)


def test_a_ground_vehicle_cannot_orbit() -> None:
    reason = refusal(act("ORBIT", coordinates="(10, 0, 0)", turns="1"), Kind.GROUND, "rover")
    assert reason is not None and reason.startswith("a rover cannot face a point")
    assert refusal(act("ORBIT", coordinates="(10, 0, 0)", turns="1"), Kind.FIXED_WING) is None
    flight = Flight(_orbit_task(coordinates="(10, 0, 0)", turns="1"),
                    vehicle=FakeVehicle(vehicle_type="rover")).run(60)
    assert flight.interp.status is Status.ABORTED
    assert [r.data["reason"] for r in flight.records
            if r.kind == "action" and "reason" in r.data] == ["infeasible"]
    assert not [r for r in flight.requests if type(r).__name__ == "GoTo"]


# --- mission items ------------------------------------------------------------------------

def test_its_items_are_the_roi_the_circle_where_it_ends_and_the_roi_cleared() -> None:
    # ArduPilot runs the DO items after a navigation item while it flies: the ROI is
    # cleared during the waypoint where the circle ends, not as the circle starts.
    plan = compiled(act("ORBIT", coordinates="(30, 10, 5)", radius="8", turns="3",
                        altitude="12"), start=(30.0, -20.0, 10.0))
    roi, circle, end, clear = plan.items
    assert [i.command for i in plan.items] == [
        M.MAV_CMD_DO_SET_ROI_LOCATION, M.MAV_CMD_NAV_LOITER_TURNS, M.MAV_CMD_NAV_WAYPOINT,
        M.MAV_CMD_DO_SET_ROI_NONE]
    assert roi.frame == circle.frame == end.frame == M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    assert local(roi) == (30.0, 10.0, 5.0) and local(circle) == (30.0, 10.0, 12.0)
    assert (circle.param1, circle.param3) == (3, 8)
    assert local(end) == (30.0, 2.0, 12.0)  # the circle's point nearest the vehicle
    assert (clear.x, clear.y, clear.z) == (0, 0, 0)
    assert plan.action_index == (0, 0, 0, 0)


def test_a_global_point_is_written_as_given_and_the_circle_defaults_to_the_altitude_there(
        ) -> None:
    plan = compiled(act("ORBIT", latitude="-35.3630", longitude="149.1653",
                        target_altitude="2", turns="1"), start=(0.0, 0.0, 17.0))
    roi, circle, _, _ = plan.items
    assert (roi.x, roi.y, roi.z) == (-353630000, 1491653000, 2.0)
    assert (circle.x, circle.y, circle.z) == (-353630000, 1491653000, 17.0)


@pytest.mark.parametrize(("duration", "turns"), [("18", 1), ("19", 2), ("36", 2), ("5", 1)])
def test_a_time_is_the_whole_turns_it_takes_at_ardu_copters_circle_rate(
        duration: str, turns: int) -> None:
    plan = compiled(act("ORBIT", coordinates="(0, 0, 0)", duration=duration))
    assert plan.items[1].param1 == turns


def test_the_item_time_is_the_way_to_the_circle_and_each_turn() -> None:
    limits = Limits(speed=5.0)
    small = act("ORBIT", coordinates="(40, 0, 0)", radius="5", turns="2")
    # A 5 m circle is flown at CIRCLE_RATE (18 s a turn), not at 5 m/s (6.3 s a turn).
    assert orbit.orbit_time(limits, "", (0.0, 0.0, 10.0), small) == pytest.approx(35 / 5 + 36)
    large = act("ORBIT", coordinates="(40, 0, 0)", radius="30", turns="1")
    assert orbit.orbit_time(limits, "", (0.0, 0.0, 10.0), large) == pytest.approx(
        10 / 5 + 2 * math.pi * 30 / 5)


def test_the_items_fly_round_the_point_in_the_simulator() -> None:
    plan = compiled(act("TAKE_OFF", altitude="10"),
                    act("ORBIT", coordinates="(20, 0, 0)", radius="6", turns="1"),
                    act("LAND"), start=(0, 0, 0))
    v, out = fly(plan.items, limit=600)
    reached = [m.seq - 1 for m in out if m.get_type() == "MISSION_ITEM_REACHED"]
    assert [plan.action_at(s) for s in reached if plan.items[s].command < 80] == [0, 1, 1, 2]
    assert v.landed


# --- tml verify ---------------------------------------------------------------------------

def test_verify_predicts_the_turns_round_the_point_at_the_altitude() -> None:
    profile = load_profile("quadcopter")
    state = PredictedState(position=(0.0, 0.0, 10.0), flying=True)
    step = assess_action(act("ORBIT", coordinates="(50, 0, 0)", radius="10", turns="2",
                             altitude="15"), state, profile).step
    assert step.loiter is not None and step.loiter.centre == (50.0, 0.0, 15.0)
    assert step.loiter.radius == 10
    assert step.circle_metres == pytest.approx(2 * 16 * 2 * 10 * math.sin(math.pi / 16))
    assert step.after.time > step.circle_metres / profile.max_speed


# --- tml import ---------------------------------------------------------------------------

def _wpl(*rows: str) -> str:
    home = "0\t1\t0\t16\t0\t0\t0\t0\t-35.363261\t149.16523\t584\t1\n"
    return "QGC WPL 110\n" + home + "".join(f"{n}\t0\t{row}\t1\n"
                                           for n, row in enumerate(rows, start=1))


def _imported_actions(text: str, tmp_path: Path) -> tuple[list[str], list[MissionItem]]:
    """The actions the waypoint file ``text`` imports as (checked to compile back to its
    very items: tests/test_imported_actions.py), and its items."""
    plan = read_wpl(text)
    _, mission = imported_and_back(plan, tmp_path)
    return [action.name for _, action in mission.actions()], list(plan.items)


def _row(item: MissionItem) -> str:
    return "\t".join(str(v) for v in (item.frame, item.command, item.param1, item.param2,
                                       item.param3, item.param4, item.x / 1e7, item.y / 1e7,
                                       item.z))


TAKE_OFF_ROW, ROI_ROW, CIRCLE_ROW, END_ROW, CLEAR_ROW = (_row(i) for i in compiled(
    act("TAKE_OFF", altitude="15"), act("ORBIT", latitude="-35.3630", longitude="149.1653",
                                          target_altitude="2", altitude="20", radius="10",
                                          turns="2"), start=(0.0, 0.0, 0.0)).items)


def test_the_roi_the_circle_where_it_ends_and_the_roi_cleared_are_imported_as_one_orbit(
        tmp_path: Path) -> None:
    names, items = _imported_actions(_wpl(TAKE_OFF_ROW, ROI_ROW, CIRCLE_ROW, END_ROW,
                                          CLEAR_ROW), tmp_path)
    assert names == ["TAKE_OFF", "ORBIT"]
    assert [i.command for i in items] == [22, 195, 18, 16, 197]


@pytest.mark.parametrize(("rows", "names"), [
    # A circle with no ROI before it is a LOITER; an ROI with no circle stays as written.
    ((TAKE_OFF_ROW, CIRCLE_ROW), ["TAKE_OFF", "LOITER"]),
    ((TAKE_OFF_ROW, ROI_ROW, CLEAR_ROW), ["TAKE_OFF", "MISSION_ITEM", "MISSION_ITEM"]),
    # The ROI cleared as the circle starts (no waypoint between): each item as written.
    ((TAKE_OFF_ROW, ROI_ROW, CIRCLE_ROW, CLEAR_ROW),
     ["TAKE_OFF", "MISSION_ITEM", "MISSION_ITEM", "MISSION_ITEM"]),
    # The circle round another point than the ROI's: no ORBIT.
    ((TAKE_OFF_ROW, ROI_ROW, CIRCLE_ROW.replace("149.1653", "149.1654"), END_ROW, CLEAR_ROW),
     ["TAKE_OFF", "MISSION_ITEM", "LOITER", "GO_TO_POSITION", "MISSION_ITEM"]),
])
def test_items_that_are_no_orbit_stay_what_they_are(rows: tuple[str, ...], names: list[str],
                                                     tmp_path: Path) -> None:
    assert _imported_actions(_wpl(*rows), tmp_path)[0] == names


def test_the_orbit_mission_exports_and_imports_back_to_its_orbits(tmp_path: Path) -> None:
    mission = validate_file(Path(__file__).parent.parent / "missions" / "orbit.xml").mission
    assert mission is not None
    plan = plan_mission(mission)
    imported = import_plan(read_plan(write_plan(plan)), plan.name)
    path = tmp_path / "back.xml"
    path.write_text(imported.text)
    back = validate_file(path).mission
    assert back is not None
    assert [a.name for _, a in back.actions()].count("ORBIT") == 2
