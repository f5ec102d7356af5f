"""One forged HEARTBEAT claiming another mode does not make tml let the vehicle go.

Without signing, any client on a vehicle's link can send a HEARTBEAT as the autopilot
(system 1, component 1). A simulator runs in this process; ``tml run --connect`` flies a
mission with a hover on it from its own process; while it hovers, a second client sends one
HEARTBEAT saying LAND, which the vehicle's routing hands to tml as well. The autopilot's
next HEARTBEAT says GUIDED again: tml must fly on to the end, and say nothing of a take-over.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from connected_flight import FAST, log_lines, start_tml, wait_for_task
from pymavlink import mavutil

from sitl.server import Simulator

MISSION = ('<mission name="Hover">\n'
           '  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="4"/>'
           '</action></task>\n'
           '  <task name="Stay"><action name="WAIT"><argument name="duration" value="20"/>'
           '</action></task>\n'
           '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')
LIMIT = 120.0  # wall seconds for each state waited for


def test_one_forged_heartbeat_does_not_make_tml_let_go(tmp_path: Path) -> None:
    with Simulator(vehicles=1, tcp_base_port=0, speedup=5.0, params=FAST) as sim:
        port = sim.tcp_ports[0]
        process, log = start_tml(tmp_path, MISSION, port)
        forger: Any = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=1,
                                                 source_component=1, dialect="ardupilotmega")
        try:
            wait_for_task(process, log, "Stay", "running", LIMIT)
            armed = mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED
            custom = mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
            forger.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_QUADROTOR,
                                      mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                      armed | custom, 9, mavutil.mavlink.MAV_STATE_ACTIVE)
            out, err = process.communicate(timeout=LIMIT)
        finally:
            forger.close()
            process.kill()
    assert process.returncode == 0, (out, err)
    assert "outside tml" not in out + err and "commands it no more" not in out + err
    lines = log_lines(log)
    assert not [line for line in lines if line["kind"] == "taken"]
    assert [line["state"] for line in lines
            if line["kind"] == "task" and line.get("task") == "Down"][-1] == "done"
