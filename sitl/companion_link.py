"""The simulated companion computer attached to an autopilot from outside: ``CompanionLink``.

Theory of operation. A real companion computer is wired to a second serial port of the
autopilot and speaks MAVLink as one more component of the vehicle; the autopilot routes
its messages to the ground station and the ground station's messages to it (ArduPilot:
GCS_MAVLink/MAVLink_routing.cpp). :class:`CompanionLink` is :class:`sitl.companion.Companion`
(the embedded simulator's onboard computer, component 191) attached that way to any
autopilot at a pymavlink connection address, e.g. ArduPilot SITL's SERIAL1
(``tcp:127.0.0.1:5762``):

1. It waits for the autopilot's HEARTBEAT (autopilot not INVALID, not a ground station or
   another onboard computer) and takes its system id, unless one is given, and its
   component id; from then on it sends as component 191 of that system.
2. It asks the autopilot, on its own port, for ATTITUDE and GLOBAL_POSITION_INT at
   :data:`POSITION_RATE` Hz and HOME_POSITION at :data:`HOME_RATE` Hz
   (MAV_CMD_SET_MESSAGE_INTERVAL), and asks again while they do not come.
3. Each ATTITUDE or GLOBAL_POSITION_INT advances the companion's clock to the autopilot's
   ``time_boot_ms`` (so a sped-up SITL is followed in vehicle seconds, and detections are
   stamped with the autopilot's own time) and steps the companion: HEARTBEAT at 1 Hz,
   detection reports at ``DET_RATE``. Its position is GLOBAL_POSITION_INT's latitude and
   longitude in metres north/east of the world's home (the frame the world's objects are
   given in), or of the vehicle's HOME_POSITION when the world names no home, and its
   ``relative_alt`` above home; its heading is ATTITUDE's yaw. Before the position is known
   (no fix yet: lat = lon = 0) only the HEARTBEAT goes out.
4. Messages addressed to system/component 191 (the parameter protocol: PARAM_SET switches
   the skills, PARAM_REQUEST_READ/LIST) are answered by the companion.

A clock that goes back (the autopilot rebooted) starts a fresh companion, skills off, as
a real onboard computer would see its autopilot come back.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable
from typing import Any

os.environ.setdefault("MAVLINK20", "1")  # mavutil picks the protocol when first imported

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.companion import Companion
from sitl.messages import COMPANION
from sitl.obstacles import Obstacles
from tml.errors import LinkLost
from tml.geo import to_local
from tml.world import Home, World

POSITION_RATE = 10.0
"""Hz of ATTITUDE and GLOBAL_POSITION_INT asked for (vehicle time)."""
HOME_RATE = 0.5
"""Hz of HOME_POSITION asked for."""
REQUEST_AGAIN = 2.0
"""Wall seconds without position or attitude after which the streams are asked for again."""
NOT_AUTOPILOTS = frozenset({mavlink.MAV_TYPE_GCS, mavlink.MAV_TYPE_ONBOARD_CONTROLLER})

Vector = tuple[float, float, float]


class CompanionLink:
    """Component 191 of the vehicle at ``address``, seeing ``world`` (see the module doc).

    ``system_id`` is the vehicle's system id (None: the first autopilot heard);
    ``on_text`` receives a line for each first sighting ("Detected item 1 A").
    """

    def __init__(self, address: str, world: World, *, system_id: int | None = None,
                 on_text: Callable[[str], None] | None = None) -> None:
        self.address = address
        self.world = world
        self.system_id = system_id
        self.autopilot_component: int | None = None
        self.on_text = on_text
        self.time = 0.0  # the autopilot's clock, seconds since boot
        self.heading = 0.0
        self.home: Home | None = None  # the vehicle's HOME_POSITION
        self.position: Vector | None = None
        self._fix: tuple[float, float, float] | None = None  # lat, lon, relative alt
        self._obstacles = Obstacles(world)
        self.companion = self._new_companion(system_id or 0)
        self._conn: Any = None
        self._last_stream = 0.0
        self._last_request = -math.inf
        self.autopilots: set[int] = set()
        """The system ids of the autopilots heard while :meth:`open` waited."""

    # ----------------------------------------------------------------- life cycle
    def open(self, timeout: float, stop: threading.Event | None = None,
             listen: float = 0.0) -> bool:
        """Connect (retrying until ``timeout`` s) and wait for the autopilot's HEARTBEAT;
        False when ``stop`` was set meanwhile. Without a system id, other autopilots on
        the link (a router's) have ``listen`` s more to be heard (:attr:`autopilots`).

        Raises :class:`~tml.errors.LinkLost` when the address cannot be opened or no
        autopilot is heard within ``timeout`` s.
        """
        end = time.monotonic() + timeout
        stop = stop or threading.Event()
        while self._conn is None:
            if stop.is_set():
                return False
            try:
                self._conn = mavutil.mavlink_connection(
                    self.address, source_system=self.system_id or 1,
                    source_component=COMPANION, dialect="ardupilotmega", autoreconnect=True)
            except (OSError, ValueError) as error:
                if time.monotonic() >= end:
                    # pyserial's words repeat the device and the errno: the system's cause
                    # is what it wraps.
                    cause = error.__context__ if isinstance(error.__context__, OSError) \
                        else error
                    why = cause.strerror if isinstance(cause, OSError) and cause.strerror \
                        else cause
                    raise LinkLost(f"cannot open MAVLink connection {self.address!r}: "
                                   f"{why}") from None
                time.sleep(0.5)
        while self.autopilot_component is None:
            if stop.is_set():
                return False
            left = end - time.monotonic()
            if left <= 0:
                who = "an autopilot" if self.system_id is None else \
                    f"the autopilot of system {self.system_id}"
                raise LinkLost(f"no heartbeat from {who} on {self.address} within "
                               f"{timeout:g} s")
            msg = self._receive(min(left, 0.2))
            if msg is not None and self._is_autopilot_heartbeat(msg):
                self.autopilots.add(msg.get_srcSystem())
                if self.system_id is None:
                    end = time.monotonic() + listen
                    while (left := end - time.monotonic()) > 0 and not stop.is_set():
                        more = self._receive(min(left, 0.2))
                        if more is not None and self._is_autopilot_heartbeat(more):
                            self.autopilots.add(more.get_srcSystem())
                self.attach(self._conn, msg.get_srcSystem(), msg.get_srcComponent())
        return True

    def attach(self, conn: Any, system_id: int, autopilot_component: int) -> None:
        """Speak on ``conn`` (a pymavlink connection) as component 191 of ``system_id``,
        whose autopilot is ``autopilot_component``, and ask for the streams."""
        self._conn = conn
        self.system_id, self.autopilot_component = system_id, autopilot_component
        conn.mav.srcSystem, conn.mav.srcComponent = system_id, COMPANION
        self.companion = self._new_companion(system_id)
        self._request_streams()

    def close(self) -> None:
        """Close the connection."""
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    def serve(self, stop: threading.Event) -> None:
        """Answer the autopilot until ``stop`` is set (after :meth:`open`)."""
        while not stop.is_set():
            self.poll(0.1)

    def poll(self, timeout: float = 0.0) -> None:
        """Handle what arrives within ``timeout`` s (everything already waiting, at least)."""
        msg = self._receive(timeout)
        while msg is not None:
            self.handle(msg)
            msg = self._receive(0.0)
        if time.monotonic() - self._last_stream > REQUEST_AGAIN:
            self._request_streams()

    # ------------------------------------------------------------------ messages
    def handle(self, msg: Any) -> None:
        """Take one message from the link: the autopilot's telemetry, or one for us."""
        if getattr(msg, "target_component", None) == COMPANION:
            if getattr(msg, "target_system", 0) in (0, self.system_id):
                self._send(self.companion.handle(msg))
            return
        if (msg.get_srcSystem(), msg.get_srcComponent()) != (self.system_id,
                                                             self.autopilot_component):
            return
        kind = msg.get_type()
        if kind == "HOME_POSITION":
            self.home = Home(msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0)
            self._locate()
        elif kind == "GLOBAL_POSITION_INT":
            self._fix = None if msg.lat == 0 and msg.lon == 0 else (
                msg.lat / 1e7, msg.lon / 1e7, msg.relative_alt / 1000.0)
            self._locate()
            self._tick(msg.time_boot_ms)
        elif kind == "ATTITUDE":
            self.heading = math.degrees(msg.yaw) % 360.0
            self._tick(msg.time_boot_ms)

    def _locate(self) -> None:
        reference = self.world.home or self.home
        if self._fix is None or reference is None:
            self.position = None
            return
        latitude, longitude, up = self._fix
        north, east, _ = to_local(latitude, longitude, reference.altitude,
                                  reference.latitude, reference.longitude, reference.altitude)
        self.position = (north, east, up)

    def _tick(self, time_boot_ms: int) -> None:
        self._last_stream = time.monotonic()
        now = time_boot_ms / 1000.0
        if now < self.time - 1.0:  # the autopilot rebooted
            self.companion = self._new_companion(self.system_id or 0)
        self.time = now
        out = self.companion.step(now, self.position, self.heading)
        self._send(out)
        if self.on_text is not None:
            for msg in out:
                if msg.get_type() == "STATUSTEXT":
                    self.on_text(msg.text if isinstance(msg.text, str) else msg.text.decode())

    def _request_streams(self) -> None:
        """SET_MESSAGE_INTERVAL for what the companion needs, on its own port."""
        now = time.monotonic()
        if self._conn is None or self.autopilot_component is None or \
                now - self._last_request < REQUEST_AGAIN:
            return
        self._last_request = now
        for msg_id, rate in ((mavlink.MAVLINK_MSG_ID_ATTITUDE, POSITION_RATE),
                             (mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, POSITION_RATE),
                             (mavlink.MAVLINK_MSG_ID_HOME_POSITION, HOME_RATE)):
            self._command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / rate)
        self._command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_HOME_POSITION)

    def _command(self, command: int, *params: float) -> None:
        p = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
        self._conn.mav.command_long_send(self.system_id, self.autopilot_component, command,
                                         0, *p)

    def _send(self, messages: list[Any]) -> None:
        for msg in messages:
            self._conn.mav.send(msg)

    def _receive(self, timeout: float) -> Any:
        """The next message within ``timeout`` s (None: nothing), skipping bad data."""
        end = time.monotonic() + timeout
        while True:
            left = end - time.monotonic()
            msg = self._conn.recv_match(blocking=left > 0, timeout=max(left, 0.0))
            if msg is None or msg.get_type() != "BAD_DATA":
                return msg

    def _is_autopilot_heartbeat(self, msg: Any) -> bool:
        return (msg.get_type() == "HEARTBEAT"
                and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID
                and msg.type not in NOT_AUTOPILOTS
                and self.system_id in (None, msg.get_srcSystem()))

    def _new_companion(self, system_id: int) -> Companion:
        return Companion(system_id, self.world, self._nearest_obstacle)

    def _nearest_obstacle(self, position: Vector) -> float | None:
        return self._obstacles.nearest(position)
