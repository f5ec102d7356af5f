"""Actions in place: ROTATE_YAW, STABILIZE, WAIT and FLIP."""

from __future__ import annotations

from dataclasses import replace

from tml.actions import guided, items, mav, reading, timing
from tml.actions.definition import ActionDef, NotApplicable, spec
from tml.actions.guided import ActionFailed, Context, Script, Send, Sleep, Until, fly_to
from tml.actions.motion import Labels, Motion, PredictedState, Step, instant
from tml.language.actions import BoundAction
from tml.language.kinds import Kind
from tml.vehicle import Flip, Hold


def rotate_yaw(ctx: Context, bound: BoundAction) -> Script:
    """Turn by an angle, or to a heading; done when the heading is within tolerance."""
    guided.require_flying(ctx, "ROTATE_YAW")
    heading = ctx.state.heading
    angle = bound.number("angle", None)
    if angle is not None:
        target = (heading + angle) % 360
    else:
        target = bound.number("orientation_angle") % 360
    yield from guided.face(ctx, target)


def stabilize(ctx: Context, bound: BoundAction) -> Script:
    """Stop all motion and hold (a fixed-wing cannot stop: it circles where it is)."""
    guided.require_flying(ctx, "STABILIZE")
    yield Send(Hold(ctx.vehicle_id))
    if guided.vehicle_kind(ctx) is Kind.FIXED_WING:
        ctx.note("STABILIZE: a fixed-wing cannot stop; it circles where it is")
        return
    yield Until(lambda s: s.ground_speed <= 0.3, ctx.limits.slack, "come to a stop")


def wait(ctx: Context, bound: BoundAction) -> Script:
    """Hold position (when flying) for a time."""
    if ctx.state.possibly_flying:
        yield Send(Hold(ctx.vehicle_id))
    yield Sleep(bound.number("duration"))


def flip(ctx: Context, bound: BoundAction) -> Script:
    """One flip as ArduCopter makes it (:class:`~tml.vehicle.Flip`), then back where it began.

    A flip costs ArduCopter about 4 m of height, so below ``flip_altitude`` the vehicle
    climbs there first; afterwards it flies back to the point it started from.
    """
    start = guided.require_flying(ctx, "FLIP")
    if "flip" not in ctx.state.capabilities:
        raise ActionFailed("unsupported", "this vehicle has no FLIP mode")
    high = max(start[2], ctx.limits.flip_altitude)
    if high - start[2] > ctx.limits.acceptance_radius:
        ctx.note(f"FLIP: climbing to {high:g} m first, a flip costs about 4 m",
                 altitude=high)
        yield from fly_to(ctx, (start[0], start[1], high), "FLIP")
    yield Send(Flip(ctx.vehicle_id, bound.choice("direction")))
    yield from fly_to(ctx, start, "FLIP")


# --- mission items (dispatch="mission") ----------------------------------------

def rotate_yaw_items(b: items.Builder, action: BoundAction) -> None:
    angle = action.number("angle", None)
    if angle is not None:
        items.yaw_item(b, angle, relative=True)
    else:
        items.yaw_item(b, action.number("orientation_angle") % 360.0, relative=False)


def stabilize_items(b: items.Builder, action: BoundAction) -> None:
    b.add(mav.NAV_DELAY, params=(0.0, -1.0, -1.0, -1.0))


def wait_items(b: items.Builder, action: BoundAction) -> None:
    # NAV_DELAY param1 is seconds; params 2-4 (a time of day) are -1: not used (or as the
    # file wrote them: ArduPilot reads them only when param1 is not above 0).
    clock = action.number("time_of_day", -1.0)
    b.add(mav.NAV_DELAY, params=(action.number("duration"), clock, clock, clock))


# --- motion models (tml verify) -------------------------------------------------------------

def rotate_yaw_motion(model: Motion, bound: BoundAction, state: PredictedState,
                      labels: Labels) -> Step:
    angle = bound.number("angle", None)
    if angle is not None:
        turn = angle
    else:
        turn = (bound.number("orientation_angle") - state.heading + 180.0) % 360.0 - 180.0
    after = model.hover(state, abs(turn) / model.profile.yaw_rate)
    return Step(state, replace(after, heading=(state.heading + turn) % 360.0), labels=labels)


def wait_motion(model: Motion, bound: BoundAction, state: PredictedState,
                labels: Labels) -> Step:
    if not state.flying:  # waits where it stands, as WAIT does (a NAV_DELAY after a landing)
        after = replace(state, time=state.time + bound.number("duration"))
        return Step(state, after, grounded=True, labels=labels)
    return Step(state, model.hover(state, bound.number("duration")), labels=labels)


# --- reading mission items back (tml import) ------------------------------------------------

def rotate_yaw_read(item: reading.ItemFields) -> reading.Arguments:
    """CONDITION_YAW: a turn in the direction param3 gives when relative, else a heading."""
    if item.param4:
        return {"angle": reading.value(item.param1 * (-1 if item.param3 < 0 else 1))}
    return {"orientation_angle": reading.value(item.param1)}


def stabilize_read(item: reading.ItemFields) -> reading.Arguments | None:
    """NAV_DELAY of no time."""
    return {} if item.param1 <= 0 else None


def wait_read(item: reading.ItemFields) -> reading.Arguments | None:
    """NAV_DELAY of a time, with the unused time of day when a file wrote it 0 (not -1) and
    the frame a file wrote."""
    clock = (item.param2, item.param3, item.param4)
    if item.param1 <= 0 or any(c != clock[0] for c in clock) or clock[0] not in (0, -1):
        return None
    arguments = {"duration": reading.value(item.param1)}
    if clock[0] == 0:
        arguments["time_of_day"] = "0"
    return reading.frame(arguments, item)


_NO_ITEM = NotApplicable("has no mission item: ArduCopter enters FLIP from "
                         "ALT_HOLD with the sticks held, never from a mission")
"""Why FLIP has no mission item (nor an item time)."""


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("ROTATE_YAW"), guided=rotate_yaw, items=rotate_yaw_items,
              motion=rotate_yaw_motion, item_time=timing.nominal,
              imports=reading.Reading({mav.CONDITION_YAW: rotate_yaw_read})),
    ActionDef(spec("STABILIZE"), guided=stabilize, items=stabilize_items, motion=instant,
              item_time=timing.nominal, imports=reading.Reading({mav.NAV_DELAY: stabilize_read})),
    ActionDef(spec("WAIT"), guided=wait, items=wait_items, motion=wait_motion,
              item_time=timing.nominal, imports=reading.Reading({mav.NAV_DELAY: wait_read})),
    ActionDef(spec("FLIP"), guided=flip, items=_NO_ITEM, motion=instant, item_time=_NO_ITEM,
              imports=_NO_ITEM),
)
