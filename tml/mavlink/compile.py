"""Compile a run of actions (``dispatch="mission"``) to MAVLink mission items.

Theory of operation
-------------------
:func:`compile_mission` walks the actions of a :class:`~tml.vehicle.FlyMission` in order
with a *cursor*: where the vehicle is expected to be (local north, east, up from home) and
which way it faces once the items so far have been flown. Actions relative to the last
position (MOVE, relative GO_TO_POINT, LOITER without a centre, SURVEY_AREA without a base
point, SET_ALTITUDE) are resolved against the cursor, so the items always carry explicit
coordinates and the autopilot never has to guess what "here" meant.

Every local point is converted to WGS84 with :mod:`tml.geo` against the vehicle's home.
Altitudes go in frame GLOBAL_RELATIVE_ALT_INT (above home), GLOBAL_INT when the author gave
``altitude_reference="amsl"`` and GLOBAL_TERRAIN_ALT_INT for ``terrain`` (their twins without
_INT, GLOBAL_RELATIVE_ALT ..., with ``frame_encoding="float"``). Items are numbered
from 0; :meth:`tml.mavlink.autopilot.Autopilot.upload` shifts them behind ArduPilot's home
item. ``action_index[i]`` says which action item ``i`` came from, so that MISSION_CURRENT
and MISSION_ITEM_REACHED tell the interpreter which action is being flown.

What each action becomes is the ``items`` part of its definition in the action registry
(:mod:`tml.actions`, the shared pieces in :mod:`tml.actions.items`); the table is in
docs/run.md. The points of the patterns (the survey's lawnmower, the expanding square,
moves in the body frame) come from :mod:`tml.patterns`, where the scripts and the verifier
take them too: the items carry the path the interpreter flies with commands and the
verifier checks. The module is pure: no I/O, no clock; pymavlink is used for the MAV_CMD
and MAV_FRAME numbers only.

For a fixed-wing (:mod:`tml.language.kinds`) the landings (LAND, LANDING_POINT,
RETURN_HOME_AND_LAND) become a landing sequence, as ArduPlane lands: a waypoint where the
final approach starts and NAV_LAND at the touchdown (:func:`glide_items`); ArduPlane's
NAV_RETURN_TO_LAUNCH would only circle home.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from tml.actions import mav
from tml.actions.definition import NotApplicable
from tml.actions.items import FRAMES, PRECISION_MODES, SPEED_TYPES, Builder, Cursor, Item, glide
from tml.actions.registry import definition
from tml.geo import Point
from tml.language.actions import BoundAction, table_entry
from tml.language.kinds import Kind
from tml.language.mavlink_tables import MAV_FRAME
from tml.mavlink.codec import mavlink
from tml.mavlink.mission import MissionItem
from tml.world import Home

__all__ = ["FLOAT_FRAMES", "FRAMES", "PRECISION_MODES", "SPEED_TYPES", "CompileError",
           "CompiledMission", "compile_mission", "glide_items", "has_items"]

FLOAT_FRAMES = {
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_INT: mavlink.MAV_FRAME_GLOBAL,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
}
"""Each global frame tml writes -> its twin without _INT (frame_encoding="float"): the same
position (MAVLink made the _INT frames synonyms of their twins), named as ArduPilot's and
QGroundControl's files name it."""


class CompileError(ValueError):
    """An action that cannot become mission items (says which and why)."""


@dataclass(frozen=True)
class CompiledMission:
    """Mission items (seq 0..N-1) and, for each, the index of the action it came from."""

    items: tuple[MissionItem, ...]
    action_index: tuple[int, ...]

    def action_at(self, seq: int) -> int | None:
        """The action index of item ``seq`` (0-based, as compiled), or None if out of range."""
        return self.action_index[seq] if 0 <= seq < len(self.action_index) else None


def _numbered(items: list[Item]) -> tuple[MissionItem, ...]:
    """The items as MISSION_ITEM_INTs numbered from 0."""
    return tuple(MissionItem(seq=seq, frame=i.frame, command=i.command, param1=i.param1,
                             param2=i.param2, param3=i.param3, param4=i.param4, x=i.x, y=i.y,
                             z=i.z, autocontinue=i.autocontinue)
                 for seq, i in enumerate(items))


def compile_mission(actions: tuple[BoundAction, ...] | list[BoundAction], home: Home,
                    start: Point, heading: float = 0.0,
                    kind: Kind = Kind.MULTICOPTER) -> CompiledMission:
    """Mission items for ``actions`` flown from ``start`` (local) facing ``heading`` by a
    vehicle of ``kind``.

    Raises :class:`CompileError` for an action that has no mission-item form or whose
    argument is a label the interpreter did not resolve.
    """
    builder = Builder(home, Cursor(start, heading), kind=kind)
    for index, action in enumerate(actions):
        builder.action = index
        if action.labels.keys() - action.values.keys():
            missing = sorted(action.labels.keys() - action.values.keys())
            raise CompileError(f"{action.name}: argument {missing[0]!r} reads label "
                               f"{action.labels[missing[0]]!r}, which has no value yet")
        compiler = definition(action).items
        if isinstance(compiler, NotApplicable):
            raise CompileError(f"{action.name} cannot be flown as a mission item: "
                               f"{compiler.reason}")
        first = len(builder.items)
        try:
            compiler(builder, action)
        except ValueError as error:  # arguments that give no items (SURVEY_PHOTOS too low)
            raise CompileError(str(error)) from None
        if action.values.get("frame_encoding") == "float":
            builder.items[first:] = [replace(item, frame=FLOAT_FRAMES.get(item.frame, item.frame))
                                     for item in builder.items[first:]]
        written = action.values.get("frame") if action.name != "MISSION_ITEM" else None
        if written is not None:  # the frame a file gave its items without a position
            entry = table_entry(MAV_FRAME, str(written))
            assert entry is not None  # validated
            builder.items[first:] = [replace(item, frame=entry[0])
                                     if item.frame == mav.FRAME_MISSION else item
                                     for item in builder.items[first:]]
    _close_trailing_commands(builder)
    return CompiledMission(_numbered(builder.items), tuple(builder.owners))


def _close_trailing_commands(b: Builder) -> None:
    """End with a waypoint where the vehicle is when more than one DO/CONDITION item follows
    the last navigation item: ArduPilot ends the mission at the first of them otherwise
    (AP_Mission finds no next navigation command), and the others never run."""
    trailing = 0
    for seq in reversed(range(len(b.items))):
        if b.items[seq].command < mavlink.MAV_CMD_NAV_LAST:
            break
        if seq in b.written:  # the author wrote the items: they stay as written
            return
        trailing += 1
    if trailing > 1 and len(b.items) > trailing:
        b.waypoint(b.cursor.position)


def glide_items(home: Home, here: Point, heading: float,
                touchdown: Point | None) -> list[MissionItem]:
    """The landing sequence of a fixed-wing at ``here`` facing ``heading`` (items 0..N-1):
    straight ahead without a ``touchdown``, else into it."""
    builder = Builder(home, Cursor(here, heading), kind=Kind.FIXED_WING)
    glide(builder, touchdown)
    return list(_numbered(builder.items))


def has_items(action_name: str) -> bool:
    """Whether the action called ``action_name`` (canonical) has a mission-item form."""
    return not isinstance(definition(action_name).items, NotApplicable)
