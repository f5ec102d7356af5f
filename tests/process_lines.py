"""Reading a child process's output line by line while a test waits for what it prints."""

from __future__ import annotations

import contextlib
import queue
import re
import threading
import time
from collections.abc import Iterable


def follow(stream: Iterable[str]) -> queue.Queue[str]:
    """A queue fed with each line of ``stream`` by a daemon thread."""
    sink: queue.Queue[str] = queue.Queue()

    def read() -> None:
        for line in stream:
            sink.put(line)

    threading.Thread(target=read, daemon=True).start()
    return sink


def wait_for(sink: queue.Queue[str], seen: list[str], pattern: str, deadline: float,
             who: str = "MAVProxy") -> None:
    """Move lines from ``sink`` to ``seen`` until one matches ``pattern``; fail the test at
    ``deadline`` (monotonic) showing the last lines."""
    while not any(re.search(pattern, line) for line in seen):
        remaining = deadline - time.monotonic()
        assert remaining > 0, f"{who} never printed {pattern!r}; got:\n{''.join(seen[-40:])}"
        with contextlib.suppress(queue.Empty):
            seen.append(sink.get(timeout=min(remaining, 0.5)))
