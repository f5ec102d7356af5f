"""The point-mass multicopter and its battery."""

from __future__ import annotations

import itertools
import math

import pytest

from sitl.physics import Battery, Body, Limits, flight_current

DT = 0.05
LIMITS = Limits(speed=5.0, climb=2.0, descent=1.0, accel=2.0, accel_z=1.0, yaw_rate=90.0)


def fly(body: Body, target: tuple[float, float, float], seconds: float) -> list:
    trace = []
    for _ in range(round(seconds / DT)):
        body.move(body.velocity_toward(target, LIMITS), LIMITS, DT, target=target)
        trace.append((body.position, body.velocity))
    return trace


def test_flies_to_a_target_within_speed_and_acceleration_limits_and_stops_on_it():
    body = Body()
    trace = fly(body, (40.0, 30.0, 10.0), 40.0)
    speeds = [math.hypot(v[0], v[1]) for _, v in trace]
    assert max(speeds) == pytest.approx(5.0, abs=1e-6)
    assert max(abs(b - a) for a, b in itertools.pairwise(speeds)) <= 2.0 * DT + 1e-9
    assert max(v[2] for _, v in trace) <= 2.0 + 1e-9
    assert body.position == pytest.approx((40.0, 30.0, 10.0))
    assert max(math.hypot(p[0], p[1]) for p, _ in trace) < 50.0 + 0.2  # a little coasting


def test_the_demand_brakes_on_a_square_root_curve():
    body = Body()
    for distance in (0.5, 2.0, 8.0):
        vn, _, _ = body.velocity_toward((distance, 0.0, 0.0), LIMITS)
        assert vn == pytest.approx(min(5.0, math.sqrt(2 * 2.0 * distance)))


def test_wind_moves_only_a_body_that_does_not_hold_position():
    held, free = Body(), Body()
    for _ in range(40):
        held.move((0.0, 0.0, 0.0), LIMITS, DT, wind=(0.0, 3.0), hold=True)
        free.move((0.0, 0.0, 0.0), LIMITS, DT, wind=(0.0, 3.0), hold=False)
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
