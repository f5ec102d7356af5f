"""A MAVLink-aware lossy proxy for tests: whole frames lost each way, the rest byte-exact.

:class:`LossyProxy` listens on 127.0.0.1 (an OS-assigned port); each client that connects
gets its own TCP connection to the vehicle's address. The bytes of each direction are cut
into MAVLink frames by pymavlink's parser (MAVLink 2 and 1, signed or not), and each whole
frame is dropped with the direction's probability, drawn from a ``random.Random`` seeded
with (seed, direction); the frames kept, and any bytes that are no frame, go on exactly as
they came. A frame is what a radio loses, so this is how a poor link looks to both ends:
sequence numbers jump, a COMMAND_ACK or a MISSION_REQUEST never comes.

For a chaos campaign (benchmarks/chaos.py) it also cuts the link: :meth:`LossyProxy.cut`
drops every frame both ways for some seconds from now (``math.inf``: until
:meth:`LossyProxy.restore`), :meth:`LossyProxy.cut_on` from the first frame of a kind
(mid-upload: the first MISSION_ITEM_INT); :meth:`LossyProxy.retarget`
hangs up every connection and sends the next ones to another port, as a vehicle that
rebooted looks to a ground station; ``up.sent`` keeps the last frame of each kind and
sequence number the ground station sent (an uploaded mission's items), and
``on_message`` of a direction sees every frame passing (the interrupt campaign names the
requests a vehicle is sent from them).

The proxy runs one thread of its own, from ``start`` (or ``with``) until ``stop``, and
stops by itself after ``lifetime`` seconds. ``up`` is ground station to vehicle, ``down``
vehicle to ground station.
"""

from __future__ import annotations

import contextlib
import random
import selectors
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

BAD_DATA = "BAD_DATA"
KEPT_KINDS = frozenset({"MISSION_ITEM_INT"})


@dataclass
class Direction:
    """One way through the proxy: its dice, its parser and what it did."""

    name: str
    loss: float
    seed: int
    forwarded: int = 0
    dropped: int = 0
    dropped_types: dict[str, int] = field(default_factory=dict)
    cut_until: float = 0.0
    """Monotonic time until which every frame is dropped (an outage)."""
    on_frame: Callable[[str], None] | None = None
    """Called with the kind of each frame before it is judged."""
    on_message: Callable[[Any], None] | None = None
    """Called with each frame (the pymavlink message) before it is judged."""
    sent: dict[tuple[str, int], Any] = field(default_factory=dict)
    """The last frame of each (kind, seq field) among KEPT_KINDS."""

    def __post_init__(self) -> None:
        self.rng = random.Random(f"{self.seed}/{self.name}")

    def parser(self) -> Any:
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True  # bytes that are no frame come out as BAD_DATA
        return parser

    def filter(self, parser: Any, data: bytes) -> bytes:
        """The bytes of ``data`` to pass on (whole frames dropped; partial ones wait)."""
        kept = bytearray()
        for msg in parser.parse_buffer(data) or []:
            raw = bytes(msg.get_msgbuf())
            kind = msg.get_type()
            if self.on_frame is not None and kind != BAD_DATA:
                self.on_frame(kind)
            if self.on_message is not None and kind != BAD_DATA:
                self.on_message(msg)
            if kind in KEPT_KINDS:
                self.sent[(kind, msg.seq)] = msg
            if kind != BAD_DATA and (time.monotonic() < self.cut_until
                                     or self.rng.random() < self.loss):
                self.dropped += 1
                self.dropped_types[kind] = self.dropped_types.get(kind, 0) + 1
                continue
            self.forwarded += kind != BAD_DATA
            kept += raw
        return bytes(kept)

    @property
    def loss_seen(self) -> float:
        """The fraction of frames dropped so far."""
        total = self.forwarded + self.dropped
        return self.dropped / total if total else 0.0


class _Pair:
    """A client and its connection to the vehicle, with a parser each way."""

    def __init__(self, client: socket.socket, vehicle: socket.socket,
                 up: Direction, down: Direction) -> None:
        self.client, self.vehicle = client, vehicle
        self.routes = {client: (vehicle, up, up.parser()),
                       vehicle: (client, down, down.parser())}

    def close(self) -> None:
        for sock in (self.client, self.vehicle):
            with contextlib.suppress(OSError):
                sock.close()


class LossyProxy:
    """Forward a TCP MAVLink link to ``host:port``, losing whole frames (module docstring)."""

    def __init__(self, port: int, host: str = "127.0.0.1", *, loss: float = 0.3,
                 loss_up: float | None = None, loss_down: float | None = None, seed: int = 0,
                 lifetime: float = 900.0) -> None:
        self.target = (host, port)
        self.up = Direction("up", loss if loss_up is None else loss_up, seed)
        self.down = Direction("down", loss if loss_down is None else loss_down, seed)
        self.lifetime = lifetime
        self._listener = socket.create_server(("127.0.0.1", 0))
        self._listener.setblocking(False)
        self.port: int = self._listener.getsockname()[1]
        self._selector = selectors.DefaultSelector()
        self._pairs: dict[socket.socket, _Pair] = {}
        self._running = threading.Event()
        self._hang_up = threading.Event()
        self.outages: list[tuple[float, float]] = []
        """(monotonic start, seconds) of each cut."""
        self._thread = threading.Thread(target=self._loop, daemon=True,
                                        name=f"lossy proxy {self.port}")

    @property
    def address(self) -> str:
        """The connection string a ground station uses to reach the vehicle through it."""
        return f"tcp:127.0.0.1:{self.port}"

    def start(self) -> LossyProxy:
        """Start forwarding (returns self)."""
        self._running.set()
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop forwarding and close every socket."""
        self._running.clear()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        self._close()

    def cut(self, seconds: float) -> float:
        """Drop every frame both ways for ``seconds`` from now; returns when it started."""
        start = time.monotonic()
        self.outages.append((start, seconds))
        self.up.cut_until = self.down.cut_until = start + seconds
        return start

    def restore(self) -> None:
        """End a cut now (one of ``math.inf`` seconds lasts until this is called)."""
        self.up.cut_until = self.down.cut_until = 0.0

    def cut_on(self, kind: str, seconds: float) -> None:
        """Cut the link for ``seconds`` when the first frame of ``kind`` comes either way."""
        def watch(seen: str) -> None:
            if seen == kind and not self.outages:
                self.cut(seconds)
        self.up.on_frame = self.down.on_frame = watch

    def retarget(self, port: int, host: str = "127.0.0.1") -> None:
        """Hang up every connection; the next ones go to ``host:port`` (a vehicle that
        rebooted: the ground station sees its link drop and a fresh vehicle after it)."""
        self.target = (host, port)
        self._hang_up.set()

    def __enter__(self) -> LossyProxy:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _loop(self) -> None:
        self._selector.register(self._listener, selectors.EVENT_READ)
        end = time.monotonic() + self.lifetime
        try:
            while self._running.is_set() and time.monotonic() < end:
                if self._hang_up.is_set():
                    self._hang_up.clear()
                    for pair in set(self._pairs.values()):
                        self._drop(pair)
                for key, _ in self._selector.select(timeout=0.1):
                    if key.fileobj is self._listener:
                        self._accept()
                    else:
                        self._pass_on(key.fileobj)  # type: ignore[arg-type]
        finally:
            self._running.clear()
            self._close()

    def _accept(self) -> None:
        client, _ = self._listener.accept()
        try:
            vehicle = socket.create_connection(self.target, timeout=5.0)
        except OSError:
            client.close()
            return
        pair = _Pair(client, vehicle, self.up, self.down)
        for sock in (client, vehicle):
            sock.settimeout(5.0)
            self._pairs[sock] = pair
            self._selector.register(sock, selectors.EVENT_READ)

    def _pass_on(self, sock: socket.socket) -> None:
        pair = self._pairs.get(sock)
        if pair is None:  # dropped with its other end earlier in the same batch of events
            return
        other, direction, parser = pair.routes[sock]
        try:
            data = sock.recv(65536)
            if data:
                kept = direction.filter(parser, data)
                if kept:
                    other.sendall(kept)
                return
        except OSError:
            pass
        self._drop(pair)  # one end closed (or failed): close the other too

    def _drop(self, pair: _Pair) -> None:
        for sock in (pair.client, pair.vehicle):
            if self._pairs.pop(sock, None) is not None:
                with contextlib.suppress(KeyError, ValueError):
                    self._selector.unregister(sock)
        pair.close()

    def _close(self) -> None:
        for pair in set(self._pairs.values()):
            self._drop(pair)
        with contextlib.suppress(OSError):
            self._listener.close()
        with contextlib.suppress(OSError, RuntimeError):
            self._selector.close()
