"""The action registry (tml.actions): every catalogue action provides every stage's part, a
missing one fails when the registry loads, and docs/language.md's action reference lists
exactly the registry's actions with their arguments."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest

from tml.actions import mav
from tml.actions.definition import STAGES, ActionDef, NotApplicable
from tml.actions.reading import Reading
from tml.actions.registry import MODULES, REGISTRY, RegistryError, build, definition
from tml.language.actions import CATALOGUE

ROOT = Path(__file__).resolve().parent.parent
DOC = (ROOT / "docs" / "language.md").read_text(encoding="utf-8")
DEFINITIONS = [d for module in MODULES for d in module.DEFINITIONS]


def test_the_registry_holds_every_catalogue_action_in_its_order() -> None:
    assert list(REGISTRY) == [spec.name for spec in CATALOGUE]
    assert all(REGISTRY[spec.name].spec is spec for spec in CATALOGUE)


@pytest.mark.parametrize("name", [spec.name for spec in CATALOGUE])
@pytest.mark.parametrize("stage", STAGES)
def test_every_action_provides_every_stage(name: str, stage: str) -> None:
    part = getattr(definition(name), stage)
    assert callable(part) or (isinstance(part, Reading) and part.commands) \
        or (isinstance(part, NotApplicable) and part.reason.strip())


@pytest.mark.parametrize("stage", STAGES)
def test_a_definition_missing_a_stage_fails_when_the_registry_loads(stage: str) -> None:
    first = DEFINITIONS[0]
    incomplete = replace(first, **{stage: None})
    with pytest.raises(RegistryError, match=f"{first.name} has no {stage!r} part"):
        build([incomplete, *DEFINITIONS[1:]])


def test_a_stage_that_does_not_apply_must_say_why() -> None:
    first = DEFINITIONS[0]
    silent = replace(first, guided=NotApplicable(" "))
    with pytest.raises(RegistryError, match="does not apply but says no reason"):
        build([silent, *DEFINITIONS[1:]])


def test_a_catalogue_action_without_a_definition_fails_when_the_registry_loads() -> None:
    with pytest.raises(RegistryError, match=f"{DEFINITIONS[-1].name} has no definition"):
        build(DEFINITIONS[:-1])


def test_an_action_defined_twice_or_outside_the_catalogue_fails() -> None:
    with pytest.raises(RegistryError, match="defined twice"):
        build([*DEFINITIONS, DEFINITIONS[0]])
    with pytest.raises(RegistryError, match="no action of the catalogue"):
        build(DEFINITIONS, [d.spec for d in DEFINITIONS[1:]])


def test_a_definition_must_carry_the_catalogue_spec() -> None:
    first = DEFINITIONS[0]
    other = replace(first.spec, description="another")
    with pytest.raises(RegistryError, match="spec is not the catalogue's"):
        build([ActionDef(other, **{s: getattr(first, s) for s in STAGES}), *DEFINITIONS[1:]])


def _section(name: str) -> str:
    start = DOC.index(f"#### {name}\n")
    end = DOC.find("\n#### ", start + 1)
    following = DOC.find("\n### ", start + 1)
    ends = [e for e in (end, following) if e >= 0]
    return DOC[start:min(ends) if ends else len(DOC)]


def test_the_action_index_of_docs_lists_exactly_the_registry() -> None:
    index = DOC[DOC.index("## Actions\n"):DOC.index("\n### ", DOC.index("## Actions\n"))]
    listed = re.findall(r"^\| \[`(\w+)`\]\(#", index, re.M)
    assert listed == list(REGISTRY)


@pytest.mark.parametrize("name", list(REGISTRY))
def test_the_reference_of_each_action_lists_exactly_its_arguments(name: str) -> None:
    rows = re.findall(r"^\| `(\w+)` \|", _section(name), re.M)
    assert rows == [argument.name for argument in REGISTRY[name].spec.arguments]


def test_the_item_stage_agrees_with_the_language() -> None:
    first = next(d for d in DEFINITIONS if d.spec.mission_item)
    with pytest.raises(RegistryError, match=f"{first.name}: the language says it has mission"):
        build([replace(first, items=NotApplicable("none")),
               *(d for d in DEFINITIONS if d is not first)])


@pytest.mark.parametrize("name", list(REGISTRY))
def test_the_reference_says_whether_each_action_has_mission_items(name: str) -> None:
    has = not isinstance(REGISTRY[name].items, NotApplicable)
    said = re.search(r"mission item: (yes|no|only)", _section(name))
    assert said is not None, f"docs/language.md's {name} does not say whether it has items"
    assert (said.group(1) in ("yes", "only")) is has


def test_the_item_numbers_are_pymavlinks() -> None:
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    numbers = {name: value for name, value in vars(mav).items()
               if name.isupper() and isinstance(value, int)}
    assert len(numbers) > 20
    for name, value in numbers.items():
        full = name if name.startswith("GRIPPER") else \
            f"MAV_{name}" if name.startswith("FRAME") else f"MAV_CMD_{name}"
        assert getattr(mavlink, full) == value, name


def test_an_item_time_goes_with_the_items() -> None:
    first = next(d for d in DEFINITIONS if not isinstance(d.items, NotApplicable))
    with pytest.raises(RegistryError, match=f"{first.name}: its item time must be"):
        build([replace(first, item_time=NotApplicable("none")),
               *(d for d in DEFINITIONS if d is not first)])


def test_a_reading_of_no_command_is_no_part() -> None:
    first = next(d for d in DEFINITIONS if isinstance(d.imports, Reading))
    with pytest.raises(RegistryError, match=f"{first.name} has no 'imports' part"):
        build([replace(d, imports=Reading({})) if d is first else d for d in DEFINITIONS])
