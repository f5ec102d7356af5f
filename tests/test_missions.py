"""Every example in missions/ is a valid mission."""

from __future__ import annotations

from pathlib import Path

import pytest

from tml.validation import validate_file

MISSIONS = sorted((Path(__file__).parent.parent / "missions").glob("*.xml"))


def test_there_are_example_missions() -> None:
    assert len(MISSIONS) >= 5


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: p.name)
def test_example_mission_is_valid(path: Path) -> None:
    result = validate_file(path)
    assert result.errors == [], "\n".join(str(d) for d in result.errors)
    assert result.mission is not None
    assert result.mission.tasks


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: p.name)
def test_example_mission_is_feasible_for_the_quadcopter(path: Path) -> None:
    from tml.verify.profile import load_profile
    from tml.verify.static import verify_mission

    result = validate_file(path)
    report = verify_mission(result.mission, load_profile("quadcopter"))
    assert report.violations == [], [str(v) for v in report.violations]
