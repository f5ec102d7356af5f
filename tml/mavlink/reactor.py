"""One thread that serves every MAVLink connection of a process: a ``selectors`` loop.

Theory of operation
-------------------
A fleet of N vehicles is N connections. A thread per connection, each blocked in its own
``select``, makes N threads take the interpreter lock in turn for every message; at a few
hundred vehicles the hand-overs cost more than the messages (docs/performance.md). A
:class:`Reactor` is one thread that waits on the files of every connection at once
(:mod:`selectors`: epoll on Linux) and, for each file that has something to read, lets its
owner (a :class:`Served`, in practice a :class:`~tml.mavlink.link.Link`) handle it. Between
reads it carries out each owner's *duties* when they are due (heartbeats, the lost check,
the redial of a TCP vehicle gone away): an owner says when its next duty is, and the loop
keeps the owners in a heap by that time.

*Right of way.* Between two owners' turns the loop gives way to a thread that asked to go
first (:meth:`tml.timebase.Timebase.right_of_way`: the runner, for its turn after a change):
its turn is then done in one piece instead of in slices between the loop's.

*Hand-overs.* The loop's thread is busy whenever telemetry comes in bursts, and a thread
woken meanwhile (the runner with a step to take) waits for the interpreter lock
until the loop's thread has held it for Python's switch interval. While a reactor runs, that
interval is :data:`SWITCH_INTERVAL` (1 ms instead of 5; restored after the last reactor):
a step is taken within milliseconds of its change even in a fleet's busiest second, for a
few more hand-overs of the lock (docs/performance.md measures both). The requests a step
submits are carried out on the loop's own thread (:meth:`tml.mavlink.link.Link.begin`).

*Fairness.* An owner handles at most :data:`MESSAGES_AT_ONCE` messages in one turn; one that
may have more (its parser holds whole messages already read from the socket, which the
socket no longer shows) is served again in the next round without waiting, after every other
ready owner had its turn.

*One reactor per time base.* The loop waits through its owners' time base
(:meth:`tml.timebase.Timebase.wait_ready`): the system's for real vehicles; a lock-step
simulator's in ``tml run --sim``, where the reactor is one thread taking part (time moves on
only when it waits and every byte sent has been read), and an owner added is announced, so
that time waits for the loop to take it in. The thread starts with the first owner and ends
with the last (:func:`serve`, :func:`unserve`).

*Files that change.* A TCP vehicle dialled again, or a ``tcpin:`` connection that accepts its
client, has a new file: the loop asks each owner for its file after each turn and watches the
new one (``None``: nothing to watch, the owner's duties carry on).

An owner that raises out of its turn is reported through :func:`threading.excepthook`, as a
thread of its own would have been, and is no longer served; the others go on.
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import os
import selectors
import sys
import threading
from typing import Protocol

from tml.timebase import Timebase

MESSAGES_AT_ONCE = 100
"""Messages an owner handles in one turn before the other ready owners have theirs."""
IDLE_WAIT = 1.0
"""Seconds the loop waits at most when no duty is due sooner."""
LET_GO_TIMEOUT = 2.0
"""Wall seconds :func:`unserve` waits for the loop to let go of an owner."""
SWITCH_INTERVAL = 0.001
"""Seconds a busy thread keeps Python's interpreter lock from one that waits for it, while a
reactor runs (instead of the default 0.005; see the module docstring)."""
THREAD_NAME = "mavlink reactor"
"""The name of the loop's thread (profiles and benchmarks find it by it)."""


class Served(Protocol):
    """What a :class:`Reactor` serves: a connection with a file to watch and duties."""

    def fileno(self) -> int | None:
        """The file to watch for reading now; None when there is none (a TCP vehicle gone)."""

    def readable(self, limit: int) -> bool:
        """Handle what can be read without waiting, at most ``limit`` messages; True when
        more may be there already (the loop comes back without waiting)."""

    def duties(self, now: float) -> float:
        """Do what is due at ``now`` (time-base seconds); returns when the next duty is."""


class Reactor:
    """The loop serving the connections of one time base (see the module docstring)."""

    def __init__(self, timebase: Timebase) -> None:
        self.timebase = timebase
        self.thread: threading.Thread | None = None
        self._selector = selectors.DefaultSelector()
        self._wake_read, self._wake_write = os.pipe()
        os.set_blocking(self._wake_read, False)
        os.set_blocking(self._wake_write, False)
        self._selector.register(self._wake_read, selectors.EVENT_READ, None)
        self._adding: list[Served] = []  # guarded by _REGISTRY_LOCK, as _removing
        self._removing: list[tuple[Served, threading.Event]] = []
        self._files: dict[Served, int | None] = {}  # owner -> the file watched for it
        self._next: dict[Served, float] = {}  # owner -> when its next duty is
        self._due: list[tuple[float, int, Served]] = []  # heap; stale entries are skipped
        self._order = itertools.count()
        self._more: list[Served] = []  # owners with messages left after their turn
        self._hurried: list[Served] = []  # owners whose duties are due now (guarded as _adding)

    @property
    def served(self) -> int:
        """How many owners the loop serves."""
        return len(self._files)

    def hurry(self, owner: Served) -> None:
        """Carry out ``owner``'s duties in the loop's next round, not when it said they were
        due (a duty of its own came sooner: a request's step). Any thread."""
        with _REGISTRY_LOCK:
            if self.thread is not None:
                self._hurried.append(owner)
                self.wake()

    def wake(self) -> None:
        """Make the loop look at its owners now (one added or removed). Called with
        _REGISTRY_LOCK held: the loop closes the pipe under it when it ends."""
        with contextlib.suppress(BlockingIOError):  # a full pipe wakes it as well
            os.write(self._wake_write, b"!")

    # --- the loop (its own thread) ---------------------------------------------------

    def run(self) -> None:
        """Serve the owners until there are none (the thread's target)."""
        with self.timebase.taking_part(announced=True):
            while self._take_in():
                self._round()

    def _round(self) -> None:
        timebase = self.timebase
        now = timebase.now()
        due = self._due
        while due and due[0][0] <= now:
            when, _, owner = heapq.heappop(due)
            if self._next.get(owner) != when:
                continue  # let go of, or rescheduled
            try:
                self._schedule(owner, owner.duties(now))
            except Exception:  # reported, and the other owners go on
                self._fail(owner)
                continue
            self._watch(owner)
            timebase.give_way()
        wait = IDLE_WAIT if not due else min(due[0][0] - now, IDLE_WAIT)
        if self._more:
            wait = 0.0  # their messages are read already: no waiting for the socket
        ready = timebase.wait_ready(self._selector, wait)
        turn, self._more = self._more, []
        if self._hurried:
            with _REGISTRY_LOCK:
                hurried, self._hurried = self._hurried, []
            now = timebase.now()
            for owner in hurried:
                if owner in self._files:
                    self._schedule(owner, now)
        for key, _ in ready:
            if key.data is None:
                with contextlib.suppress(BlockingIOError):
                    os.read(self._wake_read, 4096)
            elif key.data not in turn:
                turn.append(key.data)
        for owner in turn:
            if self._removing:  # a closing link waits for this: not for the whole round
                self._take_in()
            if owner not in self._files:
                continue  # let go of during this round
            try:
                if owner.readable(MESSAGES_AT_ONCE):
                    self._more.append(owner)
            except Exception:  # reported, and the other owners go on
                self._fail(owner)
                continue
            self._watch(owner)
            timebase.give_way()  # a runner woken by this turn's messages goes first

    def _take_in(self) -> bool:
        """Take the owners added and let go of those removed; False once none is left
        (the thread then ends, and the reactor is forgotten)."""
        if not self._adding and not self._removing and self._files:
            return True
        with _REGISTRY_LOCK:
            adding, self._adding = self._adding, []
            removing, self._removing = self._removing, []
            if not adding and not removing and not self._files:
                _REACTORS.pop(self.timebase, None)
                self.thread = None
                _hand_over_as_before()
                self._close()
                return False
        for owner in adding:
            self._files[owner] = None
            self._watch(owner)
            self._schedule(owner, self.timebase.now())
            self.timebase.arrived()
        for owner, done in removing:
            self._forget(owner)
            done.set()
        return True

    def _schedule(self, owner: Served, when: float) -> None:
        self._next[owner] = when
        heapq.heappush(self._due, (when, next(self._order), owner))

    def _watch(self, owner: Served) -> None:
        """Watch the owner's file of now (it may have changed in its turn)."""
        fd = owner.fileno()
        old = self._files.get(owner)
        if fd == old:
            return
        if old is not None:
            with contextlib.suppress(KeyError, ValueError, OSError):
                self._selector.unregister(old)
        self._files[owner] = fd
        if fd is None:
            return
        # The number of a file closed in another thread may be another owner's now.
        taken = self._selector.get_map().get(fd)
        if taken is not None:
            with contextlib.suppress(KeyError, ValueError, OSError):
                self._selector.unregister(fd)
            if taken.data is not None and taken.data in self._files:
                self._files[taken.data] = None  # looked at again after its next turn
        try:
            self._selector.register(fd, selectors.EVENT_READ, owner)
        except (ValueError, OSError):  # closed meanwhile: its duties find out why
            self._files[owner] = None

    def _forget(self, owner: Served) -> None:
        fd = self._files.pop(owner, None)
        self._next.pop(owner, None)
        if fd is not None:
            with contextlib.suppress(KeyError, ValueError, OSError):
                self._selector.unregister(fd)

    def _fail(self, owner: Served) -> None:
        """An owner raised: report it as a thread's failure, and serve it no more."""
        exc_type, exc_value, traceback = sys.exc_info()
        assert exc_type is not None
        threading.excepthook(threading.ExceptHookArgs(
            (exc_type, exc_value, traceback, threading.current_thread())))
        self._forget(owner)

    def _close(self) -> None:
        self._selector.close()
        for end in (self._wake_read, self._wake_write):
            os.close(end)


_REACTORS: dict[Timebase, Reactor] = {}
_REGISTRY_LOCK = threading.Lock()
_interval_before = sys.getswitchinterval()  # the switch interval while no reactor runs


def _hand_over_sooner() -> None:
    """A reactor's thread is about to start (with _REGISTRY_LOCK held): the first of those
    running sets the shorter switch interval."""
    global _interval_before
    if not any(r.thread is not None for r in _REACTORS.values()):
        _interval_before = sys.getswitchinterval()
        sys.setswitchinterval(min(_interval_before, SWITCH_INTERVAL))


def _hand_over_as_before() -> None:
    """A reactor's thread ends (with _REGISTRY_LOCK held): the last one restores it."""
    if not any(r.thread is not None for r in _REACTORS.values()):
        sys.setswitchinterval(_interval_before)


def serve(owner: Served, timebase: Timebase) -> Reactor:
    """Have the reactor of ``timebase`` serve ``owner`` (started with its first owner)."""
    with _REGISTRY_LOCK:
        reactor = _REACTORS.get(timebase)
        if reactor is None:
            reactor = _REACTORS[timebase] = Reactor(timebase)
        reactor._adding.append(owner)
        timebase.announce()  # time waits until the loop has taken the owner in
        if reactor.thread is None:
            timebase.announce()
            _hand_over_sooner()
            reactor.thread = threading.Thread(target=reactor.run, name=THREAD_NAME,
                                              daemon=True)
            reactor.thread.start()
        reactor.wake()
    return reactor


def unserve(owner: Served, reactor: Reactor) -> None:
    """Stop serving ``owner``; returns once the loop has let go of it (it touches the
    owner's files no more), or after :data:`LET_GO_TIMEOUT`."""
    done = threading.Event()
    with _REGISTRY_LOCK:
        if owner in reactor._adding:
            reactor._adding.remove(owner)
            reactor.timebase.arrived()
            return
        if reactor.thread is None:
            return
        if reactor.thread is threading.current_thread():  # an owner closed from its turn
            reactor._forget(owner)
            return
        reactor._removing.append((owner, done))
        reactor.wake()
    done.wait(LET_GO_TIMEOUT)
