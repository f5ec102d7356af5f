"""The HTTP API of ``tml serve`` on fake vehicles: missions, runs, vehicles, the flight log
and its live stream, auth and errors.

The fake vehicles' time stands still until a test lets it flow (``hangar.flowing``), so
a run can be caught in flight; with time flowing a short mission flies in a blink.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path

import pytest
from serving import DATA, MISSIONS, SHORT, TYPO, Served, interrupted_run

from tml.vehicle import Hold


@pytest.fixture
def served(tmp_path: Path) -> Iterator[Served]:
    with Served(tmp_path) as found:
        yield found


# --- missions ------------------------------------------------------------------------------

def test_a_mission_uploaded_as_xml_is_kept_with_its_tree_and_source(served: Served) -> None:
    mission = served.upload((MISSIONS / "verify_obstacles.xml").read_bytes(), "obst.xml")
    listed = served.client.get("/missions").json()
    assert [(m["id"], m["filename"]) for m in listed] == [(mission, "obst.xml")]
    detail = served.client.get(f"/missions/{mission}").json()
    assert detail["tasks"][0]["path"] == detail["tasks"][0]["name"]
    assert detail["world"]["obstacles"], "the world's obstacles are given for the map"
    source = served.client.get(f"/missions/{mission}/source")
    assert source.headers["content-type"].startswith("application/xml")
    assert source.content == (MISSIONS / "verify_obstacles.xml").read_bytes()


def test_a_mission_uploaded_as_a_multipart_form_is_named_by_its_file(served: Served) -> None:
    answer = served.client.post("/missions", files={"file": ("hop.xml", SHORT,
                                                             "application/xml")})
    assert answer.status_code == 201, answer.text
    assert (answer.json()["filename"], answer.json()["name"]) == ("hop.xml", "Short hop")


def test_an_invalid_mission_is_refused_with_the_diagnostics_of_tml_validate(
        served: Served) -> None:
    answer = served.client.post("/missions?filename=typo.xml", content=TYPO,
                                headers={"Content-Type": "application/xml"})
    assert answer.status_code == 422
    body = answer.json()
    assert "invalid mission" in body["error"]
    [found] = [d for d in body["diagnostics"] if d["severity"] == "error"]
    line = next(n for n, text in enumerate(TYPO.decode().splitlines(), 1) if "PIONT" in text)
    column = TYPO.decode().splitlines()[line - 1].index("<action") + 1
    assert (found["file"], found["line"], found["column"], found["code"]) == \
        ("typo.xml", line, column, "E201")
    assert "GO_TO_POINT" in found["hint"]
    assert served.client.get("/missions").json() == [], "an invalid mission is not kept"


def test_malformed_and_hostile_xml_is_refused_with_a_place(served: Served) -> None:
    for data in (b"<mission name='x'><task>", (DATA / "invalid" / "billion_laughs.xml"
                                                ).read_bytes()):
        answer = served.client.post("/missions", content=data,
                                    headers={"Content-Type": "application/xml"})
        assert answer.status_code == 422
        assert answer.json()["diagnostics"][0]["line"] >= 1


def test_an_upload_of_another_type_or_too_large_is_refused(served: Served) -> None:
    other = served.client.post("/missions", content=SHORT,
                               headers={"Content-Type": "text/plain"})
    assert (other.status_code, "application/xml" in other.json()["error"]) == (415, True)
    huge = served.client.post("/missions", content=b" " * (5 * 1024 * 1024),
                              headers={"Content-Type": "application/xml"})
    assert huge.status_code == 413
    empty_form = served.client.post("/missions", files={"other": ("a.xml", SHORT)})
    assert empty_form.status_code == 400


def test_a_mission_is_deleted_but_not_while_it_flies(served: Served) -> None:
    mission = served.upload()
    run = served.start(mission)
    refused = served.client.delete(f"/missions/{mission}")
    assert refused.status_code == 409 and run["id"] in refused.json()["error"]
    served.finish(run["id"])
    assert served.client.delete(f"/missions/{mission}").status_code == 204
    assert served.client.get(f"/missions/{mission}").status_code == 404
    # The run outlives its mission, with every task's state.
    kept = served.client.get(f"/runs/{run['id']}").json()
    assert kept["mission"]["name"] == "Short hop" and kept["tasks"]["1"]["Down"] == "done"


def test_verify_gives_the_report_of_tml_verify_with_each_actions_path(served: Served) -> None:
    mission = served.upload()
    report = served.client.post(f"/missions/{mission}/verify", json={}).json()
    assert report["feasible"] is True
    assert [a["action"] for a in report["actions"]] == ["TAKE_OFF", "GO_TO_POINT", "LAND"]
    assert report["actions"][1]["path"][-1] == [40.0, 0.0, 10.0]
    low = served.client.post(f"/missions/{mission}/verify", json={"battery": 1}).json()
    assert low["feasible"] is False and low["violations"]
    bad = served.client.post(f"/missions/{mission}/verify", json={"profile": "blimp"})
    assert bad.status_code == 422 and "profile" in bad.json()["error"]


# --- runs ------------------------------------------------------------------------------------

def test_a_run_flies_to_completion_with_every_task_done(served: Served) -> None:
    mission = served.upload()
    run = served.start(mission, vehicles=[2])
    assert run["status"] in ("waiting", "running") and run["vehicles"] == [2]
    ended = served.finish(run["id"])
    assert (ended["status"], ended["exit_code"], ended["reason"]) == \
        ("completed", 0, "all tasks done")
    assert ended["tasks"] == {"2": {"Up": "done", "Out": "done", "Down": "done"}}
    assert served.hangar.fakes[1].position[:2] == pytest.approx((40.0, 0.0), abs=0.5)


def test_two_runs_fly_at_once_and_a_vehicle_belongs_to_one_run(served: Served) -> None:
    mission = served.upload()
    first = served.start(mission, vehicles=[1])
    taken = served.client.post("/runs", json={"mission": mission, "vehicles": [1]})
    assert taken.status_code == 409
    assert taken.json() == {"error": f"vehicle 1 is held by run {first['id']}", "vehicle": 1,
                            "run": first["id"]}
    second = served.start(mission)  # the first free vehicle
    assert second["vehicles"] == [2]
    holders = {v["id"]: v["run"] for v in served.client.get("/vehicles").json()}
    assert holders == {1: first["id"], 2: second["id"]}
    none_free = served.client.post("/runs", json={"mission": mission})
    assert none_free.status_code == 409
    assert [served.finish(r["id"])["status"] for r in (first, second)] == ["completed"] * 2
    assert {v["run"] for v in served.client.get("/vehicles").json()} == {None}


def test_abort_sends_the_vehicles_to_their_safe_state(served: Served) -> None:
    mission = served.upload()
    run = served.start(mission, safe_state="land")
    fake = served.hangar.fakes[0]
    served.hangar.fly_until(lambda: fake.position[2] > 5)  # the take-off is under way
    aborted = served.client.post(f"/runs/{run['id']}/abort")
    assert aborted.status_code == 200
    ended = served.finish(run["id"])
    assert (ended["status"], ended["exit_code"]) == ("aborted", 3)
    assert "aborted by the operator" in ended["reason"]
    assert fake.mode == "LAND"
    lines = [json.loads(line) for line in served.client.get(f"/runs/{run['id']}/log")
             .text.splitlines()]
    assert any(line["kind"] == "safety" and "Land" in line["message"] for line in lines)
    again = served.client.post(f"/runs/{run['id']}/abort")
    assert again.status_code == 409 and "has ended" in again.json()["error"]


def test_an_infeasible_mission_is_not_flown_unless_forced(served: Served) -> None:
    mission = served.upload((DATA / "infeasible" / "range.xml").read_bytes(), "range.xml")
    refused = served.client.post("/runs", json={"mission": mission})
    assert refused.status_code == 422
    assert refused.json()["report"]["feasible"] is False
    assert served.client.get("/runs").json() == []
    assert {v["run"] for v in served.client.get("/vehicles").json()} == {None}
    forced = served.start(mission, force=True)
    served.client.post(f"/runs/{forced['id']}/abort")


def test_a_run_on_an_unknown_vehicle_is_refused(served: Served) -> None:
    mission = served.upload()
    answer = served.client.post("/runs", json={"mission": mission, "vehicles": [7]})
    assert answer.status_code == 422 and "no vehicle 7" in answer.json()["error"]
    assert served.client.post("/runs", json={"mission": "abc"}).status_code == 404


# --- vehicles --------------------------------------------------------------------------------

def test_a_vehicle_gives_what_an_operator_reads_and_where_its_home_is(served: Served) -> None:
    """The page draws a fleet in one frame from each vehicle's home and latitude and
    longitude, and shows the fields an operator expects."""
    vehicle = served.client.get("/vehicles/1").json()
    home = served.hangar.fakes[0].home
    assert vehicle["home"] == {"latitude": home.latitude, "longitude": home.longitude,
                               "altitude": home.altitude}
    assert vehicle["global"] == pytest.approx([home.latitude, home.longitude, home.altitude])
    assert (vehicle["satellites"], vehicle["voltage"], vehicle["climb"]) == (10, 12.6, 0.0)
    for address in ("/", "/page/app.js", "/page/style.css"):
        answer = served.client.get(address)
        assert answer.headers["cache-control"] == "no-cache", "an upgrade is never half seen"


# --- operator commands -----------------------------------------------------------------------

def test_a_command_to_a_free_vehicle_is_done_once_its_telemetry_confirms_it(
        served: Served) -> None:
    fake = served.hangar.fakes[0]
    fake.armed, fake.mode, fake.position = True, "GUIDED", (20.0, 0.0, 10.0)
    served.hangar.flowing.set()  # the vehicle moves: its motion confirms the command
    answer = served.client.post("/vehicles/1/command", json={"command": "rtl"})
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert (body["vehicle"], body["command"], body["run"]) == (1, "rtl", None)
    assert (body["outcome"], body["confirmed"]) == ("done", True)
    assert "vehicle 1: rtl done (ReturnToLaunch): mode RTL, armed" in body["message"]
    assert body["seen"].startswith("mode RTL, armed")
    assert fake.mode == "RTL" and body["vehicle_state"]["mode"] == "RTL"
    assert math.hypot(*fake.position[:2]) <= 20.0 - 1.0, "nearer home, as confirmed"
    seen = served.client.get("/vehicles/1").json()
    assert (seen["mode"], seen["run"]) == ("RTL", None), "the vehicle is free again"
    assert (seen["command"]["command"], seen["command"]["outcome"]) == ("rtl", "done")
    assert seen["command"]["detail"] == body["seen"]


def test_a_hold_of_a_free_vehicle_is_its_holding_mode_and_done_once_it_stays_still(
        served: Served) -> None:
    fake = served.hangar.fakes[0]
    fake.armed, fake.mode, fake.position = True, "GUIDED", (20.0, 0.0, 10.0)
    served.hangar.flowing.set()
    answer = served.client.post("/vehicles/1/command", json={"command": "hold"})
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert (body["outcome"], body["confirmed"]) == ("done", True)
    assert [(r.name, getattr(r, "mode", "")) for r in fake.submitted] == [("SetMode", "BRAKE")]
    assert "vehicle 1: hold done (SetMode BRAKE): mode BRAKE" in body["message"]
    assert fake.time >= 3.0, "still for 3 s of the vehicle's time"


def test_a_command_the_telemetry_does_not_confirm_is_answered_202_with_what_was_seen(
        served: Served) -> None:
    fake = served.hangar.fakes[0]
    fake.armed, fake.mode, fake.position = True, "GUIDED", (20.0, 0.0, 10.0)
    fake.stuck = True  # accepts, never moves
    served.service.options.command_timeout = 0.5
    served.hangar.flowing.set()
    answer = served.client.post("/vehicles/1/command", json={"command": "rtl"})
    assert answer.status_code == 202, answer.text
    body = answer.json()
    assert (body["outcome"], body["confirmed"]) == ("not confirmed", False)
    assert body["message"] == (
        "vehicle 1: rtl not confirmed within 0.5 s (ReturnToLaunch; wanted an RTL mode and "
        "1 m nearer home (or home); seen mode RTL, armed, 10.0 m up, ground speed 0.0 m/s, "
        "climb +0.0 m/s, 20 m from home)")
    seen = served.client.get("/vehicles/1").json()["command"]
    assert (seen["outcome"], seen["detail"]) == (
        "not confirmed", body["message"].split("(ReturnToLaunch; ")[1][:-1])


def test_a_disarm_in_the_air_is_refused_with_the_reason(served: Served) -> None:
    fake = served.hangar.fakes[0]
    fake.armed, fake.mode, fake.position = True, "GUIDED", (0.0, 0.0, 10.0)
    answer = served.client.post("/vehicles/1/command", json={"command": "disarm"})
    assert answer.status_code == 409
    assert "disarm refused: the vehicle is flying at 10.0 m" in answer.json()["error"]
    assert fake.armed and not [r for r in fake.submitted if r.name == "Disarm"]
    assert served.client.get("/vehicles/1").json()["command"]["outcome"] == "refused"
    fake.position = (0.0, 0.0, 0.0)  # landed, still armed: now it may be disarmed
    assert served.client.post("/vehicles/1/command", json={"command": "disarm"}
                              ).status_code == 200
    assert not fake.armed


def test_a_command_the_vehicle_refuses_is_a_conflict(served: Served) -> None:
    fake = served.hangar.fakes[1]
    fake.armed, fake.mode, fake.position = True, "GUIDED", (0.0, 0.0, 10.0)
    fake.reject["Land"] = "rejected"
    answer = served.client.post("/vehicles/2/command", json={"command": "land"})
    assert answer.status_code == 409
    assert "land refused by the vehicle: rejected" in answer.json()["error"]


def test_a_command_to_a_vehicle_in_a_run_ends_the_run_into_that_safe_state(
        served: Served) -> None:
    mission = served.upload()
    run = served.start(mission)  # its safe state is rtl
    fake = served.hangar.fakes[0]
    served.hangar.fly_until(lambda: fake.position[2] > 5)  # the take-off is under way
    served.hangar.flowing.set()
    answer = served.client.post("/vehicles/1/command", json={"command": "land"})
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert (body["run"], body["outcome"], body["confirmed"]) == (run["id"], "done", True)
    assert f"vehicle 1: land done (run {run['id']} ends into land): mode LAND" in \
        body["message"]
    ended = served.finish(run["id"])
    # The operator took the vehicle over through the run (docs/run.md, How a run ends).
    assert (ended["status"], ended["exit_code"]) == ("taken", 4)
    assert "operator command: land" in ended["reason"]
    assert fake.mode == "LAND"
    assert any("Land" in said for said in ended["safety"])


def test_a_hold_of_a_vehicle_in_a_run_pauses_the_run_and_is_done_once_it_stays_still(
        served: Served) -> None:
    mission = served.upload()
    run = served.start(mission)
    fake = served.hangar.fakes[0]
    served.hangar.fly_until(lambda: fake.position[0] > 5)  # on the leg out
    served.hangar.flowing.set()
    answer = served.client.post("/vehicles/1/command", json={"command": "hold"})
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert (body["run"], body["outcome"], body["confirmed"]) == (run["id"], "done", True)
    assert f"vehicle 1: hold done (run {run['id']} paused): mode GUIDED" in body["message"]
    assert served.client.get(f"/runs/{run['id']}").json()["status"] == "paused"
    assert isinstance(fake.submitted[-1], Hold), "the run's own hold, not BRAKE"
    paused = [json.loads(line) for line in served.client.get(
        f"/runs/{run['id']}/log").text.splitlines()]
    assert any("mission paused: operator command: hold" in str(r.get("message", ""))
               for r in paused), paused
    served.client.post(f"/runs/{run['id']}/abort")
    served.finish(run["id"])


def test_a_command_is_checked_before_anything_is_sent(served: Served) -> None:
    assert served.client.post("/vehicles/7/command", json={"command": "rtl"}
                              ).status_code == 404
    assert served.client.post("/vehicles/1/command", json={"command": "flip"}
                              ).status_code == 422
    nothing = served.client.post("/vehicles/1/command", json={"command": "rtl"})
    assert nothing.status_code == 200 and "nothing to do" in nothing.json()["message"]
    assert served.hangar.fakes[0].submitted == []


# --- the flight log and its stream ---------------------------------------------------------

def test_the_stream_sends_the_flight_log_lines_then_the_end(served: Served) -> None:
    mission = served.upload()
    run = served.start(mission)
    served.hangar.flowing.set()
    records, ids, end, boards = [], [], None, []
    with served.client.stream("GET", f"/runs/{run['id']}/stream") as stream:
        event = ""
        for line in stream.iter_lines():
            if line.startswith("event: "):
                event = line[7:]
            elif line.startswith("id: "):
                ids.append(int(line[4:]))
            elif line.startswith("data: ") and event == "record":
                records.append(line[6:])
            elif line.startswith("data: ") and event == "tasks":
                boards.append(json.loads(line[6:]))
            elif line.startswith("data: ") and event == "end":
                end = json.loads(line[6:])
    log = served.client.get(f"/runs/{run['id']}/log")
    assert log.headers["content-type"].startswith("application/x-ndjson")
    assert records == log.text.splitlines(), "the stream sends the lines of the log"
    assert ids == list(range(1, len(records) + 1))
    kinds = {json.loads(r)["kind"] for r in records}
    assert {"run", "mission", "task", "action", "request", "telemetry"} <= kinds
    assert end is not None and end["status"] == "completed"
    # The task board as the service folds the log, after the records sent at first and
    # each time it changes: the page draws it.
    assert boards and boards[-1] == end["tasks"]
    assert set(end["tasks"]["1"].values()) == {"done"}
    # A client that reconnects after record 5 gets the rest, from the database now.
    with served.client.stream("GET", f"/runs/{run['id']}/stream",
                              headers={"Last-Event-ID": "5"}) as stream:
        again = [line[6:] for line in stream.iter_lines() if line.startswith("data: {\"t\"")]
    assert again == records[5:]


# --- auth and errors -------------------------------------------------------------------------

def test_with_a_token_every_api_request_needs_it(tmp_path: Path) -> None:
    served = Served(tmp_path, token="s3cret")
    with served.client as client:
        missing = client.get("/vehicles")
        assert missing.status_code == 401
        assert missing.headers["www-authenticate"] == "Bearer"
        assert "Bearer" in missing.json()["error"]
        wrong = client.get("/vehicles", headers={"Authorization": "Bearer guess"})
        assert wrong.status_code == 401
        right = client.get("/vehicles", headers={"Authorization": "Bearer s3cret"})
        assert right.status_code == 200 and len(right.json()) == 2
        assert client.post("/missions", content=SHORT).status_code == 401
        # The page's files hold no data: the browser loads them, then asks for the token.
        assert client.get("/").status_code == 200
        assert client.get("/openapi.json").status_code == 200
    served.storage.close()


def test_errors_are_json_with_a_message_never_a_traceback(served: Served) -> None:
    cases = [("GET", "/nowhere", None, 404), ("GET", "/runs/zz", None, 422),
             ("GET", "/runs/abc", None, 404), ("DELETE", "/vehicles", None, 405),
             ("POST", "/runs", b"{not json", 422), ("POST", "/runs", b'{"mission": 5}', 422),
             ("GET", "/vehicles/9", None, 404)]
    for method, path, body, status in cases:
        answer = served.client.request(method, path, content=body,
                                       headers={"Content-Type": "application/json"})
        assert answer.status_code == status, (method, path, answer.text)
        assert isinstance(answer.json()["error"], str) and answer.json()["error"]
        assert "Traceback" not in answer.text


def test_a_restarted_service_lists_past_runs_with_their_task_states(tmp_path: Path) -> None:
    first = Served(tmp_path)
    with first.client:
        mission = first.upload()
        done = first.finish(first.start(mission)["id"])
    first.storage.close()
    again = Served(tmp_path)  # the same data directory
    assert again.service.start() == []
    with again.client:
        assert [r["id"] for r in again.client.get("/runs").json()] == [done["id"]]
        kept = again.client.get(f"/runs/{done['id']}").json()
        assert (kept["status"], kept["exit_code"], kept["tasks"]) == \
            ("completed", 0, done["tasks"])
        assert again.client.get(f"/runs/{done['id']}/log").text.count("\n") > 10
    again.storage.close()


PLAN = b"""<mission name="Out and back in AUTO">
  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/></action></task>
  <task name="Round trip" dispatch="mission">
    <task name="Out">
      <action name="GO_TO_POINT"><argument name="point" value="(40,0,10)"/></action>
    </task>
    <task name="Back">
      <action name="GO_TO_POINT"><argument name="point" value="(0,0,10)"/></action>
    </task>
  </task>
  <task name="Down"><action name="LAND"/></task>
</mission>
"""


def test_a_second_run_on_a_vehicle_flies_its_own_autopilot_plan(served: Served) -> None:
    # The vehicle still reports the first run's plan as finished when the second run
    # sends its own: the two plans must not share an id, or the second is taken as flown.
    mission = served.upload(PLAN, "plan.xml")
    farthest = []
    for _ in range(2):
        run = served.finish(served.start(mission)["id"])
        assert run["status"] == "completed", run["reason"]
        lines = [json.loads(line) for line in
                 served.client.get(f"/runs/{run['id']}/log").text.splitlines()]
        farthest.append(max(line["position"][0] for line in lines
                            if line["kind"] == "telemetry" and line["position"]))
        served.hangar.flowing.clear()
    assert farthest[1] > 30, farthest  # telemetry is sampled once a second


# --- pause, resume, jump -------------------------------------------------------------------

def test_pause_holds_the_vehicle_and_resume_flies_on_to_completion(served: Served) -> None:
    mission = served.upload()
    run = served.start(mission)
    fake = served.hangar.fakes[0]
    served.hangar.fly_until(lambda: fake.position[0] > 10)
    paused = served.client.post(f"/runs/{run['id']}/pause")
    assert paused.status_code == 200 and paused.json()["status"] == "paused"
    assert isinstance(fake.submitted[-1], Hold)
    where, since = fake.position, served.hangar.now
    served.hangar.fly_until(lambda: served.hangar.now > since + 30)  # half a minute paused
    assert fake.position == pytest.approx(where, abs=0.6)
    again = served.client.post(f"/runs/{run['id']}/pause")
    assert again.status_code == 409 and "paused already" in again.json()["error"]
    resumed = served.client.post(f"/runs/{run['id']}/resume")
    assert resumed.status_code == 200 and resumed.json()["status"] == "running"
    ended = served.finish(run["id"])
    assert (ended["status"], ended["tasks"]["1"]["Out"]) == ("completed", "done")
    log = served.client.get(f"/runs/{run['id']}/log").text
    controls = [json.loads(line) for line in log.splitlines() if '"kind":"control"' in line]
    assert [c["control"] for c in controls] == ["pause", "resume"]
    late = served.client.post(f"/runs/{run['id']}/resume")
    assert late.status_code == 409 and "has ended" in late.json()["error"]


def test_jump_goes_on_from_the_task_or_is_refused_with_the_languages_reason(
        served: Served) -> None:
    mission = served.upload()
    run = served.start(mission)
    fake = served.hangar.fakes[0]
    served.hangar.fly_until(lambda: fake.position[0] > 10)
    refused = served.client.post(f"/runs/{run['id']}/jump", json={"task": "Dwn"})
    assert refused.status_code == 422
    assert refused.json()["code"] == "E240" and "did you mean 'Down'" in refused.json()["error"]
    jumped = served.client.post(f"/runs/{run['id']}/jump", json={"task": "Down"})
    assert jumped.status_code == 200
    assert jumped.json()["tasks"]["1"]["Out"] == "aborted"
    ended = served.finish(run["id"])
    assert ended["status"] == "completed" and ended["tasks"]["1"]["Down"] == "done"
    assert fake.position[0] < 30, "it landed where it was, not at the end of the leg"


def test_controls_wait_for_the_vehicles_to_be_ready(tmp_path: Path) -> None:
    served = Served(tmp_path)
    for fake in served.hangar.fakes:
        fake.ready = False
    with served.client:
        run = served.start(served.upload())
        answer = served.client.post(f"/runs/{run['id']}/pause")
        assert answer.status_code == 409 and "not ready" in answer.json()["error"]
        assert served.client.post(f"/runs/{run['id']}/abort").status_code == 200
    served.storage.close()


# --- continuing an interrupted run -----------------------------------------------------------

def test_an_interrupted_run_is_continued_from_its_log(served: Served) -> None:
    """A service that died mid-flight left a run ``interrupted``, its log in the database and
    its vehicle flying the leg out: POST /runs/{id}/continue goes on from there."""
    mission_id = served.upload()
    old = interrupted_run(served.storage, served.hangar.fakes[0], mission_id)

    answer = served.client.post(f"/runs/{old}/continue")
    assert answer.status_code == 201, answer.text
    run = served.finish(answer.json()["id"])
    assert run["status"] == "completed"
    assert run["tasks"]["1"] == {"Up": "done", "Out": "done", "Down": "done"}
    log = [json.loads(line) for line in
           served.client.get(f"/runs/{run['id']}/log").text.splitlines()]
    requests = [line["message"] for line in log if line["kind"] == "request"]
    assert "TakeOff" not in requests and requests[0] == "GoTo"  # no second take-off
    again = served.client.post(f"/runs/{old}/continue")
    assert again.status_code == 422 and "continued already" in again.text
    done = served.client.post(f"/runs/{run['id']}/continue")
    assert done.status_code == 422 and "only an interrupted run" in done.text
