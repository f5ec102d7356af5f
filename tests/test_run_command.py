"""``tml run`` end to end through tml.commands.cli.main: exit codes, log, refusals, interruption."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.process_lines import simulator
from tml.commands.cli import main
from tml.errors import ExitCode
from tml.run.journal import read

ROOT_MISSIONS = Path(__file__).resolve().parent.parent / "missions"
FAST = ["--sim-param", "SIM_GPS_LOCKTIME=0.5", "--sim-param", "SIM_EKF_GPS_TIME=1",
        "--speedup", "40"]
SHORT = ('<mission name="Hop">\n'
         '  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="4"/>'
         '</action></task>\n'
         '  <task name="Over"><action name="GO_TO_POINT"><argument name="coordinates" '
         'value="(8, 0, 4)"/></action></task>\n'
         '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')
ABORTS = SHORT.replace("</mission>", '<event_handling><event name="High">'
                       '<condition parameter="ALTITUDE" comparison="greater than" value="3"/>'
                       '<action name="LAND"/><termination mode="ABORT_MISSION"/></event>'
                       '</event_handling></mission>')
GRAB = SHORT.replace('<task name="Over">', '<task name="Grab"><action name="PICK_UP_ITEM"/>'
                     '</task><task name="Over">')


def write(tmp_path: Path, text: str, name: str = "m.xml") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def test_completed_mission_exits_0_and_writes_the_log(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "flight.jsonl"
    code = main(["run", write(tmp_path, SHORT), "--sim", "-q", "--log", str(log), *FAST])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "vehicle 1: mission completed: all tasks done" in out
    lines = read(str(log))
    kinds = {line["kind"] for line in lines}
    assert {"run", "mission", "task", "action", "request", "result", "telemetry"} <= kinds
    assert lines[-1]["exit_code"] == 0
    assert any(line["kind"] == "action" and line["message"] == "LAND done" for line in lines)
    flying = [line for line in lines if line["kind"] == "telemetry" and not line["landed"]]
    assert flying and max(line["position"][0] for line in flying) > 7.5


def test_abort_mission_exits_3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", write(tmp_path, ABORTS), "--sim", "-q", *FAST]) == 3
    assert "mission aborted: event 'High' aborted the mission" in capsys.readouterr().out


def test_action_the_vehicle_cannot_do_exits_4(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "flight.jsonl"
    code = main(["run", write(tmp_path, GRAB), "--sim", "-q", "--log", str(log), *FAST,
                 "--sim-param", "GRIP_ENABLE=0"])
    out = " ".join(capsys.readouterr().out.split())
    assert code == 4
    assert ("mission failed: PICK_UP_ITEM (line 3) needs a gripper (ArduPilot's GRIP_ENABLE "
            "set), and vehicle 1 has none (refused before take-off)") in out
    assert not [line for line in read(str(log)) if line["kind"] == "request"]  # nothing sent


def test_invalid_mission_exits_1_before_flying(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    bad = write(tmp_path, SHORT.replace("LAND", "LANDD"))
    assert main(["run", bad, "--sim", "-q"]) == 1
    err = capsys.readouterr().err
    assert "unknown action" in err and "invalid mission, not flown" in err


def test_the_warnings_of_validation_are_printed_before_the_flight(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    guarded = write(tmp_path, SHORT.replace(
        '<task name="Over">', '<task name="Over">\n    <condition parameter="observed color" '
        'comparison="equal" value="green"/>\n    '))
    assert main(["run", guarded, "--sim", "-q", *FAST]) == 0
    out, err = capsys.readouterr()
    assert f"{guarded}:4:5: warning W301: nothing provides parameter 'observed color'" in err
    assert "hint: declare it if something on the vehicle reports it" in err
    assert "vehicle 1: mission completed" in out


def test_an_event_nothing_can_fire_is_refused_before_flying(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # BATTERY_LEVEL is no built-in: the low-battery landing would never happen.
    low = write(tmp_path, SHORT.replace("</mission>", '<event_handling><event name="Low">'
                '<condition parameter="BATTERY_LEVEL" comparison="less than" value="30"/>'
                '<action name="LAND"/><termination mode="ABORT_MISSION"/></event>'
                '</event_handling></mission>'))
    assert main(["run", low, "--sim", "-q", "--sim-battery", "40"]) == 1
    err = capsys.readouterr().err
    assert f"{low}:5:35: error E227: nothing provides parameter 'BATTERY_LEVEL'" in err
    assert "did you mean 'BATTERY_CHARGE_PERCENTAGE'?" in err
    assert "invalid mission, not flown" in err


def test_infeasible_mission_is_refused_unless_forced(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    far = write(tmp_path, SHORT.replace("(8, 0, 4)", "(40000, 0, 4)"))
    assert main(["run", far, "--sim", "-q"]) == 1
    assert "infeasible mission, not flown" in capsys.readouterr().err


def test_no_vehicle_at_the_address_exits_4(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", write(tmp_path, SHORT), "--connect", "udpin:127.0.0.1:0",
                 "--timeout", "0.5", "-q"])
    assert code == 4
    assert "no heartbeat" in capsys.readouterr().err


def test_sigint_commands_the_safe_state_and_exits_3(tmp_path: Path) -> None:
    slow = SHORT.replace("(8, 0, 4)", "(300, 0, 4)")
    log = tmp_path / "flight.jsonl"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(
        [sys.executable, "-m", "tml", "run", write(tmp_path, slow), "--sim", "--log", str(log),
         "--safe-state", "land", *FAST[:4], "--speedup", "5"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    assert process.stdout is not None
    for line in process.stdout:  # the line display: interrupt once the leg has started
        if "Over: running" in line:
            process.send_signal(signal.SIGINT)
            break
    out, _ = process.communicate(timeout=60)
    assert process.returncode == 3, out
    assert "aborting: interrupted (SIGINT)" in out and "Land" in out
    safety = [line for line in read(str(log)) if line["kind"] == "safety"]
    assert safety and safety[0]["request"] == "Land"


def test_out_lets_a_ground_station_watch_the_flight(tmp_path: Path) -> None:
    import socket

    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    watcher = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    watcher.bind(("127.0.0.1", 0))
    watcher.settimeout(0.2)
    port = watcher.getsockname()[1]
    try:
        assert main(["run", write(tmp_path, SHORT), "--sim", "-q", *FAST,
                     "--out", f"udpout:127.0.0.1:{port}"]) == 0
        parser, seen = mavlink.MAVLink(None), set()
        while True:
            try:
                data = watcher.recv(65536)
            except TimeoutError:
                break
            for msg in parser.parse_buffer(data) or []:
                seen.add((msg.get_srcSystem(), msg.get_type()))
    finally:
        watcher.close()
    assert {(1, "HEARTBEAT"), (1, "GLOBAL_POSITION_INT")} <= seen


def test_profile_from_the_vehicles_parameters(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    far = SHORT.replace("(8, 0, 4)", "(80, 0, 4)")
    # The quadcopter profile allows 80 m; the vehicle's own fence radius of 50 m does not.
    assert main(["run", write(tmp_path, far), "--sim", "-q", *FAST, "--profile", "vehicle",
                 "--sim-param", "FENCE_RADIUS=50"]) == 1
    err = capsys.readouterr().err
    assert "quadcopter profile from vehicle 1's parameters" in err
    assert "FENCE_RADIUS=50" in err and "infeasible mission, not flown" in err
    assert main(["run", write(tmp_path, far), "--sim", "-q", *FAST,
                 "--profile", "vehicle"]) == 0


def test_the_vehicle_profile_is_that_of_the_vehicle_s_kind(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A rover's own WP_SPEED and fence: 80 m is beyond its 50 m fence.
    drive = ('<mission name="Drive"><task name="Out"><action name="GO_TO_POINT">'
             '<argument name="coordinates" value="(80, 0, 0)"/></action></task></mission>')
    assert main(["run", write(tmp_path, drive), "--sim", "--sim-frame", "rover", "-q", *FAST,
                 "--profile", "vehicle", "--sim-param", "FENCE_RADIUS=50"]) == 1
    err = capsys.readouterr().err
    assert "rover profile from vehicle 1's parameters: " in err
    assert "WP_SPEED=5" in err and "WPNAV_SPEED" not in err


def test_a_bad_payload_option_says_what_it_expects(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "m.xml", "--sim", "--payload", "camera"]) == 2
    assert "expected ID=NAME[,NAME...]" in capsys.readouterr().err


def test_clock_vehicle_times_the_mission_in_the_vehicles_seconds(tmp_path: Path) -> None:
    from sitl.server import Simulator

    log = tmp_path / "flight.jsonl"
    params = {"SIM_GPS_LOCKTIME": 0.5, "SIM_EKF_GPS_TIME": 1.0}
    with Simulator(vehicles=1, speedup=20, tcp_base_port=0, params=params) as sim:
        code = main(["run", write(tmp_path, SHORT), "--connect",
                     f"tcp:127.0.0.1:{sim.tcp_ports[0]}", "--clock", "vehicle", "-q",
                     "--log", str(log)])
        vehicle_time = sim.time
    assert code == 0
    lines = read(str(log))
    # The log is timed by the vehicle (seconds since it booted), not the ground station.
    assert 0 < lines[0]["t"] <= lines[-1]["t"] <= vehicle_time + 0.5
    assert vehicle_time - lines[-1]["t"] < 3.0


def test_a_vehicle_that_never_gets_ready_exits_4_saying_what_it_lacked(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "flight.jsonl"
    code = main(["run", write(tmp_path, SHORT), "--sim", "-q", "--log", str(log),
                 "--speedup", "40", "--sim-param", "SIM_GPS_LOCKTIME=0.5",
                 "--sim-param", "SIM_EKF_GPS_TIME=100000", "--ready-timeout", "5"])
    out = " ".join(capsys.readouterr().out.split())
    assert code == 4, out
    assert "vehicle 1: mission failed: not ready after 5 s: waiting for" in out
    lines = read(str(log))
    assert not [line for line in lines if line["kind"] in ("request", "task")]
    (reason,) = [o["reason"] for o in lines[-1]["outcomes"]]
    awaited = [line["awaiting"] for line in lines if line["kind"] == "ready"][-1]
    assert "position estimate" in awaited and reason.endswith(", ".join(awaited))


@pytest.mark.parametrize("bad", ["-1", "soon", "inf"])
def test_a_bad_ready_timeout_says_what_it_expects(bad: str,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "m.xml", "--sim", "--ready-timeout", bad]) == 2
    assert "--ready-timeout" in capsys.readouterr().err


def test_a_mission_its_vehicle_cannot_do_is_refused_before_the_first_task(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Feasible for the default quadcopter profile, but the connected vehicle is a rover.
    log = tmp_path / "flight.jsonl"
    code = main(["run", write(tmp_path, SHORT), "--sim", "--sim-frame", "rover", "-q",
                 "--log", str(log), *FAST])
    err = capsys.readouterr().err
    assert code == 1
    assert "m.xml:2:" in err and "vehicle: TAKE_OFF: a rover cannot take off" in err
    assert "(vehicle 1)" in err and "LAND: a rover cannot land" in err
    assert "actions its vehicles cannot do, not flown" in err
    assert not log.exists() or not [line for line in read(str(log))
                                    if line["kind"] == "request"]


def test_an_unknown_simulator_frame_is_a_usage_error(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", write(tmp_path, SHORT), "--sim", "--sim-frame", "blimp"]) == 2
    assert "unknown frame 'blimp'" in capsys.readouterr().err


def test_off_a_terminal_lines_are_not_wrapped(tmp_path: Path) -> None:
    """A pipe or a CI log gets whole lines: the quoted source line and its caret are not
    cut at 80 columns, so the caret stays under its column."""
    long = ('<mission name="Wide">\n  <task name="A task whose name is long enough to push '
            'the action past column eighty"><action name="GO_TO_PIONT"/></task>\n</mission>\n')
    path = write(tmp_path, long)
    done = subprocess.run([sys.executable, "-m", "tml", "run", path, "--sim"],
                          capture_output=True, text=True, timeout=60,
                          env={**os.environ, "COLUMNS": "", "TERM": "dumb"})
    assert done.returncode == 1
    lines = done.stderr.splitlines()
    quoted = next(i for i, line in enumerate(lines) if 'name="GO_TO_PIONT"' in line)
    caret = lines[quoted + 1]
    source_column = lines[quoted].index("<action")
    assert caret.rstrip().endswith("^") and caret.index("^") == source_column, done.stderr


@pytest.mark.parametrize("option, value, message", [
    ("--speedup", "nan", "argument --speedup: expected a finite number greater than 0, got nan"),
    ("--speedup", "inf", "argument --speedup: expected a finite number greater than 0, got inf"),
    ("--link-lost-limit", "nan", "argument --link-lost-limit: expected a finite number"),
    ("--timeout", "inf", "argument --timeout: expected a finite number"),
    ("--vehicles", "1000", "argument --vehicles: at most 250 simulated vehicles"),
    ("--sim-param", "FOO=1", "argument --sim-param: unknown simulator parameter 'FOO'"),
    ("--sim-battery", "101",
     "argument --sim-battery: expected a percentage from 0 to 100, got 101"),
])
def test_numbers_that_cannot_be_flown_are_usage_errors(
        option: str, value: str, message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(ROOT_MISSIONS / "paper_example1.xml"), "--sim", option,
                 value]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


@pytest.mark.parametrize("argv, message", [
    (["nowhere.xml", "--sim"], "tml run: nowhere.xml: No such file or directory"),
    (["missions/paper_example1.xml", "--sim", "--profile", "helicopter"],
     "tml run: profile 'helicopter': no such profile or file; the profiles are quadcopter, "
     "fixed-wing, rover, vehicle"),
    (["missions", "--sim"], "tml run: missions: is a directory, not a mission file"),
    (["missions/paper_example1.xml", "--connect", "tcp:127.0.0.1:99999"],
     "tml run: --connect tcp:127.0.0.1:99999: expected tcp:HOST:PORT with a port from 0 to "
     "65535"),
    (["missions/paper_example1.xml", "--sim", "--log", "/nonexistent/dir/f.jsonl"],
     "tml run: --log /nonexistent/dir/f.jsonl: cannot write: No such file or directory"),
    (["missions/paper_example1.xml", "--sim", "--out", "udpout:127.0.0.1:99999"],
     "tml run: --out udpout:127.0.0.1:99999: expected udpout:HOST:PORT"),
    (["missions/paper_example1.xml", "--sim", "--out", "nonsense"],
     "tml run: --out nonsense: not an address a copy can be sent to"),
    # A network address without its scheme (pymavlink would listen on it for UDP and wait
    # out the timeout), a scheme that is none: the forms, at once.
    (["missions/paper_example1.xml", "--connect", "127.0.0.1:18001"],
     "tml run: --connect 127.0.0.1:18001: not an address: a network address starts with its "
     "scheme (udpin:, udpout:, udp:, tcpin:, tcp:), e.g. tcp:127.0.0.1:18001 (connect to a "
     "vehicle that listens) or udpin:127.0.0.1:18001 (listen for one that sends); a serial "
     "port is DEVICE or DEVICE,BAUD (e.g. /dev/ttyUSB0,57600)"),
    (["missions/paper_example1.xml", "--connect", "foo:bar"],
     "tml run: --connect foo:bar: not an address: a network address starts with its scheme"),
])
def test_usage_errors_exit_2_naming_the_option_and_value(
        argv: list[str], message: str, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT_MISSIONS.parent)
    assert main(["run", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err  # one line, before anything started


def test_pymavlink_s_own_prints_do_not_reach_the_user(tmp_path: Path) -> None:
    import socket

    with socket.socket() as probe:  # a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    done = subprocess.run([sys.executable, "-m", "tml", "run", str(ROOT_MISSIONS /
                           "paper_example1.xml"), "--connect", f"tcp:127.0.0.1:{port}",
                           "--timeout", "2"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 4
    said = done.stdout + done.stderr
    assert "sleeping" not in said and "Errno 111" not in said
    assert said.strip() == (f"tml run: cannot open MAVLink connection 'tcp:127.0.0.1:{port}': "
                            "Connection refused")


def test_tml_says_once_what_it_waits_for_and_how_long(tmp_path: Path) -> None:
    import socket

    with socket.create_server(("127.0.0.1", 0)) as silent:  # accepts, never speaks
        port = silent.getsockname()[1]
        done = subprocess.run([sys.executable, "-m", "tml", "run", str(ROOT_MISSIONS /
                               "paper_example1.xml"), "--connect", f"tcp:127.0.0.1:{port}",
                               "--timeout", "1"], capture_output=True, text=True, timeout=60)
    said = done.stdout + done.stderr
    waiting = f"tml run: waiting up to 1 s for a vehicle at tcp:127.0.0.1:{port}"
    assert said.count(waiting) == 1, said
    assert done.returncode == 4 and "sleeping" not in said


def _free_port() -> int:
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_a_server_that_hangs_up_exits_4_in_one_line(tmp_path: Path) -> None:
    import socket
    import threading

    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(0.05)
    port = server.getsockname()[1]
    running = threading.Event()
    running.set()

    def hang_up() -> None:  # accepts, and closes at once
        while running.is_set():
            with contextlib.suppress(TimeoutError):
                server.accept()[0].close()

    thread = threading.Thread(target=hang_up, daemon=True)
    thread.start()
    try:
        done = subprocess.run([sys.executable, "-m", "tml", "run", write(tmp_path, SHORT),
                               "--connect", f"tcp:127.0.0.1:{port}", "--timeout", "2", "-q"],
                              capture_output=True, text=True, timeout=60)
    finally:
        running.clear()
        thread.join(2.0)
        server.close()
    said = done.stdout + done.stderr
    assert done.returncode == 4, said
    assert "Traceback" not in said and "Error:" not in said
    assert said.strip() == (f"tml run: no heartbeat from a vehicle on tcp:127.0.0.1:{port} "
                            "within 2 s")


class Watched:
    """``tml run`` in a child process, its output read line by line as the test waits."""

    def __init__(self, args: list[str]) -> None:
        from tests.process_lines import follow

        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self.process = subprocess.Popen([sys.executable, "-m", "tml", "run", *args],
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                        text=True, env=env)
        assert self.process.stdout is not None
        self.lines = follow(self.process.stdout)
        self.seen: list[str] = []

    def wait_for(self, pattern: str, within: float) -> None:
        """Read until a line matches ``pattern``; fail the test after ``within`` s."""
        import time

        from tests.process_lines import wait_for

        wait_for(self.lines, self.seen, pattern, time.monotonic() + within, "tml run")

    @property
    def said(self) -> str:
        return "".join(self.seen)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_while_waiting_for_the_first_heartbeat_exits_3_cleanly(
        tmp_path: Path, sig: signal.Signals) -> None:
    import socket

    with socket.create_server(("127.0.0.1", 0)) as silent:  # accepts, never speaks
        port = silent.getsockname()[1]
        run = Watched([write(tmp_path, SHORT), "--connect", f"tcp:127.0.0.1:{port}",
                       "--timeout", "60"])
        run.wait_for("waiting up to 60 s", 30)
        run.process.send_signal(sig)
        run.process.wait(timeout=30)
        run.wait_for("interrupted|Traceback", 5)
    assert run.process.returncode == 3, run.said
    assert "Traceback" not in run.said and "KeyboardInterrupt" not in run.said
    assert run.said.splitlines()[-1] == (f"tml run: interrupted ({sig.name}) before the "
                                         "mission started")


def test_a_simulator_killed_in_flight_exits_4_in_one_line(tmp_path: Path) -> None:
    port = _free_port()
    sim = subprocess.Popen([sys.executable, "-m", "sitl", "--tcp-base-port", str(port),
                            "--param", "SIM_GPS_LOCKTIME=0.5", "--param", "SIM_EKF_GPS_TIME=1",
                            "--speedup", "5"], stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL)
    try:
        slow = SHORT.replace("(8, 0, 4)", "(300, 0, 4)")
        run = Watched([write(tmp_path, slow), "--connect", f"tcp:127.0.0.1:{port}",
                       "--timeout", "30", "--link-lost-limit", "1",
                       "--safe-state-timeout", "3"])
        run.wait_for("Over: running", 60)
        sim.kill()
        run.process.wait(timeout=90)
        run.wait_for("mission (failed|aborted|completed)", 5)
    finally:
        sim.kill()
        sim.wait()
    assert run.process.returncode == 4, run.said
    assert "Traceback" not in run.said and "Error:" not in run.said
    assert "vehicle 1: mission failed: link: vehicle 1: link lost for more than 1 s" in run.said


def test_a_vehicle_without_a_gcs_failsafe_is_refused_when_one_is_required(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", write(tmp_path, SHORT), "--sim", *FAST, "-q",
                 "--require-gcs-failsafe"])
    err = capsys.readouterr().err
    assert code == 4, err
    assert ("vehicle 1: FS_GCS_ENABLE is 0: the vehicle does nothing by itself when it "
            "loses this ground station") in err
    assert "not flown (--require-gcs-failsafe)" in err


def test_a_vehicle_with_a_gcs_failsafe_flies_when_one_is_required(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", write(tmp_path, SHORT), "--sim", *FAST, "-q",
                 "--require-gcs-failsafe", "--sim-param", "FS_GCS_ENABLE=1",
                 # the ground station's 1 Hz HEARTBEAT is 40 vehicle seconds apart at 40x
                 "--sim-param", "FS_GCS_TIMEOUT=100"])
    out = capsys.readouterr()
    assert code == 0, out
    assert "FS_GCS_ENABLE" not in out.err and "MAV_GCS_SYSID" not in out.err


@pytest.mark.parametrize("name", ["MAV_GCS_SYSID", "SYSID_MYGCS"])
def test_a_vehicle_whose_failsafe_hears_another_ground_station_is_refused_when_one_is_required(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str) -> None:
    # ArduPilot counts only its MAV_GCS_SYSID's HEARTBEATs (SYSID_MYGCS before 4.7): with
    # 250 there, tml (255) falling silent triggers nothing. The simulator keeps both names.
    code = main(["run", write(tmp_path, SHORT), "--sim", *FAST, "-q",
                 "--require-gcs-failsafe", "--sim-param", "FS_GCS_ENABLE=1",
                 "--sim-param", f"{name}=250"])
    err = capsys.readouterr().err
    assert code == 4, err
    assert ("vehicle 1: MAV_GCS_SYSID is 250 and tml sends as system 255: the vehicle's GCS "
            "failsafe hears only system 250's HEARTBEATs, so it does nothing by itself when "
            "this ground station falls silent (set MAV_GCS_SYSID to 255)") in err
    assert "not flown (--require-gcs-failsafe)" in err and "Traceback" not in err


def test_a_signed_run_on_the_simulator_flies_and_logs_what_signing_dropped(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    key = tmp_path / "key"
    key.write_text("a passphrase only the ground station and the vehicle know\n")
    log = tmp_path / "flight.jsonl"
    code = main(["run", write(tmp_path, SHORT), "--sim", *FAST, "-q",
                 "--signing-key-file", str(key), "--log", str(log)])
    assert code == 0, capsys.readouterr()
    (signing,) = [line for line in read(str(log)) if line["kind"] == "signing"]
    assert (signing["unsigned"], signing["bad_signature"]) == (0, 0)


def test_a_signing_key_file_that_cannot_be_read_is_a_usage_error(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", write(tmp_path, SHORT), "--sim", "--signing-key-file",
                 str(tmp_path / "missing")])
    assert code == 2
    assert capsys.readouterr().err.strip() == (
        f"tml run: --signing-key-file {tmp_path / 'missing'}: No such file or directory")


def _start_against_a_silent_vehicle(tmp_path: Path, silent: socket.socket
                                    ) -> subprocess.Popen[str]:
    """``tml run`` against an address that takes the connection and says nothing: tml waits
    there for a HEARTBEAT for the whole --timeout (a refused connection would end it with
    exit 4 first, sooner on a fast machine than a slow one)."""
    port = silent.getsockname()[1]
    # -X faulthandler: should tml ever not end, SIGABRT makes it say where each thread was.
    # SIGINT as a terminal leaves it to tml: a test run started in the background by a
    # script (``cmd &``) would hand its children SIGINT ignored, and a Ctrl-C that comes
    # before tml takes the signal over would be ignored with it.
    return subprocess.Popen([sys.executable, "-X", "faulthandler", "-m", "tml", "run",
                             write(tmp_path, SHORT), "--connect", f"tcp:127.0.0.1:{port}",
                             "--timeout", "300"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_interruptible)


def _interruptible() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _ended(process: subprocess.Popen[str]) -> tuple[str, str]:
    """stdout and stderr of ``process`` once it has ended; a test failure, with where each
    of its threads was, if it has not ended within a minute."""
    try:
        return process.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        process.send_signal(signal.SIGABRT)
        _, err = process.communicate(timeout=60)
        pytest.fail(f"tml did not end within 60 s of SIGINT; its threads:\n{err}")


def test_ctrl_c_while_tml_waits_for_its_vehicle_ends_it_in_one_line(tmp_path: Path) -> None:
    with socket.create_server(("127.0.0.1", 0)) as silent:
        process = _start_against_a_silent_vehicle(tmp_path, silent)
        try:
            assert process.stderr is not None
            first = process.stderr.readline()  # the state the signal must find: waiting
            assert first.startswith("tml run: waiting up to 300 s for a vehicle at "), first
            process.send_signal(signal.SIGINT)
            out, err = _ended(process)
        finally:
            process.kill()
    assert process.returncode == ExitCode.ABORTED, (out, err)
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err


INTERPRETER_START = ("Fatal Python error: init_import_site",  # importing site
                     "Could not import runpy module")  # python -m, before the module runs
"""What CPython says when a SIGINT stops its own start-up, before any of tml has run."""


@pytest.mark.parametrize("delay", [0.05, 0.2, 0.4, 0.8])
def test_ctrl_c_while_tml_starts_ends_it_without_a_traceback(tmp_path: Path,
                                                             delay: float) -> None:
    """SIGINT at any moment of the start-up (loading modules, reading the mission, before
    `tml run` takes the stop signals over) ends it with exit 3 and no traceback -- or, when
    it comes before Python has run any of tml (a busy machine may still be starting the
    interpreter after 0.8 s), as Python itself ends then: by the signal, or with one of its
    own start-up errors (:data:`INTERPRETER_START`) and exit 1."""
    with socket.create_server(("127.0.0.1", 0)) as silent:
        process = _start_against_a_silent_vehicle(tmp_path, silent)
        try:
            time.sleep(delay)  # when the signal comes, not a timing assertion
            process.send_signal(signal.SIGINT)
            out, err = _ended(process)
        finally:
            process.kill()
    if process.returncode == 1 and err.startswith(INTERPRETER_START):
        return  # the interpreter's start-up, before tml's own code (see the docstring)
    assert process.returncode in (ExitCode.ABORTED, -signal.SIGINT), (out, err)
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err


def test_a_serial_device_that_does_not_exist_exits_4_in_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    device = tmp_path / "ttyUSB9"
    assert main(["run", write(tmp_path, SHORT), "--connect", f"{device},57600"]) == 4
    err = capsys.readouterr().err
    assert err.strip() == f"tml run: cannot open serial port {device}: No such file or directory"


def test_pyserial_is_a_dependency() -> None:
    import tomllib

    project = tomllib.loads((ROOT_MISSIONS.parent / "pyproject.toml").read_text())["project"]
    assert any(d.replace(" ", "").startswith("pyserial>=") for d in project["dependencies"])


@contextlib.contextmanager
def socat(*addresses: str, ready: str | None = None) -> Iterator[None]:
    """socat joining ``addresses``, stopped by its pid on leaving; with ``ready``, once it
    has printed a line that matches."""
    import shutil

    from tests.process_lines import follow, wait_for

    if shutil.which("socat") is None:
        pytest.skip("socat is not installed (apt-get install socat)")
    bridge = subprocess.Popen(["socat", "-d", "-d", *addresses], stderr=subprocess.PIPE,
                              text=True)
    try:
        assert bridge.stderr is not None
        lines = follow(bridge.stderr)
        if ready is not None:
            wait_for(lines, [], ready, time.monotonic() + 60, "socat")
        yield
    finally:
        bridge.terminate()
        bridge.wait(timeout=60)


@pytest.fixture
def pseudo_terminal(tmp_path: Path) -> Iterator[tuple[Path, int]]:
    """A serial device (a pseudo-terminal made by socat) carrying a simulated vehicle's
    TCP port, as a telemetry radio carries an autopilot's serial port: (device, port)."""
    device = tmp_path / "ttyTML"
    with simulator("--fast-boot", "--speedup", "10") as port, \
            socat(f"pty,link={device},raw,echo=0", f"tcp:127.0.0.1:{port}",
                  ready="starting data transfer loop"):
        yield device, port


@pytest.mark.parametrize("baud", [",57600", ""])  # DEVICE,BAUD and DEVICE (57600)
def test_a_vehicle_on_a_serial_port_flies(pseudo_terminal: tuple[Path, int], tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str],
                                          baud: str) -> None:
    device, _ = pseudo_terminal
    code = main(["run", write(tmp_path, SHORT), "--connect", f"{device}{baud}", "-q",
                 "--timeout", "60"])
    out = capsys.readouterr()
    assert code == 0, out
    assert "vehicle 1: mission completed: all tasks done" in out.out


def test_a_vehicle_that_waits_to_be_contacted_over_udp_flies_through_udpout(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A Wi-Fi vehicle or companion computer listening on UDP: it answers whoever sends
    # first (socat relays that UDP port to the simulated vehicle's TCP port).
    port = _free_udp_port()
    with simulator("--fast-boot", "--speedup", "10") as vehicle, \
            socat(f"udp-listen:{port},bind=127.0.0.1,reuseaddr", f"tcp:127.0.0.1:{vehicle}",
                  ready="listening on"):
        code = main(["run", write(tmp_path, SHORT), "--connect", f"udpout:127.0.0.1:{port}",
                     "-q", "--timeout", "60"])
    out = capsys.readouterr()
    assert code == 0, out
    assert "vehicle 1: mission completed: all tasks done" in out.out


def test_a_vehicle_that_dials_in_flies_through_tcpin(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]
                                                     ) -> None:
    # A companion computer or router that connects to the ground station (socat dials
    # tml's tcpin: port, retrying until it listens, and carries the simulated vehicle).
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with simulator("--fast-boot", "--speedup", "10") as vehicle, \
            socat(f"tcp:127.0.0.1:{port},retry=600,interval=0.1", f"tcp:127.0.0.1:{vehicle}"):
        code = main(["run", write(tmp_path, SHORT), "--connect", f"tcpin:127.0.0.1:{port}",
                     "-q", "--timeout", "60"])
    out = capsys.readouterr()
    assert code == 0, out
    assert "vehicle 1: mission completed: all tasks done" in out.out


@pytest.mark.parametrize("scheme", ["udpin", "udp"])
def test_a_vehicle_that_sends_to_a_udp_port_flies(scheme: str, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # As ArduPilot's --serial0 udpclient:HOST:PORT, or mavlink-router's UDP endpoint: the
    # vehicle sends first, tml answers whoever sent.
    port = _free_udp_port()
    with simulator("--fast-boot", "--speedup", "10", "--out", f"udp:127.0.0.1:{port}"):
        code = main(["run", write(tmp_path, SHORT), "--connect", f"{scheme}:127.0.0.1:{port}",
                     "-q", "--timeout", "60"])
    out = capsys.readouterr()
    assert code == 0, out
    assert "vehicle 1: mission completed: all tasks done" in out.out


@pytest.fixture
def two_systems_on_one_port() -> Iterator[str]:
    """A router's view: two simulated vehicles sending to one UDP port, system 1 a rover
    and system 2 a copter; the address that hears both."""
    port = _free_udp_port()
    with simulator("--vehicles", "2", "--frame", "rover,copter", "--fast-boot",
                   "--speedup", "10", "--out", f"udp:127.0.0.1:{port}"):
        yield f"udpin:127.0.0.1:{port}"


def test_a_link_that_hears_several_vehicles_flies_the_one_its_sysid_names(
        two_systems_on_one_port: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "flight.jsonl"
    code = main(["run", write(tmp_path, SHORT), "--connect", two_systems_on_one_port,
                 "--sysid", "2", "-q", "--timeout", "60", "--log", str(log)])
    out = capsys.readouterr()
    assert code == 0, out  # the copter: the rover would have been refused a take-off
    assert "vehicle 1: mission completed: all tasks done" in out.out
    assert read(str(log))[0]["system_ids"] == [2]


def test_a_link_that_hears_several_vehicles_without_a_sysid_says_which_it_heard(
        two_systems_on_one_port: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", write(tmp_path, SHORT), "--connect", two_systems_on_one_port,
                 "-q", "--timeout", "60"])
    err = capsys.readouterr().err
    assert code == ExitCode.USAGE, err
    assert err.strip().splitlines() == [
        f"tml run: {two_systems_on_one_port}: vehicles with system ids 1, 2 heard: say which "
        "to fly with --sysid N (repeated for several: --sysid 1 --sysid 2)"]


def test_a_sysid_not_heard_names_those_that_were(two_systems_on_one_port: str,
                                                 tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", write(tmp_path, SHORT), "--connect", two_systems_on_one_port,
                 "--sysid", "7", "-q", "--timeout", "5"])
    err = capsys.readouterr().err
    assert code == ExitCode.FAILURE, err
    assert err.strip().splitlines() == [
        f"tml run: vehicle 7: no heartbeat from vehicle 7 on {two_systems_on_one_port} "
        "within 5 s (heard: system id 1, 2)"]


def test_a_vehicle_that_signs_its_messages_met_without_a_key_is_said_at_once(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    key = tmp_path / "key"
    key.write_text("a passphrase the vehicle was given\n")
    with simulator("--fast-boot", "--signing-key-file", str(key)) as port:
        code = main(["run", write(tmp_path, SHORT), "--connect", f"tcp:127.0.0.1:{port}",
                     "--timeout", "60"])
    err = capsys.readouterr().err
    assert code == 4, err
    assert err.strip().splitlines()[-1] == (
        f"tml run: vehicle 1: tcp:127.0.0.1:{port}: the vehicle signs its messages (MAVLink 2 "
        "signing) and ignores unsigned commands: give its key (--signing-key-file, or "
        "TML_SIGNING_KEY)")


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_a_flight_log_on_a_full_disk_stops_nothing(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # /dev/full takes the file open and refuses every write, as a full disk does.
    code = main(["run", write(tmp_path, SHORT), "--sim", *FAST, "-q", "--log", "/dev/full"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "vehicle 1: mission completed: all tasks done" in out
    assert "flight log: /dev/full (0 lines; could not write line 1: No space left on device" \
        in out


FENCED_HOP = SHORT.replace('<mission name="Hop">\n', '<mission name="Hop">\n<environment>'
                           '<geofence max_altitude="30"><point north="-50" east="-50"/>'
                           '<point north="50" east="-50"/><point north="50" east="50"/>'
                           '<point north="-50" east="50"/></geofence><rally>'
                           '<point north="-10" east="0" altitude="10"/></rally>'
                           '</environment>\n')


@pytest.mark.parametrize("keep", [False, True])
def test_the_missions_fence_goes_on_the_vehicle_unless_it_keeps_its_own(
        tmp_path: Path, keep: bool) -> None:
    log = tmp_path / "flight.jsonl"
    code = main(["run", write(tmp_path, FENCED_HOP), "--sim", "-q", "--log", str(log), *FAST,
                 *(["--keep-vehicle-fence"] if keep else [])])
    assert code == 0
    (told,) = [line for line in read(str(log)) if line["kind"] == "safeguard"]
    assert told["ok"] and told["message"] == "on the vehicle: " + (
        "the vehicle's fence kept; 1 rally point" if keep else
        "inclusion polygon of 4 corners; FENCE_ALT_MAX 30 m; FENCE_TYPE 5, FENCE_ENABLE 1; "
        "1 rally point; FENCE_ACTION 1 (RTL or land)") + "; read back matched"


def test_a_skill_that_needs_a_companion_computer_is_waited_for_and_named(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # No companion computer on board: the mission's AVOID_OBSTACLES can never be switched;
    # the run says so before anything moves, instead of failing the request in the air.
    mission = SHORT.replace('<task name="Up">', '<skill name="AVOID_OBSTACLES"/>\n  '
                            '<task name="Up">')
    code = main(["run", write(tmp_path, mission), "--sim", *FAST, "-q",
                 "--sim-param", "SIM_COMPANION=0", "--ready-timeout", "20"])
    out = capsys.readouterr().out
    assert code == 4, out
    assert ("not ready after 20 s: waiting for skill AVOID_OBSTACLES (needs a companion "
            "computer (component 191), not heard yet)") in out
