"""The flight session (tml.run.session): typed options in, vehicles opened and woken on
each message, a mission cleared (or refused) before anything is sent."""

from __future__ import annotations

import argparse
import threading
from collections.abc import Iterator
from dataclasses import fields
from pathlib import Path

import pytest

from tml.commands.vehicles import add_vehicle_arguments, session_options
from tml.language.validation import load_mission
from tml.run.session import (
    GCS_FAILSAFE,
    Refusal,
    Session,
    SessionOptions,
    SimulatorOptions,
    open_session,
)
from tml.simulator import open_simulator
from tml.vehicle import SetMode
from tml.verify.profile import load_profile
from tml.world import World

FAST = {"SIM_GPS_LOCKTIME": 0.5, "SIM_EKF_GPS_TIME": 1.0}
UP = """<mission name="Up">
  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="4"/></action></task>
  <task name="Down"><action name="LAND"/></task>
</mission>
"""


def simulated(**options: object) -> SessionOptions:
    params = {**FAST, **options.pop("params", {})}  # type: ignore[dict-item]
    return SessionOptions(simulator=SimulatorOptions(speedup=20, params=params),
                          open_simulator=open_simulator, **options)  # type: ignore[arg-type]


@pytest.fixture
def session() -> Iterator[Session]:
    with open_session(simulated(), World()) as found:
        yield found


def test_the_arguments_become_typed_options() -> None:
    parser = argparse.ArgumentParser()
    add_vehicle_arguments(parser)
    args = parser.parse_args(["--connect", "udpin:0.0.0.0:14550", "--connect",
                              "/dev/ttyUSB0,57600", "--timeout", "5",
                              "--require-gcs-failsafe"])
    options = session_options(args, "tml serve")
    assert options.connect == ("udpin:0.0.0.0:14550", "/dev/ttyUSB0,57600")
    assert (options.timeout, options.require_gcs_failsafe, options.program) == (
        5.0, True, "tml serve")
    assert options.simulator is None and options.open_simulator is None
    simulated_args = parser.parse_args(["--sim", "--vehicles", "3", "--sim-param",
                                        "SIM_EKF_GPS_TIME=2"])
    sim = session_options(simulated_args, "tml run", lockstep=True)
    assert sim.simulator == SimulatorOptions(vehicles=3, params={"SIM_EKF_GPS_TIME": 2.0})
    assert sim.lockstep and sim.open_simulator is open_simulator
    # Nothing of argparse is kept: every field is a plain value.
    assert not any(isinstance(getattr(sim, f.name), argparse.Namespace) for f in fields(sim))


def test_notify_is_called_on_each_result_instead_of_the_wake_flag() -> None:
    results = threading.Semaphore(0)
    with open_session(simulated(), World(), notify=results.release) as session:
        vehicle = session.vehicles[0]
        for mode in ("GUIDED", "LOITER"):
            vehicle.submit(SetMode(vehicle.vehicle_id, mode))
            assert results.acquire(timeout=60)
        assert not session.wake.is_set()


def test_without_notify_the_wake_flag_is_set_on_each_result() -> None:
    with open_session(simulated(), World()) as session:
        # (The vehicles' messages wake a runner through its own watch of them, only
        # when a field it reads changes: tml.run.lookout.)
        session.wake.clear()
        session.vehicles[0].submit(SetMode(session.vehicles[0].vehicle_id, "GUIDED"))
        assert session.wake.wait(60)


def test_a_mission_beyond_its_vehicles_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "up.xml"
    path.write_text(UP)
    rover = SessionOptions(simulator=SimulatorOptions(speedup=20, params=FAST,
                                                      frames=("rover",)),
                           open_simulator=open_simulator)
    with open_session(rover, World()) as session:
        assert session.clear(load_mission(str(path)), load_profile("quadcopter")) is \
            Refusal.MISSION
    forced = SessionOptions(**{**rover.__dict__, "force": True})
    with open_session(forced, World()) as session:
        assert session.clear(load_mission(str(path)), load_profile("quadcopter")) is not \
            Refusal.MISSION


def test_a_mission_the_vehicles_can_fly_is_cleared_with_its_profile(session: Session,
                                                                    tmp_path: Path) -> None:
    path = tmp_path / "up.xml"
    path.write_text(UP)
    profile = load_profile("quadcopter")
    assert session.clear(load_mission(str(path)), profile) is profile


def test_a_vehicle_without_a_gcs_failsafe_is_refused_when_one_is_required() -> None:
    with open_session(simulated(require_gcs_failsafe=True), World()) as session:
        assert session.gcs_failsafe() is Refusal.VEHICLE
    with open_session(simulated(require_gcs_failsafe=True,
                                params={GCS_FAILSAFE: 1}), World()) as session:
        assert session.gcs_failsafe() is None


def test_the_profile_is_read_from_the_vehicle_when_none_is_given(session: Session,
                                                                  tmp_path: Path) -> None:
    path = tmp_path / "up.xml"
    path.write_text(UP)
    cleared = session.clear(load_mission(str(path)), None)
    assert not isinstance(cleared, Refusal)
    assert cleared.name.startswith("quadcopter")
