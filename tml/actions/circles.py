"""Circling a point: LOITER and RETURN_HOME_AND_LOITER."""

from __future__ import annotations

from tml.actions import guided
from tml.actions.definition import ActionDef, spec
from tml.actions.guided import Context, Script
from tml.language.actions import BoundAction


def loiter(ctx: Context, bound: BoundAction) -> Script:
    """Fly to the centre and circle it: turns, a time, or until an event stops it."""
    here = guided.require_flying(ctx, "LOITER")
    centre = guided.point_argument(ctx, bound, "coordinates")
    relative = bound.point("relative_coordinates", None)
    if centre is None and relative is not None:
        dn, de, du = relative
        centre = (here[0] + dn, here[1] + de, here[2] + du)
    if centre is None:
        centre = bound.point("from_home", None)
    if centre is None and "latitude" in bound.values:
        centre = guided.local(ctx, bound)
    centre = centre or here
    yield from guided.circle(ctx, centre, bound.number("radius"), bound.number("turns", None),
                       bound.number("duration", None))


def return_home_and_loiter(ctx: Context, bound: BoundAction) -> Script:
    """Fly back over home and circle it until an event stops it."""
    here = guided.require_flying(ctx, "RETURN_HOME_AND_LOITER")
    yield from guided.circle(ctx, (0.0, 0.0, here[2]), bound.number("radius"), None, None)


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("LOITER"), guided=loiter, drives=True),
    ActionDef(spec("RETURN_HOME_AND_LOITER"), guided=return_home_and_loiter, drives=True),
)
