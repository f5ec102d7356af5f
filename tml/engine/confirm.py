"""When an operator's command is done: confirmed by what the vehicle does, not by its mode.

An accepted command and a HEARTBEAT showing its mode say only that the autopilot took it:
a vehicle switched to GUIDED by a hold flies on when another ground station (a run that
does not know) sends it its next target. So a command is *done* only when the vehicle's own
telemetry shows it carried out, read after the command (:attr:`VehicleState.current`), in
the vehicle's own time (its ``time_boot_ms``: the thresholds mean the same at any
simulator speed-up):

- ``hold``: the mode holds (:data:`~tml.engine.safety.COMMAND_SHOWN`) and the ground speed
  stays below :data:`HOLD_SPEED` m/s (and the vertical speed too, in the air) for
  :data:`HOLD_TIME` s; in GUIDED, a target the vehicle reports (POSITION_TARGET_GLOBAL_INT
  or _LOCAL_NED, :class:`Target`) must be a stop as well: a point within
  :data:`HOLD_TARGET` m, a velocity below :data:`HOLD_SPEED`. A fixed-wing cannot stop: its
  hold is shown by the mode kept for :data:`HOLD_TIME` s;
- ``rtl``: an RTL mode, and the vehicle on its way: :data:`HOME_GAIN` m nearer home than it
  was at the command, or within :data:`AT_HOME` m of home (climbing or descending there),
  or on the ground disarmed after an RTL mode was shown (its landing) or at home -- a
  vehicle already on the ground elsewhere did not return;
- ``land``: a landing mode (a fixed-wing's landing sequence in AUTO), and descending:
  :data:`LAND_DROP` m lower than at the command, or on the ground;
- ``disarm``: disarmed (on the ground, for an air vehicle).

:class:`Confirmation` is pure: it is fed states with the vehicle's time, and says whether
the command is done and what it saw.
"""

from __future__ import annotations

from typing import Protocol

from tml.engine.safety import COMMAND_SHOWN, operator_command_shown
from tml.language.kinds import Kind, kind_of
from tml.vehicle import VehicleState

HOLD_SPEED = 0.5
"""m/s: below it, horizontally and vertically, a vehicle holds."""
HOLD_TIME = 3.0
"""Seconds of the vehicle's time a hold must last to be done."""
HOME_GAIN = 1.0
"""Metres nearer home than at the command that show a return under way."""
AT_HOME = 2.0
"""Metres from home (horizontally) within which a returning vehicle is home."""
LAND_DROP = 0.5
"""Metres lower than at the command that show a landing under way."""
HOLD_TARGET = 2.0
"""Metres from the vehicle within which a GUIDED position target it reports is a stop."""


class Target(Protocol):
    """A GUIDED target the vehicle reported after the command
    (:class:`tml.mavlink.targets.GuidedTarget`)."""

    @property
    def distance(self) -> float | None: ...  # m from the vehicle (a position target)

    @property
    def speed(self) -> float | None: ...  # m/s (a velocity target)

    def describe(self) -> str: ...


class Confirmation:
    """Whether telemetry shows an operator's ``command`` carried out (module docstring)."""

    def __init__(self, command: str) -> None:
        self.command = command
        self.start: VehicleState | None = None  # the first current state
        self.still_since: float | None = None  # vehicle time the hold began
        self.last: VehicleState | None = None
        self.fastest = 0.0  # the highest ground speed seen since the command
        self.target: Target | None = None  # the GUIDED target reported since the command
        self.returned = False  # an RTL mode shown since the command

    def see(self, state: VehicleState, vehicle_time: float,
            target: Target | None = None) -> bool:
        """Take one state read at the vehicle's time ``vehicle_time`` (s), with the GUIDED
        target it reported since the command, if any; whether the command is done."""
        if state.link == "lost" or not state.current:
            return False
        self.last = state
        if self.start is None:
            self.start = state
        self.fastest = max(self.fastest, state.ground_speed)
        if target is not None:
            self.target = target
        command = self.command
        if command == "rtl" and state.armed and operator_command_shown(state, command):
            self.returned = True
        if command == "disarm" or not state.armed:
            return operator_command_shown(state, command) and (
                command != "rtl" or self.returned or self._home(state))
        if command == "hold":
            return self._held(state, vehicle_time)
        if not operator_command_shown(state, command):
            return False
        if command == "rtl":
            return self._returning(state)
        return state.landed or state.altitude <= self.start.altitude - LAND_DROP

    def _held(self, state: VehicleState, now: float) -> bool:
        fixed_wing = kind_of(state.vehicle_type) is Kind.FIXED_WING
        still = state.mode in COMMAND_SHOWN["hold"] and (fixed_wing or (
            state.ground_speed < HOLD_SPEED and abs(state.climb) < HOLD_SPEED
            and (state.mode != "GUIDED" or self._target_stops())))
        if not still:
            self.still_since = None
            return False
        if self.still_since is None:
            self.still_since = now
        return now - self.still_since >= HOLD_TIME

    def _target_stops(self) -> bool:
        """Whether the GUIDED target reported, if any, is a stop."""
        target = self.target
        if target is None:
            return True  # none reported (ArduCopter reports none under BRAKE)
        return (target.distance is None or target.distance <= HOLD_TARGET) and \
            (target.speed is None or target.speed < HOLD_SPEED)

    def _returning(self, state: VehicleState) -> bool:
        assert self.start is not None
        distance, was = state.home_distance, self.start.home_distance
        if distance is None:
            return False
        return self._home(state) or (was is not None and distance <= was - HOME_GAIN)

    @staticmethod
    def _home(state: VehicleState) -> bool:
        return state.home_distance is not None and state.home_distance <= AT_HOME

    def seen(self) -> str:
        """What the telemetry showed last, in a few words (for "not confirmed")."""
        state = self.last
        if state is None:
            return "no telemetry after the command"
        armed = "armed" if state.armed else "disarmed"
        where = "on the ground" if state.landed else f"{state.altitude:.1f} m up"
        words = [f"mode {state.mode or '?'}", armed, where,
                 f"ground speed {state.ground_speed:.1f} m/s"]
        if not state.landed:
            words.append(f"climb {state.climb:+.1f} m/s")
        if self.command == "rtl" and state.home_distance is not None:
            words.append(f"{state.home_distance:.0f} m from home")
        if self.command == "hold":
            words.append(f"fastest {self.fastest:.1f} m/s since the command")
            if self.target is not None and state.mode == "GUIDED":
                words.append(self.target.describe())
        return ", ".join(words)

    def criterion(self) -> str:
        """What would confirm the command, in a few words."""
        if self.command == "hold":
            return (f"ground speed below {HOLD_SPEED:g} m/s for {HOLD_TIME:g} s in a "
                    "holding mode")  # (and a GUIDED target reported a stop)
        if self.command == "rtl":
            return f"an RTL mode and {HOME_GAIN:g} m nearer home (or home)"
        if self.command == "land":
            return f"a landing mode and {LAND_DROP:g} m lower (or landed)"
        return "disarmed"
