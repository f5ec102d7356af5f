"""ArduCopter SITL: FLIP the way ArduCopter flips, and its answers to repeated commands."""

from __future__ import annotations

from pathlib import Path

import pytest
from command_repeats import ARDUCOPTER, probe
from test_flights import MISSIONS

from tml.commands.cli import main
from tml.run.journal import read


@pytest.mark.timeout(300)
def test_repeated_commands_are_answered_as_recorded(ardupilot) -> None:
    (sitl,) = ardupilot()
    assert probe(sitl.address) == ARDUCOPTER


@pytest.mark.timeout(600)
def test_paper_example2_flips_three_times_through_alt_hold_and_back_to_guided(
        ardupilot, tmp_path: Path) -> None:
    (sitl,) = ardupilot()
    log = tmp_path / "flip.jsonl"
    code = main(["run", str(MISSIONS / "paper_example2.xml"), "--connect", sitl.address,
                 "--clock", "vehicle", "-q", "--log", str(log)])
    lines = read(str(log))
    ended = [line for line in lines if line["kind"] == "run" and "outcomes" in line][-1]
    assert (code, ended["outcomes"][0]["reason"]) == (0, "all tasks done"), ended
    flips = [line["detail"] for line in lines
             if line["kind"] == "result" and line.get("message") == "Flip done"]
    # Each flip: the vehicle's own HEARTBEATs showed FLIP, then the mode it came from, then
    # GUIDED again.
    assert flips == ["modes: ALT_HOLD > FLIP > ALT_HOLD > GUIDED"] * 3
    assert [line for line in lines if line["kind"] == "telemetry"][-1]["landed"]
