"""ArduCopter SITL takes the photos of missions/survey_photos.xml that ``tml verify`` predicts.

The vehicle is given a camera (``CAM1_TYPE`` 1, read only at boot and not set by a
defaults file on ArduPilot 4.7: set over MAVLink, then the vehicle is rebooted).
``tml run`` flies the mission from a child process on the vehicle's first port: one
SURVEY_PHOTOS with commands (GUIDED: DO_SET_CAM_TRIGG_DIST as a COMMAND_LONG at the base
point, the passes, the trigger cleared), one as mission items (AUTO), then home and land.
A plain pymavlink client on the vehicle's second port (SERIAL1) counts the CAMERA_FEEDBACK
messages the vehicle sends in each mode (that of the latest HEARTBEAT), and each count
must be the one ``tml verify --format json`` predicts for that action, within one photo at
each end (where the vehicle is when the trigger is set and cleared is judged within its
waypoint radius).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil

M = mavutil.mavlink
MISSION = Path(__file__).resolve().parents[2] / "missions" / "survey_photos.xml"
GUIDED, AUTO = 4, 3


def _predicted() -> list[int]:
    """The photos ``tml verify`` predicts for each SURVEY_PHOTOS, in order."""
    out = subprocess.run([sys.executable, "-m", "tml", "verify", "--format", "json",
                          str(MISSION)], capture_output=True, text=True, check=True).stdout
    return [len(action["photos"]) for action in json.loads(out)["actions"]
            if action["action"] == "SURVEY_PHOTOS"]


def _photos_by_mode(address: str, run: subprocess.Popen[bytes]) -> dict[int, int]:
    """CAMERA_FEEDBACK messages the vehicle sends on SERIAL1 until the run ends, counted
    by the mode of the latest HEARTBEAT."""
    conn: Any = mavutil.mavlink_connection(address, source_system=246, source_component=190)
    try:
        beat = conn.wait_heartbeat(timeout=60)
        assert beat is not None, f"no HEARTBEAT from {address}"
        system_id = beat.get_srcSystem()
        # Anything sent makes the channel active: ArduPilot sends CAMERA_FEEDBACK to all.
        conn.mav.command_long_send(system_id, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                   M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 1e6, 0, 0, 0, 0, 0)
        mode, photos = -1, dict[int, int]()
        end = time.monotonic() + 800
        while run.poll() is None:
            assert time.monotonic() < end, "the run hung"
            msg = conn.recv_match(type=["HEARTBEAT", "CAMERA_FEEDBACK"], blocking=True,
                                  timeout=1)
            if msg is None or msg.get_srcSystem() != system_id:
                continue
            if msg.get_type() == "HEARTBEAT" and msg.get_srcComponent() == 1:
                mode = msg.custom_mode
            elif msg.get_type() == "CAMERA_FEEDBACK":
                photos[mode] = photos.get(mode, 0) + 1
        return photos
    finally:
        conn.close()


@pytest.mark.timeout(900)
def test_arducopter_takes_the_photos_verify_predicts(ardupilot, tmp_path: Path) -> None:
    guided, auto = _predicted()
    (sitl,) = ardupilot(reboot_params={"CAM1_TYPE": 1})
    log = tmp_path / "survey_photos.jsonl"
    run = subprocess.Popen([sys.executable, "-m", "tml", "run", str(MISSION), "--connect",
                            sitl.address, "--clock", "vehicle", "-q", "--log", str(log)],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        photos = _photos_by_mode(sitl.companion_address, run)
    finally:
        if run.poll() is None:
            run.kill()
        run.wait()
    print(f"predicted GUIDED {guided}, AUTO {auto}; CAMERA_FEEDBACK by mode {photos}")
    assert run.returncode == 0
    assert abs(photos.get(GUIDED, 0) - guided) <= 2
    assert abs(photos.get(AUTO, 0) - auto) <= 2
    assert set(photos) <= {GUIDED, AUTO}  # none before, between or after the surveys
