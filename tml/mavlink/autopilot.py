"""A handle on one vehicle of a :class:`~tml.mavlink.link.Link`: commands and missions.

Every method builds plain messages (``command``, ``mission``, ``modes``), lets the link
drive the sans-IO machine, and turns the outcome into the error hierarchy at one place
(:meth:`Autopilot.command`, :meth:`Autopilot.upload`): a refusal is CommandRejected or
MissionTransferError naming the result, silence is VehicleTimeout, a vehicle that stops
sending HEARTBEATs is LinkLost. Methods return when the vehicle has *acknowledged*; that it
then flies where it was told is watched from telemetry -- except a mode change, which is
done only when a HEARTBEAT shows the new mode (:class:`~tml.mavlink.modes.ModeChange`).

A command whose ACK was lost is sent again, and the vehicle may refuse the copy because it
took the first one (ArduCopter refuses NAV_TAKEOFF once it is off the ground). :data:`TAKEN`
says, per command, what in the telemetry shows the command taken; :meth:`Autopilot.command`
hands that judgement to the command sender, which then neither repeats a command the vehicle
is seen carrying out nor takes a refused repeat of it for a refusal.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TypeVar

from tml.errors import CommandRejected, MissionTransferError, VehicleTimeout
from tml.mavlink import codec
from tml.mavlink.codec import mavlink
from tml.mavlink.command import Command, CommandInt, CommandLong, CommandResult, CommandSender
from tml.mavlink.link import Link, VehicleInfo
from tml.mavlink.mission import (
    Clear,
    Download,
    ItemDifference,
    ItemForm,
    MissionItem,
    MissionType,
    Progress,
    Transfer,
    Upload,
    ardupilot_form,
    exact_form,
    read_back_differences,
    with_home_placeholder,
)
from tml.mavlink.modes import (
    ARDUPILOT,
    CONFIRM_TIMEOUT,
    ModeChange,
    commanded_mode,
    set_mode_command,
)
from tml.mavlink.steps import Exchange, Steps
from tml.mavlink.telemetry import Telemetry

T = TypeVar("T")

DEFAULT_RATES = {
    "HEARTBEAT": 1.0, "GLOBAL_POSITION_INT": 10.0,
    "ATTITUDE": 10.0, "SYS_STATUS": 2.0, "EXTENDED_SYS_STATE": 2.0, "GPS_RAW_INT": 2.0,
    "EKF_STATUS_REPORT": 2.0, "MISSION_CURRENT": 2.0, "HOME_POSITION": 0.5,
}
"""Messages and rates (Hz) :meth:`Autopilot.request_rates` asks for by default: what a
vehicle's state is built from, and nothing else (every message costs each vehicle's link
its parsing; LOCAL_POSITION_NED is not asked for: the local frame comes from
GLOBAL_POSITION_INT and HOME_POSITION)."""
FORCE = 21196.0
"""The magic param2 of COMPONENT_ARM_DISARM that skips the pre-arm checks."""
SHOWN_DIFFERENCES = 3
"""How many read-back differences a MISMATCH error names (it counts the others)."""


TAKEOFF_RISE = 0.5
"""Metres of climb since a NAV_TAKEOFF was first sent that show it taken."""
CLIMBING = 0.3
"""m/s upwards that show a NAV_TAKEOFF taken."""

TakenRule = Callable[[Command, Telemetry, Telemetry], bool]
"""``rule(command, before, now)``: whether telemetry ``now`` shows ``command`` carried out,
``before`` being the snapshot when it was first sent."""


def _armed_as_asked(command: Command, before: Telemetry, now: Telemetry) -> bool:
    # Seen at all since the command went out: ArduCopter disarms by itself DISARM_DELAY
    # (10 s) after arming on the ground, only 1 s of wall time at a speed-up of 10.
    seen = now.armed_at if command.param1 >= 0.5 else now.disarmed_at
    return seen is not None and seen > before.time


def _off_the_ground(command: Command, before: Telemetry, now: Telemetry) -> bool:
    def up(t: Telemetry) -> float:
        return t.position.relative_altitude if t.position is not None else 0.0

    lifted = before.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND and now.landed_state in (
        mavlink.MAV_LANDED_STATE_IN_AIR, mavlink.MAV_LANDED_STATE_TAKEOFF)
    climbing = now.velocity is not None and -now.velocity[2] > CLIMBING
    return now.armed and (lifted or climbing or up(now) - up(before) > TAKEOFF_RISE)


def _mission_running(command: Command, before: Telemetry, now: Telemetry) -> bool:
    # A repeated MISSION_START with a first item restarts the mission from that item.
    moved = now.mission_current != before.mission_current \
        or len(now.items_reached) > len(before.items_reached)
    return now.mode == "AUTO" and (moved or _off_the_ground(command, before, now))


def _landing(command: Command, before: Telemetry, now: Telemetry) -> bool:
    return now.mode == "LAND" or now.landed_state == mavlink.MAV_LANDED_STATE_LANDING


def _returning(command: Command, before: Telemetry, now: Telemetry) -> bool:
    return now.mode == "RTL"


def _home_moved(command: Command, before: Telemetry, now: Telemetry) -> bool:
    return now.home is not None and now.home != before.home


def _mode_set(command: Command, before: Telemetry, now: Telemetry) -> bool:
    if now.vehicle_type is None or now.autopilot is None or not isinstance(command, CommandLong):
        return False
    mode = commanded_mode(now.vehicle_type, now.autopilot, command)
    # A FLIP is over in about a second: its HEARTBEAT may be lost, its roll is not.
    flipped = mode == "FLIP" and now.tilted_at is not None and now.tilted_at > before.time
    return flipped or now.mode_shown_since(mode, before.time)


def _current_item(command: Command, before: Telemetry, now: Telemetry) -> bool:
    return now.mission_current == round(command.param1)


TAKEN: dict[int, TakenRule] = {
    mavlink.MAV_CMD_COMPONENT_ARM_DISARM: _armed_as_asked,  # already armed / disarmed
    mavlink.MAV_CMD_NAV_TAKEOFF: _off_the_ground,  # off the ground, climbing, higher
    mavlink.MAV_CMD_NAV_LAND: _landing,  # in LAND, or landing
    mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH: _returning,  # in RTL
    mavlink.MAV_CMD_DO_SET_HOME: _home_moved,  # HOME_POSITION moved
    mavlink.MAV_CMD_DO_SET_MODE: _mode_set,  # a HEARTBEAT showed the mode (a FLIP: or a roll)
    mavlink.MAV_CMD_DO_SET_MISSION_CURRENT: _current_item,  # MISSION_CURRENT shows the item
    mavlink.MAV_CMD_MISSION_START: _mission_running,  # AUTO, and the mission moves on
}
"""What in the telemetry shows each command carried out, for a retransmission whose first ACK
was lost (see the module docstring). Commands left out (speed, yaw, message rates ...) are
answered alike however often they come, so their ACK is enough."""


class Autopilot:
    """Commands and mission transfers for the vehicle ``info`` on ``link``.

    ``mode_timeout``: seconds after a mode change's ACK within which a HEARTBEAT must show
    the new mode.
    """

    def __init__(self, link: Link, info: VehicleInfo, *, command_timeout: float = 1.5,
                 command_retries: int = 5, mode_timeout: float = CONFIRM_TIMEOUT) -> None:
        self.link = link
        self.info = info
        self.command_timeout = command_timeout
        self.command_retries = command_retries
        self.mode_timeout = mode_timeout
        self.system_id = info.system_id
        self.component_id = info.component_id

    @classmethod
    def connect(cls, link: Link, system_id: int | None = None, timeout: float = 10.0
                ) -> Autopilot:
        """Wait for the vehicle's HEARTBEAT on ``link`` and return its handle."""
        return cls(link, link.wait_vehicle(system_id, timeout))

    @property
    def telemetry(self) -> Telemetry:
        """The latest telemetry snapshot."""
        return self.link.telemetry(self.system_id)

    # -- commands ---------------------------------------------------------------------

    def do(self, steps: Steps[T]) -> T:
        """Carry out ``steps`` (one of the ``*ing`` methods) on this thread, waiting."""
        return self.link.drive(steps, self.system_id, self.component_id)

    def commanding(self, command: Command) -> Steps[None]:
        """Send ``command`` until acknowledged (or, ACK lost, seen taken: :data:`TAKEN`).

        Raises CommandRejected, VehicleTimeout, or LinkLost when the vehicle is lost.
        """
        yield from _exchanging(CommandSender(
            command, codec.command_name(command.command), system_id=self.system_id,
            timeout=self.command_timeout, retries=self.command_retries,
            taken=self._taken(command)))

    def command(self, command: Command) -> None:
        """:meth:`commanding`, waited for."""
        self.do(self.commanding(command))

    def _taken(self, command: Command) -> Callable[[], bool] | None:
        """The judgement of :data:`TAKEN` for ``command``, from the snapshot as it is now."""
        rule = TAKEN.get(command.command)
        if rule is None:
            return None
        before = self.telemetry
        return lambda: rule(command, before, self.telemetry)

    def switching(self, name: str) -> Steps[None]:
        """Switch to flight mode ``name`` (e.g. GUIDED, AUTO, LAND, RTL for ArduCopter).

        Over once the ACK and then the next HEARTBEAT confirm it; a HEARTBEAT showing
        another mode is CommandRejected, none within ``mode_timeout`` VehicleTimeout.
        """
        command = set_mode_command(self.info.vehicle_type, self.info.autopilot, name,
                                   self.system_id)
        yield from _exchanging(ModeChange(
            command, name, system_id=self.system_id, timeout=self.command_timeout,
            retries=self.command_retries, confirm_timeout=self.mode_timeout,
            taken=self._taken(command)))

    def set_mode(self, name: str) -> None:
        """:meth:`switching`, waited for."""
        self.do(self.switching(name))

    def arm(self, force: bool = False) -> None:
        """Arm the motors (``force`` skips the pre-arm checks)."""
        self.command(arm_command(force))

    def disarm(self, force: bool = False) -> None:
        """Disarm the motors (``force`` also in flight)."""
        self.command(disarm_command(force))

    def takeoff(self, altitude: float) -> None:
        """Take off to ``altitude`` metres above home (GUIDED, armed)."""
        self.command(takeoff_command(altitude))

    def land(self) -> None:
        """Land where the vehicle is."""
        self.command(LAND)

    def return_to_launch(self) -> None:
        """Fly home and land (RTL)."""
        self.command(RETURN_TO_LAUNCH)

    def change_speed(self, speed: float, ground: bool = True) -> None:
        """Set the horizontal speed in m/s (ground speed, or airspeed with ground=False)."""
        self.command(speed_command(speed, ground))

    def yaw(self, heading: float, rate: float = 0.0, relative: bool = False,
            clockwise: bool | None = None) -> None:
        """Turn as :func:`yaw_command` says."""
        self.command(yaw_command(heading, rate, relative, clockwise))

    def reposition(self, latitude: float, longitude: float, altitude: float,
                   speed: float = -1, radius: float = 0.0) -> None:
        """Fly to a point in GUIDED with DO_REPOSITION (:func:`reposition_command`)."""
        self.command(reposition_command(latitude, longitude, altitude, speed, radius))

    def position_target(self, latitude: float, longitude: float, altitude: float,
                        yaw: float | None = None) -> None:
        """Stream a GUIDED position target (SET_POSITION_TARGET_GLOBAL_INT; not acknowledged).

        ``yaw`` in degrees from north; None keeps the vehicle's own choice.
        """
        self.link.send(codec.position_target(
            self.system_id, self.component_id, round(latitude * 1e7), round(longitude * 1e7),
            altitude, None if yaw is None else math.radians(yaw)))

    def stop_target(self, yaw: float | None = None) -> None:
        """Stream a GUIDED velocity target of zero: brake and hold where that ends
        (SET_POSITION_TARGET_LOCAL_NED; not acknowledged). ``yaw`` as for position_target."""
        self.link.send(codec.stop_target(self.system_id, self.component_id,
                                         None if yaw is None else math.radians(yaw)))

    def set_home(self, latitude: float | None = None, longitude: float | None = None,
                 altitude: float = 0.0) -> None:
        """Set home to a point (altitude above mean sea level), or to here if none given."""
        self.command(set_home_command(latitude, longitude, altitude))

    def start_mission(self, first: int = 0, last: int = 0) -> None:
        """Start the uploaded mission (MISSION_START; ArduPilot needs AUTO and arming, and
        DENIES any ``first`` or ``last`` but 0: make the first item current instead)."""
        self.command(start_command(first, last))

    def set_current(self, seq: int) -> None:
        """Make mission item ``seq`` the one flown next."""
        self.command(current_command(seq))

    def take_photo(self) -> None:
        """Trigger the camera once (DO_DIGICAM_CONTROL shoot)."""
        self.command(PHOTO)

    def gripper(self, grab: bool, instance: int = 1) -> None:
        """Close (``grab``) or open the gripper."""
        self.command(gripper_command(grab, instance))

    def request_rates(self, rates: dict[str, float] | None = None) -> bool:
        """Ask for messages at rates (Hz) with SET_MESSAGE_INTERVAL.

        Falls back to REQUEST_DATA_STREAM at the highest rate asked for when the vehicle
        does not support the command; returns whether SET_MESSAGE_INTERVAL was used.
        """
        rates = DEFAULT_RATES if rates is None else rates
        fallback = (CommandResult.MAV_RESULT_UNSUPPORTED.name, CommandResult.MAV_RESULT_DENIED.name)
        try:
            for name, hz in rates.items():
                try:
                    self.command(_interval_command(name, hz))
                except VehicleTimeout:
                    continue  # lost on the way: asked again when the stream stays away
        except CommandRejected as error:
            if error.result not in fallback:
                raise
            top = max(rates.values(), default=1.0)
            self.link.send(codec.request_data_stream(self.system_id, self.component_id,
                                                     max(1, round(top))))
            return False
        return True

    def ask_again(self, name: str, hz: float) -> None:
        """Ask for message ``name`` at ``hz`` once more, without waiting for the answer."""
        self.link.send(_interval_command(name, hz), self.system_id, self.component_id)

    def request_message(self, name: str) -> None:
        """Ask for one message ``name`` now (MAV_CMD_REQUEST_MESSAGE), without waiting."""
        self.link.send(CommandLong(mavlink.MAV_CMD_REQUEST_MESSAGE,
                                   getattr(mavlink, f"MAVLINK_MSG_ID_{name}")),
                       self.system_id, self.component_id)

    # -- missions ---------------------------------------------------------------------

    @property
    def keeps_home_in_item_zero(self) -> bool:
        """ArduPilot stores home as mission item 0; PX4 does not."""
        return self.info.autopilot == ARDUPILOT

    @property
    def stored_form(self) -> ItemForm:
        """How this vehicle reads items back: ArduPilot's storage rules, else as sent."""
        return ardupilot_form if self.keeps_home_in_item_zero else exact_form

    def uploading(self, items: list[MissionItem], mission_type: int = MissionType.MISSION, *,
                  verify: bool = True, on_progress: Callable[[Progress], None] | None = None
                  ) -> Steps[list[MissionItem]]:
        """Upload ``items`` (seq 0..N-1) and, with ``verify``, read them back and compare.

        On ArduPilot a mission's items go to seq 1..N behind a home placeholder, and the
        read-back is compared by ArduPilot's storage rules (:func:`ardupilot_form`); other
        autopilots must give back what they were sent. An upload whose final ACK was lost
        is settled by reading it back, ``verify`` or not. A difference is a
        MissionTransferError (result ``MISMATCH``) naming the items, fields and values.
        Returns the items as sent.
        """
        skip_home = mission_type == MissionType.MISSION and self.keeps_home_in_item_zero
        sent = with_home_placeholder(items) if skip_home else list(items)
        upload = Upload(sent, mission_type, system_id=self.system_id)
        yield from self._transferring(upload, on_progress, raise_error=_lost_for_good)
        if verify or upload.unconfirmed:
            yield from self.reading_back(sent, mission_type)
        return sent

    def upload(self, items: list[MissionItem], mission_type: int = MissionType.MISSION, *,
               verify: bool = True, on_progress: Callable[[Progress], None] | None = None
               ) -> list[MissionItem]:
        """:meth:`uploading`, waited for."""
        return self.do(self.uploading(items, mission_type, verify=verify,
                                      on_progress=on_progress))

    def reading_back(self, sent: list[MissionItem],
                     mission_type: int = MissionType.MISSION) -> Steps[None]:
        """Read the vehicle's items back and compare them with ``sent`` (as :meth:`upload`
        returned them) by this vehicle's storage rules; a difference is a
        MissionTransferError (result ``MISMATCH``) naming the items, fields and values."""
        read_back = yield from self.downloading(mission_type)
        skip_home = mission_type == MissionType.MISSION and self.keeps_home_in_item_zero
        differences = read_back_differences(sent, read_back, self.stored_form,
                                            skip_home=skip_home)
        if differences:
            raise MissionTransferError(
                f"{MissionType(mission_type).name.lower()} read back differs from the "
                f"upload: {_describe(differences)}", "MISMATCH", self.system_id)

    def check_read_back(self, sent: list[MissionItem],
                        mission_type: int = MissionType.MISSION) -> None:
        """:meth:`reading_back`, waited for."""
        self.do(self.reading_back(sent, mission_type))

    def downloading(self, mission_type: int = MissionType.MISSION
                    ) -> Steps[list[MissionItem]]:
        """The vehicle's items of ``mission_type`` (ArduPilot's home included as item 0)."""
        download = Download(mission_type, system_id=self.system_id)
        yield from self._transferring(download)
        return download.items

    def download(self, mission_type: int = MissionType.MISSION) -> list[MissionItem]:
        """:meth:`downloading`, waited for."""
        return self.do(self.downloading(mission_type))

    def clear(self, mission_type: int = MissionType.MISSION) -> None:
        """Delete the vehicle's items of ``mission_type``."""
        self.do(self._transferring(Clear(mission_type, system_id=self.system_id)))

    def _transferring(self, transfer: Transfer,
                      on_progress: Callable[[Progress], None] | None = None, *,
                      raise_error: Callable[[Transfer], bool] = lambda _: True
                      ) -> Steps[None]:
        report = None if on_progress is None else (
            lambda machine: on_progress(transfer.progress))
        yield Exchange(transfer, report)
        if transfer.error is not None and raise_error(transfer):
            raise transfer.error


# -- the commands, built (Autopilot's methods send them; a procedure yields them) ----------

def arm_command(force: bool = False) -> CommandLong:
    """COMPONENT_ARM_DISARM arming (``force`` skips the pre-arm checks)."""
    return CommandLong(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, FORCE if force else 0)


def disarm_command(force: bool = False) -> CommandLong:
    """COMPONENT_ARM_DISARM disarming (``force`` also in flight)."""
    return CommandLong(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, FORCE if force else 0)


def takeoff_command(altitude: float) -> CommandLong:
    """NAV_TAKEOFF to ``altitude`` metres above home (GUIDED, armed)."""
    return CommandLong(mavlink.MAV_CMD_NAV_TAKEOFF, param7=altitude)


LAND = CommandLong(mavlink.MAV_CMD_NAV_LAND)
"""NAV_LAND where the vehicle is."""
RETURN_TO_LAUNCH = CommandLong(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)
"""NAV_RETURN_TO_LAUNCH: fly home and land (RTL)."""
PHOTO = CommandLong(mavlink.MAV_CMD_DO_DIGICAM_CONTROL, param5=1)
"""DO_DIGICAM_CONTROL shoot: the camera triggered once."""


def speed_command(speed: float, ground: bool = True) -> CommandLong:
    """DO_CHANGE_SPEED, m/s: ground speed, or airspeed with ``ground`` False."""
    return CommandLong(mavlink.MAV_CMD_DO_CHANGE_SPEED, 1 if ground else 0, speed, -1)


def yaw_command(heading: float, rate: float = 0.0, relative: bool = False,
                clockwise: bool | None = None) -> CommandLong:
    """CONDITION_YAW to ``heading`` degrees (from north, or by that much with
    ``relative``): ``clockwise`` or not, or the shorter way (None).

    ArduCopter keeps to a direction given even for a heading from north: told clockwise
    from 90 to 45 degrees, it turns 315 degrees (AutoYaw::set_fixed_yaw)."""
    direction = 0 if clockwise is None else 1 if clockwise else -1
    return CommandLong(mavlink.MAV_CMD_CONDITION_YAW, heading, rate, direction,
                       1 if relative else 0)


def reposition_command(latitude: float, longitude: float, altitude: float,
                       speed: float = -1, radius: float = 0.0) -> CommandInt:
    """DO_REPOSITION to a point (altitude above home), entering GUIDED.

    ``radius`` (m, 0: the vehicle's default) is the circle ArduPlane loiters on there,
    clockwise (param4, the yaw, left NaN: ArduPlane reads it as clockwise).
    """
    return CommandInt(mavlink.MAV_CMD_DO_REPOSITION, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                      speed, mavlink.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, radius, math.nan,
                      round(latitude * 1e7), round(longitude * 1e7), altitude)


def set_home_command(latitude: float | None = None, longitude: float | None = None,
                     altitude: float = 0.0) -> Command:
    """DO_SET_HOME to a point (altitude above mean sea level), or to here if none given."""
    if latitude is None or longitude is None:
        return CommandLong(mavlink.MAV_CMD_DO_SET_HOME, 1)
    return CommandInt(mavlink.MAV_CMD_DO_SET_HOME, mavlink.MAV_FRAME_GLOBAL_INT, 0,
                      x=round(latitude * 1e7), y=round(longitude * 1e7), z=altitude)


def start_command(first: int = 0, last: int = 0) -> CommandLong:
    """MISSION_START (ArduPilot DENIES any ``first`` or ``last`` but 0)."""
    return CommandLong(mavlink.MAV_CMD_MISSION_START, first, last)


def current_command(seq: int) -> CommandLong:
    """DO_SET_MISSION_CURRENT: mission item ``seq`` flown next."""
    return CommandLong(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, seq)


def gripper_command(grab: bool, instance: int = 1) -> CommandLong:
    """DO_GRIPPER: close (``grab``) or open."""
    action = mavlink.GRIPPER_ACTION_GRAB if grab else mavlink.GRIPPER_ACTION_RELEASE
    return CommandLong(mavlink.MAV_CMD_DO_GRIPPER, instance, action)

def _exchanging(machine: CommandSender | ModeChange) -> Steps[None]:
    """Run ``machine`` (one Exchange); what ended it in failure is raised."""
    yield Exchange(machine)
    if machine.error is not None:
        raise machine.error


def _describe(differences: list[ItemDifference]) -> str:
    """The first differences in words, and how many more there are."""
    text = "; ".join(d.describe(codec.command_text) for d in differences[:SHOWN_DIFFERENCES])
    more = len(differences) - SHOWN_DIFFERENCES
    return f"{text} (and {more} more)" if more > 0 else text


def _interval_command(name: str, hz: float) -> CommandLong:
    """SET_MESSAGE_INTERVAL for message ``name`` at ``hz`` (0 or less: stop it)."""
    return CommandLong(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                       getattr(mavlink, f"MAVLINK_MSG_ID_{name}"), 1e6 / hz if hz > 0 else -1)


def _lost_for_good(transfer: Transfer) -> bool:
    """Whether a failed upload is lost for good (not merely missing its final ACK)."""
    return not (isinstance(transfer, Upload) and transfer.unconfirmed)
