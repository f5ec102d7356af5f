"""Three ``tml serve --cluster`` instances on one PostgreSQL fly ten runs on thirty
simulated vehicles; one instance is killed (SIGKILL) while its runs fly, and the others
continue them from their stored journals (docs/serve.md, "Beyond one machine").

Marker ``cluster`` (``pytest -m cluster``, run by .ci/run); skipped with the reason where
PostgreSQL cannot be started. Every process is started here and stopped by its pid. The
verdict waits for states (a run ended, a vehicle on the ground) with hang guards only; the
simulator writes who sent each vehicle each message (``python -m sitl --heard``), which is
what says that no vehicle heard two instances at once. The takeover times measured are
written to test-artifacts/cluster-takeover.md, not asserted on.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from serving import postgresql

# A hang guard, not a time limit: about 90 s on two busy cores, above the suite's 120 s
# per test when the machine is slower still.
pytestmark = [pytest.mark.cluster, pytest.mark.timeout(900)]

ROOT = Path(__file__).resolve().parent.parent
ARTIFACT = ROOT / "test-artifacts" / "cluster-takeover.md"
RUNS = 10
PER_RUN = 3
VEHICLES = RUNS * PER_RUN + PER_RUN  # and one run with roles, which is not continued
INSTANCES = ("alpha", "bravo", "charlie")
# Every instance sends as system 255, the ground station the vehicles' GCS failsafe
# hears; each has its own MAVLink component id, which tells them apart.
SOURCE_SYSTEM = 255
COMPONENT = {"alpha": 25, "bravo": 26, "charlie": 27}
VICTIM = "alpha"
SPEEDUP = 4.0
LEASE = 3.0
# The vehicles' own GCS failsafe, in vehicle seconds: 20 s at 4x is 5 s of wall time, as
# ArduCopter's default FS_GCS_TIMEOUT of 5 s at 1x; the 3 s lease is well inside it.
FS_GCS_TIMEOUT = 5.0 * SPEEDUP
HANG = 150.0  # s: a hang guard, not a time limit of the verdict

DOC = (ROOT / "docs" / "serve.md").read_text(encoding="utf-8")

MISSION = b"""<mission name="Cluster hop">
  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/></action></task>
  <task name="Out">
    <action name="GO_TO_POINT"><argument name="point" value="(60,0,10)"/></action>
  </task>
  <task name="Back">
    <action name="GO_TO_POINT"><argument name="point" value="(0,0,10)"/></action>
  </task>
  <task name="Down"><action name="LAND"/></task>
</mission>
"""
# The same flown by a role: a run that a survivor cannot continue (POST /runs/{id}/continue
# refuses roles), whose vehicles a survivor sends home instead.
ROLES_MISSION = MISSION.replace(
    b'<task name="Up">',
    b'<roles><role name="fleet" count="3"/></roles>\n  <task name="Hop" role="fleet">\n'
    b'  <task name="Up">').replace(b"</mission>", b"</task>\n</mission>")


def recipe() -> tuple[list[str], list[str]]:
    """The arguments of the simulator and of the first instance in the recipe of
    docs/serve.md, "Beyond one machine"."""
    section = DOC[DOC.index("## Beyond one machine"):]
    found = re.search(r"```sh\n(.*?)```", section, re.S)
    assert found, "docs/serve.md has the cluster's recipe"
    lines = found.group(1).splitlines()
    sim = next(line for line in lines if line.startswith("python -m sitl "))
    serve = next(line for line in lines if line.startswith("tml serve --cluster "))
    return shlex.split(sim)[3:], shlex.split(serve.replace("$CONNECT", "").rstrip(" &"))[2:]


def setting(args: list[str], option: str, value: object = None) -> list[str]:
    """``args`` with ``option``'s value replaced (asserting it is there)."""
    assert option in args, (option, args)
    at = args.index(option) + 1
    return [*args[:at], str(value), *args[at + 1:]]


def until(what: str, done: Callable[[], Any], guard: float = HANG) -> Any:
    """Wait for ``done`` to give something true; a hang guard only."""
    end = time.monotonic() + guard
    while True:
        found = done()
        if found:
            return found
        if time.monotonic() > end:
            raise AssertionError(f"hung waiting for {what}")
        time.sleep(0.1)


def call(base: str, method: str, path: str, body: object = None,
         content_type: str = "application/json") -> tuple[int, Any]:
    data = None if body is None else (
        body if isinstance(body, bytes) else json.dumps(body).encode())
    request = urllib.request.Request(base + path, data=data, method=method,
                                     headers={"Content-Type": content_type})
    try:
        with urllib.request.urlopen(request, timeout=30) as answer:
            return answer.status, json.loads(answer.read() or b"null")
    except urllib.error.HTTPError as error:
        return error.code, json.loads(error.read() or b"null")


class Process:
    """A process started here, its output read line by line from a file."""

    def __init__(self, argv: list[str], out: Path) -> None:
        self.out = out
        self.file = out.open("w")
        self.popen = subprocess.Popen(argv, stdout=self.file, stderr=subprocess.STDOUT,
                                      cwd=ROOT, env={**os.environ, "PYTHONUNBUFFERED": "1"})

    def lines(self) -> list[str]:
        return self.out.read_text().splitlines()

    def wait_line(self, what: str, match: Callable[[str], bool]) -> str:
        def found() -> str | None:
            if self.popen.poll() is not None:
                raise AssertionError(f"{what}: exited {self.popen.returncode}:\n"
                                     + "\n".join(self.lines()[-20:]))
            return next((line for line in self.lines() if match(line)), None)

        return str(until(what, found))

    def stop(self, sig: int = signal.SIGTERM) -> None:
        if self.popen.poll() is None:
            os.kill(self.popen.pid, sig)
            try:
                self.popen.wait(60)
            except subprocess.TimeoutExpired:
                os.kill(self.popen.pid, signal.SIGKILL)
                self.popen.wait()
        self.file.close()


@pytest.fixture(scope="module")
def database() -> Iterator[str]:
    try:
        with postgresql() as url:
            yield url.replace("postgresql+psycopg://", "postgresql://")
    except LookupError as why:
        pytest.skip(f"no PostgreSQL server for the cluster: {why}")


def test_a_killed_instance_has_its_runs_continued_and_no_vehicle_hears_two(
        database: str, tmp_path: Path) -> None:
    heard = tmp_path / "heard.jsonl"
    processes: list[Process] = []
    try:
        # The recipe's commands as written, on free ports, in this test's database.
        sim_args, serve_args = recipe()
        assert setting(sim_args, "--vehicles", VEHICLES) == sim_args
        assert setting(sim_args, "--speedup", f"{SPEEDUP:g}") == sim_args
        assert f"FS_GCS_TIMEOUT={FS_GCS_TIMEOUT:g}" in sim_args
        assert setting(serve_args, "--lease", f"{LEASE:g}") == serve_args
        sim = Process([sys.executable, "-m", "sitl", *sim_args, "--tcp-base-port", "0",
                       "--heard", str(heard)], tmp_path / "sim.out")
        processes.append(sim)
        sim.wait_line("the simulator", lambda line: line.startswith(f"vehicle {VEHICLES}:"))
        ports = [line.split("tcp:127.0.0.1:")[1].split(" ")[0] for line in sim.lines()
                 if line.startswith("vehicle ")]
        services: dict[str, Process] = {}
        for name in INSTANCES:
            assert setting(serve_args, "--source-system", SOURCE_SYSTEM) == serve_args
            args = setting(setting(setting(setting(
                serve_args, "--database", database), "--instance", name),
                "--source-component", COMPONENT[name]), "--port", 0)
            argv = [sys.executable, "-m", "tml", "serve", *args, "--data",
                    str(tmp_path / name), "--ready-timeout", "60"]
            argv += [arg for port in ports for arg in ("--connect", f"tcp:127.0.0.1:{port}")]
            services[name] = Process(argv, tmp_path / f"{name}.out")
            processes.append(services[name])
        bases = {}
        for name, process in services.items():
            banner = process.wait_line(f"instance {name}",
                                       lambda line: line.startswith("tml serve: http://"))
            bases[name] = banner.split(" ")[2].rstrip("/")
        for name, process in services.items():
            process.wait_line(f"{name} joined", lambda line: "joined the cluster" in line)
        joined = time.time()
        before = _database_counts(database)
        cpu_before = {name: _cpu(p.popen.pid) for name, p in services.items()}

        status, mission = call(bases["bravo"], "POST", "/missions?filename=hop.xml", MISSION,
                               "application/xml")
        assert status == 201, mission
        started: dict[str, str] = {}  # run id -> the instance asked to fly it
        for index in range(RUNS):
            name = INSTANCES[index % len(INSTANCES)]
            vehicles = list(range(index * PER_RUN + 1, (index + 1) * PER_RUN + 1))
            status, run = call(bases[name], "POST", "/runs",
                               {"mission": mission["id"], "vehicles": vehicles})
            assert status == 201, run
            assert run["instance"] == name
            started[run["id"]] = name
        victims = [run_id for run_id, name in started.items() if name == VICTIM]
        status, roles = call(bases["bravo"], "POST", "/missions?filename=roles.xml",
                             ROLES_MISSION, "application/xml")
        assert status == 201, roles
        status, run = call(bases[VICTIM], "POST", "/runs", {
            "mission": roles["id"], "vehicles": list(range(VEHICLES - PER_RUN + 1,
                                                           VEHICLES + 1))})
        assert status == 201, run
        with_roles = run["id"]

        # Every instance answers for every run; a control of another's run reaches it.
        other = next(r for r, name in started.items() if name == "charlie")
        status, seen = call(bases["bravo"], "GET", f"/runs/{other}")
        assert status == 200 and seen["instance"] == "charlie"
        until("charlie's run flying", lambda: call(
            bases["bravo"], "GET", f"/runs/{other}")[1]["status"] == "running")
        status, paused = call(bases["bravo"], "POST", f"/runs/{other}/pause")
        assert status == 200 and paused["status"] == "paused", paused
        status, again = call(bases["bravo"], "POST", f"/runs/{other}/pause")
        assert status == 409 and "paused" in again["error"], again  # charlie's refusal
        status, resumed = call(bases["bravo"], "POST", f"/runs/{other}/resume")
        assert status == 200 and resumed["status"] == "running", resumed

        def flying() -> bool:
            """Every vehicle of the victim's runs has taken off and is not landing yet (a
            window of about 6 s of wall time: two 60 m legs at 4x)."""
            for run_id in [*victims, with_roles]:
                _status, run = call(bases[VICTIM], "GET", f"/runs/{run_id}")
                prefix = "Hop/" if run_id == with_roles else ""
                if run["status"] != "running" or any(
                        states.get(f"{prefix}Up") != "done"
                        or states.get(f"{prefix}Down") != "pending"
                        for vehicle, states in run["tasks"].items() if vehicle):
                    return False
            return True

        until("the victim's runs flying their legs", flying)
        killed = time.time()
        services[VICTIM].stop(signal.SIGKILL)

        def ended() -> list[dict[str, Any]] | None:
            _status, runs = call(bases["bravo"], "GET", "/runs")
            if any(run["status"] in ("waiting", "running", "paused") for run in runs):
                return None
            continued = {run["options"].get("continues") for run in runs}
            if not all(run_id in continued for run_id in victims):
                return None
            if not any(run["options"].get("not_continued") for run in runs):
                return None
            return list(runs)

        runs = until("every run ended", ended)
        by_id = {run["id"]: run for run in runs}
        continuation = {run["options"]["continues"]: run for run in runs
                        if run["options"].get("continues")}
        for run_id, name in started.items():
            run = by_id[run_id]
            if name == VICTIM:
                assert run["status"] == "interrupted", run
                run = continuation[run_id]
                assert run["instance"] in ("bravo", "charlie")
            assert run["status"] == "completed", run
            assert run["exit_code"] == 0
        # The run with roles is interrupted, not continued: its vehicles were sent home.
        assert by_id[with_roles]["status"] == "interrupted"
        assert "roles" in by_id[with_roles]["options"]["not_continued"]
        assert with_roles not in continuation

        def landed() -> bool:
            _status, vehicles = call(bases["charlie"], "GET", "/vehicles")
            return all(not v["armed"] and v["landed"] for v in vehicles)

        until("every vehicle landed and disarmed", landed)
        seconds = time.time() - joined
        measured = {
            "seconds": seconds,
            "cpu": {name: (_cpu(services[name].popen.pid) - cpu_before[name]) / seconds
                    for name in INSTANCES if name != VICTIM},
            "database": {key: (value - before[key]) / seconds
                         for key, value in _database_counts(database).items()}}
        table = _heard(heard, killed, [*victims, with_roles], by_id)
        # The database says the same: each of those vehicles was handed from the killed
        # instance to the one heard next, with the next fencing token.
        handovers = _handovers(database)
        for row in table:
            token, owner = handovers[row["vehicle"]][-1][:2]
            assert (owner, handovers[row["vehicle"]][-1][2]) == (row["new"], VICTIM), row
            assert [t for t, _o, _p in handovers[row["vehicle"]]] == list(range(1, token + 1))
    finally:
        for process in reversed(processes):
            process.stop()
    _write_table(table, measured)


def _cpu(pid: int) -> float:
    """CPU seconds (user and system) a process has used."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _handovers(url: str) -> dict[int, list[tuple[int, str, str | None]]]:
    """Each vehicle's handovers in the lease table: (token, new owner, old owner)."""
    import psycopg

    found: dict[int, list[tuple[int, str, str | None]]] = {}
    with psycopg.connect(url) as conn:
        for vehicle, token, owner, previous in conn.execute(
                "SELECT vehicle, token, owner, previous FROM lease_handovers "
                "ORDER BY vehicle, token"):
            found.setdefault(vehicle, []).append((token, owner, previous))
    return found


def _database_counts(url: str) -> dict[str, int]:
    """The database's committed transactions and rows written so far."""
    import psycopg

    with psycopg.connect(url) as conn:
        row = conn.execute("SELECT xact_commit, tup_inserted, tup_updated FROM "
                           "pg_stat_database WHERE datname = current_database()").fetchone()
    assert row is not None
    return {"commits": int(row[0]), "inserted": int(row[1]), "updated": int(row[2])}


def _heard(path: Path, killed: float, victims: list[str],
           runs: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """Check who spoke to each vehicle, from the start (the instances open their links
    without a word to the vehicles); the takeover table."""
    name_of = {component: name for name, component in COMPONENT.items()}
    senders: dict[int, list[tuple[str, float, float]]] = {}
    for line in path.read_text().splitlines():
        record = json.loads(line)
        # Only the instances speak to the vehicles.
        assert record["src"] == SOURCE_SYSTEM and record["comp"] in name_of, record
        senders.setdefault(record["v"], []).append(
            (name_of[record["comp"]], record["wall"], record["t"]))
    victim_vehicles = {v for run_id in victims for v in runs[run_id]["vehicles"]}
    table: list[dict[str, Any]] = []
    for vehicle in range(1, VEHICLES + 1):
        heard = senders.get(vehicle, [])
        changes = [heard[0][0]] if heard else []
        for name, _wall, _t in heard:
            if name != changes[-1]:
                changes.append(name)
        if vehicle in victim_vehicles:
            # The victim, then one survivor: never two at once, nor back and forth.
            assert len(changes) == 2 and changes[0] == VICTIM, (vehicle, changes)
            last_old = max(t for name, _w, t in heard if name == VICTIM)
            first_new = next((w, t) for name, w, t in heard if name == changes[1])
            assert first_new[0] > killed
            table.append({"vehicle": vehicle, "old": VICTIM, "new": changes[1],
                          "wall": first_new[0] - killed, "vehicle_s": first_new[1] - last_old})
        else:
            assert len(changes) == 1 and changes[0] != VICTIM, (vehicle, changes)
    for row in table:
        row["run"] = next(r for r in victims if row["vehicle"] in runs[r]["vehicles"])
        row["did"] = "sent it home (RTL)" if runs[row["run"]]["options"].get(
            "not_continued") else "continued the run"
    return table


def _write_table(table: list[dict[str, Any]], measured: dict[str, Any]) -> None:
    ARTIFACT.parent.mkdir(exist_ok=True)
    lines = ["# Cluster takeover (tests/test_serve_cluster.py)", "",
             f"Three `tml serve --cluster` instances, {VEHICLES} simulated vehicles at "
             f"{SPEEDUP:g}x, {RUNS} runs of {PER_RUN} vehicles and one with roles (which is "
             f"not continued); instance {VICTIM} killed (SIGKILL) while its runs flew "
             "their legs. "
             f"Lease {LEASE:g} s, renewed every {LEASE / 3:g} s. Takeover: from the SIGKILL "
             "to the first message the new owner sent the vehicle (wall seconds), and from "
             "the last message of the old owner to it (vehicle seconds).", "",
             "| run | vehicle | old owner | new owner | what it did | takeover wall s | "
             "silence vehicle s |", "|---|---|---|---|---|---|---|"]
    lines += [f"| {row['run']} | {row['vehicle']} | {row['old']} | {row['new']} | "
              f"{row['did']} | {row['wall']:.2f} | {row['vehicle_s']:.2f} |" for row in table]
    for did in sorted({row["did"] for row in table}):
        walls = sorted(row["wall"] for row in table if row["did"] == did)
        lines += ["", f"Takeover wall seconds ({did}): min {walls[0]:.2f}, median "
                      f"{walls[len(walls) // 2]:.2f}, max {walls[-1]:.2f}."]
    cpu = ", ".join(f"{name} {share:.0%}" for name, share in measured["cpu"].items())
    per_second = measured["database"]
    lines += ["", f"From the join to every vehicle landed ({measured['seconds']:.0f} s): CPU "
                  f"of a core per surviving instance ({VEHICLES} vehicle links each): {cpu}; the "
                  f"database: {per_second['commits']:.0f} commits/s, "
                  f"{per_second['inserted']:.0f} rows inserted/s, "
                  f"{per_second['updated']:.0f} rows updated/s (three instances, then two, "
                  f"and the test's own reads)."]
    ARTIFACT.write_text("\n".join(lines) + "\n")
