"""``tml serve`` against hostile clients: browsers turned against it (DNS rebinding, other
sites' forms and scripts, framing), oversized bodies, a database that fails under a run,
racing starts, odd headers and methods -- the requests of an adversarial probe, kept so
that the next change keeps them refused. (The fuzzing of every operation from the OpenAPI
document is tests/test_serve_fuzz.py.)
"""

from __future__ import annotations

import json
import re
import socket
import sqlite3
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
import sqlalchemy as sa
from serving import ROOT, SHORT, Served, free_port, interrupted_run

from tml.serve import live as live_module
from tml.serve.guard import POLICY, Guard
from tml.serve.storage import Storage, database_url

EVIL = "http://evil.example"


@pytest.fixture
def served(tmp_path: Path) -> Iterator[Served]:
    with Served(tmp_path) as found:
        yield found


def _flying(served: Served) -> tuple[str, dict[str, Any]]:
    """A mission uploaded and a run of it in the air on vehicle 1."""
    mission = served.upload()
    run = served.start(mission, vehicles=[1])
    fake = served.hangar.fakes[0]
    served.hangar.fly_until(lambda: fake.position[2] > 5)
    return mission, run


# --- browsers ------------------------------------------------------------------------------

@pytest.mark.parametrize("host", ["evil.example", "evil.example:8080", "localhost.evil.example",
                                  "127.0.0.1.evil.example", ""])
def test_a_request_by_another_host_name_is_refused_dns_rebinding(served: Served,
                                                                  host: str) -> None:
    mission = served.upload()
    headers = {"Host": host}
    assert served.client.get("/status", headers=headers).status_code == 400
    assert served.client.get("/", headers=headers).status_code == 400
    upload = served.client.post("/missions", content=SHORT, headers={
        **headers, "Content-Type": "application/xml"})
    start = served.client.post("/runs", json={"mission": mission}, headers=headers)
    assert (upload.status_code, start.status_code) == (400, 400)
    assert "--allow-host" in start.json()["error"]
    assert len(served.client.get("/missions").json()) == 1
    assert served.client.get("/runs").json() == [], "nothing flies"


def test_the_service_answers_to_its_address_localhost_and_names_given(tmp_path: Path) -> None:
    served = Served(tmp_path, hosts=["Field-Laptop"])
    with served.client as client:
        for host in ("127.0.0.1", "127.0.0.1:8080", "localhost:8080", "LOCALHOST", "[::1]:8080",
                     "field-laptop:8080", "field-laptop."):
            assert client.get("/status", headers={"Host": host}).status_code == 200, host
        assert client.get("/status", headers={"Host": "10.0.0.7"}).status_code == 400
    served.storage.close()
    everywhere = Guard(lambda *_: None, bound="0.0.0.0")  # type: ignore[arg-type]
    assert everywhere.allowed_host("192.168.1.20:8080")
    assert not everywhere.allowed_host("field-laptop")


def test_another_sites_page_cannot_fly_pause_or_abort(served: Served) -> None:
    mission, run = _flying(served)
    controls = f"/runs/{run['id']}"
    cross: list[tuple[str, dict[str, Any]]] = [
        # a form posted from another site: its own encodings, and the browser's headers
        (f"{controls}/abort", {"data": {"x": "1"}, "headers": {"Origin": EVIL}}),
        (f"{controls}/pause", {"content": b"x=1", "headers": {
            "Origin": EVIL, "Content-Type": "application/x-www-form-urlencoded"}}),
        (f"{controls}/abort", {"content": b"x", "headers": {
            "Sec-Fetch-Site": "cross-site", "Content-Type": "text/plain"}}),
        (f"{controls}/abort", {"headers": {"Origin": "null"}}),  # a sandboxed frame
        ("/runs", {"json": {"mission": mission, "vehicles": [2]}, "headers": {
            "Origin": EVIL}}),
        ("/missions", {"files": {"file": ("m.xml", SHORT, "application/xml")},
                       "headers": {"Origin": EVIL}}),
        ("/missions", {"content": SHORT, "headers": {
            "Origin": "http://127.0.0.1.evil.example", "Content-Type": "application/xml"}}),
        (f"{controls}/resume", {"headers": {"Sec-Fetch-Site": "same-site"}}),
    ]
    for path, request in cross:
        answer = served.client.post(path, **request)
        assert answer.status_code == 403, (path, request, answer.text)
    # Without Origin, a form's encodings are refused all the same (an old browser).
    for kind in ("application/x-www-form-urlencoded", "text/plain", "multipart/form-data"):
        answer = served.client.post(f"{controls}/abort", content=b"x=1",
                                    headers={"Content-Type": kind})
        assert answer.status_code == 415, kind
    held = served.client.get(controls).json()
    assert held["status"] == "running" and served.hangar.fakes[0].mode != "RTL"
    assert len(served.client.get("/missions").json()) == 1
    assert [r["id"] for r in served.client.get("/runs").json()] == [run["id"]]
    # The page's own requests name its own origin, and are taken.
    own = {"Origin": "http://127.0.0.1", "Sec-Fetch-Site": "same-origin"}
    assert served.client.post(f"{controls}/pause", headers=own).status_code == 200
    assert served.client.post(f"{controls}/resume", headers=own).status_code == 200
    uploaded = served.client.post("/missions", headers=own,
                                  files={"file": ("m.xml", SHORT, "application/xml")})
    assert uploaded.status_code == 201
    assert served.finish(run["id"])["status"] == "completed"


def test_the_page_and_every_answer_carry_security_headers(served: Served) -> None:
    assert "'unsafe-inline'" not in POLICY and "frame-ancestors 'none'" in POLICY
    for path in ("/", "/page/app.js", "/page/style.css", "/status", "/openapi.json",
                 "/no/such/route"):
        answer = served.client.get(path)
        assert answer.headers["content-security-policy"] == POLICY, path
        assert answer.headers["x-frame-options"] == "DENY"
        assert answer.headers["x-content-type-options"] == "nosniff"
        assert "access-control-allow-origin" not in answer.headers
    refused = served.client.get("/status", headers={"Host": "evil.example"})
    assert refused.headers["x-frame-options"] == "DENY"
    page = served.client.get("/").text
    assert not re.search(r"<script(?![^>]*\bsrc=)[^>]*>", page), "no inline script"
    assert not re.search(r"\son[a-z]+=", page), "no inline event handler"
    preflight = served.client.options("/runs", headers={
        "Origin": EVIL, "Access-Control-Request-Method": "POST"})
    assert "access-control-allow-origin" not in preflight.headers


# --- bounded resources ----------------------------------------------------------------------

def test_every_route_takes_a_body_up_to_the_limit(tmp_path: Path) -> None:
    served = Served(tmp_path, max_body=2000)
    with served.client as client:
        assert served.upload(SHORT)  # below the limit
        big = SHORT.replace(b"</mission>", b"<!--" + b"x" * 2000 + b"--></mission>")
        for path, request in [
                ("/missions", {"content": big, "headers": {"Content-Type": "application/xml"}}),
                ("/missions", {"files": {"file": ("m.xml", big, "application/xml")}}),
                ("/runs", {"content": json.dumps({"mission": "ab", "x": "y" * 3000}),
                           "headers": {"Content-Type": "application/json"}}),
                ("/missions/abc/verify", {"json": {"profile": "x" * 3000}})]:
            answer = client.post(path, **request)  # type: ignore[arg-type]
            assert answer.status_code == 413, (path, answer.text)
            assert "--max-body" in answer.json()["error"]

        def chunks() -> Iterator[bytes]:  # no Content-Length: counted as it comes
            for _ in range(10):
                yield b" " * 500

        chunked = client.post("/runs", content=chunks(),
                              headers={"Content-Type": "application/json"})
        assert chunked.status_code == 413
        chunked = client.post("/missions", content=chunks(),
                              headers={"Content-Type": "application/xml"})
        assert chunked.status_code == 413
    served.storage.close()


def _big_mission(size: int) -> bytes:
    """A valid mission of about ``size`` bytes: a take-off, short legs, a landing."""
    head = (b'<mission name="Big">\n  <task name="Up"><action name="TAKE_OFF"><argument '
            b'name="altitude" value="10"/></action></task>\n')
    tail = b'  <task name="Down"><action name="LAND"/></task>\n</mission>\n'
    legs: list[bytes] = []
    total = len(head) + len(tail)
    while total < size:
        n = len(legs)
        leg = (b'  <task name="Leg %d"><action name="GO_TO_POINT"><argument name="point" '
               b'value="(%d,%d,10)"/></action></task>\n' % (n, n % 40, n // 40 % 40))
        legs.append(leg)
        total += len(leg)
    return head + b"".join(legs) + tail


def _rss(pid: int) -> int:
    """The resident memory of a process, in bytes."""
    status = Path(f"/proc/{pid}/status").read_text()
    return int(re.search(r"VmRSS:\s+(\d+) kB", status).group(1)) * 1024  # type: ignore[union-attr]


class Subprocess:
    """``tml serve --sim --vehicles 1`` in its own process, once it answers."""

    def __init__(self, data: Path) -> None:
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.process = subprocess.Popen(
            [sys.executable, "-m", "tml", "serve", "--sim", "--vehicles", "1", "--port",
             str(self.port), "--data", str(data)], stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True, cwd=ROOT)
        assert self.process.stdout is not None
        said = ""
        while not (line := self.process.stdout.readline()).startswith("tml serve: http://"):
            assert line, said
            said += line

    def stop(self) -> None:
        self.process.terminate()
        self.process.communicate(timeout=120)


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc")
@pytest.mark.timeout(900)  # fifty missions of 2 MB, each validated as tml validate does
def test_memory_comes_back_after_large_missions_are_deleted(tmp_path: Path) -> None:
    big = _big_mission(2_000_000)
    served = Subprocess(tmp_path / "data")
    try:
        with httpx.Client(base_url=served.url, timeout=120) as client:
            def upload(data: bytes) -> str:
                answer = client.post("/missions", content=data,
                                     headers={"Content-Type": "application/xml"})
                assert answer.status_code == 201, answer.text
                return str(answer.json()["id"])

            small = upload(SHORT)  # the parser and the database at work once
            assert client.get(f"/missions/{small}").status_code == 200
            assert client.delete(f"/missions/{small}").status_code == 204
            baseline = _rss(served.process.pid)
            # 12 of 2 MB: what the server kept of each before (some 12 times the text, above)
            # would pass both bounds several times over.
            missions = [upload(big) for _ in range(12)]
            assert client.get(f"/missions/{missions[0]}").status_code == 200
            kept = _rss(served.process.pid)
            for mission in missions:
                assert client.delete(f"/missions/{mission}").status_code == 204
            huge = client.post("/runs", content=b"[" + b"1," * 25_000_000 + b"1]",
                               headers={"Content-Type": "application/json"})
            assert huge.status_code == 413
            after = _rss(served.process.pid)
            assert client.get("/missions").json() == []
        # Generous bounds, for what one parse of a large mission leaves in the heap and
        # the database's page caches (40 MB here), whatever the number of missions:
        # before, six missions of 3.9 MB took 280 MB, and 166 MB of it stayed after their
        # deletion.
        assert kept - baseline < 128 * 1024 * 1024, (baseline, kept)
        assert after - baseline < 64 * 1024 * 1024, (baseline, after)
    finally:
        served.stop()


def test_the_real_server_refuses_a_rebound_host_and_says_who_it_is(tmp_path: Path) -> None:
    served = Subprocess(tmp_path / "data")
    try:
        with socket.create_connection(("127.0.0.1", served.port), timeout=60) as sock:
            sock.sendall(b"POST /runs HTTP/1.1\r\nHost: evil.example\r\nContent-Type: "
                         b"application/json\r\nContent-Length: 2\r\n\r\n{}")
            answer = sock.recv(65536).decode()
        assert answer.startswith("HTTP/1.1 400"), answer
        assert "x-frame-options: DENY" in answer.lower().replace("deny", "DENY")
        with httpx.Client(base_url=served.url, timeout=60) as client:
            assert client.get("/status").status_code == 200
            assert client.get("/status", headers={"Host": f"localhost:{served.port}"}
                              ).status_code == 200
    finally:
        served.stop()


# --- a database that fails ------------------------------------------------------------------

class FullStorage(Storage):
    """SQLite whose writes fail while ``full`` is set, as on a full disk."""

    full = False

    def _check(self) -> None:
        if self.full:
            raise sa.exc.OperationalError("INSERT", {}, sqlite3.OperationalError(
                "database or disk is full"))

    def add_mission(self, *args: Any, **kwargs: Any) -> None:
        self._check()
        super().add_mission(*args, **kwargs)

    def add_run(self, *args: Any, **kwargs: Any) -> None:
        self._check()
        super().add_run(*args, **kwargs)

    def update_run(self, *args: Any, **kwargs: Any) -> None:
        self._check()
        super().update_run(*args, **kwargs)

    def add_lines(self, *args: Any, **kwargs: Any) -> None:
        self._check()
        super().add_lines(*args, **kwargs)


def test_a_full_database_ends_the_run_frees_the_vehicle_and_flies_again(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(live_module, "STORE_PERIOD", 0.0)  # every line stored at once
    storage = FullStorage(database_url(None, tmp_path))
    served = Served(tmp_path, storage=storage)
    with served.client as client:
        mission, run = _flying(served)
        storage.full = True
        live = served.service.live(run["id"])
        assert live is not None
        served.hangar.flowing.set()
        ended: list[str] = []

        def watch() -> None:
            with client.stream("GET", f"/runs/{run['id']}/stream") as stream:
                ended.extend(line for line in stream.iter_lines() if line == "event: end")

        watcher = threading.Thread(target=watch)
        watcher.start()
        assert live.join(60), "the run did not end"
        watcher.join(60)
        assert not watcher.is_alive() and ended == ["event: end"], "its stream ended"
        seen = client.get(f"/runs/{run['id']}").json()
        assert seen["status"] == "failed" and "database or disk is full" in seen["reason"]
        assert served.hangar.holder(1) is None, "the vehicle is free"
        assert served.hangar.fakes[0].mode in ("RTL", "LAND"), "sent to its safe state"
        assert client.post(f"/runs/{run['id']}/abort").status_code == 409
        assert client.post("/runs", json={"mission": mission, "vehicles": [1]}
                           ).status_code == 503, "no room for a new run yet"
        assert served.hangar.holder(1) is None
        fake = served.hangar.fakes[0]
        while not fake.state().landed:  # home, with no run to move its time
            fake.advance(0.1)
        storage.full = False  # space again: no restart
        again = served.start(mission, vehicles=[1])
        assert served.finish(again["id"])["status"] == "completed"
        stored = storage.run(run["id"])
        assert stored is not None and stored.status == "failed", "stored once it could be"
        assert [seq for seq, _ in storage.lines(run["id"])] == \
            list(range(1, len(live.log.lines) + 1)), "with its whole log"
    storage.close()


# --- races and small faults -----------------------------------------------------------------

def test_starts_that_name_no_vehicle_at_the_same_time_each_get_one(served: Served) -> None:
    mission = served.upload(_big_mission(60_000))  # its verification takes a while
    for _ in range(5):
        gate = threading.Barrier(2)
        answers: list[httpx.Response] = []

        def start(gate: threading.Barrier, answers: list[httpx.Response]) -> None:
            gate.wait()
            answers.append(served.client.post("/runs", json={"mission": mission,
                                                             "force": True}))

        threads = [threading.Thread(target=start, args=(gate, answers)) for _ in range(2)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(120)
        assert [a.status_code for a in answers] == [201, 201], [a.text for a in answers]
        assert sorted(a.json()["vehicles"][0] for a in answers) == [1, 2]
        for answer in answers:
            served.client.post(f"/runs/{answer.json()['id']}/abort")
            served.finish(answer.json()["id"])
            served.hangar.flowing.clear()


def test_a_huge_or_odd_last_event_id_asks_for_nothing_more(served: Served) -> None:
    mission = served.upload()
    run = served.start(mission)
    served.finish(run["id"])
    logged = len(served.client.get(f"/runs/{run['id']}/log").text.splitlines())
    for last, records in ((b"9" * 20, 0), (b"18446744073709551616", 0),
                          (str(2**31 + 1).encode(), 0), ("²".encode("latin-1"), logged),
                          (b"-1", logged), (b"x", logged), (b"3", logged - 3)):
        with served.client.stream("GET", f"/runs/{run['id']}/stream",
                                  headers={"Last-Event-ID": last}) as stream:
            assert stream.status_code == 200, last
            lines = list(stream.iter_lines())
        assert lines.count("event: end") == 1, last
        assert lines.count("event: record") == records, last


def test_an_ended_run_says_what_was_done_to_leave_its_vehicles_safe(served: Served) -> None:
    _mission, run = _flying(served)
    served.client.post(f"/runs/{run['id']}/abort")
    ended = served.finish(run["id"])
    assert ended["status"] == "aborted"
    assert any(said.startswith("vehicle 1: ") and "RTL" in said for said in ended["safety"]), \
        ended["safety"]


@pytest.mark.parametrize(("method", "path", "allowed"), [
    ("TRACE", "/status", "GET"), ("PUT", "/runs", "GET, POST"),
    ("DELETE", "/runs/abc/abort", "POST"), ("PATCH", "/missions/abc", "GET, DELETE")])
def test_an_unknown_method_is_405_with_the_methods_allowed(served: Served, method: str,
                                                          path: str, allowed: str) -> None:
    answer = served.client.request(method, path)
    assert answer.status_code == 405
    assert answer.headers["allow"] == allowed
    assert answer.json()["error"] == f"this route takes {allowed.replace(', ', ' or ')}"


def test_a_busy_port_is_one_line_and_exit_2_before_anything_else(tmp_path: Path) -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        done = subprocess.run([sys.executable, "-m", "tml", "serve", "--sim", "--port",
                               str(port), "--data", str(tmp_path / "data")],
                              capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.splitlines() == [
        f"tml serve: cannot serve on 127.0.0.1 port {port}: Address already in use"]


LANDING = b"""<mission name="Landing">
  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/></action></task>
  <task name="There">
    <action name="LANDING_POINT"><argument name="coordinates" value="(20,0,10)"/></action>
  </task>
</mission>
"""


def test_a_run_continued_after_its_vehicle_landed_during_landing_point_is_done(
        served: Served) -> None:
    mission = served.upload(LANDING)
    fake = served.hangar.fakes[0]
    run_id = interrupted_run(served.storage, fake, mission, source=LANDING,
                             until=lambda f: f.mode == "LAND")  # over the point, landing
    while fake.state().flying:  # it lands while no service watches
        fake.advance(0.1)
    continued = served.client.post(f"/runs/{run_id}/continue")
    assert continued.status_code == 201, continued.text
    ended = served.finish(continued.json()["id"])
    assert (ended["status"], ended["reason"]) == ("completed", "all tasks done")
    assert ended["tasks"]["1"] == {"Up": "done", "There": "done"}


# --- what held, kept ------------------------------------------------------------------------

def test_fifty_starts_on_one_vehicle_at_once_give_it_to_exactly_one(served: Served) -> None:
    mission = served.upload()
    gate = threading.Barrier(50)
    answers: list[int] = []

    def start() -> None:
        gate.wait()
        answers.append(served.client.post("/runs", json={"mission": mission,
                                                         "vehicles": [1]}).status_code)

    threads = [threading.Thread(target=start) for _ in range(50)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(120)
    assert sorted(answers) == [201] + [409] * 49
    assert len(served.client.get("/runs").json()) == 1


@pytest.mark.parametrize("path", [
    "/missions/..%2F..%2Fetc%2Fpasswd", "/missions/1%20OR%201=1",
    "/runs/'%3B%20DROP%20TABLE%20runs", "/page/..%2F..%2Fservice.py", "/page/../api.py",
    "/missions/%00"])
def test_traversal_and_sql_looking_ids_find_nothing(served: Served, path: str) -> None:
    answer = served.client.get(path)
    assert answer.status_code in (404, 422), (path, answer.status_code)
    assert "Traceback" not in answer.text and "import" not in answer.text


def test_bad_or_missing_credentials_are_all_401(tmp_path: Path) -> None:
    with Served(tmp_path, token="s3cret") as served:
        mission = "0" * 12
        for header in (None, "", "Bearer", "Bearer ", "Bearer s3cre", "Bearer s3cret2",
                       "Bearer S3CRET", "Basic czNjcmV0", "bearer s3cretx", "Token s3cret"):
            headers = {} if header is None else {"Authorization": header}
            for method, path in (("GET", "/status"), ("GET", "/missions"),
                                 ("POST", "/runs"), ("DELETE", f"/missions/{mission}"),
                                 ("POST", f"/runs/{mission}/abort")):
                answer = served.client.request(method, path, headers=headers,
                                               json={"mission": mission}
                                               if path == "/runs" else None)
                assert answer.status_code == 401, (header, method, path)
