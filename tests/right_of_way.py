"""Another thread holding a time base's right of way (tml.timebase.Timebase.right_of_way)."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

from tml.timebase import Timebase


@contextmanager
def held_elsewhere(timebase: Timebase, nested: bool = False) -> Iterator[None]:
    """A thread has the right of way of ``timebase`` (twice, nested, if asked) from entry
    until exit, when it lets go of it and ends."""
    holding, release = threading.Event(), threading.Event()

    def go_first() -> None:
        with timebase.right_of_way():
            if nested:
                with timebase.right_of_way():
                    holding.set()
                    release.wait(120)
            else:
                holding.set()
                release.wait(120)

    holder = threading.Thread(target=go_first, name="right of way")
    holder.start()
    try:
        assert holding.wait(30), "the holder never got the right of way"
        yield
    finally:
        release.set()
        holder.join(30)
