"""Waypoint legs as ArduCopter's waypoint navigator flies them: S-curves, blended corners."""

from __future__ import annotations

import itertools
import math

import pytest

from sitl.physics import Body, Limits
from sitl.track import SCurve, Shape, Track, kinematic_limit, make_leg

DT = 0.05
ARDUCOPTER = Limits()  # WPNAV_SPEED 10 m/s, WPNAV_ACCEL 2.5 m/s², WPNAV_ACCEL_Z 1 m/s², ...
JERK = 1.0  # WPNAV_JERK
SHAPE = Shape(JERK, 0.3)  # ... and twice ATC_INPUT_TC


def samples(curve: SCurve) -> list[tuple[float, float, float]]:
    return [curve.at(step * DT) for step in range(round(curve.duration / DT) + 2)]


@pytest.mark.parametrize("jerk_time", [0.0, 0.3])
@pytest.mark.parametrize("length", [0.5, 5.0, 40.0, 100.0, 400.0])
def test_an_s_curve_goes_from_rest_to_rest_within_its_limits(length: float, jerk_time: float):
    curve = SCurve(length, 10.0, 2.5, JERK, jerk_time=jerk_time)
    points = samples(curve)
    assert curve.at(0.0) == (0.0, 0.0, 0.0)
    assert curve.at(curve.duration) == (length, 0.0, 0.0)
    assert max(v for _, v, _ in points) <= 10.0 + 1e-9
    assert max(abs(a) for _, _, a in points) <= 2.5 + 1e-9
    assert max(abs(b[2] - a[2]) for a, b in itertools.pairwise(points)) <= JERK * DT + 1e-9
    assert all(b[0] >= a[0] - 1e-9 for a, b in itertools.pairwise(points))  # never back
    middle = curve.at(curve.duration / 2.0)
    assert middle[0] == pytest.approx(length / 2.0)  # symmetric


def test_a_40_m_leg_peaks_near_7_m_s_and_takes_about_11_s():
    # ArduCopter SITL flew 40 m legs at up to 6.9 m/s (docs/simulator.md).
    curve = SCurve(40.0, 10.0, 2.5, JERK, jerk_time=0.3)
    assert curve.duration == pytest.approx(11.3, abs=0.05)
    assert max(v for _, v, _ in samples(curve)) == pytest.approx(7.1, abs=0.05)
    sharp = SCurve(40.0, 10.0, 2.5, JERK)  # without the snap limit: a little faster
    assert sharp.duration == pytest.approx(10.9, abs=0.05)
    long = SCurve(100.0, 10.0, 2.5, JERK, jerk_time=0.3)
    assert max(v for _, v, _ in samples(long)) == pytest.approx(10.0)  # room to cruise
    assert long.at(long.duration - 1e-6)[0] == pytest.approx(100.0)  # continuous to the end


def test_a_curve_from_a_speed_slows_or_speeds_to_its_new_top_speed_then_stops():
    slowing = SCurve(100.0, 3.0, 2.5, JERK, initial=8.0)
    assert slowing.at(0.0)[1] == pytest.approx(8.0)
    assert max(v for _, v, _ in samples(slowing)[round(8.0 / DT):]) == pytest.approx(3.0)
    assert slowing.at(slowing.duration)[0] == pytest.approx(100.0)
    too_fast = SCurve(2.0, 10.0, 2.5, JERK, initial=8.0)  # cannot stop in 2 m: brakes at once
    assert max(v for _, v, _ in samples(too_fast)) == pytest.approx(8.0)


def test_kinematic_limits_along_a_sloping_leg():
    assert kinematic_limit((1.0, 0.0, 0.0), 10.0, 2.5, 1.5) == 10.0
    assert kinematic_limit((0.0, 0.0, 1.0), 10.0, 2.5, 1.5) == 2.5
    assert kinematic_limit((0.0, 0.0, -1.0), 10.0, 2.5, 1.5) == 1.5
    slope = (math.sqrt(0.5), 0.0, math.sqrt(0.5))
    assert kinematic_limit(slope, 10.0, 2.5, 1.5) == pytest.approx(2.5 * math.sqrt(2.0))


def fly_square(corner: float = 40.0) -> tuple[list[tuple[int, float, float]], Body]:
    """Fly four legs of a square as AUTO flies NAV_WAYPOINTs: (leg, time, speed) when each
    is reached, and the body."""
    points = [(0.0, 0.0, 10.0), (corner, 0.0, 10.0), (corner, corner, 10.0),
              (0.0, corner, 10.0), (0.0, 0.0, 10.0)]
    track = Track(make_leg(points[0], points[1], ARDUCOPTER, SHAPE), 0.0, 2.0)
    track.set_next(make_leg(points[1], points[2], ARDUCOPTER, SHAPE))
    body = Body()
    body.position = points[0]
    reached, leg, time = [], 1, 0.0
    while leg < len(points) and time < 120.0:
        time += DT
        target, velocity, accel = track.update(time)
        body.shape(target, ARDUCOPTER, DT, velocity, accel)
        if track.reached:
            reached.append((leg, time, math.hypot(*body.velocity[:2])))
            leg += 1
            if leg < len(points) and track.promote():
                track.set_next(make_leg(points[leg], points[leg + 1], ARDUCOPTER, SHAPE)
                               if leg + 1 < len(points) else None)
    return reached, body


def test_corners_are_rounded_and_flown_at_arducopters_speed():
    # ArduCopter SITL, 40 m square at 10 m: corners at about 3 m/s, reached 7.0-7.1 s apart,
    # the last leg (no next waypoint) stops 9.2 s after the last corner.
    reached, body = fly_square()
    assert [leg for leg, _, _ in reached] == [1, 2, 3, 4]
    for _, _, speed in reached[:3]:
        assert speed == pytest.approx(3.0, rel=0.1)
    times = [t for _, t, _ in reached]
    for gap in (times[1] - times[0], times[2] - times[1]):
        assert gap == pytest.approx(7.05, rel=0.1)
    assert times[3] - times[2] == pytest.approx(9.2, rel=0.1)
    assert body.position == pytest.approx((0.0, 0.0, 10.0), abs=0.05)
    assert reached[3][2] < 0.05


def test_a_leg_without_a_next_one_stops_on_its_destination():
    track = Track(make_leg((0.0, 0.0, 5.0), (30.0, 0.0, 5.0), ARDUCOPTER, SHAPE), 0.0, 2.0)
    end = track.leg.curve.duration
    assert not track.reached
    track.update(end - DT)
    assert not track.reached
    position, velocity, _ = track.update(end)
    assert track.reached and position == pytest.approx((30.0, 0.0, 5.0))
    assert velocity == pytest.approx((0.0, 0.0, 0.0))
    assert not track.promote()  # nothing to go on with


def test_replanning_at_a_new_speed_keeps_the_position_and_goes_on_to_the_destination():
    track = Track(make_leg((0.0, 0.0, 5.0), (200.0, 0.0, 5.0), ARDUCOPTER, SHAPE), 0.0, 2.0)
    before, speed, _ = track.update(10.0)
    track.replan(Limits(speed=3.0), SHAPE, 10.0)
    after, speed_after, _ = track.update(10.0)
    assert after == pytest.approx(before) and speed_after == pytest.approx(speed)
    time = 10.0
    while not track.reached:
        time += DT
        position, velocity, _ = track.update(time)
        if time > 25.0:
            assert velocity[0] <= 3.0 + 1e-9
    assert position == pytest.approx((200.0, 0.0, 5.0))
