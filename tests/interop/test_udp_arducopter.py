"""ArduCopter SITL sending MAVLink over UDP to tml (``--serial1 udpclient:HOST:PORT``, as a
vehicle, a companion computer or mavlink-router sends to a ground station): ``tml run
--connect udpin:HOST:PORT`` hears it first, answers whoever sent, and flies the mission."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest
from hop_flight import fly_hop


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.mark.timeout(600)
@pytest.mark.parametrize("scheme", ["udpin", "udp"])
def test_arducopter_sending_udp_is_flown_through_udpin(ardupilot, tmp_path: Path,
                                                       scheme: str) -> None:
    port = _free_udp_port()
    ardupilot(extra=("--serial1", f"udpclient:127.0.0.1:{port}"))
    done = fly_hop(tmp_path, f"{scheme}:127.0.0.1:{port}")
    said = done.stdout + done.stderr
    assert done.returncode == 0, said
    assert "vehicle 1: mission completed: all tasks done" in said
