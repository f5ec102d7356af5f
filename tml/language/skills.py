"""The skill catalogue: abilities a task switches on for its whole duration.

Skills come from the TML paper (IMAV 2016) and Aerostack's TML v1. How each binds to a
vehicle (autopilot parameters, a companion computer) is the interpreter's business; here
they have a name, a description and the detection parameters they feed.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tml.language.model import Mission


@dataclass(frozen=True)
class SkillSpec:
    """A skill: its name, what it does, and the parameters it feeds while active."""

    name: str
    description: str
    feeds: tuple[str, ...] = ()
    aliases: tuple[str, ...] = ()
    ground: bool = False
    """Carried out by tml itself, not switched on the vehicle (nothing is sent)."""


CATALOGUE: tuple[SkillSpec, ...] = (
    SkillSpec("AVOID_OBSTACLES", "Keep clear of obstacles while moving (proximity avoidance)."),
    SkillSpec("RECOGNIZE_VISUAL_MARKERS", "Recognise numbered visual markers in the camera.",
              ("RECOGNIZED_VISUAL_MARKERS",)),
    SkillSpec("RECOGNIZE_ARUCO_MARKERS", "Recognise the id numbers of ArUco markers.",
              ("RECOGNIZED_ARUCO_MARKERS",)),
    SkillSpec("SELF_LOCATE_BY_MARKERS", "Locate the vehicle from known visual markers.",
              aliases=("SELF_LOCALIZE_BY_ARUCO_MARKERS", "SELF_LOCALIZE_BY_MARKERS")),
    SkillSpec("RECOGNIZE_ITEMS", "Recognise the items to transport (IMAV 2016).",
              ("RECOGNIZED_ITEMS",)),
    SkillSpec("RECOGNIZE_BUCKETS", "Recognise the buckets to drop items in (IMAV 2016).",
              ("RECOGNIZED_BUCKETS",)),
    SkillSpec("RECOGNIZE_FRAMES", "Recognise coloured frames (doors and windows).",
              ("RECOGNIZED_FRAMES",)),
    SkillSpec("DETECT_OBSTACLES_BY_ARUCO_MARKERS",
              "Treat ArUco markers as obstacles (Aerostack).", ("RECOGNIZED_ARUCO_MARKERS",)),
    SkillSpec("SAY_OUT_LOUD_CURRENT_TASK",
              "Announce each task as it starts (Aerostack): tml says it in the flight log and "
              "the live view.", ground=True),
)


def _key(name: str) -> str:
    return re.sub(r"[\s_\-]+", "_", name.strip()).upper()


_BY_NAME = {_key(n): s for s in CATALOGUE for n in (s.name, *s.aliases)}


def lookup(name: str) -> SkillSpec | None:
    """The skill spec for a written skill name (case and separators ignored), or None."""
    return _BY_NAME.get(_key(name))


def vehicle_skills(names: Iterable[str]) -> frozenset[str]:
    """The skills among ``names`` that a vehicle must switch (the ground ones left out),
    by their catalogue names."""
    found = (lookup(name) for name in names)
    return frozenset(spec.name for spec in found if spec is not None and not spec.ground)


def switched(mission: Mission) -> frozenset[str]:
    """Every known skill ``mission`` switches on anywhere (on itself or on any task), by
    its catalogue name."""
    found = (lookup(skill.name) for skill in (
        *mission.skills, *(s for task in mission.walk() for s in task.skills)))
    return frozenset(spec.name for spec in found if spec is not None)


def feeders(parameter: str) -> tuple[str, ...]:
    """The skills that feed the built-in ``parameter`` (a catalogue name), in catalogue
    order."""
    return tuple(spec.name for spec in CATALOGUE if parameter in spec.feeds)


def mission_vehicle_skills(mission: Mission) -> frozenset[str]:
    """Every skill ``mission`` switches on a vehicle, its own and its tasks' (ground ones left
    out): what the vehicle must provide."""
    return vehicle_skills(skill.name for skill in (
        *mission.skills, *(s for task in mission.walk() for s in task.skills)))


def skill_names() -> list[str]:
    """Every accepted skill name and alias."""
    return sorted(_BY_NAME)
