"""What one action of the catalogue is made of: :class:`ActionDef`, one field per stage.

See :mod:`tml.actions` for the design. A stage that truly does not apply to an action (a
FLIP has no mission item, a MISSION_ITEM is never flown with commands) holds a
:class:`NotApplicable` with the reason, which the stage's consumer gives when it refuses
the action; a part that is simply missing is an error when the registry loads
(:func:`tml.actions.registry.build`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from tml.actions.guided import Context, Limits, Script
from tml.actions.items import Builder
from tml.actions.motion import Labels, Motion, PredictedState, Step
from tml.actions.reading import Reading
from tml.geo import Point
from tml.language.actions import ActionSpec, BoundAction, lookup


@dataclass(frozen=True)
class NotApplicable:
    """A stage that does not apply to an action, and why (said when it is refused)."""

    reason: str


Procedure = Callable[[Context, BoundAction], Script]
"""The GUIDED procedure: a script of steps flying the action with commands
(:mod:`tml.actions.guided`)."""


ItemCompiler = Callable[[Builder, BoundAction], None]
"""The AUTO item compiler: appends the action's mission items to a builder
(:mod:`tml.actions.items`)."""


MotionModel = Callable[[Motion, BoundAction, PredictedState, Labels], Step]
"""The motion model for ``tml verify``: the step the action takes from a predicted state
(:mod:`tml.actions.motion`)."""


ItemTime = Callable[[Limits, str, Point, BoundAction], float]
"""The nominal seconds of the action flown as mission items by a vehicle of a type from a
point (:mod:`tml.actions.timing`)."""


@dataclass(frozen=True)
class ActionDef:
    """Everything tml knows about one action, stage by stage.

    ``spec``: the arguments, as the language validates them (:mod:`tml.language.actions`);
    ``guided``: how ``dispatch="command"`` flies it; ``items``: the mission items
    ``dispatch="mission"`` flies (NotApplicable: the language refuses it there, E260);
    ``item_time``: how long those items are expected to take (NotApplicable exactly when
    ``items`` is);
    ``motion``: what ``tml verify`` predicts it does (:func:`tml.actions.motion.instant`
    for an action that takes no time or battery in the model); ``resumed``: how it goes on
    when a run interrupted while it ran is resumed with the vehicle in the air (None: as
    ``guided``);
    ``imports``: how ``tml import`` reads mission items back as it
    (:mod:`tml.actions.reading`; NotApplicable for an action whose items read back as
    another's);
    ``drives``: a ground vehicle arms itself to drive before it (its moves).
    """

    spec: ActionSpec
    guided: Procedure | NotApplicable
    items: ItemCompiler | NotApplicable
    item_time: ItemTime | NotApplicable
    motion: MotionModel
    imports: Reading | NotApplicable
    drives: bool = False
    resumed: Procedure | None = None

    @property
    def name(self) -> str:
        """The canonical action name."""
        return self.spec.name


STAGES = ("guided", "items", "item_time", "motion", "imports")
"""The fields of :class:`ActionDef` every action must fill (a part or a NotApplicable)."""


def spec(name: str) -> ActionSpec:
    """The language's spec of the action called ``name`` (canonical); raises LookupError
    for a name the catalogue does not have."""
    found = lookup(name)
    if found is None or found.name != name:
        raise LookupError(f"{name!r} is not an action of the catalogue")
    return found
