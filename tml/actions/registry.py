"""The registry: every action of the catalogue with every stage's part, checked once.

:data:`REGISTRY` is built when this module is first imported, from the ``DEFINITIONS`` of
the modules in :data:`MODULES`; :func:`build` refuses (:class:`RegistryError`) a catalogue
action without a definition, a definition of no catalogue action or given twice or with
another spec than the catalogue's, a definition missing a stage's part (see
:data:`tml.actions.definition.STAGES`), an ``items`` part that contradicts the language's
``mission_item`` (which ``tml validate`` checks, E260, without loading this package), and an
``item_time`` without items or items without one.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from types import MappingProxyType

from tml.actions import (
    areas,
    camera,
    circles,
    hover,
    moves,
    orbit,
    payload,
    raw,
    settings,
    survey_photos,
    takeoff_landing,
)
from tml.actions.definition import STAGES, ActionDef, NotApplicable
from tml.actions.reading import Reading
from tml.language.actions import CATALOGUE, ActionSpec, BoundAction

MODULES = (takeoff_landing, moves, circles, areas, hover, payload, camera, settings, raw,
           orbit, survey_photos)
"""The action modules, each with its ``DEFINITIONS``: a new action is a new module here
(or a new definition in the module of its family)."""


class RegistryError(Exception):
    """The action definitions do not cover the catalogue, every action and every stage."""


def build(definitions: Iterable[ActionDef],
          catalogue: Iterable[ActionSpec] = CATALOGUE) -> Mapping[str, ActionDef]:
    """The registry: canonical action name -> its definition, read-only. Raises
    :class:`RegistryError` saying every part that is missing or wrong."""
    specs = {spec.name: spec for spec in catalogue}
    problems: list[str] = []
    found: dict[str, ActionDef] = {}
    for definition in definitions:
        if definition.name in found:
            problems.append(f"{definition.name} is defined twice")
        found[definition.name] = definition
        for stage in STAGES:
            part = getattr(definition, stage, None)
            if isinstance(part, NotApplicable):
                if not part.reason.strip():
                    problems.append(f"{definition.name}: stage {stage!r} does not apply "
                                    "but says no reason")
            elif not (callable(part) or (isinstance(part, Reading) and part.commands)):
                problems.append(f"{definition.name} has no {stage!r} part")
    problems += [f"{name} has no definition" for name in specs if name not in found]
    problems += [f"{name} is defined but is no action of the catalogue"
                 for name in found if name not in specs]
    problems += [f"{name}: its definition's spec is not the catalogue's"
                 for name, spec in specs.items() if name in found and found[name].spec is not spec]
    problems += [f"{name}: the language says it {'has' if spec.mission_item else 'has no'} "
                 "mission item, its definition the opposite"
                 for name, spec in specs.items() if name in found and spec.mission_item
                 is isinstance(found[name].items, NotApplicable)]
    problems += [f"{name}: its item time must be NotApplicable exactly when its items are"
                 for name, d in found.items() if isinstance(d.items, NotApplicable)
                 is not isinstance(d.item_time, NotApplicable)]
    if problems:
        raise RegistryError("the action registry is incomplete: " + "; ".join(problems))
    return MappingProxyType({name: found[name] for name in specs})


REGISTRY = build(d for module in MODULES for d in module.DEFINITIONS)
"""Every action of the catalogue, by canonical name, in the catalogue's order."""


def definition(bound: BoundAction | str) -> ActionDef:
    """The definition of a bound action (or of a canonical action name)."""
    return REGISTRY[bound if isinstance(bound, str) else bound.name]
