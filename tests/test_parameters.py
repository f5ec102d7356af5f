"""Built-in condition parameters (tml.language.parameters)."""

from __future__ import annotations

import pytest

from tml.language import parameters
from tml.language.model import Comparison
from tml.language.parameters import ParamType


@pytest.mark.parametrize(
    "written",
    ["BATTERY_CHARGE_PERCENTAGE", "PERCENTAGE_BATTERY_CHARGE", "percentageBatteryCharge",
     "battery charge percentage", "batteryCharge"],
)
def test_battery_spellings(written: str) -> None:
    assert parameters.lookup(written).name == "BATTERY_CHARGE_PERCENTAGE"


def test_types_and_units() -> None:
    assert parameters.lookup("ALTITUDE").unit == "m"
    assert parameters.lookup("ARMED").type is ParamType.BOOLEAN
    assert parameters.lookup("RECOGNIZED_ARUCO_MARKERS").type is ParamType.SET
    assert parameters.lookup("currentTask").name == "CURRENT_TASK"
    assert Comparison.INCLUDES in parameters.COMPARISONS[ParamType.SET]
    assert Comparison.LESS not in parameters.COMPARISONS[ParamType.STRING]


@pytest.mark.parametrize(
    ("written", "meant"),
    [("BATERY_CHARGE_PERCENTAGE", "BATTERY_CHARGE_PERCENTAGE"), ("ALTITUD", "ALTITUDE"),
     ("FLIGHT_MOD", "FLIGHT_MODE"), ("ACTION_FAILUER", "ACTION_FAILURE")],
)
def test_misspelt_names_get_a_suggestion(written: str, meant: str) -> None:
    assert parameters.lookup(written) is None
    assert parameters.suggest(written) == meant


@pytest.mark.parametrize("detection", ["Item A found", "observed color", "Bucket A found"])
def test_detection_parameters_are_not_taken_for_typos(detection: str) -> None:
    assert parameters.lookup(detection) is None
    assert parameters.suggest(detection) is None


def test_parse_boolean() -> None:
    assert parameters.parse_boolean("YES") is True
    assert parameters.parse_boolean("false") is False
    assert parameters.parse_boolean("maybe") is None
