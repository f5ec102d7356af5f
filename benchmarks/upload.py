"""Mission upload over loopback: tml against MAVProxy and against the protocol's floor.

Starts the simulator (one vehicle, TCP on a free port) in a process of its own, so that
neither tml nor MAVProxy shares an interpreter lock with it, and, for missions of 10, 100 and
500 waypoints (plus ArduPilot's home slot), measures in the same run:

* tml: ``Autopilot.upload(items, verify=False)``, MISSION_COUNT to MISSION_ACK;
* MAVProxy: ``wp load FILE`` of the same mission, from its "Loaded N waypoints from" line
  (printed right before it sends MISSION_COUNT) to its "Got MISSION_ACK" line;
* the floor: one round trip per message exchanged (N + 2 of them: COUNT -> request, each
  item -> next request or ACK), each timed as a bare MISSION_REQUEST_LIST -> MISSION_COUNT
  exchange with the same simulator over a raw pymavlink connection.

tml and MAVProxy stay connected to the simulator side by side and take turns, one upload
each, so that a change in the machine's load affects both alike. Prints the median of each
and the ratios. Needs the ``bench`` extra (MAVProxy):

    /work/venv/bin/python benchmarks/upload.py [--sizes 10 100 500] [--repeat 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tml.mavlink.autopilot import Autopilot
from tml.mavlink.codec import mavlink, mavutil
from tml.mavlink.link import Link
from tml.mavlink.mission import MissionItem

HOME = (-35.3632621, 149.1652374, 584.0)
TML_SYSTEM = 250
FRAME = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT


def mission(n: int) -> list[MissionItem]:
    """N waypoints 1 m apart going north, 20 m up."""
    return [MissionItem(seq=i, frame=FRAME, command=mavlink.MAV_CMD_NAV_WAYPOINT,
                        x=round((HOME[0] + 1e-5 * (i + 1)) * 1e7), y=round(HOME[1] * 1e7),
                        z=20.0) for i in range(n)]


def waypoint_file(n: int, directory: str) -> str:
    """The same mission as a QGC WPL 110 file (line 0 is home), for MAVProxy."""
    lines = ["QGC WPL 110", f"0\t1\t0\t16\t0\t0\t0\t0\t{HOME[0]}\t{HOME[1]}\t{HOME[2]}\t1"]
    lines += [f"{i + 1}\t0\t{FRAME}\t16\t0\t0\t0\t0\t{item.x / 1e7:.7f}\t{item.y / 1e7:.7f}"
              f"\t{item.z}\t1" for i, item in enumerate(mission(n))]
    path = os.path.join(directory, f"mission{n}.txt")
    Path(path).write_text("\n".join(lines) + "\n")
    return path


def round_trip(port: int, samples: int) -> float:
    """Median seconds of a MISSION_REQUEST_LIST -> MISSION_COUNT exchange."""
    conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=254,
                                      source_component=190)
    conn.wait_heartbeat(timeout=10)
    times = []
    for _ in range(samples):
        start = time.perf_counter()
        conn.mav.mission_request_list_send(1, 1, 0)
        if conn.recv_match(type="MISSION_COUNT", blocking=True, timeout=2) is None:
            continue
        times.append(time.perf_counter() - start)
    conn.close()
    return statistics.median(times)


def tml_upload(vehicle: Autopilot, n: int) -> float:
    """Seconds of tml's upload of ``n`` waypoints (MISSION_COUNT to MISSION_ACK)."""
    items = mission(n)
    start = time.perf_counter()
    vehicle.upload(items, verify=False)
    return time.perf_counter() - start


SIMULATOR = """
import sys
from sitl.server import Simulator
sim = Simulator(vehicles=1, tcp_base_port=0, speedup=float(sys.argv[1])).start()
print(sim.tcp_ports[0], flush=True)
sys.stdin.read()  # until the benchmark closes our stdin
sim.stop()
"""


def start_simulator(speedup: float) -> tuple[subprocess.Popen[str], int]:
    """The simulator in a child process, and the TCP port of its vehicle."""
    process = subprocess.Popen([sys.executable, "-c", SIMULATOR, str(speedup)],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                               cwd=Path(__file__).resolve().parents[1])
    assert process.stdout is not None
    return process, int(process.stdout.readline())


class MavProxy:
    """MAVProxy headless on the simulator, fed commands on stdin, its output timestamped."""

    def __init__(self, port: int) -> None:
        self.lines: list[tuple[float, str]] = []
        self._seen = threading.Condition()
        self.process = subprocess.Popen(
            [sys.executable, "-m", "MAVProxy.mavproxy", f"--master=tcp:127.0.0.1:{port}",
             "--no-state", "--default-modules=wp", "--target-system=1",
             "--target-component=1"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"}, cwd=tempfile.gettempdir())
        threading.Thread(target=self._read, daemon=True).start()
        self.wait_for("Detected vehicle 1:1", 0)

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            with self._seen:
                self.lines.append((time.perf_counter(), line))
                self._seen.notify_all()

    def wait_for(self, text: str, after: int, timeout: float = 60.0) -> tuple[float, int]:
        """When the first line from index ``after`` containing ``text`` was printed."""
        end = time.monotonic() + timeout
        with self._seen:
            while True:
                for index in range(after, len(self.lines)):
                    if text in self.lines[index][1]:
                        return self.lines[index][0], index + 1
                if time.monotonic() > end:
                    raise TimeoutError(f"MAVProxy never printed {text!r}")
                self._seen.wait(0.5)

    def upload(self, path: str, count: int) -> float:
        """Seconds from MAVProxy's MISSION_COUNT to its MISSION_ACK for ``wp load path``."""
        after = len(self.lines)
        assert self.process.stdin is not None
        self.process.stdin.write(f"wp load {path}\n")
        self.process.stdin.flush()
        start, after = self.wait_for(f"Loaded {count} waypoints from", after)
        end, _ = self.wait_for("Got MISSION_ACK: TYPE_MISSION: ACCEPTED", after)
        return end - start

    def close(self) -> None:
        assert self.process.stdin is not None
        self.process.stdin.write("set requireexit 1\nexit\n")
        self.process.stdin.close()
        try:
            self.process.wait(10)
        except subprocess.TimeoutExpired:
            self.process.kill()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 500])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--speedup", type=float, default=1.0)
    args = parser.parse_args()
    simulator, port = start_simulator(args.speedup)
    try:
        with tempfile.TemporaryDirectory() as directory:
            time.sleep(1.5 / args.speedup)  # the vehicle refuses uploads a second after boot
            compare(port, args.sizes, args.repeat, directory)
    finally:
        assert simulator.stdin is not None
        simulator.stdin.close()
        simulator.wait(10)


def compare(port: int, sizes: list[int], repeat: int, directory: str) -> None:
    """Measure and print the table."""
    rtt = round_trip(port, 200)
    print(f"round trip (MISSION_REQUEST_LIST -> MISSION_COUNT): {rtt * 1e3:.3f} ms")
    print(f"{'items':>6} {'floor ms':>10} {'tml ms':>10} {'MAVProxy ms':>12} "
          f"{'tml/floor':>10} {'MAVProxy/tml':>13}")
    proxy = MavProxy(port)
    try:
        # Not system 255 like MAVProxy: each must know the vehicle's answers for its own.
        with Link(f"tcp:127.0.0.1:{port}", source_system=TML_SYSTEM) as link:
            vehicle = Autopilot.connect(link, 1, timeout=10)
            for n in sizes:
                path = waypoint_file(n, directory)
                vehicle.upload(mission(n), verify=True)  # warm-up, and proof it arrives whole
                proxy.upload(path, n + 1)  # warm-up
                tml_times, proxy_times = [], []
                for _ in range(repeat):
                    proxy_times.append(proxy.upload(path, n + 1))
                    tml_times.append(tml_upload(vehicle, n))
                report(n, rtt, statistics.median(tml_times), statistics.median(proxy_times))
    finally:
        proxy.close()


def report(n: int, rtt: float, ours: float, theirs: float) -> None:
    """One line of the table."""
    floor = (n + 2) * rtt
    print(f"{n:>6} {floor * 1e3:>10.2f} {ours * 1e3:>10.2f} {theirs * 1e3:>12.2f} "
          f"{ours / floor:>10.2f} {theirs / ours:>13.2f}", flush=True)


if __name__ == "__main__":
    main()
