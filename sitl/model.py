"""One simulated ArduCopter: physics, flight modes, commands, streams and failsafes, no I/O.

Theory of operation. The model is a state machine driven from outside: ``handle(msg)``
takes one decoded MAVLink message and returns the replies; ``step(dt)`` advances vehicle
time by ``dt`` seconds and returns what became due (telemetry streams, STATUSTEXT,
MISSION_ITEM_REACHED, companion reports). Time advances in fixed control ticks of
:data:`TICK` seconds whatever the sizes of the steps, so a run is the same for the same
seed, the same messages and the same total time.

Each tick: the vehicle boots and its sensors age (the boot ends at 2.5 s, the GPS locks
after ``SIM_GPS_LOCKTIME`` s, the EKF sets its origin 10 s later and uses GPS after
``SIM_EKF_GPS_TIME`` s, faults strike), the arming checks report themselves while
disarmed (:mod:`sitl.arming`), failsafes are checked, the flight mode turns its
goal into a motion demand (a position target, a velocity, a landing, or the waypoint legs
of :mod:`sitl.track`), the body moves as ArduCopter's position controller moves its target
(:mod:`sitl.physics`), touch-down, collisions (:mod:`sitl.obstacles`)
and the fence (:mod:`sitl.fence`) are detected, the camera (:mod:`sitl.camera`) takes
the pictures that fell due, the battery drains (or, landed and disarmed with
``SIM_BATT_CHARGE`` set, charges on its pad), the mission protocol's timeouts run, and
the messages :mod:`sitl.streams` says are due are built by :mod:`sitl.messages`, which
reads the model's public state. The mode table is :mod:`sitl.modes`.

The model ties together classes with one job each, and keeps the vehicle's state and its
motion: the failsafes (:class:`sitl.failsafes.Failsafes`), the fence zones
(:class:`sitl.fence.Geofence`), the pilot's sticks (:class:`sitl.sticks.Sticks`), FLIP
(:class:`sitl.flip.Flip`), ArduCopter's RTL (:class:`sitl.rtl.CopterRtl`), the
navigation's speeds and limits from the parameters (:class:`sitl.speeds.Speeds`), the
battery (:class:`sitl.physics.Battery`), the camera (:class:`sitl.camera.Camera`), the
mission protocol (:class:`sitl.missions.MissionServer`) and AUTO's executor
(:class:`sitl.auto.AutoMission`).

What a ground station sees follows ArduCopter: HEARTBEAT type QUADROTOR, autopilot
ARDUPILOTMEGA, ``custom_mode`` = mode number, at 1 Hz and once more at each mode change
(so even a FLIP shorter than a second shows); any mode entered while disarmed, and arming
refused with ArduCopter's checks ("Arm: ...", COMMAND_ACK FAILED) until the vehicle can
fly; only HEARTBEAT streamed until a client asks; GLOBAL_POSITION_INT with lat = lon = 0
until the GPS fix; auto-disarm ``DISARM_DELAY`` s after landing or when idle on the ground;
the mission protocol of :mod:`sitl.missions` and the AUTO executor of :mod:`sitl.auto`.

Positions are metres north/east/up of the position the vehicle booted at (the EKF origin,
which is also the first home); ``home`` moves with DO_SET_HOME and at arming, as on
ArduPilot, and RTL flies to it.
"""

from __future__ import annotations

import math
import random
from dataclasses import replace
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import arming, auto, fence, messages
from sitl.camera import COMMANDS as CAMERA_COMMANDS
from sitl.camera import Camera
from sitl.companion import Companion
from sitl.failsafes import Failsafes
from sitl.faults import Faults
from sitl.flip import SINK_RATE, Flip
from sitl.items import MissionItem
from sitl.messages import AUTOPILOT, COMPANION, stamp, statustext, targets
from sitl.missions import FENCE, MISSION, MissionServer
from sitl.modes import COPTER, PILOT_MODES, ModeTable
from sitl.obstacles import Obstacles
from sitl.params import AUTOPILOT_DEFAULTS, Params, param_replies
from sitl.physics import (
    Battery,
    Body,
    Limits,
    flight_current,
    sqrt_controller,
    stopping_distance,
)
from sitl.results import Result
from sitl.rtl import CopterRtl
from sitl.speeds import BRAKE_DECEL, Speeds
from sitl.sticks import Sticks
from sitl.streams import Streams
from sitl.track import Shape, Track, make_leg
from sitl.wire import Fields
from tml.geo import to_global, to_local
from tml.world import Home, World

TICK = 0.05  # seconds of vehicle time per control step

M = mavlink
FORCE_ARM = (2989, 21196)  # param2 magic numbers that skip the checks
FORCE_REBOOT = 20190226  # PREFLIGHT_REBOOT_SHUTDOWN param4 that reboots even when armed
LANDED_AFTER = 1.0  # seconds on the ground before touch-down counts (ArduCopter's detector)
GUIDED_VELOCITY_TIMEOUT = 3.0  # a velocity target older than this stops the vehicle
# ArduCopter SITL sits 3.0 s on the ground after NAV_TAKEOFF before it climbs: the motors
# spool up (MOT_SPOOL_TIME), the take-off throttle ramps (TKOFF_SLEW_TIME), and half a
# second more passes before the climb lifts it (measured, docs/simulator.md).
LIFT_OFF_AFTER_SLEW = 0.5
FALLING = Limits(accel_z=9.8, descent=10.0, jerk_z=1000.0)  # disarmed in the air
# Fields(kind, args) without the call to its __new__: the model makes a dozen a step.
_fields = tuple.__new__
ORIGIN_AFTER_FIX = 10.0  # s of GPS fix before the EKF sets its origin (ArduCopter SITL: 10 -> 20 s)

Vector = tuple[float, float, float]


class VehicleModel:
    """An ArduCopter-like vehicle with system id ``system_id`` booted at ``home``.

    ``params`` overrides parameter defaults (``SIM_GPS_LOCKTIME`` and ``SIM_EKF_GPS_TIME``
    shorten the start-up delays); ``faults`` supplies command rejection, GPS loss and
    battery failure. State for inspection: ``mode``, ``armed``, ``landed``, ``position``,
    ``battery_remaining``, ``time``, ``mission_items``, ``home``.

    Other kinds of vehicle (:mod:`sitl.plane`, :mod:`sitl.rover`) subclass it: the class
    attributes say what a ground station sees (HEARTBEAT type, mode table, parameters),
    and the movement (:meth:`_fly`, :meth:`_enter`, RTL, touch-down, auto-disarm and the
    Pilot methods the AUTO executor calls) is theirs.
    """

    mav_type: int = M.MAV_TYPE_QUADROTOR
    mode_table: ModeTable = COPTER
    parameter_table = AUTOPILOT_DEFAULTS
    reports_landed_state = True  # EXTENDED_SYS_STATE says on the ground, in the air ...
    initial_mode = "STABILIZE"  # the mode it is in when it says "ArduPilot Ready"
    lands_vertically = True  # NAV_LAND: over the point first, then straight down
    orbits = False  # circles natively (a fixed-wing); else flies round a moving point
    yaws_to_roi = True  # DO_SET_ROI turns the vehicle (ArduCopter); else only a camera mount
    says_circles = True  # NAV_LOITER_TURNS says "Mission: starting circle i/N" (ArduCopter)
    # Waypoint legs as ArduCopter's S-curves (:mod:`sitl.track`); else (a plane, a rover)
    # straight to each point, done within the waypoint radius.
    flies_s_curves = True

    def __init__(
        self, system_id: int, home: Home, world: World | None = None, seed: int = 0,
        params: dict[str, float] | None = None, faults: Faults | None = None,
    ) -> None:
        self.system_id = system_id
        self.seed = seed
        self.reboot_due = False  # asked to reboot: the server puts :meth:`rebooted` in its place
        self.origin = home
        self.home = home
        self.world = world or World(home=home)
        self.faults = faults or Faults(seed=seed)
        self.params = Params(
            self.parameter_table, {"MAV_SYSID": system_id, "SYSID_THISMAV": system_id,
                                 **(params or {})}
        )
        if self.world.geofence is not None and "FENCE_ENABLE" not in (params or {}):
            self.params.set("FENCE_ENABLE", 1)
        self._rng = random.Random(f"{seed}/{system_id}")
        self.body = Body(heading=home.heading)
        self.battery = Battery.from_params(self.params)
        self.missions = MissionServer(self._home_item, self._list_changed)
        self.companion = Companion(system_id, self.world, self._nearest_obstacle)
        self.mode = self.initial_mode
        self.armed = False
        self.booted = False  # past the boot: "ArduPilot Ready"
        self.origin_set = False  # the EKF origin (and the first home) exists
        self._prearm = arming.PrearmReports()
        self.landed = True
        self.time = 0.0
        self.step_count = 0
        self.control_period = TICK
        self.gripper_closed = False
        self.images_captured = 0
        self.roll = 0.0  # radians; only a flip rolls (or pitches) the simulated vehicle
        self.pitch = 0.0
        self.sticks = Sticks(self.params)
        self.flip = Flip(self.sticks)
        self._pending = 0.0
        self._outbox: list[Any] = []
        self.streams = Streams()
        # WPNAV_SPEED, WPNAV_SPEED_UP, WPNAV_SPEED_DN and DO_CHANGE_SPEED's overrides of them.
        self.speeds = Speeds(self.params)
        self._target: Vector | None = None  # a position-controller goal (GUIDED, take-off)
        self._track: Track | None = None  # waypoint legs (AUTO, RTL)
        self._lift_off_at: float | None = None  # end of the take-off run-up
        self._velocity: tuple[Vector, float] | None = None  # (velocity, expiry time)
        self._landing: tuple[float, float] | None = None
        self._paused = False  # GUIDED paused by DO_PAUSE_CONTINUE (see _pause)
        # (heading, rate, direction: 1 clockwise, -1 anticlockwise, 0 the shorter way)
        self._yaw: tuple[float, float, int] | None = None
        self._roi: Vector | None = None  # DO_SET_ROI's point, local: the nose points at it
        self._look_at: Vector | None = None  # AUTO's loiter turns: the nose at the centre
        self.rtl = CopterRtl()
        self.auto: auto.AutoMission | None = None
        self._mission_current = 0
        self._ground_since = 0.0
        self._idle_since = 0.0
        self.failsafes = Failsafes()
        self._colliding = False
        self.camera = Camera(self.params)
        self.obstacles = Obstacles(self.world)
        self.geofence = fence.Geofence(self.world)
        # The last conversions (position, origin, result) and (home, origin, result).
        self._last_global: tuple[Vector | None, Home | None, Vector] = (None, None, (0, 0, 0))
        self._last_home_local: tuple[Home | None, Home | None, Vector] = (None, None, (0, 0, 0))
        self._last_target_global: tuple[Vector | None, Home | None, Vector] = (
            None, None, (0, 0, 0))
        self._home_changed()

    # ----------------------------------------------------------------- public state
    @property
    def position(self) -> Vector:
        """(north, east, up) in metres from the boot position."""
        return self.body.position

    @property
    def heading(self) -> float:
        """Heading in degrees clockwise from north."""
        return self.body.heading

    @property
    def battery_remaining(self) -> int:
        """Battery charge left in percent."""
        return self.battery.remaining

    @property
    def mission_items(self) -> list[MissionItem]:
        """The stored mission, seq 0 being home (empty when no mission is loaded)."""
        return self.missions.items(MISSION)

    @property
    def has_companion(self) -> bool:
        """True when the embedded companion computer is on board (``SIM_COMPANION``)."""
        return self.params["SIM_COMPANION"] > 0

    @property
    def gps_fixed(self) -> bool:
        """True once the GPS has a 3D fix (and has not lost it)."""
        return self.time >= self.params["SIM_GPS_LOCKTIME"] and not self._gps_lost

    @property
    def position_ok(self) -> bool:
        """True while the EKF has an absolute horizontal position."""
        return self.gps_fixed and self.origin_set and self.time >= self.params["SIM_EKF_GPS_TIME"]

    @property
    def prearm_ok(self) -> bool:
        """The pre-arm checks pass in the present mode (always True when armed)."""
        return arming.prearm_passes(self, self.params["SIM_EKF_GPS_TIME"])

    @property
    def origin_time(self) -> float:
        """When the EKF sets its origin: after 10 s of GPS fix, as ArduPilot's EKF3 waits for
        10 s of good GPS, and no later than it uses the GPS (``SIM_EKF_GPS_TIME``)."""
        return min(self.params["SIM_GPS_LOCKTIME"] + ORIGIN_AFTER_FIX,
                   self.params["SIM_EKF_GPS_TIME"])

    @property
    def _gps_lost(self) -> bool:
        at = self.faults.gps_loss_at
        return at is not None and self.time >= at

    # ------------------------------------------------------------------- interface
    def handle(self, msg: Any) -> list[Any]:
        """Replies to one decoded MAVLink message."""
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            # As ArduPilot (GCS_MAVLINK::handle_heartbeat): the GCS failsafe hears the
            # ground station of MAV_GCS_SYSID, by its system id alone: another system's
            # HEARTBEAT, a GCS's too, neither arms it nor keeps it quiet.
            if msg.get_srcSystem() == round(self.params["MAV_GCS_SYSID"]):
                self.failsafes.gcs_seen = self.time
            return []
        if getattr(msg, "target_component", 0) == COMPANION:
            if self.has_companion and targets(msg, self.system_id, COMPANION):
                return self.companion.handle(msg)
            return []
        if not targets(msg, self.system_id, AUTOPILOT):
            return []
        replies = self._dispatch(kind, msg)
        replies.extend(self._flush())
        return [stamp(reply, self.system_id, AUTOPILOT) if reply._header.srcSystem == 0
                else reply for reply in replies]

    def step(self, dt: float) -> list[Any]:
        """Advance ``dt`` seconds of vehicle time; returns the messages that became due."""
        out = self.step_wire(dt)
        if not out:  # most steps
            return out
        system_id = self.system_id
        return [stamp(item.message(), system_id, AUTOPILOT) if type(item) is Fields else item
                for item in out]

    def step_wire(self, dt: float) -> list[Any]:
        """As :meth:`step`, with the streamed telemetry not built: :class:`Fields` sent by
        the autopilot, which the server encodes straight to the same bytes."""
        self._pending += dt
        out: list[Any] = []
        builders = messages.BUILDERS
        streams = self.streams
        while self._pending >= TICK - 1e-9:
            self._pending -= TICK
            self.step_count += 1
            self.time = now = self.step_count * TICK
            self._tick()
            requests = self.missions.tick(now)
            if requests:
                self._outbox.extend(requests)
            if now + 1e-9 >= streams.earliest:  # most steps nothing is due (Streams.due's test)
                for msg_id in streams.due(now):
                    builder = builders[msg_id]
                    args = builder.arguments(self)
                    if args is not None:
                        out.append(_fields(Fields, (builder.kind, args)))  # Fields(kind, args)
            if self._outbox:
                out.extend(self._flush())
            companion = self.companion
            if now >= companion.next_due and self.has_companion:  # most steps: nothing due
                body = self.body
                out.extend(companion.step(now, body.position, body.heading))
        return out

    # ---------------------------------------------------------------- dispatching
    def _dispatch(self, kind: str, msg: Any) -> list[Any]:
        if kind.startswith("PARAM_"):
            replies = param_replies(self.params, msg)
            if kind == "PARAM_SET" and replies:
                self.battery.configure(self.params)
            return replies
        if kind.startswith("MISSION_") and kind not in ("MISSION_SET_CURRENT", "MISSION_ACK"):
            return self.missions.handle(msg, self.time)
        if kind == "MISSION_SET_CURRENT":
            self._set_current(msg.seq)
            return [messages.mission_current(self)]
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            return self._command(msg)
        if kind == "SET_MODE":
            ok = self.set_mode(self.mode_table.names.get(msg.custom_mode, ""))
            result = Result.ACCEPTED if ok else Result.FAILED
            return [M.MAVLink_command_ack_message(M.MAVLINK_MSG_ID_SET_MODE, result)]
        if kind == "RC_CHANNELS_OVERRIDE":
            self.sticks.override(msg, self.time)
        elif kind == "SET_POSITION_TARGET_LOCAL_NED":
            self._local_target(msg)
        elif kind == "SET_POSITION_TARGET_GLOBAL_INT":
            self._global_target(msg)
        elif kind == "REQUEST_DATA_STREAM":
            self.streams.request_data_stream(msg.req_stream_id, msg.req_message_rate,
                                             bool(msg.start_stop), self.time)
        return []

    def _command(self, msg: Any) -> list[Any]:
        command = msg.command
        p = [msg.param1, msg.param2, msg.param3, msg.param4]
        if msg.get_type() == "COMMAND_INT":
            p += [msg.x / 1e7, msg.y / 1e7, msg.z]
        else:
            p += [msg.param5, msg.param6, msg.param7]
        extra: list[Any] = []
        if command in self.faults.reject_commands:
            result = self.faults.reject_commands[command]
        else:
            result = self._execute(command, p, extra)
        ack = M.MAVLink_command_ack_message(
            command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
        )
        return [ack, *extra]

    def _execute(self, command: int, p: list[float], extra: list[Any]) -> Result:
        ok, failed = Result.ACCEPTED, Result.FAILED
        if command == M.MAV_CMD_COMPONENT_ARM_DISARM:
            forced = round(p[1]) in FORCE_ARM
            return self._arm(forced) if p[0] >= 0.5 else self._disarm(forced)
        if command == M.MAV_CMD_DO_SET_MODE:
            if not round(p[0]) & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
                return Result.UNSUPPORTED
            return ok if self.set_mode(self.mode_table.names.get(round(p[1]), "")) else failed
        if command == M.MAV_CMD_NAV_TAKEOFF:
            return ok if self._takeoff(p[6]) else failed
        if command == M.MAV_CMD_NAV_LAND:
            return ok if self.set_mode("LAND") else failed
        if command == M.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return ok if self.set_mode("RTL") else failed
        if command == M.MAV_CMD_DO_CHANGE_SPEED:
            return self._change_speed(p[0], p[1])
        if command == M.MAV_CMD_DO_PAUSE_CONTINUE:
            return self._pause(p[0] < 0.5)
        if command == M.MAV_CMD_CONDITION_YAW:
            if not 0 <= p[0] <= 360 or p[3] not in (0, 1):
                return failed
            # As ArduCopter's AutoYaw::set_fixed_yaw: a turn by an angle goes clockwise
            # unless param3 is negative; a heading from north goes the shorter way unless
            # param3 gives a direction, which it keeps however far that is.
            if p[3]:
                direction = -1 if p[2] < 0 else 1
                heading = self.heading + direction * p[0]
            else:
                direction, heading = (p[2] > 0) - (p[2] < 0), p[0]
            self.set_yaw(heading % 360.0, p[1] or 60.0, direction)
            return ok
        if command == M.MAV_CMD_DO_REPOSITION:
            return self._reposition(p)
        if command == M.MAV_CMD_DO_SET_HOME:
            if not self.position_ok:
                return failed
            if p[0] >= 0.5:
                self._set_home_here()
            else:
                self.home = Home(p[4], p[5], p[6], self.home.heading)
                self._home_changed()
            return ok
        if command == M.MAV_CMD_MISSION_START:
            if p[0] or p[1]:
                return Result.DENIED  # ArduPilot takes no first or last item
            if not self.set_mode("AUTO"):
                return failed
            if self.auto is not None and self.auto.finished:
                # Already in AUTO, set_mode changed nothing: as ArduCopter, a mission that
                # is not running (here: finished) starts again.
                self.auto.start(1)
            return ok
        if command == M.MAV_CMD_DO_SET_MISSION_CURRENT:
            return ok if self._set_current(round(p[0])) else failed
        if command in (M.MAV_CMD_DO_SET_ROI_LOCATION, M.MAV_CMD_DO_SET_ROI):
            self.set_roi(p[4], p[5], p[6])
            return ok
        if command == M.MAV_CMD_DO_SET_ROI_NONE:
            self.set_roi(0.0, 0.0, 0.0)
            return ok
        if command in CAMERA_COMMANDS:
            return self._camera(command, p)
        if command == M.MAV_CMD_DO_GRIPPER:
            return ok if self._gripper(p[1]) else failed
        if command == M.MAV_CMD_SET_MESSAGE_INTERVAL:
            return ok if self.streams.set_interval(round(p[0]), p[1], self.time) else failed
        if command == M.MAV_CMD_REQUEST_MESSAGE:
            # As ArduCopter: ACCEPTED for a message it knows even when it has nothing to
            # send yet (HOME_POSITION before the EKF origin), and then sends nothing.
            if round(p[0]) not in messages.BUILDERS:
                return failed
            built = messages.build(round(p[0]), self)
            if built is not None:
                extra.append(built)
            return ok
        if command == M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
            return self._reboot(p[0], p[3])
        if command == M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            extra.append(messages.autopilot_version(self))
            return ok
        if command == M.MAV_CMD_GET_HOME_POSITION:
            built = messages.home_position(self)
            if built is None:
                return failed
            extra.append(built)
            return ok
        return Result.UNSUPPORTED

    def _reboot(self, what: float, force: float) -> Result:
        """PREFLIGHT_REBOOT_SHUTDOWN as ArduPilot answers it: FAILED while armed unless
        forced (param4 :data:`FORCE_REBOOT`), UNSUPPORTED for anything but rebooting the
        autopilot (param1 1); else ACCEPTED, and the reboot follows the ACK."""
        if self.armed and round(force) != FORCE_REBOOT:
            return Result.FAILED
        if round(what) != 1:
            return Result.UNSUPPORTED
        self.reboot_due = True
        return Result.ACCEPTED

    def rebooted(self) -> VehicleModel:
        """The vehicle after a reboot: a new boot of the same kind, clock at zero, disarmed
        in its first mode, on the ground where it first booted (as an ArduPilot SITL
        started again), with the parameters it had (ArduPilot keeps them in its EEPROM).
        The fault that rebooted it (``reboot_at``) does not strike again."""
        params = {name: value for name, value in self.params.items()
                  if name not in ("MAV_SYSID", "SYSID_THISMAV")}
        return type(self)(self.system_id, self.origin, self.world, self.seed, params,
                          replace(self.faults, reboot_at=None))

    def _change_speed(self, speed_type: float, speed: float) -> Result:
        """DO_CHANGE_SPEED as a command, as ArduCopter answers it: DENIED for a speed that
        is not positive or an unknown speed type, FAILED in a mode that has no speed to
        change (only AUTO, GUIDED and RTL have one)."""
        kind = int(speed_type) if math.isfinite(speed_type) else -1
        if not speed > 0 or kind not in (auto.SPEED_AIR, auto.SPEED_GROUND, auto.SPEED_CLIMB,
                                         auto.SPEED_DESCENT):
            return Result.DENIED
        if self.mode not in ("AUTO", "GUIDED", "RTL"):
            return Result.FAILED
        self.set_speed(kind, speed)
        return Result.ACCEPTED

    # ------------------------------------------------------------ modes and arming
    def set_mode(self, name: str) -> bool:
        """Change flight mode as ArduCopter would; False (with a STATUSTEXT) when refused."""
        if name not in self.mode_table.numbers:
            return False
        if name == self.mode:  # as ArduCopter: already there, nothing restarts
            return True
        # As ArduCopter's Copter::set_mode, a disarmed vehicle enters any mode (the arming
        # checks then refuse to arm without a position); an armed one needs the position.
        if self.armed and name in self.mode_table.needs_position and not self.position_ok:
            self._text(M.MAV_SEVERITY_WARNING, f"Mode change to {name} failed: requires position")
            return False
        if name == "AUTO" and self.armed and self.landed and not self._starts_with_takeoff():
            self._text(M.MAV_SEVERITY_WARNING, "Auto: Missing Takeoff Cmd")
            return False
        flying = self.armed and not self.landed
        if name == "FLIP" and not self.flip.allowed(self.mode, flying, self.time):
            self._text(M.MAV_SEVERITY_WARNING, "Mode change to FLIP failed: init failed")
            return False
        previous, self.mode = self.mode, name
        if not self.armed:
            self._prearm.bring_forward(self.time)
        self._paused = False  # ArduCopter's ModeGuided::init clears it
        self._roi = self._look_at = None  # each mode starts with its default yaw
        self._stop_motion()
        self.auto = None
        self.rtl.phase = ""
        self.roll = self.pitch = 0.0
        self._announce_mode()
        self._enter(name, previous, flying)
        return True

    def _enter(self, name: str, previous: str, flying: bool) -> None:
        """What the vehicle starts doing in mode ``name`` (entered from ``previous``)."""
        if name == "FLIP":  # turn once around, then back to ``previous``
            self.flip.start(previous, self.time)
            self.body.stop()
        elif name == "BRAKE" and flying:
            # ArduCopter's BRAKE shapes the velocity to zero at BRAKE_MODE_DECEL_RATE
            # (jerk-limited), from no acceleration (init_xy_controller), and holds where
            # that ends.
            self.body.restart_shaping()
            self._velocity = ((0.0, 0.0, 0.0), math.inf)
        elif name in ("GUIDED", "LOITER") and flying:
            self._target = self._stopping_point()
        elif name == "LAND":
            self._landing = self._stopping_point()[:2] if flying else self.position[:2]
        elif name == "RTL" and flying:
            self._start_rtl()
        elif name == "AUTO":
            self._start_auto(self._mission_current or 1)

    def _announce_mode(self) -> None:
        # ArduCopter's Copter::set_mode sends a HEARTBEAT at once after every successful
        # change, besides the 1 Hz stream, so a ground station sees even a short FLIP.
        self._outbox.append(messages.heartbeat(self))

    def _starts_with_takeoff(self) -> bool:
        for item in self.mission_items[1:]:
            if item.command in auto.NAV_COMMANDS:
                return item.command == auto.NAV_TAKEOFF
        return False

    def _start_auto(self, index: int) -> None:
        if not self.armed or len(self.mission_items) < 2:
            return
        self.auto = auto.AutoMission(
            self.mission_items, self, self.params["WPNAV_RADIUS"] / 100.0
        )
        self.auto.start(index)

    def _arm(self, forced: bool) -> Result:
        if self.armed:
            return Result.ACCEPTED
        if not forced:
            problems = arming.failures(self, self.params["SIM_EKF_GPS_TIME"])
            for problem in problems:
                self._text(M.MAV_SEVERITY_CRITICAL, f"Arm: {problem}")
            if problems:
                return Result.FAILED
        self.armed = True
        self._idle_since = self.time
        self._text(M.MAV_SEVERITY_INFO, "Arming motors")
        if self.position_ok:  # home moves to where the vehicle arms
            lat, lon, alt = self._global(self.position)
            self.home = Home(lat, lon, alt, self.heading)
        if self.origin_set:
            self._announce_origin()  # ArduCopter sends both at arming, home moved or not
        return Result.ACCEPTED

    def extra_arming_failures(self) -> list[str]:
        """The simulator's own arming checks, after ArduCopter's start-up ones."""
        found = []
        if self.failsafes.active & {"battery", "battery critical"}:
            found.append("Battery failsafe")
        if self.params["FENCE_ENABLE"] and self._fence_breach(self.position):
            found.append("Vehicle breaching fence")
        return found

    def _boot_done(self) -> None:
        # As ArduCopter: a mode selected while booting gives way to the initial one.
        self.booted = True
        self._text(M.MAV_SEVERITY_INFO, "ArduPilot Ready")
        if not self.armed and self.mode != self.initial_mode:
            self.set_mode(self.initial_mode)

    def _report_prearm(self) -> None:
        if self.armed or not self._prearm.due(self.time):
            return
        for problem in arming.failures(self, self.params["SIM_EKF_GPS_TIME"]):
            self._text(M.MAV_SEVERITY_CRITICAL, f"PreArm: {problem}")

    def _disarm(self, forced: bool) -> Result:
        if not self.armed:
            return Result.ACCEPTED
        if not self.landed and not forced:
            return Result.FAILED
        self.disarm()
        return Result.ACCEPTED

    def disarm(self) -> None:
        """Stop the motors (a forced disarm in flight drops the vehicle)."""
        self.armed = False
        self._prearm.bring_forward(self.time)
        self._stop_motion()
        self.auto = None
        self._text(M.MAV_SEVERITY_INFO, "Disarming motors")

    def _takeoff(self, altitude: float) -> bool:
        if not self.armed or not self.landed or self.mode not in ("GUIDED", "LOITER"):
            return False
        here = self.position
        self._target = (here[0], here[1], max(altitude, 1.0))
        return True

    # ------------------------------------------------------------ guided targets
    def _reposition(self, p: list[float]) -> Result:
        change_mode = round(p[1]) & M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE
        if self.mode != "GUIDED" and not change_mode:
            return Result.DENIED
        if not self.armed or self.landed:
            return Result.FAILED
        target = self._reposition_target(p)
        if self._outside_fence(target):
            return Result.FAILED
        if self.mode != "GUIDED" and not self.set_mode("GUIDED"):
            return Result.FAILED
        self._roi = None  # ModeGuided::set_destination without a yaw: the default yaw
        self._go(target)
        return Result.ACCEPTED

    def _reposition_target(self, p: list[float]) -> Vector:
        """DO_REPOSITION's point (latitude and longitude 0: here; altitude NaN: the present
        one); its speed (param1), when positive, becomes the vehicle's."""
        here = self.position
        north, east = here[:2]
        if p[4] or p[5]:
            north, east, _ = self._local(p[4], p[5], self.origin.altitude)
        if p[0] > 0:
            self.speeds.horizontal = p[0]
        return north, east, here[2] if math.isnan(p[6]) else p[6]

    def _pause(self, pause: bool) -> Result:
        """DO_PAUSE_CONTINUE as ArduCopter's GUIDED takes it (ModeGuided::pause, resume):
        paused, it shapes its velocity to zero from the acceleration it has -- its velocity
        controller is not started afresh, so from 8.5 m/s it stops about 24 m on, against
        18 m for a velocity target of zero -- and holds there, flying no target it is given
        meanwhile; continued, it flies its latest target. Any other mode refuses (FAILED);
        AUTO's pause (along the leg) is not imitated (UNSUPPORTED)."""
        if self.mode == "AUTO":
            return Result.UNSUPPORTED
        if self.mode != "GUIDED":
            return Result.FAILED
        self._paused = pause
        return Result.ACCEPTED

    def _guided_ready(self) -> bool:
        return self.mode == "GUIDED" and self.armed and not self.landed

    def _local_target(self, msg: Any) -> None:
        if not self._guided_ready():
            return
        mask, frame = msg.type_mask, msg.coordinate_frame
        here = self.position
        north, east, down = msg.x, msg.y, msg.z
        vn, ve, vd = msg.vx, msg.vy, msg.vz
        if frame in (M.MAV_FRAME_BODY_NED, M.MAV_FRAME_BODY_OFFSET_NED):
            yaw = math.radians(self.heading)
            north, east = (north * math.cos(yaw) - east * math.sin(yaw),
                           north * math.sin(yaw) + east * math.cos(yaw))
            vn, ve = (vn * math.cos(yaw) - ve * math.sin(yaw),
                      vn * math.sin(yaw) + ve * math.cos(yaw))
        if frame in (M.MAV_FRAME_LOCAL_OFFSET_NED, M.MAV_FRAME_BODY_NED,
                     M.MAV_FRAME_BODY_OFFSET_NED):
            north, east, down = north + here[0], east + here[1], down - here[2]
        self._apply_target(mask, (north, east, -down), (vn, ve, -vd), msg.yaw)

    def _global_target(self, msg: Any) -> None:
        if not self._guided_ready():
            return
        base = self.origin.altitude
        altitude = msg.alt + (0.0 if msg.coordinate_frame in (0, 5) else base)
        target = self._local(msg.lat_int / 1e7, msg.lon_int / 1e7, altitude)
        self._apply_target(msg.type_mask, target, (msg.vx, msg.vy, -msg.vz), msg.yaw)

    def _apply_target(self, mask: int, position: Vector, velocity: Vector, yaw: float) -> None:
        if not mask & 0b111 and self._outside_fence(position):
            return  # ignored, as ArduCopter's ModeGuided::set_destination does
        if not mask & 0b111:
            self._go(position)
        elif not mask & 0b111000:
            if self._velocity is None:
                # ArduCopter's velocity controller starts (velaccel_control_start) from the
                # velocity the vehicle has and no acceleration: told to stop while still
                # speeding up, it brakes at once (from 8.6 m/s: 18 m, not the 24 m it
                # would need from full acceleration).
                self.body.restart_shaping()
            self._stop_motion()
            self._velocity = (velocity, self.time + GUIDED_VELOCITY_TIMEOUT)
        if not mask & 1024:
            self.set_yaw(math.degrees(yaw) % 360.0, self.params["ATC_RATE_Y_MAX"])
        elif mask & 2048 and (not mask & 0b111 or not mask & 0b111000):
            # ArduCopter hands the heading back to its default yaw behaviour on a position
            # or velocity target without a yaw or a yaw rate (ModeGuided::set_yaw_state): a
            # CONDITION_YAW turn in progress stops where it is; an ROI is let go.
            self._yaw = self._roi = None

    def _go(self, target: Vector) -> None:
        """Fly to ``target`` with the position controller (GUIDED targets, take-off)."""
        self._stop_motion()
        self._target = target

    def _fly_legs(self, destination: Vector, following: Vector | None = None) -> None:
        """Fly to ``destination`` as the waypoint navigator does (an S-curve leg), blending
        into the leg on to ``following`` when there is one."""
        p, limits, shape = self.params, self._limits(), self._shape()
        track = self._track
        if track is not None and track.next is not None and math.dist(
                track.next.destination, destination) < 0.01 and track.promote():
            track.replan(limits, shape, self.time)  # the speed may have changed meanwhile
        else:
            # A new leg starts from where the vehicle can stop, as ArduCopter's does.
            track = Track(make_leg(self._stopping_point(keep_altitude=True), destination,
                                   limits, shape), self.time, p["WPNAV_RADIUS"] / 100.0)
        track.set_next(None if following is None else make_leg(destination, following,
                                                                limits, shape))
        self._stop_motion()
        self._track = track

    def _stop_motion(self) -> None:
        self._target, self._velocity, self._landing, self._track = None, None, None, None

    # ------------------------------------------------------------------- Pilot API
    def item_position(self, item: MissionItem) -> Vector:
        """Where a mission item points, in the local frame (lat = lon = 0: here)."""
        here = self.position
        if item.frame not in (0, 3, 5, 6, 10, 11):
            return here
        absolute = item.frame in (0, 5)
        altitude = item.z if absolute else item.z + self.home.altitude
        if item.x == 0 and item.y == 0:
            return here[0], here[1], altitude - self.origin.altitude
        return self._local(item.x / 1e7, item.y / 1e7, altitude)

    def fly_to(self, target: Vector) -> None:
        """Fly to ``target`` with the position controller and hold there."""
        self._go(target)

    def take_off(self, target: Vector) -> None:
        """NAV_TAKEOFF: climb to ``target`` (straight up for a multicopter)."""
        self._go(target)

    def loiter_at(self, centre: Vector, radius: float, clockwise: bool) -> None:
        """Circle ``centre`` (a vehicle that :attr:`orbits`); a multicopter holds it."""
        self._go(centre)

    def circle_rate(self, radius: float) -> float:
        """Degrees per second around a loiter circle: ArduCopter's CIRCLE_RATE of 20, at
        most the speed along the circle that uses half of ``WPNAV_ACCEL`` toward the
        centre, and no more than ``WPNAV_SPEED`` (AC_Circle::calc_velocities)."""
        p = self.params
        speed = min(p["WPNAV_SPEED"] / 100.0, math.sqrt(0.5 * p["WPNAV_ACCEL"] / 100.0 * radius))
        return min(20.0, math.degrees(speed / radius))

    def look_at(self, point: Vector | None) -> None:
        """Point the nose at ``point`` in AUTO (an ROI still wins), or stop (None); only a
        vehicle that turns for a region of interest does."""
        self._look_at = point if self.yaws_to_roi else None

    def returned(self) -> bool:
        """NAV_RETURN_TO_LAUNCH is done: for a multicopter, landed at home."""
        return self.landed

    def fly_leg(self, target: Vector, following: Vector | None = None) -> None:
        """Fly a waypoint leg to ``target``; on to ``following`` without stopping if given."""
        if not self.flies_s_curves:
            self.fly_to(target)
            return
        self._fly_legs(target, following)

    def leg_done(self, target: Vector, radius: float) -> bool:
        """True once the waypoint leg to ``target`` is reached: at the turn's apex for a
        blended leg, else where its S-curve ends (``WPNAV_RADIUS`` decides, not ``radius``).
        A vehicle that flies no S-curves is done within ``radius`` of ``target``."""
        if not self.flies_s_curves:
            return self.arrived(target, radius)
        return self._leg_reached()

    def _leg_reached(self) -> bool:
        track = self._track
        return track is not None and track.reached and (
            track.next is not None or math.dist(
                self.position, track.destination) <= self.params["WPNAV_RADIUS"] / 100)

    def hold(self) -> None:
        """Stop and hold the present position."""
        self._go(self._stopping_point())

    def land_at(self, north: float, east: float) -> None:
        """Descend to the ground at (north, east)."""
        self._stop_motion()
        self._landing = (north, east)

    def return_home(self) -> None:
        """Run the RTL sequence (climb, return, loiter, land)."""
        self._start_rtl()

    def has_landed(self) -> bool:
        """True once touch-down has been detected."""
        return self.landed

    def arrived(self, target: Vector, radius: float) -> bool:
        """True when within ``radius`` metres of ``target``."""
        return math.dist(self.position, target) <= radius

    def set_speed(self, speed_type: int, speed: float) -> None:
        """Set one speed (m/s) for waypoints and guided targets: ``speed_type`` 0 or 1 the
        horizontal speed, 2 the climb speed, 3 the descent speed (MAVLink SPEED_TYPE).

        A waypoint leg in progress is planned again from where the vehicle is, as
        ArduCopter recalculates its leg when the speed changes."""
        self.speeds.set(speed_type, speed)
        if self._track is not None:
            self._track.replan(self._limits(), self._shape(), self.time)

    def set_yaw(self, heading: float, rate: float, direction: int = 0) -> None:
        """Turn to ``heading`` degrees at ``rate`` degrees per second, and keep it: the
        shorter way, or clockwise (``direction`` 1) or anticlockwise (-1)."""
        self._yaw = (heading, min(rate, self.params["ATC_RATE_Y_MAX"]), direction)
        self._roi = None

    def set_roi(self, latitude: float, longitude: float, altitude: float) -> None:
        """DO_SET_ROI_LOCATION / DO_SET_ROI at this point, as ArduCopter's
        AutoYaw::set_roi: from now on the nose points at it in GUIDED and AUTO (across the
        mission's waypoints) until DO_SET_ROI_NONE, a mode change, a yaw asked for
        (CONDITION_YAW, a target's yaw) or a GUIDED target without one; latitude,
        longitude and altitude all 0 is DO_SET_ROI_NONE: the default yaw again."""
        if not self.yaws_to_roi:
            return
        self._yaw = None
        none = latitude == 0 and longitude == 0 and altitude == 0
        self._roi = None if none else self._local(latitude, longitude, self.origin.altitude)

    def yaw_settled(self) -> bool:
        """True when the heading has reached the yaw target."""
        if self._yaw is None:
            return True
        return abs((self._yaw[0] - self.heading + 180.0) % 360.0 - 180.0) < 1.0

    def set_home_from(self, item: MissionItem) -> None:
        """DO_SET_HOME as a mission item."""
        if item.param1 >= 0.5 or (item.x == 0 and item.y == 0):
            self._set_home_here()
        else:
            self.home = Home(item.x / 1e7, item.y / 1e7, item.z, self.home.heading)
            self._home_changed()

    def do_command(self, item: MissionItem) -> None:
        """Camera, gripper and ROI items of a mission."""
        params = [item.param1, item.param2, item.param3, item.param4, float(item.x),
                  float(item.y), item.z]
        if item.command == auto.DO_GRIPPER:
            self._gripper(item.param2)
        elif item.command in (auto.DO_SET_ROI_LOCATION, auto.DO_SET_ROI, auto.DO_SET_ROI_NONE):
            # AP_Mission: ROI_NONE is the same handler with a zero location.
            self.set_roi(item.x / 1e7, item.y / 1e7, item.z)
        else:
            self._camera(item.command, params)

    def text(self, severity: int, message: str) -> None:
        """Queue a STATUSTEXT."""
        self._text(severity, message)

    def reached(self, seq: int) -> None:
        """Queue MISSION_ITEM_REACHED for ``seq``."""
        self._outbox.append(M.MAVLink_mission_item_reached_message(seq))

    # ------------------------------------------------------------------ the tick
    def _tick(self) -> None:
        now, params = self.time, self.params
        if not self.booted and now >= arming.READY_AT * arming.startup_scale(
                params["SIM_EKF_GPS_TIME"]):
            self._boot_done()
        if not self.origin_set and self.gps_fixed and now >= self.origin_time:
            self.origin_set = True
            self._announce_origin()
        if not self.armed:
            self._report_prearm()
        faults = self.faults
        failure_at = faults.battery_failure_at
        if failure_at is not None and now >= failure_at:
            self.battery.failed = True
        reboot_at = faults.reboot_at
        if reboot_at is not None and now >= reboot_at:
            self.reboot_due = True
        self.failsafes.check(self)
        if self.mode == "FLIP":
            self._update_flip()
        if self.mode == "RTL" or self.rtl.phase:
            self._update_rtl()
        if self.auto is not None:
            self.auto.update()
        self._fly()
        self._check_landed()
        if self.camera.update(now, self.body.position):
            self._capture_image()
        charger = params["SIM_BATT_CHARGE"]
        if charger > 0 and self.landed and not self.armed:
            # On its pad the charger also feeds the electronics, so nothing drains.
            self.battery.charge(TICK, charger)
        else:
            self.battery.drain(TICK, self._current())
        self._auto_disarm()

    def _current(self) -> float:
        """Amperes drawn now (ArduCopter SITL's motors: :func:`sitl.physics.flight_current`)."""
        return flight_current(self.armed, not self.landed, self.body.velocity,
                              self.params["SIM_WIND_SPD"])

    def _auto_disarm(self) -> None:
        """ArduCopter disarms DISARM_DELAY s after landing, or when armed idle on the ground."""
        if self.armed and self.landed and self._target is None and self._landing is None and (
                self._track is None):
            if self.time - self._idle_since >= self.params["DISARM_DELAY"] > 0:
                self.disarm()
        elif self.armed:
            self._idle_since = self.time

    def _limits(self) -> Limits:
        return self.speeds.limits(self.mode)

    def _shape(self) -> Shape:
        return self.speeds.shape()

    def _wind(self) -> tuple[float, float]:
        # SIM_WIND_DIR is where the wind comes from; it blows toward the opposite side.
        speed = self.params["SIM_WIND_SPD"]
        towards = math.radians(self.params["SIM_WIND_DIR"] + 180)
        return speed * math.cos(towards), speed * math.sin(towards)

    def _fly(self) -> None:
        body = self.body
        if not self.armed:
            if self.landed:
                body.stop()
                return
            body.shape_velocity((0.0, 0.0, -3.0), FALLING, TICK)
            return
        paused = self._paused and self.mode == "GUIDED"
        if self.landed and (paused or not (self._wants_climb() and self._lifting_off())):
            body.stop()
            return
        limits = self._limits()
        before = body.position
        if self.mode == "FLIP":
            # The flip's sink, spread over the turn: about 4 m, as ArduCopter's.
            north, east, up = body.position
            body.position, body.velocity = (north, east, up - SINK_RATE * TICK), (
                0.0, 0.0, -SINK_RATE)
        elif paused:
            body.shape_velocity((0.0, 0.0, 0.0), limits, TICK)
        elif self._landing is not None:
            speed = self._land_speed()
            north, east = self._landing
            body.shape((north, east, 0.0), replace(limits, descent=speed), TICK,
                       climb_rate=-speed)
        elif self._velocity is not None and self.time < self._velocity[1]:
            body.shape_velocity(self._velocity[0], limits, TICK)
        elif self._track is not None:
            position, velocity, accel = self._track.update(self.time)
            body.shape(position, limits, TICK, velocity, accel)
        elif self._target is not None:
            body.shape(self._target, limits, TICK)
        else:
            pilot = self.mode in PILOT_MODES
            climb = self.pilot_climb_rate() if pilot else 0.0
            body.shape_velocity((0.0, 0.0, climb), limits, TICK, self._wind(), hold=not pilot)
        if self.obstacles.present and self._blocked(body.position):
            body.position = before
            body.stop()
        if self.landed and body.position[2] > 0.05:
            self.landed = False
            self._text(M.MAV_SEVERITY_INFO, "Takeoff")
        self._turn(before)

    def _land_speed(self) -> float:
        """The descent rate (m/s) of a landing, as ArduCopter's
        ``land_run_vertical_control``: ``LAND_SPEED`` below ``LAND_ALT_LOW``; above, a rate
        braking on a square-root curve toward that altitude, between ``LAND_SPEED`` and
        ``LAND_SPEED_HIGH`` (or ``WPNAV_SPEED_DN``), so the slow final phase starts there."""
        p = self.params
        slow = abs(p["LAND_SPEED"]) / 100.0
        fast = max(slow, (p["LAND_SPEED_HIGH"] or p["WPNAV_SPEED_DN"]) / 100.0)
        above = self.position[2] - max(p["LAND_ALT_LOW"], 100.0) / 100.0
        if above <= 0.0:
            return slow
        braking = sqrt_controller(above, p["PSC_POSZ_P"], p["WPNAV_ACCEL_Z"] / 100.0, TICK)
        return max(slow, min(fast, braking))

    def _lifting_off(self) -> bool:
        """True once the take-off run-up is over: ArduCopter spools the motors up and ramps
        the take-off throttle before the vehicle leaves the ground."""
        if self._lift_off_at is None:
            p = self.params
            self._lift_off_at = self.time + p["MOT_SPOOL_TIME"] + p["TKOFF_SLEW_TIME"] + (
                LIFT_OFF_AFTER_SLEW)
        return self.time >= self._lift_off_at

    def _turn(self, before: Vector) -> None:
        roi = self._roi
        if roi is not None and self.mode in ("AUTO", "GUIDED"):
            here = self.body.position
            if math.hypot(roi[0] - here[0], roi[1] - here[1]) > 0.1:  # over it: as it is
                bearing = math.degrees(math.atan2(roi[1] - here[1], roi[0] - here[0]))
                self.body.turn(bearing % 360.0, self.params["ATC_RATE_Y_MAX"], TICK)
            return
        look_at = self._look_at
        if look_at is not None and self.mode == "AUTO":
            here = self.body.position
            if math.hypot(look_at[0] - here[0], look_at[1] - here[1]) > 0.1:
                bearing = math.degrees(math.atan2(look_at[1] - here[1], look_at[0] - here[0]))
                self.body.turn(bearing % 360.0, self.params["ATC_RATE_Y_MAX"], TICK)
            return
        if self._yaw is not None:
            heading, rate, direction = self._yaw
            self.body.turn(heading, rate, TICK, direction)
            if direction and self.yaw_settled():
                self._yaw = (heading, rate, 0)  # there: held, not turned round again
            return
        here = self.body.position
        dn, de = here[0] - before[0], here[1] - before[1]
        if self.mode in ("AUTO", "GUIDED", "RTL") and math.hypot(dn, de) > 1.0 * TICK:
            course = math.degrees(math.atan2(de, dn))
            self.body.turn(course, self.params["ATC_RATE_Y_MAX"], TICK)

    def _wants_climb(self) -> bool:
        if self.mode in PILOT_MODES:
            return self.pilot_climb_rate() > 0.0
        if self._target is not None:
            return self._target[2] > 0.3
        if self._track is not None:
            return self._track.destination[2] > 0.3
        return self._velocity is not None and self._velocity[0][2] > 0.1

    def _check_landed(self) -> None:
        body = self.body
        if body.position[2] > 0.0 or self.landed:
            self._ground_since = self.time
            if not self.landed or not self._wants_climb():
                self._lift_off_at = None
            if self.landed and self.armed and self.mode == "LAND":
                # ArduCopter's ModeLand disarms whenever the land detector says landed: a
                # vehicle armed on the ground (a take-off not begun) is disarmed at once.
                self.disarm()
            return
        body.position = (body.position[0], body.position[1], 0.0)
        body.stop()
        if self.time - self._ground_since < LANDED_AFTER:
            return
        self.landed = True
        self._idle_since = self.time
        landing = self._landing is not None
        self._stop_motion()
        if self.auto is not None:
            self.auto.update()  # lets NAV_LAND / RTL items complete and be reported
        if self.armed and (landing or self.mode in ("LAND", "RTL")):
            self.disarm()

    def _update_flip(self) -> None:
        attitude = self.flip.turn(TICK, self.armed, self.time)
        if attitude is None:
            # As ArduCopter: back to the mode the flip started from, else STABILIZE; the
            # recovery's extra throttle stops the sink.
            vn, ve, _ = self.body.velocity
            self.body.velocity = (vn, ve, 0.0)
            if not self.set_mode(self.flip.previous):
                self.set_mode("STABILIZE")
            return
        self.roll, self.pitch = attitude

    # ------------------------------------------------------------- the pilot's sticks
    def rc(self, channel: int) -> int:
        """The PWM of RC ``channel`` (1-based) now (:class:`sitl.sticks.Sticks`)."""
        return self.sticks.rc(channel, self.time)

    @property
    def sticks_overridden(self) -> frozenset[int]:
        """The RC channels a ground station holds (given back ones are not)."""
        return self.sticks.overridden

    def pilot_climb_rate(self) -> float:
        """m/s up the throttle stick asks for in ALT_HOLD."""
        return self.sticks.climb_rate(self.time)

    # --------------------------------------------------------------------- RTL
    def _start_rtl(self) -> None:
        """ArduCopter's RTL (:class:`sitl.rtl.CopterRtl`)."""
        self.rtl.start(self)

    def _update_rtl(self) -> None:
        self.rtl.update(self)

    # ---------------------------------------------------------------- failsafes
    def land_here(self) -> None:
        """LAND where the vehicle is, none of the mode's checks asked (the EKF failsafe)."""
        self.mode = "LAND"
        self._target, self._velocity, self.auto, self.rtl.phase = None, None, None, ""
        self._announce_mode()
        self._landing = self.position[:2]

    def _outside_fence(self, destination: Vector) -> bool:
        """True when the fence is on and ``destination`` breaks it: ArduCopter refuses such
        a GUIDED destination (AC_Fence::check_destination_within_fence), a DO_REPOSITION
        with FAILED and a position target by ignoring it."""
        return bool(self.params["FENCE_ENABLE"]) and bool(self._fence_breach(destination))

    def _fence_breach(self, position: Vector) -> str:
        return self.geofence.breach(position, self.params, self._home_local())

    # ------------------------------------------------------------- obstacles
    def _blocked(self, position: Vector) -> bool:
        """True when ``position`` hits an obstacle; reported once per approach."""
        margin = self.params["AVOID_MARGIN"] if (
            self.has_companion and self.companion.avoiding and self.params["AVOID_ENABLE"]
        ) else 0.0
        name = self.obstacles.touching(position, margin)
        if name is None:
            nearest = self.obstacles.nearest(position, margin)
            if nearest is None or nearest > margin + 1.0:  # a metre away: contact is over
                self._colliding = False
            return False
        if not self._colliding:
            self._colliding = True
            if margin:
                self._text(M.MAV_SEVERITY_WARNING, f"Avoid: stopped at {name}")
            else:
                self._text(M.MAV_SEVERITY_CRITICAL, f"Collision with {name}")
        return True

    def _nearest_obstacle(self, position: Vector) -> float | None:
        return self.obstacles.nearest(position)

    # ---------------------------------------------------------- camera, gripper
    def _camera(self, command: int, p: list[float]) -> Result:
        result, pictures = self.camera.command(command, p, self.time, self.position)
        for _ in range(pictures):
            self._capture_image()
        return result

    def _capture_image(self) -> None:
        self.images_captured += 1
        self._outbox.append(messages.camera_feedback(self, self.images_captured))

    def _gripper(self, action: float) -> bool:
        """DO_GRIPPER's action (GRIPPER_ACTION_RELEASE 0, GRAB 1), in any mode, as ArduPilot:
        False without a gripper (``GRIP_ENABLE`` 0 or ``GRIP_TYPE`` 0) or for another action."""
        if not (self.params["GRIP_ENABLE"] and self.params["GRIP_TYPE"]) or action not in (
                M.GRIPPER_ACTION_RELEASE, M.GRIPPER_ACTION_GRAB):
            return False
        self.gripper_closed = action == M.GRIPPER_ACTION_GRAB
        self._text(M.MAV_SEVERITY_INFO,
                   "Gripper load grabbed" if self.gripper_closed else "Gripper load released")
        return True

    # ----------------------------------------------------------------- helpers
    def _local(self, latitude: float, longitude: float, altitude: float) -> Vector:
        o = self.origin
        return to_local(latitude, longitude, altitude, o.latitude, o.longitude, o.altitude)

    def _global(self, position: Vector) -> Vector:
        # GPS_RAW_INT and GLOBAL_POSITION_INT both convert the same position, and a
        # vehicle at rest keeps it: the last conversion is kept (it is a pure function).
        o = self.origin
        last_position, last_origin, last = self._last_global
        if position == last_position and o is last_origin:
            return last
        converted = to_global(*position, o.latitude, o.longitude, o.altitude)
        self._last_global = (position, o, converted)
        return converted

    def _home_local(self) -> Vector:
        h, o = self.home, self.origin
        last_home, last_origin, last = self._last_home_local
        if h is last_home and o is last_origin:
            return last
        local = self._local(h.latitude, h.longitude, h.altitude)
        self._last_home_local = (h, o, local)
        return local

    def _set_home_here(self) -> None:
        lat, lon, alt = self._global(self.position)
        self.home = Home(lat, lon, alt, self.heading)
        self._home_changed()

    def _home_changed(self) -> None:
        if self.origin_set:
            self._outbox.append(messages.home_position(self))

    def _announce_origin(self) -> None:
        # Sent unasked, as ArduCopter does when the EKF sets its origin and at arming.
        self._outbox += [messages.gps_global_origin(self), messages.home_position(self)]

    def _home_item(self) -> MissionItem:
        h = self.home
        return MissionItem(0, M.MAV_FRAME_GLOBAL, M.MAV_CMD_NAV_WAYPOINT, 0, 1,
                           x=round(h.latitude * 1e7), y=round(h.longitude * 1e7), z=h.altitude)

    def _list_changed(self, mission_type: int) -> None:
        if mission_type == MISSION:
            count = len(self.mission_items)
            self.params.set("MIS_TOTAL", max(count - 1, 0))
            if self._mission_current >= count:
                self._mission_current = 0
            if self.auto is not None:
                self._start_auto(self.auto.current if self.auto.current < count else 1)
        elif mission_type == FENCE:
            items = self.missions.items(FENCE)
            self.params.set("FENCE_TOTAL", len(items))
            self.geofence.load([(i.command, i.param1, self._local(
                i.x / 1e7, i.y / 1e7, self.origin.altitude)[:2]) for i in items])
        else:
            self.params.set("RALLY_TOTAL", len(self.missions.items(mission_type)))

    def _set_current(self, seq: int) -> bool:
        if not 0 <= seq < max(len(self.mission_items), 1) and seq != 0:
            return False
        self._mission_current = seq
        if self.auto is not None:
            self.auto.start(seq)
        return True

    def _stopping_point(self, keep_altitude: bool = False) -> Vector:
        """Where the vehicle can stop, by ArduCopter's ``get_stopping_point``: the
        position controller's stopping distance ahead along the velocity."""
        (n, e, u), (vn, ve, _) = self.position, self.body.velocity
        accel = BRAKE_DECEL if self.mode == "BRAKE" else self.params["WPNAV_ACCEL"] / 100.0
        speed = math.hypot(vn, ve)
        up = u if keep_altitude else max(u, 0.0)
        if speed < 1e-6:
            return n, e, up
        stop = stopping_distance(speed, self.params["PSC_POSXY_P"], accel) / speed
        return n + vn * stop, e + ve * stop, up

    def _text(self, severity: int, message: str) -> None:
        self._outbox.append(statustext(severity, message))

    def _flush(self) -> list[Any]:
        out, self._outbox = self._outbox, []
        return [stamp(msg, self.system_id, AUTOPILOT) for msg in out]

    # ---------------------------------------------------------- what messages read
    @property
    def velocity(self) -> Vector:
        """(north, east, up) in m/s."""
        return self.body.velocity

    @property
    def landing(self) -> bool:
        """True while descending to touch down (LAND, RTL's last phase, NAV_LAND)."""
        return self._landing is not None

    @property
    def in_failsafe(self) -> bool:
        """True while any failsafe (battery, GCS, EKF, fence) is active."""
        return bool(self.failsafes.active)

    def global_position(self) -> Vector:
        """Latitude, longitude (degrees) and altitude above mean sea level (m)."""
        return self._global(self.position)

    def home_local(self) -> Vector:
        """Home in the local frame."""
        return self._home_local()

    def guided_target(self) -> tuple[Vector, Vector | None] | None:
        """What GUIDED flies to, as ArduCopter reports it: (position in the local frame,
        its latitude, longitude and altitude AMSL) for a point, (velocity north, east, up,
        None) under a velocity target, None without a target or in any other mode."""
        if self.mode != "GUIDED" or not self.armed or self.landed:
            return None
        target = self._target
        if target is not None:
            # Both POSITION_TARGET messages ask, every time they stream, for a target that
            # seldom changes: its conversion is kept for the same target and origin objects.
            o = self.origin
            last_target, last_origin, last = self._last_target_global
            if target is last_target and o is last_origin:
                return target, last
            converted = to_global(*target, o.latitude, o.longitude, o.altitude)
            self._last_target_global = (target, o, converted)
            return target, converted
        if self._velocity is not None:
            velocity, expiry = self._velocity
            return (velocity if self.time < expiry else (0.0, 0.0, 0.0)), None
        return None

    def gps_noise(self) -> float:
        """A draw of receiver noise in degrees (about 0.3 m), from the vehicle's seed."""
        return 1e-7 * self._rng.uniform(-3.0, 3.0)

    def mission_status(self) -> tuple[int, int, int]:
        """(seq, item count without home, MISSION_STATE) for MISSION_CURRENT."""
        total = max(self.missions.count(MISSION) - 1, 0)
        if self.auto is not None:
            state = M.MISSION_STATE_COMPLETE if self.auto.finished else M.MISSION_STATE_ACTIVE
            return self.auto.current, total, state
        state = M.MISSION_STATE_NOT_STARTED if total else M.MISSION_STATE_NO_MISSION
        return self._mission_current, total, state

