"""``tml serve --connect`` on two ArduCopter SITL vehicles, driven over HTTP as an operator's
tools drive it: two runs at once, one paused, resumed and jumped to its landing, the other
aborted; then a run whose service is killed in flight, marked interrupted by the restarted
service and continued from its stored log without a second take-off."""

from __future__ import annotations

import json
import re
import shlex
import signal
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
from serving import SHORT
from test_serve_command import DOC, Server

LONG = SHORT.replace(b"(40,0,10)", b"(120,0,10)")  # Up, Out (120 m north), Down
WITHIN = 300.0  # wall seconds: a hang guard, never a verdict


def until(what: str, done: Callable[[], Any]) -> Any:
    """Poll ``done`` until it returns something true; fail naming ``what`` after WITHIN."""
    end = time.monotonic() + WITHIN
    while not (found := done()):
        assert time.monotonic() < end, f"never: {what}"
        time.sleep(0.2)
    return found


def status(client: httpx.Client, run: str, *wanted: str) -> dict[str, Any] | None:
    found = dict(client.get(f"/runs/{run}").json())
    return found if found["status"] in wanted else None


def out_beyond(client: httpx.Client, vehicle: int, metres: float) -> bool:
    position = client.get(f"/vehicles/{vehicle}").json()["position"]
    return position is not None and position[0] > metres


def after(client: httpx.Client, vehicle: int, when: float) -> dict[str, Any] | None:
    """The vehicle, once its own clock is past ``when``."""
    found = dict(client.get(f"/vehicles/{vehicle}").json())
    return found if found["time"] > when else None


def moved(before: dict[str, Any], after: dict[str, Any]) -> float:
    """The most a vehicle moved along any axis between two readings, in metres."""
    return max(abs(a - b) for a, b in zip(after["position"], before["position"], strict=True))


def records(client: httpx.Client, run: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in client.get(f"/runs/{run}/log").text.splitlines()]


def post(client: httpx.Client, path: str, **body: object) -> dict[str, Any]:
    answer = client.post(path, json=body) if body else client.post(path)
    assert answer.status_code in (200, 201), (path, answer.status_code, answer.text)
    return dict(answer.json())


def test_the_service_flies_two_arducopters(ardupilot, tmp_path: Path) -> None:
    first, second = ardupilot(count=2)
    data = tmp_path / "data"
    command = re.search(r"```\n(tml serve --connect tcp:\S+ --connect tcp:\S+ .*)\n```",
                        DOC)
    assert command, "docs/serve.md shows how to serve two ArduCopters"
    serve = shlex.split(command.group(1))[2:]
    serve[1], serve[3] = first.address, second.address  # this run's instances
    serve += ["--timeout", "120"]
    with Server(serve, data) as server, \
            httpx.Client(base_url=server.url, timeout=60) as client:
        assert [v["id"] for v in client.get("/vehicles").json()] == [1, 2]
        mission = client.post("/missions", content=LONG, params={"filename": "long.xml"},
                              headers={"Content-Type": "application/xml"}).json()["id"]
        one = post(client, "/runs", mission=mission, vehicles=[1])["id"]
        two = post(client, "/runs", mission=mission, vehicles=[2])["id"]
        until("both runs flying", lambda: status(client, one, "running")
              and status(client, two, "running"))

        until("vehicle 1 on its way out", lambda: out_beyond(client, 1, 15))
        assert post(client, f"/runs/{one}/pause")["status"] == "paused"
        post(client, f"/runs/{two}/abort")
        # Told to hold (a velocity target of zero), ArduCopter brakes at its own limits,
        # some 18 to 25 m at 8 to 10 m/s, and stays where it stopped: how far depends on
        # its speed when the pause lands, so the test waits for the state, stopped for
        # 2 s of its time, not for a time (vehicle seconds, from its telemetry).
        readings: list[dict[str, Any]] = []

        def stopped() -> dict[str, Any] | None:
            now = dict(client.get("/vehicles/1").json())
            readings.append(now)
            before = [r for r in readings if now["time"] - r["time"] >= 2.0]
            if before and max(before[-1]["ground_speed"], now["ground_speed"]) < 0.3 \
                    and moved(before[-1], now) < 0.5:
                return now
            return None
        held = until("vehicle 1 stopped", stopped)
        now = until("vehicle 1 held", lambda: after(client, 1, held["time"] + 5))
        assert moved(held, now) < 1.0, (held, now)
        furthest = max(r["position"][0] for r in readings)
        assert furthest < held["position"][0] + 1.0, (furthest, held)  # did not fly back
        assert post(client, f"/runs/{one}/resume")["status"] == "running"
        assert post(client, f"/runs/{one}/jump", task="Down")["tasks"]["1"]["Out"] == "aborted"

        ended = until("run 1 ended", lambda: status(client, one, "completed", "failed",
                                                   "aborted", "taken"))
        assert (ended["status"], ended["tasks"]["1"]["Down"]) == ("completed", "done"), ended
        controls = [r["control"] for r in records(client, one) if r["kind"] == "control"]
        assert controls == ["pause", "resume", "jump"]
        aborted = until("run 2 aborted", lambda: status(client, two, "aborted", "completed",
                                                       "failed", "taken"))
        assert (aborted["status"], aborted["exit_code"]) == ("aborted", 3), aborted
        safety = [r for r in records(client, two) if r["kind"] == "safety"]
        assert safety and safety[0]["request"] == "ReturnToLaunch"

        # A run whose service dies in flight.
        third = post(client, "/runs", mission=mission, vehicles=[1])["id"]
        until("run 3 out of its take-off", lambda: any(
            r["kind"] == "task" and r["task"] == "Out" for r in records(client, third)))
        server.process.send_signal(signal.SIGKILL)
        server.process.communicate(timeout=60)
    with Server(serve, data) as again, \
            httpx.Client(base_url=again.url, timeout=60) as client:
        assert f"run {third} was flying when the service stopped: marked interrupted" \
            in again.said
        assert client.get(f"/runs/{third}").json()["status"] == "interrupted"
        going_on = post(client, f"/runs/{third}/continue")
        assert going_on["options"]["continues"] == third
        ended = until("the continued run ended", lambda: status(
            client, going_on["id"], "completed", "failed", "aborted", "taken"))
        assert ended["status"] == "completed", ended
        assert ended["tasks"]["1"] == dict.fromkeys(("Up", "Out", "Down"), "done")
        requests = [r["message"] for r in records(client, going_on["id"])
                    if r["kind"] == "request"]
        assert "TakeOff" not in requests, "the vehicle was in the air: no second take-off"
        code, out = again.stop()
        assert code == 0, out


def command(client: httpx.Client, vehicle: int, name: str) -> dict[str, Any]:
    """The service's answer to an operator's command, asserted confirmed (200, done)."""
    answer = client.post(f"/vehicles/{vehicle}/command", json={"command": name},
                         timeout=120)
    assert answer.status_code == 200, answer.text
    body = dict(answer.json())
    assert (body["outcome"], body["confirmed"]) == ("done", True), body
    return body


def test_operator_commands_are_done_once_arducopter_s_motion_confirms_them(
        ardupilot, tmp_path: Path) -> None:
    """A hold during a run pauses it and is done once the vehicle is still (and reports a
    stop as its GUIDED target); once the run is aborted (into hold) and ended, a hold of
    the vehicle no run holds is BRAKE, done once it is still; a land is done once it
    descends."""
    (vehicle,) = ardupilot(count=1)
    serve = ["--connect", vehicle.address, "--clock", "vehicle", "--timeout", "120"]
    with Server(serve, tmp_path / "data") as server, \
            httpx.Client(base_url=server.url, timeout=60) as client:
        mission = client.post("/missions", content=LONG, params={"filename": "long.xml"},
                              headers={"Content-Type": "application/xml"}).json()["id"]
        # Aborted into hold: the vehicle stays in the air, free, for the next hold.
        run = post(client, "/runs", mission=mission, vehicles=[1], safe_state="hold")["id"]
        until("vehicle 1 on its way out", lambda: out_beyond(client, 1, 15))
        held = command(client, 1, "hold")
        assert held["run"] == run and f"(run {run} paused): mode GUIDED" in held["message"]
        assert client.get(f"/runs/{run}").json()["status"] == "paused"
        post(client, f"/runs/{run}/abort")
        until("the run ended", lambda: status(client, run, "aborted", "completed", "failed",
                                              "taken"))
        braked = command(client, 1, "hold")
        assert braked["run"] is None and braked["message"].startswith(
            "vehicle 1: hold done (SetMode BRAKE): mode BRAKE"), braked
        assert client.get("/vehicles/1").json()["mode"] == "BRAKE"
        landed = command(client, 1, "land")
        assert landed["message"].startswith("vehicle 1: land done (Land): mode LAND")
        until("vehicle 1 landed and disarmed", lambda: not client.get(
            "/vehicles/1").json()["armed"])
        code, out = server.stop()
        assert code == 0, out
