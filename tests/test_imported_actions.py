"""Mission items as planners write them import as actions, and those actions fly.

A waypoint's hold, acceptance radius, pass radius and yaw (GO_TO_POSITION), the position and
yaw a take-off carries (TAKE_OFF), the throttle of a speed change (SET_SPEED) and the frame of
an item without a position (RETURN_HOME_AND_LAND, SET_SPEED, WAIT) and a NAV_DELAY's unused time
of day (WAIT) are arguments: the items come back
exactly, and the actions fly with ``dispatch="command"`` as well as in AUTO on the simulator.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from lxml import etree
from shared_flights import FAST

from tml.commands.cli import main
from tml.language.kinds import Kind
from tml.language.model import Mission
from tml.language.validation import validate_file
from tml.plans.imported import import_plan, same_item
from tml.plans.planned import plan_mission
from tml.plans.qgc import PlanFile, read_plan
from tml.plans.wpl import read_wpl

pytestmark = pytest.mark.timeout(600)

HOME = [-35.363262, 149.165237, 584.09]


def _qgc_item(seq: int, command: int, frame: int, params: list[Any]) -> dict[str, Any]:
    return {"AMSLAltAboveTerrain": None, "Altitude": params[6], "AltitudeMode": 1,
            "autoContinue": True, "command": command, "doJumpId": seq, "frame": frame,
            "params": params, "type": "SimpleItem"}


def _plain_plan() -> str:
    """QGroundControl's plain plan: take-off, three waypoints with the yaw unset, RTL."""
    lat, lon, _ = HOME
    items = [_qgc_item(1, 22, 3, [0, 0, 0, None, lat, lon, 10])]
    items += [_qgc_item(2 + n, 16, 3, [0, 0, 0, None, lat + 0.0003 * (n + 1), lon, 20])
              for n in range(3)]
    items.append({"autoContinue": True, "command": 20, "doJumpId": 5, "frame": 2,
                  "params": [0, 0, 0, 0, 0, 0, 0], "type": "SimpleItem"})
    return json.dumps({
        "fileType": "Plan", "groundStation": "QGroundControl", "version": 1,
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "mission": {"cruiseSpeed": 15, "firmwareType": 3, "hoverSpeed": 5, "items": items,
                    "plannedHomePosition": HOME, "vehicleType": 2, "version": 2}})


def imported_and_back(plan: PlanFile, tmp_path: Path) -> tuple[str, Mission]:
    """The mission ``plan`` imports as (its text, and the mission validated from it), after
    checking that it loses nothing and compiles back to the plan's very items."""
    imported = import_plan(plan, "imported")
    assert imported.losses == ()
    path = tmp_path / "imported.xml"
    path.write_text(imported.text)
    result = validate_file(path)
    assert not result.errors, [str(d) for d in result.errors]
    assert result.mission is not None
    back = plan_mission(result.mission, kind=Kind.MULTICOPTER)
    assert len(back.items) == len(plan.items)
    for a, b in zip(plan.items, back.items, strict=True):
        assert same_item(a, b), (a, b)
    return imported.text, result.mission


def _actions_and_back(plan: PlanFile, tmp_path: Path) -> list[etree._Element]:
    """The actions ``plan`` imports as, after checking that they compile back to its very
    items."""
    text, _ = imported_and_back(plan, tmp_path)
    return etree.fromstring(text.encode()).findall(".//action")


def _arguments(action: etree._Element) -> dict[str, str]:
    return {a.get("name"): a.get("value") for a in action.findall("argument")}


def test_a_plain_qgroundcontrol_plan_imports_every_item_as_an_action(tmp_path: Path) -> None:
    actions = _actions_and_back(read_plan(_plain_plan(), "plain.plan"), tmp_path)
    assert [a.get("name") for a in actions] == [
        "TAKE_OFF", "GO_TO_POSITION", "GO_TO_POSITION", "GO_TO_POSITION",
        "RETURN_HOME_AND_LAND"]
    take_off = _arguments(actions[0])
    assert (take_off["latitude"], take_off["longitude"], take_off["yaw"]) == (
        "-35.363262", "149.165237", "NaN")
    assert all(_arguments(a)["yaw"] == "NaN" for a in actions[1:4])


WPL = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t-35.363262\t149.165237\t584.09\t1\n"


def test_waypoint_take_off_speed_and_return_items_keep_every_param(tmp_path: Path) -> None:
    # As ArduPilot's autotest and Mission Planner write them: a take-off with a position,
    # speed changes in frame 0 with throttle 0, waypoints with a hold, an acceptance and a
    # pass radius and a yaw, RTL in frames 0 and 3.
    text = WPL + ("1\t0\t3\t22\t0\t0\t0\t0\t-35.36279\t149.165127\t10\t1\n"
                  "2\t0\t0\t178\t1\t15\t0\t0\t0\t0\t0\t1\n"
                  "3\t0\t3\t16\t5\t2\t-3\t90\t-35.3620\t149.1652\t20\t1\n"
                  "4\t0\t3\t16\t0\t0\t0\tnan\t-35.3615\t149.1652\t20\t1\n"
                  "5\t0\t3\t178\t0\t8\t-1\t0\t0\t0\t0\t1\n"
                  "6\t0\t0\t20\t0\t0\t0\t0\t0\t0\t0\t1\n"
                  "7\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1\n"
                  "8\t0\t0\t211\t0\t0\t0\t0\t0\t0\t0\t1\n")
    actions = _actions_and_back(read_wpl(text), tmp_path)
    assert [a.get("name") for a in actions] == [
        "TAKE_OFF", "SET_SPEED", "GO_TO_POSITION", "GO_TO_POSITION", "SET_SPEED",
        "RETURN_HOME_AND_LAND", "RETURN_HOME_AND_LAND", "DROP_ITEM"]
    speed, waypoint, unset, again, rtl, rtl3, drop = (_arguments(a) for a in actions[1:])
    assert drop == {"gripper": "0", "frame": "MAV_FRAME_GLOBAL"}
    assert (speed["speed_type"], speed["throttle"], speed["frame"]) == (
        "ground", "0", "MAV_FRAME_GLOBAL")
    assert "throttle" not in again and again["frame"] == "MAV_FRAME_GLOBAL_RELATIVE_ALT"
    assert {k: waypoint[k] for k in ("hold", "acceptance_radius", "pass_radius", "yaw")} == {
        "hold": "5", "acceptance_radius": "2", "pass_radius": "-3", "yaw": "90"}
    assert unset["yaw"] == "NaN" and "hold" not in unset
    assert rtl == {"frame": "MAV_FRAME_GLOBAL"}
    assert rtl3 == {"frame": "MAV_FRAME_GLOBAL_RELATIVE_ALT"}


TARGET = (-35.3630, 149.1652, 12.0)
MISSION = f"""<?xml version="1.0" encoding="UTF-8"?>
<mission name="imported actions">
  <task name="Fly" dispatch="{{dispatch}}">
    <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/>
      <argument name="latitude" value="-35.363262"/>
      <argument name="longitude" value="149.165237"/>
      <argument name="yaw" value="90"/></action></task>
    <task name="Slow"><action name="SET_SPEED"><argument name="speed" value="4"/>
      <argument name="throttle" value="50"/><argument name="frame" value="GLOBAL"/>
    </action></task>
    <task name="There"><action name="GO_TO_POSITION">
      <argument name="latitude" value="{TARGET[0]}"/>
      <argument name="longitude" value="{TARGET[1]}"/>
      <argument name="altitude" value="{TARGET[2]}"/>
      <argument name="acceptance_radius" value="2"/><argument name="yaw" value="180"/>
      <argument name="hold" value="4"/><argument name="pass_radius" value="0"/>
    </action></task>
    <task name="Drop"><action name="DROP_ITEM"><argument name="gripper" value="0"/>
      <argument name="frame" value="0"/></action></task>
    <task name="Pause"><action name="WAIT"><argument name="duration" value="3"/>
      <argument name="time_of_day" value="0"/><argument name="frame" value="GLOBAL"/>
    </action></task>
    <task name="Home"><action name="RETURN_HOME_AND_LAND">
      <argument name="frame" value="GLOBAL"/></action></task>
  </task>
</mission>
"""


def _flown(tmp_path: Path, dispatch: str) -> list[dict[str, Any]]:
    mission, log = tmp_path / f"{dispatch}.xml", tmp_path / f"{dispatch}.jsonl"
    mission.write_text(MISSION.format(dispatch=dispatch))
    assert main(["run", str(mission), "--sim", "--log", str(log), *FAST]) == 0
    return [json.loads(line) for line in log.read_text().splitlines()]


def _held_at_target(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The telemetry with the vehicle stopped within 2 m of the target (local north and
    east from the log's global position)."""
    def near(r: dict[str, Any]) -> bool:
        lat, lon, _ = r["global"]
        north = (lat - TARGET[0]) * 111_320.0
        east = (lon - TARGET[1]) * 111_320.0 * math.cos(math.radians(lat))
        return math.hypot(north, east) <= 2.0 and r["ground_speed"] <= 0.3 \
            and abs(r["position"][2] - TARGET[2]) <= 1.0
    return [r for r in records if r["kind"] == "telemetry" and r["armed"] and near(r)]


def _between(records: list[dict[str, Any]], start: str, end: str) -> list[dict[str, Any]]:
    def said(r: dict[str, Any]) -> str:
        return str(r.get("message") or r.get("text"))

    first = next(n for n, r in enumerate(records) if said(r) == start)
    last = next(n for n, r in enumerate(records) if said(r) == end)
    return records[first:last + 1]


def _paused(records: list[dict[str, Any]]) -> float:
    """How long ``records`` span, in the vehicle's time, once every picture of the
    telemetry among them shows the vehicle stopped within 1 m of the first."""
    seen = [r for r in records if r["kind"] == "telemetry"]
    assert len(seen) >= 2
    assert all(math.dist(r["position"], seen[0]["position"]) <= 1.0
               and r["ground_speed"] <= 0.3 for r in seen), "moved while it should wait"
    return float(records[-1]["t"] - records[0]["t"])


def test_a_delay_as_ardupilot_writes_it_is_a_wait(tmp_path: Path) -> None:
    # ArduPilot's autotest writes a NAV_DELAY's unused time of day as 0 and its frame 0.
    text = WPL + ("1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t10\t1\n"
                  "2\t0\t0\t93\t5\t0\t0\t0\t0\t0\t0\t1\n"
                  "3\t0\t2\t93\t7\t-1\t-1\t-1\t0\t0\t0\t1\n")
    actions = _actions_and_back(read_wpl(text), tmp_path)
    assert [(a.get("name"), _arguments(a)) for a in actions[1:]] == [
        ("WAIT", {"duration": "5", "time_of_day": "0", "frame": "MAV_FRAME_GLOBAL"}),
        ("WAIT", {"duration": "7"})]


def test_the_actions_fly_with_commands(tmp_path: Path) -> None:
    records = _flown(tmp_path, "command")
    requests = [r for r in records if r["kind"] == "request"]
    (speed,) = [r for r in requests if r["message"] == "SetSpeed"]
    assert (speed["speed"], speed["throttle"]) == (4.0, 50.0)
    assert [r["grab"] for r in requests if r["message"] == "Gripper"] == [False]
    # The take-off climbs where the vehicle is, then faces its yaw.
    take_off = _between(records, "TAKE_OFF started", "TAKE_OFF done")
    seen = [r for r in take_off if r["kind"] == "telemetry"]
    assert all(abs(r["position"][0]) < 0.5 and abs(r["position"][1]) < 0.5 for r in seen)
    assert [r["heading"] for r in take_off if r["kind"] == "request"
            and r["message"] == "SetYaw"] == [90.0]
    after = next(r for r in records[len(records) - records[::-1].index(take_off[-1]):]
                 if r["kind"] == "telemetry")  # the first picture after it was done
    assert abs(after["heading"] - 90) <= 5 and after["position"][2] >= 9.5
    # The waypoint: reached, turned to 180 degrees, held there 4 s of the vehicle's time.
    moved = _between(records, "GO_TO_POSITION started", "GO_TO_POSITION done")
    facing = [r for r in _held_at_target(moved) if abs(r["heading"] - 180) <= 5]
    assert facing and facing[-1]["t"] - facing[0]["t"] >= 3
    assert [r["heading"] for r in moved if r["kind"] == "request"
            and r["message"] == "SetYaw"] == [180.0]
    assert moved[-1]["t"] - next(r["t"] for r in moved if r["kind"] == "request"
                                 and r["message"] == "Hold") >= 4
    # The wait: hovering where the vehicle was for its 3 s.
    assert _paused(_between(records, "WAIT started", "WAIT done")) >= 3
    assert records[-1]["kind"] == "run"


def test_the_actions_fly_as_mission_items_in_auto(tmp_path: Path) -> None:
    records = _flown(tmp_path, "mission")
    texts = [r["text"] for r in records if r["kind"] == "autopilot"]
    said = [t for t in texts if t.startswith("Mission:")]
    assert said == ["Mission: 1 Takeoff", "Mission: 2 ChangeSpeed", "Mission: 3 WP",
                    "Mission: 4 Gripper", "Mission: 5 Delay", "Mission: 6 RTL"]
    # ArduCopter holds at a waypoint for its param1 before it goes on.
    at = _between(records, "Mission: 3 WP", "Mission: 4 Gripper")
    held = _held_at_target(at)
    assert held and held[-1]["t"] - held[0]["t"] >= 3
    assert all(r["mode"] == "AUTO" for r in at if r["kind"] == "telemetry")
    # The NAV_DELAY, its time of day written 0 and its frame 0, holds for its 3 s.
    assert _paused(_between(records, "Mission: 5 Delay", "Mission: 6 RTL")) >= 3



# --- a NAV_LAND as ArduPilot writes it back: param4 1, altitude 0 -----------------------------

def test_a_landing_as_ardupilot_writes_it_is_a_landing_point(tmp_path: Path) -> None:
    # ardupilot_copter_auto_land_to_brake.txt: NAV_LANDs at a position at 0 m above home with
    # param4 1; one after a turn to 1 degree is that yaw, one at 20 m keeps no altitude.
    text = WPL + ("1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t20\t1\n"
                  "2\t0\t3\t21\t0\t0\t0\t1\t-35.3630\t149.1652\t0\t1\n"
                  "3\t0\t3\t22\t0\t0\t0\t0\t0\t0\t20\t1\n"
                  "4\t0\t3\t21\t0\t0\t0\t-1\t-35.3630\t149.1652\t20\t1\n"
                  "5\t0\t3\t22\t0\t0\t0\t0\t0\t0\t20\t1\n"
                  "6\t0\t2\t115\t1\t0\t0\t0\t0\t0\t0\t1\n"
                  "7\t0\t6\t21\t0\t0\t0\t1\t-35.3630\t149.1652\t20\t1\n")
    actions = _actions_and_back(read_wpl(text), tmp_path)
    assert [a.get("name") for a in actions] == [
        "TAKE_OFF", "LANDING_POINT", "TAKE_OFF", "LANDING_POINT", "TAKE_OFF", "LANDING_POINT"]
    first, second, third = (_arguments(actions[n]) for n in (1, 3, 5))
    assert (first["loiter_direction"], first["keep_altitude"], first["altitude"]) == (
        "clockwise", "yes", "0")
    assert second["loiter_direction"] == "counter-clockwise" and "keep_altitude" not in second
    assert third["yaw"] == "1" and "loiter_direction" not in third


LANDING = (-35.3630, 149.1652)
LANDING_MISSION = f"""<?xml version="1.0" encoding="UTF-8"?>
<mission name="landing as written">
  <task name="Fly" dispatch="{{dispatch}}">
    <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/></action>
    </task>
    <task name="Down"><action name="LANDING_POINT">
      <argument name="latitude" value="{LANDING[0]}"/>
      <argument name="longitude" value="{LANDING[1]}"/>
      <argument name="altitude" value="0"/><argument name="keep_altitude" value="yes"/>
      <argument name="loiter_direction" value="clockwise"/></action></task>
  </task>
</mission>
"""


@pytest.mark.parametrize("dispatch", ["command", "mission"])
def test_the_landing_point_flies_over_at_its_altitude_and_lands_there(
        tmp_path: Path, dispatch: str) -> None:
    mission, log = tmp_path / "landing.xml", tmp_path / "landing.jsonl"
    mission.write_text(LANDING_MISSION.format(dispatch=dispatch))
    assert main(["run", str(mission), "--sim", "--log", str(log), *FAST]) == 0
    records = [json.loads(line) for line in log.read_text().splitlines()]

    def off(r: dict[str, Any]) -> float:  # metres from the landing point, horizontally
        lat, lon, _ = r["global"]
        return math.hypot((lat - LANDING[0]) * 111_320.0,
                          (lon - LANDING[1]) * 111_320.0 * math.cos(math.radians(lat)))

    seen = [r for r in records if r["kind"] == "telemetry"]
    up = next(n for n, r in enumerate(seen) if r["position"][2] >= 9.5)
    # The altitude 0 the item carries is not flown to: over the point at 10 m, then down.
    on_the_way = [r for r in seen[up:] if off(r) > 3.0 and r["armed"]]
    assert on_the_way and all(r["position"][2] >= 9.0 for r in on_the_way)
    assert not seen[-1]["armed"] and off(seen[-1]) <= 2.0 and seen[-1]["position"][2] < 0.5
