"""``tml serve`` flying the embedded simulator: two runs at once on two vehicles, and each
of the operator's controls -- pause, resume, abort, jump -- on a real MAVLink vehicle."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from serving import SHORT, simulated

from tml.serve.service import Service, ServiceOptions
from tml.serve.storage import Storage, database_url

LONG = SHORT.replace(b"(40,0,10)", b"(120,0,10)")


@pytest.fixture
def service(tmp_path: Path) -> Iterator[Service]:
    with simulated(vehicles=2, speedup=10) as hangar:
        storage = Storage(database_url(None, tmp_path))
        found = Service(storage, hangar, ServiceOptions(stop_timeout=60))
        try:
            yield found
        finally:
            found.stop()
            storage.close()


def ended(service: Service, run_id: str) -> dict:
    live = service.live(run_id)
    assert live is None or live.join(240), "the run did not end"
    return service.run(run_id)


def lines(service: Service, run_id: str) -> list[dict]:
    return [json.loads(line) for line in service.log(run_id)]


def until(service: Service, run_id: str, done) -> None:
    """Wait for the run's log to show ``done(record)``."""
    live = service.live(run_id)
    assert live is not None
    seen = 0
    while not live.ended:
        records = list(live.log.lines)
        if any(done(json.loads(line)) for _, line in records[seen:]):
            return
        seen = len(records)
        live.wake.wait(0.05)
    pytest.fail("the run ended first")


def vehicle_when(service: Service, run_id: str, vehicle: int, done) -> dict:
    """The vehicle's telemetry once ``done(telemetry)`` holds (while the run flies)."""
    live = service.live(run_id)
    assert live is not None
    while not live.ended:
        found = service.vehicle(vehicle)
        if done(found):
            return found
        live.wake.wait(0.05)
    pytest.fail("the run ended first")


def test_two_runs_fly_at_once_on_two_vehicles(service: Service) -> None:
    mission = service.upload("short.xml", SHORT)["id"]
    first = service.start_run(mission, [1])
    second = service.start_run(mission, [2])
    until(service, first["id"], lambda r: r["kind"] == "task" and r["state"] == "running")
    assert service.live(second["id"]) is not None, "both fly at once"
    runs = [ended(service, r["id"]) for r in (first, second)]
    assert [(r["status"], r["exit_code"]) for r in runs] == [("completed", 0)] * 2
    assert [r["tasks"] for r in runs] == [{"1": dict.fromkeys(("Up", "Out", "Down"), "done")},
                                         {"2": dict.fromkeys(("Up", "Out", "Down"), "done")}]
    starts = [next(x["t"] for x in lines(service, r["id"]) if x["kind"] == "mission")
              for r in runs]
    ends = [lines(service, r["id"])[-1]["t"] for r in runs]
    assert starts[1] < ends[0] and starts[0] < ends[1], "their flights overlap in time"


def test_pause_holds_and_resume_flies_on(service: Service) -> None:
    mission = service.upload("long.xml", LONG)["id"]
    run = service.start_run(mission, [1])["id"]
    until(service, run, lambda r: r["kind"] == "telemetry" and r["position"][0] > 20)
    assert service.control(run, "pause")["status"] == "paused"
    # Told to hold where it was, the vehicle brakes, comes back to that point and stays.
    told = service.vehicle(1)["time"]
    held = vehicle_when(service, run, 1, lambda v: v["time"] > told + 20)
    now = vehicle_when(service, run, 1, lambda v: v["time"] > held["time"] + 10)
    assert now["position"] == pytest.approx(held["position"], abs=0.5)
    assert service.control(run, "resume")["status"] == "running"
    result = ended(service, run)
    assert result["status"] == "completed"
    records = lines(service, run)
    assert [r["control"] for r in records if r["kind"] == "control"] == ["pause", "resume"]
    out = max(r["position"][0] for r in records if r["kind"] == "telemetry" and r["position"])
    assert out == pytest.approx(120, abs=3)


def test_abort_sends_the_vehicle_home(service: Service) -> None:
    mission = service.upload("long.xml", LONG)["id"]
    run = service.start_run(mission, [2])["id"]
    until(service, run, lambda r: r["kind"] == "telemetry" and r["position"][0] > 20)
    service.abort(run)
    result = ended(service, run)
    assert (result["status"], result["exit_code"]) == ("aborted", 3)
    safety = [r for r in lines(service, run) if r["kind"] == "safety"]
    assert safety and safety[0]["request"] == "ReturnToLaunch"
    assert service.vehicle(2)["mode"] == "RTL"


def test_jump_goes_on_from_the_task(service: Service) -> None:
    mission = service.upload("long.xml", LONG)["id"]
    run = service.start_run(mission, [1])["id"]
    until(service, run, lambda r: r["kind"] == "telemetry" and r["position"][0] > 20)
    assert service.control(run, "jump", "Down")["tasks"]["1"]["Out"] == "aborted"
    result = ended(service, run)
    assert result["status"] == "completed" and result["tasks"]["1"]["Down"] == "done"
    out = max(r["position"][0] for r in lines(service, run)
              if r["kind"] == "telemetry" and r["position"])
    assert out < 100, "it landed on its way out, not at the end of the leg"


def test_a_run_verified_with_the_profile_read_from_its_vehicle(service: Service) -> None:
    """As ``tml run --profile vehicle``: the quadcopter profile filled in from the
    vehicle's own parameters (a speed limit above what a leg needs flies)."""
    mission = service.upload("short.xml", SHORT)["id"]
    run = service.start_run(mission, [1], profile="vehicle")
    assert service.run(run["id"])["options"]["profile"] == "vehicle"
    assert (ended(service, run["id"])["status"]) == "completed"



FENCED = SHORT.replace(b'<mission name="Short hop">', (
    b'<mission name="Short hop"><environment><geofence max_altitude="30">'
    b'<point north="-100" east="-100"/><point north="100" east="-100"/>'
    b'<point north="100" east="100"/><point north="-100" east="100"/></geofence><rally>'
    b'<point north="-10" east="0" altitude="10"/></rally></environment>'))


@pytest.mark.parametrize("keep", [False, True], ids=["uploaded", "kept"])
def test_each_run_puts_its_fence_and_rally_points_on_the_vehicle_unless_told_to_keep(
        tmp_path: Path, keep: bool) -> None:
    with simulated(vehicles=1, speedup=10) as hangar:
        storage = Storage(database_url(None, tmp_path))
        found = Service(storage, hangar, ServiceOptions(stop_timeout=60,
                                                        vehicle_fence=not keep))
        try:
            run = found.start_run(found.upload("fenced.xml", FENCED)["id"], [1])
            assert ended(found, run["id"])["status"] == "completed"
            (told,) = [line for line in lines(found, run["id"]) if line["kind"] == "safeguard"]
        finally:
            found.stop()
            storage.close()
    assert told["ok"] is True and told["message"].endswith("read back matched")
    assert "1 rally point" in told["message"]
    assert ("the vehicle's fence kept" in told["message"]) is keep
    assert ("inclusion polygon of 4 corners" in told["message"]) is not keep
