"""Real-time factor of the simulator for 1, 10 and 50 vehicles, against its bare models.

Each run starts the simulator with realtime=False on loopback, connects one TCP client
per vehicle that reads everything it asked for (every stream group at 4 Hz, so every
message is built, encoded and sent), arms every vehicle and takes it off to 20 m in
GUIDED (it climbs for about 11 s, then holds its position), and steps vehicle time as
fast as the machine allows. The real-time factor is vehicle seconds per second of this
process's CPU time (user and system, the clients' reads included): on a machine shared
with other work that is what the wall-clock factor, the ceiling for ``--speedup``, is
on an idle core; the wall-clock factor is printed beside it.

The peer, measured in the same run on the same machine load: the same vehicle models
given the same commands and stepped in a bare loop, with no server, no streams asked
for and nothing encoded or sent (physics, modes, failsafes and the HEARTBEAT only). The
ratio served/bare is the share of the vehicles' time left after the MAVLink side.

    python benchmarks/sim.py [--seconds 60] [--vehicles 1 10 50]
"""

from __future__ import annotations

import argparse
import os
import socket
import time

from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.model import TICK, VehicleModel
from sitl.server import Simulator
from tml.world import Home

FAST = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2}


def _take_off(model: VehicleModel, streams: bool) -> None:
    if streams:  # nothing streams unasked (as on ArduPilot): ask for every group at 4 Hz
        model.handle(M.MAVLink_request_data_stream_message(
            model.system_id, 1, M.MAV_DATA_STREAM_ALL, 4, 1))
    model.set_mode("GUIDED")
    model.handle(M.MAVLink_command_long_message(model.system_id, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    model.handle(M.MAVLink_command_long_message(model.system_id, 1, 22, 0, 0, 0, 0, 0, 0, 0, 20))


def real_time_factor(vehicles: int, seconds: float) -> tuple[float, float]:
    """Vehicle seconds simulated per CPU second and per wall-clock second with
    ``vehicles`` served."""
    with Simulator(vehicles=vehicles, tcp_base_port=0, realtime=False, params=FAST) as sim:
        clients = [socket.create_connection(("127.0.0.1", port)) for port in sim.tcp_ports]
        for client in clients:
            client.setblocking(False)
        sim.advance(3)
        for model in sim.vehicles:
            _take_off(model, streams=True)
        start, cpu = time.perf_counter(), time.process_time()
        for _ in range(round(seconds)):
            sim.advance(1.0)
            for client in clients:
                while True:
                    try:
                        if not client.recv(1 << 16):
                            break
                    except BlockingIOError:
                        break
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        for client in clients:
            client.close()
    return seconds / cpu, seconds / wall


def bare_factor(vehicles: int, seconds: float) -> float:
    """Vehicle seconds per CPU second of the same vehicles stepped directly: no server,
    no streams, nothing encoded."""
    home = Home(-35.363261, 149.165230, 584.0)
    models = [VehicleModel(index + 1, home, params=FAST) for index in range(vehicles)]
    for model in models:
        model.step(3.0)
        _take_off(model, streams=False)
    start = time.process_time()
    for _ in range(round(seconds / TICK)):
        for model in models:
            model.step(TICK)
    return seconds / (time.process_time() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="vehicle seconds per run")
    parser.add_argument("--vehicles", type=int, nargs="+", default=[1, 10, 50])
    args = parser.parse_args()
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at the start")
    print(f"{'vehicles':>8}  {'served':>9}  {'vehicle-s/s':>11}  {'wall-clock':>10}  "
          f"{'bare models':>11}  {'served/bare':>11}")
    for vehicles in args.vehicles:
        factor, wall = real_time_factor(vehicles, args.seconds)
        bare = bare_factor(vehicles, args.seconds)
        print(f"{vehicles:>8}  {factor:>8.1f}x  {factor * vehicles:>11.1f}  {wall:>9.1f}x  "
              f"{bare:>10.1f}x  {factor / bare:>11.2f}")
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
