"""The parameters a condition may read, with their types and units.

Built-in parameters come from the vehicle's telemetry and the interpreter's own state. Any
other name is a *detection* parameter, fed by a skill or a companion computer (the paper's
"observed color" or "Item A found"); a mission declares those with ``<parameter>``. A name
of the form ``"<kind> <id> found"`` (``"Item A found"``) reads a built-in recognition set
(:func:`found_in`), and is fed by the skill that fills that set. A name close to a built-in
one but not equal to it is almost certainly a typo, and is reported with a did-you-mean
hint. A built-in number parameter names the quantity it
measures, whose range (:mod:`tml.language.quantities`) bounds the numbers a condition may
compare it with.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum

from tml.language.failures import ACTION_FAILURES
from tml.language.model import Comparison, normalize_name
from tml.language.quantities import Quantity


class ParamType(StrEnum):
    """What a parameter's values are, which decides the comparisons that fit."""

    NUMBER = "number"
    STRING = "string"
    BOOLEAN = "boolean"
    SET = "set"  # a set of numbers or names, tested with "includes"


COMPARISONS: dict[ParamType, frozenset[Comparison]] = {
    ParamType.NUMBER: frozenset({
        Comparison.EQUAL, Comparison.NOT_EQUAL, Comparison.LESS, Comparison.LESS_OR_EQUAL,
        Comparison.GREATER, Comparison.GREATER_OR_EQUAL, Comparison.KNOWN}),
    ParamType.STRING: frozenset({Comparison.EQUAL, Comparison.NOT_EQUAL, Comparison.KNOWN}),
    ParamType.BOOLEAN: frozenset({Comparison.EQUAL, Comparison.NOT_EQUAL, Comparison.KNOWN}),
    ParamType.SET: frozenset({Comparison.INCLUDES, Comparison.EQUAL, Comparison.NOT_EQUAL,
                              Comparison.KNOWN}),
}


@dataclass(frozen=True)
class ParameterSpec:
    """A built-in parameter."""

    name: str
    type: ParamType
    description: str
    unit: str = ""
    aliases: tuple[str, ...] = ()
    values: tuple[str, ...] = ()  # the closed set of values of a string parameter, if any
    quantity: Quantity | None = None  # what a number parameter measures: its values' range


BUILT_IN: tuple[ParameterSpec, ...] = (
    ParameterSpec("BATTERY_CHARGE_PERCENTAGE", ParamType.NUMBER,
                  "remaining battery charge (100 is full)", "%",
                  ("PERCENTAGE_BATTERY_CHARGE", "batteryCharge", "BATTERY", "battery_remaining"),
                  quantity=Quantity.PERCENTAGE),
    ParameterSpec("ALTITUDE", ParamType.NUMBER, "altitude above home", "m",
                  ("relative_altitude", "height"), quantity=Quantity.ALTITUDE),
    ParameterSpec("GROUND_SPEED", ParamType.NUMBER, "horizontal speed over ground", "m/s",
                  ("groundspeed", "speed"), quantity=Quantity.SPEED),
    ParameterSpec("DISTANCE_TO_HOME", ParamType.NUMBER, "horizontal distance to home", "m",
                  ("home_distance",), quantity=Quantity.DISTANCE),
    ParameterSpec("HEADING", ParamType.NUMBER, "heading, clockwise from north", "deg",
                  ("yaw",), quantity=Quantity.ANGLE),
    ParameterSpec("FLIGHT_MODE", ParamType.STRING,
                  "autopilot flight mode name (GUIDED, AUTO, RTL, LAND, ...)", "", ("mode",)),
    ParameterSpec("ARMED", ParamType.BOOLEAN, "motors armed"),
    ParameterSpec("LANDED", ParamType.BOOLEAN, "on the ground", "", ("on_ground",)),
    ParameterSpec("LINK_STATE", ParamType.STRING,
                  "state of the link to the vehicle", "", ("link",), ("ok", "degraded", "lost")),
    ParameterSpec("GPS_FIX", ParamType.NUMBER,
                  "GPS fix type (0-1 none, 2 2D, 3 3D, 4+ DGPS/RTK)", "",
                  quantity=Quantity.FIX_TYPE),
    ParameterSpec("MISSION_ELAPSED_TIME", ParamType.NUMBER, "time since the mission started",
                  "s", ("mission_time", "elapsed_time"), quantity=Quantity.DURATION),
    ParameterSpec("TASK_ELAPSED_TIME", ParamType.NUMBER,
                  "time since the current task started", "s", ("task_time",),
                  quantity=Quantity.DURATION),
    ParameterSpec("ACTION_FAILURE", ParamType.STRING,
                  "why the last action failed; absent while no action has failed", "", (),
                  tuple(reason.value for reason in ACTION_FAILURES)),
    ParameterSpec("CURRENT_TASK", ParamType.STRING,
                  "path of the running task, names joined by '/'", "", ("currentTask",)),
    ParameterSpec("CURRENT_ACTION", ParamType.STRING, "name of the running action"),
    ParameterSpec("RECOGNIZED_ARUCO_MARKERS", ParamType.SET,
                  "ids of the ArUco markers recognised (skill RECOGNIZE_ARUCO_MARKERS)"),
    ParameterSpec("RECOGNIZED_VISUAL_MARKERS", ParamType.SET,
                  "ids of the visual markers recognised (skill RECOGNIZE_VISUAL_MARKERS)",
                  "", ("visualMarker", "visual_markers")),
    ParameterSpec("RECOGNIZED_ITEMS", ParamType.SET,
                  "names of the items recognised (skill RECOGNIZE_ITEMS)"),
    ParameterSpec("RECOGNIZED_BUCKETS", ParamType.SET,
                  "names of the buckets recognised (skill RECOGNIZE_BUCKETS)"),
    ParameterSpec("RECOGNIZED_FRAMES", ParamType.SET,
                  "colours of the frames recognised (skill RECOGNIZE_FRAMES)"),
)

_BY_KEY = {normalize_name(n): p for p in BUILT_IN for n in (p.name, *p.aliases)}


def lookup(name: str) -> ParameterSpec | None:
    """The built-in parameter a written name denotes (case and separators ignored), or None."""
    return _BY_KEY.get(normalize_name(name))


_FOUND = re.compile(r"^\s*(item|bucket|aruco marker|aruco|visual marker|marker|frame)s?\s+"
                    r"(.+?)\s+(?:found|seen|recognized|recognised)\s*$", re.I)
_FOUND_SETS = {"item": "RECOGNIZED_ITEMS", "bucket": "RECOGNIZED_BUCKETS",
               "aruco marker": "RECOGNIZED_ARUCO_MARKERS", "aruco": "RECOGNIZED_ARUCO_MARKERS",
               "visual marker": "RECOGNIZED_VISUAL_MARKERS",
               "marker": "RECOGNIZED_VISUAL_MARKERS", "frame": "RECOGNIZED_FRAMES"}


def found_in(name: str) -> tuple[str, str] | None:
    """For a name of the form ``"<kind> <id> found"`` (the IMAV 2016 mission's ``"Item A
    found"``; also ``seen``, ``recognized``): the built-in set it reads and the id it looks
    for there (``("RECOGNIZED_ITEMS", "A")``); None for any other name."""
    found = _FOUND.match(name)
    if found is None:
        return None
    return _FOUND_SETS[found.group(1).lower()], found.group(2).strip()


def closest(name: str, others: Iterable[str]) -> str | None:
    """The one of ``others`` (or of the built-in names and aliases, reported by the
    built-in name) that ``name`` most likely meant, ignoring case and separators; None if
    nothing is close. Looser than :func:`suggest`: for a did-you-mean on a name already
    known to be wrong."""
    import difflib  # here: a valid mission never needs it, so start-up does without

    keys = {normalize_name(other): other for other in others}
    keys.update({key: spec.name for key, spec in _BY_KEY.items() if key not in keys})
    close = difflib.get_close_matches(normalize_name(name), list(keys), n=1, cutoff=0.6)
    return keys[close[0]] if close else None


def type_for(comparison: Comparison | None, value: str | None) -> ParamType:
    """The type a ``<parameter>`` declaration needs so that a condition with this
    comparison and value fits it (for a hint that works as written)."""
    if comparison is Comparison.INCLUDES:
        return ParamType.SET
    if comparison in ORDERINGS or (value is not None and parse_number(value) is not None
                                   and comparison is not Comparison.KNOWN):
        return ParamType.NUMBER
    if comparison is not Comparison.KNOWN and value is not None \
            and parse_boolean(value) is not None:
        return ParamType.BOOLEAN
    return ParamType.STRING


def suggest(name: str) -> str | None:
    """The built-in name a misspelt ``name`` most likely meant, or None if nothing is close."""
    import difflib  # here: a valid mission never needs it, so start-up does without

    key = normalize_name(name)
    close = difflib.get_close_matches(key, list(_BY_KEY), n=1, cutoff=0.8)
    return _BY_KEY[close[0]].name if close else None


_BOOLEAN_WORDS = {"yes": True, "true": True, "on": True, "1": True,
                  "no": False, "false": False, "off": False, "0": False}
NUMBER_PATTERN = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_NUMBER = re.compile(NUMBER_PATTERN)


def parse_boolean(text: str) -> bool | None:
    """yes/no, true/false, on/off, 1/0 (any case) as a bool; None if it is none of those."""
    return _BOOLEAN_WORDS.get(text.strip().lower())


def parse_number(text: str) -> float | None:
    """A decimal number as written in mission files (no nan, inf or ``1_0``); else None.

    A number too large for a float (``1e309``, read as inf) is refused as ``inf`` is."""
    text = text.strip()
    if not _NUMBER.fullmatch(text):
        return None
    value = float(text)
    return value if math.isfinite(value) else None


ORDERINGS = frozenset({Comparison.LESS, Comparison.LESS_OR_EQUAL, Comparison.GREATER,
                       Comparison.GREATER_OR_EQUAL})
"""The comparisons that order numbers (monotonic in the value read)."""


def compare_numbers(value: float, comparison: Comparison | None, target: float) -> bool:
    """``value COMPARISON target`` for a number read and a number written."""
    if comparison is None:
        return False
    return {
        Comparison.EQUAL: math.isclose(value, target, abs_tol=1e-9),
        Comparison.NOT_EQUAL: not math.isclose(value, target, abs_tol=1e-9),
        Comparison.LESS: value < target,
        Comparison.LESS_OR_EQUAL: value <= target,
        Comparison.GREATER: value > target,
        Comparison.GREATER_OR_EQUAL: value >= target,
    }.get(comparison, False)
