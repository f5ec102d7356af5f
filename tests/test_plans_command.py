"""``tml export`` and ``tml import`` from the command line, and MAVProxy loading the export."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import fields
from pathlib import Path

import pytest
from process_lines import follow, wait_for

from tml.commands.cli import main
from tml.language.validation import load_mission
from tml.mavlink.mission import (
    MissionItem,
    ardupilot_form,
    read_back_differences,
    with_home_placeholder,
)
from tml.plans.planned import plan_mission

ROOT = Path(__file__).resolve().parent.parent
DISPATCH = str(ROOT / "missions/mission_dispatch.xml")


def test_export_writes_each_format_by_suffix(tmp_path: Path, capsys) -> None:
    for suffix in (".plan", ".waypoints", ".kml", ".geojson"):
        out = tmp_path / f"m{suffix}"
        assert main(["export", DISPATCH, "-o", str(out)]) == 0
        assert out.stat().st_size > 0
    err = capsys.readouterr().err
    assert f"tml export: 15 mission item(s) written to {tmp_path / 'm.plan'}" in err
    assert json.loads((tmp_path / "m.plan").read_text())["fileType"] == "Plan"
    assert (tmp_path / "m.waypoints").read_text().startswith("QGC WPL 110\n")


def test_export_names_what_it_leaves_out(capsys) -> None:
    assert main(["export", str(ROOT / "missions/paper_example2.xml"), "--format", "wpl"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("QGC WPL 110\n")
    assert "paper_example2.xml: line 29: task 'Flip and move if green/Flip three times': " \
           "FLIP not exported" in err
    assert err.rstrip().endswith("1 action(s) not exported")


@pytest.mark.parametrize("argv, message", [
    (["export", DISPATCH], "--format plan|wpl|kml|geojson|fence|rally is needed"),
    (["export", DISPATCH, "-o", "x.txt.bak"], "(-o x.txt.bak: the suffix does not say)"),
    (["export", "nowhere.xml", "--format", "plan"], "nowhere.xml: No such file or directory"),
    (["export", str(ROOT / "missions/dolphin_uav_surface.xml"), "--format", "plan"],
     "--role names the one whose plan to write"),
    (["export", DISPATCH, "--format", "plan", "-o", "/nonexistent/dir/m.plan"],
     "-o /nonexistent/dir/m.plan: cannot write"),
    (["import", "nowhere.plan"], "nowhere.plan: No such file or directory"),
])
def test_usage_errors_exit_2_naming_the_value(argv: list[str], message: str, capsys) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_import_of_a_file_it_cannot_read_or_write_exits_2(tmp_path: Path, capsys) -> None:
    # As `tml import --help` says: 2 for a file that cannot be read or is not UTF-8 text
    # and for an output that cannot be written; 1 is for what the file holds.
    binary = tmp_path / "photo.plan"
    binary.write_bytes(b"\xff\xfe{\x00")
    assert main(["import", str(binary)]) == 2
    assert capsys.readouterr().err == f"tml import: {binary}: not UTF-8 text\n"
    assert main(["import", str(tmp_path)]) == 2
    assert f"tml import: {tmp_path}: Is a directory" in capsys.readouterr().err
    plan = tmp_path / "m.plan"
    assert main(["export", DISPATCH, "-o", str(plan)]) == 0
    capsys.readouterr()
    assert main(["import", str(plan), "-o", str(tmp_path / "no" / "m.xml")]) == 2
    assert f"-o {tmp_path / 'no' / 'm.xml'}: cannot write" in capsys.readouterr().err


def test_import_help_gives_each_exit_code_its_causes(capsys) -> None:
    assert main(["import", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    ones = text.split(" 1 ", 1)[1].split(" 2 ", 1)[0]
    twos = text.split(" 2 usage or I/O error ", 1)[1]
    for cause in ("not a plan or waypoint file", "holds nothing to fly",
                  "cannot carry exactly (without --allow-loss)", "makes an invalid mission"):
        assert cause in ones, cause
    for cause in ("cannot be read", "not UTF-8 text", "output that cannot be written"):
        assert cause in twos, cause


def test_an_invalid_mission_is_not_exported(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text('<mission name="m"><task name="t"><action name="GO_TO_PIONT"/></task>'
                   '</mission>')
    assert main(["export", str(bad), "--format", "plan"]) == 1
    assert "invalid mission, not exported" in capsys.readouterr().err


def test_import_of_a_file_that_is_not_a_plan_exits_1(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.waypoints"
    bad.write_text("hello\n")
    assert main(["import", str(bad)]) == 1
    assert "bad.waypoints:1: not a waypoint file" in capsys.readouterr().err


def test_import_refuses_what_it_cannot_carry_unless_allowed(tmp_path: Path, capsys) -> None:
    plan = tmp_path / "scan.plan"
    plan.write_text(json.dumps({"fileType": "Plan", "mission": {"items": [
        {"type": "SimpleItem", "command": 84, "frame": 3, "params": [0, 0, 0, 0, 0, 0, 10]},
        {"type": "ComplexItem", "complexItemType": "StructureScan"}]},
        "rallyPoints": {"points": [[47.1, 8.5, 30]]}}))
    mission = tmp_path / "scan.xml"
    assert main(["import", str(plan), "-o", str(mission)]) == 1
    err = capsys.readouterr().err
    assert "scan.plan: item 2: complex item 'StructureScan' saved without its mission items" \
        in err and "1 rally point(s): a mission places latitudes and longitudes from its " \
        "home, and the file gives none" in err
    assert "not written: 2 thing(s)" in err and not mission.exists()
    assert main(["import", str(plan), "-o", str(mission), "--allow-loss"]) == 0
    err = capsys.readouterr().err
    assert "1 mission item(s) as 1 task(s), 1 of them as MISSION_ITEM written" in err
    assert "left out (2, --allow-loss):\n" in err and mission.exists()


def test_export_then_import_then_validate(tmp_path: Path, capsys) -> None:
    plan = tmp_path / "m.plan"
    mission = tmp_path / "m.xml"
    assert main(["export", DISPATCH, "-o", str(plan)]) == 0
    assert main(["import", str(plan), "-o", str(mission)]) == 0
    assert "15 mission item(s) as 14 task(s) written" in capsys.readouterr().err
    assert main(["validate", str(mission)]) == 0
    assert main(["export", str(mission), "-o", str(tmp_path / "again.plan")]) == 0
    first = json.loads(plan.read_text())["mission"]["items"]
    again = json.loads((tmp_path / "again.plan").read_text())["mission"]["items"]
    assert [(i["command"], i["frame"]) for i in again] == [
        (i["command"], i["frame"]) for i in first]


def test_mavproxy_loads_the_exported_waypoint_file_into_the_simulator(tmp_path: Path) -> None:
    """MAVProxy's ``wp load`` (as benchmarks/upload.py drives it) reads the WPL export, and
    the vehicle stores every item as exported, home first."""
    from sitl.server import Simulator

    mavproxy = shutil.which("mavproxy.py", path=os.path.dirname(sys.executable))
    assert mavproxy, "MAVProxy is part of the test extra"
    waypoints = tmp_path / "mission.waypoints"
    assert main(["export", DISPATCH, "-o", str(waypoints)]) == 0
    plan = plan_mission(load_mission(DISPATCH))
    with Simulator(tcp_base_port=0, speedup=10) as sim:
        process = subprocess.Popen(
            [sys.executable, mavproxy, f"--master=tcp:127.0.0.1:{sim.tcp_ports[0]}",
             "--target-system=1", "--target-component=1", "--no-state",
             "--default-modules=wp", f"--state-basedir={tmp_path}"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            cwd=tmp_path, env={**os.environ, "MAVLINK20": "1"})
        sink = follow(process.stdout)
        seen: list[str] = []
        deadline = time.monotonic() + 60
        try:
            wait_for(sink, seen, r"Detected vehicle 1:1 ", deadline)
            assert process.stdin is not None
            process.stdin.write(f"wp load {waypoints}\n")
            process.stdin.flush()
            count = len(plan.items) + 1
            wait_for(sink, seen, rf"Loaded {count} waypoints? from", deadline)
            wait_for(sink, seen, r"Sent all \d+ waypoints|MISSION_ACK.*ACCEPTED", deadline)
            stored = sim.vehicle(1).mission_items
            while len(stored) < count and time.monotonic() < deadline:
                time.sleep(0.05)
                stored = sim.vehicle(1).mission_items
        finally:
            with contextlib.suppress(OSError):
                process.stdin.close()  # type: ignore[union-attr]
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
    assert [item.command for item in stored[1:]] == [item.command for item in plan.items]
    # Each item as ArduPilot keeps what tml itself uploads (the simulator stores as it does).
    read_back = [MissionItem(**{f.name: getattr(item, f.name) for f in fields(MissionItem)})
                 for item in stored]
    assert read_back_differences(with_home_placeholder(list(plan.items)), read_back,
                                 ardupilot_form, skip_home=True) == []


def test_export_names_what_of_the_world_a_format_cannot_hold(tmp_path: Path, capsys) -> None:
    assert main(["export", DISPATCH, "-o", str(tmp_path / "m.plan")]) == 0
    err = capsys.readouterr().err
    assert "note: the geofence's max_altitude 50 m is not in the plan" in err
    assert "note: obstacle 'radio mast': its top 30 m is not in the plan" in err
    assert main(["export", DISPATCH, "-o", str(tmp_path / "m.waypoints")]) == 0
    assert "note: the geofence and obstacles are not in a waypoint file" \
        in capsys.readouterr().err


def test_import_says_what_looks_odd_of_the_source_item(tmp_path: Path, capsys) -> None:
    plan = tmp_path / "yaw.waypoints"
    plan.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t-35.36\t149.16\t584\t1\n"
                    "1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t20\t1\n"
                    "2\t0\t0\t115\t640\t20\t1\t1\t0\t0\t0\t1\n")
    assert main(["import", str(plan), "-o", str(tmp_path / "yaw.xml")]) == 0
    assert "yaw.waypoints: note: item 2 (line 4): W311 MISSION_ITEM: CONDITION_YAW angle " \
        "param1 640 deg" in capsys.readouterr().err


def test_an_item_a_mission_cannot_hold_is_named_by_its_source_item(tmp_path: Path,
                                                                   capsys) -> None:
    plan = tmp_path / "north.waypoints"
    plan.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t-35.36\t149.16\t584\t1\n"
                    "1\t0\t3\t16\t0\t0\t0\t0\t95.5\t149.16\t20\t1\n")
    assert main(["import", str(plan), "-o", str(tmp_path / "north.xml")]) == 1
    err = capsys.readouterr().err
    assert "north.waypoints: item 1 (line 3): E263 MISSION_ITEM: param5 95.5 must be at " \
        "most 90 deg" in err and "north.xml:" not in err


def test_a_plan_with_a_fence_and_no_item_is_imported_as_a_world_file(tmp_path: Path,
                                                                      capsys) -> None:
    plan = tmp_path / "fence.plan"
    plan.write_text(json.dumps({"fileType": "Plan", "mission": {
        "items": [], "plannedHomePosition": [38.75, -77.49, 30]}, "geoFence": {
        "circles": [{"inclusion": False, "circle": {"center": [38.76, -77.48], "radius": 20}}],
        "polygons": []}}))
    world = tmp_path / "fence.xml"
    assert main(["import", str(plan), "-o", str(world)]) == 0
    assert "the fence (1 zone(s)) written as a world file" in capsys.readouterr().err
    assert main(["export", DISPATCH, "--world", str(world), "-o", str(tmp_path / "m.plan")]) == 0
    circles = json.loads((tmp_path / "m.plan").read_text())["geoFence"]["circles"]
    assert {"inclusion": False, "version": 1,
            "circle": {"center": [38.76, -77.48], "radius": 20.0}} in circles


FENCE_LIST = ROOT / "tests/data/plans_corpus/ardupilot_rover_path_planning_fence.txt"
RALLY_LIST = ROOT / "tests/data/plans_corpus/ardupilot_rover_rally.txt"


def test_a_fence_or_rally_list_needs_a_home_to_be_a_world_file(tmp_path: Path,
                                                               capsys) -> None:
    assert main(["import", str(FENCE_LIST)]) == 1
    assert "no home to place them from): give one with --home LAT,LON[,ALT]" \
        in capsys.readouterr().err
    world = tmp_path / "fence.xml"
    assert main(["import", str(FENCE_LIST), "--home", "40.071613,-105.230118",
                 "-o", str(world)]) == 0
    assert "the fence (3 zone(s)) written as a world file" in capsys.readouterr().err
    root = world.read_text()
    assert '<home latitude="40.071613" longitude="-105.230118" altitude="0"/>' in root
    assert root.count("<point ") == 19 + 4 and '<cylinder name="exclusion zone 3"' in root
    rally = tmp_path / "rally.xml"
    assert main(["import", str(RALLY_LIST), "--home", "40.071553,-105.229401,1589",
                 "-o", str(rally)]) == 0
    assert "the fence (0 zone(s)) and 2 rally point(s) written" in capsys.readouterr().err
    assert '<point latitude="40.072265" longitude="-105.231136" altitude="0"/>' \
        in rally.read_text() and 'altitude="1589"' in rally.read_text()


def test_a_rally_line_with_what_a_tml_rally_point_lacks_is_a_loss(tmp_path: Path,
                                                                   capsys) -> None:
    plan = tmp_path / "rally.txt"
    plan.write_text("RALLY 40.07 -105.22 30 40 0 0\nRALLY 40.08 -105.23 30 60 90 1\n")
    assert main(["import", str(plan), "--home", "40.07,-105.22"]) == 1
    err = capsys.readouterr().err
    assert "rally point 2 (line 2): break altitude 60 m, landing direction 90, flags 1" in err
    assert main(["import", str(plan), "--home", "40.07,-105.22,x"]) == 2
    assert "--home: expected LAT,LON[,ALT]" in capsys.readouterr().err


def test_the_files_home_is_kept_over_the_home_option(tmp_path: Path, capsys) -> None:
    plan = tmp_path / "fence.txt"
    plan.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t47.0\t8.5\t400\t1\n"
                    "1\t0\t0\t5004\t100\t0\t0\t0\t47.1\t8.5\t0\t1\n")
    assert main(["import", str(plan), "--home", "40.07,-105.22"]) == 0
    captured = capsys.readouterr()
    assert "note: the file's home is kept" in captured.err
    assert '<home latitude="47" longitude="8.5" altitude="400"/>' in captured.out


def test_a_world_exports_back_to_its_fence_and_rally_lists(tmp_path: Path, capsys) -> None:
    world = tmp_path / "fence.xml"
    assert main(["import", str(FENCE_LIST), "--home", "40.071613,-105.230118",
                 "-o", str(world)]) == 0
    back = tmp_path / "fence.txt"
    assert main(["export", str(world), "--format", "fence", "-o", str(back)]) == 0
    assert "24 fence item(s) written" in capsys.readouterr().err

    def fields(line: str) -> tuple[float, ...]:  # the numbers, however written
        return tuple(map(float, line.split()[1:]))

    assert [fields(line) for line in back.read_text().splitlines()[1:]] == [
        fields(line) for line in FENCE_LIST.read_text().splitlines()[1:]]
    assert main(["export", str(world), "--format", "plan"]) == 1
    assert "expected a <mission> document, found a world file" in capsys.readouterr().err
    rally = tmp_path / "rally.xml"
    assert main(["import", str(RALLY_LIST), "--home", "40.071553,-105.229401",
                 "-o", str(rally)]) == 0
    assert main(["export", str(rally), "--format", "rally", "-o", str(back)]) == 0
    assert [line.split()[0] for line in back.read_text().splitlines()] == ["RALLY"] * 2
    assert [fields(line) for line in back.read_text().splitlines()] == [
        fields(line) for line in RALLY_LIST.read_text().splitlines()]


def test_a_fence_list_names_what_it_cannot_hold(capsys) -> None:
    assert main(["export", str(ROOT / "missions/fenced_patrol.xml"), "--format", "fence"]) == 0
    err = capsys.readouterr().err
    assert "note: 2 rally point(s) not in a fence list: export --format rally" in err
    assert "the geofence's max_altitude 40 m is not in the fence list" in err
    assert "obstacle 'shed': its top 6 m is not in the fence list" in err
