"""MISSION_ITEM: one MAVLink mission item exactly as written, flown only in AUTO."""

from __future__ import annotations

import math

from tml.actions import items, mav
from tml.actions.definition import ActionDef, NotApplicable, spec
from tml.geo import to_local
from tml.language.actions import GLOBAL_FRAME_NUMBERS, RAW_PARAMS, BoundAction

# --- mission items (dispatch="mission") ------------------------------------------------------


def mission_item_items(b: items.Builder, action: BoundAction) -> None:
    """The item as written; it moves the cursor when it navigates to a position."""
    command, frame = mav.number(action.text("command")), mav.number(action.text("frame"))
    params = tuple(action.number(name) for name in RAW_PARAMS)
    placed = frame in GLOBAL_FRAME_NUMBERS
    x, y = (round(v * 1e7) if placed else round(v) for v in params[4:6])
    b.items.append(items.Item(frame=frame, command=command, param1=params[0],
                              param2=params[1], param3=params[2], param4=params[3], x=x, y=y,
                              z=params[6], autocontinue=int(action.flag("autocontinue"))))
    b.owners.append(b.action)
    b.written.add(len(b.items) - 1)
    if placed and (x or y) and math.isfinite(params[6]) and command < mav.NAV_LAST:
        amsl = params[6] if frame in (mav.FRAME_GLOBAL, mav.FRAME_GLOBAL_INT) \
            else b.home.altitude + params[6]
        north, east, up = to_local(x / 1e7, y / 1e7, amsl, b.home.latitude,
                                   b.home.longitude, b.home.altitude)
        b.cursor.position = (north, east, up)


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("MISSION_ITEM"),
              guided=NotApplicable("MISSION_ITEM is flown only as a mission item "
                                   "(dispatch=\"mission\")"),
              items=mission_item_items),
)
