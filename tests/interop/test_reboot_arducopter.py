"""ArduCopter SITL killed and started again in flight (the same instance, the same ports):
tml dials it again, sees its clock start from zero, and reports the reboot."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_taken import fly_leg


@pytest.mark.timeout(600)
def test_an_arducopter_restarted_in_flight_is_reported_rebooted(ardupilot,
                                                                 tmp_path: Path) -> None:
    (sitl,) = ardupilot()
    # The autopilot's process dies in the air and starts again.
    code, said, journal = fly_leg(sitl.address, tmp_path, sitl.restart, "--clock", "vehicle")
    assert code == 4, said
    assert "vehicle 1 rebooted while armed (its clock went from " in said, said
    assert ": tml commands it no more" in said
    rebooted = next(i for i, line in enumerate(journal) if line["kind"] == "taken")
    assert journal[rebooted]["reboot"] is True
    after = [line for line in journal[rebooted:] if line["kind"] in ("request", "safety")]
    assert after == [], after  # nothing sent to it after the reboot
