"""The service's storage, on SQLite and on a throwaway PostgreSQL server.

The PostgreSQL tests start their own server from Debian's ``postgresql`` package and are
skipped, saying why, when it is not installed.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from serving import postgresql

from tml.serve.storage import Storage, StorageError, StoredMission, StoredRun, database_url


@pytest.fixture(scope="module")
def postgres_url() -> Iterator[str]:
    try:
        with postgresql() as url:
            yield url
    except LookupError as why:
        pytest.skip(f"no PostgreSQL server to test against: {why}")


@pytest.fixture(params=["sqlite", "postgresql"])
def url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    if request.param == "sqlite":
        yield database_url(None, tmp_path)
        return
    found: str = request.getfixturevalue("postgres_url")
    yield found
    engine = sa.create_engine(found)  # the next test starts from empty tables
    with engine.begin() as db:
        for table in ("missions", "runs", "log_lines"):
            db.execute(sa.text(f"DELETE FROM {table}"))
    engine.dispose()


def a_run(run_id: str, status: str = "running", instance: str = "local",
          created: float = 1.0) -> StoredRun:
    return StoredRun(run_id, "m1", "Mission", "<mission/>", [1, 2], status, "", [], None,
                     instance, {"safe_state": "rtl"}, created, None)


def test_missions_are_kept_listed_and_deleted(url: str) -> None:
    storage = Storage(url)
    warning = {"file": "a.xml", "line": 3, "column": 5, "code": "W301", "message": "m",
               "hint": "", "severity": "warning"}
    storage.add_mission(StoredMission("b2", "Second", "b.xml", "<b/>", 2.0))
    storage.add_mission(StoredMission("a1", "First", "a.xml", "<a>é</a>", 1.0, [warning]))
    assert [m.id for m in storage.missions()] == ["a1", "b2"]
    found = storage.mission("a1")
    assert found is not None
    assert (found.name, found.filename, found.source, found.warnings) == \
        ("First", "a.xml", "<a>é</a>", [warning])
    assert storage.delete_mission("a1") is True
    assert storage.delete_mission("a1") is False
    assert storage.mission("a1") is None
    storage.close()


def test_runs_keep_their_outcome(url: str) -> None:
    storage = Storage(url)
    storage.add_run(a_run("r1"))
    storage.update_run("r1", status="aborted", reason="operator", exit_code=3, ended=9.5,
                       outcomes=[{"vehicle": 1, "status": "aborted"}])
    found = storage.run("r1")
    assert found is not None
    assert (found.status, found.reason, found.exit_code, found.ended, found.outcomes,
            found.vehicles, found.options) == ("aborted", "operator", 3, 9.5,
                                               [{"vehicle": 1, "status": "aborted"}], [1, 2],
                                               {"safe_state": "rtl"})
    assert storage.run("nope") is None
    storage.close()


def test_log_lines_come_back_in_order_from_any_point(url: str) -> None:
    storage = Storage(url)
    storage.add_lines("r1", [(1, '{"kind":"run"}'), (2, '{"kind":"task"}')])
    storage.add_lines("r1", [(3, '{"kind":"mission"}')])
    storage.add_lines("r2", [(1, '{"kind":"other run"}')])
    assert [seq for seq, _ in storage.lines("r1")] == [1, 2, 3]
    assert list(storage.lines("r1", after=2)) == [(3, '{"kind":"mission"}')]
    storage.close()


def test_a_run_flying_when_its_instance_died_is_marked_interrupted(url: str) -> None:
    first = Storage(url)
    first.add_run(a_run("r1", "running", created=1.0))
    first.add_run(a_run("r2", "completed", created=2.0))
    first.add_run(a_run("r3", "waiting", instance="north", created=3.0))
    first.close()
    again = Storage(url)  # the service started again: same database, same instance
    assert again.interrupt_unfinished("local") == ["r1"]
    statuses = {r.id: r.status for r in again.runs()}
    # Another instance's run in the shared database is that instance's business.
    assert statuses == {"r1": "interrupted", "r2": "completed", "r3": "waiting"}
    run = again.run("r1")
    assert run is not None and run.ended is not None and "stopped" in run.reason
    again.close()


def test_two_instances_sharing_one_database_see_each_others_runs(url: str) -> None:
    north, south = Storage(url), Storage(url)
    north.add_run(a_run("n1", instance="north"))
    south.add_run(a_run("s1", instance="south", created=2.0))
    assert [r.id for r in north.runs()] == [r.id for r in south.runs()] == ["n1", "s1"]
    north.close()
    south.close()


def test_an_unreachable_database_is_one_clear_error(tmp_path: Path) -> None:
    with pytest.raises(StorageError, match="cannot open the database"):
        Storage(database_url(None, tmp_path / "missing" / "dir"))


def test_postgresql_urls_are_read_with_psycopg(tmp_path: Path) -> None:
    assert database_url("postgresql://u:p@db/tml", tmp_path) == \
        "postgresql+psycopg://u:p@db/tml"
    assert database_url(None, tmp_path) == f"sqlite:///{tmp_path / 'tml.sqlite'}"
