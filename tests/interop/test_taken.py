"""ArduCopter SITL: a mode change tml did not ask for ends tml's command of the vehicle."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from process_lines import follow, wait_for
from pymavlink import mavutil

from tml.run.journal import read

LEG = ('<mission name="Leg">\n'
       '  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/>'
       '</action></task>\n'
       '  <task name="Over"><action name="GO_TO_POINT"><argument name="coordinates" '
       'value="(150, 0, 10)"/></action></task>\n'
       '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')


@pytest.mark.timeout(600)
def test_another_ground_station_switching_to_land_takes_the_vehicle(
        ardupilot, tmp_path: Path) -> None:
    (sitl,) = ardupilot()
    mission, log = tmp_path / "leg.xml", tmp_path / "leg.jsonl"
    mission.write_text(LEG)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    run = subprocess.Popen([sys.executable, "-m", "tml", "run", str(mission), "--connect",
                            sitl.address, "--clock", "vehicle", "--log", str(log)],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                           env=env)
    assert run.stdout is not None
    lines, seen = follow(run.stdout), []
    try:
        wait_for(lines, seen, "Over: running", time.monotonic() + 300, "tml run")
        # Another ground station, on the vehicle's second port, lands it.
        other = mavutil.mavlink_connection(sitl.companion_address, source_system=254)
        other.wait_heartbeat(timeout=30)
        other.mav.command_long_send(sitl.system_id, 1, mavutil.mavlink.MAV_CMD_DO_SET_MODE,
                                    0, mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 9,
                                    0, 0, 0, 0, 0)
        run.wait(timeout=120)
        wait_for(lines, seen, "mission (failed|aborted|completed)", time.monotonic() + 10,
                 "tml run")
        other.close()
    finally:
        if run.poll() is None:
            run.kill()
    said = "".join(seen)
    assert run.returncode == 4, said
    assert "vehicle 1 switched to LAND by the autopilot: tml commands it no more" in said
    journal = read(str(log))
    taken = next(i for i, line in enumerate(journal) if line["kind"] == "taken")
    assert journal[taken]["mode"] == "LAND"
    after = [line for line in journal[taken:] if line["kind"] in ("request", "safety")]
    assert after == [], after  # nothing sent to it after it was taken
