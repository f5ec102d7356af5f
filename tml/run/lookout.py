"""Which of a crew's vehicles a wake of the runner must look at.

A vehicle that can say when it changed (:meth:`tml.mavlink.adapter.MavlinkVehicle.watch`)
is *stirred* from the thread that saw the change -- the link's reactor, on a message or on a
request's result -- and a wake looks at the stirred vehicles, at those whose
own time is due (the state's refresh, the telemetry line), and at those whose last look
left something to follow (a lost link being timed). The others are not touched: in a fleet
of hundreds, most vehicles at most wakes. Without it, every wake walked every vehicle to
ask whether it changed (docs/performance.md, *Fleet*).

A stir is taken back (:meth:`Lookout.due` clears it) before the vehicle's state is read, so
a change that comes meanwhile is either in that state or stirs it again for the next wake:
none is lost.
"""

from __future__ import annotations

import heapq
import math
from collections import deque


class Lookout:
    """The stirred, due and followed vehicles of ``count``, numbered from 0."""

    def __init__(self, count: int) -> None:
        # Every vehicle is looked at by the first wake: there is no state of it yet.
        self._stirred: deque[int] = deque(range(count))
        self._flagged = [True] * count  # in _stirred already (a stir need not add it)
        self._at = [math.inf] * count  # when each is due by its own time
        self._timers: list[tuple[float, int]] = []  # heap; entries not in _at are stale
        self._following: set[int] = set()

    def stir(self, index: int) -> None:
        """Vehicle ``index`` changed: the next wake looks at it (any thread)."""
        if not self._flagged[index]:
            self._flagged[index] = True
            self._stirred.append(index)

    def due(self, now: float) -> list[int]:
        """The vehicles a wake at ``now`` looks at, in their order; their stirs taken back."""
        picked = set(self._following)
        stirred, flagged = self._stirred, self._flagged
        while stirred:
            index = stirred.popleft()
            flagged[index] = False  # before its state is read (see the module docstring)
            picked.add(index)
        timers, at = self._timers, self._at
        while timers and timers[0][0] <= now:
            when, index = heapq.heappop(timers)
            if at[index] == when:
                picked.add(index)
        return sorted(picked)

    def looked(self, index: int, due_at: float, following: bool) -> None:
        """Vehicle ``index`` was looked at: due again by its own time at ``due_at``, and at
        every wake while ``following``."""
        self._at[index] = due_at
        heapq.heappush(self._timers, (due_at, index))  # the one before it is stale now
        if following:
            self._following.add(index)
        else:
            self._following.discard(index)
