"""MISSION_ITEM: one MAVLink mission item exactly as written, flown only in AUTO."""

from __future__ import annotations

from tml.actions.definition import ActionDef, NotApplicable, spec

DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("MISSION_ITEM"),
              guided=NotApplicable("MISSION_ITEM is flown only as a mission item "
                                   "(dispatch=\"mission\")")),
)
