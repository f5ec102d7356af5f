"""Real-time factor of the simulator for 1, 10 and 50 vehicles.

Each run starts the simulator with realtime=False on loopback, connects one TCP client
per vehicle that reads everything it asked for (every stream group at 4 Hz, so every
message is encoded and sent), arms every
vehicle and flies it up and around in GUIDED, and steps vehicle time as fast as the
machine allows. The real-time factor is vehicle seconds per wall-clock second: the
ceiling for ``--speedup``.

    python benchmarks/sim.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import socket
import time

from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.server import Simulator

FAST = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2}


def real_time_factor(vehicles: int, seconds: float) -> float:
    """Vehicle seconds simulated per wall-clock second with ``vehicles`` flying."""
    with Simulator(vehicles=vehicles, tcp_base_port=0, realtime=False, params=FAST) as sim:
        clients = [socket.create_connection(("127.0.0.1", port)) for port in sim.tcp_ports]
        for client in clients:
            client.setblocking(False)
        sim.advance(3)
        for model in sim.vehicles:
            # Nothing streams unasked (as on ArduPilot): ask for every group at 4 Hz.
            model.handle(M.MAVLink_request_data_stream_message(
                model.system_id, 1, M.MAV_DATA_STREAM_ALL, 4, 1))
            model.set_mode("GUIDED")
            model.handle(M.MAVLink_command_long_message(
                model.system_id, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
            model.handle(M.MAVLink_command_long_message(
                model.system_id, 1, 22, 0, 0, 0, 0, 0, 0, 0, 20))
        start = time.perf_counter()
        for _ in range(round(seconds)):
            sim.advance(1.0)
            for client in clients:
                while True:
                    try:
                        if not client.recv(1 << 16):
                            break
                    except BlockingIOError:
                        break
        wall = time.perf_counter() - start
        for client in clients:
            client.close()
    return seconds / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="vehicle seconds per run")
    args = parser.parse_args()
    print(f"{'vehicles':>8}  {'real-time factor':>16}  {'vehicle-seconds/s':>17}")
    for vehicles in (1, 10, 50):
        factor = real_time_factor(vehicles, args.seconds)
        print(f"{vehicles:>8}  {factor:>15.1f}x  {factor * vehicles:>17.1f}")


if __name__ == "__main__":
    main()
