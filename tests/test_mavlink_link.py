"""The link over loopback UDP against a small fake autopilot written with pymavlink.

The fake answers heartbeats, commands and the vehicle side of the mission protocol; it
binds 127.0.0.1 port 0 and every wait in these tests is bounded.
"""

from __future__ import annotations

import re
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from tml.errors import LinkLost
from tml.mavlink.autopilot import Autopilot
from tml.mavlink.codec import mavlink
from tml.mavlink.link import Address, Link, parse_address

KEY = bytes(range(32))


class FakeAutopilot:
    """An ArduCopter-like endpoint: component 1 of ``system_ids``, on one socket.

    By default it binds a UDP socket and answers whoever sent last (tml's ``udpout:``);
    with ``connect`` it sends first, to that UDP address (tml's ``udpin:``), or dials it
    over TCP with ``tcp=True`` (tml's ``tcpin:``). Each system id has its own mode; commands
    are answered as the system they address. ``obey_modes=False`` makes a vehicle that
    accepts DO_SET_MODE but stays in its mode; clearing ``beating`` stops the HEARTBEATs,
    and so does receiving the command ``silent_after``.
    """

    def __init__(self, system_id: int = 1, key: bytes | None = None,
                 command_results: dict[int, int | None] | None = None, *,
                 system_ids: tuple[int, ...] | None = None,
                 connect: tuple[str, int] | None = None, tcp: bool = False,
                 obey_modes: bool = True, silent_after: int | None = None) -> None:
        self.tcp = tcp
        if tcp:
            assert connect is not None, "a TCP fake dials tml's tcpin: address"
            self.sock = socket.create_connection(connect, timeout=5.0)
        else:
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.02)
        self.port = self.sock.getsockname()[1]
        self.peer: tuple[str, int] | None = connect
        self.system_ids = system_ids or (system_id,)
        self.system_id = self.system_ids[0]
        self.command_results = command_results or {}
        self.obey_modes = obey_modes
        self.silent_after = silent_after
        self.beating = threading.Event()
        self.beating.set()
        self.modes = dict.fromkeys(self.system_ids, 0)
        self.mavs: dict[tuple[int, int], mavlink.MAVLink] = {}
        self.parser = mavlink.MAVLink(None)
        if key is not None:
            self.parser.signing.secret_key = key
            self.parser.signing.allow_unsigned_callback = lambda _m, _i: False
        self.key = key
        self.received: list[Any] = []
        self.commands: list[Any] = []
        self.missions: dict[int, list[Any]] = {}
        self.store_altitude: float | None = None
        self._incoming: list[Any] | None = None
        self._count = 0
        self._type = 0
        self._running = True
        self._thread = threading.Thread(target=self._loop, daemon=True)

    @property
    def mode(self) -> int:
        """The custom mode of the first system."""
        return self.modes[self.system_id]

    def __enter__(self) -> FakeAutopilot:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._running = False
        self._thread.join(2.0)
        self.sock.close()

    def send(self, msg: Any, system_id: int | None = None, component: int = 1,
             key: bytes | None = None) -> None:
        """Send ``msg`` as ``system_id``/``component``, signed with ``key`` if given."""
        ident = (self.system_id if system_id is None else system_id, component)
        mav = self.mavs.get(ident)
        if mav is None:
            mav = self.mavs[ident] = mavlink.MAVLink(None, srcSystem=ident[0],
                                                     srcComponent=ident[1])
        signing_key = key if key is not None else self.key
        if signing_key is not None:
            mav.signing.secret_key = signing_key
            mav.signing.sign_outgoing = True
            mav.signing.link_id = 1
            mav.signing.timestamp = max(mav.signing.timestamp, int(time.time() * 1e5))
        else:
            mav.signing.sign_outgoing = False
        data = msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        if self.tcp:
            self.sock.sendall(data)
        elif self.peer is not None:
            self.sock.sendto(data, self.peer)

    def heartbeat(self, system_id: int | None = None, **ids: Any) -> None:
        sysid = self.system_id if system_id is None else system_id
        self.send(mavlink.MAVLink_heartbeat_message(
            mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
            mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, self.modes.get(sysid, 0), 4, 3),
            system_id=sysid, **ids)

    def _loop(self) -> None:
        next_beat = 0.0
        while self._running:
            if time.monotonic() >= next_beat and (self.peer is not None or self.tcp):
                if self.beating.is_set():
                    for sysid in self.system_ids:
                        self.heartbeat(sysid)
                next_beat = time.monotonic() + 0.1
            try:
                if self.tcp:
                    data = self.sock.recv(65536)
                else:
                    data, self.peer = self.sock.recvfrom(65536)
            except (TimeoutError, OSError):
                continue
            for msg in self.parser.parse_buffer(data) or []:
                if msg.get_type() != "BAD_DATA":
                    self.received.append(msg)
                    self._answer(msg)

    def _answer(self, msg: Any) -> None:
        kind = msg.get_type()
        b = mavlink.MAVLink(None)
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            if msg.target_system not in self.system_ids:
                return
            self.commands.append(msg)
            if msg.command == self.silent_after:
                self.beating.clear()
            result = self.command_results.get(msg.command, mavlink.MAV_RESULT_ACCEPTED)
            if result is None:
                return  # this command is never answered
            if msg.command == mavlink.MAV_CMD_DO_SET_MODE and result == 0 and self.obey_modes:
                self.modes[msg.target_system] = int(msg.param2)
            self.send(b.command_ack_encode(msg.command, result, 0, 0, 255, 190),
                      system_id=msg.target_system)
        elif kind == "MISSION_COUNT":
            self._incoming, self._count, self._type = [], msg.count, msg.mission_type
            self._ask_or_finish()
        elif kind == "MISSION_ITEM_INT" and self._incoming is not None:
            if msg.seq == len(self._incoming):
                self._incoming.append(msg)
            self._ask_or_finish()
        elif kind == "MISSION_REQUEST_LIST":
            items = self.missions.get(msg.mission_type, [])
            self.send(b.mission_count_encode(255, 190, len(items), msg.mission_type))
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            item = self.missions.get(msg.mission_type, [])[msg.seq]
            self.send(b.mission_item_int_encode(
                255, 190, item.seq, item.frame, item.command, item.current, item.autocontinue,
                item.param1, item.param2, item.param3, item.param4, item.x, item.y, item.z,
                msg.mission_type))
        elif kind == "MISSION_CLEAR_ALL":
            self.missions[msg.mission_type] = []
            self.send(b.mission_ack_encode(255, 190, 0, msg.mission_type))

    def _ask_or_finish(self) -> None:
        b = mavlink.MAVLink(None)
        assert self._incoming is not None
        if len(self._incoming) < self._count:
            self.send(b.mission_request_encode(255, 190, len(self._incoming), self._type))
            return
        if self.store_altitude is not None:
            for item in self._incoming:
                item.z = self.store_altitude
        if self._type == 0 and self._incoming:  # ArduPilot puts its home in item 0
            home = self._incoming[0]
            home.frame, home.x, home.y, home.z = 0, -353632621, 1491652374, 584.0
        self.missions[self._type], self._incoming = self._incoming, None
        self.send(b.mission_ack_encode(255, 190, 0, self._type))


def eventually(check: Callable[[], bool], timeout: float = 5.0) -> bool:
    """Poll ``check`` until true or ``timeout`` (a bound on waiting, not a timing assertion)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if check():
            return True
        time.sleep(0.01)
    return check()


def test_discovers_the_vehicle_and_sends_gcs_heartbeats() -> None:
    with FakeAutopilot(system_id=3) as ap, Link(f"udpout:127.0.0.1:{ap.port}") as link:
        info = link.wait_vehicle(timeout=5)
        assert (info.system_id, info.component_id, info.vehicle_type, info.autopilot) == (
            3, 1, mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA)
        beats = [m for m in ap.received if m.get_type() == "HEARTBEAT"]
        assert beats and beats[0].type == mavlink.MAV_TYPE_GCS
        assert beats[0].get_srcSystem() == 255
        assert link.telemetry(3).mode == "STABILIZE"


def test_several_vehicles_on_one_link_are_kept_apart() -> None:
    with FakeAutopilot(system_id=1) as ap, Link(f"udpout:127.0.0.1:{ap.port}") as link:
        link.wait_vehicle(1, timeout=5)
        ap.heartbeat(system_id=2)
        companion = mavlink.MAVLink_heartbeat_message(
            mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3)
        ap.send(companion, system_id=2, component=191)
        ap.send(mavlink.MAVLink_mission_current_message(7), system_id=2)
        assert eventually(lambda: link.telemetry(2).mission_current == 7)
        vehicles = link.vehicles()
        assert sorted(vehicles) == [1, 2] and vehicles[2].components == frozenset({1, 191})
        assert link.telemetry(1).mission_current is None


def test_unexpected_system_ids_are_dropped_and_counted() -> None:
    with FakeAutopilot(system_id=1) as ap, \
            Link(f"udpout:127.0.0.1:{ap.port}", system_ids=[1]) as link:
        link.wait_vehicle(1, timeout=5)
        for _ in range(5):
            ap.heartbeat(system_id=9)
        assert eventually(lambda: link.stats.unexpected_system >= 5)
        assert sorted(link.vehicles()) == [1]
        assert link.telemetry(9).received == 0


def test_listeners_hear_each_message_with_the_fresh_snapshot() -> None:
    heard: list[tuple[int, int | None]] = []
    with FakeAutopilot() as ap, Link(f"udpout:127.0.0.1:{ap.port}") as link:
        link.listen(lambda sysid, snap, msg: heard.append((sysid, snap.mission_current))
                    if msg.get_type() == "MISSION_CURRENT" else None)
        link.wait_vehicle(1, timeout=5)
        ap.send(mavlink.MAVLink_mission_current_message(4))
        assert eventually(lambda: heard == [(1, 4)])


@pytest.fixture(params=["udpout", "udp"])  # as an output, udp: sends like MAVProxy's --out
def watched(request: pytest.FixtureRequest
            ) -> Iterator[tuple[FakeAutopilot, Link, socket.socket]]:
    """Vehicle 4, a link to it, and a ground station's UDP socket the link forwards to."""
    watcher = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    watcher.bind(("127.0.0.1", 0))
    watcher.settimeout(5.0)
    port = watcher.getsockname()[1]
    with FakeAutopilot(system_id=4) as ap, Link(
            f"udpout:127.0.0.1:{ap.port}", outputs=[f"{request.param}:127.0.0.1:{port}"]) as link:
        yield ap, link, watcher
    watcher.close()


def test_output_forwarding_copies_vehicle_messages_to_a_watcher(
        watched: tuple[FakeAutopilot, Link, socket.socket]) -> None:
    _, link, watcher = watched
    link.wait_vehicle(4, timeout=5)
    data, _ = watcher.recvfrom(65536)
    (msg,) = mavlink.MAVLink(None).parse_buffer(data)
    assert (msg.get_type(), msg.get_srcSystem()) == ("HEARTBEAT", 4)


def test_forwarding_is_one_way_a_watchers_commands_never_reach_the_vehicle(
        watched: tuple[FakeAutopilot, Link, socket.socket]) -> None:
    ap, link, watcher = watched
    vehicle = Autopilot.connect(link, 4, timeout=5)
    _, forwarder = watcher.recvfrom(65536)  # where the copies come from
    qgc = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    guided = qgc.command_long_encode(4, 1, mavlink.MAV_CMD_DO_SET_MODE, 0,
                                     mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4, 0, 0, 0, 0, 0)
    for _ in range(3):
        watcher.sendto(guided.pack(qgc), forwarder)
    vehicle.set_mode("LAND")  # tml's own command gets through meanwhile
    assert [(c.command, c.param2) for c in ap.commands] == [(mavlink.MAV_CMD_DO_SET_MODE, 9)]
    assert ap.mode == 9


def test_signing_accepts_only_correctly_signed_messages_and_signs_its_own() -> None:
    with FakeAutopilot(system_id=1, key=KEY) as ap, \
            Link(f"udpout:127.0.0.1:{ap.port}", signing_key=KEY) as link:
        link.wait_vehicle(1, timeout=5)  # heard: the fake could verify our heartbeat
        assert all(m.get_signed() for m in ap.received)
        for _ in range(3):
            ap.send(mavlink.MAVLink_mission_current_message(5), key=bytes(32))
        ap.key = None
        for _ in range(4):
            ap.send(mavlink.MAVLink_mission_current_message(6))
        ap.key = KEY
        ap.send(mavlink.MAVLink_mission_current_message(8))
        assert eventually(lambda: link.telemetry(1).mission_current == 8)
        unsigned, bad = link.signing_counts
        assert (unsigned, bad) == (4, 3)
        assert link.stats.bad_data == 7


def test_a_vehicle_that_signs_is_said_as_soon_as_it_is_heard_by_a_link_without_a_key(
        ) -> None:
    from tml.errors import VehicleError

    with Link("udpin:127.0.0.1:0") as link:
        assert link.local_address is not None
        with FakeAutopilot(system_id=3, key=KEY, connect=link.local_address), \
                pytest.raises(VehicleError, match="the vehicle signs its messages") as caught:
            link.wait_vehicle(None, timeout=60)
    assert caught.value.system_id == 3


def test_a_vehicle_heard_only_unsigned_by_a_signing_link_is_said_in_the_timeout() -> None:
    from tml.errors import LinkLost

    with Link("udpin:127.0.0.1:0", signing_key=KEY) as link:
        assert link.local_address is not None
        with FakeAutopilot(system_id=3, connect=link.local_address):
            assert eventually(lambda: link.signing_counts[0] > 0, timeout=60)
            with pytest.raises(LinkLost, match=r"within 1 s \(signing: [1-9]\d* unsigned and "
                                               r"0 wrongly signed message\(s\) dropped: the "
                                               r"vehicle does not sign with this key\)"):
                link.wait_vehicle(None, timeout=1)


@pytest.mark.parametrize(("text", "hint"), [
    ("127.0.0.1:18001", "e.g. tcp:127.0.0.1:18001 (connect to a vehicle that listens) or "
                        "udpin:127.0.0.1:18001 (listen for one that sends)"),
    ("foo:bar", "e.g. tcp:127.0.0.1:5760 or udpin:0.0.0.0:14550"),
    ("tpc:127.0.0.1:5760", "e.g. tcp:127.0.0.1:5760 or udpin:0.0.0.0:14550"),
])
def test_an_address_without_its_scheme_says_the_forms(text: str, hint: str) -> None:
    from tml.mavlink.link import address_problem

    problem = address_problem(text)
    assert problem is not None and problem.startswith(
        "not an address: a network address starts with its scheme")
    assert hint in problem and "DEVICE,BAUD" in problem


def test_a_serial_path_may_hold_colons() -> None:
    text = "/dev/serial/by-path/pci-0000:00:14.0-usb-0:2:1.0-port0,57600"
    assert parse_address(text) == Address(
        "serial", device="/dev/serial/by-path/pci-0000:00:14.0-usb-0:2:1.0-port0", baud=57600)


def test_signing_key_must_be_32_bytes() -> None:
    from tml.errors import VehicleError

    with pytest.raises(VehicleError, match="32 bytes"):
        Link("udpout:127.0.0.1:9", signing_key=b"short")


def test_no_vehicle_is_a_clear_link_lost() -> None:
    silent = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    silent.bind(("127.0.0.1", 0))
    with Link(f"udpout:127.0.0.1:{silent.getsockname()[1]}") as link, \
            pytest.raises(LinkLost, match="no heartbeat from vehicle 5"):
        link.wait_vehicle(5, timeout=0.3)
    silent.close()


def test_an_address_that_cannot_be_opened_is_a_clear_error() -> None:
    with pytest.raises(LinkLost, match="cannot open"):
        Link("/dev/tml-no-such-serial-port,57600")


def test_a_silent_vehicle_is_lost_in_the_snapshot_and_found_again() -> None:
    with FakeAutopilot(system_id=1) as ap, \
            Link(f"udpout:127.0.0.1:{ap.port}", lost_after=0.3) as link:
        link.wait_vehicle(1, timeout=5)
        assert not link.telemetry(1).link_lost
        ap.beating.clear()
        lost = link.wait_telemetry(1, lambda t: t.link_lost, timeout=5)
        assert lost.heartbeat_age(time.monotonic()) > 0.3
        with pytest.raises(LinkLost, match="vehicle 1: link lost while waiting"):
            link.wait_telemetry(1, lambda t: t.mode == "GUIDED", timeout=30)
        ap.beating.set()
        link.wait_telemetry(1, lambda t: not t.link_lost, timeout=5, lost_ok=True)
        assert link.stats.losses == 1


def test_a_vehicle_lost_during_a_command_is_link_lost_not_a_timeout() -> None:
    from tml.mavlink.command import CommandLong, CommandSender

    gripper = mavlink.MAV_CMD_DO_GRIPPER
    with FakeAutopilot(system_id=1, command_results={gripper: None},
                       silent_after=gripper) as ap, \
            Link(f"udpout:127.0.0.1:{ap.port}", lost_after=0.3) as link:
        link.wait_vehicle(1, timeout=5)
        sender = CommandSender(CommandLong(gripper), system_id=1, timeout=1.5, retries=5)
        with pytest.raises(LinkLost, match="link lost during CommandSender") as caught:
            link.run(sender, 1, 1)  # 9 s of retries, cut short by the loss
        assert caught.value.system_id == 1 and not sender.done
        assert link.telemetry(1).link_lost


# -- address forms over loopback ------------------------------------------------------------


@pytest.mark.parametrize(("text", "expected"), [
    ("/dev/ttyUSB0,57600", Address("serial", device="/dev/ttyUSB0", baud=57600)),
    ("/dev/ttyACM0,115200", Address("serial", device="/dev/ttyACM0", baud=115200)),
    ("/dev/ttyUSB1", Address("serial", device="/dev/ttyUSB1", baud=57600)),
    ("COM4,921600", Address("serial", device="COM4", baud=921600)),
    ("udpin:0.0.0.0:14550", Address("udpin", host="0.0.0.0", port=14550)),
    ("udp:127.0.0.1:14550", Address("udp", host="127.0.0.1", port=14550)),
    ("udpout:10.0.0.2:14550", Address("udpout", host="10.0.0.2", port=14550)),
    ("tcp:127.0.0.1:5760", Address("tcp", host="127.0.0.1", port=5760)),
    ("tcpin:0.0.0.0:5760", Address("tcpin", host="0.0.0.0", port=5760)),
])
def test_addresses_are_taken_apart_without_opening_anything(text: str,
                                                            expected: Address) -> None:
    assert parse_address(text) == expected


@pytest.mark.parametrize(("text", "why"), [
    ("udpin:14550", "expected udpin:HOST:PORT"),
    ("tcp:127.0.0.1:70000", "port from 0 to 65535"),
    ("/dev/ttyUSB0,fast", "DEVICE,BAUD"),
    ("", "DEVICE,BAUD"),
])
def test_malformed_addresses_say_what_is_expected(text: str, why: str) -> None:
    from tml.errors import VehicleError

    with pytest.raises(VehicleError, match=why) as caught:
        Link(text)
    assert repr(text) in str(caught.value)


@pytest.mark.parametrize("scheme", ["udpin", "udp"])
def test_a_listening_udp_link_is_found_by_a_vehicle_that_sends_first(scheme: str) -> None:
    with Link(f"{scheme}:127.0.0.1:0") as link:
        assert link.local_address is not None
        with FakeAutopilot(system_id=6, connect=link.local_address) as ap:
            vehicle = Autopilot.connect(link, 6, timeout=5)
            vehicle.set_mode("GUIDED")  # the replies find their way back to the vehicle
            assert ap.mode == 4 and vehicle.telemetry.mode == "GUIDED"


def test_a_listening_tcp_link_accepts_a_vehicle_that_dials_in() -> None:
    with Link("tcpin:127.0.0.1:0") as link:
        assert link.local_address is not None
        with FakeAutopilot(system_id=7, connect=link.local_address, tcp=True) as ap:
            vehicle = Autopilot.connect(link, 7, timeout=5)
            vehicle.set_mode("LAND")
            assert ap.mode == 9 and vehicle.telemetry.mode == "LAND"


def test_connecting_links_have_no_local_listening_address() -> None:
    with FakeAutopilot() as ap, Link(f"udpout:127.0.0.1:{ap.port}") as link:
        assert link.local_address is None


def test_two_vehicles_sending_from_one_udp_socket_are_told_apart_by_system_id() -> None:
    with Link("udpin:127.0.0.1:0") as link, \
            FakeAutopilot(system_ids=(1, 2), connect=link.local_address) as ap:
        first, second = Autopilot.connect(link, 1, timeout=5), Autopilot.connect(link, 2, timeout=5)
        second.set_mode("RTL")
        first.set_mode("LOITER")
        assert ap.modes == {1: 5, 2: 6}
        assert (first.telemetry.mode, second.telemetry.mode) == ("LOITER", "RTL")
        assert [c.target_system for c in ap.commands] == [2, 1]
        assert sorted(link.vehicles()) == [1, 2]


def test_heartbeats_waiting_behind_a_slow_listener_are_not_taken_for_silence() -> None:
    with FakeAutopilot(system_id=1) as ap, \
            Link(f"udpout:127.0.0.1:{ap.port}", lost_after=0.3) as link:
        link.wait_vehicle(1, timeout=5)
        stalled = threading.Event()

        def slow(sysid: int, snapshot: Any, msg: Any) -> None:
            if msg.get_type() == "MISSION_CURRENT" and not stalled.is_set():
                stalled.set()
                time.sleep(0.5)  # holds the receive thread while HEARTBEATs queue up

        link.listen(slow)
        received = link.telemetry(1).received
        for seq in (4, 5, 9):  # 5 and 9 wait in the socket with the HEARTBEATs
            ap.send(mavlink.MAVLink_mission_current_message(seq))
        # Raises LinkLost if the link judged the vehicle lost before reading its queue.
        link.wait_telemetry(1, lambda t: t.mission_current == 9, timeout=5)
        assert eventually(lambda: link.telemetry(1).received > received + 5)  # beats after it
        assert stalled.is_set() and link.stats.losses == 0


class TcpVehicle:
    """A vehicle that listens on TCP as ArduPilot SITL does, and can go away and come back.

    ``hang_up`` makes a server that accepts and closes at once, without a word.
    """

    def __init__(self, hang_up: bool = False) -> None:
        self.hang_up = hang_up
        self.port = 0
        self._server: socket.socket | None = None
        self._running = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> TcpVehicle:
        server = socket.socket()
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind(("127.0.0.1", self.port))
        server.listen()
        server.settimeout(0.05)
        self.port = server.getsockname()[1]
        self._server = server
        self._running.set()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Close the listening socket and every connection (the vehicle is killed)."""
        self._running.clear()
        if self._thread is not None:
            self._thread.join(2.0)
        if self._server is not None:
            self._server.close()

    def _serve(self) -> None:
        assert self._server is not None
        mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        clients: list[socket.socket] = []
        while self._running.is_set():
            try:
                client, _ = self._server.accept()
                if self.hang_up:
                    client.close()
                else:
                    clients.append(client)
            except TimeoutError:
                pass
            beat = mavlink.MAVLink_heartbeat_message(
                mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4, 4, 3).pack(mav)
            for client in list(clients):
                try:
                    client.sendall(beat)
                except OSError:
                    clients.remove(client)
        for client in clients:
            client.close()


@pytest.fixture
def thread_errors() -> Iterator[list[Any]]:
    """The exceptions that ended a thread during the test (none expected)."""
    caught: list[Any] = []
    previous = threading.excepthook
    threading.excepthook = caught.append
    yield caught
    threading.excepthook = previous


def test_a_tcp_vehicle_that_goes_away_is_lost_and_found_again_when_it_comes_back(
        thread_errors: list[Any]) -> None:
    vehicle = TcpVehicle().start()
    try:
        link = Link(f"tcp:127.0.0.1:{vehicle.port}", lost_after=0.3).start()
        link.wait_vehicle(1, timeout=5)
        vehicle.stop()  # killed: the connection ends, nothing listens any more
        link.wait_telemetry(1, lambda t: t.link_lost, timeout=5, lost_ok=True)
        assert "refused" in link.down or "closed" in link.down
        vehicle.start()  # restarted on the same port: the link dials again
        link.wait_telemetry(1, lambda t: not t.link_lost, timeout=10, lost_ok=True)
        assert link.down == ""
        link.close()
    finally:
        vehicle.stop()
    assert thread_errors == []


def test_a_server_that_hangs_up_is_a_clear_link_lost(thread_errors: list[Any]) -> None:
    server = TcpVehicle(hang_up=True).start()
    try:
        link = Link(f"tcp:127.0.0.1:{server.port}").start()
        with pytest.raises(LinkLost, match="no heartbeat"):
            link.wait_vehicle(None, timeout=1.0)
        link.close()
    finally:
        server.stop()
    assert thread_errors == []


def test_a_link_whose_vehicle_went_away_closes_quietly(thread_errors: list[Any]) -> None:
    vehicle = TcpVehicle().start()
    link = Link(f"tcp:127.0.0.1:{vehicle.port}", lost_after=0.3).start()
    link.wait_vehicle(1, timeout=5)
    vehicle.stop()
    link.wait_telemetry(1, lambda t: t.link_lost, timeout=5, lost_ok=True)
    link.close()
    assert thread_errors == []


def test_change_listeners_hear_only_messages_that_change_what_the_vehicle_shows() -> None:
    changes: list[int] = []
    with FakeAutopilot(system_id=3) as ap, Link(f"udpout:127.0.0.1:{ap.port}") as link:
        link.wait_vehicle(3, timeout=5)
        link.on_change(changes.append)
        assert eventually(lambda: link.telemetry(3).received >= 3)  # HEARTBEATs, alike
        assert changes == []
        for seq in (4, 4, 4, 5):
            ap.send(mavlink.MAVLink_mission_current_message(seq))
        assert eventually(lambda: link.telemetry(3).mission_current == 5)
        assert changes == [3, 3]  # to 4, then to 5
        assert link.revision(3) == link.telemetry(3).revision


def test_a_tcp_link_takes_in_every_message_of_a_burst_in_order() -> None:
    seen: list[int] = []
    with Link("tcpin:127.0.0.1:0") as link:
        assert link.local_address is not None
        link.listen(lambda _sysid, _snap, msg: seen.append(msg.seq)
                    if msg.get_type() == "MISSION_CURRENT" else None)
        with FakeAutopilot(system_id=2, connect=link.local_address, tcp=True) as ap:
            link.wait_vehicle(2, timeout=5)
            for seq in range(200):
                ap.send(mavlink.MAVLink_mission_current_message(seq))
            assert eventually(lambda: len(seen) >= 200)
    assert seen == list(range(200))


def test_every_address_form_of_docs_connections_is_flown_by_the_tests_it_names() -> None:
    """docs/connections.md's table names, for each address form, the tests that fly a
    mission through it: each named test exists (``::name`` alone is in the file before)."""
    root = Path(__file__).resolve().parent.parent
    doc = (root / "docs" / "connections.md").read_text(encoding="utf-8")
    rows = [line for line in doc.splitlines()
            if re.match(r"\| `(udp|tcp|DEVICE)", line) and "tests/" in line]
    assert {row.split("`")[1] for row in rows} == {
        "udpin:", "udpout:", "udp:", "tcp:", "tcpin:", "DEVICE,BAUD", "DEVICE"}
    for row in rows:
        named = re.findall(r"(tests/[\w/]+\.py)?::(\w+)", row)
        assert named, row
        source = ""
        for path, test in named:
            source = (root / path).read_text(encoding="utf-8") if path else source
            assert f"def {test}(" in source, f"{path or 'the file before'}::{test}"


class _Socket:
    """A connection's ``recv`` and parser, reading from a list of chunks and counting the
    reads that reached the socket."""

    def __init__(self, *chunks: bytes) -> None:
        self.chunks = list(chunks)
        self.reads = 0
        self.mav = mavlink.MAVLink(None)
        self.mav.robust_parsing = True
        self.first_byte = False

    def recv(self, n: int | None = None) -> bytes:
        self.reads += 1
        return self.chunks.pop(0) if self.chunks else b""


def _frames(count: int) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    return b"".join(mavlink.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3).pack(mav)
                    for _ in range(count))


def test_a_socket_is_read_once_a_turn_unless_the_read_filled_the_buffer() -> None:
    from tml.mavlink.link import READ_AHEAD, _ReadAhead, _receive

    conn = _Socket(_frames(3), _frames(2))
    reader = _ReadAhead(conn)
    reader.turn()
    got = []
    while (msg := _receive(conn)) is not None:
        got.append(msg)
    # One read for the three messages that waited; the second chunk (arrived since) waits
    # for the next turn, which the reactor's poll announces.
    assert [m.get_type() for m in got] == ["HEARTBEAT"] * 3 and conn.reads == 1
    assert all(isinstance(m._timestamp, float) for m in got)
    reader.turn()
    assert len([m for m in iter(lambda: _receive(conn), None)]) == 2 and conn.reads == 2
    # A read that filled the buffer may have left more in the socket: the parser's last,
    # cut frame is read on (in the next turn, as the socket is still readable).
    frame = len(_frames(1))
    full = _frames(READ_AHEAD // frame + 1)
    conn = _Socket(full[:READ_AHEAD], full[READ_AHEAD:])
    reader = _ReadAhead(conn)
    taken = 0
    for _ in range(2):
        reader.turn()
        taken += len(list(iter(lambda: _receive(conn), None)))
    assert taken == len(full) // frame and conn.reads == 2
