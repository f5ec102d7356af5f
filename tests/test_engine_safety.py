"""The one safe-state rule (tml.engine.safety) and the failure reasons (tml.engine.failures)."""

from __future__ import annotations

import pytest

from tml.engine.failures import ACTION_FAILURES, FailureReason
from tml.engine.safety import safe_state_request
from tml.language import parameters
from tml.vehicle import VehicleState


@pytest.mark.parametrize(("state", "safe_state", "expected"), [
    (VehicleState(1, 0.0, armed=True, landed=False), "rtl", "ReturnToLaunch"),
    (VehicleState(1, 0.0, armed=True, landed=False), "land", "Land"),
    (VehicleState(1, 0.0, armed=True, landed=False), "hold", "Hold"),
    (VehicleState(1, 0.0, armed=False, landed=False), "rtl", "ReturnToLaunch"),  # in doubt
    (VehicleState(1, 0.0, armed=True, landed=True), "rtl", "Disarm"),
    (VehicleState(1, 0.0, armed=False, landed=True), "rtl", None),
    (VehicleState(1, 0.0, armed=True, landed=False, vehicle_type="rover"), "rtl", "Disarm"),
    (VehicleState(1, 0.0, armed=False, landed=False, vehicle_type="rover"), "rtl", None),
])
def test_the_safe_state_of_each_kind_of_vehicle(state: VehicleState, safe_state: str,
                                               expected: str | None) -> None:
    found = safe_state_request(state, safe_state)
    assert (found[0].name if found else None) == expected


def test_action_failures_are_the_values_of_the_action_failure_parameter() -> None:
    spec = parameters.lookup("ACTION_FAILURE")
    assert spec is not None
    assert set(spec.values) == {reason.value for reason in ACTION_FAILURES}


def test_a_vehicle_s_reason_is_read_as_a_failure_reason() -> None:
    assert FailureReason.of("timeout") is FailureReason.TIMEOUT
    assert FailureReason.of("") is FailureReason.REJECTED  # refused without a word
    assert FailureReason.of("MAV_RESULT_DENIED") is FailureReason.GENERAL
