"""The control socket of a running ``tml run``: found by address and system id, the user's
alone, a dead run's passed over and replaced, and each command carried out by the run and
answered with what the vehicle's telemetry confirmed."""

from __future__ import annotations

import os
import socket
import stat
import tempfile
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest

from tml.errors import ControlRefused
from tml.run.control import (
    ENVIRONMENT,
    ControlServer,
    ControlUnsafe,
    OperatorDesk,
    address_key,
    ask_run,
    control_path,
    runs_at,
    runtime_dir,
)
from tml.vehicle import Request, RequestResult, VehicleState

ADDRESS = "tcp:127.0.0.1:5860"
FLYING = VehicleState(1, 0.0, armed=True, landed=False, mode="GUIDED",
                      position=(50.0, 0.0, 10.0), ground_speed=6.0, vehicle_type="quadcopter")


class Vehicle:
    """A vehicle whose clock moves a second at each look; it stops once held, goes home
    once returning (or, ``stubborn``, flies on whatever it is told)."""

    def __init__(self, state: VehicleState = FLYING, stubborn: bool = False) -> None:
        self.vehicle_id = 1
        self.current = state
        self.stubborn = stubborn

    def state(self) -> VehicleState:
        state = self.current
        self.current = replace(state, time=state.time + 1.0)
        if self.stubborn or not state.armed or state.position is None:
            return state
        if state.mode == "GUIDED":
            self.current = replace(self.current, ground_speed=0.0)
        elif state.mode == "RTL":
            north = state.position[0] - 2.0
            self.current = replace(self.current, ground_speed=2.0, position=(north, 0.0, 10.0))
        return state

    def submit(self, request: Request) -> None:
        raise AssertionError("the desk sends nothing itself")

    def poll(self) -> list[RequestResult]:
        return []


class Runner:
    """What the desk asks of a run, written down."""

    def __init__(self, vehicle: Vehicle, flying: bool = True) -> None:
        self.vehicle = vehicle
        self.flying = flying
        self.paused = False
        self.asked: list[tuple[str, ...]] = []

    def control(self, kind: str, target: str = "", timeout: float = 10.0,
                reason: str = "") -> None:
        if not self.flying:
            raise ControlRefused("the run has ended")
        self.asked.append((kind, reason))
        self.paused = True

    def take_over(self, command: str) -> None:
        self.asked.append(("take_over", command))
        self.vehicle.current = replace(self.vehicle.current, mode=command.upper())


@pytest.fixture
def directory(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    with tempfile.TemporaryDirectory(prefix="tml", dir="/tmp") as found:
        monkeypatch.setenv(ENVIRONMENT, os.path.join(found, "run"))
        yield os.path.join(found, "run")


def serve(runner: Runner, vehicle: Vehicle, problems: list[str] | None = None
          ) -> ControlServer:
    desk = OperatorDesk(runner, {1: vehicle})  # type: ignore[arg-type]
    return ControlServer(desk, {control_path(ADDRESS, 1): 1},
                         None if problems is None else problems.append)


def test_the_directory_and_the_socket_are_the_users_alone(directory: str) -> None:
    vehicle = Vehicle()
    with serve(Runner(vehicle), vehicle):
        assert stat.S_IMODE(os.stat(directory).st_mode) == 0o700
        path = control_path(ADDRESS, 1)
        assert stat.S_ISSOCK(os.stat(path).st_mode)
        assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
        assert runs_at(ADDRESS) == [1]
        assert runs_at("tcp:127.0.0.1:5870") == []
    assert not Path(path).exists() and runs_at(ADDRESS) == []


def test_a_directory_others_may_enter_is_refused(directory: str) -> None:
    os.makedirs(directory, mode=0o755)
    os.chmod(directory, 0o755)
    with pytest.raises(ControlUnsafe, match="not the user's alone"):
        runtime_dir()


def test_hold_pauses_the_run_and_is_done_once_the_vehicle_stayed_stopped(
        directory: str) -> None:
    vehicle = Vehicle()
    runner = Runner(vehicle)
    with serve(runner, vehicle):
        answer = ask_run(ADDRESS, 1, "hold", 10.0)
    assert answer is not None
    assert (answer.outcome, answer.exit_code) == ("done", 0)
    assert answer.message.startswith("vehicle 1: hold done (the run paused): mode GUIDED")
    assert runner.asked == [("pause", "operator command: hold")]


def test_rtl_ends_the_run_into_rtl_and_is_done_once_it_heads_home(directory: str) -> None:
    vehicle = Vehicle()
    runner = Runner(vehicle)
    with serve(runner, vehicle):
        answer = ask_run(ADDRESS, 1, "rtl", 10.0)
    assert answer is not None and answer.outcome == "done", answer
    assert runner.asked == [("take_over", "rtl")]


def test_a_hold_the_vehicle_does_not_keep_is_not_confirmed(directory: str) -> None:
    vehicle = Vehicle(stubborn=True)
    with serve(Runner(vehicle), vehicle):
        answer = ask_run(ADDRESS, 1, "hold", 0.3)
    assert answer is not None
    assert (answer.outcome, answer.exit_code) == ("not confirmed", 4)
    assert "hold not confirmed within 0.3 s (the run paused; wanted ground speed below " \
           "0.5 m/s for 3 s in a holding mode; seen mode GUIDED" in answer.message
    assert "ground speed 6.0 m/s" in answer.message


def test_a_disarm_in_the_air_is_refused_by_the_run(directory: str) -> None:
    vehicle = Vehicle()
    runner = Runner(vehicle)
    with serve(runner, vehicle):
        answer = ask_run(ADDRESS, 1, "disarm", 5.0)
    assert answer is not None and (answer.outcome, answer.exit_code) == ("refused", 2)
    assert "disarm refused: the vehicle is flying at 10.0 m" in answer.message
    assert runner.asked == []


def test_a_run_not_flying_sends_the_command_back_to_the_vehicle(directory: str) -> None:
    vehicle = Vehicle()
    with serve(Runner(vehicle, flying=False), vehicle):
        answer = ask_run(ADDRESS, 1, "rtl", 5.0)
    assert answer is not None and answer.outcome == "no run"


def test_a_dead_runs_socket_is_replaced_and_a_live_one_kept(directory: str) -> None:
    runtime_dir()
    path = control_path(ADDRESS, 1)
    dead = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    dead.bind(path)
    dead.close()
    assert runs_at(ADDRESS) == [] and ask_run(ADDRESS, 1, "hold", 1.0) is None
    vehicle = Vehicle()
    problems: list[str] = []
    with serve(Runner(vehicle), vehicle) as first:
        assert path in first.listening and runs_at(ADDRESS) == [1]
        with serve(Runner(vehicle), vehicle, problems) as second:
            assert not second.listening
        assert problems == [f"control socket {path}: another run listens there; operator "
                            "commands go to it"]
        assert runs_at(ADDRESS) == [1]  # the second left the first's socket alone


def test_a_request_for_another_vehicle_or_not_a_request_is_refused(directory: str) -> None:
    vehicle = Vehicle()
    with serve(Runner(vehicle), vehicle):
        path = control_path(ADDRESS, 1)
        for line, expected in [(b'{"command": "hold", "system_id": 2}\n',
                                "this socket commands vehicle 1, not 2"),
                               (b"hold\n", "not a command request")]:
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as peer:
                peer.connect(path)
                peer.sendall(line)
                assert expected.encode() in peer.recv(4096)


def test_without_sysid_an_address_that_cannot_be_heard_names_the_run_there(
        directory: str, capsys: pytest.CaptureFixture[str]) -> None:
    from tml.commands.cli import main

    address = "tcp:127.0.0.1:9"  # nothing listens (a serial port a run holds, say)
    vehicle = Vehicle()
    desk = OperatorDesk(Runner(vehicle), {3: vehicle})  # type: ignore[arg-type]
    with ControlServer(desk, {control_path(address, 3): 3}):
        assert main(["command", "hold", "--connect", address, "--timeout", "1"]) == 4
    assert capsys.readouterr().err.strip().endswith(
        "(a run flies the vehicle with system id 3 at tcp:127.0.0.1:9: give --sysid to "
        "command it through the run)")


def test_the_answer_names_the_system_id_where_the_runs_number_differs(directory: str) -> None:
    vehicle = Vehicle()  # the run's vehicle 1, system id 2 on its link
    desk = OperatorDesk(Runner(vehicle), {2: vehicle})  # type: ignore[arg-type]
    with ControlServer(desk, {control_path(ADDRESS, 2): 2}):
        answer = ask_run(ADDRESS, 2, "hold", 10.0)
    assert answer is not None and answer.outcome == "done"
    assert answer.message.startswith("vehicle 1 (system id 2): hold done (the run paused)")


def test_two_spellings_of_one_address_reach_the_same_run(directory: str,
                                                        tmp_path: Path) -> None:
    vehicle = Vehicle()
    runner = Runner(vehicle)
    with serve(runner, vehicle):  # listening for tcp:127.0.0.1:5860
        assert runs_at("tcp:localhost:5860") == [1]
        answer = ask_run("tcp:localhost:5860", 1, "hold", 10.0)
    assert answer is not None and answer.outcome == "done", answer
    # Another port or another scheme is another vehicle.
    assert address_key("tcp:localhost:5861") != address_key(ADDRESS)
    assert address_key("udpin:127.0.0.1:5860") != address_key(ADDRESS)
    # A serial device named through a link, at any speed, is the device.
    device = tmp_path / "ttyUSB0"
    device.touch()
    link = tmp_path / "usb-radio-if00"
    link.symlink_to(device)
    assert address_key(f"{link},57600") == address_key(str(device)) \
        == address_key(f"{device},115200")
    assert address_key(f"{tmp_path / 'ttyUSB1'}") != address_key(str(device))
