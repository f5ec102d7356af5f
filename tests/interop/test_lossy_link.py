"""ArduCopter SITL through a link that loses 30 % of the MAVLink frames each way.

``tml run --connect`` reaches ArduCopter through tests/lossy_proxy.py: a GUIDED mission and
a ``dispatch="mission"`` one fly every task, judged from the flight log. ArduCopter answers a
repeated command by what it is doing (a NAV_TAKEOFF repeated once it is off the ground is
FAILED), so these flights need tml's judgement of lost ACKs by telemetry. paper_example1
switches skills of the companion computer: ``tml companion`` is attached to the vehicle's
second port (not through the proxy), and tml, which waits for it before take-off, hears it
through ArduCopter's routing and the lossy link.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from lossy_proxy import LossyProxy
from test_ardupilot_missions import companion, stop
from test_flights import MISSIONS

from tml.commands.cli import main
from tml.run.journal import read

# DISARM_DELAY 0: at ten times real time ArduCopter's 10 s before it disarms an idle armed
# vehicle are 1 s of the ground station's wall clock, less than one command timeout (1.5 s),
# so a take-off lost once would find it disarmed: that is the clocks, not the link.
PARAMS = {"DISARM_DELAY": 0}


def fly_through_loss(name: str, address_port: int, log: Path) -> tuple[int, list[dict],
                                                                       LossyProxy]:
    with LossyProxy(address_port, loss=0.3, seed=1) as proxy:
        code = main(["run", str(MISSIONS / f"{name}.xml"), "--connect", proxy.address,
                     "--clock", "vehicle", "-q", "--log", str(log)])
    return code, read(str(log)), proxy


def outcome(lines: list[dict]) -> dict:
    return [line for line in lines if line["kind"] == "run" and "outcomes" in line][-1]


@pytest.mark.timeout(600)
def test_a_guided_mission_flies_on_ardupilot_through_30_percent_loss(ardupilot,
                                                                     tmp_path: Path) -> None:
    (sitl,) = ardupilot(params=PARAMS)
    helper = companion(sitl, MISSIONS / "paper_example1.xml", tmp_path / "companion.log")
    try:
        code, lines, proxy = fly_through_loss("paper_example1", sitl.port,
                                              tmp_path / "g.jsonl")
    finally:
        stop(helper)
    ended = outcome(lines)
    assert (code, ended["outcomes"][0]["reason"]) == (0, "all tasks done"), ended
    done = [line["action"] for line in lines
            if line["kind"] == "action" and line["message"].endswith(" done")]
    assert done == ["TAKE_OFF", "STABILIZE", "GO_TO_POINT", "LAND"]
    assert proxy.up.dropped > 0 and proxy.down.loss_seen > 0.25


@pytest.mark.timeout(600)
def test_a_mission_dispatched_as_items_flies_on_ardupilot_through_30_percent_loss(
        ardupilot, tmp_path: Path) -> None:
    (sitl,) = ardupilot(params=PARAMS)
    code, lines, proxy = fly_through_loss("mission_dispatch", sitl.port, tmp_path / "m.jsonl")
    ended = outcome(lines)
    assert (code, ended["outcomes"][0]["reason"]) == (0, "all tasks done"), ended
    states = {line["task"]: line["state"] for line in lines if line["kind"] == "task"}
    assert states["Photo flight"] == "done" and set(states.values()) == {"done"}
    assert max(line["position"][2] for line in lines
               if line["kind"] == "telemetry" and line["position"]) > 20.0
    assert [line for line in lines if line["kind"] == "telemetry"][-1]["landed"]
    assert proxy.up.dropped_types.get("MISSION_ITEM_INT", 0) + proxy.down.dropped_types.get(
        "MISSION_REQUEST", 0) > 0  # the upload itself went through the loss
