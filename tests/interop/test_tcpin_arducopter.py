"""ArduCopter SITL dialling the ground station (``--serial0 tcpclient:HOST:PORT``, as a
companion computer or a router that connects out): ``tml run --connect tcpin:HOST:PORT``
listens first, takes the connection and flies the mission."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hop_flight import HOP
from process_lines import follow, wait_for


@pytest.mark.timeout(600)
def test_arducopter_dialling_in_is_flown_through_tcpin(ardupilot, tmp_path: Path) -> None:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    mission = tmp_path / "hop.xml"
    mission.write_text(HOP)
    # tml listens before the vehicle starts: ArduPilot's tcpclient gives up after a few
    # refused tries.
    run = subprocess.Popen([sys.executable, "-m", "tml", "run", str(mission), "--connect",
                            f"tcpin:127.0.0.1:{port}", "--clock", "vehicle", "--timeout",
                            "120"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)
    try:
        assert run.stdout is not None
        said: list[str] = []
        lines = follow(run.stdout)
        wait_for(lines, said, "waiting up to 120 s for a vehicle at tcpin:",
                 time.monotonic() + 120, "tml run")
        ardupilot(serial0=f"tcpclient:127.0.0.1:{port}")
        assert run.wait(timeout=500) == 0, "".join(said) + "".join(lines.queue)
        wait_for(lines, said, "vehicle 1: mission completed: all tasks done",
                 time.monotonic() + 60, "tml run")
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
