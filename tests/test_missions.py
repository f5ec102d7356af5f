"""Every example in missions/ is a valid mission."""

from __future__ import annotations

from pathlib import Path

import pytest

from tml.language.validation import validate_file

MISSIONS = sorted((Path(__file__).parent.parent / "missions").glob("*.xml"))


def test_there_are_example_missions() -> None:
    assert len(MISSIONS) >= 5


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: p.name)
def test_example_mission_is_valid(path: Path) -> None:
    result = validate_file(path)
    assert result.errors == [], "\n".join(str(d) for d in result.errors)
    assert result.mission is not None
    assert result.mission.tasks


# The profile each example is written for (the quadcopter's when not listed).
PROFILES = {"plane_patrol": "fixed-wing", "rover_delivery": "rover"}


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: p.name)
def test_example_mission_is_feasible_for_its_vehicle(path: Path) -> None:
    from tml.verify.profile import load_profile
    from tml.verify.static import verify_mission

    result = validate_file(path)
    report = verify_mission(result.mission, load_profile(PROFILES.get(path.stem, "quadcopter")))
    assert report.violations == [], [str(v) for v in report.violations]


@pytest.mark.parametrize(("name", "wrong"), [("rover_delivery", "quadcopter"),
                                             ("plane_patrol", "rover")])
def test_a_vehicle_mission_is_refused_with_another_kind_of_vehicle(name: str,
                                                                   wrong: str) -> None:
    from tml.verify.profile import load_profile
    from tml.verify.static import verify_mission

    result = validate_file(MISSIONS[0].parent / f"{name}.xml")
    assert not verify_mission(result.mission, load_profile(wrong)).feasible
