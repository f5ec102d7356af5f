"""``tml serve`` as a command: the curl examples of docs/serve.md run as written against
``tml serve --sim --vehicles 2``, a service killed in flight marks the run interrupted
when it starts again, SIGTERM leaves the vehicles safe, and the refusals to start.
"""

from __future__ import annotations

import contextlib
import json
import re
import shlex
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import IO

import httpx
import pytest
from serving import FAST_SIM, ROOT, SHORT, free_port

from tests.process_lines import simulator
from tml.commands.cli import main
from tml.serve.storage import ACTIVE

DOC = (ROOT / "docs" / "serve.md").read_text(encoding="utf-8")
FAST = ["--speedup", "10", *[f for name, value in FAST_SIM.items()
                             for f in ("--sim-param", f"{name}={value:g}")]]


class Server:
    """``tml serve`` in its own process on a free port."""

    def __init__(self, args: list[str], data: Path) -> None:
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.process = subprocess.Popen(
            [sys.executable, "-m", "tml", "serve", *args, "--port", str(self.port),
             "--data", str(data)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            text=True, cwd=ROOT)
        assert self.process.stdout is not None
        self.said = ""  # what it says before its banner, said once the vehicles are open
        while not (line := self.process.stdout.readline()).startswith("tml serve: http://"):
            assert line, self.said
            self.said += line
        # What it says from now on is read as it comes: a pipe nobody reads fills up (64 kB
        # on Linux), and the service, blocked on a write, would stop answering mid-test.
        self.later: list[str] = []
        self._reader = threading.Thread(target=self._read, args=(self.process.stdout,),
                                        daemon=True)
        self._reader.start()
        with httpx.Client() as client:  # the banner comes just before the server binds
            while True:
                try:
                    client.get(f"{self.url}/status")
                    break
                except httpx.TransportError:
                    assert self.process.poll() is None, "".join(self.later)

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            self.later.append(line)

    def __enter__(self) -> Server:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.process.poll() is None:  # a test that failed half way: stop it all the same
            self.process.kill()
            self.process.wait(timeout=60)
        self._reader.join(timeout=60)

    def stop(self, sig: int = signal.SIGTERM) -> tuple[int, str]:
        """Send ``sig``; the exit code and what it said after its banner."""
        self.process.send_signal(sig)
        self.process.wait(timeout=120)
        self._reader.join(timeout=60)
        return self.process.returncode, "".join(self.later)


@pytest.fixture
def data(tmp_path: Path) -> Path:
    return tmp_path / "data"


@pytest.fixture
def server(data: Path) -> Iterator[Server]:
    command = re.search(r"```\n(tml serve --sim --vehicles 2)\n```", DOC)
    assert command, "docs/serve.md shows how to start the service the examples use"
    with Server([*shlex.split(command.group(1))[2:], *FAST], data) as found:
        yield found


@pytest.mark.timeout(900)  # several flights of the service's simulator: a hang guard only
def test_the_curl_examples_of_the_docs_work_as_written(server: Server, tmp_path: Path) -> None:
    api = DOC[DOC.index("## The API"):DOC.index("## The page")]
    blocks = re.findall(r"```sh\n(.*?)```", api, re.S)
    assert len(blocks) >= 8
    state = tmp_path / "state.sh"
    state.write_text("")
    outputs = []
    names = sorted(set(re.findall(r"^([A-Z]+)=", "\n".join(blocks), re.M)))
    for block in blocks:
        # The examples as written, on this test's port; the shell variables they set
        # (MISSION, RUN ...) are carried from one block to the next.
        script = (f"set -euo pipefail\nsource {state}\n"
                  + block.replace("127.0.0.1:8080", f"127.0.0.1:{server.port}")
                  + f"\ndeclare -p {' '.join(names)} > {state} 2>/dev/null || true\n")
        try:
            done = subprocess.run(["bash", "-c", script], capture_output=True, text=True,
                                  cwd=tmp_path if "flight.jsonl" in block else ROOT,
                                  timeout=600)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{block}\nstill running after 600 s; the service said last:\n"
                        + "".join(server.later[-40:]))
        assert done.returncode == 0, (block, done.stdout, done.stderr, server.later[-40:])
        outputs.append(done.stdout)
    # What the docs show of the answers is what the service answers.
    shown = json.loads(re.search(r"```json\n(.*?)```", api, re.S).group(1))
    invalid = next(out for block, out in zip(blocks, outputs, strict=True)
                   if "unknown_action.xml" in block)
    assert json.loads(invalid) == shown
    refused = next(out for block, out in zip(blocks, outputs, strict=True) if "RUN=$(" in block)
    assert '"error":"vehicle 1 is held by run ' in refused
    stream = next(out for block, out in zip(blocks, outputs, strict=True) if "/stream" in block)
    assert "event: end" in stream, stream
    assert json.loads(stream.split("data: ")[-1])["status"] == "completed", stream
    patrol = next(out for block, out in zip(blocks, outputs, strict=True)
                  if "fenced_patrol.xml" in block)
    (safeguard,) = [json.loads(line) for line in patrol.splitlines()
                    if '"kind":"safeguard"' in line]
    assert safeguard["ok"] is True, patrol
    assert safeguard["message"].startswith("on the vehicle: inclusion polygon of 4 corners; "
                                           "exclusion circle water tower; FENCE_ALT_MAX 40 m")
    assert "2 rally points" in safeguard["message"]
    log = [json.loads(line) for line in (tmp_path / "flight.jsonl").read_text().splitlines()]
    assert [c["control"] for c in log if c["kind"] == "control"] == ["pause", "resume", "jump"]
    assert log[-1]["kind"] == "run" and log[-1]["exit_code"] == 0
    with httpx.Client(base_url=server.url) as client:
        runs = client.get("/runs").json()
        assert [r["status"] for r in runs] == ["completed", "aborted", "aborted"]
        assert client.get("/missions").json() == []
    code, out = server.stop()
    assert code == 0, out


def start_a_run(client: httpx.Client) -> str:
    mission = client.post("/missions", content=SHORT,
                          headers={"Content-Type": "application/xml"}).json()["id"]
    return str(client.post("/runs", json={"mission": mission}).json()["id"])


def test_a_run_flying_when_the_service_was_killed_is_interrupted_after_a_restart(
        data: Path) -> None:
    with Server(["--sim", *FAST], data) as first, \
            httpx.Client(base_url=first.url, timeout=30) as client:
        run = start_a_run(client)
        while (status := client.get(f"/runs/{run}").json()["status"]) == "waiting":
            pass
        assert status == "running", "the run is killed in flight, not after it"
        with contextlib.closing(sqlite3.connect(data / "tml.sqlite")) as db:
            while not db.execute("SELECT count(*) FROM log_lines WHERE run_id = ?",
                                 (run,)).fetchone()[0]:
                pass  # the log is stored in batches: wait for the first
        first.stop(signal.SIGKILL)  # no chance to land, nor to say anything
    with Server(["--sim", *FAST], data) as again, \
            httpx.Client(base_url=again.url, timeout=30) as client:
        assert f"run {run} was flying when the service stopped: marked interrupted" \
            in again.said
        found = client.get(f"/runs/{run}").json()
        assert (found["status"], found["exit_code"]) == ("interrupted", None)
        assert "stopped while the run was flying" in found["reason"]
        assert client.get(f"/runs/{run}/log").text.count("\n") >= 1, "its log so far is kept"
        assert client.get("/vehicles/1").json()["run"] is None
        code, out = again.stop()
        assert code == 0, out


def test_a_vehicle_at_a_connection_address_flies_a_run_of_the_api(data: Path) -> None:
    with simulator("--fast-boot", "--speedup", "10") as port, \
            Server(["--connect", f"tcp:127.0.0.1:{port}", "--timeout", "60"], data) as server, \
            httpx.Client(base_url=server.url, timeout=30) as client:
        assert f"tml serve: waiting up to 60 s for a vehicle at tcp:127.0.0.1:{port}" \
            in server.said
        # The pre-flight policy of tml run: the vehicle's own failsafe is read.
        assert "tml serve: warning: vehicle 1: FS_GCS_ENABLE is 0" in server.said
        assert client.get("/vehicles").json()[0]["id"] == 1
        run = start_a_run(client)
        # A run is "waiting" until its vehicle is ready, then "running": wait for its end.
        while (found := client.get(f"/runs/{run}").json())["status"] in ACTIVE:
            pass
        assert (found["status"], found["exit_code"]) == ("completed", 0), found
        code, out = server.stop()
        assert code == 0, out


def test_a_vehicle_without_a_gcs_failsafe_is_refused_when_one_is_required(
        data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["serve", "--sim", *FAST, "--require-gcs-failsafe", "--port", "0",
                 "--data", str(data)])
    err = capsys.readouterr().err
    assert code == 4, err
    assert ("tml serve: vehicle 1: FS_GCS_ENABLE is 0: the vehicle does nothing by itself "
            "when it loses this ground station") in err
    assert "tml serve: not flown (--require-gcs-failsafe)" in err


def test_an_address_without_its_scheme_is_a_usage_error(
        data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["serve", "--connect", "127.0.0.1:5760", "--port", "0",
                 "--data", str(data)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("tml serve: --connect 127.0.0.1:5760: not an address: a network "
                          "address starts with its scheme"), err
    assert len(err.strip().splitlines()) == 1


def test_a_link_that_hears_several_vehicles_needs_a_sysid(
        data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    address = f"udpin:127.0.0.1:{port}"
    with simulator("--vehicles", "2", "--frame", "copter,rover", "--fast-boot", "--speedup",
                   "10", "--out", f"udp:127.0.0.1:{port}"):
        code = main(["serve", "--connect", address, "--port", "0", "--data", str(data)])
        err = capsys.readouterr().err
        assert code == 2, err
        assert err.strip().splitlines()[-1] == (
            f"tml serve: {address}: vehicles with system ids 1, 2 heard: say which to fly "
            "with --sysid N (repeated for several: --sysid 1 --sysid 2)")
        with Server(["--connect", address, "--sysid", "2", "--timeout", "60"], data) as server:
            vehicles = httpx.get(f"{server.url}/vehicles", timeout=30).json()
            assert [(v["id"], v["vehicle_type"]) for v in vehicles] == [(1, "rover")]
            code, out = server.stop()
            assert code == 0, out


def test_sigterm_sends_a_flying_vehicle_to_its_safe_state_first(data: Path) -> None:
    with Server(["--sim", *FAST], data) as server, \
            httpx.Client(base_url=server.url, timeout=30) as client:
        run = start_a_run(client)
        while not any(r["kind"] == "task" and r["task"] == "Out" for r in
                      map(json.loads, client.get(f"/runs/{run}/log").text.splitlines())):
            pass
        code, out = server.stop(signal.SIGTERM)
        assert code == 0, out
        assert f"run {run}: vehicle 1: vehicle in the air: ReturnToLaunch" in out
    with Server(["--sim", *FAST], data) as again, \
            httpx.Client(base_url=again.url, timeout=30) as client:
        # What the first one left in the database.
        found = client.get(f"/runs/{run}").json()
        assert (found["status"], found["exit_code"]) == ("aborted", 3)
        assert "the service is stopping" in found["reason"]
        safety = [json.loads(line) for line in client.get(f"/runs/{run}/log").text.splitlines()
                  if '"kind":"safety"' in line]
        assert safety[0]["request"] == "ReturnToLaunch"


def test_without_a_token_only_loopback_is_served(capsys: pytest.CaptureFixture[str],
                                                 tmp_path: Path) -> None:
    assert main(["serve", "--sim", "--host", "0.0.0.0", "--data", str(tmp_path)]) == 2
    assert "refusing to serve on 0.0.0.0 without a token" in capsys.readouterr().err
    empty = tmp_path / "token"
    empty.write_text("\n")
    assert main(["serve", "--sim", "--token-file", str(empty), "--data", str(tmp_path)]) == 2
    assert "the token file is empty" in capsys.readouterr().err


def test_a_database_that_cannot_be_opened_is_one_clear_error(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["serve", "--sim", "--database", "postgresql://nobody@127.0.0.1:1/none",
                 "--data", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("tml serve: cannot open the database postgresql+psycopg://nobody@")
    assert "Traceback" not in err


@pytest.mark.parametrize(("option", "value", "said"), [
    ("--source-system", "0", "expected a MAVLink system id from 1 to 255, got '0'"),
    ("--source-component", "256", "expected a MAVLink component id from 1 to 255, got '256'"),
    ("--source-component", "gcs", "expected a MAVLink component id from 1 to 255, got 'gcs'"),
])
def test_a_mavlink_id_out_of_range_is_refused_with_why(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, option: str, value: str,
        said: str) -> None:
    assert main(["serve", "--sim", option, value, "--data", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"argument {option}: {said}" in err and "Traceback" not in err
