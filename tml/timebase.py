"""The time that every wait of a flight reads: the system's, or a simulator's in lock-step.

Theory of operation
-------------------
Every thread of tml that waits for a vehicle -- the runner between two steps, the reactor
for the next message, heartbeat or request's deadline of any link, a command-line tool for
an answer -- waits through one :class:`Timebase`. The system's (:data:`SYSTEM`) is
the monotonic clock with ordinary waits: a real vehicle does not wait for us.

:class:`Lockstep` is the time of an embedded simulator that the simulator advances itself,
one control tick at a time, and only when nothing in tml can act any more at the present
instant. So what tml does at a vehicle time t depends on what the vehicle said before t,
never on how busy the machine is: a flight on an idle machine and on a saturated one give
the same flight log (up to the order of things done at one instant).

*Taking part.* The threads whose work must be done before time moves on say so
(:meth:`Timebase.taking_part`): the runner and the reactor that reads every link and
carries out every request. A thread taking part is *running* unless it is inside one of
the waits below:

- :meth:`Timebase.wait` on a condition: it ends at the condition's :meth:`Timebase.notify_all`
  or at its deadline in this time base's seconds. A notify made through the time base counts
  the woken threads as running at once, before they even get the processor, so a message
  handled by the reactor and the runner it wakes both finish before time moves on;
- :meth:`Timebase.wait_readable` on a socket, or :meth:`Timebase.wait_ready` on the
  sockets of a selector (tml.mavlink.reactor: one thread for every link), for the next
  bytes or a deadline.

*Bytes in flight.* A socket saying it has nothing to read proves nothing: on a busy machine
the kernel may deliver a loopback segment after the send that made it returned. So both
ends count what they send and what they read on each connection between tml and the
simulator (:meth:`Lockstep.track`, :meth:`Lockstep.carried`), and time waits while any
byte sent has not been read.

:meth:`Lockstep.settled` is true when every thread taking part waits. An instant then goes
in two phases: the simulator advances the time (:meth:`Lockstep.advance`) and sends what its
vehicles say at that instant, which tml handles until settled; then the waits whose deadline
came end (:meth:`Lockstep.fire`) and run until settled again. So a runner woken by its
timer at t always sees the telemetry of t. Threads
that do not take part (the main thread opening the links, a web server's threads) may wait on
the time base too; what they send is handled at the next tick. A thread that takes part and
blocks outside the time base (a bug) would stop time for good: after ``stall_after`` wall
seconds without settling, time moves on anyway and :attr:`Lockstep.stalls` counts it.

:class:`Flag` is an event whose waits go through a time base; with :data:`SYSTEM` it behaves
as :class:`threading.Event`.
"""

from __future__ import annotations

import contextlib
import math
import os
import select
import selectors
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field

GUARD = 0.1
"""Wall seconds a lock-step wait sleeps at most before looking again: nothing is missed by
it, but a thread told to stop (a link closed) notices within that time."""


SIGNAL_SLICE = 0.2
"""Wall seconds the main thread waits at most at once (see :meth:`Timebase.wait`)."""

GIVE_WAY_LIMIT = 0.1
"""Wall seconds a thread giving way (:meth:`Timebase.give_way`) waits at most for one
stretch of right of way: a slow turn (a disk that takes its time to sync) delays it no more."""


class _RightOfWay:
    """Threads that have the right of way, and a condition to wait for them to be done."""

    def __init__(self) -> None:
        self.cond = threading.Condition(threading.Lock())
        self.holders = 0
        self.stretch = 0  # counts the stretches with a holder
        self.outlasted = 0  # the last stretch that outlasted GIVE_WAY_LIMIT: no more waits


class Timebase:
    """The system's time: :func:`time.monotonic` and ordinary waits."""

    lockstep = False

    def __init__(self) -> None:
        self._way = _RightOfWay()

    def now(self) -> float:
        """Seconds of this time base."""
        return time.monotonic()

    def wait(self, cond: threading.Condition, timeout: float | None) -> None:
        """Wait (holding ``cond``) for a :meth:`notify_all` of it, or ``timeout`` seconds;
        the main thread may come back sooner (its callers wait again)."""
        if threading.current_thread() is threading.main_thread():
            # A Ctrl-C that the kernel hands to another thread (a numerical library's own)
            # does not interrupt the main thread's wait: Python runs the handler only when
            # the main thread comes back, which a wait for a 300 s time-out would delay.
            timeout = SIGNAL_SLICE if timeout is None else min(timeout, SIGNAL_SLICE)
        cond.wait(timeout)

    def notify_all(self, cond: threading.Condition) -> None:
        """Wake every thread waiting on ``cond`` (held by the caller)."""
        cond.notify_all()

    def wait_readable(self, fileno: int, timeout: float) -> None:
        """Wait until something can be read from ``fileno``, or ``timeout`` seconds."""
        select.select([fileno], [], [], max(timeout, 0.0))

    def wait_ready(self, selector: selectors.BaseSelector, timeout: float
                   ) -> list[tuple[selectors.SelectorKey, int]]:
        """Wait until a file of ``selector`` can be read, or ``timeout`` seconds; returns
        the files ready (none at the time-out)."""
        return selector.select(max(timeout, 0.0))

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass."""
        if seconds > 0:
            time.sleep(seconds)

    def track(self, connection: object) -> None:
        """Count the bytes of ``connection`` (tml's end's socket address) in flight."""

    def carried(self, connection: object, sent: int) -> None:
        """``sent`` bytes went onto ``connection`` (read from it: negative)."""

    def announce(self) -> None:
        """Say that a thread about to be started will take part (its
        :meth:`taking_part` is then called with ``announced=True``): time waits for it from
        now on, not only from when it gets to run."""

    def arrived(self) -> None:
        """Say that what was announced is taken in by a thread already taking part (a
        link handed to the thread that serves every link), or will not come."""

    @contextlib.contextmanager
    def taking_part(self, announced: bool = False) -> Iterator[None]:
        """Count the calling thread among those whose work comes before time moves on."""
        yield

    @contextlib.contextmanager
    def right_of_way(self) -> Iterator[None]:
        """Let the calling thread's work go first: a thread that calls :meth:`give_way`
        meanwhile waits until it is done.

        Two busy threads of one process take Python's interpreter lock in turn, each for
        a few milliseconds at a time (:func:`sys.setswitchinterval`). The runner's turn
        after a vehicle's event (its look, its step, its requests) would be spread over
        the link thread's reading of a whole burst of telemetry; with the right of way it
        is done in one piece, and the reading goes on after it.
        """
        way = self._way
        with way.cond:
            if not way.holders:
                way.stretch += 1
            way.holders += 1
        try:
            yield
        finally:
            with way.cond:
                way.holders -= 1
                if not way.holders:
                    way.cond.notify_all()

    def give_way(self) -> None:
        """Wait while a thread has the right of way (:meth:`right_of_way`), at most
        :data:`GIVE_WAY_LIMIT` wall seconds in one stretch of it; return at once otherwise.

        A thread that gives way holds no lock the one with the right of way could need.
        The wait is on the wall clock, outside this time base: in lock-step, time does not
        move on meanwhile, as for any thread taking part that has work."""
        way = self._way
        if not way.holders:  # nearly always: read without the lock, a stretch missed is harmless
            return
        with way.cond:
            stretch, deadline = way.stretch, time.monotonic() + GIVE_WAY_LIMIT
            while way.holders and way.stretch == stretch and way.outlasted != stretch:
                left = deadline - time.monotonic()
                if left <= 0:
                    way.outlasted = stretch
                    return
                way.cond.wait(left)


SYSTEM = Timebase()
"""The time of real vehicles."""


@dataclass(eq=False)
class _Wait:
    """One thread waiting in a :class:`Lockstep`."""

    thread: int
    deadline: float
    cond: threading.Condition | None = None
    fileno: int = -1
    woken: bool = False
    pipe: tuple[int, int] | None = None  # wakes a socket wait


@dataclass
class _Pipes:
    """A pipe per thread that waits on sockets, made once and kept."""

    by_thread: dict[int, tuple[int, int]] = field(default_factory=dict)

    def get(self, thread: int) -> tuple[int, int]:
        pipe = self.by_thread.get(thread)
        if pipe is None:
            pipe = self.by_thread[thread] = os.pipe()
            os.set_blocking(pipe[0], False)
            os.set_blocking(pipe[1], False)
        return pipe


class Lockstep(Timebase):
    """A simulator's time, advanced by the simulator when tml has nothing left to do (see
    the module docstring). Starts at 0."""

    lockstep = True

    def __init__(self, stall_after: float = 5.0) -> None:
        super().__init__()
        self.stall_after = stall_after
        self.stalls = 0
        """Times time moved on before every thread taking part waited (0 when all is well)."""
        self._time = 0.0
        # Re-entrant: a signal handler (Ctrl-C setting the runner's wake flag) may run on a
        # thread that holds it.
        self._lock = threading.RLock()
        self._parts: dict[int, _Wait | None] = {}  # thread taking part -> its wait or None
        self._depth: dict[int, int] = {}  # thread taking part -> nested taking_part calls
        self._announced = 0  # threads started to take part that have not said so yet
        self._in_flight: dict[object, int] = {}  # connection -> bytes sent, not read yet
        self._waits: set[_Wait] = set()
        self._on_cond: dict[int, set[_Wait]] = {}  # id(condition) -> its waits
        self._pipes = _Pipes()
        self._settling = threading.Condition(self._lock)  # a thread taking part began to wait
        self._unsettled_since: float | None = None

    # --- time --------------------------------------------------------------------------

    def now(self) -> float:
        return self._time

    def advance(self, to: float) -> None:
        """Make it ``to`` seconds (never back). The waits whose deadline came end only at
        :meth:`fire`: what the vehicles said at this instant is handled first."""
        with self._lock:
            self._time = max(self._time, to)

    def fire(self) -> bool:
        """End the waits whose deadline came; False when there were none."""
        due: list[_Wait] = []
        with self._lock:
            for w in self._waits:
                if not w.woken and w.deadline <= self._time:
                    self._wake(w)
                    due.append(w)
        self._rouse(due)
        return bool(due)

    # --- the waits -----------------------------------------------------------------------

    def wait(self, cond: threading.Condition, timeout: float | None) -> None:
        me = threading.get_ident()
        w = _Wait(me, math.inf if timeout is None else self._time + max(timeout, 0.0),
                  cond=cond)
        with self._lock:
            if w.deadline <= self._time:
                return
            self._enter(w)
            self._on_cond.setdefault(id(cond), set()).add(w)
        try:
            while not w.woken:
                cond.wait(GUARD)
        finally:
            with self._lock:
                self._leave(w)
                waits = self._on_cond.get(id(cond))
                if waits is not None:
                    waits.discard(w)
                    if not waits:
                        del self._on_cond[id(cond)]

    def notify_all(self, cond: threading.Condition) -> None:
        with self._lock:
            for w in self._on_cond.get(id(cond), ()):
                self._wake(w)
        cond.notify_all()

    def wait_readable(self, fileno: int, timeout: float) -> None:
        me = threading.get_ident()
        with self._lock:
            pipe = self._pipes.get(me)
            w = _Wait(me, self._time + max(timeout, 0.0), fileno=fileno, pipe=pipe)
            if w.deadline <= self._time:
                return
            self._enter(w)
        try:
            while not w.woken:
                ready, _, _ = select.select([fileno, pipe[0]], [], [], GUARD)
                if pipe[0] in ready:
                    with contextlib.suppress(BlockingIOError):
                        os.read(pipe[0], 512)
                if fileno in ready:
                    break
        finally:
            with self._lock:
                self._leave(w)

    def wait_ready(self, selector: selectors.BaseSelector, timeout: float
                   ) -> list[tuple[selectors.SelectorKey, int]]:
        ready = selector.select(0)
        if ready:
            return ready
        me = threading.get_ident()
        with self._lock:
            pipe = self._pipes.get(me)
            w = _Wait(me, self._time + max(timeout, 0.0), pipe=pipe)
            if w.deadline <= self._time:
                return []
            self._enter(w)
        selector.register(pipe[0], selectors.EVENT_READ, None)
        try:
            while not w.woken:
                ready = selector.select(GUARD)
                if any(key.fd == pipe[0] for key, _ in ready):
                    with contextlib.suppress(BlockingIOError):
                        os.read(pipe[0], 512)
                    ready = [(key, events) for key, events in ready if key.fd != pipe[0]]
                if ready:
                    return ready
            return []
        finally:
            selector.unregister(pipe[0])
            with self._lock:
                self._leave(w)

    def track(self, connection: object) -> None:
        with self._lock:
            self._in_flight.setdefault(connection, 0)

    def carried(self, connection: object, sent: int) -> None:
        with self._lock:
            if connection in self._in_flight:
                self._in_flight[connection] += sent

    def sleep(self, seconds: float) -> None:
        cond = threading.Condition()
        with cond:
            self.wait(cond, seconds)

    def announce(self) -> None:
        with self._lock:
            self._announced += 1

    def arrived(self) -> None:
        with self._lock:
            self._announced -= 1
            self._settling.notify_all()

    @contextlib.contextmanager
    def taking_part(self, announced: bool = False) -> Iterator[None]:
        me = threading.get_ident()
        with self._lock:
            if announced:
                self._announced -= 1
            self._depth[me] = self._depth.get(me, 0) + 1
            self._parts.setdefault(me, None)
        try:
            yield
        finally:
            pipe = None
            with self._lock:
                self._depth[me] -= 1
                if not self._depth[me]:
                    del self._depth[me]
                    self._parts.pop(me, None)
                    pipe = self._pipes.by_thread.pop(me, None)
                    self._settling.notify_all()
            if pipe is not None:
                for end in pipe:
                    os.close(end)

    # --- for the simulator -------------------------------------------------------------

    def settled(self) -> bool:
        """True when every thread taking part waits and every byte sent has been read."""
        with self._lock:
            if (self._announced or any(w is None for w in self._parts.values())
                    or any(self._in_flight.values())):
                return self._stalled()
        self._unsettled_since = None
        return True

    def wait_settled(self, timeout: float) -> None:
        """Sleep until a thread taking part begins to wait, or ``timeout`` wall seconds."""
        with self._lock:
            if self._announced or any(w is None for w in self._parts.values()):
                self._settling.wait(timeout)

    def _stalled(self) -> bool:
        now = time.monotonic()
        if self._unsettled_since is None:
            self._unsettled_since = now
            return False
        if now - self._unsettled_since < self.stall_after:
            return False
        self.stalls += 1
        self._unsettled_since = None
        return True

    # --- bookkeeping (self._lock held) ---------------------------------------------------

    def _enter(self, w: _Wait) -> None:
        self._waits.add(w)
        if w.thread in self._parts:
            self._parts[w.thread] = w
            self._settling.notify_all()

    def _leave(self, w: _Wait) -> None:
        self._waits.discard(w)
        if self._parts.get(w.thread) is w:
            self._parts[w.thread] = None

    def _wake(self, w: _Wait) -> None:
        w.woken = True
        if self._parts.get(w.thread) is w:
            self._parts[w.thread] = None  # running from now on, before it is scheduled

    @staticmethod
    def _rouse(due: list[_Wait]) -> None:
        """Wake the threads of ``due`` (self._lock not held: a condition's own lock is
        taken here, and a thread holding it may be waiting for self._lock)."""
        for w in due:
            if w.cond is not None:
                with w.cond:
                    w.cond.notify_all()
            elif w.pipe is not None:
                with contextlib.suppress(OSError):
                    os.write(w.pipe[1], b"!")


class Flag:
    """:class:`threading.Event` whose wait goes through a time base."""

    def __init__(self, timebase: Timebase = SYSTEM) -> None:
        self.timebase = timebase
        self._cond = threading.Condition()
        self._set = False

    def set(self) -> None:
        if self._set:
            # A waiter sees it set, or has been woken already: a link sets it on every
            # message that changes a vehicle, and the lock and notify cost each of them.
            return
        with self._cond:
            self._set = True
            self.timebase.notify_all(self._cond)

    def clear(self) -> None:
        with self._cond:
            self._set = False

    def is_set(self) -> bool:
        return self._set

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until set, or ``timeout`` seconds of the time base; True when set."""
        with self._cond:
            if not self._set:
                self.timebase.wait(self._cond, timeout)
            return self._set
