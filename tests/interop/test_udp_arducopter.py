"""ArduCopter SITL sending MAVLink over UDP to tml (``--serial1 udpclient:HOST:PORT``, as a
vehicle, a companion computer or mavlink-router sends to a ground station): ``tml run
--connect udpin:HOST:PORT`` hears it first, answers whoever sent, and flies the mission."""

from __future__ import annotations

import json
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


@pytest.mark.timeout(600)
def test_two_arducopters_sending_to_one_port_need_a_sysid(ardupilot, tmp_path: Path) -> None:
    # As mavlink-router forwards a fleet to one ground-station port: two vehicles, each
    # with its SERIAL0 sending UDP to the same udpin address.
    port = _free_udp_port()
    first, second = ardupilot(count=2, serial0=f"udpclient:127.0.0.1:{port}")
    address = f"udpin:127.0.0.1:{port}"
    refused = fly_hop(tmp_path, address)
    ids = sorted((first.system_id, second.system_id))
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert refused.stderr.strip().splitlines()[-1] == (
        f"tml run: {address}: vehicles with system ids {ids[0]}, {ids[1]} heard: say which "
        f"to fly with --sysid N (repeated for several: --sysid {ids[0]} --sysid {ids[1]})")
    log = tmp_path / "flight.jsonl"
    done = fly_hop(tmp_path, address, "--sysid", str(second.system_id), "--log", str(log))
    said = done.stdout + done.stderr
    assert done.returncode == 0, said
    assert "vehicle 1: mission completed: all tasks done" in said
    assert json.loads(log.read_text().splitlines()[0])["system_ids"] == [second.system_id]
