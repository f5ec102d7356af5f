"""An independent ground station: plain pymavlink, none of tml's code.

It flies what a minimal ground station written for ArduCopter flies: connect, ask for the
streams it needs, select GUIDED, arm (retrying until the vehicle accepts), take off with
NAV_TAKEOFF, upload three waypoints and an RTL with the MAVLink mission protocol, read the
mission back, switch to AUTO, watch MISSION_ITEM_REACHED, and wait for the landing and the
disarm. The same client flies the simulator (tests/test_ground_station.py) and ArduCopter
SITL (tests/interop/test_ground_station_arducopter.py): a simulator kinder than ArduCopter
would let a client through that ArduCopter stops, and this is the check that it does not.

Times are wall-clock seconds: the client does not know how fast its vehicle's clock runs.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pymavlink import mavutil

M = mavutil.mavlink
GUIDED, AUTO = 4, 3  # ArduCopter's custom modes
ALTITUDE = 10.0  # m, take-off and waypoint altitude above home
LEGS = ((30.0, 0.0), (30.0, 30.0), (0.0, 30.0))  # waypoints, metres north/east of home
EARTH_RADIUS = 6378137.0


class GroundStationError(AssertionError):
    """The vehicle did not do what the ground station asked within the time allowed."""


@dataclass
class Flight:
    """What the ground station saw."""

    arm_refusals: list[str] = field(default_factory=list)  # STATUSTEXTs while arming failed
    arm_attempts: int = 0
    takeoff_result: int | None = None
    uploaded: list[tuple[int, int, int, float]] = field(default_factory=list)
    read_back: list[tuple[int, int, int, float]] = field(default_factory=list)
    reached: list[int] = field(default_factory=list)
    texts: list[str] = field(default_factory=list)
    landed_disarmed: bool = False


class GroundStation:
    """A pymavlink connection to one vehicle and the steps of the flight."""

    def __init__(self, address: str, timeout: float = 120.0) -> None:
        self.conn = mavutil.mavlink_connection(address, source_system=255,
                                               source_component=M.MAV_COMP_ID_MISSIONPLANNER)
        self.conn.WIRE_PROTOCOL_VERSION = "2.0"
        self.timeout = timeout
        self.flight = Flight()
        self.target = 0
        self.heartbeat: Any = None
        self.position: Any = None
        self._beat = 0.0

    def close(self) -> None:
        """Close the connection."""
        self.conn.close()

    # -- receiving ----------------------------------------------------------------------
    def _receive(self, wait: float) -> Any:
        now = time.monotonic()
        if now - self._beat >= 1.0:  # a ground station's own 1 Hz HEARTBEAT
            self._beat = now
            self.conn.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        msg = self.conn.recv_match(blocking=True, timeout=wait)
        if msg is None or msg.get_type() == "BAD_DATA":
            return None
        kind = msg.get_type()
        if self.target and msg.get_srcSystem() != self.target:
            return None
        if kind == "HEARTBEAT" and msg.get_srcComponent() == M.MAV_COMP_ID_AUTOPILOT1:
            self.heartbeat = msg
        elif kind == "GLOBAL_POSITION_INT":
            self.position = msg
        elif kind == "STATUSTEXT":
            self.flight.texts.append(msg.text)
        elif kind == "MISSION_ITEM_REACHED" and msg.seq not in self.flight.reached:
            self.flight.reached.append(msg.seq)
        return msg

    def wait(self, until: Callable[[Any], bool], what: str, timeout: float | None = None,
             every: Callable[[], None] | None = None, period: float = 0.5) -> Any:
        """Receive until ``until(msg)`` holds for a message; ``every()`` each ``period`` s."""
        end = time.monotonic() + (timeout or self.timeout)
        due = 0.0
        while time.monotonic() < end:
            if every is not None and time.monotonic() >= due:
                due = time.monotonic() + period
                every()
            msg = self._receive(0.05)
            if msg is not None and until(msg):
                return msg
        raise GroundStationError(f"{what}: not within {timeout or self.timeout:g} s; "
                                 f"last texts {self.flight.texts[-5:]}")

    @property
    def armed(self) -> bool:
        """The last autopilot HEARTBEAT says armed."""
        return bool(self.heartbeat and self.heartbeat.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)

    def command(self, command: int, *params: float) -> None:
        """Send COMMAND_LONG ``command`` with up to seven params."""
        values = [*params, *[0.0] * (7 - len(params))]
        self.conn.mav.command_long_send(self.target, 1, command, 0, *values)

    def ack(self, command: int, timeout: float = 5.0) -> int:
        """Send ``command`` until it is answered; the COMMAND_ACK's result."""
        return self.wait(lambda m: m.get_type() == "COMMAND_ACK" and m.command == command,
                         f"COMMAND_ACK {command}", timeout, every=lambda: None).result

    # -- the flight ---------------------------------------------------------------------
    def connect(self) -> None:
        """Wait for the autopilot's HEARTBEAT and ask for the streams the flight reads."""
        # ArduCopter replaces a mode selected while it boots: wait for it to be ready.
        self.wait(lambda m: m.get_type() == "HEARTBEAT"
                  and m.get_srcComponent() == M.MAV_COMP_ID_AUTOPILOT1
                  and m.system_status not in (M.MAV_STATE_UNINIT, M.MAV_STATE_BOOT),
                  "HEARTBEAT after the boot")
        self.target = self.heartbeat.get_srcSystem()
        for stream in (M.MAV_DATA_STREAM_POSITION, M.MAV_DATA_STREAM_EXTENDED_STATUS,
                       M.MAV_DATA_STREAM_EXTRA3):
            self.conn.mav.request_data_stream_send(self.target, 1, stream, 4, 1)
        self.wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT", "GLOBAL_POSITION_INT",
                  every=lambda: self.conn.mav.request_data_stream_send(
                      self.target, 1, M.MAV_DATA_STREAM_POSITION, 4, 1), period=2.0)

    def set_mode(self, mode: int) -> None:
        """DO_SET_MODE, once accepted (no retry on a refusal), until a HEARTBEAT shows it."""
        result = self.wait(
            lambda m: m.get_type() == "COMMAND_ACK" and m.command == M.MAV_CMD_DO_SET_MODE,
            f"mode {mode} answered", every=lambda: self.command(
                M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode),
            period=2.0).result
        if result != M.MAV_RESULT_ACCEPTED:
            raise GroundStationError(f"mode {mode} refused ({result}); "
                                     f"last texts {self.flight.texts[-5:]}")
        self.wait(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1
                  and m.custom_mode == mode, f"mode {mode} in HEARTBEAT")

    def arm(self) -> None:
        """Arm, retrying every half second until the vehicle accepts."""
        def attempt() -> None:
            self.flight.arm_attempts += 1
            self.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)

        def answered(msg: Any) -> bool:
            if msg.get_type() == "STATUSTEXT" and not self.armed:
                self.flight.arm_refusals.append(msg.text)
            return (msg.get_type() == "COMMAND_ACK" and msg.command ==
                    M.MAV_CMD_COMPONENT_ARM_DISARM and msg.result == M.MAV_RESULT_ACCEPTED)

        self.wait(answered, "arming accepted", every=attempt)

    def take_off(self) -> None:
        """NAV_TAKEOFF to :data:`ALTITUDE`, and wait until nearly there."""
        self.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, ALTITUDE)
        self.flight.takeoff_result = self.ack(M.MAV_CMD_NAV_TAKEOFF)
        if self.flight.takeoff_result != M.MAV_RESULT_ACCEPTED:
            raise GroundStationError(f"NAV_TAKEOFF answered {self.flight.takeoff_result}; "
                                     f"last texts {self.flight.texts[-5:]}")
        self.wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT"
                  and m.relative_alt > (ALTITUDE - 1.0) * 1000, "take-off altitude")

    def _items(self) -> list[tuple[int, int, int, float]]:
        """(command, lat 1e7, lon 1e7, alt) of items 1.. : three waypoints, then RTL."""
        home_lat, home_lon = self.position.lat / 1e7, self.position.lon / 1e7
        items = []
        for north, east in LEGS:
            lat = home_lat + math.degrees(north / EARTH_RADIUS)
            lon = home_lon + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(home_lat))))
            items.append((M.MAV_CMD_NAV_WAYPOINT, round(lat * 1e7), round(lon * 1e7), ALTITUDE))
        items.append((M.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0.0))
        return items

    def upload(self) -> None:
        """The mission protocol's upload: seq 0 is home (the vehicle overwrites it)."""
        items = [(M.MAV_CMD_NAV_WAYPOINT, 0, 0, 0.0), *self._items()]
        self.flight.uploaded = items[1:]

        def send(seq: int) -> None:
            command, lat, lon, alt = items[seq]
            self.conn.mav.mission_item_int_send(
                self.target, 1, seq, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, command, 0, 1,
                0, 0, 0, 0, lat, lon, alt, M.MAV_MISSION_TYPE_MISSION)

        def answer(msg: Any) -> bool:
            if msg.get_type() in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
                send(msg.seq)
            return msg.get_type() == "MISSION_ACK"

        self.conn.mav.mission_count_send(self.target, 1, len(items), M.MAV_MISSION_TYPE_MISSION)
        ack = self.wait(answer, "MISSION_ACK", 30.0)
        if ack.type != M.MAV_MISSION_ACCEPTED:
            raise GroundStationError(f"upload answered MISSION_ACK {ack.type}")

    def download(self) -> None:
        """The mission protocol's download of items 1.. (item 0 is home)."""
        self.conn.mav.mission_request_list_send(self.target, 1, M.MAV_MISSION_TYPE_MISSION)
        count = self.wait(lambda m: m.get_type() == "MISSION_COUNT", "MISSION_COUNT", 10.0).count
        for seq in range(1, count):
            item = self.wait(
                lambda m, seq=seq: m.get_type() == "MISSION_ITEM_INT" and m.seq == seq,
                f"MISSION_ITEM_INT {seq}", 10.0,
                every=lambda seq=seq: self.conn.mav.mission_request_int_send(
                    self.target, 1, seq, M.MAV_MISSION_TYPE_MISSION), period=1.0)
            self.flight.read_back.append((item.command, item.x, item.y, item.z))
        self.conn.mav.mission_ack_send(self.target, 1, M.MAV_MISSION_ACCEPTED,
                                       M.MAV_MISSION_TYPE_MISSION)

    def fly_mission(self) -> None:
        """AUTO, then wait for the landing and the disarm (RTL ends the mission)."""
        self.set_mode(AUTO)
        self.wait(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1
                  and not self.armed, "disarmed after the landing")
        altitude = self.wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT",
                             "position after landing").relative_alt / 1000
        self.flight.landed_disarmed = altitude < 1.0


def fly(address: str, timeout: float = 120.0) -> Flight:
    """Fly the whole flight against the vehicle at ``address``; what was seen."""
    station = GroundStation(address, timeout)
    try:
        station.connect()
        station.set_mode(GUIDED)
        station.arm()
        station.take_off()
        station.upload()
        station.download()
        station.fly_mission()
    finally:
        station.close()
    return station.flight


def same_mission(sent: list[tuple[int, int, int, float]],
                 read: list[tuple[int, int, int, float]]) -> bool:
    """Commands and positions equal (the frame is not compared: ArduPilot normalises it)."""
    return len(sent) == len(read) and all(
        a[0] == b[0] and abs(a[1] - b[1]) <= 1 and abs(a[2] - b[2]) <= 1
        and abs(a[3] - b[3]) < 0.01 for a, b in zip(sent, read, strict=True))


@contextlib.contextmanager
def python_sitl(speedup: float = 20.0, *options: str) -> Iterator[str]:
    """``python -m sitl`` with its default parameters (and ``options``, e.g. ``--param``),
    on a free port: its address. It is stopped by its pid on leaving."""
    process = subprocess.Popen(
        [sys.executable, "-m", "sitl", "--tcp-base-port", "0", "--speedup", str(speedup),
         *options],
        cwd=Path(__file__).resolve().parents[2], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline() if process.stdout else ""
        assert line.startswith("vehicle 1: tcp:127.0.0.1:"), process.stderr
        yield line.split()[2]
    finally:
        os.kill(process.pid, signal.SIGTERM)
        process.communicate(timeout=10)


def on_both(ardupilot: Callable[..., Any], fly: Callable[[str], Any],
            speedup: float = 2.0) -> tuple[Any, Any]:
    """What ``fly(address)`` returns flown on an ArduCopter SITL (the ``ardupilot``
    fixture's) and then on ``python -m sitl``, both at ``speedup``, printed side by side."""
    (sitl,) = ardupilot(speedup=speedup)
    arducopter = fly(sitl.address)
    with python_sitl(speedup=speedup) as address:
        simulator = fly(address)
    print("ArduCopter", arducopter, "simulator", simulator)
    return arducopter, simulator


def watch_run(address: str, run: subprocess.Popen[bytes], types: list[str]
              ) -> Iterator[tuple[int, Any]]:
    """Every message of ``types`` the vehicle at ``address`` sends until ``run`` (a ``tml
    run`` flying it from another port) ends, with the custom mode of the vehicle's latest
    HEARTBEAT (-1 before the first). GLOBAL_POSITION_INT is asked for at 10 Hz; asking
    also makes ArduPilot count the link as active, and send it what goes to every link
    (CAMERA_FEEDBACK)."""
    conn: Any = mavutil.mavlink_connection(address, source_system=246, source_component=190)
    try:
        beat = conn.wait_heartbeat(timeout=60)
        assert beat is not None, f"no HEARTBEAT from {address}"
        system_id = beat.get_srcSystem()
        conn.mav.command_long_send(system_id, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                   M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 1e5, 0, 0, 0, 0, 0)
        mode = -1
        end = time.monotonic() + 800
        while run.poll() is None:
            assert time.monotonic() < end, "the run hung"
            msg = conn.recv_match(type=["HEARTBEAT", *types], blocking=True, timeout=1)
            if msg is None or msg.get_srcSystem() != system_id:
                continue
            if msg.get_type() == "HEARTBEAT" and msg.get_srcComponent() == 1:
                mode = msg.custom_mode
            if msg.get_type() in types:
                yield mode, msg
    finally:
        conn.close()
