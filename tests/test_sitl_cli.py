"""``python -m sitl``: argument errors, the listening lines, clean stop on signals."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from sitl.cli import main

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("argv, message", [
    (["--vehicles", "0"], "at least 1"),
    (["--vehicles", "256"], "at most 255 vehicles (a MAVLink system id is one byte)"),
    (["--home", "1,2"], "lat,lon,alt"),
    (["--home", "95,0,0"], "out of range"),
    (["--speedup", "0"], "greater than 0"),
    (["--loss-in", "1.5"], "probability"),
    (["--out", "udp:nowhere"], "UDP address"),
    (["--outage", "5:1"], "ends before"),
    (["--reject", "arm"], "CMD_ID"),
    (["--param", "BATT_CAPACITY=big"], "NAME=NUMBER"),
    (["--param", "NO_SUCH_PARAM=1"], "unknown simulator parameter 'NO_SUCH_PARAM'"),
    (["--frame", "copter,blimp"], "unknown frame 'blimp'"),
    (["--battery", "101"], "argument --battery: expected a percentage from 0 to 100, got 101"),
    (["--battery", "-5"], "argument --battery: expected a percentage from 0 to 100, got -5"),
    (["--battery", "nan"], "argument --battery: expected a percentage from 0 to 100, got nan"),
    (["--battery", "full"], "argument --battery: expected a number, got 'full'"),
    (["--tcp-base-port", "70000"], "expected a port number from 0 to 65535, got '70000'"),
    (["--tcp-base-port", "-1"], "expected a port number from 0 to 65535, got '-1'"),
    (["--tcp-base-port", "65530", "--vehicles", "2"],
     "--tcp-base-port 65530 with 2 vehicles puts vehicle 2 on port 65540, past 65535"),
])
def test_bad_arguments_exit_2_with_a_reason(argv, message, capsys):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_battery_and_fast_boot_are_parameter_settings() -> None:
    from sitl.cli import build_parser

    args = build_parser().parse_args(["--param", "SIM_EKF_GPS_TIME=5", "--battery", "40",
                                      "--fast-boot"])
    assert dict(args.param) == {"SIM_BATT_START": 40.0, "SIM_GPS_LOCKTIME": 1.0,
                                "SIM_EKF_GPS_TIME": 2.0}
    assert build_parser().parse_args([]).param == []  # the default list is left alone


def test_missing_world_file_exits_2(capsys, tmp_path):
    assert main(["--world", str(tmp_path / "absent.xml"), "--tcp-base-port", "0"]) == 2
    assert "absent.xml" in capsys.readouterr().err


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_runs_prints_where_it_listens_and_stops_on_signal(sig):
    process = subprocess.Popen(
        [sys.executable, "-m", "sitl", "--vehicles", "2", "--tcp-base-port", "0",
         "--speedup", "5", "--frame", "plane,rover"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = [process.stdout.readline() for _ in range(2)]
        assert lines[0].startswith("vehicle 1: tcp:127.0.0.1:")
        assert lines[1].startswith("vehicle 2: tcp:127.0.0.1:")
        assert "(plane; home" in lines[0] and "(rover; home" in lines[1]
        process.send_signal(sig)
        assert process.wait(timeout=10) == 0
    finally:
        process.kill()
        process.communicate()


@pytest.mark.parametrize("argv, message", [
    (["--speedup", "nan"], "argument --speedup: expected a finite number greater than 0"),
    (["--speedup", "inf"], "argument --speedup: expected a finite number greater than 0"),
    (["--latency", "nan"], "argument --latency: expected a finite number"),
    (["--out", "udp:127.0.0.1:0"], "UDP address"),
])
def test_tml_sim_refuses_numbers_it_cannot_run_with_and_speaks_as_itself(argv, message):
    done = subprocess.run([sys.executable, "-m", "tml", "sim", "--tcp-base-port", "0", *argv],
                          capture_output=True, text=True, timeout=30)
    assert done.returncode == 2
    assert message in done.stderr and "Traceback" not in done.stderr
    # One line: what is wrong and where the help is, not the synopsis of every option.
    assert done.stderr.startswith("tml sim: error: argument ")
    assert done.stderr.endswith(" (see tml sim --help)\n") and done.stderr.count("\n") == 1


def test_tml_sim_help_shows_defaults_and_its_name():
    done = subprocess.run([sys.executable, "-m", "tml", "sim", "--help"], capture_output=True,
                          text=True, timeout=30)
    assert done.returncode == 0 and done.stdout.startswith("usage: tml sim ")
    assert "python -m sitl" not in done.stdout
    text = " ".join(done.stdout.split())
    assert "K times faster than real time (default 1)" in text
    assert "(default 5760)" in text and "default: None" not in text


def test_tml_sim_takes_the_world_of_a_mission(tmp_path):
    process = subprocess.Popen(
        [sys.executable, "-m", "tml", "sim", "--tcp-base-port", "0", "--world",
         "missions/mission_dispatch.xml"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, cwd=str(ROOT))
    try:
        line = process.stdout.readline()
        # The mission's <environment> gives home at -35.363261, 149.165230, 584 m.
        assert "home -35.3632610,149.1652300,584.0" in line, process.stderr.read()
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=10) == 0
    finally:
        process.kill()
        process.communicate()


def test_tml_sim_errors_are_prefixed_like_the_rest(tmp_path):
    done = subprocess.run([sys.executable, "-m", "tml", "sim", "--tcp-base-port", "0",
                           "--world", str(tmp_path / "absent.xml")], capture_output=True,
                          text=True, timeout=30)
    assert done.returncode == 2
    assert done.stderr.startswith("tml sim: ") and "absent.xml" in done.stderr


def test_a_signing_key_file_that_cannot_be_read_exits_2_saying_so(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "missing"
    assert main(["--signing-key-file", str(missing), "--tcp-base-port", "0"]) == 2
    assert capsys.readouterr().err.strip() == (
        f"python -m sitl: --signing-key-file {missing}: No such file or directory")


def test_a_port_in_use_is_named_with_the_option_that_chooses_another() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = subprocess.run([sys.executable, "-m", "tml", "sim", "--tcp-base-port",
                               str(port)], capture_output=True, text=True, timeout=30)
    assert done.returncode == 1 and done.stdout == ""
    assert done.stderr == (
        f"tml sim: vehicle 1 cannot listen on TCP port {port} of 127.0.0.1: it is in use "
        "(another simulator or autopilot?); choose other ports with --tcp-base-port P "
        "(vehicle i listens on P + 10*(i-1); 0 takes free ones)\n")


def test_an_address_not_of_this_machine_is_named_with_bind() -> None:
    # 192.0.2.0/24 is TEST-NET-1: documentation only, never an address of this machine.
    done = subprocess.run([sys.executable, "-m", "sitl", "--bind", "192.0.2.1",
                           "--tcp-base-port", "5760"], capture_output=True, text=True,
                          timeout=30)
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert done.stderr.startswith(
        "python -m sitl: vehicle 1 cannot listen on port 5760 of 192.0.2.1: ")
    assert done.stderr.endswith("(--bind 192.0.2.1: is it an address of this machine?)\n")
