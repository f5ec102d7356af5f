"""``tml companion``: the simulated companion computer attached to a vehicle from outside."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from connected_flight import vehicles_on_one_udp_port
from flight_checks import check_imav2016

from sitl.server import Simulator
from tml.commands.cli import main
from tml.run.journal import read

MISSIONS = Path(__file__).parent.parent / "missions"
IMAV = str(MISSIONS / "imav2016.xml")
# The simulator's own companion computer is taken off board: every detection tml gets
# comes from the `tml companion` process.
PARAMS = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2, "SIM_COMPANION": 0}


def companion(address: str, *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "tml", "companion", "--connect", address,
                             *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def attached(process: subprocess.Popen[str]) -> str:
    """The companion's first line, once it has found the autopilot (a busy machine may take
    seconds to start a Python process: the flight must not start before it is there)."""
    assert process.stdout is not None
    return process.stdout.readline()


def stop(process: subprocess.Popen[str]) -> tuple[str, str]:
    process.send_signal(signal.SIGTERM)
    out, err = process.communicate(timeout=10)
    return out, err


def test_imav2016_flies_with_the_standalone_companion(tmp_path: Path) -> None:
    log = tmp_path / "imav2016.jsonl"
    with Simulator(speedup=20, tcp_base_port=0, params=PARAMS) as sim:
        address = f"tcp:127.0.0.1:{sim.tcp_ports[0]}"
        process = companion(address, "--world", IMAV)
        try:
            first = attached(process)
            code = main(["run", IMAV, "--connect", address, "--clock", "vehicle", "-q",
                         "--log", str(log)])
        finally:
            out, err = stop(process)
    assert process.returncode == 0, err
    assert "component 191 of system 1 attached" in first and "stopped (SIGTERM)" in out
    assert "Detected item 1 A" in out and "Detected bucket 1 A" in out
    assert code == 0
    check_imav2016(read(str(log)))


def test_the_world_can_be_a_world_file_and_the_system_id_is_kept(tmp_path: Path) -> None:
    world = tmp_path / "arena.xml"
    world.write_text('<world><object kind="item" id="A" north="0" east="0"/></world>')
    with Simulator(speedup=20, tcp_base_port=0, params=PARAMS) as sim:
        process = companion(f"tcp:127.0.0.1:{sim.tcp_ports[0]}", "--world", str(world),
                            "--system-id", "1", "--timeout", "20")
        line = attached(process)
        _, err = stop(process)
    assert "component 191 of system 1 attached" in line and "1 object(s)" in line, err
    assert process.returncode == 0


def test_a_link_that_hears_several_autopilots_needs_a_sysid(
        capsys: pytest.CaptureFixture[str]) -> None:
    with vehicles_on_one_udp_port(2, PARAMS) as address:
        assert main(["companion", "--connect", address, "--world", IMAV]) == 2
        assert capsys.readouterr().err.strip().splitlines() == [
            f"tml companion: {address}: vehicles with system ids 1, 2 heard: say which "
            "with --sysid N"]
        process = companion(address, "--world", IMAV, "--sysid", "2")
        line = attached(process)
        _, err = stop(process)
    assert "component 191 of system 2 attached" in line, err
    assert process.returncode == 0


@pytest.mark.parametrize(("argv", "message"), [
    (["--connect", "tcp:127.0.0.1", "--world", IMAV], "expected tcp:HOST:PORT"),
    (["--connect", "tcp:127.0.0.1:5762", "--world", "no/such/world.xml"],
     "no/such/world.xml: No such file or directory"),
])
def test_bad_arguments_are_usage_errors(argv: list[str], message: str,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["companion", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_an_invalid_world_file_says_where(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    world = tmp_path / "bad.xml"
    world.write_text('<world>\n  <object kind="spaceship" id="1" north="0" east="0"/>\n</world>')
    assert main(["companion", "--connect", "tcp:127.0.0.1:5762", "--world", str(world)]) == 2
    assert f"{world}:2" in capsys.readouterr().err


def test_a_system_id_out_of_range_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["companion", "--connect", "tcp:127.0.0.1:5762", "--world", IMAV,
                 "--system-id", "300"]) == 2
    assert "system id from 1 to 255" in capsys.readouterr().err


def test_no_autopilot_heard_is_a_link_failure(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.create_server(("127.0.0.1", 0)) as silent:  # accepts, never speaks
        port = silent.getsockname()[1]
        code = main(["companion", "--connect", f"tcp:127.0.0.1:{port}", "--world", IMAV,
                     "--timeout", "0.5", "-q"])
    assert code == 4
    assert "no heartbeat from an autopilot" in capsys.readouterr().err


def test_a_serial_device_that_does_not_exist_is_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    device = tmp_path / "ttyUSB9"
    code = main(["companion", "--connect", f"{device},57600", "--world", IMAV,
                 "--timeout", "0.5", "-q"])
    err = capsys.readouterr().err
    assert code == 4, err
    assert err.strip() == (f"tml companion: cannot open MAVLink connection '{device},57600': "
                           "No such file or directory")


def test_an_address_without_its_scheme_says_the_forms(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["companion", "--connect", "127.0.0.1:5762", "--world", IMAV]) == 2
    err = capsys.readouterr().err
    assert "not an address: a network address starts with its scheme" in err
    assert "e.g. tcp:127.0.0.1:5762" in err and len(err.strip().splitlines()) == 1
