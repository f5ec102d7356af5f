"""An independent pymavlink ground station flies ``python -m sitl`` as it flies ArduCopter.

The client (tests/interop/ground_station.py, plain pymavlink, none of tml's code) is the one
the interoperability suite flies against ArduCopter SITL: select GUIDED, arm with retries
until accepted, take off, upload three waypoints and an RTL, read them back, AUTO, land. The
simulator runs with its default parameters, ArduCopter's start-up delays included: it
must refuse the arm as ArduCopter does until it can take off, and then fly the same way.
"""

from __future__ import annotations

from interop.ground_station import fly, python_sitl, same_mission


def test_an_independent_ground_station_flies_the_simulator_as_it_flies_arducopter() -> None:
    with python_sitl(speedup=20) as address:
        flight = fly(address, timeout=60.0)
    # Refused until the EKF uses GPS, with ArduCopter's reason; then flown like ArduCopter.
    assert "Arm: Need Position Estimate" in flight.arm_refusals
    assert flight.takeoff_result == 0
    assert same_mission(flight.uploaded, flight.read_back)
    assert flight.reached[:3] == [1, 2, 3]
    assert flight.landed_disarmed
