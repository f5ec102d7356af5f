"""The one safe-state rule (tml.engine.safety) and the failure reasons (tml.engine.failures)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from tml.engine.safety import (
    SAFE_STATES,
    CommandRefusal,
    left_to_itself,
    operator_command_shown,
    operator_request,
    safe_state_request,
    safe_state_shown,
)
from tml.language import parameters
from tml.language.failures import ACTION_FAILURES
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


ON_THE_GROUND = VehicleState(1, 10.0, armed=False, landed=True)


@pytest.mark.parametrize(("heard", "expected"), [(4.0, "ReturnToLaunch"), (5.0, "ReturnToLaunch"),
                                                 (5.1, None)])
def test_a_vehicle_asked_to_fly_counts_as_flying_until_telemetry_after_the_request(
        heard: float, expected: str | None) -> None:
    # Ctrl-C 0.05 s after the take-off request: the picture still says disarmed on the
    # ground, from before the request.
    state = replace(ON_THE_GROUND, heard=heard, asked=5.0, flight_asked=5.0)
    found = safe_state_request(state, "rtl")
    assert (found[0].name if found else None) == expected


def test_a_ground_vehicle_asked_to_move_is_disarmed_until_telemetry_after_the_request() -> None:
    rover = replace(ON_THE_GROUND, vehicle_type="rover", flight_asked=5.0, asked=5.0)
    found = safe_state_request(replace(rover, heard=4.0), "rtl")
    assert found is not None and found[0].name == "Disarm"
    assert safe_state_request(replace(rover, heard=6.0), "rtl") is None


def test_a_safe_state_is_shown_only_by_telemetry_newer_than_the_latest_request() -> None:
    rtl = VehicleState(1, 10.0, armed=True, landed=False, mode="RTL", asked=8.0)
    assert not safe_state_shown(replace(rtl, heard=7.9), "rtl")
    assert safe_state_shown(replace(rtl, heard=8.2), "rtl")
    # A source that does not say how old its readings are is read as it always was.
    assert safe_state_shown(replace(rtl, heard=None), "rtl")


@pytest.mark.parametrize(("mode", "safe_state", "expected"), [
    ("LAND", "rtl", None), ("RTL", "rtl", None), ("LAND", "land", None),
    ("RTL", "land", "Land"), ("GUIDED", "rtl", "ReturnToLaunch"), ("LAND", "hold", "Hold")])
def test_a_vehicle_landing_or_returning_already_is_left_to_it(mode: str, safe_state: str,
                                                              expected: str | None) -> None:
    # An interrupt during the mission's own landing: sending the copter back up to return
    # would take 25 s to the ground instead of a few.
    landing = VehicleState(1, 10.0, armed=True, landed=False, mode=mode, asked=8.0, heard=9.0)
    found = safe_state_request(landing, safe_state)
    assert (found[0].name if found else None) == expected
    # Left to it is a decision too, and says why (the caller logs it as a safety line).
    said = left_to_itself(landing, safe_state)
    assert bool(said) is (expected is None)
    if said:
        assert said == (f"vehicle landing ({mode}): left to land by itself" if mode == "LAND"
                        else f"vehicle returning ({mode}): left to return by itself")
    # ... but only on a picture newer than the latest request, and over a live link.
    for doubt in (replace(landing, heard=7.0), replace(landing, link="lost")):
        found = safe_state_request(doubt, safe_state)
        assert found is not None and found[0].name == SAFE_STATES[safe_state](1).name
        assert left_to_itself(doubt, safe_state) == ""


def test_action_failures_are_the_values_of_the_action_failure_parameter() -> None:
    spec = parameters.lookup("ACTION_FAILURE")
    assert spec is not None
    assert set(spec.values) == {reason.value for reason in ACTION_FAILURES}


# --- an operator's command (tml command, POST /vehicles/{id}/command) ------------------------

FLYING = VehicleState(1, 10.0, armed=True, landed=False, mode="GUIDED", position=(0, 0, 12))


@pytest.mark.parametrize(("state", "command", "expected"), [
    (FLYING, "rtl", "ReturnToLaunch"), (FLYING, "land", "Land"), (FLYING, "hold", "Hold"),
    (VehicleState(1, 0.0, armed=True, landed=True), "disarm", "Disarm"),
    (VehicleState(1, 0.0, armed=False, landed=True), "disarm", None),
    (VehicleState(1, 0.0, armed=False, landed=True), "rtl", None),
    (VehicleState(1, 0.0, armed=True, landed=False, vehicle_type="rover"), "disarm", "Disarm"),
    (VehicleState(1, 0.0, armed=True, landed=False, vehicle_type="rover"), "rtl",
     "ReturnToLaunch"),
    (VehicleState(1, 0.0, armed=True, landed=False, vehicle_type="rover"), "hold", "Hold"),
    (VehicleState(1, 0.0, armed=True, landed=False, vehicle_type="fixed-wing"), "land", "Land"),
])
def test_an_operator_command_is_the_request_of_its_kind(state: VehicleState, command: str,
                                                       expected: str | None) -> None:
    found = operator_request(state, command)
    assert (found.name if found else None) == expected


@pytest.mark.parametrize(("state", "command", "reason"), [
    (FLYING, "disarm", "flying at 12.0 m: disarming would drop it"),
    (VehicleState(1, 0.0, armed=False, landed=False), "disarm", "flying"),  # in doubt
    (replace(ON_THE_GROUND, heard=4.0, asked=5.0, flight_asked=5.0), "disarm", "flying"),
    (VehicleState(1, 0.0, armed=True, landed=False, vehicle_type="rover"), "land",
     "a ground vehicle does not land"),
    (VehicleState(1, 0.0, armed=True, landed=True), "rtl", "on the ground, armed"),
    (replace(FLYING, link="lost"), "rtl", "link is lost"),
    (FLYING, "flip", "not a command"),
])
def test_an_unsafe_or_impossible_operator_command_is_refused_with_the_reason(
        state: VehicleState, command: str, reason: str) -> None:
    with pytest.raises(CommandRefusal, match=reason):
        operator_request(state, command)


@pytest.mark.parametrize(("state", "command", "shown"), [
    (replace(FLYING, mode="RTL", heard=6.0, asked=5.0), "rtl", True),
    (replace(FLYING, mode="RTL", heard=4.0, asked=5.0), "rtl", False),  # an older picture
    (replace(FLYING, mode="GUIDED", heard=6.0, asked=5.0), "rtl", False),
    (replace(FLYING, mode="LAND", heard=6.0, asked=5.0), "land", True),
    (replace(FLYING, mode="AUTO", vehicle_type="fixed-wing", heard=6.0, asked=5.0), "land",
     True),
    (replace(FLYING, mode="BRAKE", heard=6.0, asked=5.0), "hold", True),
    (replace(FLYING, mode="RTL", heard=6.0, asked=5.0), "hold", False),
    (replace(ON_THE_GROUND, heard=6.0, asked=5.0), "disarm", True),
    (replace(ON_THE_GROUND, armed=True, heard=6.0, asked=5.0), "disarm", False),
    (replace(FLYING, armed=False, heard=6.0, asked=5.0), "disarm", False),  # not landed
])
def test_an_operator_command_is_shown_by_telemetry_after_it(state: VehicleState, command: str,
                                                           shown: bool) -> None:
    assert operator_command_shown(state, command) is shown
