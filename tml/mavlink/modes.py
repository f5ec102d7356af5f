"""Flight modes by name, chosen from what a vehicle says in its HEARTBEAT.

ArduPilot numbers its modes per vehicle kind (Copter, Plane, Rover, ...) and sends the
number as ``custom_mode``; PX4 packs a main mode and a sub mode into ``custom_mode``. The
tables are pymavlink's (``mavutil.mode_mapping_*`` and ``px4_map``), so they follow upstream.
A mode is set with MAV_CMD_DO_SET_MODE: param1 the base mode flags, param2 the custom (or
PX4 main) mode, param3 the PX4 sub mode.

A mode change is confirmed as ArduPilot confirms it (:class:`ModeChange`): the command's
ACCEPTED, then the vehicle's next HEARTBEAT (1 Hz) showing the new mode -- or, when the ACK
was lost, the telemetry showing the mode (the ``taken`` judgement of
:class:`~tml.mavlink.command.CommandSender`). ArduPilot switches
before it acknowledges, so that HEARTBEAT is the proof; one showing another mode means the
vehicle did not switch, or left the mode at once (a failsafe), and is a refusal. "Next" is
by the autopilot's packet sequence numbers: a HEARTBEAT sent shortly before the ACK that
arrives after it (UDP may reorder) is not taken for the answer. Modes the vehicle leaves by
itself within about a second (ArduCopter's FLIP returns to the mode it started from) may be
over before the next HEARTBEAT, so for them the ACK alone confirms: ArduCopter refuses,
with the ACK, a FLIP it cannot start.
"""

from __future__ import annotations

import types
from collections.abc import Callable

from tml.errors import CommandRejected, VehicleError, VehicleTimeout
from tml.mavlink.codec import mavlink, mavutil
from tml.mavlink.command import (
    RETRIES,
    TIMEOUT,
    Command,
    CommandAck,
    CommandLong,
    CommandSender,
    Heartbeat,
)

PX4: int = mavlink.MAV_AUTOPILOT_PX4
ARDUPILOT: int = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
CONFIRM_TIMEOUT = 3.0
"""Seconds after the ACK within which a HEARTBEAT must show the mode (three heartbeats)."""
STRAGGLER_WINDOW = 32
"""A HEARTBEAT at most this many packets older than the ACK was sent before it."""
SELF_ENDING_MODES = frozenset({"FLIP"})
"""Modes a HEARTBEAT may never show (see the module docstring): confirmed by the ACK."""


def mode_names(vehicle_type: int, autopilot: int) -> list[str]:
    """The mode names a vehicle of this HEARTBEAT type and autopilot understands."""
    if autopilot == PX4:
        return list(mavutil.px4_map)
    table = mavutil.mode_mapping_bynumber(vehicle_type) or {}
    return list(table.values())


def mode_name(vehicle_type: int, autopilot: int, base_mode: int, custom_mode: int) -> str:
    """The name of the mode a HEARTBEAT reports (``Mode(<n>)`` when unknown)."""
    if autopilot == PX4:
        return str(mavutil.interpret_px4_mode(base_mode, custom_mode))
    table: dict[int, str] = mavutil.mode_mapping_bynumber(vehicle_type) or {}
    return table.get(custom_mode, f"Mode({custom_mode})")


def set_mode_command(vehicle_type: int, autopilot: int, name: str,
                     system_id: int | None = None) -> CommandLong:
    """The DO_SET_MODE command that selects mode ``name`` (case-insensitive)."""
    wanted = name.upper()
    if autopilot == PX4:
        if wanted in mavutil.px4_map:
            base, main, sub = mavutil.px4_map[wanted]
            return CommandLong(mavlink.MAV_CMD_DO_SET_MODE, base, main, sub)
    else:
        table = mavutil.mode_mapping_byname(vehicle_type) or {}
        if wanted in table:
            return CommandLong(mavlink.MAV_CMD_DO_SET_MODE,
                               mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, table[wanted])
    known = ", ".join(mode_names(vehicle_type, autopilot)) or "none known"
    raise VehicleError(f"no flight mode {name!r} for this vehicle (modes: {known})", system_id)


def commanded_mode(vehicle_type: int, autopilot: int, command: CommandLong) -> str:
    """The name of the mode a DO_SET_MODE ``command`` selects (the inverse of
    :func:`set_mode_command`)."""
    base, custom = round(command.param1), round(command.param2)
    if autopilot == PX4:
        custom = (custom << 16) | (round(command.param3) << 24)
    return mode_name(vehicle_type, autopilot, base, custom)


FOLLOWS: dict[str, frozenset[str]] = {
    "FLIP": frozenset({"ALT_HOLD", "STABILIZE", "ACRO"}),  # ArduCopter, back where it began
}
"""Modes an autopilot enters by itself as the end of a mode tml asked for: not taken."""
FIXED_WING_FOLLOWS: dict[str, frozenset[str]] = {
    **FOLLOWS, "AUTO": frozenset({"RTL"}),  # ArduPlane at the end of its mission
}
"""The same for a fixed-wing. An ArduCopter ends its mission in AUTO (its RTL item is flown
in AUTO): AUTO to RTL there is a failsafe (a fence breached, a battery low), not an end."""


AGREE = 0.9
"""Seconds over which the autopilot's HEARTBEATs must all show a mode nobody here asked for
before the vehicle counts as taken: two of ArduPilot's 1 Hz HEARTBEATs in a row."""


class ModeWatch:
    """Tells a mode change nobody on this side asked for: the autopilot's own (an EKF, GPS
    or battery failsafe landing), a pilot's RC switch, another ground station.

    Sans-IO: :meth:`ask` before each mode change is sent (:meth:`refused` if it failed),
    :meth:`seen` with each autopilot HEARTBEAT's mode and the time it came. A vehicle is
    *taken* when, armed, after the mode asked was shown, the HEARTBEATs show another mode
    that does not follow it (:data:`FOLLOWS`, :data:`FIXED_WING_FOLLOWS` for a
    ``fixed_wing``), all of them for :data:`AGREE` s: one stray
    or forged HEARTBEAT (without signing any client on the link can send one as the
    autopilot) is answered by the real one's next, and believes nothing. ``taken`` then
    keeps that mode. Before the first ask the vehicle's mode is its own (on the ground,
    before the mission), and while an asked mode is not shown yet the old one is still
    expected.
    """

    def __init__(self, fixed_wing: bool = False) -> None:
        self.follows = FIXED_WING_FOLLOWS if fixed_wing else FOLLOWS
        self.asked: str | None = None
        self.confirmed = False
        self.taken = ""
        self.since: tuple[str, float] | None = None  # another mode shown, from when
        self._before: tuple[str | None, bool] = (None, False)

    def ask(self, mode: str) -> None:
        """The mode about to be asked for."""
        self._before = (self.asked, self.confirmed)
        self.asked, self.confirmed, self.since = mode.upper(), False, None

    def adopt(self, mode: str) -> None:
        """The vehicle is flown in ``mode`` as it is, with nothing asked on this link yet:
        a resumed or continued run takes it up in the GUIDED the interrupted run left it
        in. That mode is expected from now on, as if asked and shown, so that another's
        switch is told as a take-over (rather than overridden by the next request)."""
        if self.asked is None:
            self.asked, self.confirmed, self.since = mode.upper(), True, None

    def refused(self) -> None:
        """The last ask failed: the mode asked before is still the one expected."""
        self.asked, self.confirmed = self._before

    def seen(self, mode: str, armed: bool, now: float) -> bool:
        """A HEARTBEAT shows ``mode`` at ``now``; True when that makes the vehicle taken."""
        if self.taken or self.asked is None:
            return False
        if mode == self.asked or mode in self.follows.get(self.asked, ()):
            self.confirmed, self.since = True, None
            return False
        if not (self.confirmed and armed):
            return False
        if self.since is None or self.since[0] != mode:
            self.since = (mode, now)
            return False
        if now - self.since[1] >= AGREE:
            self.taken = mode
            return True
        return False


class ModeChange:
    """DO_SET_MODE to mode ``name``, done once the vehicle's next HEARTBEAT shows the mode.

    (Or once accepted, for the SELF_ENDING_MODES.)

    A sans-IO machine like :class:`~tml.mavlink.command.CommandSender` (which it drives for
    the command itself), fed COMMAND_ACKs and the autopilot's HEARTBEATs. ``error`` is the
    sender's for a refused or unanswered command, :class:`~tml.errors.CommandRejected` when
    the HEARTBEAT after the ACK shows another mode, :class:`~tml.errors.VehicleTimeout` when
    no HEARTBEAT comes within ``confirm_timeout`` of the ACK.
    """

    inputs: type | types.UnionType = CommandAck | Heartbeat

    def __init__(self, command: CommandLong, name: str, *, system_id: int | None = None,
                 timeout: float = TIMEOUT, retries: int = RETRIES,
                 confirm_timeout: float = CONFIRM_TIMEOUT,
                 taken: Callable[[], bool] | None = None) -> None:
        self.sender = CommandSender(command, "MAV_CMD_DO_SET_MODE", system_id=system_id,
                                    timeout=timeout, retries=retries, taken=taken)
        self.mode = name.upper()
        self.system_id = system_id
        self.confirm_timeout = confirm_timeout
        self.shown: str | None = None
        """The mode the HEARTBEAT after the ACK showed (None until it came)."""
        self.timed_out = False
        self._ack_seq: int | None = None
        self._confirm_by = float("inf")

    @property
    def deadline(self) -> float:
        """When :meth:`tick` is next due."""
        return self._confirm_by if self.sender.accepted else self.sender.deadline

    @property
    def done(self) -> bool:
        """True once the mode is confirmed or the change failed."""
        if not self.sender.accepted or self.mode in SELF_ENDING_MODES \
                or self.sender.by_telemetry:
            return self.sender.done
        return self.shown is not None or self.timed_out

    @property
    def error(self) -> VehicleError | None:
        """The exception this outcome amounts to, or None if confirmed or still running."""
        if not self.sender.accepted or self.mode in SELF_ENDING_MODES \
                or self.sender.by_telemetry:
            return self.sender.error
        if self.timed_out:
            return VehicleTimeout(f"{self.sender.name}: {self.mode} accepted, but no HEARTBEAT "
                                  f"within {self.confirm_timeout:g} s", self.system_id)
        if self.shown is not None and self.shown != self.mode:
            return CommandRejected(self.sender.name, f"ACCEPTED, but the next HEARTBEAT shows "
                                   f"{self.shown}, not {self.mode}", self.system_id)
        return None

    def start(self, now: float) -> list[Command]:
        """The first transmission of the command."""
        return self.sender.start(now)

    def receive(self, msg: CommandAck | Heartbeat, now: float) -> list[Command]:
        """Feed a COMMAND_ACK or an autopilot HEARTBEAT."""
        if isinstance(msg, CommandAck):
            waiting = not self.sender.done
            self.sender.receive(msg, now)
            if waiting and self.sender.accepted:
                self._ack_seq = msg.packet_seq
                self._confirm_by = now + self.confirm_timeout
        elif self.sender.accepted and not self.done and not self._straggler(msg):
            self.shown = mode_name(msg.vehicle_type, msg.autopilot, msg.base_mode,
                                   msg.custom_mode)
            self._confirm_by = float("inf")
        return []

    def tick(self, now: float) -> list[Command]:
        """Retransmit the command, or give up waiting for the HEARTBEAT."""
        if not self.sender.done:
            return self.sender.tick(now)
        if self.sender.accepted and not self.done and now >= self._confirm_by:
            self.timed_out = True
            self._confirm_by = float("inf")
        return []

    def _straggler(self, beat: Heartbeat) -> bool:
        # Sent before the ACK, overtaken by it: sequence numbers wrap at 256.
        if self._ack_seq is None or beat.packet_seq is None:
            return False
        return 0 < (self._ack_seq - beat.packet_seq) % 256 <= STRAGGLER_WINDOW
