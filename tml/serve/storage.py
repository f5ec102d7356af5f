"""Where the service keeps missions, runs and flight logs: one SQL database.

Theory of operation
-------------------
Three tables, written through SQLAlchemy Core so that one code path serves SQLite (a file
in the data directory, the default) and PostgreSQL (``--database postgresql://...``):

- ``missions``: each uploaded mission's XML text as it was sent, its name and its file
  name. Only valid missions are kept (an invalid upload is answered with its diagnostics).
- ``runs``: one row per run: the mission it flies (its name and text are copied in, so a
  run outlives the deletion of its mission), the vehicles, the status, the outcome per
  vehicle, the exit code, the instance of the service that flies it, and times.
- ``log_lines``: the run's flight log, one row per JSON line, numbered from 1 in the order
  the journal wrote them; the same lines ``tml run --log`` writes to its file.

A run that is still ``waiting``, ``running`` or ``paused`` when its service starts again
was flying when the service died: :meth:`Storage.interrupt_unfinished` marks it
``interrupted`` (only the runs of this instance: several instances may share one
database, see docs/serve.md).

Every method opens its own short transaction; the engine's connection pool makes the
storage safe to use from the run threads and the request handlers at once.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Engine

from tml.errors import TmlError
from tml.run.endings import Ending

ACTIVE = ("waiting", "running", "paused")  # a run in one of these is flying (or about to)
SCHEMA_LOCK = 0x746D6C  # PostgreSQL advisory lock held while tables are created ("tml")

_meta = sa.MetaData()
_missions = sa.Table(
    "missions", _meta,
    sa.Column("id", sa.String(32), primary_key=True),
    sa.Column("name", sa.Text, nullable=False),
    sa.Column("filename", sa.Text, nullable=False),
    sa.Column("source", sa.Text, nullable=False),
    sa.Column("uploaded", sa.Float, nullable=False),
    sa.Column("warnings", sa.Text, nullable=False, default="[]"),
)
_runs = sa.Table(
    "runs", _meta,
    sa.Column("id", sa.String(32), primary_key=True),
    sa.Column("mission_id", sa.String(32), nullable=False),
    sa.Column("mission_name", sa.Text, nullable=False),
    sa.Column("mission_source", sa.Text, nullable=False),
    sa.Column("vehicles", sa.Text, nullable=False),
    sa.Column("status", sa.String(16), nullable=False),
    sa.Column("reason", sa.Text, nullable=False, default=""),
    sa.Column("outcomes", sa.Text, nullable=False, default="[]"),
    sa.Column("exit_code", sa.Integer, nullable=True),
    sa.Column("instance", sa.Text, nullable=False),
    sa.Column("options", sa.Text, nullable=False, default="{}"),
    sa.Column("created", sa.Float, nullable=False),
    sa.Column("ended", sa.Float, nullable=True),
)
_lines = sa.Table(
    "log_lines", _meta,
    sa.Column("run_id", sa.String(32), primary_key=True),
    sa.Column("seq", sa.Integer, primary_key=True, autoincrement=False),
    sa.Column("line", sa.Text, nullable=False),
)


class StorageError(TmlError):
    """The database cannot be opened or used."""


@dataclass(frozen=True)
class StoredMission:
    """A mission as kept: its text and what validation warned about."""

    id: str
    name: str
    filename: str
    source: str
    uploaded: float
    warnings: list[dict[str, Any]] = field(default_factory=list)


@dataclass(frozen=True)
class StoredRun:
    """A run as kept."""

    id: str
    mission_id: str
    mission_name: str
    mission_source: str
    vehicles: list[int]
    status: str
    reason: str
    outcomes: list[dict[str, Any]]
    exit_code: int | None
    instance: str
    options: dict[str, Any]
    created: float
    ended: float | None


def database_url(database: str | None, data: Path) -> str:
    """The SQLAlchemy URL: ``database`` as given (``postgresql://`` is read with psycopg
    3), or the SQLite file ``tml.sqlite`` in ``data``."""
    if database is None:
        return f"sqlite:///{data / 'tml.sqlite'}"
    if database.startswith("postgresql://") or database.startswith("postgres://"):
        return "postgresql+psycopg://" + database.split("://", 1)[1]
    return database


class Storage:
    """The service's database; see the module docstring."""

    def __init__(self, url: str) -> None:
        self.url = url
        try:
            self.engine: Engine = sa.create_engine(url, pool_pre_ping=True)
            if self.engine.dialect.name == "sqlite":
                sa.event.listen(self.engine, "connect", _sqlite_pragmas)
            with self.engine.begin() as db:
                if self.engine.dialect.name == "postgresql":
                    # Services started together on one database would race on CREATE
                    # TABLE (one fails on pg_type's unique index): one at a time.
                    db.execute(sa.text("SELECT pg_advisory_xact_lock(:key)"),
                               {"key": SCHEMA_LOCK})
                _meta.create_all(db)
        except (sa.exc.SQLAlchemyError, ImportError) as error:
            missing = isinstance(error, ImportError) and error.name == "psycopg"
            hint = (" (PostgreSQL needs tml's postgresql extra: pip install "
                    "'tml-flight[postgresql]'; in a checkout, pip install '.[postgresql]')"
                    if missing else "")
            raise StorageError(f"cannot open the database {_safe(url)}: "
                               f"{_first_line(error)}{hint}") from None

    @property
    def backend(self) -> str:
        """``sqlite`` or ``postgresql``."""
        return str(self.engine.dialect.name)

    def close(self) -> None:
        """Close every pooled connection."""
        self.engine.dispose()

    # --- missions ------------------------------------------------------------------------

    def add_mission(self, mission: StoredMission) -> None:
        """Keep a mission."""
        with self.engine.begin() as db:
            db.execute(_missions.insert().values(
                id=mission.id, name=mission.name, filename=mission.filename,
                source=mission.source, uploaded=mission.uploaded,
                warnings=json.dumps(mission.warnings)))

    def missions(self) -> list[StoredMission]:
        """Every mission, the oldest first."""
        with self.engine.connect() as db:
            rows = db.execute(_missions.select().order_by(_missions.c.uploaded,
                                                          _missions.c.id))
            return [_mission(row) for row in rows]

    def mission(self, mission_id: str) -> StoredMission | None:
        """One mission, or None."""
        with self.engine.connect() as db:
            row = db.execute(_missions.select().where(_missions.c.id == mission_id)).first()
            return None if row is None else _mission(row)

    def delete_mission(self, mission_id: str) -> bool:
        """Forget a mission; False when there was none. Its runs stay."""
        with self.engine.begin() as db:
            found = db.execute(_missions.delete().where(_missions.c.id == mission_id))
            return bool(found.rowcount)

    # --- runs ----------------------------------------------------------------------------

    def add_run(self, run: StoredRun) -> None:
        """Keep a new run."""
        with self.engine.begin() as db:
            db.execute(_runs.insert().values(
                id=run.id, mission_id=run.mission_id, mission_name=run.mission_name,
                mission_source=run.mission_source, vehicles=json.dumps(run.vehicles),
                status=run.status, reason=run.reason, outcomes=json.dumps(run.outcomes),
                exit_code=run.exit_code, instance=run.instance,
                options=json.dumps(run.options), created=run.created, ended=run.ended))

    def update_run(self, run_id: str, *, status: str, reason: str | None = None,
                   outcomes: list[dict[str, Any]] | None = None, exit_code: int | None = None,
                   ended: float | None = None) -> None:
        """Change a run's status (and, when it has ended, its outcome). A run marked
        ``interrupted`` stays so: in a cluster, another instance has taken it over, and
        what a stalled instance still writes of it changes nothing (tml.serve.cluster)."""
        values: dict[str, Any] = {"status": status}
        if reason is not None:
            values["reason"] = reason
        if outcomes is not None:
            values["outcomes"] = json.dumps(outcomes)
        if exit_code is not None:
            values["exit_code"] = exit_code
        if ended is not None:
            values["ended"] = ended
        with self.engine.begin() as db:
            db.execute(_runs.update().where(_runs.c.id == run_id,
                                            _runs.c.status != Ending.INTERRUPTED.status
                                            ).values(**values))

    def runs(self) -> list[StoredRun]:
        """Every run, the oldest first."""
        with self.engine.connect() as db:
            rows = db.execute(_runs.select().order_by(_runs.c.created, _runs.c.id))
            return [_run(row) for row in rows]

    def run(self, run_id: str) -> StoredRun | None:
        """One run, or None."""
        with self.engine.connect() as db:
            row = db.execute(_runs.select().where(_runs.c.id == run_id)).first()
            return None if row is None else _run(row)

    def interrupt_unfinished(self, instance: str) -> list[str]:
        """Mark ``interrupted`` the runs of ``instance`` that were still flying when it
        stopped; their ids."""
        with self.engine.begin() as db:
            ids = [row.id for row in db.execute(
                sa.select(_runs.c.id).where(_runs.c.instance == instance,
                                            _runs.c.status.in_(ACTIVE)))]
            if ids:
                db.execute(_runs.update().where(_runs.c.id.in_(ids)).values(
                    status=Ending.INTERRUPTED.status, ended=time.time(),
                    reason="the service stopped while the run was flying"))
            return ids

    # --- flight logs ---------------------------------------------------------------------

    def add_lines(self, run_id: str, lines: Sequence[tuple[int, str]]) -> None:
        """Append numbered lines to a run's flight log."""
        if not lines:
            return
        with self.engine.begin() as db:
            db.execute(_lines.insert(), [{"run_id": run_id, "seq": seq, "line": line}
                                         for seq, line in lines])

    def lines(self, run_id: str, after: int = 0) -> Iterator[tuple[int, str]]:
        """A run's flight log lines numbered above ``after``, in order."""
        with self.engine.connect() as db:
            rows = db.execute(sa.select(_lines.c.seq, _lines.c.line)
                              .where(_lines.c.run_id == run_id, _lines.c.seq > after)
                              .order_by(_lines.c.seq))
            yield from ((row.seq, row.line) for row in rows)


def failure(error: BaseException) -> str:
    """An error in one line: a database's own message without SQLAlchemy's wrapping
    ("the database failed: database or disk is full"), else its repr."""
    if isinstance(error, sa.exc.SQLAlchemyError):
        return f"the database failed: {_first_line(error)}"
    return repr(error)


def _mission(row: Any) -> StoredMission:
    return StoredMission(row.id, row.name, row.filename, row.source, row.uploaded,
                         json.loads(row.warnings))


def _run(row: Any) -> StoredRun:
    return StoredRun(row.id, row.mission_id, row.mission_name, row.mission_source,
                     json.loads(row.vehicles), row.status, row.reason,
                     json.loads(row.outcomes), row.exit_code, row.instance,
                     json.loads(row.options), row.created, row.ended)


def _sqlite_pragmas(connection: Any, _record: Any) -> None:
    # WAL lets the page read a log while a run appends to it; NORMAL sync is durable
    # across a crash of the service (not of the machine), as a flight log needs.
    cursor = connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.close()


def _safe(url: str) -> str:
    """The URL without its password."""
    try:
        return sa.engine.make_url(url).render_as_string(hide_password=True)
    except sa.exc.ArgumentError:
        return "(unreadable URL)"


def _first_line(error: BaseException) -> str:
    text = str(getattr(error, "orig", None) or error)
    return text.strip().splitlines()[0] if text.strip() else type(error).__name__

