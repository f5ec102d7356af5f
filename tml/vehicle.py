"""The vehicle interface the interpreter talks to.

The engine (:mod:`tml.engine`) never touches a link. It reads :class:`VehicleState`
snapshots and emits :class:`Request` objects; a :class:`Vehicle` carries the requests out
(on MAVLink: :mod:`tml.mavlink.adapter`; in tests: ``FakeVehicle``, tests/fake_vehicle.py)
and reports each one's outcome as a :class:`RequestResult`. Positions are local metres
(north, east, up) from home, headings degrees clockwise from north, speeds metres per
second.

Requests are asynchronous: ``submit`` returns at once; the outcome comes later through
``poll``. A request is *done* when the vehicle accepted it (for commands, an ACCEPTED
COMMAND_ACK); whether the vehicle then gets where it was sent is for the engine to watch
in the state.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields
from types import MappingProxyType
from typing import Protocol

from tml.geo import Point as Point  # re-exported: requests and states speak in local points
from tml.language.actions import BoundAction
from tml.language.failures import FailureReason
from tml.world import Home, World

_EMPTY: Mapping[str, object] = MappingProxyType({})


@dataclass(frozen=True)
class MissionProgress:
    """How far the vehicle is in a mission plan uploaded with :class:`FlyMission`."""

    plan_id: int
    action_index: int  # index into FlyMission.actions of the action being flown
    finished: bool = False
    item: int = 0  # the mission item being flown, from 1 (ArduPilot's "Mission: N WP"); 0 unknown
    items: int = 0  # the items of the plan (home not counted); 0 unknown


SEVERITIES = ("emergency", "alert", "critical", "error", "warning", "notice", "info", "debug")
"""MAV_SEVERITY by number: 0 is the worst."""
MESSAGES_KEPT = 10
"""Autopilot messages a state carries (the latest)."""
ARMING_REASONS = ("PreArm:", "Arm:")
"""How ArduPilot begins the messages that say why it will not arm."""


@dataclass(frozen=True)
class AutopilotMessage:
    """A message of the autopilot (MAVLink STATUSTEXT: PreArm reasons, failsafes, mode
    changes ...). ``number`` counts a vehicle's messages from 1, so that each is told once."""

    number: int
    severity: int  # MAV_SEVERITY: 0 emergency ... 7 debug
    text: str

    @property
    def severity_name(self) -> str:
        """``warning``, ``critical`` ...: MAV_SEVERITY's word for the severity."""
        return SEVERITIES[self.severity] if 0 <= self.severity < len(SEVERITIES) \
            else str(self.severity)

    @property
    def shown_severity(self) -> int:
        """The severity an operator is shown: :func:`shown_severity` of this message."""
        return shown_severity(self.severity, self.text)


INFO = SEVERITIES.index("info")
WARNING = SEVERITIES.index("warning")


def shown_severity(severity: int, text: str) -> int:
    """The severity to show an operator for an autopilot message said with ``severity``.

    ArduPilot says why it would not arm (``PreArm: ...``, or ``Arm: ...`` refusing an arm
    command) as critical, and says it only while disarmed: its pre-arm checks run only
    then. After every landing ArduCopter says ``PreArm: Mode not armable`` while it sits
    in RTL or LAND -- the simulator right after ``Disarming motors``, before the HEARTBEAT
    that shows it disarmed, so the vehicle's last known state cannot tell. On the ground
    and disarmed that is the expected state, not an alarm: such a message is shown as
    info. (What it means before a flight is said where it matters: the wait for a vehicle
    to be ready names it, and a refused arm fails its action.)
    """
    if text.startswith(ARMING_REASONS) and severity < INFO:
        return INFO
    return severity


@dataclass(frozen=True)
class VehicleState:
    """What the engine knows of one vehicle at ``time``."""

    vehicle_id: int
    time: float
    link: str = "ok"  # "ok", "degraded" (messages missing) or "lost" (no heartbeat)
    ready: bool = True  # position estimate good enough to arm (ArduPilot EKF flags)
    armable: bool | None = True  # the autopilot's pre-arm checks pass (None: not said)
    prearm: str = ""  # the autopilot's latest reason not to arm ("PreArm: ...")
    armed: bool = False
    landed: bool = True
    mode: str = ""
    position: Point | None = None
    heading: float = 0.0
    heading_known: bool = True  # False until the autopilot reports its attitude
    ground_speed: float = 0.0
    battery: float | None = None  # percent remaining
    gps_fix: int | None = None  # GPS_RAW_INT fix type (3 = 3D); None until reported
    # What an operator reads and no rule does: left out of the comparison of two states
    # (tml.run.runner steps the interpreter when a compared field changes, and a voltage
    # changes with every SYS_STATUS).
    satellites: int | None = field(default=None, compare=False)  # GPS satellites visible
    voltage: float | None = field(default=None, compare=False)  # battery volts
    climb: float = field(default=0.0, compare=False)  # vertical speed, m/s, up positive
    home: Home | None = None
    mission: MissionProgress | None = None
    detections: Mapping[str, object] = field(default_factory=lambda: _EMPTY)
    capabilities: frozenset[str] = frozenset()  # "gripper", "flip", "camera"
    skills: Mapping[str, str] | None = None
    """Each skill the vehicle can switch, and why it cannot now ("": it can; its companion
    computer not heard yet); a skill not in it has nothing on this vehicle to switch it.
    None: the vehicle does not say, and every skill is taken as there."""
    status_text: str = ""  # the last STATUSTEXT
    messages: tuple[AutopilotMessage, ...] = ()  # the latest STATUSTEXTs, oldest first
    vehicle_type: str = ""  # a word of VEHICLE_TYPES, "" while unknown
    rejected: int = 0  # telemetry messages ignored for an absurd value (battery 127 %, NaN)
    rejected_last: str = ""  # what was absurd in the last of them
    taken: str = ""  # the mode the vehicle was switched to by someone else (the autopilot)
    rebooted: str = ""  # the autopilot's latest reboot, as it was seen ("": none)
    reboots: int = 0  # reboots seen since the vehicle was opened
    # How old the picture is, in the runner's time (None: the source does not say, and
    # its readings are taken as current). Left out of the comparison: they move with
    # every message and every request, and the rules below read them on every step.
    heard: float | None = field(default=None, compare=False)
    """When the oldest of the readings the rules judge by arrived: the last HEARTBEAT
    (armed, mode), the landed state, the position."""
    asked: float | None = field(default=None, compare=False)
    """When the latest request was submitted to the vehicle."""
    flight_asked: float | None = field(default=None, compare=False)
    """When the latest request that can put the vehicle in the air was submitted
    (:data:`FLIGHT_REQUESTS`)."""

    @property
    def flying(self) -> bool:
        """Armed and off the ground; for a ground vehicle (which reports no landed state):
        armed, underway."""
        return self.armed and not self.landed

    @property
    def current(self) -> bool:
        """Whether every reading the rules judge by arrived after the latest request: no
        decision about a request is made from an older picture (a LAND is not done on a
        'landed' heard before the land command)."""
        return self.heard is None or self.asked is None or self.heard > self.asked

    @property
    def possibly_flying(self) -> bool:
        """Flying, saying it is not landed, or asked to fly with no reading since: from the
        first request that can put it in the air until telemetry that arrived after it
        shows it on the ground, a vehicle counts as flying (a Ctrl-C right after a take-off
        request must not find it 'disarmed' on the picture of a moment before)."""
        return self.flying or not self.landed or self.flight_unseen

    @property
    def flight_unseen(self) -> bool:
        """Asked to fly (:data:`FLIGHT_REQUESTS`) with no reading arrived since."""
        return (self.flight_asked is not None and self.heard is not None
                and self.heard <= self.flight_asked)

    @property
    def altitude(self) -> float:
        """Altitude above home in metres (0 when the position is unknown)."""
        return self.position[2] if self.position else 0.0

    @property
    def home_distance(self) -> float | None:
        """Metres from home, horizontally (None when the position is unknown)."""
        return None if self.position is None else math.hypot(self.position[0],
                                                             self.position[1])


COMPARED_FIELDS = tuple(f.name for f in fields(VehicleState) if f.name != "time" and f.compare)
"""The fields that say what a vehicle shows: all but its time and what only an operator
reads (the fields of VehicleState left out of its comparison)."""


SHOWN_FIELDS = (*COMPARED_FIELDS, "current")
"""What a reader waiting for any change of a vehicle watches: the compared fields, and
whether its picture is :attr:`~VehicleState.current`, which moves with ``heard`` and
``asked`` (left out of the comparison) while nothing it shows changes: a landed vehicle's
next HEARTBEAT, the same as the one before, is what makes its LAND done."""


def same_state(a: VehicleState, b: VehicleState,
               names: Iterable[str] = COMPARED_FIELDS) -> bool:
    """Whether two states of a vehicle show the same in the fields ``names`` (by default
    :data:`COMPARED_FIELDS`)."""
    if a is b:
        return True
    for name in names:  # noqa: SIM110 -- a loop is quicker, and this runs at every step
        if getattr(a, name) != getattr(b, name):
            return False
    return True


NO_SKILL = "nothing on this vehicle switches it"
"""Why a skill cannot be switched on a vehicle that has no component for it."""


def unprovided(state: VehicleState, skills: Iterable[str]) -> tuple[str, ...]:
    """The ``skills`` nothing on the vehicle switches (:attr:`VehicleState.skills`): a
    mission switching them is refused at once, waiting would not bring them."""
    if state.skills is None:
        return ()
    return tuple(sorted(skill for skill in skills if skill not in state.skills))


def awaiting(state: VehicleState, skills: Iterable[str] = ()) -> tuple[str, ...]:
    """What a vehicle still lacks before a mission may start on it ("" items: none).

    Everything the interpreter reads must have arrived (a value not yet reported is
    unknown, never 0): the heartbeat, the position, home, the GPS and the battery. A
    vehicle on the ground and disarmed must also be armable: a position estimate the
    autopilot flies on (ArduPilot's EKF) and pre-arm checks that pass, whose failure is
    named with the autopilot's own words when it said them. A vehicle already armed or
    flying is taken as it is. Each of the ``skills`` the mission switches on the vehicle
    must be there too, its component heard (a companion computer): flying or not, a skill
    switched before its component is heard fails.
    """
    if state.link == "lost":
        return ("heartbeat",)
    missing: list[str] = []
    if state.skills is not None:
        for skill in sorted(skills):
            why = state.skills.get(skill, NO_SKILL)
            if why:
                missing.append(f"skill {skill} ({why})")
    if state.gps_fix is None:
        missing.append("GPS status")
    if state.position is None:
        missing.append("position")
    if not state.heading_known:
        missing.append("attitude")
    if state.home is None:
        missing.append("home position")
    if state.battery is None:
        missing.append("battery status")
    if not state.armed:
        unarmable = []
        if not state.ready:
            unarmable.append("GPS fix" if (state.gps_fix or 0) < 3 else "position estimate")
        if state.armable is False:
            unarmable.append("pre-arm checks")
        if unarmable and state.prearm:
            unarmable.append(f"autopilot: {state.prearm}")
        missing.extend(unarmable)
    return tuple(missing)


# --- requests -------------------------------------------------------------------------------

class IdSource:
    """Hands out ids, each once: the ids of requests and of autopilot plans.

    One source serves a whole run -- the engine and whoever else sends to its vehicles (the
    runner's own safety requests) -- so that no two requests to a vehicle share an id and
    a vehicle's progress in one plan is never taken for another's. Nothing is numbered
    process-wide: each run (each test) counts from ``first``; a service that flies one
    vehicle in run after run gives them all one source (which several threads may share).
    """

    def __init__(self, first: int = 1) -> None:
        self._ids = itertools.count(first)  # next() on a count is atomic: thread-safe

    def take(self) -> int:
        """A new id."""
        return next(self._ids)


@dataclass(frozen=True)
class Request:
    """Something the engine asks a vehicle to do.

    ``request_id`` is 0 until the request is sent: the sender numbers each request it sends
    from the run's :class:`IdSource`, and the vehicle's :class:`RequestResult` carries the
    number back.
    """

    vehicle_id: int
    request_id: int = field(default=0, kw_only=True)

    @property
    def name(self) -> str:
        """The request's kind, for logs."""
        return type(self).__name__


@dataclass(frozen=True)
class SetMode(Request):
    """Switch flight mode (ArduPilot names: GUIDED, AUTO, LOITER, RTL, LAND, BRAKE ...)."""

    mode: str


@dataclass(frozen=True)
class Arm(Request):
    """Arm the motors."""


@dataclass(frozen=True)
class Disarm(Request):
    """Disarm the motors (refused in flight by the autopilot)."""


@dataclass(frozen=True)
class TakeOff(Request):
    """Climb to ``altitude`` metres above home (GUIDED, armed)."""

    altitude: float


@dataclass(frozen=True)
class GoTo(Request):
    """Fly to a local point (GUIDED position target); ``speed`` None keeps the current one,
    ``yaw`` (degrees clockwise from north) None leaves the heading to the autopilot."""

    target: Point
    speed: float | None = None
    yaw: float | None = None


@dataclass(frozen=True)
class SetYaw(Request):
    """Turn to ``heading`` degrees (or by it, when ``relative``), clockwise from north."""

    heading: float
    relative: bool = False


@dataclass(frozen=True)
class Hold(Request):
    """Stop and hold the current position (the running action is being stopped)."""


@dataclass(frozen=True)
class Land(Request):
    """Land where the vehicle is, or at ``touchdown`` (a local point on the ground).

    A multicopter descends vertically where it is (the scripts fly it over its touchdown
    first); a fixed-wing flies a landing approach (:func:`tml.language.kinds.landing_approach`):
    straight ahead without a touchdown, else into the touchdown from the side it comes
    from.
    """

    touchdown: Point | None = None


@dataclass(frozen=True)
class Circle(Request):
    """Circle ``centre`` (local) at ``radius`` metres, clockwise, until told otherwise: a
    fixed-wing's own loiter (a multicopter flies circles as a series of GoTo)."""

    centre: Point
    radius: float


@dataclass(frozen=True)
class ReturnToLaunch(Request):
    """Return home and land (ArduPilot RTL)."""


@dataclass(frozen=True)
class SetSpeed(Request):
    """Change speed: ``kind`` is airspeed, ground, climb or descent; ``throttle`` in
    percent, -1 for no change (DO_CHANGE_SPEED's param3)."""

    speed: float
    kind: str = "ground"
    throttle: float = -1.0


@dataclass(frozen=True)
class Camera(Request):
    """``photo`` (``count`` photos, ``interval`` s apart), ``start`` (until stopped), ``stop``,
    or ``distance``: a photo each time the vehicle has flown ``distance`` metres, the first
    at once (0: no more)."""

    operation: str
    count: int = 1
    interval: float = 0.0
    distance: float = 0.0


@dataclass(frozen=True)
class Gripper(Request):
    """Close (``grab``) or open the gripper."""

    grab: bool


@dataclass(frozen=True)
class SetHome(Request):
    """Set home to the current position (``position`` None) or to a WGS84 position."""

    position: tuple[float, float, float] | None = None  # latitude, longitude, altitude AMSL


@dataclass(frozen=True)
class SetSkill(Request):
    """Switch a skill on or off (autopilot parameters or the companion computer)."""

    skill: str
    enabled: bool


@dataclass(frozen=True)
class Flip(Request):
    """Flip once (``direction`` front, back, left or right) and come back to GUIDED.

    ArduCopter flips only from a mode flown by the pilot's sticks: the vehicle carries out
    the whole sequence (see :meth:`tml.mavlink.adapter.MavlinkVehicle`'s FLIP) and is done
    when it is back in GUIDED; the result's detail lists the modes it went through.
    """

    direction: str = "front"


@dataclass(frozen=True)
class FlyMission(Request):
    """Compile ``actions`` to mission items, upload them and fly them in AUTO.

    ``start`` is where the vehicle is expected to be when the mission starts (for actions
    relative to the last position). Progress is reported in ``VehicleState.mission``.
    With ``track``, the plan is on the vehicle already, uploaded as ``plan_id`` by a run
    that was interrupted, and flown in AUTO: nothing is uploaded or commanded, the vehicle's
    progress through it is followed (as QGroundControl resumes an uploaded plan).
    """

    plan_id: int
    actions: tuple[BoundAction, ...]
    start: Point
    track: bool = False


@dataclass(frozen=True)
class Safeguard(Request):
    """Put the mission's safety on the vehicle before the first take-off: ``world``'s
    geofence and obstacles as its fence (unless ``fence`` is False: the vehicle's own fence
    is kept as it is) and its rally points; read back and compared
    (:mod:`tml.mavlink.safeguards`). The result's ``detail`` says what was uploaded. The
    runner sends it, never the engine."""

    world: World
    fence: bool = True


FLIGHT_REQUESTS: tuple[type[Request], ...] = (Arm, TakeOff, SetMode, FlyMission, Flip)
"""The requests that can put a vehicle in the air (:attr:`VehicleState.possibly_flying`)."""


@dataclass(frozen=True)
class RequestResult:
    """The outcome of a request: ``ok``, or the failure's ``reason`` and ``detail``.

    A vehicle's reasons are values of the ACTION_FAILURE parameter: REJECTED (the vehicle
    refused), TIMEOUT (no answer), UNSUPPORTED (the vehicle cannot do it) or GENERAL; a
    failure without one counts as REJECTED.
    """

    vehicle_id: int
    request_id: int
    ok: bool
    reason: FailureReason | None = None
    detail: str = ""


class Vehicle(Protocol):
    """What the runner needs of a vehicle."""

    vehicle_id: int

    def state(self) -> VehicleState:
        """The latest state."""
        ...

    def submit(self, request: Request) -> None:
        """Start carrying out a request; must not block."""
        ...

    def poll(self) -> list[RequestResult]:
        """Outcomes that arrived since the last poll."""
        ...
