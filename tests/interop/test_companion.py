"""Missions that need detections fly on ArduCopter with ``tml companion`` on SERIAL1.

The companion runs as a separate process attached to the autopilot's second serial port,
as a real onboard computer is; ArduPilot routes its messages to tml on SERIAL0 and tml's
PARAM_SETs to it. The vehicle is fitted with a gripper at boot (GRIP_ENABLE takes effect
only then), as the simulator's vehicle is, since both missions carry an item.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from ardupilot_sitl import SitlVehicle

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: shared log checks
from flight_checks import check_imav2016

from tml.cli import main
from tml.journal import read

MISSIONS = Path(__file__).resolve().parents[2] / "missions"
GRIPPER = {"GRIP_ENABLE": 1, "GRIP_TYPE": 1, "SERVO9_FUNCTION": 28}


def fly_with_companion(sitl: SitlVehicle, name: str, tmp_path: Path
                       ) -> tuple[int, list[dict], str, str]:
    """Fly ``missions/NAME.xml`` with the companion on SERIAL1: (exit code, log lines,
    the outcome's reason, what the companion printed)."""
    mission = str(MISSIONS / f"{name}.xml")
    log = tmp_path / f"{name}.jsonl"
    companion = subprocess.Popen(
        [sys.executable, "-m", "tml", "companion", "--connect", sitl.companion_address,
         "--world", mission], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # Fly once the companion has found the autopilot (starting Python takes a while).
        first = companion.stdout.readline() if companion.stdout else ""
        code = main(["run", mission, "--connect", sitl.address, "--clock", "vehicle", "-q",
                     "--log", str(log)])
    finally:
        os.kill(companion.pid, signal.SIGTERM)
        out, err = companion.communicate(timeout=10)
    assert companion.returncode == 0, err
    assert f"component 191 of system {sitl.system_id} attached" in first
    lines = read(str(log))
    ended = [line for line in lines if line["kind"] == "run" and "outcomes" in line]
    reason = ended[-1]["outcomes"][0]["reason"] if ended else ""
    return code, lines, reason, out


@pytest.mark.timeout(300)
def test_imav2016_recognises_transports_and_lands_at_the_operating_zone(
        ardupilot, tmp_path: Path) -> None:
    (sitl,) = ardupilot(boot_params=GRIPPER)
    code, lines, reason, out = fly_with_companion(sitl, "imav2016", tmp_path)
    assert (code, reason) == (0, "all tasks done"), reason
    assert "Detected item 1 A" in out and "Detected bucket 1 A" in out
    check_imav2016(lines)


@pytest.mark.timeout(300)
def test_catalogue_tour_delivers_the_crate_it_recognised(ardupilot, tmp_path: Path) -> None:
    (sitl,) = ardupilot(boot_params=GRIPPER)
    code, lines, reason, out = fly_with_companion(sitl, "catalogue_tour", tmp_path)
    assert (code, reason) == (0, "all tasks done"), reason
    assert "Detected item 1 crate" in out and "Detected bucket 1 bin" in out
    fired = {line["event"] for line in lines if line["kind"] == "event"}
    assert {"Crate seen", "Bin seen", "Window seen during a survey"} <= fired
    states = {line["task"]: line["state"] for line in lines if line["kind"] == "task"}
    assert states["Inspection/Deliver the crate"] == "done"
    grips = [line["grab"] for line in lines
             if line["kind"] == "request" and line["message"] == "Gripper"]
    assert grips == [True, False]
