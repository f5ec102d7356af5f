"""Reading parameters and evaluating conditions, from a vehicle state and the engine's memory.

Built-in parameters come from :class:`~tml.vehicle.VehicleState` and the interpreter
(elapsed times, current task, last action failure). Any other name is a detection
parameter: it is looked up in the state's detections by its exact name, and a name of the
form ``"<kind> <id> found"`` (the IMAV 2016 mission's ``"Item A found"``) is true while
``<id>`` is among the recognised objects of that kind (``RECOGNIZED_ITEMS`` ...).

Sets are compared with ``includes``; ``equal`` on a set is also true when the set
includes the value (the paper's ``visualMarker equal 3``), ``not equal to`` when it does
not. Comparisons on an unknown value are false, except ``known`` with value ``no``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from tml.language import parameters
from tml.language.model import Comparison, Condition, ConditionKind
from tml.language.parameters import ParamType
from tml.vehicle import VehicleState


@dataclass(frozen=True)
class Memory:
    """What the interpreter itself knows when a condition is evaluated."""

    labels: Mapping[str, tuple[float, float, float]]
    mission_time: float
    task_time: float
    current_task: tuple[str, ...]  # path of the running terminal task ("" when none)
    current_action: str
    action_failure: str | None
    running_paths: frozenset[tuple[str, ...]]  # the running task and all its ancestors


_STATE_READERS: dict[str, tuple[frozenset[str], Callable[[VehicleState], object]]] = {
    # parameter: (the VehicleState fields it reads, how)
    "BATTERY_CHARGE_PERCENTAGE": (frozenset({"battery"}), lambda s: s.battery),
    "ALTITUDE": (frozenset({"position"}), lambda s: s.position[2] if s.position else None),
    "GROUND_SPEED": (frozenset({"position", "ground_speed"}),
                     lambda s: s.ground_speed if s.position is not None else None),
    "DISTANCE_TO_HOME": (frozenset({"position"}),
                         lambda s: math.hypot(s.position[0], s.position[1])
                         if s.position else None),
    "HEADING": (frozenset({"heading", "heading_known"}),
                lambda s: s.heading if s.heading_known else None),
    "FLIGHT_MODE": (frozenset({"mode"}), lambda s: s.mode or None),
    "ARMED": (frozenset({"armed"}), lambda s: s.armed),
    "LANDED": (frozenset({"landed"}), lambda s: s.landed),
    "LINK_STATE": (frozenset({"link"}), lambda s: s.link),
    "GPS_FIX": (frozenset({"gps_fix"}), lambda s: s.gps_fix),
}
STATE_FIELDS: dict[str, frozenset[str]] = {name: fields
                                           for name, (fields, _) in _STATE_READERS.items()}
"""The fields of :class:`~tml.vehicle.VehicleState` each built-in parameter read from the
vehicle's state depends on (set parameters read ``detections``)."""


def read_parameter(name: str, state: VehicleState, memory: Memory) -> object:
    """The current value of a parameter (None when unknown)."""
    spec = parameters.lookup(name)
    if spec is not None:
        known = _STATE_READERS.get(spec.name)
        if known is not None:
            return known[1](state)
        if spec.type is ParamType.SET:
            return _as_set(state.detections.get(spec.name))
        return {
            "MISSION_ELAPSED_TIME": memory.mission_time,
            "TASK_ELAPSED_TIME": memory.task_time,
            "CURRENT_TASK": "/".join(memory.current_task) or None,
            "CURRENT_ACTION": memory.current_action or None,
            "ACTION_FAILURE": memory.action_failure,
        }.get(spec.name)
    if name in state.detections:
        return state.detections[name]
    found = parameters.found_in(name)
    if found is not None:
        seen = _as_set(state.detections.get(found[0]))
        return found[1].lower() in {str(v).lower() for v in seen}
    return None


def _as_set(value: object) -> frozenset[str]:
    if value is None:
        return frozenset()
    if isinstance(value, (set, frozenset, list, tuple)):
        return frozenset(_text(v) for v in value)
    return frozenset({_text(value)})


def _text(value: object) -> str:
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)


ENGINE_PARAMETERS = frozenset({"MISSION_ELAPSED_TIME", "TASK_ELAPSED_TIME", "CURRENT_TASK",
                               "CURRENT_ACTION", "ACTION_FAILURE"})
"""The parameters read from the interpreter itself rather than from the vehicle."""


def reads_vehicle(condition: Condition) -> bool:
    """Whether a condition reads the vehicle (its telemetry, its detections) rather than the
    interpreter's own state (elapsed times, the current task or action, the last failure,
    memorized labels): while an event's handler runs, only the former say anything about
    the world -- the latter describe the handler itself."""
    if condition.kind in (ConditionKind.CURRENT_TASK, ConditionKind.LABEL):
        return False
    spec = parameters.lookup(condition.subject)
    return spec is None or spec.name not in ENGINE_PARAMETERS


def evaluate(condition: Condition, state: VehicleState, memory: Memory) -> tuple[bool, object]:
    """Whether a condition holds, and the value it read (for the flight log)."""
    if condition.kind is ConditionKind.CURRENT_TASK:
        wanted = condition.subject
        holds = any(names_task(wanted, path) for path in memory.running_paths)
        return holds, "/".join(memory.current_task)
    if condition.kind is ConditionKind.LABEL:
        known = condition.subject in memory.labels
        return _compare_known(known, condition.value), known
    value = read_parameter(condition.subject, state, memory)
    comparison = condition.comparison
    if comparison is Comparison.KNOWN:
        known = value is not None and value != frozenset()
        return _compare_known(known, condition.value), value
    if value is None or condition.value is None:
        return False, value
    return _compare(value, comparison, condition.value), value


def evaluate_all(condition: Condition, states: Sequence[VehicleState],
                 memory: Memory) -> tuple[bool, object]:
    """Whether a condition holds for every one of ``states`` (a role's vehicles), and the
    value read from the first. With no vehicle (the role is not picked) nothing is known."""
    if not states:
        if condition.comparison is Comparison.KNOWN:
            return _compare_known(False, condition.value), None
        return False, None
    readings = [evaluate(condition, state, memory) for state in states]
    return all(holds for holds, _ in readings), readings[0][1]


def names_task(wanted: str, path: tuple[str, ...]) -> bool:
    """Whether ``wanted`` (a task's name, or its path written with ``/``) names ``path``."""
    if "/" in wanted:
        return tuple(part.strip() for part in wanted.split("/")) == path
    return bool(path) and path[-1] == wanted.strip()


def _compare_known(known: bool, value: str | None) -> bool:
    expected = parameters.parse_boolean(value) if value is not None else True
    return known == (True if expected is None else expected)


def _compare(value: object, comparison: Comparison | None, written: str) -> bool:
    if isinstance(value, frozenset):
        members = {m.lower() for m in value}
        inside = _text(_number_or_text(written)).lower() in members
        return inside if comparison is not Comparison.NOT_EQUAL else not inside
    if isinstance(value, bool):
        expected = parameters.parse_boolean(written)
        if expected is None:
            return False
        return (value == expected) == (comparison is not Comparison.NOT_EQUAL)
    if isinstance(value, (int, float)):
        try:
            target = float(written)
        except ValueError:
            return False
        return parameters.compare_numbers(value, comparison, target)
    equal = str(value).strip().lower() == written.strip().lower()
    return equal if comparison is not Comparison.NOT_EQUAL else not equal


def _number_or_text(written: str) -> object:
    try:
        return float(written)
    except ValueError:
        return written.strip()
