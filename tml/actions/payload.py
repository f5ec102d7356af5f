"""The gripper: PICK_UP_ITEM and DROP_ITEM (IMAV 2016)."""

from __future__ import annotations

from tml.actions import guided, items, mav, reading, timing
from tml.actions.definition import ActionDef, spec
from tml.actions.guided import ActionFailed, Context, Script, Send, Sleep, fly_to
from tml.actions.motion import instant
from tml.language.actions import BoundAction
from tml.vehicle import Gripper


def pick_up_item(ctx: Context, bound: BoundAction) -> Script:
    """Descend to 1 m, close the gripper, climb back."""
    here = guided.require_flying(ctx, "PICK_UP_ITEM")
    if "gripper" not in ctx.state.capabilities:
        raise ActionFailed("unsupported", "this vehicle has no gripper")
    yield from fly_to(ctx, (here[0], here[1], min(here[2], 1.0)), "PICK_UP_ITEM")
    yield Send(Gripper(ctx.vehicle_id, grab=True))
    yield Sleep(1.0)
    yield from fly_to(ctx, here, "PICK_UP_ITEM")


def drop_item(ctx: Context, bound: BoundAction) -> Script:
    """Open the gripper."""
    if "gripper" not in ctx.state.capabilities:
        raise ActionFailed("unsupported", "this vehicle has no gripper")
    yield Send(Gripper(ctx.vehicle_id, grab=False))
    yield Sleep(1.0)


# --- mission items (dispatch="mission") ----------------------------------------

def pick_up_item_items(b: items.Builder, action: BoundAction) -> None:
    b.add(mav.DO_GRIPPER, params=(float(action.integer("gripper", 1)),
                                  mav.GRIPPER_ACTION_GRAB, 0.0, 0.0))


def drop_item_items(b: items.Builder, action: BoundAction) -> None:
    b.add(mav.DO_GRIPPER, params=(float(action.integer("gripper", 1)),
                                  mav.GRIPPER_ACTION_RELEASE, 0.0, 0.0))


# --- reading mission items back (tml import) ------------------------------------------------

def _gripper(item: reading.ItemFields) -> reading.Arguments:
    """A DO_GRIPPER's gripper number when not 1, and its frame when not MISSION."""
    arguments = {} if item.param1 == 1 else {"gripper": reading.value(item.param1)}
    return reading.frame(arguments, item)


def pick_up_item_read(item: reading.ItemFields) -> reading.Arguments | None:
    """DO_GRIPPER grabbing."""
    return _gripper(item) if int(item.param2) == mav.GRIPPER_ACTION_GRAB else None


def drop_item_read(item: reading.ItemFields) -> reading.Arguments | None:
    """DO_GRIPPER releasing."""
    return None if int(item.param2) == mav.GRIPPER_ACTION_GRAB else _gripper(item)


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("PICK_UP_ITEM"), guided=pick_up_item, items=pick_up_item_items, motion=instant,
              item_time=timing.nominal,
              imports=reading.Reading({mav.DO_GRIPPER: pick_up_item_read})),
    ActionDef(spec("DROP_ITEM"), guided=drop_item, items=drop_item_items, motion=instant,
              item_time=timing.nominal, imports=reading.Reading({mav.DO_GRIPPER: drop_item_read})),
)
