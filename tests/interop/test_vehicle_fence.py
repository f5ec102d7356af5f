"""The mission's fence and rally points on ArduCopter SITL: uploaded, read back, enforced.

A mission's ``<environment>`` goes onto the vehicle before take-off
(:mod:`tml.mavlink.safeguards`). Here ArduCopter takes the fence and rally points of
missions/fenced_patrol.xml, reads them back as tml sent them (by ArduPilot's storage rules),
and its own fence, not tml, stops a flight that strays into the water tower's exclusion
zone; and the whole mission flies with them in place.
"""

from __future__ import annotations

from pathlib import Path

from vehicle_steps import do, until

from tml.commands.cli import main
from tml.errors import Location
from tml.language.actions import BoundAction, bind
from tml.language.model import Action, Argument
from tml.language.validation import load_mission
from tml.mavlink.adapter import MavlinkVehicle
from tml.mavlink.link import Link
from tml.mavlink.mission import MissionType
from tml.run.journal import read
from tml.vehicle import FlyMission, Safeguard

ROOT = Path(__file__).resolve().parents[2]
PATROL = ROOT / "missions" / "fenced_patrol.xml"
HERE = Location("test.xml", 1)


def act(name: str, **values: str) -> BoundAction:
    return bind(Action(name, tuple(Argument(k, v, None, HERE) for k, v in values.items()),
                       HERE))


def test_arducopter_takes_the_missions_fence_and_stops_a_flight_that_strays(
        ardupilot) -> None:
    (sitl,) = ardupilot()
    world = load_mission(str(PATROL)).world
    assert world is not None
    with Link(sitl.address) as link:
        vehicle = MavlinkVehicle(link, sitl.system_id, world=world)
        try:
            vehicle.prepare()
            until(vehicle, lambda s: s.home is not None and s.ready, "home and EKF")
            result = do(vehicle, Safeguard(sitl.system_id, world, request_id=1))
            assert result.ok, result.detail
            assert result.detail.endswith("read back matched")
            fence = vehicle.mav.download(MissionType.FENCE)
            assert [item.command for item in fence] == [5001] * 4 + [5004]
            assert [item.command for item in vehicle.mav.download(MissionType.RALLY)] == [
                5100, 5100]
            values = vehicle.read_parameters(["FENCE_ENABLE", "FENCE_TYPE", "FENCE_ALT_MAX"])
            assert values == {"FENCE_ENABLE": 1, "FENCE_TYPE": 5, "FENCE_ALT_MAX": 40}
            # Uploaded as a mission (AUTO checks no destination against the fence): a
            # straight line from home through the water tower (60 N, 20 E, radius 6).
            actions = (act("TAKE_OFF", altitude="10"),
                       act("GO_TO_POINT", coordinates="(90, 30, 10)"),
                       act("LAND"))
            assert do(vehicle, FlyMission(sitl.system_id, 2, actions, (0.0, 0.0, 0.0),
                                          request_id=2)).ok
            stopped = until(vehicle, lambda s: s.mode in ("RTL", "LAND", "BRAKE"),
                            "the fence's action")
            said = [m.text for m in stopped.messages]
            assert "Polygon fence breached" in said, said  # as the simulator says it
            # Stopped at the tower's edge, never past it to the point it was sent to.
            assert stopped.position is not None and stopped.position[0] < 62.0
        finally:
            vehicle.close()


def test_the_fenced_patrol_flies_with_its_fence_on_arducopter(ardupilot, tmp_path: Path
                                                               ) -> None:
    (sitl,) = ardupilot()
    log = tmp_path / "fenced_patrol.jsonl"
    code = main(["run", str(PATROL), "--connect", sitl.address, "-q", "--log", str(log)])
    lines = read(str(log))
    ended = [line for line in lines if line["kind"] == "run" and "outcomes" in line]
    reason = ended[-1]["outcomes"][0]["reason"] if ended else ""
    assert (code, reason) == (0, "all tasks done"), [
        line.get("message") for line in lines
        if line["kind"] in ("action", "result", "error", "safeguard")][-8:]
    (told,) = [line for line in lines if line["kind"] == "safeguard"]
    assert told["ok"] and told["message"].endswith("read back matched"), told


def test_tml_run_reports_arducopters_fence_breach_in_its_own_words(
        ardupilot, tmp_path: Path, capsys) -> None:
    # The patrol's environment, and a plan flown in AUTO straight through the water tower
    # (AUTO checks no destination against the fence): ArduCopter breaches its exclusion
    # zone and returns (FENCE_ACTION 1, RTL); tml run sees the switch it did not ask for,
    # says the autopilot's words, and commands the vehicle no more.
    text = PATROL.read_text()
    start, end = text.index("  <task name=\"take off\">"), text.index("  <event_handling>")
    mission = tmp_path / "strays.xml"
    mission.write_text(text[:start] + (
        '  <task name="take off"><action name="TAKE_OFF"><argument name="altitude" '
        'value="10"/></action></task>\n'
        '  <task name="through the tower" dispatch="mission"><action name="GO_TO_POINT">'
        '<argument name="coordinates" value="(90, 30, 10)"/></action></task>\n'
        '  <task name="down"><action name="LAND"/></task>\n') + text[end:])
    (sitl,) = ardupilot()
    log = tmp_path / "strays.jsonl"
    code = main(["run", str(mission), "--connect", sitl.address, "--force", "-q",
                 "--log", str(log)])  # --force: the verifier sees the tower on the way
    said = capsys.readouterr().out
    assert code == 4, said
    assert ("vehicle 1 switched to RTL outside tml (autopilot: Polygon fence breached): "
            "tml commands it no more") in said, said
    lines = read(str(log))
    taken = next(i for i, line in enumerate(lines) if line["kind"] == "taken")
    assert lines[taken]["mode"] == "RTL"
    assert [line for line in lines[taken:] if line["kind"] in ("request", "safety")] == []
