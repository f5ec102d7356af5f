"""The kinds of simulated vehicle ("frames", as ArduPilot SITL's ``--model``): which model
class flies each, and how a list of them is written on a command line.

``copter`` is ArduCopter (:class:`sitl.model.VehicleModel`), ``plane`` ArduPlane
(:class:`sitl.plane.PlaneModel`), ``rover`` Rover (:class:`sitl.rover.RoverModel`). A
fleet of mixed vehicles is written ``copter,rover``: vehicle 1 is a copter, vehicle 2 a
rover, and the last frame written is repeated for the vehicles after it.
"""

from __future__ import annotations

from collections.abc import Sequence

from sitl.model import VehicleModel
from sitl.plane import PlaneModel
from sitl.rover import RoverModel

FRAMES: dict[str, type[VehicleModel]] = {
    "copter": VehicleModel, "plane": PlaneModel, "rover": RoverModel,
}
DEFAULT = "copter"


def parse_frames(text: str) -> list[str]:
    """``copter,rover`` -> ["copter", "rover"]; ValueError naming an unknown frame."""
    frames = [word.strip().lower() for word in text.split(",")]
    for frame in frames:
        if frame not in FRAMES:
            raise ValueError(f"unknown frame {frame!r} (frames: {', '.join(FRAMES)})")
    return frames


def frame_of(frames: Sequence[str], index: int) -> str:
    """The frame of vehicle ``index`` (0-based): the last written repeats."""
    return frames[min(index, len(frames) - 1)] if frames else DEFAULT
