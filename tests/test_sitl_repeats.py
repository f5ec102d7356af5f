"""The simulator answers commands sent again after they were taken as ArduCopter does."""

from __future__ import annotations

import pytest
from command_repeats import ARDUCOPTER, probe

from sitl.server import Simulator


@pytest.mark.timeout(120)
def test_repeated_commands_are_answered_as_arducopter_answers_them() -> None:
    params = {"SIM_GPS_LOCKTIME": 1, "SIM_EKF_GPS_TIME": 2}
    with Simulator(vehicles=1, speedup=10, tcp_base_port=0, params=params) as sim:
        assert probe(f"tcp:127.0.0.1:{sim.tcp_ports[0]}") == ARDUCOPTER
