"""A vehicle's clock from the time_boot_ms of its messages (tml.mavlink.clock)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from tml.mavlink.clock import VehicleClock, VehicleClockEstimator
from tml.mavlink.telemetry import Telemetry


def fed(stamps: list[tuple[float, float]]) -> VehicleClockEstimator:
    clock = VehicleClockEstimator()
    for vehicle, local in stamps:
        clock.feed(vehicle, local)
    return clock


def test_before_any_stamp_the_vehicle_time_is_zero() -> None:
    clock = VehicleClockEstimator()
    assert not clock.started and clock.now(123.0) == 0.0


def test_a_sped_up_vehicle_is_followed_between_stamps_at_its_rate() -> None:
    # A SITL at --speedup 10: ten vehicle seconds per local second.
    clock = fed([(40.0 + 10 * i * 0.1, 100.0 + i * 0.1) for i in range(11)])
    assert clock.rate == pytest.approx(10.0)
    assert clock.now(101.0) == pytest.approx(50.0)
    assert clock.now(101.05) == pytest.approx(50.5)  # between stamps


def test_a_silent_vehicle_keeps_ageing_so_that_a_lost_link_looks_lost() -> None:
    clock = fed([(10.0, 0.0), (11.0, 1.0)])
    assert clock.now(6.0) == pytest.approx(16.0)


def test_the_clock_never_goes_back() -> None:
    clock = fed([(10.0, 0.0), (12.0, 1.0)])  # rate 2
    assert clock.now(1.5) == pytest.approx(13.0)
    clock.feed(12.2, 1.6)  # the vehicle was slower than the extrapolation
    assert clock.now(1.6) == pytest.approx(13.0)
    assert clock.now(2.0) == pytest.approx(13.0)  # held until the vehicle catches up
    assert clock.now(3.0) > 13.0


def test_a_reboot_carries_on_from_where_the_clock_stood() -> None:
    clock = fed([(100.0, 0.0), (101.0, 1.0)])
    clock.feed(0.5, 2.0)  # time_boot_ms restarted
    assert clock.now(2.0) == pytest.approx(101.0)
    clock.feed(1.5, 3.0)
    assert clock.now(3.0) == pytest.approx(102.0)


class TelemetryOnly:
    """The part of a Link a VehicleClock reads."""

    def __init__(self) -> None:
        self.snapshot = Telemetry(1)

    def telemetry(self, system_id: int):  # type: ignore[no-untyped-def]
        return self.snapshot


def test_vehicle_clock_reads_the_links_latest_stamp() -> None:
    link = TelemetryOnly()
    now = [50.0]
    clock = VehicleClock(link, 1, local=lambda: now[0])  # type: ignore[arg-type]
    assert clock() == 0.0
    link.snapshot = replace(link.snapshot, boot_time=30.0, boot_time_received=49.5)
    assert clock() == pytest.approx(30.5)  # rate 1 until the rate is measured


def test_waiting_for_the_first_stamp_ends_when_it_comes_or_at_the_timeout() -> None:
    link = TelemetryOnly()
    now = [10.0]

    def wait(seconds: float) -> None:  # the local clock moves only while waiting
        now[0] += seconds
        if now[0] >= 10.5:
            link.snapshot = replace(link.snapshot, boot_time=3.0, boot_time_received=10.5)

    clock = VehicleClock(link, 1, local=lambda: now[0])  # type: ignore[arg-type]
    assert clock.wait_started(5.0, wait) and 10.5 <= now[0] < 10.6
    assert clock() == pytest.approx(3.0, abs=0.1)
    silent = VehicleClock(TelemetryOnly(), 1, local=lambda: now[0])  # type: ignore[arg-type]
    start = now[0]
    assert not silent.wait_started(2.0, wait) and now[0] - start == pytest.approx(2.0, abs=0.05)
