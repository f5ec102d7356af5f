"""The GUIDED target a vehicle reports: POSITION_TARGET_GLOBAL_INT and _LOCAL_NED.

A hold in GUIDED is undone by the next target another ground station sends; the vehicle
says what it now flies to. ArduCopter (4.7.0-dev SITL, measured) reports, once asked for
them (SET_MESSAGE_INTERVAL), and in GUIDED only: flying to a point,
POSITION_TARGET_GLOBAL_INT (frame GLOBAL, type_mask 65016: the position alone) and
POSITION_TARGET_LOCAL_NED (type_mask 3576); under a velocity target, POSITION_TARGET_LOCAL_NED
alone (type_mask 3079: the velocity alone); in BRAKE, neither. :class:`TargetWatch` keeps
the latest of them as a :class:`GuidedTarget`: how far from the vehicle a position target
is, how fast a velocity target goes.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any

from tml.geo import to_local
from tml.mavlink.autopilot import Autopilot
from tml.mavlink.link import Link
from tml.mavlink.telemetry import Telemetry

RATE = 2.0  # Hz asked for each of the two messages
POSITION_IGNORED = 0b111  # type_mask bits: x, y, z ignored
VELOCITY_IGNORED = 0b111000  # type_mask bits: vx, vy, vz ignored


@dataclass(frozen=True)
class GuidedTarget:
    """The target a vehicle reported in GUIDED."""

    received: float  # when it arrived (the link's time, s)
    distance: float | None = None  # m from the vehicle, horizontally (a position target)
    speed: float | None = None  # m/s, horizontally (a velocity target)

    def describe(self) -> str:
        """In a few words: "GUIDED target 152 m away", "GUIDED target velocity 0.0 m/s"."""
        words = []
        if self.distance is not None:
            words.append(f"{self.distance:.0f} m away")
        if self.speed is not None:
            words.append(f"velocity {self.speed:.1f} m/s")
        return f"GUIDED target {', '.join(words)}" if words else "GUIDED target"


class TargetWatch:
    """The latest GUIDED target vehicle ``system_id`` on ``link`` reported (None until it
    reports one after :meth:`clear`)."""

    def __init__(self, link: Link, system_id: int) -> None:
        self.system_id = system_id
        self.latest: GuidedTarget | None = None
        self._lock = threading.Lock()
        link.listen(self._on_message)

    def ask(self, mav: Autopilot) -> None:
        """Ask the vehicle for both messages (without waiting for its answer)."""
        for name in ("POSITION_TARGET_GLOBAL_INT", "POSITION_TARGET_LOCAL_NED"):
            mav.ask_again(name, RATE)

    def clear(self) -> None:
        """Forget what was reported so far (before a command)."""
        with self._lock:
            self.latest = None

    def _on_message(self, system_id: int, snapshot: Telemetry, msg: Any) -> None:
        if system_id != self.system_id:
            return
        kind = msg.get_type()
        if kind not in ("POSITION_TARGET_GLOBAL_INT", "POSITION_TARGET_LOCAL_NED"):
            return
        mask = int(msg.type_mask)
        distance = speed = None
        if kind == "POSITION_TARGET_GLOBAL_INT" and not mask & POSITION_IGNORED \
                and snapshot.position is not None:
            here = snapshot.position
            north, east, _ = to_local(msg.lat_int / 1e7, msg.lon_int / 1e7, 0.0,
                                      here.latitude, here.longitude, 0.0)
            distance = math.hypot(north, east)
        if not mask & VELOCITY_IGNORED:
            speed = math.hypot(msg.vx, msg.vy)
        if distance is None and speed is None:
            return  # a local position target: its distance is the global one's
        with self._lock:
            self.latest = GuidedTarget(snapshot.time, distance, speed)
