"""What the commands do on SIGINT (Ctrl-C) and SIGTERM: one way to take them over."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from typing import Any

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that ask a command to stop: each command makes them end it cleanly."""


class Stopped(KeyboardInterrupt):
    """A stop signal ended a command before it had anything to make safe (``tml run``
    waiting for a vehicle's first heartbeat). A KeyboardInterrupt, outside tml's error
    hierarchy on purpose: raised from a signal handler wherever the main thread is, it must
    not be taken for an error by an ``except Exception`` on the way (pymavlink's connect
    retries on any Exception)."""

    def __init__(self, signal_name: str, on_taken: Callable[[], None] | None = None) -> None:
        self.signal_name = signal_name
        self._on_taken = on_taken
        super().__init__(f"interrupted ({signal_name})")

    def taken(self) -> None:
        """Say that a command caught this stop and ends because of it: it is raised no
        more (:class:`StopSignals` raises it again only in case a library swallowed it,
        and would otherwise interrupt the command's own clean-up on a slow machine)."""
        if self._on_taken is not None:
            self._on_taken()


AGAIN_AFTER = 1.0
"""Seconds after which :class:`StopSignals` raises :class:`Stopped` again, and again."""


@contextlib.contextmanager
def on_stop_signals(handler: Callable[[str], None]) -> Iterator[None]:
    """Call ``handler(name)`` ("SIGINT", "SIGTERM") on a stop signal while this holds, then
    put the previous handlers back. Off the main thread (a command called from a test's or
    a service's thread) signals cannot be taken, and nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def take(number: int, _frame: object) -> None:
        handler(signal.Signals(number).name)

    previous = {sig: signal.signal(sig, take) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


class StopSignals:
    """While this holds (``with``), a stop signal raises :class:`Stopped` where the main
    thread is -- and raises it again every :data:`AGAIN_AFTER` s until the block is left:
    a library's bare ``except:`` may swallow it (pymavlink's own import of curses does),
    and a Ctrl-C must not be lost to that. :attr:`received` tells which came, if any."""

    def __init__(self) -> None:
        self.received: str | None = None
        self._held: contextlib.ExitStack | None = None
        self._alarm: Any = None

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            self._alarm = signal.getsignal(signal.SIGALRM)
            self._held = contextlib.ExitStack()
            self._held.enter_context(on_stop_signals(self._stop))
        return self

    def __exit__(self, *exc: object) -> None:
        if self._held is not None:
            self._held.close()
            if self.received is not None:
                signal.setitimer(signal.ITIMER_REAL, 0)
                signal.signal(signal.SIGALRM, self._alarm)

    def _stop(self, name: str) -> None:
        if self.received is None:
            self.received = name
            signal.signal(signal.SIGALRM, lambda _number, _frame: self._stop(name))
            signal.setitimer(signal.ITIMER_REAL, AGAIN_AFTER, AGAIN_AFTER)
        raise Stopped(name, on_taken=self._taken)

    def _taken(self) -> None:
        signal.setitimer(signal.ITIMER_REAL, 0)  # a new signal still raises Stopped
