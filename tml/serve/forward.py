"""Controls of a run flown by another instance of a cluster, carried by PostgreSQL's
LISTEN/NOTIFY.

Theory of operation
-------------------
Every instance of a cluster answers the whole API, but only the instance that flies a run
can pause, resume, jump or abort it. An instance asked to control another's run
(:meth:`Forwarder.ask`) sends the request with ``pg_notify`` on the channel
``tml_serve``, addressed to the owner by instance name and numbered with a random id, and
waits for the answer on the same channel. Every instance listens on its own connection
(a thread blocked in psycopg's ``notifies``); the owner carries the request out through
its own :class:`~tml.serve.service.Service`, and answers with the HTTP status and message
it would have given itself. A notification is delivered once the transaction that sent
it commits, to every connection listening at that moment: an owner that died answers
nothing, and the asker gives up after ``timeout`` (504).

No broker is needed: the database every instance already holds a connection to is the
bus, and a notification's payload (8000 bytes at most) carries only the request and its
status line; the run as it stands afterwards is read from the database.
"""

from __future__ import annotations

import json
import logging
import secrets
import threading
from collections.abc import Callable
from typing import Any, Literal, Required, TypedDict

import sqlalchemy as sa
from pydantic import JsonValue
from sqlalchemy.engine import Engine

CHANNEL = "tml_serve"
TIMEOUT = 10.0  # s to wait for the owner's answer



class Forwarded(TypedDict, total=False):
    """A request carried to the instance that flies a run (``abort``, ``control``: its
    ``kind`` and ``target``) or leases a vehicle (``command``)."""

    op: Required[Literal["abort", "control", "command"]]
    run: str
    kind: str
    target: str
    vehicle: int
    command: str


Answer = tuple[int, str, dict[str, JsonValue]]
"""How a forwarded request was answered: HTTP status, message and more JSON (a
refusal's detail; a command's run, outcome and what was seen)."""

Handler = Callable[[Forwarded], Answer]
"""Carries out a request addressed to this instance."""

log = logging.getLogger("tml.serve")


class Unanswered(Exception):
    """The owner did not answer in time (it may have died)."""


class Forwarder:
    """This instance's end of the channel; see the module docstring."""

    def __init__(self, engine: Engine, name: str, handle: Handler) -> None:
        self.engine = engine
        self.name = name
        self.handle = handle
        self._answers: dict[str, dict[str, Any]] = {}
        self._waiting: dict[str, threading.Event] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._listening = threading.Event()
        self._thread = threading.Thread(target=self._listen, name="cluster notify",
                                        daemon=True)

    def start(self) -> None:
        """Listen (returns once the LISTEN is in place)."""
        self._thread.start()
        self._listening.wait(10.0)

    def stop(self) -> None:
        """Stop listening."""
        self._stop.set()
        self._thread.join(2.0)

    def ask(self, instance: str, request: Forwarded, timeout: float = TIMEOUT) -> Answer:
        """Have ``instance`` carry out ``request``; its (status, message, detail). Raises
        Unanswered after ``timeout`` seconds without an answer."""
        ident = secrets.token_hex(8)
        done = threading.Event()
        with self._lock:
            self._waiting[ident] = done
        try:
            self._notify({"id": ident, "to": instance, "from": self.name,
                          "request": request})
            if not done.wait(timeout):
                raise Unanswered(f"the service instance {instance!r} did not answer in "
                                 f"{timeout:g} s")
            with self._lock:
                answer = self._answers.pop(ident)
            return int(answer["status"]), str(answer["message"]), dict(answer["detail"])
        finally:
            with self._lock:
                self._waiting.pop(ident, None)
                self._answers.pop(ident, None)

    def _notify(self, payload: dict[str, Any]) -> None:
        with self.engine.begin() as db:
            db.execute(sa.text("SELECT pg_notify(:channel, :payload)"),
                       {"channel": CHANNEL, "payload": json.dumps(payload)})

    def _listen(self) -> None:
        import psycopg

        url = self.engine.url.set(drivername="postgresql")
        while not self._stop.is_set():
            try:
                with psycopg.connect(url.render_as_string(hide_password=False),
                                     autocommit=True) as conn:
                    conn.execute(f"LISTEN {CHANNEL}")
                    self._listening.set()
                    while not self._stop.is_set():
                        for note in conn.notifies(timeout=0.5):
                            self._take(json.loads(note.payload))
            except psycopg.Error as error:
                log.warning("cluster: listening for controls: %s", error)
                self._stop.wait(1.0)

    def _take(self, payload: dict[str, Any]) -> None:
        if payload.get("to") != self.name:
            return
        if "answer" in payload:
            with self._lock:
                done = self._waiting.get(str(payload.get("id")))
                if done is not None:
                    self._answers[str(payload["id"])] = payload["answer"]
                    done.set()
            return
        # Carried out in a thread of its own: an abort waits for nothing, but a listener
        # that blocked would hold up every answer this instance waits for.
        threading.Thread(target=self._answer, args=(payload,), daemon=True).start()

    def _answer(self, payload: dict[str, Any]) -> None:
        try:
            status, message, detail = self.handle(payload.get("request", {}))
        except Exception as error:  # answered, not left to time out
            status, message, detail = 500, f"{type(error).__name__}: {error}", {}
        self._notify({"id": payload.get("id"), "to": payload.get("from"),
                      "answer": {"status": status, "message": message, "detail": detail}})
