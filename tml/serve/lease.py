"""Who may command which vehicle, when several ``tml serve`` instances share PostgreSQL.

Theory of operation
-------------------
Two tables, kept by PostgreSQL's own clock (``clock_timestamp()``, the one clock every
instance's lease is judged by; an instance's own clock only measures how long ago it
renewed):

- ``cluster_instances``: one row per instance name, with the *session* of the process
  that holds it (a random id per start) and when its lease *expires*. An instance renews
  its row every ``renew`` seconds (:meth:`Leases.renew`: one ``UPDATE`` of one row, however
  many vehicles it flies); a renewal that finds the row expired fails, for good: that
  session's vehicles are anybody's.
- ``vehicle_leases``: one row per vehicle: the instance and session that own it, and a
  *fencing token* that grows by one each time the vehicle changes hands. A vehicle's
  lease is valid while its owner's session row has not expired. :meth:`Leases.take` takes
  a vehicle that nobody owns, or whose owner's session has expired (``UPDATE ... WHERE``
  on the server's clock, in one transaction: two instances asking at once are ordered by
  the row lock, and the second finds the first's live session);
  :meth:`Leases.release` gives it back.

A run flown by an instance whose session has expired is an orphan: :meth:`Leases.orphans`
lists them and :meth:`Leases.adopt` marks one ``interrupted`` (``UPDATE ... WHERE status
IN (waiting, running, paused) RETURNING``: exactly one instance wins it) so that the
winner continues it from its stored journal.

Every handover of a vehicle is written to ``lease_handovers`` (vehicle, token, new and old
owner, server time), so that who could command a vehicle when can be read afterwards.

Creating the tables takes an advisory lock: instances starting together do not race on
``CREATE TABLE IF NOT EXISTS``. Only PostgreSQL is supported (``--cluster`` refuses
SQLite, whose single writer cannot be shared by machines).
"""

from __future__ import annotations

import json
import secrets
from collections.abc import Iterable
from dataclasses import dataclass

import sqlalchemy as sa
from sqlalchemy.engine import Connection, Engine

from tml.errors import TmlError
from tml.serve.storage import SCHEMA_LOCK

_SCHEMA = """
CREATE TABLE IF NOT EXISTS cluster_instances (
    name text PRIMARY KEY,
    session text NOT NULL,
    expires timestamptz NOT NULL,
    joined timestamptz NOT NULL,
    source_system integer NOT NULL
);
CREATE TABLE IF NOT EXISTS vehicle_leases (
    vehicle integer PRIMARY KEY,
    owner text,
    session text,
    token bigint NOT NULL,
    taken timestamptz NOT NULL
);
CREATE TABLE IF NOT EXISTS lease_handovers (
    vehicle integer NOT NULL,
    token bigint NOT NULL,
    owner text NOT NULL,
    previous text,
    taken timestamptz NOT NULL,
    PRIMARY KEY (vehicle, token)
);
"""

# A session is live while its row says so by the server's clock.
_LIVE = ("EXISTS (SELECT 1 FROM cluster_instances i WHERE i.name = {owner} "
         "AND i.session = {session} AND i.expires > clock_timestamp())")


class ClusterError(TmlError):
    """The cluster's tables cannot be used (not PostgreSQL, or the name is in use)."""


@dataclass(frozen=True)
class Taken:
    """A vehicle taken: its fencing token, and the instance that had it (None: nobody)."""

    vehicle: int
    token: int
    previous: str | None


class Leases:
    """One instance's view of the lease tables; see the module docstring."""

    def __init__(self, engine: Engine, name: str, lease: float = 3.0,
                 source_system: int = 255) -> None:
        if engine.dialect.name != "postgresql":
            raise ClusterError(f"a cluster needs PostgreSQL (--database postgresql://...), "
                               f"not {engine.dialect.name}")
        self.engine = engine
        self.name = name
        self.lease = lease
        self.source_system = source_system
        self.session = secrets.token_hex(8)
        with self.engine.begin() as db:
            db.execute(sa.text("SELECT pg_advisory_xact_lock(:key)"), {"key": SCHEMA_LOCK})
            for statement in filter(str.strip, _SCHEMA.split(";")):
                db.execute(sa.text(statement))

    # --- the instance's own lease --------------------------------------------------------

    def join(self) -> bool:
        """Hold this instance's name with a new lease; False while another live process
        holds it (an instance restarted after a crash waits for its old lease to expire).
        Each join is a new session: what an earlier one owned is not this one's."""
        self.session = secrets.token_hex(8)
        with self.engine.begin() as db:
            row = db.execute(sa.text(
                "INSERT INTO cluster_instances (name, session, expires, joined, "
                "source_system) VALUES (:name, :session, clock_timestamp() + "
                "make_interval(secs => :lease), clock_timestamp(), :source) "
                "ON CONFLICT (name) DO UPDATE SET session = EXCLUDED.session, "
                "expires = EXCLUDED.expires, joined = EXCLUDED.joined, "
                "source_system = EXCLUDED.source_system "
                "WHERE cluster_instances.expires < clock_timestamp() RETURNING name"),
                self._me()).first()
            return row is not None

    def renew(self) -> bool:
        """Push this session's expiry ``lease`` seconds past the server's now; False when
        it had expired already (the session is over: its vehicles may have been taken)."""
        with self.engine.begin() as db:
            row = db.execute(sa.text(
                "UPDATE cluster_instances SET expires = clock_timestamp() + "
                "make_interval(secs => :lease) WHERE name = :name AND session = :session "
                "AND expires > clock_timestamp() RETURNING name"), self._me()).first()
            return row is not None

    def leave(self) -> None:
        """End this session now (a clean stop): its vehicles are free at once."""
        with self.engine.begin() as db:
            db.execute(sa.text(
                "UPDATE vehicle_leases SET owner = NULL, session = NULL "
                "WHERE owner = :name AND session = :session"), self._me())
            db.execute(sa.text(
                "UPDATE cluster_instances SET expires = clock_timestamp() "
                "WHERE name = :name AND session = :session"), self._me())

    def live_instances(self) -> dict[str, int]:
        """The instances whose lease runs, with the MAVLink source system of each."""
        with self.engine.connect() as db:
            rows = db.execute(sa.text(
                "SELECT name, source_system FROM cluster_instances "
                "WHERE expires > clock_timestamp() ORDER BY name"))
            return {row.name: row.source_system for row in rows}

    # --- vehicles ------------------------------------------------------------------------

    def take(self, vehicle: int) -> Taken | None:
        """Own ``vehicle``: when nobody does, its owner's session has expired, or it is
        this session's already; None when a live instance owns it or this session's own
        lease has run out."""
        me = self._me() | {"vehicle": vehicle}
        with self.engine.begin() as db:
            if not self._alive(db):
                return None
            row = db.execute(sa.text(
                "SELECT owner, session, token FROM vehicle_leases WHERE vehicle = :vehicle "
                "FOR UPDATE"), me).first()
            if row is None:
                taken = db.execute(sa.text(
                    "INSERT INTO vehicle_leases (vehicle, owner, session, token, taken) "
                    "VALUES (:vehicle, :name, :session, 1, clock_timestamp()) "
                    "ON CONFLICT (vehicle) DO NOTHING RETURNING token"), me).first()
                previous = None
            elif row.owner == self.name and row.session == self.session:
                return Taken(vehicle, int(row.token), self.name)
            else:
                free = "owner IS NULL OR NOT " + _LIVE.format(owner="vehicle_leases.owner",
                                                             session="vehicle_leases.session")
                taken = db.execute(sa.text(
                    "UPDATE vehicle_leases SET owner = :name, session = :session, "
                    "token = token + 1, taken = clock_timestamp() "
                    f"WHERE vehicle = :vehicle AND ({free}) RETURNING token"), me).first()
                previous = row.owner
            if taken is None:
                return None
            db.execute(sa.text(
                "INSERT INTO lease_handovers (vehicle, token, owner, previous, taken) "
                "VALUES (:vehicle, :token, :name, :previous, clock_timestamp())"),
                me | {"token": taken.token, "previous": previous})
            return Taken(vehicle, int(taken.token), previous)

    def release(self, vehicle: int) -> None:
        """Give ``vehicle`` back (when this session owns it)."""
        with self.engine.begin() as db:
            db.execute(sa.text(
                "UPDATE vehicle_leases SET owner = NULL, session = NULL WHERE vehicle = "
                ":vehicle AND owner = :name AND session = :session"),
                self._me() | {"vehicle": vehicle})

    def owners(self, vehicles: Iterable[int]) -> dict[int, str]:
        """The live owner of each of ``vehicles`` that has one."""
        wanted = list(vehicles)
        live = _LIVE.format(owner="v.owner", session="v.session")
        with self.engine.connect() as db:
            rows = db.execute(sa.text(
                f"SELECT vehicle, owner FROM vehicle_leases v WHERE {live} "
                "AND vehicle = ANY(:vehicles)"), {"vehicles": wanted})
            return {row.vehicle: row.owner for row in rows}

    def abandoned(self) -> dict[int, float]:
        """The vehicles still owned by a session whose lease has expired, with the seconds
        since it expired by the server's clock (a very large number when the instance
        has joined again since, as a new session)."""
        with self.engine.connect() as db:
            rows = db.execute(sa.text(
                "SELECT v.vehicle, COALESCE(EXTRACT(EPOCH FROM clock_timestamp() - "
                "i.expires), 1e9) AS silent FROM vehicle_leases v LEFT JOIN "
                "cluster_instances i ON i.name = v.owner AND i.session = v.session "
                "WHERE v.owner IS NOT NULL AND (i.expires IS NULL OR "
                "i.expires <= clock_timestamp()) ORDER BY v.vehicle"))
            return {row.vehicle: float(row.silent) for row in rows}

    # --- runs ----------------------------------------------------------------------------

    def orphans(self, own: bool = False) -> list[str]:
        """The runs still flying in the database whose instance has no live lease, the
        oldest first; with ``own``, this instance's too (an earlier process of the same
        name flew them: asked once, on joining, before this one flies anything)."""
        with self.engine.connect() as db:
            rows = db.execute(sa.text(
                "SELECT id FROM runs r WHERE r.status IN ('waiting', 'running', 'paused') "
                "AND (NOT EXISTS (SELECT 1 FROM cluster_instances i WHERE i.name = "
                "r.instance AND i.expires > clock_timestamp()) OR (:own AND r.instance = "
                ":name)) ORDER BY created, id"), {"own": own, "name": self.name})
            return [row.id for row in rows]

    def in_runs(self, since: float) -> set[int]:
        """The vehicles of every run still flying in the database, or interrupted since
        ``since`` (a wall-clock time) and neither continued nor given up yet: a survivor
        is about to go on with it."""
        with self.engine.connect() as db:
            rows = db.execute(sa.text(
                "SELECT r.vehicles FROM runs r WHERE r.status IN ('waiting', 'running', "
                "'paused') OR (r.status = 'interrupted' AND r.ended > :since AND "
                "r.options NOT LIKE '%\"not_continued\"%' AND NOT EXISTS "
                "(SELECT 1 FROM runs c WHERE c.options LIKE "
                "'%\"continues\": \"' || r.id || '\"%'))"), {"since": since})
            return {int(v) for row in rows for v in json.loads(row.vehicles)}

    def adopt(self, run_id: str, reason: str, ended: float) -> bool:
        """Mark an orphan run ``interrupted`` so that this instance continues it; False
        when another instance did first (or the run ended)."""
        with self.engine.begin() as db:
            row = db.execute(sa.text(
                "UPDATE runs SET status = 'interrupted', reason = :reason, ended = :ended "
                "WHERE id = :id AND status IN ('waiting', 'running', 'paused') RETURNING id"),
                {"id": run_id, "reason": reason, "ended": ended}).first()
            return row is not None

    def give_up(self, run_id: str, why: str) -> None:
        """Note in an adopted run's options why it is not continued (``not_continued``):
        its vehicles are no run's to go on with."""
        with self.engine.begin() as db:
            row = db.execute(sa.text("SELECT options FROM runs WHERE id = :id FOR UPDATE"),
                             {"id": run_id}).first()
            if row is not None:
                options = {**json.loads(row.options), "not_continued": why}
                db.execute(sa.text("UPDATE runs SET options = :options WHERE id = :id"),
                           {"id": run_id, "options": json.dumps(options)})

    # --- helpers -------------------------------------------------------------------------

    def _me(self) -> dict[str, object]:
        return {"name": self.name, "session": self.session, "lease": self.lease,
                "source": self.source_system}

    def _alive(self, db: Connection) -> bool:
        row = db.execute(sa.text("SELECT " + _LIVE.format(owner=":name", session=":session")
                                 + " AS alive"), self._me()).first()
        return bool(row is not None and row.alive)
