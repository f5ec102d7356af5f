"""Fault descriptions and the seeded wire channel that applies them to packets."""

from __future__ import annotations

import pytest

from sitl.faults import Faults, WireChannel


def run(faults: Faults, loss: float = 0.0, packets: int = 200, until: float = 100.0,
        stream: str = "1/out") -> list[int]:
    channel: WireChannel[int] = WireChannel(faults, loss, stream)
    for n in range(packets):
        channel.send(n * 0.01, n)
    return channel.due(until)


@pytest.mark.parametrize("options", [
    {"loss_in": 1.5}, {"duplicate": -0.1}, {"latency": -1.0}, {"outages": ((5.0, 1.0),)},
])
def test_impossible_faults_are_refused(options):
    with pytest.raises(ValueError):
        Faults(**options)


def test_only_link_faults_affect_the_wire():
    assert not Faults(seed=3, gps_loss_at=10.0, reject_commands={400: 4}).affects_wire
    assert Faults(latency=0.1).affects_wire and Faults(outages=((1.0, 2.0),)).affects_wire


def test_outage_windows_include_their_start_and_exclude_their_end():
    f = Faults(outages=((1.0, 2.0),))
    assert [f.in_outage(t) for t in (0.99, 1.0, 1.99, 2.0)] == [False, True, True, False]


def test_a_clean_channel_delivers_everything_in_order():
    assert run(Faults()) == list(range(200))


def test_loss_is_seeded_per_stream_and_near_its_rate():
    lossy = run(Faults(seed=5), loss=0.3)
    assert lossy == run(Faults(seed=5), loss=0.3)
    assert lossy != run(Faults(seed=6), loss=0.3)
    assert lossy != run(Faults(seed=5), loss=0.3, stream="1/in")
    assert 0.6 * 200 < len(lossy) < 0.8 * 200


def test_latency_does_not_change_which_packets_are_lost():
    plain = run(Faults(seed=2), loss=0.3)
    delayed = run(Faults(seed=2, latency=0.5, jitter=0.2), loss=0.3)
    assert sorted(delayed) == plain


def test_latency_holds_packets_until_their_time():
    channel: WireChannel[str] = WireChannel(Faults(latency=0.5), 0.0, "x")
    channel.send(1.0, "a")
    assert channel.due(1.49) == [] and channel.due(1.5) == ["a"]


def test_duplicates_outages_and_reordering():
    assert run(Faults(duplicate=1.0), packets=10) == [n for n in range(10) for _ in (0, 1)]
    assert run(Faults(outages=((0.5, 1.0),))) == [*range(50), *range(100, 200)]
    reordered = run(Faults(seed=1, reorder=0.3, reorder_delay=0.05))
    assert reordered != sorted(reordered) and sorted(reordered) == list(range(200))
