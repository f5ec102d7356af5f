"""Frames (sitl/frames.py): which model flies each vehicle, written on a command line."""

from __future__ import annotations

import pytest

from sitl.frames import FRAMES, frame_of, parse_frames
from sitl.params import UnknownParameter
from sitl.plane import PlaneModel
from sitl.rover import RoverModel
from sitl.server import Simulator


def test_frames_are_parsed_and_the_last_repeats() -> None:
    frames = parse_frames("Copter, rover")
    assert frames == ["copter", "rover"]
    assert [frame_of(frames, i) for i in range(4)] == ["copter", "rover", "rover", "rover"]
    assert frame_of([], 3) == "copter"


def test_an_unknown_frame_is_named() -> None:
    with pytest.raises(ValueError, match=r"unknown frame 'blimp' \(frames: copter, plane"):
        parse_frames("copter,blimp")


def test_a_mixed_simulator_gives_each_vehicle_its_own_parameters() -> None:
    sim = Simulator(vehicles=3, tcp_base_port=None, realtime=False, frames=["plane", "rover"],
                    params={"AIRSPEED_CRUISE": 18, "WP_SPEED": 3, "BATT_CAPACITY": 900})
    plane, rover, other = sim.vehicles
    assert isinstance(plane, PlaneModel) and type(rover) is type(other) is RoverModel
    assert plane.params["AIRSPEED_CRUISE"] == 18 and "WP_SPEED" not in plane.params
    assert rover.params["WP_SPEED"] == 3 and "AIRSPEED_CRUISE" not in rover.params
    assert {v.params["BATT_CAPACITY"] for v in sim.vehicles} == {900}
    assert set(FRAMES) == {"copter", "plane", "rover"}


def test_a_parameter_no_vehicle_has_is_refused() -> None:
    with pytest.raises(UnknownParameter):
        Simulator(tcp_base_port=None, realtime=False, frames=["rover"],
                  params={"WPNAV_SPEED": 500})
