"""The process's heap while runs fly: what was there before is kept out of the garbage
collector's passes.

CPython's cyclic garbage collector stops every thread while it runs, and a pass over the
oldest generation visits every object the process holds: with a fleet connected (its links,
the parsers' message classes, the mission) that was 37 ms of CPU (83 ms of wall time) at
500 vehicles, long enough for an event's command to wait behind it (docs/performance.md,
*Fewer looks, a quiet collector*). What exists when the first run starts to fly lives as
long as the runs, so :func:`frozen` moves it out of the collector's reach (:func:`gc.freeze`)
while any run flies, and gives it back (:func:`gc.unfreeze`) when the last one ends: cycles
that were garbage already are collected then, nothing is lost. A run that begins while
another flies freezes nothing more, so a service whose runs overlap for days keeps no more
out of reach than there was at the first: what came since is collected as ever. Freezing
and thawing move lists, not objects: they cost nothing at any size, and nothing is
collected on the way.
"""

from __future__ import annotations

import gc
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_lock = threading.Lock()
_flying = 0  # runs inside frozen() (tml serve flies several at once)


@contextmanager
def frozen() -> Iterator[None]:
    """While the block runs (a run flies), the objects that existed when the first of the
    blocks running began are not visited by the garbage collector."""
    global _flying
    with _lock:
        if not _flying:
            gc.freeze()
        _flying += 1
    try:
        yield
    finally:
        with _lock:
            _flying -= 1
            if not _flying:
                gc.unfreeze()
