"""``tml serve`` flying the embedded simulator: two runs at once on two vehicles, and each
of the operator's controls -- pause, resume, abort, jump -- on a real MAVLink vehicle."""

from __future__ import annotations

import contextlib
import json
import math
import re
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from pymavlink import mavutil
from serving import SHORT, simulated
from test_command_command import LIMIT, Observer, fly_away

from tml.mavlink.autopilot import Autopilot
from tml.mavlink.link import Link
from tml.serve.answers import RunView, VehicleView
from tml.serve.api import create_app
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


def ended(service: Service, run_id: str) -> RunView:
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


def vehicle_when(service: Service, run_id: str, vehicle: int, done) -> VehicleView:
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
    mission = service.upload("short.xml", SHORT).id
    first = service.start_run(mission, [1])
    second = service.start_run(mission, [2])
    until(service, first.id, lambda r: r["kind"] == "task" and r["state"] == "running")
    assert service.live(second.id) is not None, "both fly at once"
    runs = [ended(service, r.id) for r in (first, second)]
    assert [(r.status, r.exit_code) for r in runs] == [("completed", 0)] * 2
    assert [r.tasks for r in runs] == [{"1": dict.fromkeys(("Up", "Out", "Down"), "done")},
                                         {"2": dict.fromkeys(("Up", "Out", "Down"), "done")}]
    starts = [next(x["t"] for x in lines(service, r.id) if x["kind"] == "mission")
              for r in runs]
    ends = [lines(service, r.id)[-1]["t"] for r in runs]
    assert starts[1] < ends[0] and starts[0] < ends[1], "their flights overlap in time"


def test_pause_holds_and_resume_flies_on(service: Service) -> None:
    mission = service.upload("long.xml", LONG).id
    run = service.start_run(mission, [1]).id
    until(service, run, lambda r: r["kind"] == "telemetry" and r["position"][0] > 20)
    assert service.control(run, "pause").status == "paused"
    # Told to hold where it was, the vehicle brakes, comes back to that point and stays.
    told = service.vehicle(1).time
    held = vehicle_when(service, run, 1, lambda v: v.time > told + 20)
    now = vehicle_when(service, run, 1, lambda v: v.time > held.time + 10)
    assert now.position == pytest.approx(held.position, abs=0.5)
    assert service.control(run, "resume").status == "running"
    result = ended(service, run)
    assert result.status == "completed"
    records = lines(service, run)
    assert [r["control"] for r in records if r["kind"] == "control"] == ["pause", "resume"]
    out = max(r["position"][0] for r in records if r["kind"] == "telemetry" and r["position"])
    assert out == pytest.approx(120, abs=3)


def test_abort_sends_the_vehicle_home(service: Service) -> None:
    mission = service.upload("long.xml", LONG).id
    run = service.start_run(mission, [2]).id
    until(service, run, lambda r: r["kind"] == "telemetry" and r["position"][0] > 20)
    service.abort(run)
    result = ended(service, run)
    assert (result.status, result.exit_code) == ("aborted", 3)
    safety = [r for r in lines(service, run) if r["kind"] == "safety"]
    assert safety and safety[0]["request"] == "ReturnToLaunch"
    assert service.vehicle(2).mode == "RTL"


def test_jump_goes_on_from_the_task(service: Service) -> None:
    mission = service.upload("long.xml", LONG).id
    run = service.start_run(mission, [1]).id
    until(service, run, lambda r: r["kind"] == "telemetry" and r["position"][0] > 20)
    assert service.control(run, "jump", "Down").tasks["1"]["Out"] == "aborted"
    result = ended(service, run)
    assert result.status == "completed" and result.tasks["1"]["Down"] == "done"
    out = max(r["position"][0] for r in lines(service, run)
              if r["kind"] == "telemetry" and r["position"])
    assert out < 100, "it landed on its way out, not at the end of the leg"


def test_a_run_verified_with_the_profile_read_from_its_vehicle(service: Service) -> None:
    """As ``tml run --profile vehicle``: the quadcopter profile filled in from the
    vehicle's own parameters (a speed limit above what a leg needs flies)."""
    mission = service.upload("short.xml", SHORT).id
    run = service.start_run(mission, [1], profile="vehicle")
    assert service.run(run.id).options["profile"] == "vehicle"
    assert (ended(service, run.id).status) == "completed"



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
            run = found.start_run(found.upload("fenced.xml", FENCED).id, [1])
            assert ended(found, run.id).status == "completed"
            (told,) = [line for line in lines(found, run.id) if line["kind"] == "safeguard"]
        finally:
            found.stop()
            storage.close()
    assert told["ok"] is True and told["message"].endswith("read back matched")
    assert "1 rally point" in told["message"]
    assert ("the vehicle's fence kept" in told["message"]) is keep
    assert ("inclusion polygon of 4 corners" in told["message"]) is not keep


# --- operator commands through the HTTP API, judged by an independent observer -------------

BRAKE_MODE, GUIDED_MODE = 17, 4
M = mavutil.mavlink


@contextlib.contextmanager
def flown_by_another_station(service: Service, vehicle: int) -> Iterator[
        tuple[TestClient, Autopilot, Observer]]:
    """The service's API, another ground station (a tml Link) that flies ``vehicle`` up and
    away at 8 m/s while no run holds it, and a plain pymavlink observer on its port."""
    address = service.hangar.vehicles[vehicle].link.address  # type: ignore[attr-defined]
    with TestClient(create_app(service), base_url="http://127.0.0.1") as client, \
            Link(address) as link:
        pilot = Autopilot.connect(link, vehicle, timeout=10)
        pilot.request_rates()
        link.wait_telemetry(vehicle, lambda t: t.position_ready, timeout=LIMIT)
        pilot.set_mode("GUIDED")
        pilot.arm()
        fly_away(pilot)
        observer = Observer(int(address.rsplit(":", 1)[1]))
        try:
            yield client, pilot, observer
        finally:
            observer.close()


def observed(observer: Observer, vehicle: int, check: Callable[[Any], bool],
             vehicle_seconds: float = 60.0) -> bool:
    """Whether the vehicle's GLOBAL_POSITION_INT, as the observer reads it from now on
    (asked for first; what it had not read yet is older, and left), satisfies ``check``
    within ``vehicle_seconds`` of the vehicle's own clock (its ``time_boot_ms``): a busy
    machine slows the simulator down, never changes what it flies in that time. LIMIT x 10
    wall seconds only guard against a hang."""
    observer.conn.mav.request_data_stream_send(vehicle, 1, mavutil.mavlink.MAV_DATA_STREAM_ALL,
                                               10, 1)
    while observer.conn.recv_match(blocking=False) is not None:
        pass
    first: float | None = None
    end = time.monotonic() + LIMIT * 10
    while time.monotonic() < end:
        msg = observer.conn.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=1)
        if msg is None or msg.get_srcSystem() != vehicle:
            continue
        if check(msg):
            return True
        first = msg.time_boot_ms if first is None else first
        if msg.time_boot_ms - first > vehicle_seconds * 1000:
            return False
    return False


def stopped(msg: Any) -> bool:
    return bool(math.hypot(msg.vx, msg.vy) / 100 < 0.5)


def confirmed(client: TestClient, vehicle: int, command: str, run: str | None) -> dict:
    """The answer to ``command``, asserted confirmed (200, done), naming ``run``."""
    answer = client.post(f"/vehicles/{vehicle}/command", json={"command": command})
    assert answer.status_code == 200, answer.text
    body = dict(answer.json())
    assert (body["outcome"], body["confirmed"], body["run"]) == ("done", True, run)
    return body


def test_hold_of_a_vehicle_no_run_holds_is_brake_and_confirmed_by_its_stop(
        service: Service) -> None:
    with flown_by_another_station(service, 1) as (client, _pilot, observer):
        body = confirmed(client, 1, "hold", None)
        assert body["message"].startswith("vehicle 1: hold done (SetMode BRAKE): mode BRAKE")
        assert float(re.search(r"ground speed (\d+\.\d)", body["seen"])[1]) < 0.5  # type: ignore[index]
        assert "fastest" in body["seen"] and client.get("/vehicles/1").json()["command"][
            "outcome"] == "done"
        # The observer, on its own: the vehicle is in BRAKE and stopped.
        assert observer.until(lambda o: o.modes[-1] == BRAKE_MODE)
        assert observed(observer, 1, stopped)


def test_hold_during_a_run_pauses_it_and_is_confirmed_by_the_stop(service: Service) -> None:
    mission = service.upload("long.xml", LONG).id
    run = service.start_run(mission, [1]).id
    until(service, run, lambda r: r["kind"] == "telemetry" and r["position"][0] > 20)
    address = service.hangar.vehicles[1].link.address  # type: ignore[attr-defined]
    observer = Observer(int(address.rsplit(":", 1)[1]))
    try:
        with TestClient(create_app(service), base_url="http://127.0.0.1") as client:
            body = confirmed(client, 1, "hold", run)
            assert body["message"].startswith(f"vehicle 1: hold done (run {run} paused): "
                                              "mode GUIDED")
            assert client.get(f"/runs/{run}").json()["status"] == "paused"
            assert observed(observer, 1, stopped)
            records = lines(service, run)
            assert [r["control"] for r in records if r["kind"] == "control"] == ["pause"]
            assert client.post(f"/runs/{run}/abort").status_code == 200
    finally:
        observer.close()
    assert ended(service, run).status == "aborted"


def test_rtl_during_a_run_ends_it_and_is_confirmed_on_its_way_home(service: Service) -> None:
    # Out 400 m, and everything ready before the run starts: the command must come while the
    # vehicle flies out however slowly this machine runs the test (the simulator keeps its
    # own pace), not after the mission's landing at the far end.
    mission = service.upload("far.xml", SHORT.replace(b"(40,0,10)", b"(400,0,10)")).id
    address = service.hangar.vehicles[2].link.address  # type: ignore[attr-defined]
    observer = Observer(int(address.rsplit(":", 1)[1]))
    try:
        with TestClient(create_app(service), base_url="http://127.0.0.1") as client:
            run = service.start_run(mission, [2]).id
            vehicle_when(service, run, 2, lambda v: v.position and v.position[0] > 30)
            body = confirmed(client, 2, "rtl", run)
        # The observer, on its own: flying south, home (it flew out north).
        assert observed(observer, 2, lambda msg: msg.vx < -100)
    finally:
        observer.close()
    assert body["message"].startswith(f"vehicle 2: rtl done (run {run} ends into rtl): "
                                      "mode RTL")
    assert re.search(r"\d+ m from home", body["seen"]), body["seen"]
    assert (ended(service, run).status) == "taken"


def test_a_hold_another_station_undoes_is_not_confirmed(service: Service) -> None:
    """Another ground station switches the vehicle back to GUIDED the moment it shows
    BRAKE and sends it on: the mode was shown, the stop never was: 202, not confirmed."""
    service.options.command_timeout = 4.0  # (40 s of the vehicle's: it never gets there)
    with flown_by_another_station(service, 1) as (client, pilot, observer):
        start = pilot.telemetry.position
        assert start is not None
        done = threading.Event()

        def fight() -> None:
            conn = observer.conn
            while not done.is_set():
                msg = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2)
                if msg is None or msg.get_srcSystem() != 1 or msg.custom_mode != BRAKE_MODE:
                    continue
                conn.mav.command_long_send(1, 1, M.MAV_CMD_DO_SET_MODE, 0,
                                           M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED_MODE,
                                           0, 0, 0, 0, 0)
                conn.mav.set_position_target_global_int_send(
                    0, 1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000,
                    int((start.latitude + 5000 / 111_320) * 1e7), int(start.longitude * 1e7),
                    start.relative_altitude, 0, 0, 0, 0, 0, 0, 0, 0)

        fighter = threading.Thread(target=fight)
        fighter.start()
        try:
            answer = client.post("/vehicles/1/command", json={"command": "hold"})
        finally:
            done.set()
            fighter.join()
        assert answer.status_code == 202, answer.text
        body = answer.json()
        assert (body["outcome"], body["confirmed"]) == ("not confirmed", False)
        assert body["message"].startswith("vehicle 1: hold not confirmed within 4 s "
                                          "(SetMode BRAKE; wanted ground speed below 0.5 m/s "
                                          "for 3 s in a holding mode; seen mode GUIDED")
        assert client.get("/vehicles/1").json()["command"]["outcome"] == "not confirmed"
