"""A vehicle that reboots during a run: the simulator reboots as ArduCopter does (on
MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, or a fault at a vehicle time), and tml says so."""

from __future__ import annotations

import os
import re
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("MAVLINK20", "1")
from connected_flight import FAST, log_lines, start_tml, wait_for_task
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M
from test_mavlink_adapter import make_rig
from test_sitl_server import connect, settle

from sitl.faults import Faults
from sitl.model import FORCE_REBOOT
from sitl.server import Simulator

LIMIT = 120.0  # wall seconds for each state waited for
HOVER = ('<mission name="Hover">\n'
         '  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="4"/>'
         '</action></task>\n'
         '  <task name="Stay"><action name="WAIT"><argument name="duration" value="60"/>'
         '</action></task>\n'
         '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')


def clock_fall(said: str, how: str) -> tuple[float, float]:
    """The two times of "HOW (its clock went from B s back to A s)"."""
    found = re.fullmatch(re.escape(how) + r" \(its clock went from ([0-9.]+) s back to "
                         r"([0-9.]+) s\)", said)
    assert found, said
    return float(found[1]), float(found[2])


def reboot_command(force: float = 0.0, what: float = 1.0) -> Any:
    return M.MAVLink_command_long_message(1, 1, M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 0,
                                          what, 0, 0, force, 0, 0, 0)


def test_the_simulator_reboots_as_arducopter_refusing_while_armed_unless_forced() -> None:
    with Simulator(tcp_base_port=0, realtime=False, params={**FAST, "DISARM_DELAY": 0}
                   ) as sim:
        link = connect(sim.tcp_ports[0])
        settle(sim, link, 3)
        link.send(M.MAVLink_command_long_message(1, 1, 176, 0, 1, 4, 0, 0, 0, 0, 0))
        link.send(M.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
        link.send(reboot_command())
        link.send(reboot_command(FORCE_REBOOT, what=0))
        link.send(reboot_command(FORCE_REBOOT))
        got = settle(sim, link, 2)
        acks = [(m.command, m.result) for m in got if m.get_type() == "COMMAND_ACK"]
        assert acks[2:] == [(246, M.MAV_RESULT_FAILED), (246, M.MAV_RESULT_UNSUPPORTED),
                            (246, M.MAV_RESULT_ACCEPTED)]
        vehicle = sim.vehicle(1)
        assert vehicle.time < 2.5 and not vehicle.armed and vehicle.mode == "STABILIZE"
        assert vehicle.params["DISARM_DELAY"] == 0  # kept, as in ArduPilot's EEPROM
        beats = [m for m in got if m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1]
        assert beats[-1].custom_mode == 0 and not beats[-1].base_mode & 128
        link.close()


def test_a_fault_reboots_the_simulated_autopilot_once_at_its_vehicle_time() -> None:
    with Simulator(tcp_base_port=0, realtime=False, faults=Faults(reboot_at=5.0)) as sim:
        sim.advance(6.0)
        assert 0.5 < sim.vehicle(1).time < 1.5
        sim.advance(5.0)
        assert sim.vehicle(1).time > 5.5  # the new boot is not rebooted again


def test_the_adapter_tells_a_reboot_in_flight_and_one_on_the_ground() -> None:
    with make_rig(faults=Faults(reboot_at=20.0)) as rig:
        rig.fly()
        state = rig.until(lambda s: bool(s.rebooted), "rebooted")
        before, after = clock_fall(state.rebooted, "rebooted while armed")
        assert 18.0 < before <= 20.05 and after < 10.0
        assert not state.armed and state.mode == "STABILIZE"
    with make_rig(faults=Faults(reboot_at=12.0)) as rig:
        state = rig.until(lambda s: bool(s.rebooted), "rebooted")
        before, after = clock_fall(state.rebooted, "rebooted disarmed")
        assert 10.0 < before <= 12.05 and after < 10.0


def test_a_vehicle_rebooted_in_flight_is_reported_and_commanded_no_more(
        tmp_path: Path) -> None:
    with Simulator(vehicles=1, tcp_base_port=0, speedup=5.0, params=FAST) as sim:
        port = sim.tcp_ports[0]
        process, log = start_tml(tmp_path, HOVER, port)
        other: Any = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=254,
                                                dialect="ardupilotmega")
        try:
            wait_for_task(process, log, "Stay", "running", LIMIT)
            end = time.monotonic() + LIMIT
            # An uptime the new boot's first stamps are far below (they come a second or
            # two after its first HEARTBEAT, at five times real time).
            while sim.vehicle(1).time < 40.0:
                assert time.monotonic() < end and process.poll() is None, "ended early"
                time.sleep(0.05)
            other.mav.send(reboot_command(FORCE_REBOOT))
            out, err = process.communicate(timeout=LIMIT)
        finally:
            other.close()
            process.kill()
    said = out + err
    assert process.returncode == 4, said
    assert "vehicle 1 rebooted while armed (its clock went from " in said, said
    assert ": tml commands it no more" in said
    lines = log_lines(log)
    rebooted = next(i for i, line in enumerate(lines) if line["kind"] == "taken")
    assert lines[rebooted]["reboot"] is True
    assert lines[rebooted]["message"].startswith("vehicle 1 rebooted while armed")
    after = [line for line in lines[rebooted:] if line["kind"] in ("request", "safety")]
    assert after == [], after  # nothing sent to it after the reboot
    ended = [line for line in lines if line["kind"] == "run" and "outcomes" in line][-1]
    assert "rebooted while armed" in ended["outcomes"][0]["reason"], ended
