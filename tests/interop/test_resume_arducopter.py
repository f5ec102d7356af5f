"""``tml run`` killed with SIGKILL while flying ArduCopter SITL, then resumed (``--resume``): the
vehicle, which outlives the ground station, is not told to take off again, no task is
skipped or run twice, and the mission ends as a run left alone does
(benchmarks/resume.py holds the kill-and-resume both use). paper_example1 switches skills of
the companion computer: ``tml companion`` is attached to each vehicle's second port, and the
resumed run waits for it before it goes on, as the first did before take-off."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from test_ardupilot_missions import companion, stop
from test_resume_command import harness  # tests/ is on the path (conftest.py)

ROOT = Path(__file__).resolve().parents[2]


# Mid-climb (the TakeOff sent, the vehicle climbing when killed), on a leg, and landing;
# and while ArduCopter flies an uploaded plan in AUTO, which is followed, not uploaded again.
POINTS = {"paper_example1": [(3, 0.4), (9, 0.0), (14, 0.2)], "mission_dispatch": [(8, 1.0)]}


@pytest.mark.timeout(600)
@pytest.mark.parametrize("name", sorted(POINTS))
def test_killed_and_resumed_on_arducopter_ends_as_left_alone(name: str, ardupilot: Any,
                                                             tmp_path: Path) -> None:
    bench = harness()
    mission = ROOT / "missions" / f"{name}.xml"
    def fly(log: str, point: tuple[int, float] | None = None) -> Any:
        [sitl] = ardupilot()
        helper = companion(sitl, mission, tmp_path / f"companion-{log}.log") \
            if name == "paper_example1" else None
        try:
            return bench.fly(mission, sitl.address, tmp_path / f"{log}.jsonl", point)
        finally:
            if helper is not None:
                stop(helper)
            sitl.stop()

    alone = fly("alone")
    assert alone.exit_code == 0 and alone.takeoffs_flown == 1
    for count, delay in POINTS[name]:
        resumed = fly(str(count), (count, delay))
        assert resumed.runs == 2, (count, delay)
        assert resumed.exit_code == alone.exit_code, (count, delay)
        assert resumed.ends == alone.ends, (count, delay)
        assert resumed.takeoffs_flown == 1, (count, delay)
        assert resumed.takeoffs_commanded == 1, (count, delay)
        assert resumed.uploads == alone.uploads, (count, delay)
