"""Every mission in missions/ flies on the simulator to its expected outcome (end to end).

Each flight runs ``tml run FILE --sim`` at 50x with the GPS and EKF delays cut to 1-2 s;
the flight log is then read to check what happened, not only the exit code.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from flight_checks import LOG_CHECKS

from tml.cli import main
from tml.journal import read

MISSIONS = Path(__file__).parent.parent / "missions"
FAST = ["--speedup", "50", "--sim-param", "SIM_GPS_LOCKTIME=1",
        "--sim-param", "SIM_EKF_GPS_TIME=2"]
# Fleets: a 1700 mAh battery and a 64 A charging pad make the rounds drain to 30 % and
# recharge to 90 % in minutes (see tests/test_fleet_flights.py); several simulated vehicles
# load the machine, so a stalled link is given longer before the run is aborted.
FLEET = ["--sim-param", "BATT_CAPACITY=1700", "--sim-param", "SIM_BATT_CHARGE=64",
         "--link-lost-limit", "60"]

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
    "fleet_compositions": (0, "all tasks done", ["--vehicles", "3", "--link-lost-limit", "60"]),
    "imav2016": (0, "all tasks done", []),
    "jump_and_repeat": (0, "all tasks done", []),
    "mission_dispatch": (0, "all tasks done", []),
    "dolphin_uav_surface": (0, "all tasks done",
                            ["--vehicles", "2", "--sim-frame", "copter,rover",
                             "--link-lost-limit", "60"]),
    "paper_example1": (0, "all tasks done", []),
    "paper_example2": (0, "all tasks done", []),
    "plane_patrol": (0, "all tasks done", ["--sim-frame", "plane", "--profile", "fixed-wing"]),
    "rover_delivery": (0, "all tasks done", ["--sim-frame", "rover", "--profile", "rover"]),
    "verify_obstacles": (0, "all tasks done", []),
}
KNOWN_GAPS: dict[str, str] = {}


def fly(tmp_path: Path, name: str, extra: list[str]) -> tuple[int, list[dict], str]:
    log = tmp_path / f"{name}.jsonl"
    code = main(["run", str(MISSIONS / f"{name}.xml"), "--sim", "-q", "--log", str(log),
                 *FAST, *extra])
    lines = read(str(log))
    ended = [line for line in lines if line["kind"] == "run" and "outcomes" in line]
    reason = ended[-1]["outcomes"][0]["reason"] if ended else ""
    return code, lines, reason


def test_every_mission_has_an_expected_outcome() -> None:
    assert sorted(p.stem for p in MISSIONS.glob("*.xml")) == sorted(EXPECTED)


@pytest.mark.parametrize("name", [
    pytest.param(name, marks=pytest.mark.xfail(reason=KNOWN_GAPS[name], strict=True))
    if name in KNOWN_GAPS else name for name in sorted(EXPECTED)])
def test_mission_flies_to_its_expected_outcome(name: str, tmp_path: Path) -> None:
    code, lines, reason = fly(tmp_path, name, EXPECTED[name][2])
    expected_code, expected_reason, _ = EXPECTED[name]
    assert (code, expected_reason in reason) == (expected_code, True), reason
    assert not [line for line in lines if line["kind"] == "error"]
    last = [line for line in lines if line["kind"] == "telemetry"][-1]
    assert last["mode"] != "AUTO" or last["landed"], "left flying an unwatched AUTO mission"
    if name in LOG_CHECKS:  # IMAV 2016: items and buckets seen, gripper, operating zone
        LOG_CHECKS[name](lines)


def test_battery_event_lands_and_aborts(tmp_path: Path) -> None:
    code, lines, reason = fly(tmp_path, "battery_event", ["--sim-param", "BATT_CAPACITY=300"])
    assert code == 3 and "Low battery" in reason
    fired = [line for line in lines if line["kind"] == "event"]
    assert [f["event"] for f in fired] == ["Low battery"]
    assert fired[0]["read"][0]["value"] < 30
    after = [line for line in lines if line["t"] >= fired[0]["t"]]
    assert any(line["kind"] == "request" and line["message"] == "Land" for line in after)
    assert any(line["kind"] == "action" and line["message"] == "LAND done" for line in after)
    states = {line["task"]: line["state"] for line in lines if line["kind"] == "task"}
    assert states.get("Return and land", "pending") == "pending"  # never flown


def _telemetry(lines: list[dict], vehicle: int = 1) -> list[dict]:
    return [line for line in lines if line["kind"] == "telemetry"
            and line["position"] is not None and line["vehicle"] == vehicle]


def _done(lines: list[dict]) -> dict[str, tuple[float, float]]:
    """task -> (start, end) mission time of the tasks done."""
    started = {line["task"]: line["t"] for line in lines
               if line["kind"] == "task" and line["state"] == "running"}
    return {line["task"]: (started[line["task"]], line["t"]) for line in lines
            if line["kind"] == "task" and line["state"] == "done" and line["task"] in started}


def test_plane_patrol_takes_off_circles_and_lands_at_home(tmp_path: Path) -> None:
    code, lines, _ = fly(tmp_path, "plane_patrol", EXPECTED["plane_patrol"][2])
    assert code == 0
    done = _done(lines)
    assert {"Launch", "Patrol", "Orbit", "Over home", "Land"} <= set(done)
    # Never hovering: every airborne sample of the flight is at speed.
    flight = [line for line in _telemetry(lines) if line["armed"] and not line["landed"]
              and line["position"][2] > 20]
    assert min(line["ground_speed"] for line in flight) > 15
    # The take-off is TAKEOFF mode, not GUIDED.
    modes = [line["mode"] for line in _telemetry(lines) if line["armed"]]
    assert modes[0] == "TAKEOFF" and "GUIDED" not in modes[:modes.index("AUTO")]
    # The patrol legs reach 400 m north, then 400 m east.
    patrol = [line["position"] for line in _telemetry(lines)
              if done["Patrol"][0] <= line["t"] <= done["Patrol"][1]]
    assert max(p[0] for p in patrol) > 330 and max(p[1] for p in patrol) > 330
    # Two circles around (200, 400): on the circle at about its 80 m radius.
    orbit = [line["position"] for line in _telemetry(lines)
             if done["Orbit"][1] - 30 <= line["t"] <= done["Orbit"][1]]
    radii = [math.dist(p[:2], (200, 400)) for p in orbit]
    assert all(60 < r < 100 for r in radii), radii
    # It lands along its approach and stops near home, on the ground and disarmed.
    landed = [line for line in _telemetry(lines) if line["landed"] and line["t"] > done["Land"][0]]
    assert landed and math.dist(landed[0]["position"][:2], (0, 0)) < 100
    assert not _telemetry(lines)[-1]["armed"]


def test_rover_delivery_drives_stops_and_comes_home(tmp_path: Path) -> None:
    code, lines, _ = fly(tmp_path, "rover_delivery", EXPECTED["rover_delivery"][2])
    assert code == 0
    done = _done(lines)
    telemetry = _telemetry(lines)
    assert all(line["position"][2] == 0.0 for line in telemetry)  # no altitude, ever
    at = {task: min((line for line in telemetry if line["t"] >= end),
                    key=lambda line: line["t"])["position"] for task, (_, end) in done.items()}
    assert math.dist(at["To the drop point"][:2], (40, 0)) <= 3.5
    assert math.dist(at["Second drop/To the second point"][:2], (40, 25)) <= 3.5
    unloading = [line for line in telemetry
                 if done["Unload"][0] + 2 <= line["t"] <= done["Unload"][1]]
    assert unloading and all(line["ground_speed"] < 0.3 for line in unloading)
    # SET_SPEED 2 m/s holds for the second leg.
    second = [line["ground_speed"] for line in telemetry
              if done["Second drop/To the second point"][0] <= line["t"]
              <= done["Second drop/To the second point"][1]]
    assert 1.5 < max(second) <= 2.2
    assert math.dist(telemetry[-1]["position"][:2], (0, 0)) <= 3.5
    assert not telemetry[-1]["armed"]
    requests = {line["message"] for line in lines if line["kind"] == "request"}
    assert not requests & {"TakeOff", "Land"}


def test_uav_and_surface_vehicle_fly_their_own_roles(tmp_path: Path) -> None:
    code, lines, _ = fly(tmp_path, "dolphin_uav_surface", EXPECTED["dolphin_uav_surface"][2])
    assert code == 0
    scout, rover = _telemetry(lines, 1), _telemetry(lines, 2)
    assert max(line["position"][2] for line in scout) > 14
    assert all(line["position"][2] == 0.0 for line in rover)
    # The rover sets off only once the scout is above 10 m (wait_for on the other role).
    moving = min(line["t"] for line in rover if line["ground_speed"] > 0.5)
    climbed = min(line["t"] for line in scout if line["position"][2] > 10)
    assert moving >= climbed - 1.0
    # It holds at the rendezvous under the scout's last point, and both end at home.
    assert any(math.dist(line["position"][:2], (30, 20)) < 3.5 for line in rover)
    for track in (scout, rover):
        assert math.dist(track[-1]["position"][:2], (0, 0)) < 3.5
        assert not track[-1]["armed"]
