"""A vehicle's link health from what arrives (tml.mavlink.health)."""

from __future__ import annotations

import math

import pytest

from tml.mavlink.health import DEGRADED_LOSS, LinkHealth


def stream(health: LinkHealth, start: float, end: float, *, lag: float = 0.0,
           period: float = 0.1, received: int = 0) -> int:
    """Messages stamped every ``period`` s of the vehicle's time from ``start`` to ``end``,
    a HEARTBEAT each second, read ``lag`` seconds late; returns the count received."""
    stamp = start
    while stamp <= end + 1e-9:
        received += 1
        health.heard(stamp + lag, abs(stamp - round(stamp)) < 1e-6, stamp, received, 0)
        stamp += period
    return received


def test_no_heartbeat_yet_is_lost() -> None:
    health = LinkHealth()
    assert health.silence(10.0) == math.inf and health.state(10.0) == "lost"


def test_a_steady_link_is_ok() -> None:
    health = LinkHealth()
    stream(health, 0.0, 20.0)
    assert health.state(20.05) == "ok" and health.silence(20.05) < 1.1


def test_a_ground_station_that_reads_late_does_not_see_the_vehicle_silent() -> None:
    # Everything is read 4 s after it was sent (a busy machine behind a sped-up simulator):
    # by the reader's clock the last HEARTBEAT is always 4 s old, yet the vehicle is
    # talking; the stamps it read carry the HEARTBEATs with them.
    health = LinkHealth()
    stream(health, 0.0, 30.0, lag=4.0)
    assert health.state(34.05) == "ok"
    by_arrival_only = 34.05 - 30.0  # what timing the last HEARTBEAT's arrival would say
    assert by_arrival_only > health.degraded_after


def test_a_vehicle_that_falls_silent_degrades_then_is_lost() -> None:
    health = LinkHealth()
    stream(health, 0.0, 10.0)
    assert health.state(11.0) == "ok"
    assert health.state(13.0) == "degraded"  # 3 s since the HEARTBEAT at 10 s
    assert health.state(15.5) == "lost"


def test_calm_says_when_silence_alone_changes_the_health() -> None:
    health = LinkHealth()
    stream(health, 0.0, 10.0)  # the last HEARTBEAT at 10 s
    for now in (10.5, 12.0, 13.0, 14.9, 16.0):
        calm = health.calm(now)
        # Nothing changes before now + calm, and something does just after it.
        assert health.state(now + calm - 1e-6) == health.state(now)
        assert health.state(now + calm + 1e-6) != health.state(now) or calm == math.inf
    assert health.calm(11.0) == pytest.approx(1.5)  # degraded 2.5 s after the HEARTBEAT
    assert health.calm(13.0) == pytest.approx(2.0)  # then lost 5 s after it
    assert health.calm(16.0) == math.inf  # lost: only a message changes it


def test_heartbeats_missing_from_a_stream_that_goes_on_degrade_the_link() -> None:
    # Other messages keep coming, HEARTBEATs do not (stamps 10-14 s): silence by the stamps.
    health = LinkHealth()
    received = stream(health, 0.0, 10.0)
    for i in range(1, 41):
        received += 1
        health.heard(10.0 + i * 0.1, False, 10.0 + i * 0.1, received, 0)
    assert health.state(14.05) == "degraded"


def test_loss_above_the_limit_degrades_the_link() -> None:
    health = LinkHealth()
    health.heard(0.0, True, 0.0, 10, 0)
    health.heard(1.0, True, 1.0, 20, 5)  # 5 of the 15 messages of that second missing
    assert health.loss > DEGRADED_LOSS and health.state(1.0) == "degraded"
    health.heard(2.0, True, 2.0, 40, 5)  # none missing since
    assert health.loss == 0.0 and health.state(2.0) == "ok"


def test_a_reboot_restarts_the_stamps_without_looking_silent() -> None:
    health = LinkHealth()
    stream(health, 100.0, 110.0)
    health.heard(110.5, True, 0.2, 200, 0)  # rebooted: stamps start again near 0
    health.heard(110.6, False, 0.3, 201, 0)
    assert health.state(110.7) == "ok"


def test_before_any_stamp_the_silence_is_timed_on_the_callers_clock() -> None:
    health = LinkHealth()
    health.heard(5.0, True, None, 1, 0)
    assert health.silence(6.0) == 1.0 and health.state(8.0) == "degraded"
