"""The lossy proxy of the tests: whole MAVLink frames lost each way, seeded, the rest exact."""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Iterator

import pytest
from lossy_proxy import LossyProxy
from pymavlink.dialects.v10 import ardupilotmega as mavlink1
from pymavlink.dialects.v20 import ardupilotmega as mavlink


class Vehicle:
    """A TCP server that keeps every byte its one client sends and can send some back."""

    def __init__(self) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.received = bytearray()
        self.client: socket.socket | None = None
        self.connected = threading.Event()
        self.closed = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        self.server.settimeout(10.0)
        self.client, _ = self.server.accept()
        self.connected.set()
        self.client.settimeout(10.0)
        # close() may shut the socket under this loop: that ends it too.
        with contextlib.suppress(OSError):
            while data := self.client.recv(65536):
                self.received += data
        self.closed.set()

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
        self.server.close()


@pytest.fixture
def vehicle() -> Iterator[Vehicle]:
    made = Vehicle()
    yield made
    made.close()


def frames(count: int) -> list[bytes]:
    """MAVLink 2 frames (signed ones among them) and MAVLink 1 frames, mixed."""
    plain = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    signed = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    signed.signing.secret_key = b"k" * 32
    signed.signing.sign_outgoing = True
    signed.signing.link_id = 1
    signed.signing.timestamp = 1
    old = mavlink1.MAVLink(None, srcSystem=255, srcComponent=190)
    out = []
    for n in range(count):
        if n % 5 == 3:
            out.append(mavlink1.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(old))
        else:
            encoder = signed if n % 7 == 0 else plain
            out.append(mavlink.MAVLink_statustext_message(6, f"frame {n}".encode()).pack(encoder))
            encoder.seq = (encoder.seq + 1) % 256
    return out


def through(proxy: LossyProxy, vehicle: Vehicle, data: bytes) -> bytes:
    """Send ``data`` through the proxy, close, and return what reached the vehicle."""
    with socket.create_connection(("127.0.0.1", proxy.port), timeout=10.0) as gcs:
        for start in range(0, len(data), 50):  # in pieces that cut frames in two
            gcs.sendall(data[start:start + 50])
    assert vehicle.closed.wait(10.0)
    return bytes(vehicle.received)


def test_without_loss_every_byte_goes_through_as_it_came(vehicle: Vehicle) -> None:
    data = b"".join(frames(100)) + b"\x00\x13 not a frame"
    with LossyProxy(vehicle.port, loss=0.0) as proxy:
        assert through(proxy, vehicle, data) == data
        assert (proxy.up.forwarded, proxy.up.dropped) == (100, 0)


def test_whole_frames_are_lost_at_the_rate_asked_and_the_rest_are_exact(vehicle: Vehicle) -> None:
    sent = frames(400)
    with LossyProxy(vehicle.port, loss=0.3, seed=7) as proxy:
        received = through(proxy, vehicle, b"".join(sent))
    parser = mavlink.MAVLink(None)
    got = [bytes(m.get_msgbuf()) for m in parser.parse_buffer(received)]
    assert b"".join(got) == received  # nothing but whole frames
    position = 0
    for frame in got:  # in order, each one of those sent
        position = sent.index(frame, position) + 1
    assert len(got) == proxy.up.forwarded and len(sent) - len(got) == proxy.up.dropped
    assert 0.25 < proxy.up.loss_seen < 0.35


def test_the_same_seed_loses_the_same_frames() -> None:
    sent = b"".join(frames(200))
    kept = []
    for _ in range(2):
        vehicle = Vehicle()
        with LossyProxy(vehicle.port, loss=0.3, seed=11) as proxy:
            kept.append(through(proxy, vehicle, sent))
        vehicle.close()
    assert kept[0] == kept[1] and len(kept[0]) < len(sent)


def test_the_vehicles_answers_come_back_through_it_lost_in_their_own_direction(
        vehicle: Vehicle) -> None:
    with LossyProxy(vehicle.port, loss_up=0.0, loss_down=1.0) as proxy, \
            socket.create_connection(("127.0.0.1", proxy.port), timeout=10.0) as gcs:
        assert vehicle.connected.wait(10.0) and vehicle.client is not None
        vehicle.client.sendall(b"".join(frames(10)))
        gcs.sendall(b"".join(frames(10)))
        gcs.settimeout(0.5)
        with pytest.raises(TimeoutError):
            gcs.recv(65536)  # every frame down was lost
    assert (proxy.up.dropped, proxy.down.dropped) == (0, 10)


def test_a_cut_loses_every_frame_until_it_ends(vehicle: Vehicle) -> None:
    with LossyProxy(vehicle.port, loss=0.0) as proxy:
        start = proxy.cut(600.0)
        assert through(proxy, vehicle, b"".join(frames(20))) == b""
    assert proxy.up.dropped == 20 and proxy.outages == [(start, 600.0)]


def test_a_cut_on_a_kind_starts_with_its_first_frame(vehicle: Vehicle) -> None:
    sent = frames(10)  # the first HEARTBEAT is the fourth frame
    with LossyProxy(vehicle.port, loss=0.0) as proxy:
        proxy.cut_on("HEARTBEAT", 600.0)
        assert through(proxy, vehicle, b"".join(sent)) == b"".join(sent[:3])
    assert len(proxy.outages) == 1


def test_retarget_hangs_up_and_connects_on_to_the_new_vehicle(vehicle: Vehicle) -> None:
    rebooted = Vehicle()
    try:
        with LossyProxy(vehicle.port, loss=0.0) as proxy, \
                socket.create_connection(("127.0.0.1", proxy.port), timeout=10.0) as gcs:
            assert vehicle.connected.wait(10.0)
            proxy.retarget(rebooted.port)
            assert gcs.recv(65536) == b""  # the ground station sees its link drop
            assert through(proxy, rebooted, b"".join(frames(5))) == b"".join(frames(5))
    finally:
        rebooted.close()


def test_the_mission_items_sent_are_kept_lost_or_not(vehicle: Vehicle) -> None:
    gcs = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    items = [mavlink.MAVLink_mission_item_int_message(1, 1, seq, 6, 16, 0, 1, 0, 0, 0, 0,
                                                      seq, seq, 10.0, 0).pack(gcs)
             for seq in range(5)]
    with LossyProxy(vehicle.port, loss=1.0) as proxy:
        assert through(proxy, vehicle, b"".join(items)) == b""
    assert sorted(proxy.up.sent) == [("MISSION_ITEM_INT", seq) for seq in range(5)]
    assert proxy.up.sent[("MISSION_ITEM_INT", 3)].x == 3
