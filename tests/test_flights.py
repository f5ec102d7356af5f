"""Every mission in missions/ flies on the simulator to its expected outcome (end to end).

Each flight runs ``tml run FILE --sim`` at 50x with the GPS and EKF delays cut to 1-2 s,
once per session for every test that reads it (tests/shared_flights.py); the flight log is
then read to check what happened, not only the exit code.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from flight_checks import LOG_CHECKS
from shared_flights import FLEET, flown

from tml.commands.cli import main
from tml.run.journal import read

# A guard against a hang, not a time limit: a flight in lock-step with the simulator is
# slower, never different, on a busy machine (tests/test_timebase.py), and one of a fleet
# beside three CPU spinners takes several minutes.
pytestmark = pytest.mark.timeout(900)

MISSIONS = Path(__file__).parent.parent / "missions"

# mission -> (exit code, text the outcome's reason contains, extra simulator parameters)
EXPECTED: dict[str, tuple[int, str, list[str]]] = {
    "aerostack_example": (0, "all tasks done", []),
    "battery_event": (3, "event 'Low battery' aborted the mission",
                      ["--sim-param", "BATT_CAPACITY=300"]),
    "catalogue_tour": (0, "all tasks done", []),
    "dolphin_fleet_relay": (0, "all tasks done", ["--vehicles", "4", *FLEET]),
    "dolphin_fleet_single": (0, "all tasks done", FLEET),
    "dolphin_fleet_survey": (0, "all tasks done", ["--vehicles", "2", *FLEET]),
    "dolphin_relay_single": (0, "all tasks done", []),
    # loiters until the battery falls below 30 %: a small battery makes that minutes
    "dolphin_single_vehicle": (0, "event 'Battery below 30 %' ended the mission",
                               ["--sim-param", "BATT_CAPACITY=1000"]),
    "dolphin_survey_north": (0, "all tasks done", []),
    "fenced_patrol": (0, "all tasks done", []),
    "fleet_compositions": (0, "all tasks done", ["--vehicles", "3", "--link-lost-limit", "60"]),
    "imav2016": (0, "all tasks done", []),
    "jump_and_repeat": (0, "all tasks done", []),
    "mission_dispatch": (0, "all tasks done", []),
    "orbit": (0, "all tasks done", []),
    "dolphin_uav_surface": (0, "all tasks done",
                            ["--vehicles", "2", "--sim-frame", "copter,rover",
                             "--link-lost-limit", "60"]),
    "paper_example1": (0, "all tasks done", []),
    "paper_example2": (0, "all tasks done", []),
    "plane_patrol": (0, "all tasks done", ["--sim-frame", "plane", "--profile", "fixed-wing"]),
    "raw_items": (0, "all tasks done", []),
    "survey_photos": (0, "all tasks done", []),
    "rover_delivery": (0, "all tasks done", ["--sim-frame", "rover", "--profile", "rover"]),
    "terrain_hill": (0, "all tasks done", []),
    "verify_obstacles": (0, "all tasks done", []),
}
KNOWN_GAPS: dict[str, str] = {}


def fly(factory: pytest.TempPathFactory, name: str, extra: list[str]
        ) -> tuple[int, list[dict], str]:
    flight = flown(factory, name, extra)
    code, lines = flight.code, flight.lines
    ended = [line for line in lines if line["kind"] == "run" and "outcomes" in line]
    reason = ended[-1]["outcomes"][0]["reason"] if ended else ""
    return code, lines, reason


def test_every_mission_has_an_expected_outcome() -> None:
    assert sorted(p.stem for p in MISSIONS.glob("*.xml")) == sorted(EXPECTED)


@pytest.mark.parametrize("name", [
    pytest.param(name, marks=pytest.mark.xfail(reason=KNOWN_GAPS[name], strict=True))
    if name in KNOWN_GAPS else name for name in sorted(EXPECTED)])
def test_mission_flies_to_its_expected_outcome(name: str,
                                               tmp_path_factory: pytest.TempPathFactory) -> None:
    code, lines, reason = fly(tmp_path_factory, name, EXPECTED[name][2])
    expected_code, expected_reason, _ = EXPECTED[name]
    assert (code, expected_reason in reason) == (expected_code, True), reason
    assert not [line for line in lines if line["kind"] == "error"]
    last = [line for line in lines if line["kind"] == "telemetry"][-1]
    assert last["mode"] != "AUTO" or last["landed"], "left flying an unwatched AUTO mission"
    if name in LOG_CHECKS:  # what the log shows besides the outcome (tests/flight_checks.py)
        LOG_CHECKS[name](lines)


def test_battery_event_lands_and_aborts(tmp_path_factory: pytest.TempPathFactory) -> None:
    code, lines, reason = fly(tmp_path_factory, "battery_event",
                              ["--sim-param", "BATT_CAPACITY=300"])
    assert code == 3 and "Low battery" in reason
    fired = [line for line in lines if line["kind"] == "event"]
    assert [f["event"] for f in fired] == ["Low battery"]
    assert fired[0]["read"][0]["value"] < 30
    after = [line for line in lines if line["t"] >= fired[0]["t"]]
    assert any(line["kind"] == "request" and line["message"] == "Land" for line in after)
    assert any(line["kind"] == "action" and line["message"] == "LAND done" for line in after)
    states = {line["task"]: line["state"] for line in lines if line["kind"] == "task"}
    assert states.get("Return and land", "pending") == "pending"  # never flown


def test_a_battery_started_low_fires_the_low_battery_event(tmp_path: Path) -> None:
    """The README's low-battery line: --sim-battery starts the battery at 40 %, and
    --sim-fast-boot makes the vehicle armable at once (2 s, not 41 s)."""
    log = tmp_path / "low.jsonl"
    code = main(["run", str(MISSIONS / "battery_event.xml"), "--sim", "-q", "--log", str(log),
                 "--speedup", "50", "--sim-battery", "40", "--sim-fast-boot"])
    lines = read(str(log))
    telemetry = [line for line in lines if line["kind"] == "telemetry"]
    assert telemetry[0]["battery"] == 40
    took_off = next(line for line in lines if line["kind"] == "action"
                    and line["message"] == "TAKE_OFF started")
    assert took_off["t"] < 10  # no wait for the EKF's 41 s
    fired = [line for line in lines if line["kind"] == "event"]
    assert code == 3 and [f["event"] for f in fired] == ["Low battery"]
