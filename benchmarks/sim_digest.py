"""Digests of what the simulator serves and how its vehicles move, to compare two versions.

A change made for speed must leave the simulator's behaviour as it was: run this on the
code before and after and compare the lines. It serves five vehicles (three ArduCopters,
an ArduPlane, a Rover) with ``realtime=False``, one TCP client each asking for every
stream group at 4 Hz and for EXTENDED_SYS_STATE, HOME_POSITION, GPS_GLOBAL_ORIGIN and
GUIDED's targets by interval, and flies a script through the sockets: take-offs, an AUTO
mission (uploaded to vehicle 2), a GUIDED position target, a velocity target, a speed
change, BRAKE, a CONDITION_YAW turn, RTL and landing. It prints, per parameter set
(ArduPilot's defaults; wind, a simulated pack, a slower WPNAV_SPEED and the fence on),
the bytes each client received and a digest of them (with the mission upload's replies),
and a digest of every vehicle's position, velocity, acceleration, heading, consumed
charge and mode at every control step.

    python benchmarks/sim_digest.py
"""

from __future__ import annotations

import hashlib
import socket
import time
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.model import TICK
from sitl.server import Simulator

FAST = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2}
FRAMES = ("copter", "copter", "copter", "plane", "rover")
INTERVALS = (M.MAVLINK_MSG_ID_POSITION_TARGET_GLOBAL_INT,
             M.MAVLINK_MSG_ID_POSITION_TARGET_LOCAL_NED, M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN,
             M.MAVLINK_MSG_ID_HOME_POSITION, M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE)
# (command, north m, east m, altitude m) of vehicle 2's mission; 0, 0 is "here".
MISSION = ((16, 0, 0, 0), (22, 0, 0, 15), (16, 60, 0, 20), (16, 60, 60, 25), (16, 0, 60, 15),
           (20, 0, 0, 0))


def _drain(client: socket.socket, into: bytearray) -> None:
    while True:
        try:
            data = client.recv(1 << 16)
        except BlockingIOError:
            return
        if not data:
            return
        into += data


def _command(system: int, command: int, *params: float) -> Any:
    return M.MAVLink_command_long_message(system, 1, command, 0, *params,
                                          *[0.0] * (7 - len(params)))


def fly(params: dict[str, float]) -> tuple[list[int], str, str]:
    """Bytes received per client, the digest of everything received, the states' digest."""
    link = M.MAVLink(None, 255, 190)
    states: list[Any] = []
    with Simulator(vehicles=len(FRAMES), tcp_base_port=0, realtime=False, params=params,
                   frames=FRAMES) as sim:
        clients = [socket.create_connection(("127.0.0.1", port)) for port in sim.tcp_ports]
        for client in clients:
            client.setblocking(False)
        received = [bytearray() for _ in clients]

        def send(index: int, msg: Any) -> None:
            clients[index].sendall(msg.pack(link))
            link.seq = (link.seq + 1) % 256

        def advance(seconds: float) -> None:
            time.sleep(0.05)  # what was just sent is in the simulator's sockets
            for _ in range(round(seconds / TICK)):
                sim.advance(TICK)
                for client, into in zip(clients, received, strict=True):
                    _drain(client, into)
                states.extend((m.body.position, m.body.velocity, m.body.accel, m.body.heading,
                               m.battery.consumed_mah, m.mode) for m in sim.vehicles)

        for index, model in enumerate(sim.vehicles):
            system = model.system_id
            send(index, M.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))
            send(index, M.MAVLink_request_data_stream_message(
                system, 1, M.MAV_DATA_STREAM_ALL, 4, 1))
            for msg_id in INTERVALS:
                send(index, _command(system, M.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 200_000))
        advance(3)
        second = sim.vehicles[1]
        home = second.origin
        replies = second.handle(M.MAVLink_mission_count_message(2, 1, len(MISSION), 0))
        for seq, (command, north, east, altitude) in enumerate(MISSION):
            here = command in (22, 20)
            lat = 0 if here else round((home.latitude + north / 111111.0) * 1e7)
            lon = 0 if here else round((home.longitude + east / 91000.0) * 1e7)
            replies += second.handle(M.MAVLink_mission_item_int_message(
                2, 1, seq, 3, command, 0, 1, 0, 0, 0, 0, lat, lon, altitude, 0))
        for index, model in enumerate(sim.vehicles):
            system = model.system_id
            send(index, _command(system, 176, 1, 15 if index == 2 else 4))  # AUTOTUNE, GUIDED
            send(index, _command(system, 400, 1))  # arm
            send(index, _command(system, 22, 0, 0, 0, 0, 0, 0, 20))  # take off to 20 m
        advance(1)
        send(1, _command(2, 300))  # MISSION_START
        advance(14)
        send(0, M.MAVLink_set_position_target_local_ned_message(
            0, 1, 1, 1, 0b110111111000, 40, 10, -25, 0, 0, 0, 0, 0, 0, 0, 0))
        advance(8)
        send(0, M.MAVLink_set_position_target_local_ned_message(
            0, 1, 1, 1, 0b110111000111, 0, 0, 0, 3, -2, -0.5, 0, 0, 0, 0, 0))
        send(0, _command(1, 178, 1, 7))  # DO_CHANGE_SPEED 7 m/s
        advance(4)
        send(0, _command(1, 176, 1, 17))  # BRAKE
        advance(4)
        send(0, _command(1, 115, 90, 30, 1, 1))  # CONDITION_YAW 90 degrees more, clockwise
        send(0, _command(1, 176, 1, 4))  # GUIDED
        advance(4)
        for index in (0, 3, 4):
            send(index, _command(index + 1, 20))  # RTL
        advance(20)
        send(2, _command(3, 176, 1, 5))  # LOITER
        advance(50)
        for client in clients:
            client.close()
    everything = hashlib.sha256()
    for data in received:
        everything.update(bytes(data))
    everything.update(b"".join(reply.pack(link) for reply in replies))
    moves = hashlib.sha256(repr(states).encode()).hexdigest()[:16]
    return [len(data) for data in received], everything.hexdigest()[:16], moves


def main() -> None:
    windy = {**FAST, "SIM_WIND_SPD": 6, "SIM_WIND_DIR": 45, "SIM_BATT_CAP_AH": 2.5,
             "WPNAV_SPEED": 700, "FENCE_ENABLE": 1}
    for name, params in (("defaults", FAST), ("windy", windy)):
        sizes, served, moves = fly(params)
        print(f"{name}: bytes {sizes} served {served} states {moves}")


if __name__ == "__main__":
    main()
