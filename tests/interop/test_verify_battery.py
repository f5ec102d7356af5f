"""The verifier's battery model against ArduCopter's drain, on one whole flight.

missions/verify_obstacles.xml (take-off, a detour round a building, two circles round a
mast, a survey, back, RTL) is verified with the shipped quadcopter profile, whose battery
figures were measured on ArduCopter SITL (docs/verify.md), and then flown on ArduCopter
SITL with the mission's clock on the vehicle's. It must end as on the simulator, all tasks
done and no low-battery event, and the battery it used must be what the verifier predicted
within :data:`TOLERANCE` (measured: 58 % predicted, 63 % used).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tml.commands.cli import main
from tml.language.validation import load_mission
from tml.run.journal import read
from tml.verify.profile import load_profile
from tml.verify.static import verify_mission

MISSION = Path(__file__).resolve().parents[2] / "missions" / "verify_obstacles.xml"
TOLERANCE = 0.15
"""Largest difference between the predicted and the used battery, as a share of the used."""


@pytest.mark.timeout(300)
def test_verify_obstacles_uses_the_battery_the_verifier_predicts(ardupilot,
                                                                 tmp_path: Path) -> None:
    report = verify_mission(load_mission(MISSION), load_profile("quadcopter"))
    assert report.feasible and report.end is not None
    predicted = 100.0 - report.end.battery
    (sitl,) = ardupilot()
    log = tmp_path / "verify_obstacles.jsonl"
    code = main(["run", str(MISSION), "--connect", sitl.address, "--clock", "vehicle", "-q",
                 "--log", str(log)])
    lines = read(str(log))
    outcome = [line for line in lines if line["kind"] == "run" and "outcomes" in line][-1]
    assert (code, outcome["outcomes"][0]["reason"]) == (0, "all tasks done")
    assert [line for line in lines if line["kind"] == "event"] == []  # no low battery
    charge = [line["battery"] for line in lines
              if line["kind"] == "telemetry" and line["battery"] is not None]
    used = charge[0] - charge[-1]
    assert charge[0] == 100.0
    assert abs(predicted - used) <= TOLERANCE * used, (predicted, used)
