"""Public copter mission files (tests/data/plans_corpus), imported by tml and compiled
back, upload to ArduCopter SITL and read back the same items, compared by ArduPilot's
rules (tml.mavlink.mission.ardupilot_form): what tml exports of a file is what ArduCopter
keeps of it."""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from plans_corpus import read
from process_lines import follow, wait_for
from test_mission_transfer import connect, upload_when_ready

from tml.commands.cli import main
from tml.language.validation import validate_file
from tml.mavlink.link import Link
from tml.mavlink.mission import (
    ardupilot_form,
    exact_form,
    read_back_differences,
    with_home_placeholder,
)
from tml.plans.imported import import_plan
from tml.plans.planned import plan_mission

CORPUS = Path(__file__).resolve().parents[1] / "data" / "plans_corpus"
SELECTION = ["ardupilot_copter_far_origin.txt", "ardupilot_copter_spline_last_waypoint.txt",
             "ardupilot_copter_auto_land_to_brake.txt", "ardupilot_copter_loiter_to_alt.txt",
             "ardupilot_copter_do_change_speed.txt", "ardupilot_copter_weathervane_mission.txt",
             "ardupilot_copter_gripper_mission.txt", "mavsdk_qgroundcontrol_sample.plan"]
"""Copter files of every kind of item. Not here: NAV_ARC_WAYPOINT and command 116 (the
WPArcs and ConditionLocation tests of a later ArduPilot), which the ArduCopter build in
../shared/ardupilot refuses as UNSUPPORTED."""


@pytest.mark.parametrize("name", SELECTION)
def test_an_imported_file_uploads_to_arducopter_and_reads_back_the_same(
        name: str, ardupilot, tmp_path: Path) -> None:
    source = read(CORPUS / name)
    mission = tmp_path / "imported.xml"
    mission.write_text(import_plan(source, Path(name).stem).text, encoding="utf-8")
    result = validate_file(mission)
    assert result.mission is not None and not result.errors
    items = list(plan_mission(result.mission).items)
    (sitl,) = ardupilot()
    with Link(sitl.address) as link:
        vehicle = connect(link)
        sent = upload_when_ready(vehicle, items)
        back = vehicle.download()
    assert len(back) == len(source.items) + 1  # behind ArduPilot's home
    assert read_back_differences(sent, back, ardupilot_form, skip_home=True) == []


WAYPOINT_FILES = ["ardupilot_copter_far_origin.txt", "ardupilot_copter_auto_land_to_brake.txt"]


def mavproxy_load(sitl: object, waypoints: Path, tmp_path: Path) -> list:
    """What ArduCopter reads back after MAVProxy's ``wp load`` of ``waypoints``."""
    mavproxy = shutil.which("mavproxy.py", path=os.path.dirname(sys.executable))
    assert mavproxy, "MAVProxy is part of the test extra"
    address = sitl.address  # type: ignore[attr-defined]
    system = sitl.system_id  # type: ignore[attr-defined]  # instance + 1: 21 on a 2nd worker
    process = subprocess.Popen(
        [sys.executable, mavproxy, f"--master={address}", f"--target-system={system}",
         "--target-component=1", "--no-state", "--default-modules=wp",
         f"--state-basedir={tmp_path}"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        cwd=tmp_path, env={**os.environ, "MAVLINK20": "1"})
    sink = follow(process.stdout)
    seen: list[str] = []
    deadline = time.monotonic() + 90
    try:
        wait_for(sink, seen, rf"Detected vehicle {system}:1 ", deadline)
        time.sleep(2)  # ArduCopter answers NO_SPACE to uploads for about a second after boot
        assert process.stdin is not None
        process.stdin.write(f"wp load {waypoints}\n")
        process.stdin.flush()
        wait_for(sink, seen, r"Sent all \d+ waypoints|MISSION_ACK.*ACCEPTED", deadline)
    finally:
        with contextlib.suppress(OSError):
            process.stdin.close()  # type: ignore[union-attr]
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    with Link(address) as link:
        return connect(link).download()


@pytest.mark.parametrize("name", WAYPOINT_FILES)
def test_mavproxy_loads_tmls_export_of_a_file_as_it_loads_the_file(
        name: str, ardupilot, tmp_path: Path) -> None:
    """The waypoint file tml exports of an imported file and the original file, each loaded
    with MAVProxy's ``wp load`` into ArduCopter, read back the same, field for field.
    (MAVProxy truncates degrees to 1e-7-degree integers where tml rounds: 149.164563 goes
    up as 1491645629; the export writes the same decimals, so MAVProxy makes the same of
    both.)"""
    source = read(CORPUS / name)
    mission = tmp_path / "imported.xml"
    mission.write_text(import_plan(source, Path(name).stem).text, encoding="utf-8")
    waypoints = tmp_path / "export.waypoints"
    assert main(["export", str(mission), "-o", str(waypoints)]) == 0
    (sitl,) = ardupilot()
    original = mavproxy_load(sitl, CORPUS / name, tmp_path)
    exported = mavproxy_load(sitl, waypoints, tmp_path)  # in place of the original
    assert len(original) == len(source.items) + 1
    assert read_back_differences(original, exported, exact_form, skip_home=True) == []
    # And both are the file's items as ArduCopter keeps them, but for MAVProxy's
    # truncation of a degree to 1e-7 (at most one unit of x or y).
    for wrong in read_back_differences(with_home_placeholder(list(source.items)), original,
                                       ardupilot_form, skip_home=True):
        assert wrong.field in ("x", "y") and abs(wrong.sent - wrong.read) == 1, wrong
