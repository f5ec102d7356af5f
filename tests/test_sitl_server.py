"""The simulator over loopback sockets, stepped by hand (realtime=False) unless said otherwise."""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import socket
import subprocess
import sys
import time

import pytest

os.environ.setdefault("MAVLINK20", "1")
from process_lines import follow, wait_for
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.faults import Faults
from sitl.server import Simulator, parse_udp_address

FAST = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2}


class Link:
    """A bare MAVLink 2 client over TCP: what arrived so far, and a way to send."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=5)
        self.sock.setblocking(False)
        self.mav = M.MAVLink(None, 255, 190)
        self.mav.robust_parsing = True

    def send(self, msg) -> None:
        self.sock.sendall(msg.pack(self.mav))

    def drain(self) -> list:
        out = []
        while True:
            try:
                data = self.sock.recv(65536)
            except BlockingIOError:
                return out
            if not data:
                return out
            out += [m for m in self.mav.parse_buffer(data) or [] if m.get_type() != "BAD_DATA"]

    def close(self) -> None:
        self.sock.close()


def connect(port: int) -> Link:
    return Link(port)


def drain(link: Link) -> list:
    return link.drain()


def streaming(sim: Simulator) -> Simulator:
    """``sim`` with every vehicle's port streaming all groups at 4 Hz, as if a client had
    asked (a port streams nothing but HEARTBEAT unasked)."""
    for vehicle in sim.vehicles:
        vehicle.handle(M.MAVLink_request_data_stream_message(0, 0, M.MAV_DATA_STREAM_ALL, 4, 1))
    return sim


def settle(sim: Simulator, conn, seconds: float) -> list:
    """Advance and read everything the vehicle sent meanwhile."""
    out = []
    for _ in range(round(seconds / 0.5)):
        sim.advance(0.5)
        out += drain(conn)
    return out


def test_each_vehicle_has_its_own_port_and_system_id():
    with Simulator(vehicles=2, tcp_base_port=0, realtime=False) as sim:
        ports = sim.tcp_ports
        assert len(set(ports)) == 2
        links = [connect(port) for port in ports]
        for expected, link in enumerate(links, start=1):
            beats = [m for m in settle(sim, link, 2) if m.get_type() == "HEARTBEAT"]
            assert {(b.get_srcSystem(), b.get_srcComponent()) for b in beats} == {
                (expected, 1), (expected, 191)}
            link.close()
        assert sim.vehicle(2).system_id == 2
        with pytest.raises(KeyError):
            sim.vehicle(3)


def test_commands_over_tcp_are_acknowledged():
    with Simulator(tcp_base_port=0, realtime=False, params=FAST) as sim:
        link = connect(sim.tcp_ports[0])
        settle(sim, link, 3)
        link.send(M.MAVLink_command_long_message(1, 1, 176, 0, 1, 4, 0, 0, 0, 0, 0))
        link.send(M.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
        acks = [m for m in settle(sim, link, 1) if m.get_type() == "COMMAND_ACK"]
        assert [(a.command, a.result, a.target_system) for a in acks] == [
            (176, 0, 255), (400, 0, 255)]
        assert sim.vehicle(1).armed and sim.vehicle(1).mode == "GUIDED"
        link.close()


def test_streams_are_the_ports_not_the_connections():
    # As an ArduPilot serial port: nothing but HEARTBEAT unasked; what one client asked for
    # is what a client that connects later gets.
    with Simulator(tcp_base_port=0, realtime=False) as sim:
        first = connect(sim.tcp_ports[0])
        kinds = {m.get_type() for m in settle(sim, first, 2)}
        assert kinds == {"HEARTBEAT"}
        first.send(M.MAVLink_command_long_message(
            1, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, M.MAVLINK_MSG_ID_SYS_STATUS, 500_000,
            0, 0, 0, 0, 0))
        assert [m.get_type() for m in settle(sim, first, 2)].count("SYS_STATUS") >= 4  # 2 Hz
        first.close()
        later = connect(sim.tcp_ports[0])
        assert [m.get_type() for m in settle(sim, later, 2)].count("SYS_STATUS") >= 4
        later.close()


def sequence_numbers(faults: Faults) -> list[int]:
    with Simulator(tcp_base_port=0, realtime=False, faults=faults) as sim:
        link = connect(streaming(sim).tcp_ports[0])
        got = [m.get_seq() for m in settle(sim, link, 5) if m.get_srcComponent() == 1]
        link.close()
        return got


def test_lossy_link_is_reproducible_from_the_seed():
    clean = sequence_numbers(Faults())
    lossy = sequence_numbers(Faults(seed=3, loss_out=0.3))
    assert lossy == sequence_numbers(Faults(seed=3, loss_out=0.3))
    assert lossy != sequence_numbers(Faults(seed=4, loss_out=0.3))
    assert 0.5 * len(clean) < len(lossy) < 0.9 * len(clean)
    assert set(lossy) < set(clean)


def test_outage_window_silences_the_link():
    with Simulator(tcp_base_port=0, realtime=False, faults=Faults(outages=((1.0, 3.2),))) as sim:
        link = connect(sim.tcp_ports[0])
        assert settle(sim, link, 1)
        assert settle(sim, link, 2) == []
        assert settle(sim, link, 1)
        link.close()


def test_duplicates_reordering_and_latency():
    faults = Faults(duplicate=1.0, latency=0.5)
    with Simulator(tcp_base_port=0, realtime=False, faults=faults) as sim:
        link = connect(sim.tcp_ports[0])
        sim.advance(0.45)
        assert drain(link) == []  # nothing has arrived yet: half a second of latency
        got = [m.get_seq() for m in settle(sim, link, 3) if m.get_srcComponent() == 1]
        assert got and all(got.count(seq) == 2 for seq in got)
        link.close()
    with Simulator(tcp_base_port=0, realtime=False, faults=Faults(seed=1, reorder=0.3)) as sim:
        link = connect(streaming(sim).tcp_ports[0])
        got = [m.get_seq() for m in settle(sim, link, 3) if m.get_srcComponent() == 1]
        assert got != sorted(got) and len(set(got)) == len(got)  # reordered, none lost
        link.close()


def test_udp_out_streams_and_accepts_commands():
    gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs.bind(("127.0.0.1", 0))
    gcs.settimeout(0)
    address = f"udp:127.0.0.1:{gcs.getsockname()[1]}"
    parser = M.MAVLink(None, 255, 190)
    with Simulator(tcp_base_port=None, udp_out=[address], realtime=False, params=FAST) as sim:
        assert sim.tcp_ports == []
        sim.advance(3)
        data, source = gcs.recvfrom(65536)
        assert any(m.get_type() == "HEARTBEAT" for m in parser.parse_buffer(data) or [])
        command = M.MAVLink_command_long_message(1, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 4, 0, 0, 0,
                                                 0, 0)
        gcs.sendto(command.pack(parser), source)
        sim.advance(0.5)
        assert sim.vehicle(1).mode == "GUIDED"
    gcs.close()


def test_realtime_loop_serves_and_stops():
    with Simulator(tcp_base_port=0, speedup=20) as sim:
        link = mavutil.mavlink_connection(f"tcp:127.0.0.1:{sim.tcp_ports[0]}")
        # The autopilot's (component 1): the companion computer on board says hello too,
        # and either may come first.
        beat = link.recv_match(type="HEARTBEAT", blocking=True, timeout=10,
                               condition="HEARTBEAT.get_srcComponent() == 1")
        assert beat is not None and beat.type == M.MAV_TYPE_QUADROTOR
        link.close()
    assert sim.tcp_ports == []


def test_a_slower_speedup_goes_on_from_where_vehicle_time_stands():
    with Simulator(tcp_base_port=0, speedup=50) as sim:
        while sim.time < 40.0:  # far ahead of what twice real time would have reached
            time.sleep(0.01)
        with pytest.raises(ValueError):
            sim.set_speedup(0)
        sim.set_speedup(2.0)
        slowed = sim.time
        end = time.monotonic() + 10.0  # a hang guard: counted from the start, time would
        while sim.time < slowed + 0.2:  # stand still for some 20 s of wall time
            assert time.monotonic() < end, "vehicle time stood still"
            time.sleep(0.01)


@pytest.mark.parametrize("text", ["udp:localhost", "udp::14550", "udp:host:99999", "host:port"])
def test_bad_udp_addresses(text):
    with pytest.raises(ValueError, match="UDP address"):
        parse_udp_address(text)


def test_mavproxy_uploads_arms_and_flies_the_mission_in_auto(tmp_path):
    """MAVProxy (an independent ground station) flies a mission and sees every item reached."""
    mavproxy = shutil.which("mavproxy.py", path=os.path.dirname(sys.executable))
    assert mavproxy, "MAVProxy is part of the test extra"
    home = (-35.363261, 149.165230, 584.0)
    points = [(-35.363081, 149.165230), (-35.363081, 149.165450)]  # ~20 m north, then east
    rows = [f"0\t1\t0\t16\t0\t0\t0\t0\t{home[0]}\t{home[1]}\t{home[2]}\t1",
            "1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t10\t1"]
    rows += [f"{i}\t0\t3\t16\t0\t0\t0\t0\t{lat}\t{lon}\t10\t1"
             for i, (lat, lon) in enumerate(points, start=2)]
    rows.append(f"4\t0\t3\t21\t0\t0\t0\t0\t{points[-1][0]}\t{points[-1][1]}\t0\t1")
    mission = tmp_path / "mission.txt"
    mission.write_text("QGC WPL 110\n" + "\n".join(rows) + "\n")
    with Simulator(tcp_base_port=0, speedup=10, params=FAST) as sim:
        process = subprocess.Popen(
            [sys.executable, mavproxy, f"--master=tcp:127.0.0.1:{sim.tcp_ports[0]}",
             "--target-system=1", "--target-component=1", "--no-state",
             "--default-modules=wp,mode,arm", f"--state-basedir={tmp_path}"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            cwd=tmp_path, env={**os.environ, "MAVLINK20": "1"})
        sink = follow(process.stdout)
        seen: list[str] = []
        deadline = time.monotonic() + 60

        def say(command: str) -> None:
            process.stdin.write(command + "\n")
            process.stdin.flush()

        try:
            while not sim.vehicle(1).position_ok:  # the vehicle's own start-up, not MAVProxy's
                assert time.monotonic() < deadline
                time.sleep(0.05)
            wait_for(sink, seen, r"Detected vehicle 1:1 ", deadline)  # the autopilot
            say("watch MISSION_ITEM_REACHED")
            say(f"wp load {mission}")
            wait_for(sink, seen, r"Sent all 5 waypoints|Loaded 5 waypoints? in", deadline)
            say("mode guided")
            wait_for(sink, seen, r"GUIDED", deadline)
            say("arm throttle")
            wait_for(sink, seen, r"ARMED|Arming motors", deadline)
            say("mode auto")
            for seq in range(1, 5):
                wait_for(sink, seen, rf"MISSION_ITEM_REACHED \{{seq : {seq}\}}", deadline)
            wait_for(sink, seen, r"DISARMED|Disarming motors", deadline)
        finally:
            with contextlib.suppress(OSError):
                process.stdin.close()
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        assert [item.command for item in sim.vehicle(1).mission_items] == [16, 22, 16, 16, 21]


def test_messages_are_routed_between_clients_as_arducopter_routes_its_ports():
    """A companion computer on the vehicle's port reaches the ground station and back."""
    params = {**FAST, "SIM_COMPANION": 0}
    with Simulator(tcp_base_port=0, realtime=False, params=params) as sim:
        gcs, onboard, watcher = (connect(sim.tcp_ports[0]) for _ in range(3))
        onboard.mav.srcSystem, onboard.mav.srcComponent = 1, 191
        watcher.mav.srcSystem = 254
        gcs.send(M.MAVLink_heartbeat_message(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID,
                                             0, 0, 4, 3))
        sim.advance(0.1)
        onboard.send(M.MAVLink_heartbeat_message(M.MAV_TYPE_ONBOARD_CONTROLLER,
                                                 M.MAV_AUTOPILOT_INVALID, 0, 0, 4, 3))
        onboard.send(M.MAVLink_named_value_int_message(100, b"ITEM", 3))
        sim.advance(0.1)
        heard = [(m.get_type(), m.get_srcComponent()) for m in gcs.drain()]
        assert ("HEARTBEAT", 191) in heard and ("NAMED_VALUE_INT", 191) in heard
        # A client that has said nothing yet gets the HEARTBEAT only (no route learned).
        assert [m.get_type() for m in watcher.drain() if m.get_srcComponent() == 191] == [
            "HEARTBEAT"]
        # Addressed to the companion: to the client it was heard on, not to the others.
        gcs.send(M.MAVLink_param_set_message(1, 191, b"RECOG_ITEMS", 1, 2))
        sim.advance(0.1)
        assert [(m.get_type(), m.get_srcSystem()) for m in onboard.drain()
                if m.get_type() == "PARAM_SET"] == [("PARAM_SET", 255)]
        assert "PARAM_SET" not in [m.get_type() for m in watcher.drain()]
        # The embedded companion is switched off: nobody else answers for component 191.
        assert [m for m in gcs.drain() if m.get_srcComponent() == 191] == []
        # Addressed to the autopilot: handled by the vehicle, not passed on.
        onboard.send(M.MAVLink_command_long_message(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0,
                                                    M.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                                                    0, 0, 0, 0, 0, 0))
        sim.advance(0.1)
        assert "COMMAND_LONG" not in [m.get_type() for m in gcs.drain()]
        for link in (gcs, onboard, watcher):
            link.close()


def test_the_embedded_companion_is_on_board_unless_switched_off():
    for on_board in (1, 0):
        with Simulator(tcp_base_port=0, realtime=False,
                       params={"SIM_COMPANION": on_board}) as sim:
            gcs = connect(sim.tcp_ports[0])
            gcs.send(M.MAVLink_param_request_read_message(1, 191, b"CAM_HFOV", -1))
            components = {m.get_srcComponent() for m in settle(sim, gcs, 2)}
            assert (191 in components) == bool(on_board)
            gcs.close()


KEY = bytes(range(32))


def _signing(link: Link, key: bytes) -> Link:
    link.mav.signing.secret_key = key
    link.mav.signing.sign_outgoing = True
    link.mav.signing.link_id = 1
    link.mav.signing.timestamp = int((time.time() - 1420070400) * 1e5)
    return link


def test_a_signing_simulator_refuses_unsigned_and_wrongly_signed_commands():
    with Simulator(tcp_base_port=0, realtime=False, params=FAST, signing_key=KEY) as sim:
        spoofer, wrong = connect(sim.tcp_ports[0]), _signing(connect(sim.tcp_ports[0]),
                                                            bytes(32))
        owner = _signing(connect(sim.tcp_ports[0]), KEY)
        settle(sim, owner, 3)
        set_mode = M.MAVLink_command_long_message(1, 1, 176, 0, 1, 4, 0, 0, 0, 0, 0)
        spoofer.send(set_mode)
        wrong.send(set_mode)
        settle(sim, owner, 1)
        assert sim.vehicle(1).mode != "GUIDED"
        assert sim.signing_rejected == (1, 1)  # (unsigned, wrongly signed)
        owner.send(set_mode)
        acks = [m for m in settle(sim, owner, 1) if m.get_type() == "COMMAND_ACK"]
        assert acks and sim.vehicle(1).mode == "GUIDED"
        assert all(m.get_signed() for m in acks)  # what it sends is signed
        for link in (spoofer, wrong, owner):
            link.close()


def test_heard_says_which_ground_station_sent_each_vehicle_what():
    heard = io.StringIO()
    with Simulator(vehicles=2, tcp_base_port=0, realtime=False, heard=heard) as sim:
        first, second = connect(sim.tcp_ports[0]), connect(sim.tcp_ports[1])
        first.mav.srcSystem, second.mav.srcSystem = 251, 252
        first.send(M.MAVLink_heartbeat_message(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID,
                                               0, 0, 4, 3))
        sim.advance(0.5)
        second.send(M.MAVLink_command_long_message(2, 1, 176, 0, 1, 4, 0, 0, 0, 0, 0))
        sim.advance(0.5)
        for link in (first, second):
            link.close()
    records = [json.loads(line) for line in heard.getvalue().splitlines()]
    assert [(r["v"], r["src"], r["comp"], r["type"], r["to"]) for r in records] == [
        (1, 251, 190, "HEARTBEAT", 0), (2, 252, 190, "COMMAND_LONG", 2)]
    assert records[0]["t"] < records[1]["t"] and records[0]["wall"] <= records[1]["wall"]
