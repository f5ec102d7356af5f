"""What the tests of ``tml serve`` share: a hangar of fake vehicles on a fake clock, a
hangar of simulated ones, missions, and a throwaway PostgreSQL server.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import socket
import subprocess
import tempfile
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from fake_vehicle import FakeVehicle

from tml.serve.hangar import Hangar
from tml.vehicle import Request, RequestResult, VehicleState
from tml.world import World

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = ROOT / "missions"
DATA = Path(__file__).parent / "data"

# A mission small enough to fly in seconds: up, a leg, down.
SHORT = b"""<mission name="Short hop">
  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/></action></task>
  <task name="Out">
    <action name="GO_TO_POINT"><argument name="point" value="(40,0,10)"/></action>
  </task>
  <task name="Down"><action name="LAND"/></task>
</mission>
"""
# The same with a typo in an action's name.
TYPO = SHORT.replace(b"GO_TO_POINT", b"GO_TO_PIONT")
FAST_SIM = {"SIM_GPS_LOCKTIME": 1.0, "SIM_EKF_GPS_TIME": 2.0}


class _Locked:
    """A fake vehicle behind the hangar's lock (the runs' threads read it while another
    run's wait moves it)."""

    def __init__(self, fake: FakeVehicle, lock: threading.Lock) -> None:
        self.fake, self._lock = fake, lock
        self.vehicle_id = fake.vehicle_id

    def state(self) -> VehicleState:
        with self._lock:
            return self.fake.state()

    def submit(self, request: Request) -> None:
        with self._lock:
            self.fake.submit(request)

    def poll(self) -> list[RequestResult]:
        with self._lock:
            return self.fake.poll()


class FakeHangar(Hangar):
    """Fake vehicles whose time moves by each run's wait while ``flowing`` is set, and
    stands still (the runs wait on their wake events) while it is not."""

    def __init__(self, count: int = 2, flowing: bool = True, **knobs: object) -> None:
        self.fakes = [FakeVehicle(vehicle_id=i + 1, **knobs) for i in range(count)]  # type: ignore[arg-type]
        self._move = threading.Lock()
        self.now = 0.0
        super().__init__([_Locked(f, self._move) for f in self.fakes], lambda: self.now)
        self.flowing = threading.Event()
        if flowing:
            self.flowing.set()
        self._until: Callable[[], bool] | None = None
        self._there = threading.Event()

    def fly_until(self, done: Callable[[], bool], timeout: float = 60.0) -> None:
        """Let time flow until ``done()`` holds, then stop it -- in the step that made it
        hold, however busy the machine (a test's own check would come steps later)."""
        self._there.clear()
        self._until = done
        self.flowing.set()
        assert self._there.wait(timeout), "it never got there"

    def wait(self, wake: threading.Event, timeout: float) -> None:
        if not self.flowing.is_set():
            super().wait(wake, timeout)
            return
        with self._move:
            self.now += timeout
            for fake in self.fakes:
                fake.advance(timeout)
            if self._until is not None and self._until():
                self.flowing.clear()
                self._until = None
                self._there.set()
        wake.clear()


@contextlib.contextmanager
def simulated(vehicles: int = 2, speedup: float = 20.0) -> Iterator[Hangar]:
    """A hangar of simulated vehicles, opened as ``tml serve --sim`` opens them."""
    from tml.run.session import SessionOptions, SimulatorOptions, open_session
    from tml.simulator import open_simulator

    options = SessionOptions(simulator=SimulatorOptions(vehicles=vehicles, speedup=speedup,
                                                        params=FAST_SIM),
                             open_simulator=open_simulator, program="tml serve")
    hangars: list[Hangar] = []

    def notify() -> None:
        for hangar in hangars:
            hangar.notify()

    with open_session(options, World(), notify=notify) as session:
        hangars.append(Hangar(session.vehicles, session.clock))
        yield hangars[0]


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _postgres_bin() -> Path | None:
    for version in sorted(Path("/usr/lib/postgresql").glob("*/bin"), reverse=True):
        if (version / "initdb").exists() and (version / "pg_ctl").exists():
            return version
    return None


@contextlib.contextmanager
def postgresql() -> Iterator[str]:
    """A throwaway PostgreSQL server on 127.0.0.1 (Debian's ``postgresql`` package) for the
    duration; its SQLAlchemy URL. Raises LookupError, saying why, when none can be had."""
    binaries = _postgres_bin()
    if binaries is None:
        raise LookupError("no PostgreSQL server binaries (Debian package postgresql)")
    as_user: list[str] = []
    # Not under pytest's tmp_path: as root the server runs as another user, who must be
    # able to reach its directory.
    data = Path(tempfile.mkdtemp(prefix="tml-pg-"))
    try:
        if os.geteuid() == 0:  # PostgreSQL refuses to run as root: its own user runs it
            # /usr/sbin is not on every root's PATH (env -i, some CI shells).
            runuser = shutil.which("runuser") or shutil.which("runuser", path="/usr/sbin:/sbin")
            if runuser is None:
                raise LookupError("running as root without runuser to start PostgreSQL")
            as_user = [runuser, "-u", "postgres", "--"]
            data.chmod(0o755)
            shutil.chown(data, "postgres")
        port = free_port()
        subprocess.run([*as_user, str(binaries / "initdb"), "-D", str(data / "db"), "-A",
                        "trust", "-U", "tml", "--no-sync"], check=True, capture_output=True)
        started = subprocess.run(
            [*as_user, str(binaries / "pg_ctl"), "-D", str(data / "db"), "-l",
             str(data / "server.log"), "-w", "-o",
             f"-p {port} -k {data} -c listen_addresses=127.0.0.1 -c fsync=off", "start"],
            capture_output=True, text=True)
        if started.returncode != 0:
            raise LookupError(f"PostgreSQL did not start: {started.stderr or started.stdout}")
        try:
            subprocess.run([*as_user, str(binaries / "createdb"), "-h", "127.0.0.1", "-p",
                            str(port), "-U", "tml", "tml"], check=True, capture_output=True)
            yield f"postgresql+psycopg://tml@127.0.0.1:{port}/tml"
        finally:
            subprocess.run([*as_user, str(binaries / "pg_ctl"), "-D", str(data / "db"), "-m",
                            "fast", "-w", "stop"], capture_output=True)
    finally:
        shutil.rmtree(data, ignore_errors=True)


def interrupted_run(storage: Any, fake: FakeVehicle, mission_id: str,
                    run_id: str = "01d01d01d01d", source: bytes = SHORT,
                    until: Callable[[FakeVehicle], bool] | None = None) -> str:
    """A run of ``source`` (SHORT) that a service was flying on ``fake`` when it died when
    ``until(fake)`` held (SHORT: on the leg out): its log in ``storage`` as the service
    stored it, marked ``interrupted``, and the vehicle left flying. The run's id."""
    from tml.engine import Interpreter
    from tml.language.validation import validate_file
    from tml.run.journal import Journal
    from tml.serve.storage import StoredRun

    mission = validate_file("m.xml", source).mission
    assert mission is not None
    engine = Interpreter(mission, [fake.vehicle_id])
    sink = io.StringIO()
    journal = Journal(sink)
    now, out = 0.0, engine.start(0.0, {fake.vehicle_id: fake.state()})
    while not (until or (lambda f: f.position[0] >= 10))(fake):
        for record in out.records:
            journal.write(record.time, record.kind, record.vehicle_id, record.data)
        for request in out.requests:
            fake.submit(request)
        fake.advance(0.1)
        now += 0.1
        out = engine.step(now, {fake.vehicle_id: fake.state()},
                          {fake.vehicle_id: fake.poll()})
    storage.add_run(StoredRun(run_id, mission_id, mission.name, source.decode(),
                              [fake.vehicle_id], "interrupted", "the service stopped", [],
                              None, "local", {"safe_state": "rtl", "profile": "quadcopter",
                                              "force": False}, 1.0, 2.0))
    storage.add_lines(run_id, list(enumerate(sink.getvalue().splitlines(), 1)))
    return run_id


class Served:
    """A service on fake vehicles (their time stands still until a test lets it flow), and
    a client for its API, calling it as http://127.0.0.1; ``storage`` instead of SQLite in
    ``tmp_path``, ``app`` more options of create_app."""

    def __init__(self, tmp_path: Path, token: str | None = None, count: int = 2,
                 storage: Any = None, **app: Any) -> None:
        from fastapi.testclient import TestClient

        from tml.serve.api import create_app
        from tml.serve.service import Service, ServiceOptions
        from tml.serve.storage import Storage, database_url

        self.hangar = FakeHangar(count, flowing=False)
        self.storage = storage or Storage(database_url(None, tmp_path))
        self.service = Service(self.storage, self.hangar, ServiceOptions(stop_timeout=10))
        self.client = TestClient(create_app(self.service, token, **app),
                                 base_url="http://127.0.0.1")

    def __enter__(self) -> Served:
        self.client.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.client.__exit__(*exc)
        self.storage.close()

    def upload(self, data: bytes = SHORT, name: str = "short.xml") -> str:
        answer = self.client.post("/missions", content=data, params={"filename": name},
                                  headers={"Content-Type": "application/xml"})
        assert answer.status_code == 201, answer.text
        return str(answer.json()["id"])

    def start(self, mission: str, **request: object) -> dict[str, Any]:
        answer = self.client.post("/runs", json={"mission": mission, **request})
        assert answer.status_code == 201, answer.text
        return dict(answer.json())

    def finish(self, run_id: str) -> dict[str, Any]:
        """Let time flow until the run has ended; the run."""
        self.hangar.flowing.set()
        live = self.service.live(run_id)
        assert live is None or live.join(60), "the run did not end"
        return dict(self.client.get(f"/runs/{run_id}").json())
