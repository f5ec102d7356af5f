"""Reading a child process's output line by line while a test waits for what it prints."""

from __future__ import annotations

import contextlib
import queue
import re
import threading
import time
from collections.abc import Iterable, Iterator


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


@contextlib.contextmanager
def simulator(*args: str, within: float = 120.0) -> Iterator[int]:
    """``python -m sitl ARGS`` in its own process on a free TCP port; yields vehicle 1's
    port once the simulator has said it listens, and stops it (by its pid) after."""
    import subprocess
    import sys

    process = subprocess.Popen([sys.executable, "-m", "sitl", "--tcp-base-port", "0", *args],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert process.stdout is not None
        seen: list[str] = []
        wait_for(follow(process.stdout), seen, r"^vehicle 1: tcp:", time.monotonic() + within,
                 "python -m sitl")
        found = re.search(r"tcp:127\.0\.0\.1:(\d+)", "".join(seen))
        assert found, seen
        yield int(found.group(1))
    finally:
        process.terminate()
        try:
            process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
