"""How a vehicle answers a command sent again after it was taken: one probe, two vehicles.

A ground station whose COMMAND_ACK was lost sends the command again (confirmation 1), and
the vehicle answers the copy by what it is doing now. :func:`probe` plays those repeats to
a vehicle with a bare pymavlink connection and returns each answer; :data:`ARDUCOPTER` is
what ArduCopter SITL (4.7.0-dev) answers, which the simulator must answer too
(tests/test_sitl_repeats.py, tests/interop/test_flip_and_repeats.py).
"""

from __future__ import annotations

import time
from typing import Any

from pymavlink import mavutil

M = mavutil.mavlink
GUIDED, LAND, FLIP = 4, 9, 14

ARDUCOPTER: dict[str, str] = {
    "ARM, armed already": "MAV_RESULT_ACCEPTED",
    "DO_SET_MODE GUIDED, in GUIDED already": "MAV_RESULT_ACCEPTED",
    "NAV_TAKEOFF again at once, still on the ground": "MAV_RESULT_ACCEPTED",
    "NAV_TAKEOFF again, off the ground": "MAV_RESULT_FAILED",
    "DO_SET_HOME here, again": "MAV_RESULT_ACCEPTED",
    "DO_SET_MODE FLIP from GUIDED": "MAV_RESULT_FAILED",
    "NAV_LAND again, landing": "MAV_RESULT_ACCEPTED",
    "DO_SET_MODE LAND again, landing": "MAV_RESULT_ACCEPTED",
    "DISARM, disarmed already": "MAV_RESULT_ACCEPTED",
}
"""Each repeat and ArduCopter's answer (measured; docs/simulator.md)."""


class _Probe:
    def __init__(self, address: str) -> None:
        self.conn = mavutil.mavlink_connection(address, source_system=255,
                                               source_component=190)
        beat = self.conn.wait_heartbeat(timeout=60)
        assert beat is not None, f"no heartbeat from {address}"
        self.target = self.conn.target_system
        self.conn.mav.request_data_stream_send(self.target, 1, M.MAV_DATA_STREAM_ALL, 10, 1)
        self.state: dict[str, Any] = {"mode": None, "armed": False, "altitude": 0.0}

    def _feed(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "HEARTBEAT" and msg.get_srcComponent() == 1 and msg.type != M.MAV_TYPE_GCS:
            self.state["mode"] = msg.custom_mode
            self.state["armed"] = bool(msg.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
        elif kind == "GLOBAL_POSITION_INT":
            self.state["altitude"] = msg.relative_alt / 1000

    def wait(self, seconds: float, until: Any = None) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            msg = self.conn.recv_match(blocking=True, timeout=0.05)
            if msg is not None:
                self._feed(msg)
            if until is not None and until(self.state):
                return True
        return until is None

    def command(self, command: int, *params: float, confirmation: int = 0) -> str:
        values = [*params, *[0.0] * (7 - len(params))]
        self.conn.mav.command_long_send(self.target, 1, command, confirmation, *values)
        end = time.monotonic() + 5.0
        while time.monotonic() < end:
            msg = self.conn.recv_match(blocking=True, timeout=0.05)
            if msg is None:
                continue
            self._feed(msg)
            if msg.get_type() == "COMMAND_ACK" and msg.command == command:
                return M.enums["MAV_RESULT"][msg.result].name
        return "no answer"

    def until_accepted(self, seconds: float, command: int, *params: float) -> None:
        end = time.monotonic() + seconds
        while self.command(command, *params) != "MAV_RESULT_ACCEPTED":
            assert time.monotonic() < end, f"command {command} never accepted"
            self.wait(0.5)


def probe(address: str, boot_timeout: float = 120.0) -> dict[str, str]:
    """Play the repeats of :data:`ARDUCOPTER` to the copter at ``address``; its answers."""
    p = _Probe(address)
    answers: dict[str, str] = {}
    try:
        mode = M.MAV_CMD_DO_SET_MODE
        custom = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        # GUIDED needs the EKF's position; one accepted while ArduCopter still boots is
        # forgotten, so it counts once a HEARTBEAT shows it.
        end = time.monotonic() + boot_timeout
        while not p.wait(2.0, lambda s: s["mode"] == GUIDED):
            assert time.monotonic() < end, "never in GUIDED"
            p.command(mode, custom, GUIDED)
        p.until_accepted(boot_timeout, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        answers["ARM, armed already"] = p.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1,
                                                  confirmation=1)
        answers["DO_SET_MODE GUIDED, in GUIDED already"] = p.command(mode, custom, GUIDED,
                                                                      confirmation=1)
        takeoff = (M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10.0)
        assert p.command(*takeoff) == "MAV_RESULT_ACCEPTED"
        answers["NAV_TAKEOFF again at once, still on the ground"] = p.command(
            *takeoff, confirmation=1)
        assert p.wait(60.0, lambda s: s["altitude"] > 3.0), "never off the ground"
        answers["NAV_TAKEOFF again, off the ground"] = p.command(*takeoff, confirmation=1)
        p.wait(60.0, lambda s: s["altitude"] > 9.0)
        assert p.command(M.MAV_CMD_DO_SET_HOME, 1) == "MAV_RESULT_ACCEPTED"
        answers["DO_SET_HOME here, again"] = p.command(M.MAV_CMD_DO_SET_HOME, 1, confirmation=1)
        answers["DO_SET_MODE FLIP from GUIDED"] = p.command(mode, custom, FLIP)
        assert p.command(M.MAV_CMD_NAV_LAND) == "MAV_RESULT_ACCEPTED"
        answers["NAV_LAND again, landing"] = p.command(M.MAV_CMD_NAV_LAND, confirmation=1)
        answers["DO_SET_MODE LAND again, landing"] = p.command(mode, custom, LAND,
                                                                confirmation=1)
        assert p.wait(120.0, lambda s: not s["armed"]), "never landed and disarmed"
        answers["DISARM, disarmed already"] = p.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                                        confirmation=1)
    finally:
        p.conn.close()
    return answers
