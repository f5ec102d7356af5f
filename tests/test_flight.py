"""The one use case of flying a mission (tml.run.flight): clear, start, fly, safe end."""

from __future__ import annotations

import io
import json

import pytest
from fake_vehicle import FakeVehicle
from test_runner import GO, LAND, TAKE_OFF, Sim, mission

from tml.run.clearance import Cleared, Incapable, NotCleared, Refusal
from tml.run.flight import Flight, FlightOptions
from tml.run.journal import Journal
from tml.run.session import SessionOptions, SimulatorOptions
from tml.serve.service import ServiceOptions
from tml.vehicle import Land, ReturnToLaunch
from tml.verify.profile import load_profile
from tml.world import World

QUAD = load_profile("quadcopter")


def test_the_options_of_the_flight_are_the_runner_s_and_the_clearance_s() -> None:
    options = FlightOptions(safe_state="land", link_lost_limit=3.0, ready_timeout=7.0,
                            safe_state_timeout=9.0, vehicle_fence=False, force=True,
                            gcs_failsafe=False, require_gcs_failsafe=True)
    run = options.run_options(QUAD, World())
    assert (run.safe_state, run.link_lost_limit, run.ready_timeout, run.safe_state_timeout,
            run.vehicle_fence) == ("land", 3.0, 7.0, 9.0, False)
    assert run.engine.pre_check is not None and run.engine.limits.cruise is not None
    clearance = options.clearance()
    assert (clearance.force, clearance.gcs_failsafe, clearance.require_gcs_failsafe) == \
        (True, False, True)


def test_tml_run_and_tml_serve_fly_with_their_own_options() -> None:
    """tml run reads the GCS failsafe of vehicles it connects to, not of its own simulator;
    tml serve read it when it opened the vehicles, never again for a run."""
    connected = SessionOptions(connect=("udp:x",), safe_state="hold", keep_vehicle_fence=True,
                               force=True, require_gcs_failsafe=True).flight
    assert (connected.safe_state, connected.vehicle_fence, connected.force,
            connected.gcs_failsafe, connected.require_gcs_failsafe) == \
        ("hold", False, True, True, True)
    assert not SessionOptions(simulator=SimulatorOptions()).flight.gcs_failsafe
    served = ServiceOptions(link_lost_limit=4.0, ready_timeout=5.0, vehicle_fence=False)
    run = served.flight(safe_state="land", force=True)
    assert (run.safe_state, run.link_lost_limit, run.ready_timeout, run.vehicle_fence,
            run.force, run.gcs_failsafe) == ("land", 4.0, 5.0, False, True, False)


def test_a_mission_beyond_its_vehicles_is_not_cleared_unless_forced() -> None:
    rover = FakeVehicle(vehicle_type="rover")
    up = mission(TAKE_OFF + LAND)
    refused = Flight(up, [rover]).clear(QUAD)
    assert isinstance(refused, NotCleared) and refused.refusal is Refusal.MISSION
    assert any(isinstance(f, Incapable) for f in refused.findings)
    forced = Flight(up, [rover], FlightOptions(force=True)).clear(QUAD)
    assert isinstance(forced, Cleared) and forced.profile is QUAD


def test_a_cleared_mission_flies_to_its_end() -> None:
    sim = Sim(FakeVehicle())
    log = io.StringIO()
    flight = Flight(mission(TAKE_OFF + GO + LAND), sim.vehicles)
    cleared = flight.clear(QUAD)
    assert isinstance(cleared, Cleared)
    runner = flight.start(cleared.profile, World(), Journal(log), clock=sim.clock,
                          wait=sim.wait, about={"sha256": "0" * 64})
    assert flight.runner is runner
    outcome = flight.fly()
    assert outcome.ending.status == "completed"
    first = json.loads(log.getvalue().splitlines()[0])
    assert (first["kind"], first["sha256"]) == ("run", "0" * 64)


class Broken(FakeVehicle):
    """A vehicle whose adapter breaks once it flies above 3 m."""

    def poll(self):  # type: ignore[no-untyped-def]
        if self.position[2] > 3.0 and not self.submitted[-1].name == "ReturnToLaunch":
            raise OSError("the adapter broke")
        return super().poll()


@pytest.mark.parametrize("safe_state, sent", [("rtl", ReturnToLaunch), ("land", Land)])
def test_a_runner_that_breaks_leaves_every_vehicle_in_its_safe_state(safe_state: str,
                                                                    sent: type) -> None:
    sim = Sim(Broken(vehicle_id=1), FakeVehicle(vehicle_id=2))
    log = io.StringIO()
    said: list[str] = []
    flight = Flight(mission(TAKE_OFF + GO + LAND), sim.vehicles,
                    FlightOptions(safe_state=safe_state), on_safety=said.append)
    flight.start(QUAD, World(), Journal(log), clock=sim.clock, wait=sim.wait)
    with pytest.raises(OSError, match="the adapter broke"):
        flight.fly(lambda error: f"broken: {error}")
    assert [type(v.submitted[-1]) for v in sim.vehicles] == [sent, sent]
    assert [m for m in said if m.endswith("(broken: the adapter broke)")] == [
        f"vehicle {v}: {sent.__name__} (broken: the adapter broke)" for v in (1, 2)]
    error = [r for r in map(json.loads, log.getvalue().splitlines()) if r["kind"] == "error"]
    assert [r["message"] for r in error] == ["broken: the adapter broke"]
    assert "OSError: the adapter broke" in error[0]["traceback"]


def test_a_flight_not_started_has_no_runner() -> None:
    with pytest.raises(RuntimeError, match="not started"):
        Flight(mission(TAKE_OFF), [FakeVehicle()]).fly()
