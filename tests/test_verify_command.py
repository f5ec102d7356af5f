"""``tml verify``: exit codes, messages with file:line, JSON output, the corpus of
infeasible examples."""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

import pytest

from tml.commands.cli import main

ROOT = Path(__file__).parent.parent
FEASIBLE = ROOT / "missions" / "verify_obstacles.xml"
INFEASIBLE = Path(__file__).parent / "data" / "infeasible"
EXPECTED = tomllib.loads((INFEASIBLE / "expected.toml").read_text())


def test_corpus_is_complete() -> None:
    assert {p.name for p in INFEASIBLE.glob("*.xml")} == set(EXPECTED)


def test_feasible_mission_exits_0_with_a_table(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["verify", str(FEASIBLE)]) == 0
    out = capsys.readouterr().out
    for heading in ("task", "action", "distance m", "time s", "battery %", "clearance m"):
        assert heading in out
    assert "SURVEY_AREA" in out
    assert f"{FEASIBLE}: feasible" in out


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_infeasible_mission_exits_1_naming_constraint_and_line(
        name: str, capsys: pytest.CaptureFixture[str]) -> None:
    expected = EXPECTED[name]
    path = INFEASIBLE / name
    assert main(["verify", str(path), *_profile(name)]) == 1
    out, err = capsys.readouterr()
    assert f"{path}:{expected['line']}:" in out
    assert f": {expected['constraint']}: " in out
    if "message" in expected:  # what the vehicle cannot do at all: the exact finding
        assert re.search(re.escape(f"{path}:{expected['line']}:") + r"\d+: "
                         + re.escape(expected["message"]) + r"( \(in [^)]*\))?$", out, re.M)
    else:
        assert "must be" in out
    assert "INFEASIBLE" in out
    assert "Traceback" not in out + err


def _profile(name: str) -> list[str]:
    profile = EXPECTED[name].get("profile")
    return ["--profile", profile] if profile else []


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_json_lists_the_violation(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["verify", str(INFEASIBLE / name), "--format", "json", *_profile(name)]) == 1
    data = json.loads(capsys.readouterr().out)
    assert data["feasible"] is False
    found = {(v["constraint"], v["line"]) for v in data["violations"]}
    assert (EXPECTED[name]["constraint"], EXPECTED[name]["line"]) in found
    for violation in data["violations"]:
        assert {"value", "limit", "relation", "unit", "message", "file"} <= set(violation)


def test_json_of_a_feasible_mission(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["verify", str(FEASIBLE), "--format", "json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["feasible"] is True and data["violations"] == []
    assert data["profile"] == "quadcopter"
    assert [a["action"] for a in data["actions"]][:2] == ["TAKE_OFF", "GO_TO_POINT"]
    assert data["end"]["flying"] is False
    assert data["end"]["battery"] == pytest.approx(data["actions"][-2]["battery"])


def test_profile_option_changes_the_verdict(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["verify", str(FEASIBLE), "--profile", "fixed-wing"]) == 1
    assert "turn-radius" in capsys.readouterr().out


def test_low_start_battery_makes_it_infeasible(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["verify", str(FEASIBLE), "--battery", "30"]) == 1
    assert "return-reserve" in capsys.readouterr().out


def test_world_file_adds_obstacles(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = tmp_path / "world.xml"
    world.write_text('<?xml version="1.0"?>\n<world>\n'
                     '  <cylinder name="crane" north="100" east="2" radius="1"/>\n</world>\n')
    assert main(["verify", str(FEASIBLE), "--world", str(world)]) == 1
    assert "'crane'" in capsys.readouterr().out


def test_invalid_mission_exits_1_with_the_validation_errors(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.xml"
    path.write_text('<?xml version="1.0"?>\n<mission name="m">\n  <task name="t">\n'
                    '    <action name="FLY_TO_MARS"/>\n  </task>\n</mission>\n')
    assert main(["verify", str(path)]) == 1
    out = capsys.readouterr().out
    assert f"{path}:4:" in out
    assert "not verified" in out


@pytest.mark.parametrize("arguments", [
    ["verify", "no/such/mission.xml"],
    ["verify", str(FEASIBLE), "--profile", "no/such/profile.toml"],
    ["verify", str(FEASIBLE), "--world", "no/such/world.xml"],
    ["verify", str(FEASIBLE), "--battery", "150"],
    ["verify"],
])
def test_usage_and_io_errors_exit_2(arguments: list[str],
                                    capsys: pytest.CaptureFixture[str]) -> None:
    assert main(arguments) == 2
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err


def test_an_unknown_profile_exits_2_listing_the_profiles(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["verify", str(FEASIBLE), "--profile", "helicopter"]) == 2
    assert capsys.readouterr().err == (
        "tml verify: profile 'helicopter': no such profile or file; the profiles are "
        "quadcopter, fixed-wing, rover, vehicle (filled in from the vehicle's own parameters) "
        "or a TOML file\n")
    assert main(["verify", str(FEASIBLE), "--profile", "rover"]) in (0, 1)  # one of them


def test_bad_profile_exits_2_naming_file_and_key(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    profile = tmp_path / "p.toml"
    profile.write_text('base = "quadcopter"\nmax_speed = "fast"\n')
    assert main(["verify", str(FEASIBLE), "--profile", str(profile)]) == 2
    assert f"{profile}: key 'max_speed'" in capsys.readouterr().err


def test_bad_world_file_exits_2_with_its_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = tmp_path / "world.xml"
    world.write_text('<?xml version="1.0"?>\n<world>\n  <cylinder north="1" east="1"/>\n'
                     '</world>\n')
    assert main(["verify", str(FEASIBLE), "--world", str(world)]) == 2
    assert f"{world}:3" in capsys.readouterr().err


def test_profile_vehicle_needs_an_address_and_an_address_needs_it(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["verify", str(FEASIBLE), "--profile", "vehicle"]) == 2
    assert "--connect ADDRESS" in capsys.readouterr().err
    assert main(["verify", str(FEASIBLE), "--connect", "tcp:127.0.0.1:5760"]) == 2


def test_profile_from_the_connected_vehicles_parameters(
        capsys: pytest.CaptureFixture[str]) -> None:
    """A vehicle with twice ArduCopter's battery flies the mission on what the shipped
    profile calls too little charge."""
    from sitl.server import Simulator

    assert main(["verify", str(FEASIBLE), "--battery", "55"]) == 1
    capsys.readouterr()
    with Simulator(tcp_base_port=0, params={"BATT_CAPACITY": 6600}) as sim:
        code = main(["verify", str(FEASIBLE), "--battery", "55", "--profile", "vehicle",
                     "--connect", f"tcp:127.0.0.1:{sim.tcp_ports[0]}", "--format", "json"])
    out, err = capsys.readouterr()
    assert code == 0, out
    assert "profile from vehicle 1's parameters" in err and "BATT_CAPACITY=6600" in err
    assert json.loads(out)["feasible"] is True


def test_profile_vehicle_with_no_vehicle_there_is_an_error(
        capsys: pytest.CaptureFixture[str]) -> None:
    import socket

    with socket.create_server(("127.0.0.1", 0)) as silent:
        code = main(["verify", str(FEASIBLE), "--profile", "vehicle", "--connect",
                     f"tcp:127.0.0.1:{silent.getsockname()[1]}", "--timeout", "0.5"])
    assert code == 2
    err = capsys.readouterr().err
    assert "no heartbeat" in err and "Traceback" not in err


HOVERS = ('<mission name="Hover"><task name="Up"><action name="TAKE_OFF">'
          '<argument name="altitude" value="12"/></action></task></mission>')


def test_several_files_are_verified_and_the_worst_exit_code_wins(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["verify", str(FEASIBLE), str(FEASIBLE)]) == 0
    out = capsys.readouterr().out
    assert out.count(f"{FEASIBLE}: feasible") == 2
    assert main(["verify", str(FEASIBLE), str(tmp_path / "missing.xml")]) == 2
    assert "missing.xml: No such file or directory" in capsys.readouterr().err
    assert main(["verify", "--format", "json", str(FEASIBLE), str(FEASIBLE)]) == 0
    documents = json.loads(capsys.readouterr().out)
    assert [d["feasible"] for d in documents] == [True, True]


def test_a_mission_that_ends_in_the_air_gets_a_warning(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "hover.xml"
    path.write_text(HOVERS)
    assert main(["verify", str(path)]) == 0  # a warning: the mission may still be flown
    assert "warning: the mission ends with the vehicle in the air (up to 12 m) on 1 of 1 " \
           "way(s) through it" in capsys.readouterr().out
    assert main(["verify", "--format", "json", str(path)]) == 0
    assert json.loads(capsys.readouterr().out)["warnings"][0].startswith("the mission ends")
    assert main(["verify", "--format", "json", str(FEASIBLE)]) == 0
    assert json.loads(capsys.readouterr().out)["warnings"] == []


def test_a_rover_is_not_told_it_ends_in_the_air(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    # The rover delivery without its last task: it ends 25 m from where it started, on the
    # ground, where LAND (refused to a rover) would do nothing.
    delivery = (ROOT / "missions" / "rover_delivery.xml").read_text()
    start = delivery.index('  <task name="Home">')
    path = tmp_path / "stops_out.xml"
    path.write_text(delivery[:start] + delivery[delivery.index("</task>", start) + 8:])
    assert main(["verify", "--profile", "rover", "--format", "json", str(path)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["feasible"] and report["warnings"] == []
    assert report["actions"][-1]["action"] == "MOVE"
    assert main(["verify", "--profile", "rover", str(path)]) == 0
    assert "in the air" not in capsys.readouterr().out
    # A copter that ends there is still told, and how to land.
    hovers = tmp_path / "hovers.xml"
    hovers.write_text(HOVERS)
    assert main(["verify", "--profile", "quadcopter", str(hovers)]) == 0
    assert "end with LAND or RETURN_HOME_AND_LAND" in capsys.readouterr().out


GUARDED = ('<mission name="Guarded">\n'
           '  <task name="Up"><action name="TAKE_OFF"/></task>\n'
           '  <task name="Move if green">\n'
           '    <condition parameter="observed color" comparison="equal" value="green"/>\n'
           '    <action name="LAND"/>\n  </task>\n'
           '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')


@pytest.mark.parametrize("form", ["table", "json"])
def test_the_warnings_of_validation_are_printed_to_stderr(
        form: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "guarded.xml"
    path.write_text(GUARDED)
    assert main(["verify", "--format", form, str(path)]) == 0
    out, err = capsys.readouterr()
    assert f"{path}:4:5: warning W301: nothing provides parameter 'observed color'" in err
    assert 'hint: declare it if something on the vehicle reports it: <parameter ' \
           'name="observed color" type="string"/>' in err
    assert "W301" not in out
    if form == "json":
        assert json.loads(out)["feasible"] is True  # stdout stays one JSON document
    # Without warnings, nothing on stderr.
    assert main(["verify", "--format", form, str(FEASIBLE)]) == 0
    assert capsys.readouterr().err == ""


def test_the_shipped_world_file_adds_obstacles_the_legs_go_around(
        capsys: pytest.CaptureFixture[str]) -> None:
    root = Path(__file__).resolve().parent.parent
    mission = root / "missions/verify_obstacles.xml"
    world = root / "missions/worlds/field_works.xml"
    assert main(["validate", str(world.parent)]) == 0  # found in a directory: as a world
    assert "1 file(s) checked: 1 valid" in capsys.readouterr().out
    assert main(["verify", "--format", "json", str(mission)]) == 0
    alone = json.loads(capsys.readouterr().out)
    assert main(["verify", "--format", "json", str(mission), "--world", str(world)]) == 0
    laid = json.loads(capsys.readouterr().out)
    # The tent stands on the way home: the planned legs there are longer.
    assert sum(a["distance"] for a in laid["actions"]) > sum(
        a["distance"] for a in alone["actions"])


def test_the_report_says_which_skills_the_vehicle_must_provide(
        capsys: pytest.CaptureFixture[str]) -> None:
    mission = Path(__file__).resolve().parent.parent / "missions" / "paper_example1.xml"
    assert main(["verify", str(mission)]) == 0
    assert ("skills the vehicle must provide: AVOID_OBSTACLES, RECOGNIZE_VISUAL_MARKERS "
            "(tml run waits for the component that switches them before take-off)"
            ) in capsys.readouterr().out
    assert main(["verify", str(mission), "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["skills"] == [
        "AVOID_OBSTACLES", "RECOGNIZE_VISUAL_MARKERS"]
    assert main(["verify", str(FEASIBLE), "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["skills"] == []
