"""``tml run --connect`` in a process of its own, flying a simulator that runs in the test's
process: the test watches the vehicle itself (an independent pymavlink client) and reads
the flight log tml flushes at each decision."""

from __future__ import annotations

import contextlib
import json
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

FAST = {"SIM_GPS_LOCKTIME": 0.5, "SIM_EKF_GPS_TIME": 1.0}
"""Simulator parameters that make its vehicles armable within two seconds."""


def start_tml(tmp_path: Path, mission: str, port: int) -> tuple[subprocess.Popen[str], Path]:
    """``tml run`` of the ``mission`` text on the vehicle at ``port``; (process, its log)."""
    path = tmp_path / "mission.xml"
    path.write_text(mission)
    log = tmp_path / "flight.jsonl"
    process = subprocess.Popen(
        [sys.executable, "-m", "tml", "run", str(path), "--connect",
         f"tcp:127.0.0.1:{port}", "-q", "--log", str(log)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return process, log


def wait_for_task(process: subprocess.Popen[str], log: Path, task: str, state: str,
                  limit: float) -> None:
    """Wait until the flight log says task ``task`` is ``state`` (at most ``limit`` wall
    seconds, a hang guard; the run must not end first)."""
    end = time.monotonic() + limit
    while not any(line.get("kind") == "task" and line.get("task") == task
                  and line.get("state") == state for line in log_lines(log)):
        assert time.monotonic() < end and process.poll() is None, f"never: {task} {state}"
        time.sleep(0.01)


def log_lines(log: Path) -> list[dict[str, Any]]:
    """The flight log's lines so far (a line being written is left out)."""
    if not log.exists():
        return []
    return [json.loads(text) for text in log.read_text().splitlines() if text.endswith("}")]


@contextlib.contextmanager
def vehicles_on_one_udp_port(count: int, params: dict[str, float]) -> Iterator[str]:
    """``count`` simulated vehicles all sending to one UDP port, as several autopilots
    behind one radio or router do: the address (``udpin:``) that hears them all."""
    from sitl.server import Simulator

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with Simulator(vehicles=count, speedup=20, tcp_base_port=None, params=params,
                   udp_out=[f"udp:127.0.0.1:{port}"]):
        yield f"udpin:127.0.0.1:{port}"
