"""What the commands do on SIGINT (Ctrl-C) and SIGTERM: one way to take them over."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that ask a command to stop: each command makes them end it cleanly."""


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
