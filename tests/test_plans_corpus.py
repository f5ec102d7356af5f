"""Public mission files written by others (tests/data/plans_corpus, SOURCES.md says whose):
each imports exactly or is refused for a stated reason, the mission validates, and its
export in the file's own format holds the same items, compared by the format's rules
(tests/plans_corpus.py)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import pytest
from lxml import etree
from plans_corpus import differences, read

from tml.language.build import load_world
from tml.language.validation import validate_file
from tml.plans.imported import import_plan
from tml.plans.planned import plan_mission
from tml.plans.qgc import PlanFileError, read_plan, write_plan
from tml.plans.wpl import read_wpl, write_fence, write_rally, write_wpl
from tml.world import Home

CORPUS = Path(__file__).parent / "data" / "plans_corpus"
FILES = sorted(p for p in CORPUS.iterdir() if p.suffix in (".plan", ".txt", ".mission"))

REFUSED = {
    "mavsdk_qgroundcontrol_sample_with_structured_scan.plan":
        "complex item 'StructureScan' saved without its mission items",
    "mavsdk_qgroundcontrol_sample_with_survey_missing_items.plan":
        "complex item 'survey' saved without its mission items",
    "mavsdk_qgroundcontrol_sample_without_mission.plan": 'the plan has no "mission"',
    # QGroundControl wrote the coordinate under the cursor into params 5-6 of a
    # VTOL_TRANSITION (frame 2), where a MISSION_ITEM_INT carries whole numbers only
    "px4_vtol_old_1.plan": "item 2: param5 47.398033142089844 in frame 2 is an integer",
}
"""The files refused by design, and why (a substring of the message)."""

WORLDS = {"qgc_geofence_rd_2.plan": "world file",
          "ardupilot_rover_path_planning_fence.txt": "world file",
          "ardupilot_rover_rally.txt": "world file"}
"""The files that hold a fence or rally points and no item: imported as a world file, whose
export laid over a mission gives the same fence and rally points back (and a fence or rally
list's export as one, the same list)."""

HOMES = {"ardupilot_rover_path_planning_fence.txt": Home(40.071613, -105.230118, 0),
         "ardupilot_rover_rally.txt": Home(40.071553, -105.229401, 0)}
"""The home a fence or rally list gives none of, as ``tml import --home`` gives it: the
first vertex or rally point."""


class Outcome(NamedTuple):
    """What became of a file: "exact", "world file" or the reason it was refused."""

    result: str
    items: int = 0  # in the file
    raw: int = 0  # carried as MISSION_ITEM
    repeats: int = 0  # DO_JUMPs imported as <repeat>


def outcome(path: Path, tmp_path: Path) -> Outcome:
    """Import ``path``, validate the mission and export it back in the file's format,
    asserting that the export holds the file's items."""
    try:
        source = read(path)
        if path.name in HOMES:
            source = replace(source, home=HOMES[path.name])
        imported = import_plan(source, path.stem)
    except PlanFileError as error:
        return Outcome(str(error))
    if imported.losses:
        return Outcome("; ".join(imported.losses), len(source.items))
    if imported.world:  # a fence and no item: a world file, laid over a one-task mission
        world = tmp_path / f"{path.stem}.xml"
        world.write_text(imported.text, encoding="utf-8")
        lands = validate_file("lands.xml", b'<mission name="m"><task name="t">'
                              b'<action name="LAND"/></task></mission>').mission
        assert lands is not None
        back = read_plan(write_plan(plan_mission(lands, world=load_world(world))))
        assert differences(source, replace(back, items=())) == []
        if path.suffix == ".txt":  # a fence or rally list: back to its own format too
            write = write_rally if source.rally else write_fence
            native = read_wpl(write(load_world(world)))
            assert differences(replace(source, home=None), native) == []
        return Outcome("world file")
    mission = tmp_path / f"{path.stem}.xml"
    mission.write_text(imported.text, encoding="utf-8")
    result = validate_file(mission)
    assert not result.errors, [str(d) for d in result.errors]
    assert result.mission is not None
    plan = plan_mission(result.mission)
    json = path.read_text(encoding="utf-8").lstrip().startswith("{")
    back = tmp_path / ("back.plan" if json else "back.waypoints")
    back.write_text(write_plan(plan) if json else write_wpl(plan), encoding="utf-8")
    assert differences(source, read(back)) == []
    return Outcome("exact", len(source.items), imported.raw,
                   imported.text.count("<repeat "))


def test_the_corpus_has_40_files_with_their_sources() -> None:
    sources = (CORPUS / "SOURCES.md").read_text(encoding="utf-8")
    assert len(FILES) >= 40
    missing = [p.name for p in FILES if f"`{p.name}`" not in sources]
    assert not missing, f"SOURCES.md does not name {missing}"


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_each_file_imports_exactly_and_exports_back_item_for_item(
        path: Path, tmp_path: Path) -> None:
    result = outcome(path, tmp_path).result
    if path.name in REFUSED:
        assert REFUSED[path.name] in result
    else:
        assert result == WORLDS.get(path.name, "exact")


SOURCES = {"ardupilot_copter": "ArduPilot copter autotest missions",
           "ardupilot_plane": "ArduPilot plane and quadplane",
           "ardupilot_quadplane": "ArduPilot plane and quadplane",
           "ardupilot_rover": "ArduPilot rover", "mavsdk": "MAVSDK test plans",
           "px4": "PX4 test missions", "qgc": "QGroundControl geofence"}
"""The source of each file, by the start of its name."""
ARTIFACT = Path(__file__).parent.parent / "test-artifacts" / "plans-corpus.md"


def test_the_closing_table_counts_every_file(tmp_path: Path) -> None:
    """The corpus in numbers, per source, written to test-artifacts/plans-corpus.md (the
    table docs/plans.md quotes): files, items, exact round trips, the items carried as
    actions and as MISSION_ITEMs, the DO_JUMPs imported as repeats, the refusals and why."""
    rows: dict[str, list[int]] = {}
    refusals: dict[str, list[str]] = {}
    for path in FILES:
        source = next(v for k, v in SOURCES.items() if path.name.startswith(k + "_"))
        folder = tmp_path / path.stem
        folder.mkdir()
        found = outcome(path, folder)
        row = rows.setdefault(source, [0] * 6)
        exact = found.result in ("exact", "world file")
        row[0] += 1
        row[1] += found.items
        row[2] += exact
        row[3] += found.items - found.raw if exact else 0
        row[4] += found.raw if exact else 0
        row[5] += found.repeats
        if not exact:
            refusals.setdefault(source, []).append(f"`{path.name}`: {REFUSED[path.name]}")
    lines = ["| source | files | items | exact round trips | items as actions | items as "
             "MISSION_ITEM | DO_JUMPs as `<repeat>` | refused, and why |",
             "|---|---|---|---|---|---|---|---|"]
    total = [0] * 6
    for source, row in rows.items():
        total = [a + b for a, b in zip(total, row, strict=True)]
        lines.append(f"| {source} | {' | '.join(map(str, row))} | "
                     f"{'; '.join(refusals.get(source, [])) or '-'} |")
    lines.append(f"| all | {' | '.join(map(str, total))} | "
                 f"{sum(map(len, refusals.values()))} files |")
    ARTIFACT.parent.mkdir(exist_ok=True)
    ARTIFACT.write_text("\n".join(lines) + "\n", encoding="utf-8")
    assert total[0] == len(FILES) and total[2] + len(REFUSED) == len(FILES)


FLOWN = ["ardupilot_copter_auto_land_to_brake.txt", "ardupilot_copter_do_change_speed.txt",
         "ardupilot_copter_far_origin.txt", "ardupilot_copter_gripper_mission.txt",
         "ardupilot_copter_loiter_to_alt.txt", "ardupilot_copter_nav_delay.txt",
         "ardupilot_copter_weathervane_mission.txt"]
"""The copter files the embedded simulator flies. The other copter files hold commands it
refuses in an upload (NAV_ARC_WAYPOINT, DO_AUX_FUNCTION, CONDITION_DISTANCE with
DO_SET_SERVO, DO_PARACHUTE, NAV_PAYLOAD_PLACE, command 5005) or a home at 0, 0, where it
finds no position; the terrain mission's waypoints are 6,000 km from its home, which the
verifier finds beyond the vehicle's range and battery (infeasible, not flown)."""


def _fly(name: str, tmp_path: Path, *options: str) -> int:
    from tml.commands.cli import main

    imported = import_plan(read(CORPUS / name), Path(name).stem)
    mission = tmp_path / "imported.xml"
    mission.write_text(imported.text, encoding="utf-8")
    return main(["run", str(mission), "--sim", "-q", "--speedup", "50", *options,
                 "--sim-param", "SIM_GPS_LOCKTIME=1", "--sim-param", "SIM_EKF_GPS_TIME=2"])


FORCED = {"ardupilot_copter_do_change_speed.txt": ["--force"]}
"""Files the verifier finds infeasible for the default copter profile, flown anyway: the
autotest asks DO_CHANGE_SPEED for 17 m/s, above the profile's 15 m/s (a SET_SPEED the
verifier reads)."""


@pytest.mark.parametrize("name", FLOWN)
def test_copter_files_fly_on_the_simulator(name: str, tmp_path: Path) -> None:
    assert _fly(name, tmp_path, *FORCED.get(name, [])) == 0


DRIVEN = ["ardupilot_rover_camera_mission.txt", "ardupilot_rover_drive_mission.txt",
          "ardupilot_rover_rtl.txt"]
"""Rover files the simulator's rover drives to the end, a few seconds each: the longest
(19 items: waypoints whose unused altitudes are 9-11 km, DO_CHANGE_SPEED), one that ends
in NAV_RETURN_TO_LAUNCH, one with camera items. The gripper and end-mission files drive as
well and are left out for time; the sprayer mission holds DO_SPRAYER, which the simulator
refuses in an upload. No plane or quadplane file flies on the simulator's plane: the
DO_CHANGE_SPEED mission has no take-off (the autotest flies the plane up by hand first),
and the others hold commands it refuses in an upload (NAV_PAYLOAD_PLACE in the delay
mission; NAV_ARC_WAYPOINT, NAV_LOITER_TO_ALT and the jump tags in the item-types tour;
NAV_VTOL_TAKEOFF and NAV_VTOL_LAND in both quadplane missions, for which it has no
frame)."""


@pytest.mark.parametrize("name", DRIVEN)
def test_rover_files_drive_on_the_simulator(name: str, tmp_path: Path) -> None:
    assert _fly(name, tmp_path, "--sim-frame", "rover", "--profile", "rover") == 0


@pytest.mark.parametrize(("name", "repeats", "raw"), [
    ("ardupilot_copter_far_origin.txt", ["2"], 0),  # back to item 8 once: items 8-9 twice
    ("ardupilot_quadplane_ksfo_vtol.txt", ["2"], 0),  # the circuit, items 3-6, twice
    # the triangle, items 20-22, twice; item 19 jumps 0 times: carried as written
    ("ardupilot_plane_mission_item_types.txt", ["2"], 1),
    ("ardupilot_plane_delay_secs.txt", [], 1),  # a DO_JUMP forever: carried as written
])
def test_do_jumps_back_over_whole_actions_are_repeats(name: str, repeats: list[str],
                                                      raw: int) -> None:
    text = import_plan(read(CORPUS / name), Path(name).stem).text
    root = etree.fromstring(text.encode("utf-8"))
    assert [r.get("times") for r in root.iter("repeat")] == repeats
    jumps = [e for e in root.iter("mission_item") if e.get("command") == "MAV_CMD_DO_JUMP"]
    assert len(jumps) == raw
