"""``python -m sitl``: argument errors, the listening lines, clean stop on signals."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from sitl.cli import main


@pytest.mark.parametrize("argv, message", [
    (["--vehicles", "0"], "at least 1"),
    (["--home", "1,2"], "lat,lon,alt"),
    (["--home", "95,0,0"], "out of range"),
    (["--speedup", "0"], "positive"),
    (["--loss-in", "1.5"], "probability"),
    (["--out", "udp:nowhere"], "UDP address"),
    (["--outage", "5:1"], "ends before"),
    (["--reject", "arm"], "CMD_ID"),
    (["--param", "BATT_CAPACITY=big"], "NAME=NUMBER"),
    (["--param", "NO_SUCH_PARAM=1"], "unknown simulator parameter 'NO_SUCH_PARAM'"),
    (["--frame", "copter,blimp"], "unknown frame 'blimp'"),
])
def test_bad_arguments_exit_2_with_a_reason(argv, message, capsys):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


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
