"""An operator's command to a vehicle a ``tml run`` flies goes through that run.

A simulator runs in this process; ``tml run --connect`` flies a long leg on it from a
process of its own; mid-leg, ``tml command hold`` (called here) finds the run's control
socket and the run pauses. An independent pymavlink client on the vehicle's port sees the
vehicle stop and stay within 1 m for 10 s of the vehicle's own time, while the run's
flight log says it was paused by the operator's command.
"""

from __future__ import annotations

import contextlib
import math
import signal
import subprocess
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from connected_flight import FAST, log_lines, start_tml, wait_for_task
from pymavlink import mavutil

from sitl.server import Simulator
from tml.commands.cli import main
from tml.run.control import ENVIRONMENT, runs_at

M = mavutil.mavlink
MISSION = ('<mission name="Leg">\n'
           '  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/>'
           '</action></task>\n'
           '  <task name="Speed"><action name="SET_SPEED"><argument name="speed" value="6"/>'
           '</action></task>\n'
           '  <task name="Leg"><action name="GO_TO_POINT">'
           '<argument name="point" value="(300,0,10)"/></action></task>\n'
           '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')
LIMIT = 120.0  # wall seconds for each state waited for (a hang guard, not a timing)
HELD_FOR = 10.0  # s of the vehicle's time the hold is watched
WITHIN = 1.0  # m the vehicle may move meanwhile


class Observer:
    """A plain pymavlink client on the vehicle's port (system 250): positions with the
    vehicle's time stamps."""

    def __init__(self, port: int) -> None:
        self.conn: Any = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}",
                                                    source_system=250, dialect="ardupilotmega")
        assert self.conn.wait_heartbeat(timeout=30) is not None
        self.conn.mav.request_data_stream_send(1, 1, M.MAV_DATA_STREAM_ALL, 10, 1)

    def position(self) -> tuple[float, float, float, float]:
        """(vehicle time s, north m, east m, ground speed m/s) of the next position."""
        end = time.monotonic() + LIMIT
        while time.monotonic() < end:
            msg = self.conn.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=1)
            if msg is not None and msg.get_srcSystem() == 1:
                north = msg.lat / 1e7 * 111_320.0
                east = msg.lon / 1e7 * 111_320.0 * math.cos(math.radians(msg.lat / 1e7))
                return msg.time_boot_ms / 1000, north, east, math.hypot(msg.vx, msg.vy) / 100
        raise AssertionError("no position from the vehicle")

    def until_speed(self, above: float) -> None:
        end = time.monotonic() + LIMIT
        while self.position()[3] <= above:
            assert time.monotonic() < end, f"never faster than {above} m/s"

    def track(self, after: float, seconds: float) -> list[tuple[float, float, float, float]]:
        """The positions over ``seconds`` of the vehicle's time from its time ``after``
        (those read before, still queued, are passed over)."""
        seen = [self.position()]
        while seen[0][0] < after:
            seen = [self.position()]
        while seen[-1][0] - seen[0][0] < seconds:
            seen.append(self.position())
        return seen

    def close(self) -> None:
        self.conn.close()


@pytest.fixture
def runtime_dir(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """A control-socket directory of this test's (short: a socket path has 108 bytes)."""
    with tempfile.TemporaryDirectory(prefix="tml", dir="/tmp") as directory:
        monkeypatch.setenv(ENVIRONMENT, directory)
        yield directory


@contextlib.contextmanager
def run_on_its_leg(tmp_path: Path) -> Iterator[tuple[Simulator, str, subprocess.Popen[str],
                                                     Path]]:
    """A simulator here and ``tml run`` flying its leg from its own process: (simulator,
    address, the run's process, its flight log); the run is killed after, if still on."""
    with Simulator(vehicles=1, tcp_base_port=0, speedup=4.0, params=FAST) as sim:
        port = sim.tcp_ports[0]
        process, log = start_tml(tmp_path, MISSION, port)
        try:
            wait_for_task(process, log, "Leg", "running", LIMIT)
            yield sim, f"tcp:127.0.0.1:{port}", process, log
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()


def test_hold_mid_leg_pauses_the_run_and_the_vehicle_stays(
        tmp_path: Path, runtime_dir: str, capsys: pytest.CaptureFixture[str]) -> None:
    with run_on_its_leg(tmp_path) as (sim, address, process, log):
        observer = Observer(int(address.rsplit(":", 1)[1]))
        try:
            observer.until_speed(4.0)
            assert runs_at(address) == [1]
            code = main(["command", "hold", "--connect", address, "--sysid", "1",
                         "--timeout", "60"])
            out = capsys.readouterr().out
            assert code == 0, out
            assert "vehicle 1: hold done (the run paused)" in out
            assert "[through the run]" in out
            track = observer.track(sim.time, HELD_FOR)
            first = track[0]
            moved = max(math.hypot(n - first[1], e - first[2]) for _, n, e, _ in track)
            assert moved <= WITHIN, f"moved {moved:.2f} m while held"
            assert max(speed for *_, speed in track) < 0.5
            assert process.poll() is None, "the run ended"
            process.send_signal(signal.SIGINT)  # ends it into its safe state (RTL)
            process.communicate(timeout=LIMIT)
        finally:
            observer.close()
    lines = log_lines(log)
    paused = [line for line in lines if line["kind"] == "control"
              and line.get("control") == "pause"]
    assert paused and paused[0]["message"] == "mission paused: operator command: hold"
    assert not [line for line in lines if line["kind"] == "taken"]
    assert not runs_at(address)  # the socket is gone with the run


def test_rtl_through_the_run_ends_it_into_rtl(
        tmp_path: Path, runtime_dir: str, capsys: pytest.CaptureFixture[str]) -> None:
    with run_on_its_leg(tmp_path) as (sim, address, process, log):
        code = main(["command", "rtl", "--connect", address, "--timeout", "60"])
        out, err = capsys.readouterr()
        assert code == 0, (out, err)
        assert "vehicle 1: rtl done (the run ends into rtl)" in out
        run_out, _ = process.communicate(timeout=LIMIT)
    assert process.returncode == 4, run_out  # taken by the operator (tml.run.endings)
    assert "mission aborted: operator command: rtl" in run_out
    assert "run taken (exit 4): taken over by an operator's command, carried out through " \
        "the run" in run_out
    assert sim.vehicle(1).mode in ("RTL", "LAND") or not sim.vehicle(1).armed
    assert not [line for line in log_lines(log) if line["kind"] == "taken"]

