"""ArduCopter SITL: a mode change tml did not ask for ends tml's command of the vehicle."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

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


def _tml_run(mission: Path, address: str, *options: str
             ) -> tuple[subprocess.Popen[str], Any, list[str]]:
    """``tml run`` in a child process, and the queue and list its lines are read into."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    run = subprocess.Popen([sys.executable, "-m", "tml", "run", str(mission), "--connect",
                            address, *options], stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True, env=env)
    assert run.stdout is not None
    return run, follow(run.stdout), []


def fly_leg(address: str, tmp_path: Path, during: Callable[[], object], *options: str
            ) -> tuple[int | None, str, list[dict[str, Any]]]:
    """``tml run`` flies :data:`LEG` at ``address``; ``during()`` is called once it says
    ``Over: running``. Returns its exit code, what it said and its flight log."""
    mission, log = tmp_path / "leg.xml", tmp_path / "leg.jsonl"
    mission.write_text(LEG)
    run, lines, seen = _tml_run(mission, address, "--log", str(log), *options)
    try:
        wait_for(lines, seen, "Over: running", time.monotonic() + 300, "tml run")
        during()
        run.wait(timeout=180)
        wait_for(lines, seen, "mission (failed|aborted|completed)", time.monotonic() + 10,
                 "tml run")
    finally:
        if run.poll() is None:
            run.kill()
    return run.returncode, "".join(seen), read(str(log))


@pytest.mark.timeout(600)
def test_another_ground_station_switching_to_land_takes_the_vehicle(
        ardupilot, tmp_path: Path) -> None:
    (sitl,) = ardupilot()
    other = mavutil.mavlink_connection(sitl.companion_address, source_system=254)

    def land() -> None:  # another ground station, on the vehicle's second port, lands it
        other.wait_heartbeat(timeout=30)
        other.mav.command_long_send(sitl.system_id, 1, mavutil.mavlink.MAV_CMD_DO_SET_MODE,
                                    0, mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 9,
                                    0, 0, 0, 0, 0)

    try:
        code, said, journal = fly_leg(sitl.address, tmp_path, land, "--clock", "vehicle")
    finally:
        other.close()
    assert code == 4, said
    # Not "by the autopilot": it was another ground station, which telemetry cannot tell.
    assert "vehicle 1 switched to LAND outside tml: tml commands it no more" in said
    taken = next(i for i, line in enumerate(journal) if line["kind"] == "taken")
    assert journal[taken]["mode"] == "LAND"
    after = [line for line in journal[taken:] if line["kind"] in ("request", "safety")]
    assert after == [], after  # nothing sent to it after it was taken


@pytest.mark.timeout(600)
def test_after_an_outage_the_vehicle_is_told_its_safe_state_again_until_it_shows_it(
        ardupilot, tmp_path: Path) -> None:
    from lossy_proxy import LossyProxy

    (sitl,) = ardupilot(params={"FS_GCS_ENABLE": 0})  # nothing of its own: it would hover
    with LossyProxy(sitl.port, loss=0.0, seed=1) as proxy:
        def outage() -> None:  # 20 s, both ways
            proxy.up.loss = proxy.down.loss = 1.0
            time.sleep(20.0)
            proxy.up.loss = proxy.down.loss = 0.0

        code, said, journal = fly_leg(proxy.address, tmp_path, outage,
                                      "--link-lost-limit", "10")
    assert code == 4, said
    confirmed = [line for line in journal if line["kind"] == "safety" and line.get("confirmed")]
    assert len(confirmed) == 1 and confirmed[0]["mode"] == "RTL", said
