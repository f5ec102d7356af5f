"""ArduCopter SITL and the simulator take the photos ``tml verify`` predicts for
missions/survey_photos.xml.

The vehicle is given a camera (``CAM1_TYPE`` 1, read only at boot and not set by a
defaults file on ArduPilot 4.7: set over MAVLink, then the vehicle is rebooted).
``tml run`` flies the mission from a child process on the vehicle's first port: one
SURVEY_PHOTOS with commands (GUIDED: DO_SET_CAM_TRIGG_DIST as a COMMAND_LONG at the base
point, the passes, the trigger cleared), one as mission items (AUTO), then home and land.
A plain pymavlink client on the vehicle's second port (SERIAL1) counts the CAMERA_FEEDBACK
messages the vehicle sends in each mode (that of the latest HEARTBEAT), and each count
must be the one ``tml verify --format json`` predicts for that action, within one photo at
each end (where the vehicle is when the trigger is set and cleared is judged within its
waypoint radius). The simulator (``python -m sitl``, a camera by default) flies the same
mission, watched the same way on its one port.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from ground_station import AUTO, GUIDED, python_sitl, watch_run

MISSION = Path(__file__).resolve().parents[2] / "missions" / "survey_photos.xml"


def _predicted() -> list[int]:
    """The photos ``tml verify`` predicts for each SURVEY_PHOTOS, in order."""
    out = subprocess.run([sys.executable, "-m", "tml", "verify", "--format", "json",
                          str(MISSION)], capture_output=True, text=True, check=True).stdout
    return [len(action["photos"]) for action in json.loads(out)["actions"]
            if action["action"] == "SURVEY_PHOTOS"]


def _photos_by_mode(address: str, run: subprocess.Popen[bytes]) -> dict[int, int]:
    """CAMERA_FEEDBACK messages the vehicle sends on SERIAL1 until the run ends, counted
    by the mode of the latest HEARTBEAT."""
    photos: dict[int, int] = {}
    for mode, _ in watch_run(address, run, ["CAMERA_FEEDBACK"]):
        photos[mode] = photos.get(mode, 0) + 1
    return photos


def _fly(address: str, observer: str, tmp_path: Path) -> dict[int, int]:
    """``tml run`` of the mission on the vehicle at ``address``; the photos the observer on
    ``observer`` counted in each mode."""
    run = subprocess.Popen([sys.executable, "-m", "tml", "run", str(MISSION), "--connect",
                            address, "--clock", "vehicle", "-q", "--log",
                            str(tmp_path / "survey_photos.jsonl")],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        photos = _photos_by_mode(observer, run)
    finally:
        if run.poll() is None:
            run.kill()
        run.wait()
    assert run.returncode == 0
    return photos


def _judge(photos: dict[int, int], guided: int, auto: int) -> None:
    assert abs(photos.get(GUIDED, 0) - guided) <= 2
    assert abs(photos.get(AUTO, 0) - auto) <= 2
    assert set(photos) <= {GUIDED, AUTO}  # none before, between or after the surveys


@pytest.mark.timeout(900)
def test_arducopter_takes_the_photos_verify_predicts(ardupilot, tmp_path: Path) -> None:
    guided, auto = _predicted()
    (sitl,) = ardupilot(reboot_params={"CAM1_TYPE": 1})
    photos = _fly(sitl.address, sitl.companion_address, tmp_path)
    print(f"ArduCopter: predicted GUIDED {guided}, AUTO {auto}; CAMERA_FEEDBACK by mode "
          f"{photos}")
    _judge(photos, guided, auto)


@pytest.mark.timeout(900)
def test_the_simulator_takes_the_photos_verify_predicts(tmp_path: Path) -> None:
    guided, auto = _predicted()
    with python_sitl(10.0) as address:
        photos = _fly(address, address, tmp_path)
    print(f"simulator: predicted GUIDED {guided}, AUTO {auto}; CAMERA_FEEDBACK by mode "
          f"{photos}")
    _judge(photos, guided, auto)
