"""``tml command`` against the embedded simulator: a vehicle flown up by another client is
returned, refused a disarm in the air, and disarmed on the ground; an independent
pymavlink client on the vehicle's port judges what the vehicle did."""

from __future__ import annotations

import math
import re
import threading
import time
from collections.abc import Callable, Iterator
from types import SimpleNamespace
from typing import Any

import pytest
from connected_flight import vehicles_on_one_udp_port
from pymavlink import mavutil

from sitl.server import Simulator
from tml.commands.cli import main
from tml.mavlink.autopilot import Autopilot
from tml.mavlink.link import Link
from tml.vehicle import RequestResult, VehicleState

# Armable at once; an armed vehicle left on the ground does not disarm by itself.
PARAMS = {"SIM_GPS_LOCKTIME": 0.5, "SIM_EKF_GPS_TIME": 1.0, "DISARM_DELAY": 0}
LIMIT = 60.0  # wall seconds for each state waited for (a bound, not a timing)
RTL_MODE = 6
M = mavutil.mavlink
BRAKE_MODE = 17


class Observer:
    """A plain pymavlink client on the vehicle's port, reading its HEARTBEATs."""

    def __init__(self, port: int) -> None:
        self.conn: Any = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}",
                                                    source_system=250, dialect="ardupilotmega")
        self.modes: list[int] = []
        self.armed = False

    def until(self, check: Callable[[Observer], bool], limit: float = LIMIT) -> bool:
        end = time.monotonic() + limit
        while time.monotonic() < end:
            msg = self.conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
            if msg is not None and msg.get_srcSystem() == 1 and msg.get_srcComponent() == 1:
                self.modes.append(msg.custom_mode)
                self.armed = bool(msg.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
                if check(self):
                    return True
        return False

    def close(self) -> None:
        self.conn.close()


@pytest.fixture
def vehicle(request: pytest.FixtureRequest) -> Iterator[tuple[Simulator, Autopilot, Observer]]:
    """A simulated copter, a pilot's client armed on it in GUIDED, and an observer (the
    simulator at 20 times real time, or at the speed-up of the test's parameter)."""
    speedup = float(getattr(request, "param", 20.0))
    with Simulator(vehicles=1, tcp_base_port=0, speedup=speedup, params=PARAMS) as sim, \
            Link(f"tcp:127.0.0.1:{sim.tcp_ports[0]}") as link:
        pilot = Autopilot.connect(link, 1, timeout=10)
        pilot.request_rates()
        link.wait_telemetry(1, lambda t: t.position_ready, timeout=LIMIT)
        pilot.set_mode("GUIDED")
        pilot.arm()
        observer = Observer(sim.tcp_ports[0])
        try:
            yield sim, pilot, observer
        finally:
            observer.close()


def fly_up(pilot: Autopilot) -> None:
    pilot.takeoff(10.0)
    pilot.link.wait_telemetry(1, lambda t: t.position is not None
                              and t.position.relative_altitude > 9.0, timeout=LIMIT)


def command(sim: Simulator, *words: str) -> list[str]:
    return ["command", *words, "--connect", f"tcp:127.0.0.1:{sim.tcp_ports[0]}",
            "--timeout", "30"]


def test_rtl_returns_a_flying_vehicle_and_it_lands(
        vehicle: tuple[Simulator, Autopilot, Observer], capsys: pytest.CaptureFixture[str]
) -> None:
    sim, pilot, observer = vehicle
    fly_up(pilot)
    assert main(command(sim, "rtl")) == 0
    out = capsys.readouterr().out
    assert "vehicle 1: rtl done: mode RTL, armed" in out
    assert observer.until(lambda o: o.modes[-1] == RTL_MODE)
    assert observer.until(lambda o: not o.armed), "never landed and disarmed"
    assert sim.vehicle(1).landed


def test_a_disarm_in_the_air_is_refused_and_the_vehicle_flies_on(
        vehicle: tuple[Simulator, Autopilot, Observer], capsys: pytest.CaptureFixture[str]
) -> None:
    sim, pilot, observer = vehicle
    fly_up(pilot)
    assert main(command(sim, "disarm", "--sysid", "1")) == 2
    err = capsys.readouterr().err
    assert "vehicle 1: disarm refused: the vehicle is flying" in err
    assert "disarming would drop it" in err
    assert observer.until(lambda o: o.armed and len(o.modes) >= 3)
    assert sim.vehicle(1).armed and not sim.vehicle(1).landed
    assert pilot.telemetry.position is not None
    assert pilot.telemetry.position.relative_altitude > 8.0


def test_a_disarm_on_the_ground_disarms(
        vehicle: tuple[Simulator, Autopilot, Observer], capsys: pytest.CaptureFixture[str]
) -> None:
    sim, _pilot, observer = vehicle
    assert observer.until(lambda o: o.armed)
    assert main(command(sim, "disarm")) == 0
    assert "vehicle 1: disarm done: mode GUIDED, disarmed, on the ground" in \
        capsys.readouterr().out
    assert observer.until(lambda o: not o.armed)
    assert not sim.vehicle(1).armed


def test_no_vehicle_at_the_address_is_a_failure(capsys: pytest.CaptureFixture[str]) -> None:
    with Simulator(vehicles=1, tcp_base_port=0, speedup=20.0, params=PARAMS) as sim:
        words = command(sim, "land", "--sysid", "7")
        words[-1] = "1"
        assert main(words) == 4
    assert "no heartbeat from vehicle 7" in capsys.readouterr().err


def test_a_malformed_address_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["command", "hold", "--connect", "127.0.0.1:5760"]) == 2
    assert "--connect 127.0.0.1:5760: not an address" in capsys.readouterr().err


def fly_away(pilot: Autopilot) -> None:
    """Up, and on its way to a point 300 m north at 8 m/s."""
    fly_up(pilot)
    t = pilot.telemetry
    assert t.position is not None
    pilot.change_speed(8.0)
    pilot.position_target(t.position.latitude + 300 / 111_320, t.position.longitude,
                          t.position.relative_altitude)
    pilot.link.wait_telemetry(1, lambda t: t.velocity is not None
                              and math.hypot(*t.velocity[:2]) > 5.0, timeout=LIMIT)


def test_hold_brakes_a_vehicle_no_run_flies_and_confirms_the_stop(
        vehicle: tuple[Simulator, Autopilot, Observer], capsys: pytest.CaptureFixture[str]
) -> None:
    sim, pilot, observer = vehicle
    fly_away(pilot)
    assert main(command(sim, "hold")) == 0
    out = capsys.readouterr().out
    # BRAKE holds by itself: nothing keeps a GUIDED target once tml command has gone.
    assert "vehicle 1: hold done: mode BRAKE, armed" in out
    found = re.search(r"ground speed (\d+\.\d) m/s", out)
    assert found and float(found.group(1)) < 0.5, out
    assert observer.until(lambda o: o.modes[-1] == BRAKE_MODE)
    assert sim.vehicle(1).mode == "BRAKE" and math.hypot(*sim.vehicle(1).velocity[:2]) < 0.5
    assert main(command(sim, "land")) == 0
    assert "vehicle 1: land done: mode LAND, armed" in capsys.readouterr().out
    assert observer.until(lambda o: not o.armed), "never landed and disarmed"


def test_a_rover_is_refused_a_landing_and_holds(capsys: pytest.CaptureFixture[str]) -> None:
    fast = {"SIM_GPS_LOCKTIME": 0.5, "SIM_EKF_GPS_TIME": 1.0}
    with Simulator(vehicles=1, frames=["rover"], tcp_base_port=0, speedup=20.0,
                   params=fast) as sim, \
            Link(f"tcp:127.0.0.1:{sim.tcp_ports[0]}") as link:
        driver = Autopilot.connect(link, 1, timeout=10)
        driver.request_rates()
        link.wait_telemetry(1, lambda t: t.position_ready, timeout=LIMIT)
        driver.set_mode("GUIDED")
        # Disarmed or armed, a ground vehicle is refused a landing: it is not a command
        # it can carry out, whatever its state (not "nothing to do").
        assert main(command(sim, "land")) == 2
        assert "vehicle 1: land refused: a ground vehicle does not land" in \
            capsys.readouterr().err
        driver.arm()
        assert main(command(sim, "land")) == 2
        assert "a ground vehicle does not land" in capsys.readouterr().err
        assert main(command(sim, "hold")) == 0
        assert "vehicle 1: hold done: mode HOLD, armed" in capsys.readouterr().out
        assert sim.vehicle(1).mode == "HOLD"


class SwitchedBack:
    """A flying copter that accepts every command, but whose telemetry keeps showing GUIDED
    (another ground station switched it back): the interface of MavlinkVehicle that
    ``tml command`` uses, and nothing more."""

    vehicle_id = system_id = 1

    def __init__(self) -> None:
        arrived = {"HEARTBEAT": 1.0, "GLOBAL_POSITION_INT": 1.0, "EXTENDED_SYS_STATE": 1.0}
        self.mav = SimpleNamespace(request_rates=lambda: None, ask_again=lambda *_: None)
        self.link = SimpleNamespace(arrivals=lambda _system_id: arrived,
                                    listen=lambda _listener: None)
        self.submitted: list[Any] = []
        self.now = 1.0

    def state(self) -> VehicleState:
        self.now += 1.0  # every picture newer than the request
        return VehicleState(1, self.now, armed=True, landed=False, mode="GUIDED",
                            position=(0.0, 0.0, 10.0), heard=self.now,
                            asked=1.0 if self.submitted else None)

    def submit(self, request: Any) -> None:
        self.submitted.append(request)

    def poll(self) -> list[RequestResult]:
        return [RequestResult(1, r.request_id, True) for r in self.submitted]


def test_a_command_accepted_but_never_shown_is_a_failure_naming_the_mode_seen(
        capsys: pytest.CaptureFixture[str]) -> None:
    from tml.commands.command import _carry_out

    vehicle = SwitchedBack()
    assert _carry_out(vehicle, "rtl", timeout=0.3) == 4  # type: ignore[arg-type]
    assert [r.name for r in vehicle.submitted] == ["ReturnToLaunch"]
    assert capsys.readouterr().err == (
        "tml command: vehicle 1: rtl not confirmed within 0.3 s (wanted an RTL mode and 1 m "
        "nearer home (or home); seen mode GUIDED, armed, 10.0 m up, ground speed 0.0 m/s, "
        "climb +0.0 m/s, 0 m from home)\n")


@pytest.mark.parametrize("vehicle", [1.0], indirect=True)  # (the other station keeps up)
def test_a_hold_the_vehicle_does_not_keep_is_not_confirmed(
        vehicle: tuple[Simulator, Autopilot, Observer], capsys: pytest.CaptureFixture[str]
) -> None:
    """Another ground station switches the vehicle back to GUIDED the moment it is in
    BRAKE and sends it on: the mode was shown, the stop never was."""
    sim, pilot, _observer = vehicle
    fly_away(pilot)
    start = pilot.telemetry.position
    assert start is not None
    other: Any = mavutil.mavlink_connection(f"tcp:127.0.0.1:{sim.tcp_ports[0]}",
                                            source_system=255, source_component=50,
                                            dialect="ardupilotmega")
    done = threading.Event()

    def fight() -> None:
        while not done.is_set():
            if sim.vehicle(1).mode == "BRAKE":
                other.mav.command_long_send(1, 1, M.MAV_CMD_DO_SET_MODE, 0,
                                            M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4,
                                            0, 0, 0, 0, 0)
                other.mav.set_position_target_global_int_send(
                    0, 1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000,
                    int((start.latitude + 600 / 111_320) * 1e7),
                    int(start.longitude * 1e7), start.relative_altitude,
                    0, 0, 0, 0, 0, 0, 0, 0)
            time.sleep(0.01)

    fighter = threading.Thread(target=fight)
    fighter.start()
    try:
        code = main([*command(sim, "hold")[:-1], "8"])
    finally:
        done.set()
        fighter.join()
        other.close()
    err = capsys.readouterr().err
    assert code == 4, err
    assert "vehicle 1: hold not confirmed within 8 s" in err
    assert "wanted ground speed below 0.5 m/s for 3 s in a holding mode" in err
    assert sim.vehicle(1).mode == "GUIDED"
    # The simulator reports the other station's point as ArduCopter does: the line names it.
    seen = re.search(r"GUIDED target (\d+) m away\)$", err.strip())
    assert seen is not None, err
    assert 2 < int(seen[1]) <= 610


def test_several_vehicles_at_the_address_need_a_sysid(
        capsys: pytest.CaptureFixture[str]) -> None:
    with vehicles_on_one_udp_port(2, PARAMS) as address:
        assert main(["command", "hold", "--connect", address, "--timeout", "30"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"tml command: {address}: vehicles with system ids 1, 2 heard: say which with "
        "--sysid N"]
