"""MISSION_ITEM: one MAVLink mission item exactly as written, flown only in AUTO."""

from __future__ import annotations

import math
from dataclasses import replace

from tml.actions import items, mav, timing
from tml.actions.definition import ActionDef, NotApplicable, spec
from tml.actions.motion import Labels, Motion, PredictedState, Step
from tml.actions.takeoff_landing import return_home_and_land_motion
from tml.geo import to_local
from tml.language.actions import GLOBAL_FRAME_NUMBERS, RAW_PARAMS, BoundAction, table_entry
from tml.language.kinds import Kind
from tml.language.mavlink_tables import MAV_FRAME

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


# --- motion models (tml verify) -------------------------------------------------------------

def mission_item_motion(model: Motion, bound: BoundAction, state: PredictedState,
                        labels: Labels) -> Step:
    """A raw mission item, as the autopilot flies its command: a take-off climbs, a
    navigation item with a position flies there (and holds or loiters its param1
    seconds where the command says so), a landing lands, a return to launch comes
    home; other commands (DO_, CONDITION_) take no time. A DO_JUMP's repeats are not
    predicted."""
    command = bound.text("command").removeprefix("MAV_CMD_")
    frame = table_entry(MAV_FRAME, bound.text("frame"))
    hold = bound.number("param1")
    altitude = bound.number("param7")
    if not math.isfinite(altitude):
        altitude = state.position[2]
    elif frame is not None and frame[0] in (0, 5):  # above sea level
        altitude -= model.home.altitude
    latitude, longitude = bound.number("param5"), bound.number("param6")
    placed = frame is not None and frame[0] in GLOBAL_FRAME_NUMBERS \
        and (latitude or longitude)
    if bound.number("param7") == 0:  # ArduCopter: an altitude of 0 is the current one
        altitude = state.position[2]
    here = model.local(latitude, longitude, altitude, "relative") if placed \
        else (*state.position[:2], altitude)
    if command in ("NAV_TAKEOFF", "NAV_VTOL_TAKEOFF"):
        if state.flying or model.profile.kind is Kind.GROUND:
            return Step(state, state, labels=labels)
        step = model.go(bound, replace(state, flying=True), labels,
                        [(*state.position[:2], altitude)], cruise=False)
        return replace(step, before=state)
    if command in ("NAV_LAND", "NAV_VTOL_LAND"):
        if model.profile.kind is Kind.GROUND:
            return Step(state, state, labels=labels)
        target = (*here[:2], 0.0) if placed else (*state.position[:2], 0.0)
        if model.profile.kind is Kind.FIXED_WING:
            return model.landing(bound, state, labels, target)
        targets = [(*here[:2], state.position[2]), target] if placed else [target]
        step = model.go(bound, state, labels, targets, landing=True, cruise=False)
        return replace(step, after=replace(step.after, flying=False))
    if command == "NAV_RETURN_TO_LAUNCH":
        return return_home_and_land_motion(model, bound, state, labels)
    if command == "NAV_DELAY" and hold > 0:
        return Step(state, model.hover(state, hold), labels=labels)
    if command.startswith("NAV_") and command not in ("NAV_DELAY",):
        step = model.go(bound, state, labels, [here])
        if command in ("NAV_WAYPOINT", "NAV_LOITER_TIME") and hold > 0 \
                and math.isfinite(hold):
            step = replace(step, after=model.hover(step.after, hold))
        return step
    notes = ("DO_JUMP: its repeats are not predicted",) if command == "DO_JUMP" else ()
    return Step(state, state, labels=labels, notes=notes)


DEFINITIONS: tuple[ActionDef, ...] = (
    ActionDef(spec("MISSION_ITEM"),
              guided=NotApplicable("MISSION_ITEM is flown only as a mission item "
                                   "(dispatch=\"mission\")"),
              items=mission_item_items, motion=mission_item_motion, item_time=timing.nominal,
              imports=NotApplicable("an item no other action reads back exactly is one: "
                                    "the importer's own way (tml.plans.imported)")),
)
