"""The reading toolkit: how ``tml import`` reads mission items back as the actions they came
from (:mod:`tml.plans.imported`, theory of operation there).

An action's ``imports`` part (a :class:`Reading`) names the MAV_CMDs it may come from, each
with a reader that gives the action's arguments (as the XML writes them) when an item reads
back as this action, None otherwise; the readers of one command are exclusive (NAV_LAND
without a position is a LAND, with one a LANDING_POINT). ``join`` merges an action into the
one before it when the compiler wrote the two as one action (a LANDING_POINT's heading, a
LOITER's turns beyond what one item keeps). The importer keeps an action only when it
compiles back to the very items it was read from.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol

from tml.actions import mav
from tml.language.mavlink_tables import MAV_FRAME

Arguments = dict[str, str]
"""An action's arguments, name -> value as the XML writes it."""


class ItemFields(Protocol):
    """The fields of a mission item a reader reads (:class:`tml.mavlink.mission.MissionItem`)."""

    @property
    def frame(self) -> int: ...
    @property
    def command(self) -> int: ...
    @property
    def param1(self) -> float: ...
    @property
    def param2(self) -> float: ...
    @property
    def param3(self) -> float: ...
    @property
    def param4(self) -> float: ...
    @property
    def x(self) -> int: ...
    @property
    def y(self) -> int: ...
    @property
    def z(self) -> float: ...


Reader = Callable[[ItemFields], Arguments | None]
"""The arguments of the action an item reads back as, or None when it is another action's."""

Joiner = Callable[[str, Mapping[str, str], Mapping[str, str]], Arguments | None]
"""Given the action before (name, arguments) and this action's arguments: the arguments of
the one action both are, or None when they are two."""


@dataclass(frozen=True)
class Reading:
    """How the importer reads items back as one action."""

    commands: Mapping[int, Reader]
    join: Joiner | None = None


def value(number: float) -> str:
    """The shortest text that reads back as ``number`` (``15``, not ``15.0``; ``NaN``)."""
    number = float(number)
    if math.isnan(number):
        return "NaN"
    return str(int(number)) if number.is_integer() else repr(number)


def encoding(arguments: Arguments, item: ItemFields) -> Arguments:
    """``arguments`` with frame_encoding="float" for an item in a global frame without
    _INT (frame 3 ...)."""
    if item.frame in mav.FLOAT_FRAMES:
        arguments["frame_encoding"] = "float"
    return arguments


def frame(arguments: Arguments, item: ItemFields) -> Arguments:
    """``arguments`` with the frame of an item without a position when it is not the
    MISSION frame the compiler writes."""
    if item.frame != mav.FRAME_MISSION:
        arguments["frame"] = MAV_FRAME.get(item.frame) or str(item.frame)
    return arguments


def position(arguments: Arguments, item: ItemFields) -> Arguments:
    """``arguments`` with the latitude, longitude, altitude and its reference of a global
    item."""
    arguments["latitude"] = value(item.x / 1e7)
    arguments["longitude"] = value(item.y / 1e7)
    arguments["altitude"] = value(item.z)
    if item.frame in mav.AMSL_FRAMES:
        arguments["altitude_reference"] = "amsl"
    elif item.frame in mav.TERRAIN_FRAMES:
        arguments["altitude_reference"] = "terrain"
    return encoding(arguments, item)


def placed(item: ItemFields) -> bool:
    """Whether the item says where (a global frame, and a latitude or longitude not 0)."""
    return item.frame in mav.GLOBAL_FRAMES and (item.x != 0 or item.y != 0)
