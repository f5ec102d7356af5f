"""Parameter reading and condition evaluation (tml.engine.conditions)."""

from __future__ import annotations

import pytest

from tml.engine.conditions import Memory, evaluate, read_parameter
from tml.errors import Location
from tml.language.model import Comparison, Condition, ConditionKind
from tml.vehicle import VehicleState

HERE = Location("m.xml", 1, 1)
STATE = VehicleState(1, 10.0, armed=True, landed=False, mode="GUIDED", position=(3.0, 4.0, 12.0),
                     heading=90.0, ground_speed=4.5, battery=42.0, gps_fix=3,
                     detections={"RECOGNIZED_ARUCO_MARKERS": frozenset({3.0, 7}),
                                 "RECOGNIZED_ITEMS": ["A"], "observed color": "green"})
MEMORY = Memory({"door": (1.0, 2.0, 3.0)}, 61.0, 5.0, ("Explore", "Scan"), "WAIT", "timeout",
                frozenset({("Explore",), ("Explore", "Scan")}))


def holds(kind: ConditionKind, subject: str, comparison: Comparison | None = None,
          value: str | None = None) -> bool:
    return evaluate(Condition(kind, subject, comparison, value, HERE), STATE, MEMORY)[0]


P = ConditionKind.PARAMETER


@pytest.mark.parametrize(
    ("name", "expected"),
    [("BATTERY_CHARGE_PERCENTAGE", 42.0), ("percentageBatteryCharge", 42.0), ("ALTITUDE", 12.0),
     ("DISTANCE_TO_HOME", 5.0), ("GROUND_SPEED", 4.5), ("HEADING", 90.0), ("FLIGHT_MODE", "GUIDED"),
     ("ARMED", True), ("LANDED", False), ("LINK_STATE", "ok"), ("GPS_FIX", 3),
     ("MISSION_ELAPSED_TIME", 61.0), ("TASK_ELAPSED_TIME", 5.0), ("CURRENT_TASK", "Explore/Scan"),
     ("CURRENT_ACTION", "WAIT"), ("ACTION_FAILURE", "timeout"),
     ("RECOGNIZED_ARUCO_MARKERS", frozenset({"3", "7"})), ("observed color", "green"),
     ("Item A found", True), ("Item B found", False), ("Bucket A found", False),
     ("unheard of", None)],
)
def test_read_parameter(name: str, expected: object) -> None:
    assert read_parameter(name, STATE, MEMORY) == expected


@pytest.mark.parametrize(
    ("subject", "comparison", "value", "expected"),
    [
        ("BATTERY_CHARGE_PERCENTAGE", Comparison.LESS, "50", True),
        ("BATTERY_CHARGE_PERCENTAGE", Comparison.LESS_OR_EQUAL, "42", True),
        ("BATTERY_CHARGE_PERCENTAGE", Comparison.GREATER, "42", False),
        ("BATTERY_CHARGE_PERCENTAGE", Comparison.GREATER_OR_EQUAL, "42", True),
        ("BATTERY_CHARGE_PERCENTAGE", Comparison.EQUAL, "42.0", True),
        ("BATTERY_CHARGE_PERCENTAGE", Comparison.NOT_EQUAL, "42", False),
        ("FLIGHT_MODE", Comparison.EQUAL, "guided", True),
        ("FLIGHT_MODE", Comparison.NOT_EQUAL, "AUTO", True),
        ("ARMED", Comparison.EQUAL, "yes", True),
        ("LANDED", Comparison.EQUAL, "true", False),
        ("RECOGNIZED_ARUCO_MARKERS", Comparison.INCLUDES, "3", True),
        ("RECOGNIZED_ARUCO_MARKERS", Comparison.INCLUDES, "4", False),
        ("RECOGNIZED_ARUCO_MARKERS", Comparison.EQUAL, "7", True),  # the paper's visualMarker
        ("RECOGNIZED_ARUCO_MARKERS", Comparison.NOT_EQUAL, "7", False),
        ("RECOGNIZED_ITEMS", Comparison.INCLUDES, "a", True),
        ("ACTION_FAILURE", Comparison.KNOWN, "yes", True),
        ("RECOGNIZED_BUCKETS", Comparison.KNOWN, "no", True),
        ("unheard of", Comparison.EQUAL, "x", False),
        ("unheard of", Comparison.KNOWN, None, False),
    ],
)
def test_comparisons(subject: str, comparison: Comparison, value: str | None,
                     expected: bool) -> None:
    assert holds(P, subject, comparison, value) is expected


def test_labels_and_current_task() -> None:
    assert holds(ConditionKind.LABEL, "door", Comparison.KNOWN, "yes")
    assert holds(ConditionKind.LABEL, "window", Comparison.KNOWN, "no")
    assert holds(ConditionKind.LABEL, "door", Comparison.KNOWN)  # no value means yes
    assert holds(ConditionKind.CURRENT_TASK, "Explore")  # an ancestor of the running task
    assert holds(ConditionKind.CURRENT_TASK, "Explore/Scan")
    assert not holds(ConditionKind.CURRENT_TASK, "Scan/Explore")
    assert not holds(ConditionKind.CURRENT_TASK, "Land")


def test_evaluate_returns_the_value_read() -> None:
    condition = Condition(P, "ALTITUDE", Comparison.GREATER, "20", HERE)
    assert evaluate(condition, STATE, MEMORY) == (False, 12.0)


def test_unknown_position_reads_as_unknown() -> None:
    state = VehicleState(1, 0.0)
    assert read_parameter("ALTITUDE", state, MEMORY) is None
    assert not evaluate(Condition(P, "ALTITUDE", Comparison.LESS, "5", HERE), state, MEMORY)[0]


@pytest.mark.parametrize("name", ["BATTERY_CHARGE_PERCENTAGE", "GPS_FIX", "HEADING",
                                  "GROUND_SPEED", "ALTITUDE", "DISTANCE_TO_HOME"])
def test_a_value_the_vehicle_has_not_reported_is_unknown_not_zero(name: str) -> None:
    booting = VehicleState(1, 0.0, heading_known=False)  # nothing but a heartbeat yet
    assert read_parameter(name, booting, MEMORY) is None
    unknown = Condition(P, name, Comparison.LESS_OR_EQUAL, "100", HERE)
    assert evaluate(unknown, booting, MEMORY) == (False, None)
    assert evaluate(Condition(P, name, Comparison.KNOWN, "no", HERE), booting, MEMORY)[0]
