"""``tml run --connect`` in a process of its own, flying a simulator that runs in the test's
process: the test watches the vehicle itself (an independent pymavlink client) and reads
the flight log tml flushes at each decision."""

from __future__ import annotations

import json
import subprocess
import sys
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


def log_lines(log: Path) -> list[dict[str, Any]]:
    """The flight log's lines so far (a line being written is left out)."""
    if not log.exists():
        return []
    return [json.loads(text) for text in log.read_text().splitlines() if text.endswith("}")]
