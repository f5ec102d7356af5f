"""Every mission in missions/ flies on ArduPilot SITL to the outcome it has on the simulator.

Each test flies one mission twice, as a user would with ``tml run``: on the embedded
simulator exactly as tests/test_flights.py does (in a process of its own, at the same time,
so that the two flights share the wall time), and on ArduPilot SITL (speed-up 10, one
instance per vehicle, ``--clock vehicle``): ArduCopter, or the Plane and Rover that the
simulator's frames (``--sim-frame``) stand for. The expected exit code and outcome are
tests/test_flights.py's ``EXPECTED`` (one table for both). Both flight logs are then read:
besides the outcome, every task ends in the same state on both (done, skipped, failed,
aborted, never started), so no task is skipped on ArduCopter for want of telemetry, and
the tasks that fly on the simulator fly there too. A difference that has a reason is
listed in ``DIFFERENCES`` and in docs/interop.md. The missions that tests/test_flights.py
checks further (``flight_checks.LOG_CHECKS``: what was recognised, where the vehicles went)
are checked the same on ArduPilot.

The simulator's parameters of a flight become ArduCopter's where ArduCopter has the same
parameter (BATT_CAPACITY); the simulator's charging pad (SIM_BATT_CHARGE) is played by a
:class:`ChargingPad` on the vehicle's second port; missions whose skills need the companion
computer fly with ``tml companion`` attached to that port, and the flight starts once it
is attached. Every vehicle is fitted with a gripper at boot (GRIP_ENABLE takes effect only
then), as the simulator's vehicle is. Missions with more to show than their outcome
(``LOG_CHECKS``: IMAV 2016's items, buckets, gripper and landing at the operating zone)
are held to the same checks of the flight log as on the simulator.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from ardupilot_sitl import ChargingPad, SitlVehicle
from flight_checks import LOG_CHECKS
from shared_flights import FAST
from test_flights import EXPECTED, MISSIONS

from tml.commands.cli import main
from tml.language.validation import validate_file
from tml.mavlink.adapter import COMPANION, SKILL_BINDINGS
from tml.run.journal import read

ARDUPILOT_PARAMETERS = frozenset({"BATT_CAPACITY"})
"""Simulator parameters ArduCopter has under the same name and meaning."""
GRIPPER = {"GRIP_ENABLE": 1, "GRIP_TYPE": 1, "SERVO9_FUNCTION": 28}
"""Boot parameters that fit a servo gripper, as the simulator's vehicle has."""
ATTACH_TIMEOUT = 60.0
DIFFERENCES: dict[str, dict[str, str]] = {}
"""mission -> task -> why it ends differently on ArduCopter (see docs/interop.md)."""

Log = list[dict]


@dataclass
class Setup:
    """How a mission is flown on ArduPilot, from its simulator arguments."""

    vehicles: int = 1
    frames: list[str] = field(default_factory=lambda: ["copter"])  # per vehicle, last repeats
    params: dict[str, float] = field(default_factory=dict)
    charge_amps: float = 0.0
    tml_args: list[str] = field(default_factory=list)
    companion: bool = False


def setup(name: str) -> Setup:
    """Translate the simulator's extra arguments of EXPECTED into an ArduPilot set-up."""
    found = Setup()
    args = list(EXPECTED[name][2])
    while args:
        arg = args.pop(0)
        if arg == "--sim-param":
            key, _, value = args.pop(0).partition("=")
            if key in ARDUPILOT_PARAMETERS:
                found.params[key] = float(value)
            elif key == "SIM_BATT_CHARGE":
                found.charge_amps = float(value)
            else:
                raise AssertionError(f"{name}: no ArduPilot counterpart for {key}")
        elif arg == "--vehicles":
            found.vehicles = int(args.pop(0))
        elif arg == "--sim-frame":
            found.frames = args.pop(0).split(",")
        else:
            found.tml_args.append(arg)
    mission = validate_file(MISSIONS / f"{name}.xml").mission
    assert mission is not None
    skills = {skill.name for task in mission.walk() for skill in task.skills}
    found.companion = any(SKILL_BINDINGS[s].component == COMPANION
                          for s in skills if s in SKILL_BINDINGS)
    return found


def final_states(lines: Log) -> dict[str, str]:
    """Each task's last state in a flight log (tasks never started are left out)."""
    return {line["task"]: line["state"] for line in lines if line["kind"] == "task"}


def outcome(lines: Log) -> tuple[int, str]:
    (ended,) = [line for line in lines if line["kind"] == "run" and "outcomes" in line]
    return ended["exit_code"], ended["outcomes"][0]["reason"]


def companion(sitl: SitlVehicle, mission: Path, log: Path) -> subprocess.Popen[bytes]:
    """``tml companion`` attached to the vehicle's second port, as a process of its own;
    returns once it says it is attached (starting Python can take seconds on a busy
    machine, while the sped-up vehicle would fly on without it)."""
    with log.open("wb") as out:
        process = subprocess.Popen(
            [sys.executable, "-m", "tml", "companion", "--connect", sitl.companion_address,
             "--world", str(mission)], stdout=out, stderr=subprocess.STDOUT)
    end = time.monotonic() + ATTACH_TIMEOUT
    while b" attached to " not in log.read_bytes():
        if process.poll() is not None or time.monotonic() > end:
            stop(process)
            raise AssertionError(f"tml companion did not attach: {log.read_text()}")
        time.sleep(0.1)
    return process


def stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is None:
        os.kill(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.kill(process.pid, signal.SIGKILL)
            process.wait()


def start_on_the_simulator(name: str, tmp_path: Path) -> tuple[subprocess.Popen[bytes], Path]:
    """``tml run --sim`` of the mission as tests/test_flights.py flies it, started now."""
    log = tmp_path / f"{name}.simulator.jsonl"
    process = subprocess.Popen(
        [sys.executable, "-m", "tml", "run", str(MISSIONS / f"{name}.xml"), "--sim", "-q",
         "--log", str(log), *FAST, *EXPECTED[name][2]],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return process, log


def fly_on_ardupilot(name: str, vehicles: list[SitlVehicle], how: Setup, tmp_path: Path
                     ) -> tuple[int, Log, float]:
    log = tmp_path / f"{name}.ardupilot.jsonl"
    mission = MISSIONS / f"{name}.xml"
    helpers: list[subprocess.Popen[bytes]] = []
    pads = [ChargingPad(sitl, how.charge_amps, how.params.get("BATT_CAPACITY", 0.0))
            for sitl in vehicles] if how.charge_amps else []
    try:
        if how.companion:
            helpers = [companion(sitl, mission, tmp_path / f"companion-{sitl.instance}.log")
                       for sitl in vehicles]
        for pad in pads:
            pad.start()
        connects = [arg for sitl in vehicles for arg in ("--connect", sitl.address)]
        start = time.monotonic()
        code = main(["run", str(mission), *connects, "--clock", "vehicle", "-q",
                     "--log", str(log), *how.tml_args])
        wall = time.monotonic() - start
    finally:
        for pad in pads:
            pad.stop()
        for process in helpers:
            stop(process)
    return code, read(str(log)), wall


# Each test flies its mission twice at ArduCopter's pace: four ArduCopter instances and then
# four simulated vehicles for the fleet relay take over two minutes of wall time.
@pytest.mark.timeout(300)
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_mission_flies_on_ardupilot_as_on_the_simulator(name: str, ardupilot, tmp_path: Path
                                                        ) -> None:
    how = setup(name)
    vehicles = [sitl for index in range(how.vehicles) for sitl in ardupilot(
        vehicle=how.frames[min(index, len(how.frames) - 1)], params=how.params,
        boot_params=GRIPPER if how.frames[min(index, len(how.frames) - 1)] == "copter"
        else None)]
    simulator, sim_log = start_on_the_simulator(name, tmp_path)
    try:
        code, lines, wall = fly_on_ardupilot(name, vehicles, how, tmp_path)
        sim_code = simulator.wait(timeout=600)
    finally:
        stop(simulator)
    print(f"{name}: exit {code} in {wall:.1f} s of wall time at speed-up 10")
    expected_code, expected_reason, _ = EXPECTED[name]
    assert not [line for line in lines if line["kind"] == "error"]
    assert outcome(lines)[0] == code
    assert (code, expected_reason in outcome(lines)[1]) == (expected_code, True), outcome(lines)
    sim_lines = read(str(sim_log))
    assert sim_code == code
    on_sim, on_ardupilot = final_states(sim_lines), final_states(lines)
    allowed = DIFFERENCES.get(name, {})
    differing = {task: (on_sim.get(task, "never started"),
                        on_ardupilot.get(task, "never started"))
                 for task in on_sim.keys() | on_ardupilot.keys()
                 if on_sim.get(task) != on_ardupilot.get(task) and task not in allowed}
    assert differing == {}, "task: (on the simulator, on ArduCopter)"
    if name in LOG_CHECKS:
        LOG_CHECKS[name](lines)
    last = [line for line in lines if line["kind"] == "telemetry"][-1]
    assert last["mode"] != "AUTO" or last["landed"], "left flying an unwatched AUTO mission"
