"""ArduCopter SITL on a serial device, as an autopilot behind a telemetry radio: socat makes
a pseudo-terminal pair, the vehicle's SERIAL0 takes one end (``--serial0
uart:PATH:57600``) and ``tml run --connect /dev/pts/N,57600`` flies a mission over the
other, real bytes through pyserial."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from hop_flight import fly_hop
from process_lines import follow, wait_for


@pytest.fixture
def pty_pair() -> Iterator[tuple[str, str]]:
    """Two pseudo-terminals joined by socat: (the vehicle's end, the ground station's)."""
    if shutil.which("socat") is None:
        pytest.skip("socat is not installed (apt-get install socat)")
    bridge = subprocess.Popen(["socat", "-d", "-d", "pty,raw,echo=0", "pty,raw,echo=0"],
                              stderr=subprocess.PIPE, text=True)
    try:
        assert bridge.stderr is not None
        seen: list[str] = []
        wait_for(follow(bridge.stderr), seen, "starting data transfer loop",
                 time.monotonic() + 60, "socat")
        ends = re.findall(r"PTY is (/dev/pts/\d+)", "".join(seen))
        assert len(ends) == 2, seen
        yield ends[0], ends[1]
    finally:
        bridge.terminate()
        bridge.wait(timeout=60)


@pytest.mark.timeout(600)
def test_arducopter_on_a_serial_device_is_flown_over_the_other_end(
        ardupilot, pty_pair: tuple[str, str], tmp_path: Path) -> None:
    vehicle_end, ground_end = pty_pair
    assert os.path.exists(ground_end)
    ardupilot(serial0=f"uart:{vehicle_end}:57600")
    done = fly_hop(tmp_path, f"{ground_end},57600")
    said = done.stdout + done.stderr
    assert done.returncode == 0, said
    assert "vehicle 1: mission completed: all tasks done" in said
