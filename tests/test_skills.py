"""The skill catalogue (tml.language.skills)."""

from __future__ import annotations

from tml.language import skills


def test_paper_and_aerostack_skills_are_known() -> None:
    for name in ("AVOID_OBSTACLES", "RECOGNIZE_VISUAL_MARKERS", "RECOGNIZE_ARUCO_MARKERS",
                 "SELF_LOCATE_BY_MARKERS", "RECOGNIZE_ITEMS", "RECOGNIZE_BUCKETS",
                 "SELF_LOCALIZE_BY_ARUCO_MARKERS", "SAY_OUT_LOUD_CURRENT_TASK"):
        assert skills.lookup(name) is not None, name


def test_lookup_ignores_case_and_separators() -> None:
    assert skills.lookup("recognize aruco markers").name == "RECOGNIZE_ARUCO_MARKERS"
    assert skills.lookup("SELF_LOCALIZE_BY_ARUCO_MARKERS").name == "SELF_LOCATE_BY_MARKERS"
    assert skills.lookup("FLY_BACKWARDS") is None


def test_recognition_skills_feed_parameters() -> None:
    assert skills.lookup("RECOGNIZE_ARUCO_MARKERS").feeds == ("RECOGNIZED_ARUCO_MARKERS",)
