"""How the interpreter gets the procedure that flies an action with commands
(``dispatch="command"``).

Each action's procedure is the ``guided`` part of its definition in the action registry
(:mod:`tml.actions`); the steps a procedure yields (:class:`Send`, :class:`Until`,
:class:`Sleep`), its failure (:class:`ActionFailed`), what it may read (:class:`Context`)
and the limits it assumes (:class:`Limits`) are :mod:`tml.actions.guided`'s, named here
for the engine. :func:`script_for` picks the procedure for the vehicle's kind, or refuses
the action with ACTION_FAILURE ``infeasible`` when the kind cannot do it at all
(:func:`tml.language.kinds.refusal`), before anything is sent.
"""

from __future__ import annotations

from tml.actions.definition import NotApplicable
from tml.actions.guided import (
    LANDED_READS,
    ActionFailed,
    Context,
    Limits,
    Script,
    Send,
    Sleep,
    Until,
    start_driving,
    vehicle_kind,
)
from tml.actions.registry import definition
from tml.language.actions import BoundAction
from tml.language.kinds import Kind, refusal

__all__ = ["LANDED_READS", "ActionFailed", "Context", "Limits", "Script", "Send", "Sleep",
           "Until", "procedure", "script_for"]


def _refused(reason: str, failure: str = "infeasible") -> Script:
    raise ActionFailed(failure, reason)
    yield  # a generator that fails when it is first run


def procedure(ctx: Context, bound: BoundAction) -> Script:
    """The action's own GUIDED procedure, as its definition gives it; for an action never
    flown with commands, one that fails with ACTION_FAILURE ``unsupported`` at once."""
    guided = definition(bound).guided
    if isinstance(guided, NotApplicable):
        return _refused(guided.reason, "unsupported")
    return guided(ctx, bound)


def _driven(ctx: Context, bound: BoundAction) -> Script:
    """A ground vehicle's move: armed first (it may not even know where it is before)."""
    if not ctx.state.armed:
        yield from start_driving(ctx)
    yield from procedure(ctx, bound)


def script_for(ctx: Context, bound: BoundAction, resumed: bool = False) -> Script:
    """The script flying ``bound`` on the vehicle of ``ctx``; for an action the vehicle's
    kind cannot do at all, one that fails with ACTION_FAILURE ``infeasible`` at once.
    ``resumed``: the action was running when the run was interrupted (tml.engine.resume)."""
    kind = vehicle_kind(ctx)
    cannot = refusal(bound, kind, ctx.state.vehicle_type)
    if cannot is not None:
        return _refused(cannot)
    action = definition(bound)
    if resumed and action.resumed is not None and ctx.state.flying:
        return action.resumed(ctx, bound)
    if kind is Kind.GROUND and action.drives:
        return _driven(ctx, bound)
    return procedure(ctx, bound)
