"""Serve simulated vehicles over TCP and UDP, like ArduPilot SITL instances.

Theory of operation. One thread owns every socket and every vehicle model. Each vehicle
(system id i, 1-based) listens on its own TCP port (``tcp_base_port + 10 * (i - 1)``, as
several ArduPilot SITL instances do, or an OS-assigned port with ``tcp_base_port=0``) and
optionally sends to ground-station UDP addresses (``udp_out``) from its own UDP socket,
reading the replies that come back to it. Everything a vehicle emits goes to every client
of that vehicle; bytes received are parsed with pymavlink's MAVLink 2 parser (one parser
per connection) and handed to the vehicle's model; what the model emits is encoded by
:func:`sitl.wire.encode` (pymavlink's bytes at a quarter of the cost; the streamed
telemetry straight from its arguments, never built as pymavlink messages).

Like ArduPilot between its serial ports, a vehicle also routes what one client sends to
its other clients (so a companion computer connected beside the ground station reaches
it): each connection learns the (system, component) ids it has heard from; a HEARTBEAT
goes to every other client, a message addressed to a system and component goes to the
clients that component was heard on, and an unaddressed or broadcast message goes to
every other client that has said something. Forwarded messages keep their bytes and skip
the fault channels below.

All vehicles share one clock that advances in the model's control ticks. With
``realtime=True`` a background thread keeps vehicle time at ``speedup`` times wall-clock
time (falling behind instead of skipping when the machine cannot keep up). With
``realtime=False`` nothing moves until :meth:`Simulator.advance` is called, which steps
time deterministically and serves the sockets between ticks: a test sends, advances,
and reads the replies. Given a ``lockstep`` (:class:`tml.timebase.Lockstep`, the time base
of the ground station in the same process), the background thread moves time on only
when that ground station has handled everything the vehicles said and waits for them
(:meth:`~tml.timebase.Lockstep.settled`), and never faster than ``speedup`` times
wall-clock time: a flight is then the same on an idle and on a saturated machine.

*Who spoke to a vehicle.* Given ``heard`` (a text file), every message a vehicle receives
from a client is written there as one JSON line: the vehicle's system id, its time
(``t``) and the wall-clock time (``wall``), the sender's system and component ids
(``src``, ``comp``), the message type and target system, and the client's port: which
ground station commanded which vehicle when (the cluster test of ``tml serve`` checks
that no vehicle hears two at once).

Link faults (:class:`sitl.faults.Faults`) act here, on decoded messages going in and on
encoded packets going out, timed in vehicle time so they replay from the seed.
"""

from __future__ import annotations

import contextlib
import json
import selectors
import socket
import threading
import time
from dataclasses import replace
from typing import IO, Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import MAX_VEHICLES
from sitl.faults import Faults, WireChannel
from sitl.frames import FRAMES, frame_of
from sitl.messages import AUTOPILOT
from sitl.model import TICK, VehicleModel
from sitl.params import UnknownParameter
from sitl.wire import ENCODERS, Fields, encode
from tml.geo import to_global
from tml.signing import signature_first, timestamp_now
from tml.timebase import Lockstep
from tml.world import Home, World

MAX_BACKLOG = 1 << 20  # bytes queued for a client that does not read before we drop
VEHICLE_SPACING = 5.0  # metres east between the boot positions of consecutive vehicles


def _own(kind: type[VehicleModel], params: dict[str, float] | None) -> dict[str, float]:
    """The parameters of ``params`` that a vehicle of ``kind`` has (a mixed fleet is given
    one set: a copter's WPNAV_SPEED means nothing to a rover)."""
    names = {name for name, _, _ in kind.parameter_table}
    return {name: value for name, value in (params or {}).items() if name in names}




def parse_udp_address(text: str) -> tuple[str, int]:
    """``udp:HOST:PORT`` (or ``HOST:PORT``) -> (host, port); ValueError when malformed."""
    body = text[4:] if text.startswith("udp:") else text
    host, _, port = body.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"not a UDP address (udp:HOST:PORT): {text!r}")
    return host, int(port)


class _Peer:
    """One connection (a TCP client, or a UDP address) and its parser and send queue."""

    def __init__(self, sock: socket.socket, address: tuple[str, int] | None = None,
                 signing_key: bytes | None = None, lockstep: Lockstep | None = None,
                 remote: tuple[str, int] | None = None) -> None:
        self.sock = sock
        self.address = address  # UDP destination; None for TCP
        # A TCP client's address, whose bytes a lock-step ground station counts with us
        self.lockstep = lockstep
        self.remote = remote
        self.parser = mavlink.MAVLink(None)
        self.parser.robust_parsing = True
        if signing_key is not None:  # as ArduPilot with a key: nothing unsigned is taken
            self.parser.signing.secret_key = signing_key
            self.parser.signing.allow_unsigned_callback = lambda _mav, _msgid: False
            signature_first(self.parser)  # a keyless frame moves no stream's time stamp
        self.backlog = bytearray()
        self.routes: set[tuple[int, int]] = set()  # (system, component) heard on it

    def send(self, data: bytes) -> None:
        if self.address is not None:
            with contextlib.suppress(OSError):
                self.sock.sendto(data, self.address)
            return
        if len(self.backlog) < MAX_BACKLOG:
            self.backlog += data

    def flush(self) -> bool:
        """Send what the socket takes; False when the connection is gone."""
        if not self.backlog or self.address is not None:
            return True
        try:
            sent = self.sock.send(self.backlog)
        except BlockingIOError:
            return True
        except OSError:
            return False
        del self.backlog[:sent]
        if self.lockstep is not None:
            self.lockstep.carried(self.remote, sent)
        return True


class _Endpoint:
    """A vehicle with its sockets, encoders and fault channels."""

    def __init__(self, model: VehicleModel, faults: Faults,
                 signing_key: bytes | None = None) -> None:
        self.model = model
        self.signing_key = signing_key
        self.listener: socket.socket | None = None
        self.udp: socket.socket | None = None
        self.tcp_peers: list[_Peer] = []
        self.udp_peers: list[_Peer] = []
        self.sequences: dict[int, int] = {}  # component -> next packet sequence number
        self.signers: dict[int, Any] = {}  # component -> pymavlink encoder, when signing
        wire = faults.affects_wire
        sid = model.system_id
        self.incoming: WireChannel[Any] | None = (
            WireChannel(faults, faults.loss_in, f"{sid}/in") if wire else None)
        self.outgoing: WireChannel[bytes] | None = (
            WireChannel(faults, faults.loss_out, f"{sid}/out") if wire else None)

    def encode(self, msg: Any) -> bytes:
        if type(msg) is Fields:
            component = AUTOPILOT
            if self.signing_key is not None:  # pymavlink signs: build the message
                return self._signed(msg.message(), component)
        else:
            component = msg._header.srcComponent or AUTOPILOT
            if self.signing_key is not None:
                return self._signed(msg, component)
        seq = self.sequences.get(component, 0)
        self.sequences[component] = (seq + 1) % 256  # each component counts its own
        return encode(msg, seq, self.model.system_id, component)

    def encode_all(self, messages: list[Any]) -> list[bytes]:
        """The packets of ``messages``, in order: as :meth:`encode` makes each, with the
        streamed telemetry (most of what is sent) handed to its message's encoder at once."""
        if self.signing_key is not None:
            return [self.encode(msg) for msg in messages]
        sequences, system = self.sequences, self.model.system_id
        seq = sequences.get(AUTOPILOT, 0)
        packets = []
        for msg in messages:
            if type(msg) is Fields:
                kind, args = msg
                packets.append(ENCODERS[kind](args, seq, system, AUTOPILOT))
                seq = (seq + 1) % 256
            else:
                sequences[AUTOPILOT] = seq
                packets.append(self.encode(msg))
                seq = sequences[AUTOPILOT]
        sequences[AUTOPILOT] = seq
        return packets

    def _signed(self, msg: Any, component: int) -> bytes:
        """``msg`` packed and signed by pymavlink (sitl.wire does not sign)."""
        signer = self.signers.get(component)
        if signer is None:
            signer = mavlink.MAVLink(None, self.model.system_id, component)
            signer.signing.secret_key = self.signing_key
            signer.signing.sign_outgoing = True
            self.signers[component] = signer
        # The time stamp follows the clock (pymavlink only counts one up per frame, and
        # a client that comes later refuses a new stream more than a minute behind its own).
        signer.signing.timestamp = max(signer.signing.timestamp, timestamp_now())
        packet: bytes = msg.pack(signer)
        signer.seq = (signer.seq + 1) % 256  # pack() leaves counting to send()
        return packet

    def peers(self) -> list[_Peer]:
        return self.tcp_peers + self.udp_peers


class PortUnavailable(OSError):
    """A vehicle's socket could not be bound: the system's reason (``errno``, ``strerror``),
    and which vehicle, on which address and port (0: a free one was asked for)."""

    def __init__(self, error: OSError, system_id: int, host: str, port: int) -> None:
        super().__init__(error.errno, error.strerror)
        self.system_id = system_id
        self.host = host
        self.port = port

    def __str__(self) -> str:
        return f"vehicle {self.system_id}: {self.host}:{self.port}: {self.strerror}"


class Simulator:
    """N simulated vehicles served on loopback (see the module docstring).

    ``frames`` says which kind each vehicle is (:mod:`sitl.frames`: copter, plane, rover;
    the last repeats); ArduCopters by default.
    """

    def __init__(
        self, vehicles: int = 1, home: Home | None = None, speedup: float = 1.0, seed: int = 0,
        world: World | None = None, faults: Faults | None = None,
        tcp_base_port: int | None = 5760, udp_out: list[str] | tuple[str, ...] = (),
        bind: str = "127.0.0.1", realtime: bool = True, params: dict[str, float] | None = None,
        frames: list[str] | tuple[str, ...] = (),
        signing_key: bytes | None = None, lockstep: Lockstep | None = None,
        heard: IO[str] | None = None,
    ) -> None:
        if not 1 <= vehicles <= MAX_VEHICLES:
            raise ValueError(f"1 to {MAX_VEHICLES} vehicles (a MAVLink system id is one byte)")
        if speedup <= 0:
            raise ValueError("speedup must be positive")
        self.speedup = speedup
        self.realtime = realtime or lockstep is not None
        self.lockstep = lockstep
        self.bind = bind
        self.tcp_base_port = tcp_base_port
        self.udp_out = [parse_udp_address(address) for address in udp_out]
        self.faults = faults or Faults(seed=seed)
        world = world or World()
        base = home or world.home_or_default
        kinds = {FRAMES[frame_of(frames, index)] for index in range(vehicles)}
        known = {name for kind in kinds for name, _, _ in kind.parameter_table}
        for name in params or {}:
            if name not in known:
                raise UnknownParameter(name)
        self._endpoints: list[_Endpoint] = []
        for index in range(vehicles):
            lat, lon, alt = to_global(0.0, VEHICLE_SPACING * index, 0.0,
                                      base.latitude, base.longitude, base.altitude)
            own_home = replace(base, latitude=lat, longitude=lon, altitude=alt)
            kind = FRAMES[frame_of(frames, index)]
            model = kind(index + 1, own_home, world, seed, _own(kind, params), self.faults)
            self._endpoints.append(_Endpoint(model, self.faults, signing_key))
        # The vehicles whose packets pass through fault channels (lost, delayed).
        self._channelled = [e for e in self._endpoints
                            if e.incoming is not None or e.outgoing is not None]
        if signing_key is not None and len(signing_key) != 32:
            raise ValueError("a MAVLink 2 signing key is 32 bytes")
        self.signing_key = signing_key
        self._refused = [0, 0]  # messages dropped: unsigned, wrongly signed
        self.time = 0.0
        self._ticks = 0
        self._selector = selectors.DefaultSelector()
        self._thread: threading.Thread | None = None
        self._running = threading.Event()
        self._rebase = threading.Event()  # the speed-up changed: count from now on
        self._started = False
        self.heard = heard  # see "Who spoke to a vehicle" in the module docstring

    # ------------------------------------------------------------------ API
    @property
    def tcp_ports(self) -> list[int]:
        """The TCP port of each vehicle (index 0 = system id 1); empty without TCP."""
        return [e.listener.getsockname()[1] for e in self._endpoints if e.listener is not None]

    @property
    def udp_ports(self) -> list[int]:
        """The local port each vehicle sends its UDP stream from."""
        return [e.udp.getsockname()[1] for e in self._endpoints if e.udp is not None]

    def vehicle(self, system_id: int) -> VehicleModel:
        """The model of vehicle ``system_id`` (1-based)."""
        if not 1 <= system_id <= len(self._endpoints):
            raise KeyError(f"no vehicle with system id {system_id}")
        return self._endpoints[system_id - 1].model

    @property
    def vehicles(self) -> list[VehicleModel]:
        """All vehicle models, by system id."""
        return [e.model for e in self._endpoints]

    def start(self) -> Simulator:
        """Open the sockets; in real time, also start the loop thread. Returns self."""
        if self._started:
            return self
        try:
            for index, endpoint in enumerate(self._endpoints):
                self._open(endpoint, index)
        except OSError:
            self._close()
            raise
        self._started = True
        if self.realtime:
            self._running.set()
            loop = self._loop if self.lockstep is None else self._lockstep_loop
            self._thread = threading.Thread(target=loop, name="sitl", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the loop and close every socket."""
        self._running.clear()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self._close()
        self._started = False

    def __enter__(self) -> Simulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def set_speedup(self, speedup: float) -> None:
        """Run real time ``speedup`` times faster from now on: vehicle time goes on from
        where it stands (a test slows a flight down for a while, as when a link cut must
        last long on the wall clock of a ground station in another process)."""
        if speedup <= 0:
            raise ValueError("speedup must be positive")
        self.speedup = speedup
        self._rebase.set()

    def advance(self, seconds: float) -> None:
        """Step vehicle time by ``seconds`` (realtime=False), serving I/O between ticks."""
        if self.realtime:
            raise RuntimeError("advance() is for realtime=False simulators")
        if not self._started:
            self.start()
        for _ in range(max(0, round(seconds / TICK))):
            self._serve(0.0)
            self._tick()
        self._serve(0.0)

    # --------------------------------------------------------------- sockets
    def _open(self, endpoint: _Endpoint, index: int) -> None:
        if self.tcp_base_port is not None:
            port = self.tcp_base_port + 10 * index if self.tcp_base_port else 0
            listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            endpoint.listener = listener  # closed by _close() should the bind fail
            listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._bind(listener, port, index)
            listener.listen(4)
            listener.setblocking(False)
            self._selector.register(listener, selectors.EVENT_READ, (endpoint, None))
        if self.udp_out:
            udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            endpoint.udp = udp
            self._bind(udp, 0, index)
            udp.setblocking(False)
            endpoint.udp_peers = [_Peer(udp, address, self.signing_key)
                                  for address in self.udp_out]
            self._selector.register(udp, selectors.EVENT_READ, (endpoint, "udp"))

    def _bind(self, sock: socket.socket, port: int, index: int) -> None:
        try:
            sock.bind((self.bind, port))
        except OSError as error:
            raise PortUnavailable(error, index + 1, self.bind, port) from error

    def _close(self) -> None:
        for endpoint in self._endpoints:
            sockets = [p.sock for p in endpoint.tcp_peers]
            sockets += [s for s in (endpoint.listener, endpoint.udp) if s is not None]
            for sock in sockets:
                with contextlib.suppress(KeyError, ValueError):
                    self._selector.unregister(sock)
                sock.close()
            endpoint.tcp_peers, endpoint.udp_peers = [], []
            endpoint.listener = endpoint.udp = None

    def _serve(self, timeout: float) -> bool:
        """Read what came in (True when anything did), deliver what is due, flush."""
        ready = self._selector.select(timeout)
        for key, _ in ready:
            endpoint, peer = key.data
            if peer is None:
                self._accept(endpoint)
            elif peer == "udp":
                self._read_udp(endpoint)
            else:
                self._read_tcp(endpoint, peer)
        if self._channelled:
            self._deliver_due()
        gone = None
        for endpoint in self._endpoints:
            for peer in endpoint.tcp_peers:
                # Most steps a vehicle has nothing to send.
                if peer.backlog and not peer.flush():
                    gone = gone or []
                    gone.append((endpoint, peer))
        for endpoint, peer in gone or ():
            self._drop(endpoint, peer)
        return bool(ready)

    def _accept(self, endpoint: _Endpoint) -> None:
        assert endpoint.listener is not None
        try:
            sock, remote = endpoint.listener.accept()
        except BlockingIOError:
            return
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        peer = _Peer(sock, signing_key=self.signing_key, lockstep=self.lockstep, remote=remote)
        endpoint.tcp_peers.append(peer)
        self._selector.register(sock, selectors.EVENT_READ, (endpoint, peer))

    def _drop(self, endpoint: _Endpoint, peer: _Peer) -> None:
        with contextlib.suppress(KeyError, ValueError):
            self._selector.unregister(peer.sock)
        peer.sock.close()
        if peer in endpoint.tcp_peers:
            endpoint.tcp_peers.remove(peer)

    def _read_tcp(self, endpoint: _Endpoint, peer: _Peer) -> None:
        try:
            data = peer.sock.recv(65536)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._drop(endpoint, peer)
            return
        if peer.lockstep is not None:
            peer.lockstep.carried(peer.remote, -len(data))
        self._received(endpoint, peer, data)

    def _read_udp(self, endpoint: _Endpoint) -> None:
        assert endpoint.udp is not None
        while True:
            try:
                data, address = endpoint.udp.recvfrom(65536)
            except (BlockingIOError, ConnectionRefusedError):
                return
            except OSError:
                return
            peer = next((p for p in endpoint.udp_peers if p.address == address), None)
            if peer is None:  # a ground station answering from another port: serve it too
                peer = _Peer(endpoint.udp, address)
                endpoint.udp_peers.append(peer)
            self._received(endpoint, peer, data)

    @property
    def signing_rejected(self) -> tuple[int, int]:
        """Messages refused with signing on: (unsigned, wrongly signed)."""
        return self._refused[0], self._refused[1]

    def _received(self, endpoint: _Endpoint, peer: _Peer, data: bytes) -> None:
        signing = peer.parser.signing
        before = (signing.reject_count, signing.badsig_count)
        try:
            messages = peer.parser.parse_buffer(data) or []
        except mavlink.MAVError:
            return
        finally:
            bad = signing.badsig_count - before[1]
            self._refused[0] += signing.reject_count - before[0] - bad
            self._refused[1] += bad
        routing = len(endpoint.peers()) > 1
        for msg in messages:
            if msg.get_type() == "BAD_DATA":
                continue
            if self.heard is not None:
                self._write_heard(endpoint, peer, msg)
            if routing:
                self._route(endpoint, peer, msg)
            if endpoint.incoming is not None:
                endpoint.incoming.send(self.time, msg)
            else:
                self._emit(endpoint, endpoint.model.handle(msg))
                if endpoint.model.reboot_due:  # asked: after its ACK, as ArduPilot
                    self._reboot(endpoint)

    def _write_heard(self, endpoint: _Endpoint, peer: _Peer, msg: Any) -> None:
        assert self.heard is not None
        where = peer.remote or peer.address
        self.heard.write(json.dumps({
            "v": endpoint.model.system_id, "t": round(self.time, 3),
            "wall": round(time.time(), 4), "src": msg.get_srcSystem(),
            "comp": msg.get_srcComponent(), "type": msg.get_type(),
            "to": getattr(msg, "target_system", 0),
            "port": where[1] if where else None}) + "\n")
        self.heard.flush()  # read while the simulator runs, and kept if it is killed

    def _route(self, endpoint: _Endpoint, source: _Peer, msg: Any) -> None:
        """Forward ``msg`` from ``source`` to the vehicle's other clients, as ArduPilot's
        MAVLink routing does (see the module docstring)."""
        sender = (msg.get_srcSystem(), msg.get_srcComponent())
        source.routes.add(sender)
        system = getattr(msg, "target_system", 0)
        component = getattr(msg, "target_component", 0)
        for peer in endpoint.peers():
            if peer is source or sender in peer.routes:
                continue
            if msg.get_type() == "HEARTBEAT":
                wanted = True
            elif system == 0:
                wanted = bool(peer.routes)
            else:
                wanted = any(s == system and component in (0, c) for s, c in peer.routes)
            if wanted:
                peer.send(msg.get_msgbuf())

    def _deliver_due(self) -> None:
        for endpoint in self._channelled:
            if endpoint.incoming is not None:
                for msg in endpoint.incoming.due(self.time):
                    self._emit(endpoint, endpoint.model.handle(msg))
                    if endpoint.model.reboot_due:
                        self._reboot(endpoint)
            if endpoint.outgoing is not None:
                for packet in endpoint.outgoing.due(self.time):
                    for peer in endpoint.peers():
                        peer.send(packet)

    def _emit(self, endpoint: _Endpoint, messages: list[Any]) -> None:
        if not messages or not (endpoint.tcp_peers or endpoint.udp_peers):
            return  # nothing to say, or nobody listens: skip the encoding work
        packets = endpoint.encode_all(messages)
        if endpoint.outgoing is not None:
            for packet in packets:
                endpoint.outgoing.send(self.time, packet)
            return
        # A TCP client takes the step's packets as one piece of its stream; a UDP address
        # one datagram per packet.
        joined = b"".join(packets)
        for peer in endpoint.tcp_peers:
            peer.send(joined)
        for peer in endpoint.udp_peers:
            for packet in packets:
                peer.send(packet)

    # ------------------------------------------------------------------ clock
    def _tick(self) -> None:
        self._ticks += 1
        self.time = self._ticks * TICK
        for endpoint in self._endpoints:
            model = endpoint.model
            out = model.step_wire(TICK)
            if out:  # most steps send nothing
                self._emit(endpoint, out)
            if model.reboot_due:  # a fault (Faults.reboot_at)
                self._reboot(endpoint)

    def _reboot(self, endpoint: _Endpoint) -> None:
        """The vehicle reboots: a new boot takes the model's place (its clients stay
        connected, as to an ArduPilot SITL's serial port; packets count from 0 again)."""
        endpoint.model = endpoint.model.rebooted()
        endpoint.sequences.clear()

    def _loop(self) -> None:
        wall_start, time_start = time.monotonic(), self.time
        while self._running.is_set():
            if self._rebase.is_set():
                self._rebase.clear()
                wall_start, time_start = time.monotonic(), self.time
            target = time_start + (time.monotonic() - wall_start) * self.speedup
            if target - self.time > 1.0:  # too slow: run behind instead of bursting
                wall_start, time_start = time.monotonic(), self.time
            while self.time + TICK <= target and self._running.is_set():
                self._tick()
                self._serve(0.0)
            wait = (self.time + TICK - target) / self.speedup
            self._serve(min(max(wait, 0.0), 0.01))

    def _lockstep_loop(self) -> None:
        lockstep = self.lockstep
        assert lockstep is not None
        wall_start, time_start = time.monotonic(), self.time
        while self._running.is_set():
            self._serve(0.0)
            if any(peer.backlog for e in self._endpoints for peer in e.tcp_peers):
                self._serve(0.001)  # a client reads slowly: what it was sent comes first
                continue
            if not lockstep.settled():
                lockstep.wait_settled(0.002)
                continue
            # Settled: everything sent before the waits began is in the sockets by now.
            if self._serve(0.0):
                continue
            if lockstep.fire():  # the timers of this instant, once its messages are handled
                continue
            if self._rebase.is_set():
                self._rebase.clear()
                wall_start, time_start = time.monotonic(), self.time
            target = time_start + (time.monotonic() - wall_start) * self.speedup
            if target - self.time > 1.0:  # held up: run behind instead of bursting
                wall_start, time_start = time.monotonic(), self.time
            if self.time + TICK > target:
                self._serve(min((self.time + TICK - target) / self.speedup, 0.01))
                continue
            self._tick()
            lockstep.advance(self.time)
