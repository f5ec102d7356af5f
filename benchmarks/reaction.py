"""Reaction time: from the telemetry message that makes an event true to the command it causes.

Run by hand: ``python benchmarks/reaction.py [--trials 1000] [--breakdown]``.

A TCP proxy sits between the ground side and the embedded simulator (1x). It injects, as
the vehicle's companion computer (component 191), NAMED_VALUE_FLOAT ``TRIGGER`` = 1 and
stamps the moment it writes it to the ground side; it stamps the moment the first byte of
the resulting COMMAND_LONG (DO_DIGICAM_CONTROL) arrives from the ground side. Then it
injects ``TRIGGER`` = 0, waits for the vehicle's COMMAND_ACK, and starts the next trial.

Two ground sides are measured in the same run:

- ``tml run``'s stack: MavlinkVehicle + Runner + Interpreter, with the mission below (an
  edge-triggered event whose action is CAPTURE_PHOTO, termination CONTINUE);
- the peer: a bare pymavlink loop that blocks on ``recv_match`` and answers the trigger with
  the same command -- the least any Python ground station can do.

It prints p50 and p99 of both and their ratio. With ``--breakdown`` (which costs tml a
little: every stamp is a wrapped call) it also prints where tml's time goes, hop by hop:
the link's handling of the trigger, the runner's wake, its look before the interpreter's
step, the step, the request's procedure begun (on the runner's thread, up to its first
step: tml.mavlink.link.Link.begin), and the command's sending.
"""

from __future__ import annotations

import argparse
import os
import socket
import statistics
import sys
import threading
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("MAVLINK20", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.server import Simulator

MISSION = b"""<mission name="Reaction">
  <parameter name="TRIGGER" type="number"
             description="NAMED_VALUE_FLOAT TRIGGER from the companion computer"/>
  <task name="Wait"><action name="WAIT"><argument name="duration" value="86400"/></action>
  </task>
  <event_handling>
    <event name="Trigger">
      <condition parameter="TRIGGER" comparison="equal" value="1"/>
      <action name="CAPTURE_PHOTO"/>
      <termination mode="CONTINUE"/>
    </event>
  </event_handling>
</mission>"""
COMMAND = mavlink.MAV_CMD_DO_DIGICAM_CONTROL


class Proxy:
    """Forwards bytes between one ground client and the simulator; injects and times."""

    def __init__(self, sim_port: int) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.sim_port = sim_port
        self.encoder = mavlink.MAVLink(None, 1, 191)
        self.lock = threading.Lock()
        self.command_at: float | None = None
        self.acked = threading.Event()
        self.commanded = threading.Event()
        self.ground: socket.socket | None = None
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        ground, _ = self.server.accept()
        ground.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        vehicle = socket.create_connection(("127.0.0.1", self.sim_port))
        vehicle.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.ground = ground
        threading.Thread(target=self._pump, args=(vehicle, ground, True), daemon=True).start()
        self._pump(ground, vehicle, False)

    def _pump(self, source: socket.socket, sink: socket.socket, from_vehicle: bool) -> None:
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True
        while True:
            try:
                data = source.recv(65536)
            except OSError:
                return
            now = time.perf_counter()
            if not data:
                return
            for msg in parser.parse_buffer(data) or []:
                kind = msg.get_type()
                if not from_vehicle and kind == "COMMAND_LONG" and msg.command == COMMAND \
                        and self.command_at is None:
                    self.command_at = now
                    self.commanded.set()
                if from_vehicle and kind == "COMMAND_ACK" and msg.command == COMMAND:
                    self.acked.set()
            with self.lock:
                try:
                    sink.sendall(data)
                except OSError:
                    return

    def inject(self, value: float) -> float:
        """Send TRIGGER = value to the ground side as the companion; returns when."""
        packet = self.encoder.named_value_float_encode(0, b"TRIGGER", value).pack(self.encoder)
        self.encoder.seq = (self.encoder.seq + 1) % 256
        with self.lock:
            stamp = time.perf_counter()
            assert self.ground is not None
            self.ground.sendall(packet)
        return stamp


def trials(proxy: Proxy, count: int, settle: float) -> list[float]:
    """Reaction times in milliseconds."""
    times = []
    for _ in range(count):
        proxy.command_at = None
        proxy.commanded.clear()
        proxy.acked.clear()
        sent = proxy.inject(1.0)
        if not proxy.commanded.wait(5.0) or not proxy.acked.wait(5.0):
            raise SystemExit(f"no command (or no ACK) came back within 5 s, trial {len(times)}")
        assert proxy.command_at is not None
        times.append((proxy.command_at - sent) * 1000)
        proxy.inject(0.0)
        time.sleep(settle)  # the false value reaches the event: the next 1 is a new edge
    return times


HOPS = ("trigger handled by the link", "runner woken", "interpreter stepped from",
        "interpreter's step done", "request submitted", "procedure begun", "command sent")
"""The stamps of ``--breakdown``, in order; the first is timed from the trigger written."""


class Breakdown:
    """Stamps each trial's way through tml (see HOPS) by wrapping the calls on it."""

    def __init__(self, proxy_class: type) -> None:
        from tml.engine.interpreter import Interpreter
        from tml.mavlink.adapter import MavlinkVehicle
        from tml.mavlink.link import Link
        from tml.run.runner import Runner

        self.trial = 0
        self.stamps: dict[tuple[int, int], float] = {}
        hop = self.hop

        def handle(original: Any, link: Any, msg: Any, now: float) -> Any:
            if msg.get_type() == "NAMED_VALUE_FLOAT" and msg.value == 1.0:
                hop(1)
            return original(link, msg, now)

        def tick(original: Any, runner: Any, *args: Any) -> Any:
            if (self.trial, 1) in self.stamps:
                hop(2)
            return original(runner, *args)

        def step(original: Any, engine: Any, *args: Any, **kwargs: Any) -> Any:
            if (self.trial, 2) in self.stamps:
                hop(3)
            output = original(engine, *args, **kwargs)
            if (self.trial, 3) in self.stamps:
                hop(4)
            return output

        def send(original: Any, link: Any, msg: Any, *args: Any, **kwargs: Any) -> Any:
            if getattr(msg, "command", None) == COMMAND:
                hop(7)
            return original(link, msg, *args, **kwargs)

        def inject(original: Any, proxy: Any, value: float) -> float:
            stamp: float = original(proxy, value)
            if value == 1.0:
                self.trial += 1
                self.stamps[(self.trial, 0)] = stamp
            return stamp

        for owner, name, wrapper in (
                (Link, "_handle", handle), (Runner, "_tick", tick), (Interpreter, "step", step),
                (MavlinkVehicle, "submit", lambda o, v, r: (hop(5), o(v, r))[1]),
                (Link, "_advance", lambda o, k, p, e: (hop(6), o(k, p, e))[1]),
                (Link, "send", send), (proxy_class, "inject", inject)):
            setattr(owner, name, self._wrap(getattr(owner, name), wrapper))

    @staticmethod
    def _wrap(original: Any, wrapper: Any) -> Any:
        def wrapped(*args: Any, **kwargs: Any) -> Any:
            return wrapper(original, *args, **kwargs)
        return wrapped

    def hop(self, index: int) -> None:
        self.stamps.setdefault((self.trial, index), time.perf_counter())

    def print(self) -> None:
        """Each hop's p50 and p99, in ms, over the trials that passed every stamp."""
        whole = [t for t in range(1, self.trial + 1)
                 if all((t, i) in self.stamps for i in range(len(HOPS) + 1))]
        print(f"  where tml's time goes ({len(whole)} trials stamped at every hop), ms:")
        for index, name in enumerate(HOPS, start=1):
            spans = [(self.stamps[(t, index)] - self.stamps[(t, index - 1)]) * 1000
                     for t in whole]
            print(f"    {name:30s} p50 {percentile(spans, 0.5):7.3f}  p99 "
                  f"{percentile(spans, 0.99):7.3f}")


def tml_side(port: int, stop: threading.Event) -> None:
    from tml.engine import Options
    from tml.language.validation import validate_file
    from tml.mavlink.adapter import MavlinkVehicle
    from tml.mavlink.link import Link
    from tml.run.runner import Runner, RunOptions

    mission = validate_file("reaction.xml", MISSION).mission
    wake = threading.Event()
    with Link(f"tcp:127.0.0.1:{port}") as link:  # the vehicle wakes the runner (its watch)
        vehicle = MavlinkVehicle(link, 1, on_result=wake.set)
        vehicle.prepare()
        runner = Runner(mission, [vehicle], options=RunOptions(engine=Options()), wake=wake)
        threading.Thread(target=lambda: (stop.wait(), runner.stop("benchmark over")),
                         daemon=True).start()
        runner.run()
        vehicle.close()


def peer_side(port: int, stop: threading.Event) -> None:
    conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=255,
                                      source_component=190)
    conn.wait_heartbeat()
    armed = True
    while not stop.is_set():
        msg = conn.recv_match(type="NAMED_VALUE_FLOAT", blocking=True, timeout=0.5)
        if msg is None:
            continue
        if msg.value == 1.0 and armed:
            conn.mav.command_long_send(1, 1, COMMAND, 0, 0, 0, 0, 0, 1, 0, 0)
            armed = False
        elif msg.value == 0.0:
            armed = True


def measure(side: object, count: int, settle: float) -> list[float]:
    with Simulator(vehicles=1, speedup=1.0, tcp_base_port=0,
                   params={"SIM_GPS_LOCKTIME": 0.5, "SIM_EKF_GPS_TIME": 1.0}) as sim:
        proxy = Proxy(sim.tcp_ports[0])
        stop = threading.Event()
        thread = threading.Thread(target=side, args=(proxy.port, stop), daemon=True)
        thread.start()
        while proxy.ground is None:
            time.sleep(0.01)
        time.sleep(6.0)  # the ground side settles (rates, parameters, mission start)
        try:
            return trials(proxy, count, settle)
        finally:
            stop.set()
            thread.join(timeout=15)


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=1000)
    parser.add_argument("--settle", type=float, default=0.1,
                        help="seconds between a trial's end and the next trigger")
    parser.add_argument("--breakdown", action="store_true",
                        help="also stamp tml's hops and print where its time goes")
    args = parser.parse_args()
    breakdown = Breakdown(Proxy) if args.breakdown else None
    results = {"tml": measure(tml_side, args.trials, args.settle),
               "pymavlink loop": measure(peer_side, args.trials, args.settle)}
    print(f"reaction time, {args.trials} trials each (ms): trigger written -> first byte "
          "of the command read")
    for name, values in results.items():
        print(f"  {name:15s} p50 {percentile(values, 0.5):7.3f}  p99 "
              f"{percentile(values, 0.99):7.3f}  mean {statistics.fmean(values):7.3f}  "
              f"max {max(values):7.3f}")
    tml, peer = results["tml"], results["pymavlink loop"]
    print(f"  ratio tml / peer: p50 {percentile(tml, 0.5) / percentile(peer, 0.5):.2f}x, "
          f"p99 {percentile(tml, 0.99) / percentile(peer, 0.99):.2f}x")
    if breakdown is not None:
        breakdown.print()


if __name__ == "__main__":
    main()
