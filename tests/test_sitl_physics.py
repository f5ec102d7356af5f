"""The point-mass multicopter and its battery."""

from __future__ import annotations

import itertools
import math

import pytest

from sitl.physics import Battery, Body, Limits, flight_current, sqrt_controller, stopping_distance

DT = 0.05  # the model's TICK
LIMITS = Limits(speed=5.0, climb=2.0, descent=1.0, accel=2.0, accel_z=1.0, yaw_rate=90.0)
ARDUCOPTER = Limits()  # WPNAV_SPEED 10, WPNAV_ACCEL 2.5, PSC_JERK_XY 5 m/s³, ...


def fly(body: Body, target: tuple[float, float, float], seconds: float,
        limits: Limits = LIMITS) -> list:
    """(time, position, velocity, acceleration) every tick."""
    trace = []
    for step in range(round(seconds / DT)):
        body.shape(target, limits, DT)
        trace.append(((step + 1) * DT, body.position, body.velocity, body.accel))
    return trace


def first(trace: list, test) -> float:
    return next(t for t, *state in trace if test(*state))


def test_flies_to_a_target_within_speed_acceleration_and_jerk_limits_and_stops_on_it():
    body = Body()
    trace = fly(body, (40.0, 30.0, 10.0), 40.0)
    speeds = [math.hypot(v[0], v[1]) for _, _, v, _ in trace]
    accels = [a for _, _, _, a in trace]
    assert max(speeds) == pytest.approx(5.0, abs=0.05)
    assert max(math.hypot(a[0], a[1]) for a in accels) <= 2.0 + 1e-9
    assert max(math.hypot(b[0] - a[0], b[1] - a[1])
               for a, b in itertools.pairwise(accels)) <= LIMITS.jerk * DT + 1e-9
    assert max(v[2] for _, _, v, _ in trace) <= 2.0 + 1e-3
    assert max(abs(a[2]) for a in accels) <= 1.0 + 1e-9
    assert body.position == pytest.approx((40.0, 30.0, 10.0), abs=1e-3)
    assert max(math.hypot(p[0], p[1]) for _, p, _, _ in trace) < 50.0 + 0.2  # centimetres past


def test_a_guided_move_takes_arducopters_time():
    # ArduCopter SITL, a GUIDED position target (docs/simulator.md): 20 m within 1 m after
    # 5.5 s at up to 5.4 m/s; 100 m within 1 m after 14.2 s at 10 m/s.
    for distance, within, peak in ((20.0, 5.5, 5.4), (100.0, 14.2, 10.0)):
        trace = fly(Body(), (distance, 0.0, 0.0), 30.0, ARDUCOPTER)
        assert first(trace, lambda p, v, a, d=distance: p[0] >= d - 1.0) == pytest.approx(
            within, rel=0.1)
        assert max(v[0] for _, _, v, _ in trace) == pytest.approx(peak, rel=0.05)


def test_the_approach_brakes_on_a_square_root_curve_at_half_the_acceleration():
    # ArduPilot's sqrt_controller: linear near zero, sqrt(2 a (d - a / 2k²)) beyond a / k².
    assert sqrt_controller(0.5, 1.0, 1.25, DT) == pytest.approx(0.5)
    assert sqrt_controller(40.0, 1.0, 1.25, DT) == pytest.approx(math.sqrt(2.5 * (40 - 0.625)))
    assert sqrt_controller(-40.0, 1.0, 1.25, DT) == -sqrt_controller(40.0, 1.0, 1.25, DT)
    assert sqrt_controller(0.01, 100.0, 100.0, DT) == pytest.approx(0.01 / DT)  # never past zero
    # From 10 m/s a GUIDED vehicle starts braking about 40 m out, as ArduCopter does.
    body = Body()
    body.position, body.velocity = (0.0, 0.0, 0.0), (10.0, 0.0, 0.0)
    trace = fly(body, (200.0, 0.0, 0.0), 30.0, ARDUCOPTER)
    braking_from = next(p[0] for _, p, v, _ in trace if v[0] < 9.9)
    assert 200.0 - braking_from == pytest.approx(40.0, rel=0.1)


def test_a_target_behind_a_fast_vehicle_brakes_it_past_the_point_and_brings_it_back():
    # What tml's HOLD does at 10 m/s on ArduCopter SITL: 23.6 m past, back after 13 s.
    body = Body()
    body.velocity = (10.0, 0.0, 0.0)
    trace = fly(body, (0.0, 0.0, 0.0), 20.0, ARDUCOPTER)
    assert max(p[0] for _, p, _, _ in trace) == pytest.approx(23.6, rel=0.1)
    assert first(trace, lambda p, v, a: v[0] < 1.0) == pytest.approx(3.9, rel=0.1)
    assert body.position == pytest.approx((0.0, 0.0, 0.0), abs=0.01)
    assert stopping_distance(10.0, 1.0, 2.5) == pytest.approx(21.25)  # where GUIDED stops
    assert stopping_distance(2.0, 1.0, 2.5) == pytest.approx(2.0)  # slow: linear


def test_a_velocity_demand_is_reached_within_the_limits():
    body = Body()
    for _ in range(round(8.0 / DT)):
        body.shape_velocity((10.0, 0.0, -1.5), ARDUCOPTER, DT)
    assert body.velocity == pytest.approx((10.0, 0.0, -1.5), abs=1e-3)
    assert body.accel == pytest.approx((0.0, 0.0, 0.0), abs=1e-3)


def test_a_landing_descends_at_the_given_rate_over_its_point():
    body = Body()
    body.position = (3.0, 0.0, 10.0)
    for _ in range(round(10.0 / DT)):
        body.shape((0.0, 0.0, 0.0), ARDUCOPTER, DT, climb_rate=-0.5)
    assert body.velocity[2] == pytest.approx(-0.5)
    assert body.position[:2] == pytest.approx((0.0, 0.0), abs=1e-3)
    assert body.position[2] == pytest.approx(10.0 - 0.5 * 10.0, abs=0.3)


def test_wind_moves_only_a_body_that_does_not_hold_position():
    held, free = Body(), Body()
    for _ in range(40):
        held.shape_velocity((0.0, 0.0, 0.0), LIMITS, DT, wind=(0.0, 3.0), hold=True)
        free.shape_velocity((0.0, 0.0, 0.0), LIMITS, DT, wind=(0.0, 3.0), hold=False)
    assert held.position == (0.0, 0.0, 0.0)
    assert free.position[1] == pytest.approx(3.0 * 40 * DT) and free.position[0] == 0.0


def test_turns_the_short_way_at_the_rate_limit():
    body = Body(heading=350.0)
    body.turn(30.0, 90.0, 0.1)
    assert body.heading == pytest.approx(359.0)
    for _ in range(10):
        body.turn(30.0, 90.0, 0.1)
    assert body.heading == pytest.approx(30.0)


def test_battery_charge_voltage_and_failure():
    battery = Battery(capacity_mah=1000.0, full_volts=12.6, cell_capacity_mah=1000.0)
    assert (battery.remaining, battery.voltage) == (100, pytest.approx(12.6))
    battery.drain(360.0, 5.0)  # 5 A for 6 minutes: 500 mAh
    assert battery.consumed_mah == pytest.approx(500.0) and battery.remaining == 50
    resting = Battery(1000.0, cell_capacity_mah=1000.0)
    resting.consumed_mah = 500.0
    assert battery.voltage < resting.voltage < 12.6  # sag under load, and with the charge
    battery.failed = True
    assert battery.remaining == 0 and battery.voltage < Battery.EMPTY_VOLTS


def test_without_a_simulated_pack_the_voltage_holds_and_the_count_goes_past_empty():
    # ArduCopter SITL (SIM_BATT_CAP_AH 0): 12.6 V throughout; mAh consumed count on past
    # BATT_CAPACITY while the percentage stays at 0.
    battery = Battery(capacity_mah=1000.0, full_volts=12.6)
    battery.drain(720.0, 10.0)  # 2000 mAh
    assert battery.voltage == 12.6 and battery.remaining == 0
    assert battery.consumed_mah == pytest.approx(2000.0)


def test_a_charger_refills_at_its_current_until_full_and_not_a_failed_battery():
    battery = Battery(capacity_mah=1000.0)
    battery.consumed_mah = 600.0
    battery.charge(360.0, 5.0)  # 5 A for 6 minutes: 500 mAh back
    assert battery.consumed_mah == pytest.approx(100.0) and battery.remaining == 90
    assert battery.current == pytest.approx(-5.0)
    resting = Battery(1000.0, cell_capacity_mah=1000.0)
    resting.consumed_mah = 100.0
    battery.cell_capacity_mah = 1000.0
    assert battery.voltage > resting.voltage  # the charger lifts the terminal voltage
    battery.charge(360.0, 5.0)  # only 100 mAh were missing
    assert battery.consumed_mah == 0.0 and battery.remaining == 100
    assert battery.current == pytest.approx(-100.0 * 3.6 / 360.0)
    battery.charge(1.0, 5.0)
    assert battery.current == 0.0  # full: the charger stops
    failed = Battery(1000.0)
    failed.consumed_mah = 600.0
    failed.failed = True
    failed.charge(360.0, 5.0)
    assert failed.consumed_mah == 600.0 and failed.current == 0.0


def test_current_is_arducopter_sitls():
    still = (0.0, 0.0, 0.0)
    # Measured on ArduCopter SITL (docs/simulator.md): nothing on the ground, 28.1 A hovering.
    assert flight_current(False, False, still, 0) == flight_current(True, False, still, 0) == 0
    assert flight_current(True, True, still, 0) == pytest.approx(28.1)
    assert flight_current(True, True, (0, 0, 2.5), 0) == pytest.approx(30.5, abs=0.1)
    assert flight_current(True, True, (0, 0, -1.5), 0) == pytest.approx(26.9, abs=0.1)
    assert flight_current(True, True, (5, 0, 0), 0) == pytest.approx(28.3, abs=0.1)
    assert flight_current(True, True, (6, 8, 0), 0) == pytest.approx(30.3, abs=0.1)  # 10 m/s
    assert flight_current(True, True, still, 0) < flight_current(True, True, still, 8)
