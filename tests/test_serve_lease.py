"""The cluster's leases, fence and control channel (tml.serve.lease, tml.serve.cluster,
tml.serve.forward) against a real PostgreSQL server (Debian's ``postgresql`` package;
skipped with the reason where there is none). Leases expire by the server's clock: a test
waits for the state it needs (an expiry) with a hang guard, never for a set time."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
import sqlalchemy as sa
from serving import postgresql

from tml.serve.cluster import ClusterHangar, FailsafeMissing, VehicleLeased
from tml.serve.forward import Forwarder, Unanswered
from tml.serve.lease import ClusterError, Leases, Taken
from tml.serve.storage import Storage, StoredRun


@pytest.fixture(scope="module")
def database() -> Iterator[str]:
    try:
        with postgresql() as url:
            yield url
    except LookupError as why:
        pytest.skip(str(why))


@pytest.fixture
def engine(database: str) -> Iterator[sa.Engine]:
    storage = Storage(database)  # the runs table, as a service makes it
    with storage.engine.begin() as db:
        for table in ("runs", "log_lines", "cluster_instances", "vehicle_leases",
                      "lease_handovers"):
            db.execute(sa.text(f"DROP TABLE IF EXISTS {table}"))
    storage.close()
    storage = Storage(database)
    yield storage.engine
    storage.close()


def until(done: Callable[[], bool], guard: float = 20.0) -> None:
    """Wait for ``done`` (a hang guard, not a timing assertion)."""
    end = time.monotonic() + guard
    while not done():
        assert time.monotonic() < end, "state not reached"
        time.sleep(0.02)


def expire(engine: sa.Engine, name: str) -> None:
    """The lease of instance ``name`` runs out now, as if it had stopped renewing it."""
    with engine.begin() as db:
        db.execute(sa.text("UPDATE cluster_instances SET expires = clock_timestamp() - "
                           "interval '1 millisecond' WHERE name = :name"), {"name": name})


def test_an_instance_name_is_held_by_one_live_process(engine: sa.Engine) -> None:
    # Both leases are long: each runs out only when the test says so, however busy the
    # machine.
    first, second = Leases(engine, "a", lease=30.0), Leases(engine, "a", lease=30.0)
    assert first.join()
    assert not second.join()  # the first one's lease runs
    expire(engine, "a")
    until(second.join)  # ... until it expires: a restarted process gets the name
    assert not first.renew()  # and the first one's session is over for good
    assert second.renew()


def test_a_vehicle_is_owned_by_one_instance_until_its_lease_expires(
        engine: sa.Engine) -> None:
    a, b = Leases(engine, "a", lease=30.0), Leases(engine, "b", lease=30.0)
    assert a.join() and b.join()
    taken = a.take(7)
    assert taken is not None and taken.token == 1 and taken.previous is None
    assert a.take(7) == Taken(7, 1, "a")  # taking it again changes nothing
    assert b.take(7) is None
    assert b.owners([7, 8]) == {7: "a"}
    expire(engine, "a")
    until(lambda: b.take(7) is not None)  # a stopped renewing: b takes it over
    assert b.owners([7]) == {7: "b"}
    assert a.take(7) is None and not a.renew()
    with engine.connect() as db:
        handovers = db.execute(sa.text(
            "SELECT token, owner, previous FROM lease_handovers WHERE vehicle = 7 "
            "ORDER BY token")).all()
    assert [tuple(h) for h in handovers] == [(1, "a", None), (2, "b", "a")]


def test_a_released_vehicle_is_free_at_once_and_leaving_frees_every_one(
        engine: sa.Engine) -> None:
    a, b = Leases(engine, "a", lease=30.0), Leases(engine, "b", lease=30.0)
    assert a.join() and b.join()
    assert a.take(1) and a.take(2)
    a.release(1)
    assert b.take(1) == Taken(1, 2, None)  # nobody owned it: a gave it back
    a.leave()
    assert b.take(2) == Taken(2, 2, None)
    assert b.live_instances() == {"b": 255}


def test_two_instances_taking_one_vehicle_at_once_get_it_once(engine: sa.Engine) -> None:
    instances = [Leases(engine, f"i{n}", lease=30.0) for n in range(4)]
    assert all(i.join() for i in instances)
    won: list[str] = []
    start = threading.Barrier(len(instances))

    def take(leases: Leases) -> None:
        start.wait()
        if leases.take(3) is not None:
            won.append(leases.name)

    threads = [threading.Thread(target=take, args=(i,)) for i in instances]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(won) == 1


def test_the_runs_of_an_expired_instance_are_adopted_by_one_survivor(
        engine: sa.Engine, database: str) -> None:
    storage = Storage(database)
    dead, one, two = (Leases(engine, name, lease=30.0) for name in ("dead", "one", "two"))
    assert dead.join() and one.join() and two.join()
    for vehicle, (run_id, instance, status) in enumerate(
            (("r1", "dead", "running"), ("r2", "one", "running"),
             ("r3", "dead", "completed")), start=1):
        storage.add_run(StoredRun(run_id, "m", "M", "<mission/>", [vehicle], status, "", [],
                                  None, instance, {}, time.time(), None))
    assert one.orphans() == []  # its lease holds (for 30 s: however slow this machine is)
    expire(engine, "dead")  # ... and now "dead" has stopped renewing it, and it ran out
    assert one.orphans() == ["r1"]
    assert two.adopt("r1", "its instance died", time.time())
    assert not one.adopt("r1", "its instance died", time.time())
    stored = storage.run("r1")
    assert stored is not None and stored.status == "interrupted"
    # What the dead instance still writes of it changes nothing.
    storage.update_run("r1", status="failed", reason="late", ended=time.time())
    assert storage.run("r1").status == "interrupted"  # type: ignore[union-attr]
    # A process restarted under a live name adopts what its predecessor flew.
    assert one.orphans(own=True) == ["r2"]
    # r1's vehicle is a survivor's to go on with (unless r1 was interrupted long ago) ...
    assert one.in_runs(since=0.0) == {1, 2}
    assert one.in_runs(since=time.time() + 60) == {2}
    # ... and once r1 is continued (here on vehicle 4), the continuation's.
    storage.add_run(StoredRun("r4", "m", "M", "<mission/>", [4], "running", "", [], None,
                              "two", {"continues": "r1"}, time.time(), None))
    assert one.in_runs(since=0.0) == {2, 4}
    # A run the survivor cannot go on with (roles) is given up: its vehicles are no run's.
    storage.add_run(StoredRun("r5", "m", "M", "<mission/>", [5], "interrupted", "", [],
                              None, "dead", {"safe_state": "rtl"}, time.time(), time.time()))
    assert one.in_runs(since=0.0) == {2, 4, 5}
    one.give_up("r5", "run r5 has roles")
    assert one.in_runs(since=0.0) == {2, 4}
    assert storage.run("r5").options == {  # type: ignore[union-attr]
        "safe_state": "rtl", "not_continued": "run r5 has roles"}
    storage.close()


def test_a_vehicle_whose_owner_died_is_abandoned_for_as_long_as_it_stays_so(
        engine: sa.Engine) -> None:
    dead, alive = Leases(engine, "dead", lease=30.0), Leases(engine, "alive", lease=30.0)
    assert dead.join() and alive.join()
    assert dead.take(5) and alive.take(6)
    assert alive.abandoned() == {}  # its lease holds (for 30 s: however slow this machine is)
    expire(engine, "dead")
    until(lambda: 5 in alive.abandoned())
    assert list(alive.abandoned()) == [5]
    until(lambda: alive.abandoned()[5] > 0.3)  # seconds since, by the server's clock
    assert alive.take(5) is not None and alive.abandoned() == {}


class _Link:
    gate: Callable[[int], bool] | None = None


class _Vehicle:
    def __init__(self, vehicle_id: int, system_id: int, link: _Link,
                 failsafe: float | None = 1.0) -> None:
        self.vehicle_id, self.system_id, self.link = vehicle_id, system_id, link
        self.failsafe = failsafe
        self.spoken: list[str] = []  # what was asked of it, and whether the gate was open

    def prepare(self) -> None:
        assert self.link.gate is not None
        self.spoken.append(f"prepare {'open' if self.link.gate(self.system_id) else 'shut'}")

    def read_parameters(self, names: list[str]) -> dict[str, float]:
        self.spoken.append(f"read {' '.join(names)}")
        return {} if self.failsafe is None else {name: self.failsafe for name in names}

    def read_first(self, names: list[str]) -> tuple[str, float] | None:
        self.spoken.append(f"read first {' '.join(names)}")
        return names[0], 255.0

    source_system = 255

    def state(self) -> Any:
        return type("State", (), {"armed": False})()


def test_the_fence_opens_only_for_owned_vehicles_within_the_proven_lease(
        engine: sa.Engine) -> None:
    now = [100.0]
    shared, alone = _Link(), _Link()
    vehicles = [_Vehicle(1, 1, shared), _Vehicle(2, 2, shared), _Vehicle(3, 1, alone)]
    leases = Leases(engine, "a", lease=3.0)
    hangar = ClusterHangar(vehicles, time.monotonic, leases,  # type: ignore[arg-type]
                           monotonic=lambda: now[0])
    assert shared.gate is not None and alone.gate is not None
    assert not alone.gate(0)  # nothing owned, nothing proven: not even a HEARTBEAT
    sent = now[0]
    assert leases.join()
    hangar.renewed(sent)
    hangar.claim([3, 1], "run")
    assert alone.gate(0) and alone.gate(1) and shared.gate(1)
    assert not shared.gate(2) and not shared.gate(0)  # vehicle 2 is not ours
    now[0] = sent + 3.0 - 0.5 - 0.01
    assert alone.gate(1)
    now[0] = sent + 3.0 - 0.5  # the renewal's proof has run out: silence at once
    assert not alone.gate(1) and not hangar.may_send(3)
    hangar.renewed(now[0])
    assert alone.gate(1)
    other = Leases(engine, "b", lease=3.0)
    assert other.join() and other.take(2) is not None
    with pytest.raises(VehicleLeased, match="leased by the service instance 'b'"):
        hangar.claim([2], "run2")
    assert hangar.holder(2) is None
    hangar.release("run")
    assert sorted(hangar.give_back()) == [1, 3]  # disarmed and held by nothing
    assert not alone.gate(1)
    # Spoken to once it was first leased (the session opened it without a word), and only
    # then: taken again, it is not prepared again.
    read = ["read FS_GCS_ENABLE", "read first MAV_GCS_SYSID SYSID_MYGCS"]
    assert vehicles[2].spoken == ["prepare open", *read]
    hangar.claim([3], "run3")
    assert vehicles[2].spoken == ["prepare open", *read]


def test_a_vehicle_without_its_own_failsafe_is_not_leased_when_one_is_required(
        engine: sa.Engine) -> None:
    link = _Link()
    vehicles = [_Vehicle(1, 1, link, failsafe=0.0)]
    leases = Leases(engine, "a", lease=30.0)
    hangar = ClusterHangar(vehicles, time.monotonic, leases,  # type: ignore[arg-type]
                           require_gcs_failsafe=True)
    assert leases.join()
    hangar.renewed(time.monotonic())
    with pytest.raises(FailsafeMissing, match=r"vehicle 1: FS_GCS_ENABLE is 0: the vehicle "
                       r"does nothing by itself when it loses this ground station \(1 "
                       r"returns home, 5 lands\): not flown"):
        hangar.claim([1], "run")
    assert hangar.holder(1) is None and hangar.owned == {} and leases.owners([1]) == {}


def test_a_cluster_needs_postgresql(tmp_path: Any) -> None:
    storage = Storage(f"sqlite:///{tmp_path / 'x.sqlite'}")
    with pytest.raises(ClusterError, match="needs PostgreSQL"):
        Leases(storage.engine, "a")
    storage.close()


def test_a_control_reaches_the_instance_named_and_comes_back_with_its_answer(
        engine: sa.Engine) -> None:
    carried: list[dict[str, Any]] = []

    def owner(request: dict[str, Any]) -> tuple[int, str, dict[str, Any]]:
        carried.append(request)
        return 409, "cannot pause run r1: it is paused already", {"run_status": "paused"}

    a = Forwarder(engine, "a", owner)
    b = Forwarder(engine, "b", lambda request: (500, "not me", {}))
    a.start()
    b.start()
    try:
        assert b.ask("a", {"op": "control", "kind": "pause", "run": "r1"}) == (
            409, "cannot pause run r1: it is paused already", {"run_status": "paused"})
        assert carried == [{"op": "control", "kind": "pause", "run": "r1"}]
        with pytest.raises(Unanswered, match="'ghost' did not answer"):
            b.ask("ghost", {"op": "abort", "run": "r2"}, timeout=0.5)
    finally:
        a.stop()
        b.stop()


def test_tml_serve_cluster_without_postgresql_is_a_usage_error(
        capsys: pytest.CaptureFixture[str]) -> None:
    from tml.commands.cli import main

    assert main(["serve", "--sim", "--cluster", "--port", "0"]) == 2
    assert capsys.readouterr().err == ("tml serve: --cluster needs --database "
                                       "postgresql://...: the instances share their leases "
                                       "there\n")


def test_an_operator_command_to_a_vehicle_another_instance_leases_is_carried_out_there(
        tmp_path: Any) -> None:
    from serving import FakeHangar

    from tml.serve.service import RequestError, Service, ServiceOptions

    class Leased(FakeHangar):
        owner: str | None = None

        def owner_elsewhere(self, vehicle_id: int) -> str | None:
            return self.owner

    here, there = Leased(1), Leased(1)
    storages = [Storage(f"sqlite:///{tmp_path / name}.sqlite") for name in "ab"]
    a = Service(storages[0], here, ServiceOptions(instance="a"))
    b = Service(storages[1], there, ServiceOptions(instance="b"))
    asked: list[tuple[str, dict[str, Any]]] = []

    def forward(instance: str, request: dict[str, Any]) -> tuple[int, str, dict[str, Any]]:
        asked.append((instance, request))
        if instance != "b":
            return 504, f"the service instance {instance!r} did not answer in 10 s", {}
        return b.carry_out(request)

    a.forward = forward
    answer, done = a.command(1, "rtl")  # nobody else leases it: sent from here
    assert asked == [] and done
    here.owner = "b"
    answer, done = a.command(1, "rtl")
    assert asked == [("b", {"op": "command", "vehicle": 1, "command": "rtl"})]
    assert done and answer.message == "vehicle 1: nothing to do: " \
        f"{there.fakes[0].state().mode}, on the ground, disarmed"
    assert answer.vehicle_state.id == 1
    here.owner = "ghost"
    with pytest.raises(RequestError, match="'ghost' did not answer") as refused:
        a.command(1, "land")
    assert refused.value.status == 504
    for storage in storages:
        storage.close()


def test_an_instance_whose_lease_expired_shuts_its_fence_aborts_its_runs_and_joins_again(
        engine: sa.Engine) -> None:
    from tml.serve.answers import ServiceStatus
    from tml.serve.cluster import Cluster

    class Service:
        def __init__(self) -> None:
            self.aborted: list[str] = []
            self.reasons: list[str] = []

        def status(self) -> ServiceStatus:
            return ServiceStatus(version="0", instance="a", storage="postgresql",
                                 started=0.0, vehicles=[1], live_runs=["r1"])

        def abort(self, run_id: str, reason: str) -> None:
            self.aborted.append(run_id)
            self.reasons.append(reason)

    link = _Link()
    leases = Leases(engine, "a", lease=3.0)
    hangar = ClusterHangar([_Vehicle(1, 1, link)], time.monotonic,  # type: ignore[list-item]
                           leases)
    service = Service()
    cluster = Cluster(hangar, service)  # type: ignore[arg-type]
    assert leases.join()
    hangar.renewed(time.monotonic())
    hangar.claim([1], "r1")
    first = leases.session
    cluster._renew()
    assert link.gate is not None and link.gate(1) and service.aborted == []
    with engine.begin() as db:  # the process stalled past its lease
        db.execute(sa.text("UPDATE cluster_instances SET expires = clock_timestamp() "
                           "WHERE name = 'a'"))
    cluster._renew()
    assert not link.gate(1) and hangar.owned == {}
    assert service.aborted == ["r1"]
    # Said as it was: not the operator's abort (docs/run.md, How a run ends: STOPPED).
    assert service.reasons == ["the lease of service instance a expired"]
    assert leases.session != first and leases.renew()  # a new session, its lease running
    assert leases.owners([1]) == {}  # what the old session owned is not the new one's


def test_services_started_together_on_one_database_create_its_tables_once(
        database: str) -> None:
    with Storage(database).engine.begin() as db:  # a database no service has used yet
        for table in ("runs", "log_lines", "missions", "cluster_instances",
                      "vehicle_leases", "lease_handovers"):
            db.execute(sa.text(f"DROP TABLE IF EXISTS {table}"))
    opened: list[Storage] = []
    failed: list[BaseException] = []
    start = threading.Barrier(4)

    def open_both() -> None:
        start.wait()
        try:
            storage = Storage(database)
            Leases(storage.engine, f"i{threading.get_ident()}")
            opened.append(storage)
        except BaseException as error:  # reported below
            failed.append(error)

    threads = [threading.Thread(target=open_both) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert failed == [] and len(opened) == 4
    for storage in opened:
        storage.close()
