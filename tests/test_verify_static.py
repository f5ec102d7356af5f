"""Static verification of whole missions: repeats, conditions, labels, events."""

from __future__ import annotations

from dataclasses import replace

import pytest

from tml.language.model import Mission
from tml.language.validation import validate_file
from tml.verify.constraints import Constraint
from tml.verify.motion import PredictedState
from tml.verify.profile import load_profile
from tml.verify.static import verify_mission
from tml.world import Cylinder, World

PROFILE = replace(load_profile("quadcopter"), battery_per_metre=0.1, battery_per_second=0.1,
                  cruise_speed=5.0, climb_rate=2.0, descent_rate=1.0, return_altitude=10.0,
                  takeoff_altitude=10.0, battery_reserve=20.0, min_clearance=5.0,
                  acceleration=0.0, land_speed=0.0, land_altitude=0.0, return_hover=0.0)


def mission(tasks: str, events: str = "", environment: str = "") -> Mission:
    text = f"""<?xml version="1.0"?>
<mission name="m">
{environment}
{tasks}
<event_handling>{events}</event_handling>
</mission>
"""
    result = validate_file("m.xml", text.encode())
    assert result.mission is not None and not result.errors, result.diagnostics
    return result.mission


TAKE_OFF = '<task name="up"><action name="TAKE_OFF"/></task>'


def go(name: str, point: str, extra: str = "") -> str:
    return (f'<task name="{name}">{extra}<action name="GO_TO_POINT">'
            f'<argument name="coordinates" value="{point}"/></action></task>')


def test_repeats_are_unrolled() -> None:
    report = verify_mission(mission(TAKE_OFF + """
        <task name="hop"><repeat times="3"/>
          <action name="MOVE"><argument name="coordinates" value="(10, 0, 0)"/></action>
        </task>"""), PROFILE)
    assert [r.task for r in report.rows] == ["up", "hop #1", "hop #2", "hop #3"]
    assert report.end is not None
    assert report.end.position == (30.0, 0.0, 10.0)
    # 10 m climb (5 s) and 30 m flown: per metre dominates the climb? 10 m * 0.1 = 1 %.
    assert report.end.battery == pytest.approx(100 - 1.0 - 3.0)
    assert report.feasible


def sortie(name: str, at_least: int) -> str:
    """A 250 s hover (25 % of PROFILE's battery) when the battery is at least ``at_least``."""
    return (f'<task name="{name}"><condition parameter="BATTERY_CHARGE_PERCENTAGE" '
            f'comparison="greater than or equal to" value="{at_least}"/>'
            '<action name="WAIT"><argument name="duration" value="250"/></action></task>')


def test_a_battery_condition_false_at_the_predicted_battery_skips_the_task() -> None:
    # 100 % -> 75 % -> 50 %: a third sortie needs 60 %, which 50 % + 10 points is not.
    body = TAKE_OFF + sortie("one", 60) + sortie("two", 60) + sortie("three", 60)
    report = verify_mission(mission(body + '<task name="down"><action name="LAND"/></task>'),
                            PROFILE)
    assert [r.task for r in report.rows] == ["up", "one", "two", "down"]
    assert report.feasible
    assert any("task three: skipped where its battery condition is false" in note
               for note in report.notes)


def test_a_battery_condition_within_the_margin_is_followed_both_ways() -> None:
    # After two sorties 50 % is left: "at least 55" may hold (the prediction is 10 points
    # from certain), so the third sortie is walked, and the worst end is after it.
    body = TAKE_OFF + sortie("one", 55) + sortie("two", 55) + sortie("three", 55)
    report = verify_mission(mission(body), PROFILE)
    assert "three" in [r.task for r in report.rows]
    assert report.end is not None and report.end.battery < 30


def test_a_conditioned_task_may_or_may_not_run() -> None:
    condition = '<condition parameter="GROUND_SPEED" comparison="less than" value="3"/>'
    report = verify_mission(mission(TAKE_OFF + go("maybe far", "(300, 0, 10)", condition)
                                    + go("back", "(0, 0, 10)")), PROFILE)
    back = [r for r in report.rows if r.task == "back"]
    assert len(back) == 1
    # The worst way is the one that flew out: 1 + 30 + 30 % used.
    assert back[0].battery == pytest.approx(100 - 1 - 30 - 30)
    assert back[0].distance == pytest.approx(300.0)


def test_label_memorized_only_on_one_branch_is_a_violation() -> None:
    condition = '<condition parameter="GROUND_SPEED" comparison="less than" value="3"/>'
    tasks = TAKE_OFF + f"""
        <task name="mark">{condition}
          <action name="MEMORIZE_POINT"><argument name="coordinates" label="spot"/></action>
        </task>
        {go("away", "(50, 0, 10)")}
        <task name="return"><action name="GO_TO_POINT">
          <argument name="coordinates" label="spot"/></action></task>"""
    report = verify_mission(mission(tasks), PROFILE)
    labels = [v for v in report.violations if v.constraint is Constraint.LABEL]
    assert len(labels) == 1
    assert labels[0].location is not None and labels[0].location.line == 9
    assert labels[0].task == "return"


def test_event_actions_are_checked_from_where_they_can_fire() -> None:
    events = """<event name="photo spot">
        <condition parameter="GROUND_SPEED" comparison="less than" value="1"/>
        <action name="GO_TO_POINT"><argument name="coordinates" value="(0, 57, 10)"/></action>
        <termination mode="CONTINUE"/></event>"""
    environment = '<environment><cylinder name="mast" north="0" east="60" radius="1"/>' \
                  '</environment>'
    report = verify_mission(mission(TAKE_OFF + go("out", "(100, 0, 10)"), events,
                                    environment), PROFILE)
    event_violations = [v for v in report.violations if v.task.startswith("event photo spot")]
    assert [v.constraint for v in event_violations] == [Constraint.C1]
    assert event_violations[0].value == pytest.approx(2.0)
    assert [r.event for r in report.rows if r.event] == ["photo spot"]


def test_return_home_event_is_judged_from_the_worst_point() -> None:
    events = """<event name="low battery">
        <condition parameter="BATTERY_CHARGE_PERCENTAGE" comparison="less than" value="30"/>
        <action name="RETURN_HOME_AND_LAND"/><termination mode="END_MISSION"/></event>"""
    tasks = TAKE_OFF + go("far", "(250, 0, 10)") + go("near", "(10, 0, 10)") + \
        '<task name="land"><action name="LAND"/></task>'
    report = verify_mission(mission(tasks, events), PROFILE,
                            start=PredictedState(battery=60.0))
    worst = [r for r in report.rows if r.event == "low battery"]
    # From 250 m out: 60 - 1 - 25 = 34 % there, then 250 m home and 10 m down = 26 %.
    assert worst[0].battery == pytest.approx(34 - 26)
    assert not report.feasible
    reserve = [v for v in report.violations if v.constraint is Constraint.RETURN_RESERVE]
    assert [v.task for v in reserve] == ["far", "near"]
    # The event's own RETURN_HOME_AND_LAND is not held to the reserve, only to c2.
    assert [r.battery for r in worst] == [pytest.approx(8.0)]


def test_world_file_is_laid_over_the_environment() -> None:
    world = World(obstacles=(Cylinder("tree", 100, 2, 1),))
    report = verify_mission(mission(TAKE_OFF + go("out", "(100, 0, 10)")), PROFILE, world)
    assert [v.constraint for v in report.violations] == [Constraint.C1]
    assert verify_mission(mission(TAKE_OFF + go("out", "(100, 0, 10)")), PROFILE).feasible


def test_many_independent_conditions_stay_bounded() -> None:
    condition = '<condition parameter="GROUND_SPEED" comparison="less than" value="3"/>'
    tasks = TAKE_OFF + "".join(
        f'<task name="mark {i}">{condition}<action name="MEMORIZE_POINT">'
        f'<argument name="coordinates" label="spot {i}"/></action></task>' for i in range(6))
    report = verify_mission(mission(tasks), PROFILE)
    # 2**6 sets of labels are possible; the walk keeps a bounded number of them.
    assert report.approximate
    assert len(report.rows) == 7


def _label_violations(tasks: str, events: str = "") -> list:
    report = verify_mission(mission(tasks, events), PROFILE)
    return [v for v in report.violations if v.constraint is Constraint.LABEL]


READ_SPOT = ('<action name="GO_TO_POINT"><argument name="coordinates" label="spot"/>'
             '</action></task>')
MARK_ON_ONE_BRANCH = TAKE_OFF + (
    '<task name="mark"><condition parameter="GROUND_SPEED" comparison="less than" value="3"/>'
    '<action name="MEMORIZE_POINT"><argument name="coordinates" label="spot"/></action></task>')


def test_read_guarded_by_known_is_not_a_violation() -> None:
    guarded = ('<task name="return"><condition label="spot" comparison="known" value="yes"/>'
               + READ_SPOT)
    assert _label_violations(MARK_ON_ONE_BRANCH + guarded) == []
    # The guard on a parent task covers its sub-tasks too.
    nested = ('<task name="back"><condition label="spot" comparison="known"/>'
              '<task name="return">' + READ_SPOT + '</task>')
    assert _label_violations(MARK_ON_ONE_BRANCH + nested) == []
    # "known no" guarantees nothing.
    unguarded = ('<task name="return"><condition label="spot" comparison="known" value="no"/>'
                 + READ_SPOT)
    assert len(_label_violations(MARK_ON_ONE_BRANCH + unguarded)) == 1


def test_label_an_event_may_store_is_not_a_violation() -> None:
    event = ('<event name="seen"><condition parameter="RECOGNIZED_ITEMS" comparison="includes" '
             'value="A"/><action name="MEMORIZE_POINT"><argument name="coordinates" '
             'label="spot"/></action><termination mode="CONTINUE"/></event>')
    assert _label_violations(TAKE_OFF + '<task name="return">' + READ_SPOT, event) == []


ROLES = '<roles><role name="north"/><role name="south" count="2"/></roles>'


def fly(name: str, point: str, role: str = "", extra: str = "") -> str:
    """Take off, fly to ``point`` and land there, as one task of ``role``."""
    written = f' role="{role}"' if role else ""
    return (f'<task name="{name}"{written}{extra}>' + TAKE_OFF + go("out", point)
            + '<task name="down"><action name="RETURN_HOME_AND_LAND"/></task></task>')


def test_each_role_is_its_own_vehicle_and_findings_name_it() -> None:
    # North flies 450 m out: 1 + 45 % there, 46 % to come home: below the 20 % reserve.
    # South flies 50 m out and back on its own vehicles.
    tasks = ('<task name="Both" composition="parallel">'
             + fly("N", "(450, 0, 10)", "north") + fly("S", "(50, 0, 10)", "south") + '</task>')
    report = verify_mission(mission(tasks, environment=ROLES), PROFILE)
    assert not report.feasible
    assert {(v.role, v.vehicles) for v in report.violations} == {("north", (1,))}
    assert [v.constraint for v in report.violations] == [Constraint.RETURN_RESERVE]
    assert [(r.task, r.role, r.vehicles) for r in report.rows if r.role == "south"] == [
        ("Both/S/up", "south", (1, 2)), ("Both/S/out", "south", (1, 2)),
        ("Both/S/down", "south", (1, 2))]
    # South's branch is flown from the ground at home with a full battery.
    south_up = next(r for r in report.rows if r.task == "Both/S/up")
    assert south_up.battery == pytest.approx(99.0) and south_up.time == pytest.approx(5.0)
    assert report.roles == ("north", "south")
    assert report.ends["south"].battery == pytest.approx(100 - 1 - 5 - 6)


SORTIE = fly("sortie", "(250, 0, 10)", extra=' release="north"')


@pytest.mark.parametrize(("release", "feasible"), [(True, True), (False, False)])
def test_release_brings_a_fresh_vehicle(release: bool, feasible: bool) -> None:
    # A sortie uses 1 + 25 + 26 = 52 %: a second one on the same battery breaks the reserve.
    sortie = SORTIE if release else SORTIE.replace(' release="north"', "")
    tasks = ('<task name="Relay" role="north"><loop/>'
             + sortie.replace('"sortie"', '"first"') + sortie.replace('"sortie"', '"second"')
             + '</task>')
    report = verify_mission(mission(tasks, environment=ROLES), PROFILE)
    assert report.feasible is feasible
    assert any(n.endswith("task Relay: loop verified for one round") for n in report.notes)
    second = next(r for r in report.rows if r.task == "Relay/second/out")
    if release:
        assert second.vehicles == (2,)
        assert second.battery == pytest.approx(100 - 1 - 25)
    else:
        assert second.vehicles == (1,)
        # 22 % left 250 m out: below the reserve there, and too little to come home.
        assert {(v.task, v.vehicles) for v in report.violations} == {
            ("Relay/second/out", (1,)), ("Relay/second/down", (1,))}


def test_a_mission_without_roles_is_verified_as_one_vehicle() -> None:
    tasks = TAKE_OFF + go("far", "(450, 0, 10)") + go("near", "(10, 0, 10)")
    plain = verify_mission(mission(tasks), PROFILE)
    assert plain.roles == () and plain.ends == {}
    assert all(r.role == "" and r.vehicles == () for r in plain.rows)
    assert all(v.role == "" and v.vehicles == () for v in plain.violations)
    # With one declared role every task is flown by it: the same predictions and findings.
    single = verify_mission(mission(tasks, environment='<roles><role name="solo"/></roles>'),
                            PROFILE)
    assert [replace(r, role="", vehicles=()) for r in single.rows] == plain.rows
    assert [replace(v, role="", vehicles=()) for v in single.violations] == plain.violations
    assert plain.violations and {v.role for v in single.violations} == {"solo"}
    assert single.end == plain.end


def test_choice_keeps_the_worst_branch_from_the_same_start() -> None:
    tasks = TAKE_OFF + ('<task name="pick" composition="choice">'
                        + go("far", "(300, 0, 10)") + go("near", "(50, 0, 10)")
                        + '</task>') + go("back", "(0, 0, 10)")
    report = verify_mission(mission(tasks), PROFILE)
    near = next(r for r in report.rows if r.task == "pick/near")
    # Not after the far branch: both start after the take-off.
    assert near.battery == pytest.approx(100 - 1 - 5)
    back = [r for r in report.rows if r.task == "back"]
    assert back[0].battery == pytest.approx(100 - 1 - 30 - 30)


def test_error_handler_runs_from_the_start_or_the_end_of_its_task() -> None:
    handler = ('<on_error><task name="home"><action name="RETURN_HOME_AND_LAND"/></task>'
               '</on_error>')
    tasks = (TAKE_OFF + '<task name="mission"><until><condition parameter="GROUND_SPEED" '
             'comparison="less than" value="1"/></until>' + go("far", "(300, 0, 10)")
             + handler + '</task>' + '<task name="again"><action name="TAKE_OFF"/></task>')
    report = verify_mission(mission(tasks), PROFILE)
    home = [r for r in report.rows if r.task == "mission/home"]
    # Worst: the failure after the far leg (69 % left), then 300 m home and 10 m down.
    assert len(home) == 1 and home[0].battery == pytest.approx(69 - 30 - 1)
    assert any("until and time_limit can only shorten the task" in n for n in report.notes)
    # After the task, the ways with and without the handler go on: the worst is landed.
    again = next(r for r in report.rows if r.task == "again")
    assert again.distance == pytest.approx(10.0)


def test_events_of_a_role_are_checked_on_its_vehicles_only() -> None:
    events = """<event name="look" role="south">
        <condition parameter="GROUND_SPEED" comparison="less than" value="1"/>
        <action name="ROTATE_YAW"><argument name="angle" value="90"/></action>
        <termination mode="CONTINUE"/></event>"""
    tasks = fly("N", "(100, 0, 10)", "north") + fly("S", "(20, 0, 10)", "south")
    report = verify_mission(mission(tasks, events, ROLES), PROFILE)
    assert [(r.event, r.role) for r in report.rows if r.event] == [("look", "south")]


FLEET = """<roles><role name="air" type="multicopter"/><role name="ground" type="rover"/></roles>
<task name="both" composition="parallel">
  <task name="fly" role="air"><action name="TAKE_OFF"/></task>
  <task name="drive" role="ground">{ground}</task>
</task>"""


def test_a_role_of_another_kind_is_verified_with_its_own_profile() -> None:
    drive = ('<action name="GO_TO_POINT"><argument name="coordinates" value="(20, 0, 0)"/>'
             '</action>')
    report = verify_mission(mission(FLEET.format(ground=drive)), PROFILE)
    assert report.feasible, [str(v) for v in report.violations]
    assert any("role ground (type rover) verified with the rover profile" in note
               for note in report.notes)
    # The rover drove at ground level without taking off.
    assert report.ends["ground"].position == (20.0, 0.0, 0.0)


def test_a_role_is_held_to_what_its_vehicle_type_can_do() -> None:
    report = verify_mission(mission(FLEET.format(ground='<action name="LAND"/>')), PROFILE)
    (violation,) = report.violations
    assert violation.constraint is Constraint.VEHICLE and violation.role == "ground"
    assert "a rover cannot land" in str(violation)
