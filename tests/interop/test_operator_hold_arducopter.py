"""ArduCopter SITL: ``tml command hold`` during a ``tml run`` goes through the run, and the
vehicle stops and stays.

``tml run`` flies a 300 m leg (SET_SPEED 6 first) from a child process on the vehicle's
first port;
mid-leg an operator runs ``tml command hold`` with the same address. It finds the run's
control socket, the run pauses (its vehicle held where it is), and the command says done
only once the vehicle's telemetry showed it stopped, and the GUIDED target it reports
(POSITION_TARGET_LOCAL_NED) is the run's zero velocity. A plain pymavlink ground station on
the vehicle's second port (SERIAL1) judges it: the vehicle moves less than 1 m in the 10 s
of its own time after the command, and the run, still paused, is not ended by it.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import pytest
from process_lines import follow, wait_for
from pymavlink import mavutil

from tml.run.journal import read

M = mavutil.mavlink
LEG = ('<mission name="Leg">\n'
       '  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/>'
       '</action></task>\n'
       '  <task name="Speed"><action name="SET_SPEED"><argument name="speed" value="6"/>'
       '</action></task>\n'
       '  <task name="Over"><action name="GO_TO_POINT"><argument name="coordinates" '
       'value="(300, 0, 10)"/></action></task>\n'
       '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')
HELD_FOR = 10.0  # s of the vehicle's time
WITHIN = 1.0  # m


class Observer:
    """A plain pymavlink client on the vehicle's second port: positions and their time."""

    def __init__(self, address: str) -> None:
        self.conn: Any = mavutil.mavlink_connection(address, source_system=246,
                                                    source_component=190)
        beat = self.conn.wait_heartbeat(timeout=60)
        assert beat is not None, f"no HEARTBEAT from {address}"
        self.system_id = beat.get_srcSystem()
        self.conn.mav.command_long_send(self.system_id, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                        M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 1e5,
                                        0, 0, 0, 0, 0)

    def position(self) -> tuple[float, float, float, float]:
        """(vehicle time s, north m, east m, ground speed m/s) of the next position."""
        end = time.monotonic() + 60
        while time.monotonic() < end:
            msg = self.conn.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=1)
            if msg is not None and msg.get_srcSystem() == self.system_id:
                north = msg.lat / 1e7 * 111_320.0
                east = msg.lon / 1e7 * 111_320.0 * math.cos(math.radians(msg.lat / 1e7))
                return msg.time_boot_ms / 1000, north, east, math.hypot(msg.vx, msg.vy) / 100
        raise AssertionError("no position from the vehicle")

    def now(self) -> float:
        """The vehicle's time now: the newest position's, the queue read to its end."""
        latest = self.position()[0]
        while (msg := self.conn.recv_match(type="GLOBAL_POSITION_INT", blocking=False)) \
                is not None:
            latest = max(latest, msg.time_boot_ms / 1000)
        return latest

    def close(self) -> None:
        self.conn.close()


@pytest.mark.timeout(900)
def test_hold_during_a_run_stops_the_vehicle_through_the_run(
        ardupilot, tmp_path: Path) -> None:
    (sitl,) = ardupilot()
    mission, log = tmp_path / "leg.xml", tmp_path / "leg.jsonl"
    mission.write_text(LEG)
    with tempfile.TemporaryDirectory(prefix="tml", dir="/tmp") as sockets:
        env = {**os.environ, "PYTHONUNBUFFERED": "1", "TML_RUNTIME_DIR": sockets}
        run = subprocess.Popen([sys.executable, "-m", "tml", "run", str(mission), "--connect",
                                sitl.address, "--log", str(log)], stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True, env=env)
        assert run.stdout is not None
        lines, seen = follow(run.stdout), []
        observer = Observer(sitl.companion_address)
        try:
            wait_for(lines, seen, "Over: running", time.monotonic() + 300, "tml run")
            end = time.monotonic() + 60
            while observer.position()[3] < 4.0:
                assert time.monotonic() < end, "never on its way at 4 m/s"
            command = subprocess.run(
                [sys.executable, "-m", "tml", "command", "hold", "--connect", sitl.address,
                 "--sysid", str(sitl.system_id), "--timeout", "60"],
                capture_output=True, text=True, env=env, timeout=300)
            said = command.stdout + command.stderr
            assert command.returncode == 0, said
            assert "hold done (the run paused)" in said and "[through the run]" in said
            # What ArduCopter flies to, by its own word: the run's zero velocity.
            assert "GUIDED target velocity 0.0 m/s" in said, said
            start = observer.now()
            track = [observer.position()]
            while track[-1][0] - max(start, track[0][0]) < HELD_FOR:
                track.append(observer.position())
            first = track[0]
            moved = max(math.hypot(n - first[1], e - first[2]) for _, n, e, _ in track)
            assert moved <= WITHIN, f"moved {moved:.2f} m in {HELD_FOR:g} s while held"
            assert run.poll() is None, "the run ended"
            wait_for(lines, seen, "mission paused: operator command: hold",
                     time.monotonic() + 10, "tml run")
            run.send_signal(signal.SIGINT)  # ends it into its safe state: RTL
            run.wait(timeout=300)
        finally:
            observer.close()
            if run.poll() is None:
                run.kill()
                run.wait()
    journal = read(str(log))
    assert not [line for line in journal if line["kind"] == "taken"]
    paused = [line for line in journal if line["kind"] == "control"]
    assert paused and paused[0]["message"] == "mission paused: operator command: hold"
