"""Ctrl-C right after each request that can put a vehicle in the air never strands it.

A simulator runs in this process (in real time); ``tml run --connect`` flies a short
mission on it from its own process; the moment a request line reaches the flight log, the
run gets SIGINT. The verdict comes from a plain pymavlink client on the vehicle's port, not
from tml: after tml has exited, the vehicle must be seen disarmed on the ground.
"""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest
from connected_flight import FAST, log_lines, start_tml
from pymavlink import mavutil

from sitl.server import Simulator

MISSION = ('<mission name="Hop">\n'
           '  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="4"/>'
           '</action></task>\n'
           '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')
LIMIT = 120.0  # wall seconds for each state waited for: generous, a state is what is tested


def wait_for_request(log: Path, name: str, process: subprocess.Popen[str]) -> None:
    """Until the flight log has the request line ``name`` (tml flushes it at each decision)."""
    end = time.monotonic() + LIMIT
    while time.monotonic() < end:
        if any(line.get("kind") == "request" and line.get("message") == name
               for line in log_lines(log)):
            return
        assert process.poll() is None, process.communicate()
        time.sleep(0.005)
    raise AssertionError(f"no {name} request in the log")


def observe_safe(port: int) -> tuple[bool, float]:
    """A ground station of its own: (armed, relative altitude) once both a HEARTBEAT and a
    GLOBAL_POSITION_INT have arrived after it started watching, and the vehicle is disarmed
    on the ground -- or fail after LIMIT."""
    observer: Any = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=250,
                                               dialect="ardupilotmega")
    try:
        armed: bool | None = None
        altitude: float | None = None
        end = time.monotonic() + LIMIT
        while time.monotonic() < end:
            msg = observer.recv_match(type=["HEARTBEAT", "GLOBAL_POSITION_INT"],
                                      blocking=True, timeout=0.5)
            if msg is None or msg.get_srcSystem() != 1 or msg.get_srcComponent() != 1:
                continue
            if msg.get_type() == "HEARTBEAT":
                armed = bool(msg.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            else:
                altitude = msg.relative_alt / 1000.0
            if armed is False and altitude is not None and altitude < 0.3:
                return armed, altitude
        return bool(armed), altitude if altitude is not None else float("nan")
    finally:
        observer.close()


@pytest.mark.timeout(300)
@pytest.mark.parametrize("request_name", ["SetMode", "Arm", "TakeOff"])
def test_ctrl_c_right_after_a_request_leaves_the_vehicle_on_the_ground(
        tmp_path: Path, request_name: str) -> None:
    with Simulator(vehicles=1, tcp_base_port=0, speedup=10.0, params=FAST) as sim:
        port = sim.tcp_ports[0]
        process, log = start_tml(tmp_path, MISSION, port)
        try:
            wait_for_request(log, request_name, process)
            process.send_signal(signal.SIGINT)
            out, err = process.communicate(timeout=LIMIT)
        finally:
            process.kill()
        assert process.returncode == 3, (out, err)
        armed, altitude = observe_safe(port)
        assert (armed, altitude < 0.3) == (False, True), (out, err, armed, altitude)
    # A safe state commanded is confirmed. None is commanded when telemetry fresher than
    # the request already showed the vehicle disarmed on the ground (the rule of
    # tml.engine.safety), which a busy machine may see before the signal: the observer's
    # verdict above is the one that counts.
    safety = [line for line in log_lines(log) if line["kind"] == "safety"]
    assert not safety or safety[-1].get("confirmed"), safety
