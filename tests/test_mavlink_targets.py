"""The GUIDED target a vehicle reports, as ArduCopter reports it (type masks measured on
ArduCopter SITL: 65016 a position in POSITION_TARGET_GLOBAL_INT, 3576 one in
POSITION_TARGET_LOCAL_NED, 3079 a velocity in POSITION_TARGET_LOCAL_NED)."""

from __future__ import annotations

from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from tml.mavlink.targets import TargetWatch
from tml.mavlink.telemetry import GlobalPosition, Telemetry

HERE = GlobalPosition(-35.3632621, 149.1652374, 600.0, 10.0)


class Link:
    def __init__(self) -> None:
        self.listeners: list[Any] = []

    def listen(self, listener: Any) -> None:
        self.listeners.append(listener)


def report(link: Link, msg: Any, at: float, system_id: int = 1) -> None:
    msg._header = mavlink.MAVLink_header(msg.id, srcSystem=system_id, srcComponent=1)
    for listener in link.listeners:
        listener(system_id, Telemetry(system_id, at, position=HERE), msg)


def global_target(north: float, mask: int = 65016) -> Any:
    return mavlink.MAVLink_position_target_global_int_message(
        0, 0, mask, round((HERE.latitude + north / 111_195.0) * 1e7),
        round(HERE.longitude * 1e7), 600.0, 0, 0, 0, 0, 0, 0, 0, 0)


def local_target(mask: int, vx: float = 0.0) -> Any:
    return mavlink.MAVLink_position_target_local_ned_message(
        0, 1, mask, 200.0, 0, -10, vx, 0, 0, 0, 0, 0, 0, 0)


def test_a_position_target_is_told_by_its_distance_a_velocity_by_its_speed() -> None:
    link = Link()
    watch = TargetWatch(link, 1)  # type: ignore[arg-type]
    report(link, global_target(150.0), 1.0)
    assert watch.latest is not None and watch.latest.distance == pytest.approx(150.0, abs=1.0)
    assert watch.latest.speed is None
    report(link, local_target(3576), 1.0)  # the same position, locally: nothing new
    assert watch.latest.distance == pytest.approx(150.0, abs=1.0)
    report(link, local_target(3079, vx=0.0), 2.0)
    assert (watch.latest.distance, watch.latest.speed, watch.latest.received) == (None, 0.0, 2.0)
    assert watch.latest.describe() == "GUIDED target velocity 0.0 m/s"
    watch.clear()
    assert watch.latest is None


def test_another_vehicles_target_is_not_this_ones() -> None:
    link = Link()
    watch = TargetWatch(link, 1)  # type: ignore[arg-type]
    report(link, global_target(150.0), 1.0, system_id=2)
    assert watch.latest is None
