"""``tml command`` on ArduPilot SITL: a flying ArduCopter refused a disarm, held, and
returned until it lands and disarms; an armed Rover refused a landing, held, and disarmed.

A plain pymavlink ground station on the vehicle's second port (SERIAL1) arms and flies it
and judges what it did; ``tml command`` runs in a child process on SERIAL0, as an operator
would run it.
"""

from __future__ import annotations

import subprocess
import sys

import pytest
from pymavlink import mavutil
from test_plane_rover import Station

M = mavutil.mavlink


def tml_command(address: str, command: str) -> tuple[int, str]:
    """``tml command COMMAND --connect ADDRESS``: its exit code and what it said."""
    done = subprocess.run([sys.executable, "-m", "tml", "command", command, "--connect",
                           address, "--timeout", "60"], capture_output=True, text=True,
                          timeout=300)
    return done.returncode, done.stdout + done.stderr


@pytest.mark.timeout(900)
def test_arducopter_refuses_no_disarm_in_the_air_holds_and_returns(ardupilot) -> None:
    (sitl,) = ardupilot(params={"FS_GCS_ENABLE": 0})
    gcs = Station(sitl.companion_address)
    try:
        gcs.ready()
        assert gcs.set_mode("GUIDED") == M.MAV_RESULT_ACCEPTED
        gcs.arm()
        assert gcs.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10) == \
            M.MAV_RESULT_ACCEPTED
        gcs.wait("10 m up", lambda s: s.local()[2] > 9.0, 60)

        code, said = tml_command(sitl.address, "disarm")
        assert code == 2 and "disarm refused: the vehicle is flying" in said, said
        gcs.pump(1.0)
        assert gcs.armed() and gcs.local()[2] > 8.0, "it flies on"

        code, said = tml_command(sitl.address, "hold")
        assert code == 0 and "hold done: mode BRAKE, armed" in said, said

        code, said = tml_command(sitl.address, "rtl")
        assert code == 0 and "rtl done: mode RTL, armed" in said, said
        gcs.wait("RTL", lambda s: s.mode() == "RTL", 10)
        gcs.wait("landed and disarmed", lambda s: not s.armed(), 180)
        assert gcs.local()[2] < 1.0
    finally:
        gcs.close()


@pytest.mark.timeout(900)
def test_ardurover_is_refused_a_landing_holds_and_disarms(ardupilot) -> None:
    (sitl,) = ardupilot(vehicle="rover", params={"FS_GCS_ENABLE": 0})
    gcs = Station(sitl.companion_address)
    try:
        gcs.ready()
        assert gcs.set_mode("GUIDED") == M.MAV_RESULT_ACCEPTED
        gcs.arm()

        code, said = tml_command(sitl.address, "land")
        assert code == 2 and "a ground vehicle does not land" in said, said

        code, said = tml_command(sitl.address, "hold")
        assert code == 0 and "hold done: mode HOLD, armed" in said, said
        gcs.wait("HOLD", lambda s: s.mode() == "HOLD", 10)

        code, said = tml_command(sitl.address, "disarm")
        assert code == 0 and "disarm done: mode HOLD, disarmed" in said, said
        gcs.wait("disarmed", lambda s: not s.armed(), 10)
    finally:
        gcs.close()
