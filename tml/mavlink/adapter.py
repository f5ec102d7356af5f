"""The Vehicle interface of :mod:`tml.vehicle` over a MAVLink link: ``MavlinkVehicle``.

Theory of operation
-------------------
The interpreter reads :class:`~tml.vehicle.VehicleState` and submits requests without ever
waiting; a MAVLink vehicle answers commands in round trips of tens of milliseconds (and
seconds when the link is poor). So each request is carried out as a *procedure*
(:mod:`tml.mavlink.steps`): a generator that yields each exchange with the vehicle (a
command, a mode change, a mission transfer, a parameter read) and each wait for the
telemetry to show something, and is resumed when that step is over. The link's reactor
drives the procedures (:meth:`~tml.mavlink.link.Link.begin`): ``submit`` only queues the
request, the reactor begins it after the one before it and resumes it as the vehicle
answers, and ``poll`` returns the :class:`~tml.vehicle.RequestResult` of the requests
finished since the last poll. A fleet of any size has no thread per vehicle: the one
thread that reads every link also carries out every request. What must be done
periodically besides -- the streams asked again when they stay away
(:data:`STREAM_CHECK_PERIOD`), the GUIDED target kept -- is done by the link listener at the
vehicle's HEARTBEAT, and the pilot's sticks a FLIP holds (:class:`_Sticks`) are sent
again by the reactor as one of the link's duties.

``state`` is built on demand from the link's latest :class:`~tml.mavlink.telemetry.Telemetry`
snapshot: local position from GLOBAL_POSITION_INT relative to HOME_POSITION (via
:mod:`tml.geo`), heading from ATTITUDE, ground speed, battery, landed from
EXTENDED_SYS_STATE, ``ready`` from the EKF flags. Three things need more than the snapshot,
and come from a listener on the link that sees every message of this vehicle:

- *link health* (:class:`~tml.mavlink.health.LinkHealth`): how long since the last
  HEARTBEAT, in the vehicle's own stamps and on ``link_clock``, and the messages lost.
  ``link_clock`` is the runner's clock by default (the simulator's clock in ``--sim``, so
  that a speed-up does not make the link look faster than the vehicle), the local clock
  under ``--clock vehicle``, whose time between the vehicle's stamps is extrapolated (an
  ArduPilot SITL starved of CPU falls silent without its own time passing; extrapolated at
  its speed-up, that silence would look like a failing link);
- *detections* from the companion computer (component 191, see sitl/companion.py for the
  protocol): each NAMED_VALUE_INT ``ITEM``/``BUCKET``/``MARKER``/``ARUCO``/``FRAME`` report
  keeps the object in the matching ``RECOGNIZED_*`` set for ``detection_hold`` s; objects
  are named by their world ident when the world is known (so ``"Item A found"`` works),
  else by number; other NAMED_VALUE names are passed through as detection parameters;
- *mission progress* of the last :class:`~tml.vehicle.FlyMission`: MISSION_CURRENT and
  MISSION_ITEM_REACHED seqs are mapped back to action indices with the item map of
  :mod:`tml.mavlink.compile`;
- *the GUIDED target kept*: a position target (GoTo) or a velocity target of zero (Hold: the
  vehicle brakes within its limits and holds where it stopped, rather than fly past the
  point where it was told and back) is a message nobody acknowledges, and one lost on a
  poor link would leave the vehicle doing what it did; so the last one is sent
  again at each HEARTBEAT (at most every ``TARGET_PERIOD`` s) while the vehicle is in GUIDED,
  until another request takes its place. After a SetYaw the kept target carries that
  heading: a target without a yaw hands the heading back to the autopilot (ArduCopter's
  WP_YAW_BEHAVIOR), which would stop the turn where it is.

*FLIP.* ArduCopter refuses FLIP from GUIDED: it flips only from a mode flown by the pilot's
sticks (ACRO, STABILIZE, ALT_HOLD), armed and flying, and returns to that mode when the flip
is over (ArduCopter's mode_flip.cpp). A :class:`~tml.vehicle.Flip` is therefore carried out
as a pilot would: the sticks are held by RC_CHANNELS_OVERRIDE (:class:`_Sticks`: throttle
mid-stick, so that ALT_HOLD neither climbs nor sinks, the others centred), the vehicle is
switched to ALT_HOLD, the roll or pitch stick leans toward the flip's direction while FLIP is
asked for (ArduCopter reads the direction from the sticks when the flip starts), the flip is
waited out (telemetry shows FLIP, or a roll beyond 57 degrees, then the mode it came from),
the vehicle goes back to GUIDED, and only then are the sticks released. Whatever fails on the
way, the vehicle is put back in GUIDED before the sticks are let go: in ALT_HOLD a released
throttle stick is a throttle at zero, and the vehicle would sink.

Requests are carried out the way the vehicle's kind flies them (:mod:`tml.language.kinds`, from the
HEARTBEAT type), after ArduPilot's Copter, Plane and Rover as measured on their SITL:

- *fixed-wing* (ArduPlane): TakeOff sets TKOFF_ALT and switches to TAKEOFF mode, which arms
  and climbs (NAV_TAKEOFF is refused in GUIDED); GoTo, Circle and Hold are DO_REPOSITION
  (which enters GUIDED; ArduPlane takes only the altitude of a
  SET_POSITION_TARGET_GLOBAL_INT) with the loiter radius in param3; Land is a landing
  sequence (:func:`tml.mavlink.compile.glide_items`) uploaded and flown in AUTO, since
  ArduPlane has no LAND mode and answers NAV_LAND UNSUPPORTED; ReturnToLaunch is RTL,
  which circles home (the safe state);
- *ground* (Rover): altitudes are 0 (a rover has none to report; Rover SITL may even
  report the ground's height above the sea as GLOBAL_POSITION_INT.relative_alt, when its
  home was set before its field elevation at start-up); Hold is HOLD mode; a speed
  is sent after the position target, since Rover takes DO_CHANGE_SPEED only while it
  drives to one; TakeOff and Land are unsupported (Rover answers NAV_TAKEOFF and NAV_LAND
  UNSUPPORTED).

Skills are bound to the vehicle through :data:`SKILL_BINDINGS` (documented in docs/run.md).
Every failure becomes a result, never an exception: ``rejected`` (the vehicle refused: the
COMMAND_ACK or MISSION_ACK result is the detail), ``timeout``, ``unsupported`` (the vehicle
lacks what the request needs) or ``general``.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import partial
from types import MappingProxyType
from typing import Any

from tml.errors import CommandRejected, MissionTransferError, VehicleError, VehicleTimeout
from tml.geo import to_global, to_local
from tml.language.failures import FailureReason
from tml.language.kinds import HANDLING, Kind, kind_of
from tml.mavlink import codec
from tml.mavlink.autopilot import (
    DEFAULT_RATES,
    LAND,
    PHOTO,
    RETURN_TO_LAUNCH,
    Autopilot,
    arm_command,
    current_command,
    disarm_command,
    gripper_command,
    reposition_command,
    set_home_command,
    speed_command,
    start_command,
    takeoff_command,
    yaw_command,
)
from tml.mavlink.codec import mavlink
from tml.mavlink.command import CommandLong
from tml.mavlink.compile import (
    SPEED_TYPES,
    CompiledMission,
    CompileError,
    compile_mission,
    glide_items,
)
from tml.mavlink.health import LinkHealth
from tml.mavlink.link import Link
from tml.mavlink.mission import MissionType
from tml.mavlink.modes import ModeWatch, mode_names
from tml.mavlink.reboot import RebootWatch, is_boot_text
from tml.mavlink.safeguards import fence_action, safeguards
from tml.mavlink.steps import Steps, Until
from tml.mavlink.telemetry import COMPANION_COMPONENT, Telemetry
from tml.vehicle import (
    FLIGHT_REQUESTS,
    MESSAGES_KEPT,
    Arm,
    AutopilotMessage,
    Camera,
    Circle,
    Disarm,
    Flip,
    FlyMission,
    GoTo,
    Gripper,
    Hold,
    Land,
    MissionProgress,
    Request,
    RequestResult,
    ReturnToLaunch,
    Safeguard,
    SetHome,
    SetMode,
    SetSkill,
    SetSpeed,
    SetYaw,
    TakeOff,
    VehicleState,
)
from tml.world import Home, World

Clock = Callable[[], float]

SHOWN_BY: Mapping[str, frozenset[str]] = MappingProxyType({
    kind: frozenset(names) for kind, names in {
        # (A mission's progress ends when the vehicle is seen disarmed, and a ground
        # vehicle's position has no altitude: see state.)
        "HEARTBEAT": ("armed", "mode", "landed", "prearm", "taken", "vehicle_type",
                      "mission", "position"),
        "GLOBAL_POSITION_INT": ("position", "ground_speed", "climb"),
        "HOME_POSITION": ("home", "position"),
        "ATTITUDE": ("heading", "heading_known"),
        "SYS_STATUS": ("battery", "voltage", "armable"),
        "EXTENDED_SYS_STATE": ("landed",),
        "GPS_RAW_INT": ("gps_fix", "satellites"),
        "EKF_STATUS_REPORT": ("ready",),
        "STATUSTEXT": ("status_text", "messages", "prearm"),
    }.items()})
"""The fields of a :class:`~tml.vehicle.VehicleState` (as :meth:`MavlinkVehicle.state` builds
them from the link's snapshot) that a message of each kind from the autopilot may change: a
watcher told only these (:meth:`MavlinkVehicle.watch`) need not look at the vehicle when it
reads none of them. A kind not here may change any field. (``current`` turns true with one
of :data:`VITAL`, once after each request, and ``link`` turns back to ``ok`` with a message
after a silence: each is told as a change of any field.)"""
Watcher = Callable[[frozenset[str] | None], None]
"""What :meth:`MavlinkVehicle.watch` calls: with the fields that may have changed (None: any)."""
VITAL = ("HEARTBEAT", "EXTENDED_SYS_STATE", "GLOBAL_POSITION_INT")
"""The messages of the readings the rules judge by: armed and mode, landed, position."""
STREAM_CHECK_PERIOD = 2.0
"""Seconds at least between two checks (at a HEARTBEAT) that the streams asked for arrive."""
CLOSE_WAIT = 10.0
"""Wall seconds :meth:`MavlinkVehicle.close` waits for the requests submitted to be carried out."""
STAMP_SILENCE = 1.5
"""Seconds (the link's clock) without a ``time_boot_ms`` stamp from the autopilot after which
its HEARTBEAT brings a new request for the streams: a rebooted autopilot has forgotten
them, and its reboot shows only in the stamps (tml.mavlink.reboot) -- the sooner they come,
the clearer the clock's fall."""
PARAM_TIMEOUT = 1.0
PARAM_RETRIES = 3
"""Times a PARAM_REQUEST_READ is sent, PARAM_TIMEOUT s apart, before the parameter is taken
as absent (an autopilot does not answer for a parameter it does not have)."""
PARAM_SET_RETRIES = 12
"""Times a PARAM_SET is sent before its PARAM_VALUE is given up: at 30 % loss each way one
exchange in two fails, and a flight's pre-flight writes (the fence's parameters) must not
fail on that (12 in a row: 1 in 3,000)."""

AUTOPILOT = "autopilot"
COMPANION = "companion"

MID_STICK = 1500
"""PWM of a centred stick, and of a throttle that holds the altitude in ALT_HOLD."""
FLIP_LEAN = 100
"""Microseconds a stick leans toward the flip's direction: ArduCopter's flip pitches when the
pitch stick is beyond 300 centidegrees (of 4500), rolls left below 0 roll."""
FLIP_STICKS = {"front": (MID_STICK, MID_STICK - FLIP_LEAN),
               "back": (MID_STICK, MID_STICK + FLIP_LEAN),
               "left": (MID_STICK - FLIP_LEAN, MID_STICK),
               "right": (MID_STICK, MID_STICK)}
"""Flip direction -> (roll, pitch) stick while FLIP is asked for (a centred roll rolls right)."""
STICK_PERIOD = 0.04
"""Seconds between RC_CHANNELS_OVERRIDE messages: ArduPilot drops an override older than
RC_OVERRIDE_TIME (3 s of its own clock, 0.3 s of wall time at a speed-up of 10), and at 25 Hz
seven in a row must be lost for that."""
TAKEOFF_ATTEMPTS = 3
"""Take-offs tried, arming again in between, when the vehicle disarmed by itself meanwhile."""
TARGET_PERIOD = 0.5
"""Seconds at least between two copies of the GUIDED target kept."""
FLIP_WAIT = 10.0
"""Seconds to wait for a flip to be over (ArduCopter abandons one after 2.5 s)."""


@dataclass(frozen=True)
class _Aim:
    """The GUIDED target kept: a point (latitude, longitude, metres above home), or a stop
    where the vehicle can (no point); ``yaw`` in degrees from north, None: the autopilot's
    choice."""

    point: tuple[float, float, float] | None
    yaw: float | None = None


@dataclass(frozen=True)
class SkillBinding:
    """How a skill is switched: parameters set to 1 (on) and 0 (off) on a component."""

    component: str  # AUTOPILOT or COMPANION
    parameters: tuple[str, ...]
    autopilot_on: tuple[tuple[str, float], ...] = ()  # autopilot parameters set while on


SKILL_BINDINGS: dict[str, SkillBinding] = {
    # The companion's rangefinder feeds ArduCopter's proximity avoidance (AVOID_ENABLE bit 2
    # "proximity"; 3 = fence + proximity) which stops AVOID_MARGIN metres short.
    "AVOID_OBSTACLES": SkillBinding(COMPANION, ("AVOID_OBST",), (("AVOID_ENABLE", 3),)),
    "RECOGNIZE_VISUAL_MARKERS": SkillBinding(COMPANION, ("RECOG_MARKERS",)),
    "RECOGNIZE_FRAMES": SkillBinding(COMPANION, ("RECOG_MARKERS",)),
    "RECOGNIZE_ARUCO_MARKERS": SkillBinding(COMPANION, ("RECOG_ARUCO",)),
    "DETECT_OBSTACLES_BY_ARUCO_MARKERS": SkillBinding(COMPANION, ("RECOG_ARUCO",)),
    "SELF_LOCATE_BY_MARKERS": SkillBinding(COMPANION, ("SELF_LOCATE",)),
    "RECOGNIZE_ITEMS": SkillBinding(COMPANION, ("RECOG_ITEMS",)),
    "RECOGNIZE_BUCKETS": SkillBinding(COMPANION, ("RECOG_BUCKETS",)),
}
"""Skill name -> what switching it does (SAY_OUT_LOUD_CURRENT_TASK has no vehicle side)."""
_ALL_SKILLS: Mapping[str, str] = MappingProxyType({name: "" for name in SKILL_BINDINGS})
_SKILLS_WITHOUT_COMPANION: Mapping[str, str] = MappingProxyType({
    name: f"needs a companion computer (component {COMPANION_COMPONENT}), not heard yet"
    if binding.component == COMPANION else "" for name, binding in SKILL_BINDINGS.items()})
"""The skills a vehicle switches, with what stops them before its companion is heard."""

DETECTION_SETS = {"ITEM": "RECOGNIZED_ITEMS", "SUBJECT": "RECOGNIZED_ITEMS",
                  "BUCKET": "RECOGNIZED_BUCKETS", "MARKER": "RECOGNIZED_VISUAL_MARKERS",
                  "ARUCO": "RECOGNIZED_ARUCO_MARKERS", "FRAME": "RECOGNIZED_FRAMES"}
"""Companion NAMED_VALUE_INT name -> the TML parameter (a set) it feeds."""
TAG_KINDS = {"ITEM": "item", "SUBJECT": "subject", "BUCKET": "bucket", "MARKER": "marker",
             "ARUCO": "aruco", "FRAME": "frame"}


def detection_names(world: World | None) -> dict[tuple[str, int], str]:
    """(tag, number) -> the name a detection stands for, from the world's objects.

    The companion reports an object by its ident when that is an integer, else by its
    1-based rank among the world's objects of its kind; frames are named by colour.
    """
    names: dict[tuple[str, int], str] = {}
    ranks: dict[str, int] = {}
    tags = {kind: tag for tag, kind in TAG_KINDS.items()}
    for obj in world.objects if world else ():
        ranks[obj.kind] = ranks.get(obj.kind, 0) + 1
        ident = obj.ident.strip()
        number = int(ident) if ident.lstrip("-").isdigit() else ranks[obj.kind]
        names[(tags[obj.kind], number)] = obj.color if obj.kind == "frame" and obj.color \
            else ident
    return names


class _Plan:
    """The compiled mission being flown, and what the vehicle has said about it."""

    def __init__(self, plan_id: int, compiled: CompiledMission, offset: int) -> None:
        self.plan_id = plan_id
        self.compiled = compiled
        self.offset = offset  # wire seq of compiled item 0 (1 behind ArduPilot's home)
        self.started = False
        self.current = 0
        self.finished = False
        navs = [i for i, item in enumerate(compiled.items) if item.command < _NAV_LAST]
        self.last_nav = navs[-1] if navs else None
        # ArduPilot reports a landing item reached only once it is on the ground.
        self.ends_landed = self.last_nav is not None and compiled.items[self.last_nav].command \
            in (mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)

    def progress(self) -> MissionProgress:
        index = self.compiled.action_at(self.current)
        last = len(self.compiled.items) and self.compiled.action_index[-1]
        items = len(self.compiled.items)
        return MissionProgress(self.plan_id, last if index is None else index, self.finished,
                               item=items if self.finished else self.current + 1, items=items)

    def seen(self, msg: Any) -> None:
        """Fold in a MISSION_CURRENT or MISSION_ITEM_REACHED."""
        if not self.started:
            return
        index = msg.seq - self.offset
        if msg.get_type() == "MISSION_CURRENT":
            if getattr(msg, "mission_state", 0) == mavlink.MISSION_STATE_COMPLETE:
                self.finished = True
            elif index >= 0:
                self.current = max(self.current, min(index, len(self.compiled.items) - 1))
        elif index >= 0:
            self.current = max(self.current, min(index + 1, len(self.compiled.items) - 1))
            if index == self.last_nav:
                self.finished = True


_NAV_LAST = 95  # MAV_CMD ids below this are navigation commands (ArduPilot's numbering)


class MavlinkVehicle:
    """One vehicle of a :class:`~tml.mavlink.link.Link`, as the interpreter sees it."""

    def __init__(self, link: Link, system_id: int, *, vehicle_id: int | None = None,
                 clock: Clock = time.monotonic, world: World | None = None,
                 lost_after: float = 5.0, degraded_after: float = 2.5,
                 detection_hold: float = 1.5, command_timeout: float = 1.5,
                 connect_timeout: float = 10.0, ready_timeout: float = 120.0,
                 on_result: Callable[[], None] | None = None,
                 link_clock: Clock | None = None) -> None:
        self.link = link
        self.timebase = link.timebase  # every wait and period of the vehicle (tml.timebase)
        self.mav = Autopilot(link, link.wait_vehicle(system_id, connect_timeout),
                           command_timeout=command_timeout)
        self.system_id = system_id
        self.vehicle_id = system_id if vehicle_id is None else vehicle_id
        self.clock = clock
        self.link_clock = clock if link_clock is None else link_clock  # see the module doc
        self.health = LinkHealth(lost_after, degraded_after)
        self.detection_hold = detection_hold
        self.ready_timeout = ready_timeout  # wall s a mission upload waits for home/EKF
        self.on_result = on_result  # called when a result is ready (wakes the runner)
        self.capabilities: frozenset[str] = frozenset({"camera"})
        self._names = detection_names(world)
        self._lock = threading.Lock()
        self._results: list[RequestResult] = []
        # Requests submitted and not yet carried out: the one being carried out (by the
        # link's reactor, see submit) and those queued behind it (guarded by _requests).
        self._requests = threading.Condition(threading.Lock())
        self._queued: deque[Request] = deque()
        self._pending = 0
        self._streams_checked = self.timebase.now()  # when _keep_streams last looked
        self._params: dict[tuple[int, str], float] = {}  # PARAM_VALUEs awaited (_fold)
        self._params_lock = threading.Lock()
        self._seen: dict[tuple[str, int], float] = {}
        self._values: dict[str, float] = {}
        self._plan: _Plan | None = None
        self._changes = 0  # counts what changes the state besides the link's snapshot
        self._progress: MissionProgress | None = None
        self._cache: tuple[Any, Any, tuple[float, float, float] | None] = (None, None, None)
        # (status_texts, their count, the messages built of them): see _latest_messages
        self._said: tuple[object, int, tuple[AutopilotMessage, ...]] = (None, -1, ())
        self._companion_seen = False
        self._target: _Aim | None = None  # kept in GUIDED
        self._target_sent = 0.0
        self._ground_speed: float | None = None  # a rover's speed, sent with each target
        # Tells a mode change nobody here asked for (a fixed-wing ends its mission in RTL).
        self._modes = ModeWatch(
            kind_of(link.telemetry(system_id).airframe) is Kind.FIXED_WING)
        self._reboots = RebootWatch()  # the autopilot's clock going back: a new boot
        self._stamps_asked = -math.inf  # when the streams were last asked for by _keep_stamps
        self._stamped_at: float | None = None  # when the autopilot's last stamp came
        self._asked: float | None = None  # when the latest request was submitted or done
        self._flight_asked: float | None = None  # ... the latest of FLIGHT_REQUESTS
        self._flights_pending = 0  # FLIGHT_REQUESTS submitted and not yet carried out
        self._vital_at: dict[str, float] = {}  # when each VITAL message last came (clock)
        self._watchers: tuple[Watcher, ...] = ()  # see watch
        self._handled: str | None = None  # the kind of the autopilot's message being handled
        self._current = False  # the state has shown current since the latest request
        self._link_shown = "ok"  # the link's health when last judged (see _fold)
        link.listen(self._on_message)
        link.on_change(self._link_changed)

    # --- set-up ---------------------------------------------------------------------------

    def prepare(self) -> None:
        """Ask for telemetry rates and find out what the vehicle can do (blocks).

        ``gripper`` when the autopilot's GRIP_ENABLE is set; ``flip`` when the flight-mode
        table of the vehicle's type and autopilot (pymavlink's) has a FLIP mode.
        """
        self.mav.request_rates()
        capabilities = {"camera"}
        grip = self.mav.do(self._read_param("GRIP_ENABLE"))
        if grip is not None and grip > 0:
            capabilities.add("gripper")
        info = self.mav.info
        if "FLIP" in mode_names(info.vehicle_type, info.autopilot):
            capabilities.add("flip")
        self.capabilities = frozenset(capabilities)
        self._changes += 1
        self._stir()

    # --- the Vehicle protocol ---------------------------------------------------------------

    def state(self) -> VehicleState:
        """The latest state, built from the link's telemetry snapshot."""
        t = self.link.telemetry(self.system_id)
        now = self.clock()
        home = _home(t)
        position = self._local_position(t, home)
        if position is not None and kind_of(t.airframe) is Kind.GROUND:
            position = (position[0], position[1], 0.0)  # see the module docstring
        velocity = t.velocity or (0.0, 0.0, 0.0)
        landed = t.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND \
            if t.landed_state else not t.armed
        with self._lock:
            detections = self._detections(now)
            plan = self._plan
            if plan is not None and plan.started and not t.armed:
                plan.finished = True  # disarmed: whatever was left will not be flown
            if plan is not None and plan.finished and plan.ends_landed:
                landed = True  # EXTENDED_SYS_STATE may lag the final MISSION_ITEM_REACHED
            progress = plan.progress() if plan is not None else self._progress
        link = self._link_shown = self.health.state(self.link_clock())
        return VehicleState(
            vehicle_id=self.vehicle_id, time=now, link=link,
            ready=t.position_ready, armable=t.prearm_ok, prearm=t.prearm_text if not t.armed
            else "", armed=t.armed, landed=landed, mode=t.mode,
            position=position,
            heading=math.degrees(t.attitude[2]) % 360.0 if t.attitude else 0.0,
            heading_known=t.attitude is not None,
            ground_speed=math.hypot(velocity[0], velocity[1]),
            battery=None if t.battery_remaining is None else float(t.battery_remaining),
            gps_fix=t.gps_fix, satellites=t.satellites, voltage=t.battery_voltage,
            climb=-velocity[2], home=home, mission=progress, detections=detections,
            capabilities=self.capabilities, skills=self._skills(), vehicle_type=t.airframe,
            status_text=t.status_texts[-1].text if t.status_texts else "",
            messages=self._latest_messages(t), rejected=t.rejected, rejected_last=t.rejected_last,
            taken=self._modes.taken, heard=self._heard(now),
            # A request not yet carried out is asked for now: no reading is newer than it.
            asked=now if self._pending else self._asked,
            rebooted="" if self._reboots.reboot is None else str(self._reboots.reboot),
            reboots=self._reboots.count,
            flight_asked=now if self._flights_pending else self._flight_asked)

    def _skills(self) -> Mapping[str, str]:
        """Each skill of :data:`SKILL_BINDINGS` and why it cannot be switched now ("": it
        can): one bound to the companion computer needs its HEARTBEAT first."""
        if self._companion_seen:
            return _ALL_SKILLS
        return _SKILLS_WITHOUT_COMPANION

    def _heard(self, now: float) -> float:
        """When (the runner's clock) the oldest of the readings the rules judge by arrived
        (:data:`VITAL`); minus infinity before any has."""
        # Noted on the runner's clock as each arrives (_on_message): the link's own arrival
        # times are on its time base, which a simulator's clock outruns at its speed-up --
        # a HEARTBEAT from before an Arm looked newer than the Arm, and an aborted run left
        # the vehicle climbing, judged disarmed on the ground.
        times = [self._vital_at[name] for name in VITAL if name in self._vital_at]
        return min(times) if times else -math.inf

    def calm(self) -> float:
        """Seconds from now in which time alone changes nothing :meth:`state` shows (the
        link's health while nothing arrives, a detection's hold running out): whatever
        else changes it is told to the watchers (:meth:`watch`)."""
        quiet = self.health.calm(self.link_clock())
        if self._seen:
            now = self.clock()
            with self._lock:
                for when in self._seen.values():
                    left = when + self.detection_hold - now
                    if left >= 0.0:
                        quiet = min(quiet, left)
        return quiet

    def _shows_current(self, now: float) -> bool:
        """Whether :meth:`state` shows ``current`` at ``now``."""
        asked = now if self._pending else self._asked
        return asked is None or self._heard(now) > asked

    def revision(self) -> tuple[int, int]:
        """Changes when :meth:`state` may show something new, apart from what time alone
        changes (the link's health, detections held past ``detection_hold``): equal
        revisions, equal state. A runner reads this to rebuild only the states that changed."""
        return self.link.revision(self.system_id), self._changes

    def watch(self, watcher: Watcher) -> Callable[[], None]:
        """Call ``watcher(fields)`` whenever :meth:`revision` may have changed, or a result
        is ready -- from the thread that saw it (the link's reactor; :meth:`submit`'s caller
        for a request over before its first step) -- with the names of the state's fields that
        may show something new (:data:`SHOWN_BY`; None: any). It must return quickly.
        Returns the function that stops the calls."""
        self._watchers = (*self._watchers, watcher)

        def unwatch() -> None:
            self._watchers = tuple(w for w in self._watchers if w is not watcher)
        return unwatch

    def _stir(self, fields: frozenset[str] | None = None) -> None:
        for watcher in self._watchers:
            watcher(fields)

    def _link_changed(self, system_id: int) -> None:
        if system_id == self.system_id:
            # The link tells a change after its listeners saw the message (_on_message);
            # one told with no message before it (the link found lost) may change anything.
            kind, self._handled = self._handled, None
            self._stir(None if kind is None else SHOWN_BY.get(kind))

    def submit(self, request: Request) -> None:
        """Have the request carried out after those submitted before it; never waits for
        the vehicle.

        A request is a procedure (:mod:`tml.mavlink.steps`), begun here when none is under
        way -- its first message goes out before this returns -- and carried on by the
        link's reactor, which resumes it as the vehicle answers and then begins the next:
        no thread of its own. A relative SetYaw is made absolute here, against the heading the
        interpreter has just seen: by the time it is sent the vehicle may have turned
        further, and the interpreter waits for the heading it computed.
        """
        if isinstance(request, SetYaw) and request.relative:
            heading = (self.state().heading + request.heading) % 360.0
            request = replace(request, heading=heading, relative=False)
        now = self.clock()  # read outside the lock: a vehicle clock reads the link's
        with self._lock:
            self._asked = now
            self._current = False
            if isinstance(request, FLIGHT_REQUESTS):
                self._flight_asked = now
                self._flights_pending += 1
            self._changes += 1
        with self._requests:
            self._pending += 1
            if self._pending > 1:
                self._queued.append(request)
                return
        self._begin(request)

    def _begin(self, request: Request) -> None:
        self.link.begin(self._carry_out(request), self.system_id, self.mav.component_id,
                        partial(self._ended, request))

    def _ended(self, request: Request, result: RequestResult | None,
               error: BaseException | None) -> None:
        """A request's procedure is over (told by the thread that resumed it last, the
        reactor's as a rule): its result is ready, and the next request begins."""
        if result is None:  # ended by what _carry_out does not expect (a link closed)
            result = RequestResult(self.vehicle_id, request.request_id, False,
                                   FailureReason.GENERAL, f"{type(error).__name__}: {error}")
        self._carried_out(request)
        with self._lock:
            self._results.append(result)
        with self._requests:
            self._pending -= 1
            following = self._queued.popleft() if self._queued else None
            self._requests.notify_all()
        if self.on_result is not None:
            self.on_result()
        self._stir()
        if following is not None:
            self._begin(following)

    def poll(self) -> list[RequestResult]:
        """Results finished since the last poll."""
        if not self._results:  # most polls: nothing, and no lock taken to say so
            return []
        with self._lock:
            results, self._results = self._results, []
        return results

    def close(self) -> None:
        """Return once the requests submitted so far are carried out (waits up to
        :data:`CLOSE_WAIT` wall seconds)."""
        end = time.monotonic() + CLOSE_WAIT
        with self._requests:
            while self._pending and (left := end - time.monotonic()) > 0:
                self._requests.wait(left)

    def idle(self) -> bool:
        """True when every submitted request has been carried out."""
        return self._pending == 0

    # --- state pieces -------------------------------------------------------------------

    def _local_position(self, t: Telemetry, home: Home | None
                        ) -> tuple[float, float, float] | None:
        p = t.position
        if p is None or home is None or (p.latitude == 0 and p.longitude == 0):
            return None  # no fix yet: ArduPilot reports 0, 0
        if self._cache[0] is p and self._cache[1] == home:
            return self._cache[2]
        north, east, _ = to_local(p.latitude, p.longitude, home.altitude,
                                  home.latitude, home.longitude, home.altitude)
        local = (north, east, p.relative_altitude)
        self._cache = (p, home, local)
        return local

    def _latest_messages(self, t: Telemetry) -> tuple[AutopilotMessage, ...]:
        """:func:`_messages`, built again only when a new STATUSTEXT came (a state is
        built at most messages)."""
        said = self._said
        if said[0] is t.status_texts and said[1] == t.status_text_count:
            return said[2]
        messages = _messages(t)
        self._said = (t.status_texts, t.status_text_count, messages)
        return messages

    def _detections(self, now: float) -> Mapping[str, object]:
        if not self._seen and not self._values:
            return _NO_DETECTIONS  # most vehicles, at every state built
        sets: dict[str, set[str]] = {}
        for (tag, number), when in self._seen.items():
            if now - when > self.detection_hold:
                continue
            name = self._names.get((tag, number), str(number))
            sets.setdefault(DETECTION_SETS[tag], set()).add(name)
        found: dict[str, object] = dict(self._values)
        found.update((k, frozenset(v)) for k, v in sets.items())
        return MappingProxyType(found)

    # --- the link listener (receive thread: must be quick) --------------------------------

    def _on_message(self, system_id: int, snapshot: Telemetry, msg: Any) -> None:
        if system_id != self.system_id:
            return
        changes = self._changes
        self._fold(snapshot, msg)
        if self._changes != changes:
            self._handled = None
            self._stir()

    def _fold(self, snapshot: Telemetry, msg: Any) -> None:
        """Take in what a message of this vehicle's says beyond the link's snapshot."""
        kind = msg.get_type()
        component = msg.get_srcComponent()
        self._handled = kind if component == self.mav.component_id else None
        now = self.clock()
        if kind in VITAL and component == self.mav.component_id:
            self._vital_at[kind] = now
            if not self._current and self._shows_current(now):
                self._current = True
                self._changes += 1  # a change a watcher cannot tell from the kind
        if component == COMPANION_COMPONENT and not self._companion_seen:
            self._companion_seen = True
            self._changes += 1  # its skills can be switched from now on
        if component == self.mav.component_id:
            at = self.link_clock()
            beat = kind == "HEARTBEAT"
            self.health.heard(at, beat, snapshot.boot_time, snapshot.received, snapshot.lost)
            # A message changes the link's health only after a silence, or by the losses a
            # HEARTBEAT counts: judged again then, not at every message.
            if beat or self._link_shown != "ok":
                link = self.health.state(at)
                if link != self._link_shown:
                    self._link_shown = link
                    self._changes += 1
            boot_ms = getattr(msg, "time_boot_ms", None)
            if boot_ms is not None:
                self._stamped_at = at
                with self._lock:
                    if self._reboots.seen(boot_ms / 1000, at):
                        self._changes += 1
        if kind == "HEARTBEAT" and component == self.mav.component_id:
            with self._lock:
                self._modes.seen(snapshot.mode, snapshot.armed, self.link_clock())
                self._reboots.heartbeat(snapshot.armed)
                if msg.system_status == mavlink.MAV_STATE_BOOT and \
                        self._reboots.boot_sign(self.link_clock()):
                    self._changes += 1
            self._keep_target(snapshot)
            self._keep_stamps()
            if self.timebase.now() - self._streams_checked >= STREAM_CHECK_PERIOD:
                self._streams_checked = self.timebase.now()
                with contextlib.suppress(OSError):
                    self._keep_streams()
        elif kind == "STATUSTEXT" and component == self.mav.component_id:
            if is_boot_text(_text(msg.text)):
                with self._lock:
                    if self._reboots.boot_sign(self.link_clock()):
                        self._changes += 1
        elif kind == "PARAM_VALUE":
            with self._params_lock:  # an Until of _param_exchange sees it (no notify)
                self._params[(component, _text(msg.param_id))] = msg.param_value
        elif kind in ("MISSION_CURRENT", "MISSION_ITEM_REACHED"):
            with self._lock:
                if self._plan is not None:
                    self._plan.seen(msg)
                    self._changes += 1
        elif component == COMPANION_COMPONENT and kind in ("NAMED_VALUE_INT",
                                                            "NAMED_VALUE_FLOAT"):
            name = _text(msg.name)
            with self._lock:
                if kind == "NAMED_VALUE_INT" and name in DETECTION_SETS:
                    self._seen[(name, int(msg.value))] = now
                else:
                    self._values[name] = msg.value
                self._changes += 1

    def _keep_stamps(self) -> None:
        """Ask again for the streams when the autopilot beats but sends no stamp (see
        :data:`STAMP_SILENCE`); at most once per silence period."""
        now = self.link_clock()
        if self._stamped_at is None or now - self._stamped_at < STAMP_SILENCE \
                or now - self._stamps_asked < STAMP_SILENCE:
            return
        self._stamps_asked = now
        with contextlib.suppress(OSError):
            for name, hz in DEFAULT_RATES.items():
                if name != "HEARTBEAT" and hz > 0:
                    self.mav.ask_again(name, hz)

    def _keep_target(self, snapshot: Telemetry) -> None:
        target = self._target
        now = self.timebase.now()
        if target is None or snapshot.mode != "GUIDED" or self._modes.taken \
                or now - self._target_sent < TARGET_PERIOD:
            return
        self._target_sent = now
        with contextlib.suppress(OSError):
            self._send_target(target)

    def _aim(self, latitude: float, longitude: float, altitude: float) -> None:
        """Send a GUIDED position target, and keep it (see the module docstring)."""
        self._keep_aim(_Aim((latitude, longitude, altitude)))

    def _keep_aim(self, aim: _Aim) -> None:
        self._target = aim
        self._target_sent = self.timebase.now()
        self._send_target(aim)

    def _send_target(self, aim: _Aim) -> None:
        if aim.point is None:
            self.mav.stop_target(aim.yaw)
        else:
            self.mav.position_target(*aim.point, aim.yaw)

    # --- carrying requests out -----------------------------------------------------------

    def _carried_out(self, request: Request) -> None:
        """A request has gone out and been answered (or given up): what the vehicle shows
        counts for it from now on. A reading that arrived while it waited in the queue or
        was being sent says nothing about it -- an Arm still queued when the run is
        aborted would otherwise be judged from a 'disarmed' heard before it went out, and
        arm the vehicle after the abort decided it was safe."""
        now = self.clock()
        with self._lock:
            self._asked = now
            self._current = False
            if isinstance(request, FLIGHT_REQUESTS):
                self._flight_asked = now
                self._flights_pending -= 1
            self._changes += 1

    def _keep_streams(self) -> None:
        """Ask again for each stream that stays away (the request or its answer was lost,
        or the autopilot restarted) and for HOME_POSITION until it has come once."""
        now = self.timebase.now()
        arrived = self.link.arrivals(self.system_id)
        for name, hz in DEFAULT_RATES.items():
            last = arrived.get(name)
            if name != "HEARTBEAT" and hz > 0 and (
                    last is None or now - last > max(3.0 / hz, STREAM_CHECK_PERIOD)):
                self.mav.ask_again(name, hz)
        if "HOME_POSITION" not in arrived:
            self.mav.request_message("HOME_POSITION")

    def _carry_out(self, request: Request) -> Steps[RequestResult]:
        """The procedure of ``request``: its handler's steps, and its result."""
        def fail(reason: FailureReason, detail: str) -> RequestResult:
            return RequestResult(self.vehicle_id, request.request_id, False, reason, detail)

        try:
            handler = _HANDLERS[type(request)]
            if not isinstance(request, (SetYaw, SetSpeed, Camera, Gripper, SetSkill, Safeguard)):
                self._target = None  # the request takes the kept target's place
            detail = yield from handler(self, request)
        except CommandRejected as error:
            return fail(FailureReason.REJECTED, f"{error.command}: {error.result}")
        except MissionTransferError as error:
            return fail(FailureReason.TIMEOUT if error.result in ("", "TIMEOUT")
                        else FailureReason.REJECTED, str(error))
        except VehicleTimeout as error:
            return fail(FailureReason.TIMEOUT, str(error))
        except _Unsupported as error:
            return fail(FailureReason.UNSUPPORTED, str(error))
        except CompileError as error:
            return fail(FailureReason.UNSUPPORTED, str(error))
        except VehicleError as error:
            return fail(FailureReason.GENERAL, str(error))
        return RequestResult(self.vehicle_id, request.request_id, True, detail=detail or "")

    # --- one procedure per request --------------------------------------------------------

    def _switching(self, mode: str, steps: Steps[None] | None = None) -> Steps[None]:
        """Change to ``mode`` (by DO_SET_MODE, or by the ``steps`` of the command that
        enters it), told to the mode watch first: a switch asked here is not taken."""
        with self._lock:
            self._modes.ask(mode)
        try:
            yield from self.mav.switching(mode) if steps is None else steps
        except BaseException:
            with self._lock:
                self._modes.refused()
            raise

    def _repositioning(self, latitude: float, longitude: float, altitude: float,
                       radius: float = 0.0) -> Steps[None]:
        """DO_REPOSITION, which enters GUIDED by itself (ArduPlane, Rover): asked here."""
        yield from self._switching("GUIDED", self.mav.commanding(
            reposition_command(latitude, longitude, altitude, radius=radius)))

    def _guided(self) -> Steps[None]:
        if self.link.telemetry(self.system_id).mode != "GUIDED":
            self._end_plan()
            yield from self._switching("GUIDED")
        else:
            self._adopt_guided()

    def _adopt_guided(self) -> None:
        """Flown in the GUIDED it is in, with no switch asked on this link (a resumed or
        continued run): the mode watch expects GUIDED from now on."""
        with self._lock:
            self._modes.adopt("GUIDED")

    def _end_plan(self) -> None:
        with self._lock:
            if self._plan is not None:
                self._progress = self._plan.progress()
                self._plan = None
                self._changes += 1
        self._stir()

    def _set_mode(self, request: SetMode) -> Steps[None]:
        if request.mode.upper() != "AUTO":
            self._end_plan()
        yield from self._switching(request.mode)  # transient modes (FLIP): by their ACK

    def _flip(self, request: Flip) -> Steps[str]:
        """A flip as a pilot makes it (see the module docstring); returns the modes seen."""
        began = self.timebase.now()
        sticks = _Sticks(self.link, self.system_id, self.mav.component_id)
        closed = False  # abandoned unfinished (garbage): nobody would resume a step now
        try:
            yield from self._switching("ALT_HOLD")
            sticks.hold(*FLIP_STICKS.get(request.direction, FLIP_STICKS["right"]))
            asked = self.timebase.now()
            try:
                yield from self._switching("FLIP")
            finally:
                sticks.hold()

            def over() -> bool:
                t = self.link.telemetry(self.system_id)
                return t.mode != "FLIP" and (
                    t.mode_shown_since("FLIP", asked) or (t.tilted_at or 0.0) > asked)
            # Accepted, so flown; if its telemetry was all lost, it is over by the time limit.
            with contextlib.suppress(VehicleTimeout):
                yield Until(over, FLIP_WAIT, "the flip's end")
            yield from self._switching("GUIDED")
        except GeneratorExit:
            closed = True
            raise
        finally:
            try:
                if not closed and self.link.telemetry(self.system_id).mode != "GUIDED":
                    yield from self._switching("GUIDED")
            except VehicleError:
                pass  # the error that brought us here is the one to report
            finally:
                sticks.release()
        seen = [mode for when, mode in self.link.telemetry(self.system_id).mode_changes
                if when >= began]
        return "modes: " + " > ".join(seen)

    def _arm(self, request: Arm) -> Steps[None]:
        yield from self.mav.commanding(arm_command())

    def _disarm(self, request: Disarm) -> Steps[None]:
        yield from self.mav.commanding(disarm_command())

    def _kind(self) -> Kind:
        return kind_of(self.link.telemetry(self.system_id).airframe)

    def _take_off(self, request: TakeOff) -> Steps[None]:
        kind = self._kind()
        if kind is Kind.GROUND:
            raise _Unsupported("a ground vehicle does not take off")
        if kind is Kind.FIXED_WING:
            yield from self._write_param("TKOFF_ALT", request.altitude, AUTOPILOT)
            self._end_plan()
            yield from self._switching("TAKEOFF")
            if not self.link.telemetry(self.system_id).armed:
                yield from self.mav.commanding(arm_command())
            return
        t = self.link.telemetry(self.system_id)
        if t.armed and t.mode == "GUIDED" and t.position is not None \
                and t.landed_state in (mavlink.MAV_LANDED_STATE_IN_AIR,
                                       mavlink.MAV_LANDED_STATE_TAKEOFF):
            # ArduCopter refuses NAV_TAKEOFF in the air (FAILED): a take-off asked again
            # there -- resumed after a hold -- climbs on to its altitude where it is.
            self._aim(t.position.latitude, t.position.longitude, request.altitude)
            return
        for attempt in range(TAKEOFF_ATTEMPTS):
            try:
                yield from self.mav.commanding(takeoff_command(request.altitude))
                return
            except CommandRejected:
                t = self.link.telemetry(self.system_id)
                if t.armed or t.mode != "GUIDED" or attempt == TAKEOFF_ATTEMPTS - 1:
                    raise
            # Armed on the ground, ArduCopter disarms by itself after DISARM_DELAY (10 s);
            # a take-off lost on the way for that long finds it disarmed, and is refused.
            yield from self.mav.commanding(arm_command())

    def _go_to(self, request: GoTo) -> Steps[None]:
        home = self._require_home()
        latitude, longitude, _ = _global(request.target, home)
        kind = self._kind()
        if kind is Kind.FIXED_WING:
            self._end_plan()
            yield from self._repositioning(latitude, longitude, request.target[2],
                                           radius=HANDLING[kind].loiter_radius)
            if request.speed:
                yield from self.mav.commanding(speed_command(request.speed, ground=False))
            return
        yield from self._guided()
        if request.speed and kind is not Kind.GROUND:
            yield from self.mav.commanding(speed_command(request.speed))
        self._keep_aim(_Aim((latitude, longitude, request.target[2]), request.yaw))
        speed = request.speed or self._ground_speed
        if speed and kind is Kind.GROUND:
            yield from self.mav.commanding(speed_command(speed))

    def _circle(self, request: Circle) -> Steps[None]:
        if self._kind() is not Kind.FIXED_WING:
            raise _Unsupported("only a fixed-wing circles on its own; a multicopter or a "
                               "ground vehicle is sent round the circle point by point")
        self._end_plan()
        latitude, longitude, _ = _global(request.centre, self._require_home())
        yield from self._repositioning(latitude, longitude, request.centre[2],
                                       radius=request.radius)

    def _set_yaw(self, request: SetYaw) -> Steps[None]:
        if request.relative:
            yield from self.mav.commanding(yaw_command(
                abs(request.heading), relative=True, clockwise=request.heading >= 0))
        else:
            yield from self.mav.commanding(yaw_command(request.heading % 360.0))  # shorter way
        target = self._target
        if target is not None and not request.relative:
            # A position or velocity target without a yaw hands the heading back to the
            # autopilot (ArduCopter: WP_YAW_BEHAVIOR), which would undo the turn when the
            # kept target is sent again: from now on it carries the heading asked for.
            self._target = replace(target, yaw=request.heading % 360.0)

    def _hold(self, request: Hold) -> Steps[None]:
        t = self.link.telemetry(self.system_id)
        if not t.armed or t.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND:
            return
        kind = self._kind()
        if kind is Kind.GROUND:
            self._end_plan()
            yield from self._switching("HOLD")
            return
        if kind is Kind.FIXED_WING:  # circle where it is
            state = self.state()
            if state.position is not None:
                self._end_plan()
                latitude, longitude, _ = _global(state.position, self._require_home())
                yield from self._repositioning(latitude, longitude, state.position[2],
                                               radius=HANDLING[kind].loiter_radius)
            return
        if t.mode != "GUIDED":
            yield from self._guided()  # ArduCopter stops at its stopping point in GUIDED
            return
        self._adopt_guided()
        # Braked to a stop where it can: a position target at the point where it was would
        # be flown past (at 10 m/s ArduCopter needs some 20 m to stop) and back to.
        self._keep_aim(_Aim(None))

    def _land(self, request: Land) -> Steps[None]:
        kind = self._kind()
        if kind is Kind.GROUND:
            raise _Unsupported("a ground vehicle does not land")
        if kind is Kind.FIXED_WING:
            yield from self._glide(request.touchdown)
            return
        self._end_plan()
        # Where it is: the scripts fly a multicopter over its touchdown.
        yield from self._switching("LAND", self.mav.commanding(LAND))

    def _glide(self, touchdown: tuple[float, float, float] | None) -> Steps[None]:
        """A fixed-wing's landing: the approach and NAV_LAND uploaded and flown in AUTO."""
        home, state = self._require_home(), self.state()
        if state.position is None:
            raise VehicleError("the vehicle's position is not known yet", self.system_id)
        items = glide_items(home, state.position, state.heading, touchdown)
        self._end_plan()
        yield from self.mav.uploading(items)
        # From its first item: made current, then AUTO and MISSION_START without items.
        yield from self.mav.commanding(current_command(
            1 if self.mav.keeps_home_in_item_zero else 0))
        yield from self._switching("AUTO")
        yield from self.mav.commanding(start_command())

    def _return_to_launch(self, request: ReturnToLaunch) -> Steps[None]:
        self._end_plan()
        yield from self._switching("RTL", self.mav.commanding(RETURN_TO_LAUNCH))

    def _set_speed(self, request: SetSpeed) -> Steps[None]:
        if self._kind() is Kind.GROUND and request.kind in ("airspeed", "ground"):
            self._ground_speed = request.speed  # sent with the next position target
            return
        yield from self.mav.commanding(CommandLong(
            mavlink.MAV_CMD_DO_CHANGE_SPEED, SPEED_TYPES.get(request.kind, 1), request.speed,
            request.throttle))

    def _camera(self, request: Camera) -> Steps[None]:
        if request.operation == "stop":
            yield from self.mav.commanding(CommandLong(mavlink.MAV_CMD_IMAGE_STOP_CAPTURE))
        elif request.operation == "distance":
            # param3 = 1 takes the first photo at once (ArduPilot's "trigger once").
            yield from self.mav.commanding(CommandLong(
                mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST, request.distance, 0,
                1 if request.distance > 0 else 0))
        elif request.operation == "photo" and request.count <= 1:
            yield from self.mav.commanding(PHOTO)
        else:
            count = 0 if request.operation == "start" else request.count
            yield from self.mav.commanding(CommandLong(
                mavlink.MAV_CMD_IMAGE_START_CAPTURE, 0, request.interval, count))

    def _gripper(self, request: Gripper) -> Steps[None]:
        if "gripper" not in self.capabilities:
            raise _Unsupported("this vehicle has no gripper (GRIP_ENABLE is 0)")
        yield from self.mav.commanding(gripper_command(request.grab))

    def _set_home(self, request: SetHome) -> Steps[None]:
        if request.position is None:
            yield from self.mav.commanding(set_home_command())
        else:
            yield from self.mav.commanding(set_home_command(*request.position))

    def _set_skill(self, request: SetSkill) -> Steps[None]:
        binding = SKILL_BINDINGS.get(request.skill)
        if binding is None:
            raise _Unsupported(f"skill {request.skill} has nothing to switch on this vehicle")
        if binding.component == COMPANION and not self._companion_seen:
            raise _Unsupported(f"skill {request.skill} needs a companion computer "
                               f"(component {COMPANION_COMPONENT}), and none was heard")
        value = 1.0 if request.enabled else 0.0
        for name in binding.parameters:
            yield from self._write_param(name, value, binding.component)
        if request.enabled:
            for name, setting in binding.autopilot_on:
                yield from self._write_param(name, setting, AUTOPILOT)

    def _safeguard(self, request: Safeguard) -> Steps[str]:
        """Upload the mission's fence and rally points, read them back and compare, then set
        the fence parameters and read them back (:mod:`tml.mavlink.safeguards`)."""
        home = self._require_home()
        put = safeguards(request.world, home, fence=request.fence)
        if request.fence and put.fence:
            yield from self.mav.uploading(put.fence, MissionType.FENCE)
        if put.rally:
            yield from self.mav.uploading(put.rally, MissionType.RALLY)
        for name, value in put.parameters.items():
            yield from self._write_param(name, value, AUTOPILOT)
        kept = "" if request.fence else "the vehicle's fence kept; "
        action = ""
        if put.has_fence:
            action = f"; {fence_action((yield from self._read_param('FENCE_ACTION')))}"
        return f"{kept}{put.summary or 'nothing to upload'}{action}; read back matched"

    def _fly_mission(self, request: FlyMission) -> Steps[None]:
        # A mission may be the first thing asked: wait for home (and for a position good
        # enough to arm with, when the mission starts on the ground).
        def ready() -> bool:
            t = self.link.telemetry(self.system_id)
            return t.home is not None and (t.armed or t.position_ready)
        yield Until(ready, self.ready_timeout, "home and a position to arm with")
        home = self._require_home()
        state = self.state()
        compiled = compile_mission(request.actions, home, request.start, state.heading,
                                   kind_of(state.vehicle_type))
        self._end_plan()
        plan = _Plan(request.plan_id, compiled, 1 if self.mav.keeps_home_in_item_zero else 0)
        if request.track:  # uploaded by an interrupted run and flown: follow it
            if state.mode != "AUTO":
                raise CommandRejected("tracking an uploaded mission",
                                      f"the vehicle is in {state.mode}, not AUTO",
                                      self.system_id)
            with self._lock:
                self._plan = plan
                plan.started = True
            return
        yield from self.mav.uploading(list(compiled.items))
        with self._lock:
            self._plan = plan
            self._changes += 1
        self._stir()
        if not state.armed:
            # A mission that starts on the ground: arm in GUIDED, then AUTO takes off.
            yield from self._switching("GUIDED")
            yield from self.mav.commanding(arm_command())
        # The first item is made current before AUTO, which starts (or resumes) the mission
        # there; MISSION_START then names no items: ArduPilot DENIES a first or last item.
        yield from self.mav.commanding(current_command(plan.offset))
        yield from self._switching("AUTO")
        yield from self.mav.commanding(start_command())
        with self._lock:
            plan.started = True
            plan.finished = plan.last_nav is None  # DO items only: done on starting
            self._changes += 1
        self._stir()

    def _require_home(self) -> Home:
        home = _home(self.link.telemetry(self.system_id))
        if home is None:
            raise VehicleError("the vehicle has not reported its home position yet",
                               self.system_id)
        return home

    # --- parameters ---------------------------------------------------------------------

    def _component(self, which: str) -> int:
        return COMPANION_COMPONENT if which == COMPANION else self.mav.component_id

    def read_parameters(self, names: Iterable[str]) -> dict[str, float]:
        """The autopilot's values of ``names`` (those it has), read one by one (waits)."""
        values = {name: self.mav.do(self._read_param(name)) for name in names}
        return {name: value for name, value in values.items() if value is not None}

    def read_first(self, names: Sequence[str]) -> tuple[str, float] | None:
        """One parameter known by several names (each firmware version has one of them):
        the first name the autopilot answers for, and its value; None when it answers for
        none. All are asked at once, so a name the firmware lacks costs no time-out."""
        component = self._component(AUTOPILOT)
        asked = {name: mavlink.MAVLink_param_request_read_message(
            self.system_id, component, name.encode(), -1) for name in names}
        try:
            return self.mav.do(self._param_exchange(asked, component))
        except VehicleTimeout:
            return None

    @property
    def source_system(self) -> int:
        """The MAVLink system id tml sends to this vehicle as."""
        return self.link.source_system

    def _read_param(self, name: str, which: str = AUTOPILOT) -> Steps[float | None]:
        component = self._component(which)
        msg = mavlink.MAVLink_param_request_read_message(self.system_id, component,
                                                         name.encode(), -1)
        try:
            return (yield from self._param_exchange({name: msg}, component))[1]
        except VehicleTimeout:
            return None

    def _write_param(self, name: str, value: float, which: str) -> Steps[None]:
        component = self._component(which)
        msg = mavlink.MAVLink_param_set_message(self.system_id, component, name.encode(),
                                                value, mavlink.MAV_PARAM_TYPE_REAL32)
        stored = (yield from self._param_exchange({name: msg}, component,
                                                  PARAM_SET_RETRIES))[1]
        if not math.isclose(stored, value, abs_tol=1e-6):
            raise CommandRejected(f"PARAM_SET {name}", f"stored {stored:g}", self.system_id)

    def _param_exchange(self, asked: Mapping[str, Any], component: int,
                        tries: int = PARAM_RETRIES) -> Steps[tuple[str, float]]:
        """Send each parameter's PARAM_SET/PARAM_REQUEST_READ of ``asked`` (by name) until
        a PARAM_VALUE of one of them comes back: its name (the first of ``asked`` answered)
        and value."""
        keys = [(component, name) for name in asked]

        def answered() -> bool:
            return any(key in self._params for key in keys)
        for _ in range(tries):
            with self._params_lock:
                for key in keys:
                    self._params.pop(key, None)
            for msg in asked.values():
                self.link.send(msg)
            # A lost vehicle is waited out as silence: an absent parameter looks the same.
            with contextlib.suppress(VehicleTimeout):
                yield Until(answered, PARAM_TIMEOUT, "PARAM_VALUE", lost_ok=True)
            with self._params_lock:
                found = next((key for key in keys if key in self._params), None)
                if found is not None:
                    return found[1], self._params[found]
        raise VehicleTimeout(f"no PARAM_VALUE for {' or '.join(asked)} from component "
                             f"{component}", self.system_id)


class _Unsupported(VehicleError):
    """The vehicle lacks what a request needs."""


class _Sticks:
    """The pilot's sticks held by RC_CHANNELS_OVERRIDE, sent by the link's reactor every
    STICK_PERIOD seconds from the start until :meth:`release`: throttle mid-stick, roll,
    pitch and yaw as :meth:`hold` sets them."""

    def __init__(self, link: Link, system_id: int, component_id: int) -> None:
        self.link = link
        self.target = (system_id, component_id)
        self.sticks = (MID_STICK, MID_STICK, MID_STICK, MID_STICK)
        self._send()
        self._stop = link.repeat(self._send, STICK_PERIOD)

    def hold(self, roll: int = MID_STICK, pitch: int = MID_STICK) -> None:
        """Hold roll and pitch there (centred by default), from now on."""
        self.sticks = (roll, pitch, MID_STICK, MID_STICK)
        for _ in range(3):  # a lost copy would leave the old sticks until the next period
            self._send()

    def release(self) -> None:
        """Stop holding and give channels 1-4 back to the radio."""
        self._stop()
        self.sticks = (codec.RC_RELEASE,) * 4
        for _ in range(3):  # if all are lost, RC_OVERRIDE_TIME releases them anyway
            self._send()

    def _send(self) -> None:
        # A link gone: the vehicle drops the override after RC_OVERRIDE_TIME by itself.
        with contextlib.suppress(OSError):
            self.link.send(codec.rc_override(*self.target, self.sticks))


_HANDLERS: dict[type, Callable[[MavlinkVehicle, Any], Steps[str | None]]] = {
    SetMode: MavlinkVehicle._set_mode, Arm: MavlinkVehicle._arm,
    Disarm: MavlinkVehicle._disarm, TakeOff: MavlinkVehicle._take_off,
    GoTo: MavlinkVehicle._go_to, SetYaw: MavlinkVehicle._set_yaw,
    Hold: MavlinkVehicle._hold, Land: MavlinkVehicle._land,
    ReturnToLaunch: MavlinkVehicle._return_to_launch, SetSpeed: MavlinkVehicle._set_speed,
    Circle: MavlinkVehicle._circle,
    Camera: MavlinkVehicle._camera, Gripper: MavlinkVehicle._gripper,
    SetHome: MavlinkVehicle._set_home, SetSkill: MavlinkVehicle._set_skill,
    FlyMission: MavlinkVehicle._fly_mission, Flip: MavlinkVehicle._flip,
    Safeguard: MavlinkVehicle._safeguard,
}


_NO_DETECTIONS: Mapping[str, object] = MappingProxyType({})


def _messages(t: Telemetry) -> tuple[AutopilotMessage, ...]:
    """The latest STATUSTEXTs, numbered from the first the link received."""
    texts = t.status_texts[-MESSAGES_KEPT:]
    first = t.status_text_count - len(texts) + 1
    return tuple(AutopilotMessage(first + i, s.severity, s.text) for i, s in enumerate(texts))


def _home(t: Telemetry) -> Home | None:
    h = t.home
    return None if h is None else Home(h.latitude, h.longitude, h.altitude)


def _global(point: tuple[float, float, float], home: Home) -> tuple[float, float, float]:
    return to_global(*point, home.latitude, home.longitude, home.altitude)


def _text(value: str | bytes) -> str:
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    return value.rstrip("\x00")
