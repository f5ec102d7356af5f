"""Plans for other tools: a mission's mission items, .plan and WPL files, maps, import."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import pytest
from lxml import etree

from tml.language.kinds import Kind
from tml.language.validation import load_mission, validate_file
from tml.mavlink.codec import mavlink
from tml.mavlink.mission import MissionItem
from tml.plans.imported import import_plan, same_item
from tml.plans.maps import KML_NAMESPACE, write_geojson, write_kml
from tml.plans.planned import Plan, PlanError, plan_mission
from tml.plans.qgc import PlanFile, PlanFileError, read_plan, write_plan
from tml.plans.wpl import read_wpl, write_wpl

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = sorted((ROOT / "missions").glob("*.xml"))
FORMATS = {"plan": (write_plan, read_plan), "wpl": (write_wpl, read_wpl)}


def _plans(path: Path) -> list[Plan]:
    mission = load_mission(path)
    return [plan_mission(mission, role.name) for role in mission.roles] \
        or [plan_mission(mission)]


def _same_items(sent: tuple[MissionItem, ...], back: tuple[MissionItem, ...]) -> None:
    assert len(back) == len(sent)
    for a, b in zip(sent, back, strict=True):
        # The compiler's altitudes AMSL go through the geodesy both ways: a micrometre.
        assert replace(b, z=0.0) == replace(a, z=0.0), (a, b)
        assert b.z == pytest.approx(a.z, abs=1e-6)


def _imported_plan(text: str, kind: Kind, tmp_path: Path) -> Plan:
    path = tmp_path / "imported.xml"
    path.write_text(text)
    result = validate_file(path)
    assert not result.errors, [str(d) for d in result.errors]
    assert result.mission is not None
    return plan_mission(result.mission, kind=kind)


@pytest.mark.parametrize("form", FORMATS)
@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: p.name)
def test_export_then_import_keeps_the_items(path: Path, form: str, tmp_path: Path) -> None:
    write, read = FORMATS[form]
    for plan in _plans(path):
        imported = import_plan(read(write(plan)), plan.name)
        back = _imported_plan(imported.text, plan.kind, tmp_path)
        _same_items(plan.items, back.items)
        assert (back.home.latitude, back.home.longitude, back.home.altitude) == (
            plan.home.latitude, plan.home.longitude, plan.home.altitude)


def test_guided_actions_become_their_mission_items() -> None:
    plan = plan_mission(load_mission(ROOT / "missions/paper_example1.xml"))
    assert [i.command for i in plan.items] == [
        mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_CMD_NAV_DELAY, mavlink.MAV_CMD_NAV_WAYPOINT,
        mavlink.MAV_CMD_NAV_LAND]
    assert plan.tasks[2] == "Navigate avoiding obstacles/Go to destination"
    # The GO_TO_POINT to (3, 4, 1.5) as a WGS84 waypoint 1.5 m above home.
    lat, lon, alt = plan.position(plan.items[2]) or (0, 0, 0)
    assert alt == pytest.approx(plan.home.altitude + 1.5)
    assert math.hypot((lat - plan.home.latitude) * 111_000,
                      (lon - plan.home.longitude) * 111_000 * math.cos(math.radians(lat))
                      ) == pytest.approx(5.0, abs=0.05)
    assert plan.notes == ("1 event handler(s) not in the plan: the autopilot flies the items "
                          "without them",)


def test_actions_without_a_mission_item_are_named_once() -> None:
    plan = plan_mission(load_mission(ROOT / "missions/paper_example2.xml"))
    assert [(s.action, s.line) for s in plan.skipped] == [("FLIP", 29)]  # repeated 3 times
    assert "flown with commands only" in plan.skipped[0].reason
    labels = plan_mission(load_mission(ROOT / "missions/jump_and_repeat.xml")).skipped
    assert ("GO_TO_POINT", "reads label 'start'") in [
        (s.action, "reads label 'start'") for s in labels if "label 'start'" in s.reason]


def test_a_kind_that_cannot_fly_an_action_leaves_it_out() -> None:
    plan = plan_mission(load_mission(ROOT / "missions/paper_example1.xml"), kind=Kind.GROUND)
    assert {s.action for s in plan.skipped} == {"TAKE_OFF", "LAND"}
    assert mavlink.MAV_CMD_NAV_TAKEOFF not in [i.command for i in plan.items]


def test_a_mission_with_roles_needs_one_chosen() -> None:
    mission = load_mission(ROOT / "missions/dolphin_uav_surface.xml")
    with pytest.raises(PlanError, match="roles scout, surface: --role"):
        plan_mission(mission)
    with pytest.raises(PlanError, match="no role 'boat'"):
        plan_mission(mission, "boat")
    surface = plan_mission(mission, "surface")
    assert surface.kind is Kind.GROUND and surface.role == "surface"
    assert mavlink.MAV_CMD_NAV_TAKEOFF not in [i.command for i in surface.items]


def test_a_repeat_is_its_body_once_and_a_do_jump_back() -> None:
    once = plan_mission(load_mission(ROOT / "missions/paper_example2.xml"))
    assert len(once.items) == 3
    mission = load_mission(ROOT / "missions/battery_event.xml")
    repeated, = [t for t in mission.walk() if t.repeat > 1]
    plan = plan_mission(mission)
    commands = [i.command for i in plan.items]
    assert commands == [22, 16, 16, 16, 16, 177, 20]
    jump = plan.items[5]
    # Back to item 2 (numbered from 1, behind home), 4 more times: 5 rounds in all.
    assert (jump.frame, jump.param1, jump.param2) == (0, 2.0, repeated.repeat - 1)
    assert plan.tasks[5] == repeated.path_name


REPEATS = """<mission name="r"><task name="t" dispatch="mission">
  <task name="up"><action name="TAKE_OFF"><argument name="altitude" value="10"/></action></task>
  {body}
</task></mission>"""


def _repeat_plan(body: str) -> Plan:
    mission = validate_file("r.xml", REPEATS.format(body=body).encode()).mission
    assert mission is not None
    return plan_mission(mission)


def test_a_repeat_whose_rounds_fly_elsewhere_stays_unrolled() -> None:
    # Each round moves 10 m on from where the last ended: a DO_JUMP would fly the same
    # leg again.
    plan = _repeat_plan('<task name="legs"><repeat times="3"/><task name="m"><action '
                        'name="MOVE"><argument name="coordinates" value="(10, 0, 0)"/>'
                        '</action></task></task>')
    assert [i.command for i in plan.items] == [22, 16, 16, 16]
    assert len({i.x for i in plan.items[1:]}) == 3


def test_a_repeat_inside_a_repeat_is_a_do_jump_in_each_round() -> None:
    # ArduPilot counts a DO_JUMP's repeats once per mission: the outer repeat is unrolled,
    # so that each round's inner loop has its own DO_JUMP.
    plan = _repeat_plan(
        '<task name="outer"><repeat times="2"/><task name="inner"><repeat times="3"/>'
        '<task name="a"><action name="GO_TO_POSITION"><argument name="latitude" '
        'value="-35.36"/><argument name="longitude" value="149.16"/><argument '
        'name="altitude" value="10"/></action></task></task>'
        '<task name="b"><action name="WAIT"><argument name="duration" value="2"/></action>'
        '</task></task>')
    assert [(i.command, i.param1, i.param2) for i in plan.items if i.command != 16] == [
        (22, 15.0, 0.0), (177, 2.0, 2.0), (93, 2.0, -1.0), (177, 5.0, 2.0), (93, 2.0, -1.0)]


def test_a_do_jump_back_over_whole_actions_is_imported_as_a_repeat(tmp_path: Path) -> None:
    text = WPL_HOME + ("1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t20\t1\n"
                       "2\t0\t3\t16\t0\t0\t0\t0\t-35.3621\t149.1651\t20\t1\n"
                       "3\t0\t3\t16\t0\t0\t0\t0\t-35.3622\t149.1652\t20\t1\n"
                       "4\t0\t0\t177\t2\t3\t0\t0\t0\t0\t0\t1\n"  # back to 2, 3 more times
                       "5\t0\t0\t177\t3\t-1\t0\t0\t0\t0\t0\t1\n"  # forever: raw
                       "6\t0\t0\t177\t8\t1\t0\t0\t0\t0\t0\t1\n"  # forward: raw
                       "7\t0\t3\t16\t0\t0\t0\t0\t-35.3623\t149.1653\t20\t1\n"
                       "8\t0\t3\t21\t0\t0\t0\t0\t-35.3623\t149.1653\t20\t1\n")
    imported = import_plan(read_wpl(text), "loop")
    assert imported.raw == 2  # the two other DO_JUMPs
    root = etree.fromstring(imported.text.encode())
    loop, = root.iter("repeat")
    assert loop.get("times") == "4"
    body = loop.getparent()
    assert [t.get("name") for t in body.findall("task")] == [
        "item 2 (line 4): GO_TO_POSITION", "item 3 (line 5): GO_TO_POSITION"]
    assert [e.get("param1") for e in root.iter("mission_item")
            if e.get("command") == "MAV_CMD_DO_JUMP"] == ["3", "8"]
    _round_trip(read_wpl(text), tmp_path)


def test_a_do_jump_in_qgroundcontrols_frame_2_is_a_repeat_that_exports_back_in_it(
        tmp_path: Path) -> None:
    text = WPL_HOME + ("1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t20\t1\n"
                       "2\t0\t3\t16\t0\t0\t0\t0\t-35.3621\t149.1651\t20\t1\n"
                       "3\t0\t3\t16\t0\t0\t0\t0\t-35.3622\t149.1652\t20\t1\n"
                       "4\t0\t2\t177\t2\t1\t0\t0\t0\t0\t0\t1\n"  # back to 2, once more
                       "5\t0\t3\t21\t0\t0\t0\t0\t-35.3623\t149.1653\t20\t1\n")
    imported = import_plan(read_wpl(text), "loop")
    assert imported.raw == 0
    loop, = etree.fromstring(imported.text.encode()).iter("repeat")
    assert (loop.get("times"), loop.get("jump_frame")) == ("2", "2")
    back = _round_trip(read_wpl(text), tmp_path)
    assert (back.items[3].command, back.items[3].frame) == (mavlink.MAV_CMD_DO_JUMP, 2)


def test_a_do_jump_into_the_middle_of_an_action_stays_a_mission_item(tmp_path: Path) -> None:
    # Items 2-3 are one LANDING_POINT with a yaw (CONDITION_YAW, then NAV_LAND): a jump to
    # item 3 lands in the middle of it.
    text = WPL_HOME + ("1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t20\t1\n"
                       "2\t0\t2\t115\t90\t0\t0\t0\t0\t0\t0\t1\n"
                       "3\t0\t3\t21\t0\t0\t0\t90\t-35.3622\t149.1652\t20\t1\n"
                       "4\t0\t0\t177\t3\t1\t0\t0\t0\t0\t0\t1\n")
    imported = import_plan(read_wpl(text), "middle")
    assert "<repeat" not in imported.text and "LANDING_POINT" in imported.text
    _round_trip(read_wpl(text), tmp_path)


def test_plan_file_has_fence_obstacles_and_home() -> None:
    plan = plan_mission(load_mission(ROOT / "missions/verify_obstacles.xml"))
    document = json.loads(write_plan(plan))
    assert document["fileType"] == "Plan" and document["version"] == 1
    mission = document["mission"]
    assert mission["plannedHomePosition"] == [plan.home.latitude, plan.home.longitude,
                                              plan.home.altitude]
    assert [i["command"] for i in mission["items"]] == [i.command for i in plan.items]
    assert all(len(i["params"]) == 7 for i in mission["items"])
    fence = document["geoFence"]
    inclusion = [p for p in fence["polygons"] if p["inclusion"]]
    assert len(inclusion) == 1 and len(inclusion[0]["polygon"]) == 4
    assert len(fence["circles"]) + len(fence["polygons"]) - 1 == len(plan.world.obstacles)
    read = read_plan(json.dumps(document))
    assert [z.inclusion for z in read.zones].count(True) == 1


def test_waypoint_file_is_tab_separated_with_home_first() -> None:
    plan = plan_mission(load_mission(ROOT / "missions/mission_dispatch.xml"))
    lines = write_wpl(plan).splitlines()
    assert lines[0] == "QGC WPL 110"
    assert [len(line.split("\t")) for line in lines[1:]] == [12] * (len(plan.items) + 1)
    home = lines[1].split("\t")
    assert home[:4] == ["0", "1", "0", "16"]
    assert [float(v) for v in home[8:11]] == [plan.home.latitude, plan.home.longitude,
                                               plan.home.altitude]
    assert [int(line.split("\t")[0]) for line in lines[2:]] == list(
        range(1, len(plan.items) + 1))


def test_a_survey_made_in_qgroundcontrol_is_read_with_its_items() -> None:
    simple = {"type": "SimpleItem", "command": 16, "frame": 3, "autoContinue": True,
              "params": [0, 0, 0, None, -35.3630, 149.1650, 30]}
    document = {"fileType": "Plan", "version": 1, "mission": {"items": [
        {"type": "SimpleItem", "command": 22, "frame": 3, "params": [0, 0, 0, None, 0, 0, 30]},
        {"type": "ComplexItem", "complexItemType": "survey",
         "TransectStyleComplexItem": {"Items": [simple, simple]}},
        {"type": "ComplexItem", "complexItemType": "CorridorScan"},
        {"type": "SimpleItem", "command": 20, "frame": 2, "params": [0] * 7}]}}
    plan = read_plan(json.dumps(document))
    assert [i.command for i in plan.items] == [22, 16, 16, 20]
    assert plan.items[1].x == -353630000 and plan.items[1].seq == 1
    assert len(plan.losses) == 1
    assert plan.losses[0].startswith("item 3: complex item 'CorridorScan'")


@pytest.mark.parametrize("text, message", [
    ("{", "not JSON"),
    ('{"fileType": "Flight"}', "not a QGroundControl plan"),
    ('{"fileType": "Plan", "geoFence": {}}', 'the plan has no "mission"'),
    ('{"fileType": "Plan", "mission": {"items": [{"type": "SimpleItem", "command": 16, '
     '"frame": 3, "params": [1, 2]}]}}', "expected 7 params"),
])
def test_bad_plan_files_are_refused_saying_why(text: str, message: str) -> None:
    with pytest.raises(PlanFileError, match=message):
        read_plan(text, "bad.plan")


@pytest.mark.parametrize("text, message", [
    ("", "not a waypoint file"),
    ("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t1\t2\t3\n", r"bad:2: expected 12 fields, got 11"),
    ("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\tx\t2\t3\t1\n", "bad:2: could not convert"),
])
def test_bad_waypoint_files_are_refused_saying_where(text: str, message: str) -> None:
    with pytest.raises(PlanFileError, match=message):
        read_wpl(text, "bad")


def test_items_with_no_action_are_carried_as_mission_items(tmp_path: Path) -> None:
    text = ("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t-35.36\t149.16\t584\t1\n"
            "1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t12\t1\n"
            "2\t0\t0\t177\t5\t3\t0\t0\t0\t0\t0\t1\n"  # DO_JUMP forward
            "3\t0\t0\t114\t5\t0\t0\t0\t0\t0\t0\t1\n"  # CONDITION_DISTANCE
            "4\t0\t0\t116\t0\t0\t0\t0\t0\t0\t0\t1\n"  # no MAV_CMD has 116
            "5\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1\n")
    plan = read_wpl(text)
    imported = import_plan(plan, "jumps")
    assert imported.warnings == () and imported.losses == ()
    back = _imported_plan(imported.text, Kind.MULTICOPTER, tmp_path)
    assert [i.command for i in back.items] == [22, 177, 114, 116, 20]
    assert all(same_item(a, b) for a, b in zip(plan.items, back.items, strict=True))
    root = etree.fromstring(imported.text.encode())
    assert root.find("task").get("dispatch") == "mission"
    assert [t.get("name") for t in root.find("task")][1:3] == [
        "item 2 (line 4): DO_JUMP", "item 3 (line 5): CONDITION_DISTANCE"]
    result = validate_file("jumps.xml", imported.text.encode())
    assert [d.code for d in result.diagnostics] == ["W309"]  # 116 is no MAV_CMD


def test_geojson_and_kml_hold_the_path_obstacles_and_fence() -> None:
    plan = plan_mission(load_mission(ROOT / "missions/verify_obstacles.xml"))
    features = json.loads(write_geojson([plan], plan.world))["features"]
    kinds = [f["properties"]["kind"] for f in features]
    assert kinds.count("geofence") == 1 and kinds.count("path") == 1
    assert kinds.count("obstacle") == len(plan.world.obstacles)
    path = next(f for f in features if f["properties"]["kind"] == "path")
    assert path["geometry"]["type"] == "LineString"
    assert [round(c, 7) for c in path["geometry"]["coordinates"][0][:2]] == [
        plan.home.longitude, plan.home.latitude]  # GeoJSON: longitude first
    for feature in features:
        if feature["geometry"]["type"] == "Polygon":
            ring = feature["geometry"]["coordinates"][0]
            assert ring[0] == ring[-1]  # closed, as RFC 7946 requires
    root = etree.fromstring(write_kml([plan], plan.world, "x").encode())
    marks = root.findall(f".//{{{KML_NAMESPACE}}}Placemark")
    assert len(marks) == len(features)
    line = root.find(f".//{{{KML_NAMESPACE}}}LineString/{{{KML_NAMESPACE}}}coordinates")
    assert line is not None and line.text is not None
    assert len(line.text.split()) == len(path["geometry"]["coordinates"])


def test_every_role_is_drawn_on_a_map() -> None:
    plans = _plans(ROOT / "missions/dolphin_uav_surface.xml")
    features = json.loads(write_geojson(plans, plans[0].world))["features"]
    assert sorted(f["properties"]["role"] for f in features
                  if f["properties"]["kind"] == "path") == ["scout", "surface"]


WPL_HOME = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t-35.363262\t149.165237\t584.09\t1\n"


def _round_trip(plan: PlanFile, tmp_path: Path) -> Plan:
    imported = import_plan(plan, "again")
    assert imported.losses == ()
    back = _imported_plan(imported.text, Kind.MULTICOPTER, tmp_path)
    assert len(back.items) == len(plan.items)
    for a, b in zip(plan.items, back.items, strict=True):
        assert same_item(a, b), (a, b)
    return back


def test_waypoints_far_from_home_are_imported_where_they_are(tmp_path: Path) -> None:
    # 8,000 km from home: through the local frame item 2 came back at 7.87, 142.98.
    text = WPL_HOME + ("1\t0\t6\t22\t0\t0\t0\t0\t0\t0\t20\t1\n"
                       "2\t0\t6\t16\t0\t0\t0\t0\t36.3244251\t138.6379423\t20\t1\n"
                       "3\t0\t5\t16\t0\t0\t0\t0\t-35.2001234\t149.3998765\t612.5\t1\n"
                       "4\t0\t6\t21\t0\t0\t0\t0\t0\t0\t0\t1\n")
    back = _round_trip(read_wpl(text), tmp_path)
    assert (back.items[1].x, back.items[1].y) == (363244251, 1386379423)


def test_frames_without_int_are_actions_that_name_them(tmp_path: Path) -> None:
    # ArduPilot's and QGroundControl's files write frame 3 (GLOBAL_RELATIVE_ALT), 0 and 10
    # where tml writes 6, 5 and 11: the same position, so the same action, which says so.
    text = WPL_HOME + ("1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t20\t1\n"
                       "2\t0\t3\t16\t0\t0\t0\t0\t-35.3621\t149.1651\t20\t1\n"
                       "3\t0\t0\t16\t0\t0\t0\t0\t-35.3622\t149.1652\t620.5\t1\n"
                       "4\t0\t10\t16\t0\t0\t0\t0\t-35.3623\t149.1653\t30\t1\n"
                       "5\t0\t3\t19\t10\t0\t15\t0\t-35.3624\t149.1654\t20\t1\n"
                       "6\t0\t6\t16\t0\t0\t0\t0\t-35.3625\t149.1655\t20\t1\n"
                       "7\t0\t3\t21\t0\t0\t0\t0\t-35.3625\t149.1655\t20\t1\n")
    imported = import_plan(read_wpl(text), "frames")
    assert imported.raw == 0
    root = etree.fromstring(imported.text.encode())
    actions = root.findall(".//action")
    assert [a.get("name") for a in actions] == [
        "TAKE_OFF", "GO_TO_POSITION", "GO_TO_POSITION", "GO_TO_POSITION", "LOITER",
        "GO_TO_POSITION", "LANDING_POINT"]
    encodings = [a.find("argument[@name='frame_encoding']") for a in actions]
    assert [e is not None and e.get("value") for e in encodings] == [
        "float", "float", "float", "float", "float", False, "float"]
    back = _round_trip(read_wpl(text), tmp_path)
    assert [i.frame for i in back.items] == [3, 3, 0, 10, 3, 6, 3]


def test_a_null_param_stays_unset(tmp_path: Path) -> None:
    # QGroundControl writes NaN as null: an altitude null is not 0 m above sea level.
    document = {"fileType": "Plan", "version": 1, "mission": {
        "plannedHomePosition": [47.3977424, 8.545599, 488.103], "items": [
            {"type": "SimpleItem", "command": 22, "frame": 3, "autoContinue": True,
             "params": [0, 0, 0, None, 47.39781011, 8.54553801, 15]},
            {"type": "SimpleItem", "command": 16, "frame": 0, "autoContinue": True,
             "AltitudeMode": 3, "params": [0, 0, 0, None, 47.3978, 8.5454, None]}]}}
    plan = read_plan(json.dumps(document))
    assert math.isnan(plan.items[1].z) and math.isnan(plan.items[1].param4)
    back = _round_trip(plan, tmp_path)
    exported = json.loads(write_plan(back))["mission"]["items"]
    assert exported[1]["params"][3] is None and exported[1]["params"][6] is None


def test_line_0_of_a_waypoint_file_is_home_only_in_home_form() -> None:
    assert read_wpl(WPL_HOME + "1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t10\t1\n").home is not None
    # MAVSDK's sample starts with a take-off: it is an item, and there is no home.
    sample = read_wpl("QGC WPL 110\n0\t1\t5\t22\t0\t0\t0\t0\t47.3978101\t8.5455380\t15\t1\n"
                      "1\t0\t5\t16\t0\t0\t0\t0\t47.3977992\t8.5454669\t15\t1\n")
    assert sample.home is None and [i.command for i in sample.items] == [22, 16]
    assert sample.sources == ("item 0 (line 2)", "item 1 (line 3)")


def test_qgroundcontrols_older_layout_is_read() -> None:
    document = {"fileType": "Plan", "version": 1, "mission": {"version": 1, "items": [
        {"type": "SimpleItem", "command": 16, "frame": 3, "autoContinue": True,
         "coordinate": [47.3978, 8.5454, 25], "params": [5, 0, 0, 0]}]}}
    item, = read_plan(json.dumps(document)).items
    assert (item.param1, item.x, item.y, item.z) == (5.0, 473978000, 85454000, 25.0)


def test_items_are_counted_from_1_in_messages() -> None:
    document = {"fileType": "Plan", "mission": {"items": [
        {"type": "SimpleItem", "command": 16, "frame": 3, "params": [1, 2]}]}}
    with pytest.raises(PlanFileError, match="item 1: expected 7 params, got 2"):
        read_plan(json.dumps(document), "p.plan")


def test_what_has_no_tml_form_is_a_loss_naming_its_item() -> None:
    document = {"fileType": "Plan", "mission": {"plannedHomePosition": [1.5, 1.5, 0], "items": [
        {"type": "SimpleItem", "command": 22, "frame": 3, "params": [0, 0, 0, 0, 0, 0, 10]},
        {"type": "ComplexItem", "complexItemType": "StructureScan"},
        {"type": "SimpleItem", "command": 183, "frame": 2, "params": [9, 1500, 0, 0, 0.5, 0, 0]}
    ]}, "geoFence": {"polygons": [
        {"inclusion": True, "polygon": [[1, 1], [1, 2], [2, 2]]},
        {"inclusion": True, "polygon": [[3, 3], [3, 4], [4, 4]]}]},
        "rallyPoints": {"points": [[1.2, 1.8, 30], [1.2, 1.2, -5], [0.5, 1.5, 20]]}}
    imported = import_plan(read_plan(json.dumps(document)), "lossy")
    assert [loss.split(":")[0] for loss in imported.losses] == [
        "item 2", "item 3", "geofence zone 2", "rally point 2", "rally point 3"]
    assert "rally point 3: outside the geofence" in imported.losses[-1]
    assert '<point latitude="1.2" longitude="1.8" altitude="30"/>' in imported.text


def test_a_plan_with_no_item_is_refused() -> None:
    fence = read_wpl("QGC WPL 110\n0\t0\t0\t5003\t100\t0\t0\t0\t47.1\t8.5\t0\t1\n")
    assert fence.items == () and fence.zones[0].radius == 100.0
    with pytest.raises(PlanFileError, match=r"no mission items to fly \(it holds a fence"
                       r".*give one with --home"):
        import_plan(fence, "fence")


def test_values_an_action_refuses_are_kept_as_raw_items(tmp_path: Path) -> None:
    # CONDITION_YAW to 640 deg, photos at interval 0, a rover altitude beyond 10 km, a
    # waypoint hold, an abort altitude, a LOITER_TURNS exit flag, a gripper release.
    text = WPL_HOME + ("1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t10\t1\n"
                       "2\t0\t0\t115\t640\t0\t1\t0\t0\t0\t0\t1\n"
                       "3\t0\t0\t2000\t0\t0\t1\t0\t0\t0\t0\t1\n"
                       "4\t0\t3\t16\t5\t0\t0\t0\t-35.36\t149.16\t15000\t1\n"
                       "5\t0\t3\t18\t2\t0\t0\t1\t-35.36\t149.16\t20\t1\n"
                       "6\t0\t0\t211\t1\t0\t0\t0\t0\t0\t0\t1\n"
                       "7\t0\t3\t17\t0\t0\t0\t0\t-35.36\t149.16\t20\t1\n"  # radius 0
                       "8\t0\t0\t203\t1\t0\t0\t0\t1\t0\t0\t1\n"  # DIGICAM session 1
                       "9\t0\t3\t21\t630\t0\t0\t1\t-35.36\t149.16\t0\t1\n")
    _round_trip(read_wpl(text), tmp_path)


def test_zones_far_from_home_come_back_where_they_were(tmp_path: Path) -> None:
    # Through the local frame a circle 35 km from home came back 0.7 m off.
    document = {"fileType": "Plan", "mission": {
        "plannedHomePosition": [38.7508357856351, -77.496978971791, 30], "items": [
            {"type": "SimpleItem", "command": 22, "frame": 3, "params": [0, 0, 0, 0, 0, 0, 10]}]},
        "geoFence": {"polygons": [{"inclusion": True, "polygon": [
            [38.7507608625056, -77.49735908548331], [38.75094024382851, -77.49709285710168],
            [38.75073132744176, -77.49686508648041]]}],
            "circles": [{"inclusion": False, "circle": {"center": [38.9, -77.1],
                                                        "radius": 50.5}}]}}
    plan = read_plan(json.dumps(document))
    back = read_plan(write_plan(_round_trip(plan, tmp_path)))
    assert [(z.inclusion, z.points, z.radius) for z in back.zones] == [
        (z.inclusion, z.points, z.radius) for z in plan.zones]


def test_a_fence_without_a_home_is_a_loss() -> None:
    document = {"fileType": "Plan", "mission": {"items": [
        {"type": "SimpleItem", "command": 22, "frame": 3, "params": [0, 0, 0, 0, 0, 0, 10]}]},
        "geoFence": {"circles": [{"inclusion": False, "circle": {"center": [38.9, -77.1],
                                                                 "radius": 50}}]}}
    imported = import_plan(read_plan(json.dumps(document)), "homeless")
    assert imported.losses == ("1 fence zone(s): a mission places latitudes and longitudes "
                               "from its home, and the file gives none: left out",)
    assert validate_file("homeless.xml", imported.text.encode()).valid()


def test_a_plans_do_jump_names_its_target_by_doJumpId() -> None:
    # QGroundControl numbers a DO_JUMP's target by doJumpId and makes it a sequence number
    # when it uploads; here the ids start at 10.
    def item(command: int, jump_id: int, p1: float = 0) -> dict:
        return {"type": "SimpleItem", "command": command, "frame": 2, "doJumpId": jump_id,
                "params": [p1, 2, 0, 0, 0, 0, 0]}

    document = {"fileType": "Plan", "mission": {"items": [
        item(22, 10), item(93, 11), item(177, 12, 11), item(177, 13, 99)]}}
    plan = read_plan(json.dumps(document))
    assert [i.param1 for i in plan.items] == [0, 0, 2, 99]
    assert plan.losses == ("item 4: DO_JUMP to doJumpId 99, which no item has: left as "
                           "written",)


def test_values_no_mission_item_carries_are_losses_naming_their_item() -> None:
    text = WPL_HOME + ("1\t0\t3\t16\t0\t1e39\tinf\t0\t-35.3\t149.1\tnan\t1\n"
                       "2\t0\t3\t16\t0\t0\t0\t0\t1e300\t149.1\t10\t1\n")
    plan = read_wpl(text)
    assert [loss.split(" is ")[0] for loss in plan.losses] == [
        "item 1 (line 3): param2 1e+39", "item 1 (line 3): param3 inf",
        "item 2 (line 4): param5 1e+300"]
    assert math.isnan(plan.items[0].z)  # NaN is "not set", and carried
    document = {"fileType": "Plan", "mission": {"items": [
        {"type": "SimpleItem", "command": 16, "frame": 3, "params": [True, 0, 0, 0, 0, 0, 0]}]}}
    with pytest.raises(PlanFileError, match="item 1: True is not a number"):
        read_plan(json.dumps(document))


def test_a_plan_made_for_another_firmware_is_said() -> None:
    document = {"fileType": "Plan", "mission": {"firmwareType": 12, "items": [
        {"type": "SimpleItem", "command": 22, "frame": 3, "params": [0, 0, 0, 0, 0, 0, 10]}]}}
    assert read_plan(json.dumps(document)).skipped == (
        "the plan was made for firmware type 12 (PX4): its items are kept as written and "
        "flown as ArduPilot flies them; the export writes firmware type 12 back",)


def test_the_plans_mission_settings_come_back(tmp_path: Path) -> None:
    # QGroundControl's Mission Settings: planned home, firmware, vehicle, speeds.
    document = {"fileType": "Plan", "mission": {
        "firmwareType": 12, "vehicleType": 20, "cruiseSpeed": 17.5, "hoverSpeed": 3,
        "globalPlanAltitudeMode": 4,
        "plannedHomePosition": [47.3977419, 8.5455939, 487.9], "items": [
            {"type": "SimpleItem", "command": 22, "frame": 3, "params": [0, 0, 0, 0, 0, 0, 10]},
            {"type": "SimpleItem", "command": 20, "frame": 2, "params": [0] * 7}]}}
    imported = import_plan(read_plan(json.dumps(document)), "settings")
    settings = etree.fromstring(imported.text.encode()).find("environment/plan_settings")
    assert settings is not None and dict(settings.attrib) == {
        "firmware_type": "12", "vehicle_type": "20", "cruise_speed": "17.5", "hover_speed": "3",
        "altitude_mode": "4"}
    back = json.loads(write_plan(_imported_plan(imported.text, Kind.MULTICOPTER, tmp_path)))
    mission = back["mission"]
    assert (mission["firmwareType"], mission["vehicleType"], mission["cruiseSpeed"],
            mission["hoverSpeed"], mission["globalPlanAltitudeMode"]) == (12, 20, 17.5, 3, 4)
    assert mission["plannedHomePosition"] == [47.3977419, 8.5455939, 487.9]


def test_a_plans_global_altitude_mode_comes_back_as_given_or_not_given(tmp_path: Path) -> None:
    # QGroundControl reads a plan without globalPlanAltitudeMode as mixed (0): it stays
    # without one; a mode it has no AltMode for (7) is ignored, as the other settings are.
    for given, back in ((None, None), (0, 0), (2, 2), (7, None)):
        mission = {"firmwareType": 3, "plannedHomePosition": [47.39, 8.54, 488], "items": [
            {"type": "SimpleItem", "command": 22, "frame": 3, "params": [0] * 6 + [10]}]}
        if given is not None:
            mission["globalPlanAltitudeMode"] = given
        plan = read_plan(json.dumps({"fileType": "Plan", "mission": mission}))
        imported = import_plan(plan, "mode")
        written = json.loads(write_plan(_imported_plan(imported.text, Kind.MULTICOPTER,
                                                       tmp_path)))["mission"]
        assert written.get("globalPlanAltitudeMode") == back, given


def test_a_plan_from_tml_says_ardupilot_the_kind_and_qgroundcontrols_speeds() -> None:
    mission = json.loads(write_plan(plan_mission(
        load_mission(ROOT / "missions/mission_dispatch.xml"), kind=Kind.GROUND)))["mission"]
    assert (mission["firmwareType"], mission["vehicleType"], mission["cruiseSpeed"],
            mission["hoverSpeed"], mission["globalPlanAltitudeMode"]) == (3, 10, 15, 5, 1)


def test_rally_points_go_to_a_plan_and_come_back() -> None:
    plan = plan_mission(load_mission(ROOT / "missions/fenced_patrol.xml"))
    document = json.loads(write_plan(plan))
    points = document["rallyPoints"]["points"]
    assert [p[2] for p in points] == [15, 20]
    read = read_plan(json.dumps(document))
    assert read.rally == tuple(tuple(p) for p in points)
    imported = import_plan(read, "back")
    world = validate_file("back.xml", imported.text.encode()).mission.world
    assert world is not None and [(round(p.north, 1), round(p.east, 1), p.altitude)
                                  for p in world.rally] == [(100.0, -20.0, 15), (-25.0, 70.0, 20)]
    assert not [loss for loss in imported.losses if "rally" in loss]


def test_a_plan_altitude_mode_qgroundcontrol_has_not_is_refused() -> None:
    def errors(mode: str) -> list[str]:
        text = ('<mission name="m"><environment><plan_settings altitude_mode="' + mode
                + '"/></environment><task name="t"><action name="LAND"/></task></mission>')
        return [d.message for d in validate_file("m.xml", text.encode()).errors]

    assert errors("5") == [] and errors("6") != []


def test_a_plan_exports_back_its_ground_station_and_each_items_editor_fields(
        tmp_path: Path) -> None:
    def simple(seq: int, command: int, frame: int, params: list, **editor: object) -> dict:
        return {**editor, "autoContinue": True, "command": command, "doJumpId": seq,
                "frame": frame, "params": params, "type": "SimpleItem"}

    items = [simple(1, 22, 3, [0, 0, 0, None, -35.3632, 149.1652, 10], Altitude=10,
                    AltitudeMode=1, AMSLAltAboveTerrain=None),
             simple(2, 16, 0, [0, 0, 0, None, -35.3620, 149.1652, 600], Altitude=16,
                    AltitudeMode=3, AMSLAltAboveTerrain=600.5),
             simple(3, 20, 2, [0, 0, 0, 0, 0, 0, 0])]
    text = json.dumps({"fileType": "Plan", "version": 1, "groundStation": "LiniaGenerator",
                       "geoFence": {"circles": [], "polygons": [], "version": 2},
                       "rallyPoints": {"points": [], "version": 2},
                       "mission": {"items": items, "plannedHomePosition": [
                           -35.3632, 149.1652, 584], "version": 2}})
    imported = import_plan(read_plan(text, "p.plan"), "editor")
    assert imported.raw == 0 and imported.losses == ()
    back = json.loads(write_plan(_imported_plan(imported.text, Kind.MULTICOPTER, tmp_path)))
    assert back["groundStation"] == "LiniaGenerator"
    editor = ("Altitude", "AltitudeMode", "AMSLAltAboveTerrain")
    assert [{k: i[k] for k in editor if k in i} for i in back["mission"]["items"]] == [
        {k: i[k] for k in editor if k in i} for i in items]
    # A mission written in TML says it was tml.
    plain = _plans(ROOT / "missions/mission_dispatch.xml")[0]
    assert json.loads(write_plan(plain))["groundStation"] == "tml"
