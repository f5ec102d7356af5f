"""ArduCopter SITL killed and started again in flight (the same instance, the same ports):
tml dials it again, sees its clock start from zero, and reports the reboot."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from process_lines import wait_for
from test_taken import LEG, _tml_run

from tml.run.journal import read


@pytest.mark.timeout(600)
def test_an_arducopter_restarted_in_flight_is_reported_rebooted(ardupilot,
                                                                 tmp_path: Path) -> None:
    (sitl,) = ardupilot()
    mission, log = tmp_path / "leg.xml", tmp_path / "leg.jsonl"
    mission.write_text(LEG)
    run, lines, seen = _tml_run(mission, sitl.address, "--clock", "vehicle", "--log",
                                str(log))
    try:
        wait_for(lines, seen, "Over: running", time.monotonic() + 300, "tml run")
        sitl.restart()  # the autopilot's process dies in the air and starts again
        run.wait(timeout=180)
        wait_for(lines, seen, "mission (failed|aborted|completed)", time.monotonic() + 10,
                 "tml run")
    finally:
        if run.poll() is None:
            run.kill()
    said = "".join(seen)
    assert run.returncode == 4, said
    assert "vehicle 1 rebooted while armed (its clock went from " in said, said
    assert ": tml commands it no more" in said
    journal = read(str(log))
    rebooted = next(i for i, line in enumerate(journal) if line["kind"] == "taken")
    assert journal[rebooted]["reboot"] is True
    after = [line for line in journal[rebooted:] if line["kind"] in ("request", "safety")]
    assert after == [], after  # nothing sent to it after the reboot
