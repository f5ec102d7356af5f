"""A scriptable kinematic vehicle for engine, runner and service tests: the test double of
:class:`tml.vehicle.Vehicle`, driven by an injected clock instead of a link."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from types import MappingProxyType

from tml.language.actions import BoundAction
from tml.language.failures import FailureReason
from tml.language.kinds import Kind, kind_of
from tml.vehicle import (
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
    Point,
    Request,
    RequestResult,
    ReturnToLaunch,
    SetMode,
    SetSkill,
    SetSpeed,
    SetYaw,
    TakeOff,
    VehicleState,
)
from tml.world import DEFAULT_HOME, Home


@dataclass
class FakeVehicle:
    """A scriptable kinematic vehicle for engine tests, driven by an injected clock.

    ``advance(dt)`` moves it toward its target at ``speed`` (horizontal) and ``climb_rate``
    (vertical), drains the battery, and lands it when told. Scripting knobs: ``reject``
    (request kinds answered with a failure), ``ignore`` (request kinds never answered),
    ``stuck`` (accepts moves but never moves), ``ready``, ``capabilities``,
    ``detections`` (set by the test), ``battery``, and ``vehicle_type``, whose kind
    (:mod:`tml.language.kinds`) it answers as ArduPilot's vehicles do in the main: a fixed-wing's
    TakeOff arms it (TAKEOFF mode), it lands at a touchdown and flies a Circle round and
    round; a ground vehicle refuses TakeOff and Land, reports no landed state (landed while
    disarmed) and its RTL drives home and stops.
    """

    vehicle_id: int = 1
    home: Home = DEFAULT_HOME
    speed: float = 5.0
    climb_rate: float = 2.5
    yaw_rate: float = 90.0
    drain_per_second: float = 0.05
    battery: float = 100.0
    ready: bool = True
    capabilities: frozenset[str] = frozenset({"camera"})
    vehicle_type: str = "quadcopter"
    reject: dict[str, str] = field(default_factory=dict)  # request name -> reason
    ignore: set[str] = field(default_factory=set)
    stuck: bool = False
    time: float = 0.0
    position: Point = (0.0, 0.0, 0.0)
    heading: float = 0.0
    armed: bool = False
    mode: str = "STABILIZE"
    detections: dict[str, object] = field(default_factory=dict)
    skills: set[str] = field(default_factory=set)
    gripping: bool = False
    photos: int = 0
    flips: int = 0
    submitted: list[Request] = field(default_factory=list)
    mission: MissionProgress | None = None
    rejected: int = 0  # absurd telemetry messages ignored (set by the test)
    rejected_last: str = ""
    taken: str = ""  # the mode someone else switched it to (set by the test)
    _target: Point | None = None
    _target_heading: float | None = None
    _circle: tuple[Point, float, float] | None = None  # centre, radius, angle (rad)
    _landing: bool = False
    _climb: float = 0.0  # m/s up over the last advance
    _results: list[RequestResult] = field(default_factory=list)
    _mission_points: list[Point] = field(default_factory=list)
    _messages: list[AutopilotMessage] = field(default_factory=list)

    def say(self, severity: int, text: str) -> None:
        """The autopilot says ``text`` (a STATUSTEXT of MAV_SEVERITY ``severity``)."""
        self._messages.append(AutopilotMessage(len(self._messages) + 1, severity, text))

    def state(self) -> VehicleState:
        """The current state."""
        landed = not self.armed if kind_of(self.vehicle_type) is Kind.GROUND else \
            self.position[2] <= 0.05
        return VehicleState(
            vehicle_id=self.vehicle_id, time=self.time, ready=self.ready, armed=self.armed,
            armable=self.ready, landed=landed, mode=self.mode, position=self.position,
            heading=self.heading, ground_speed=self.speed if self._moving() is not None else 0.0,
            battery=self.battery, gps_fix=3, satellites=10,
            voltage=round(10.5 + 2.1 * self.battery / 100, 2), climb=self._climb,
            home=self.home, mission=self.mission,
            detections=MappingProxyType(dict(self.detections)),
            capabilities=self.capabilities, vehicle_type=self.vehicle_type,
            status_text=self._messages[-1].text if self._messages else "",
            messages=tuple(self._messages[-MESSAGES_KEPT:]), rejected=self.rejected,
            rejected_last=self.rejected_last, taken=self.taken)

    def submit(self, request: Request) -> None:
        """Record and carry out a request (answered at the next ``poll``)."""
        self.submitted.append(request)
        if request.name in self.ignore:
            return
        if request.name in self.reject:
            self._answer(request, False, self.reject[request.name])
            return
        failure = self._apply(request)
        self._answer(request, failure is None, failure or "")

    def poll(self) -> list[RequestResult]:
        """Outcomes since the last poll."""
        results, self._results = self._results, []
        return results

    def _answer(self, request: Request, ok: bool, reason: str) -> None:
        self._results.append(RequestResult(self.vehicle_id, request.request_id, ok,
                                           None if ok else FailureReason(reason)))

    def _apply(self, request: Request) -> str | None:
        n, e, u = self.position
        kind = kind_of(self.vehicle_type)
        self._circle = None
        if kind is Kind.GROUND and isinstance(request, TakeOff | Land):
            return "unsupported"
        if kind is Kind.FIXED_WING and isinstance(request, TakeOff) and self.ready:
            self.armed, self.mode = True, "TAKEOFF"  # TAKEOFF mode arms and climbs
        if kind is Kind.GROUND and isinstance(request, ReturnToLaunch):
            self.mode, self._target, self._landing = "RTL", (0.0, 0.0, 0.0), False
            return None
        if isinstance(request, Land) and request.touchdown is not None:
            self.mode, self._target, self._landing = "AUTO", request.touchdown, True
            return None
        if isinstance(request, Circle):
            self.mode = "GUIDED"
            self._circle = (request.centre, request.radius, 0.0)
            self._target = (request.centre[0] + request.radius, request.centre[1],
                            request.centre[2])
            return None
        if isinstance(request, SetMode):
            self.mode = request.mode
            if request.mode == "RTL":
                self._target, self._landing = (0.0, 0.0, max(u, 15.0)), True
            elif request.mode == "LAND":
                self._target, self._landing = None, True
        elif isinstance(request, Arm):
            if not self.ready:
                return "rejected"
            self.armed = True
        elif isinstance(request, Disarm):
            if u > 0.05:
                return "rejected"
            self.armed = False
        elif isinstance(request, TakeOff):
            if not self.armed:
                return "rejected"
            self._target, self._landing = (n, e, request.altitude), False
        elif isinstance(request, GoTo):
            if not self.armed:
                return "rejected"
            self._target, self._landing = request.target, False
            if request.speed:
                self.speed = request.speed
        elif isinstance(request, SetYaw):
            self._target_heading = (request.heading + (self.heading if request.relative
                                                       else 0.0)) % 360
        elif isinstance(request, Hold):
            self._target, self._landing, self.mission = (n, e, u), False, None
        elif isinstance(request, Land):
            self.mode, self._target, self._landing = "LAND", None, True
        elif isinstance(request, ReturnToLaunch):
            self.mode, self._target, self._landing = "RTL", (0.0, 0.0, max(u, 15.0)), True
        elif isinstance(request, SetSpeed):
            if request.kind in ("airspeed", "ground"):
                self.speed = request.speed
        elif isinstance(request, Camera):
            self.photos += request.count if request.operation == "photo" else 0
        elif isinstance(request, Gripper):
            if "gripper" not in self.capabilities:
                return "unsupported"
            self.gripping = request.grab
        elif isinstance(request, SetSkill):
            (self.skills.add if request.enabled else self.skills.discard)(request.skill)
        elif isinstance(request, Flip):
            if "flip" not in self.capabilities or self.mode != "GUIDED":
                return "unsupported" if "flip" not in self.capabilities else "rejected"
            self.flips += 1
        elif isinstance(request, FlyMission) and request.track:
            pass  # it flies on through the plan it has
        elif isinstance(request, FlyMission):
            self.mode = "AUTO"
            self.mission = MissionProgress(request.plan_id, 0, item=1,
                                           items=len(request.actions))
            self._mission_points = [_mission_point(a, request.start, self.position)
                                    for a in request.actions]
            self._target = self._mission_points[0] if self._mission_points else None
        return None

    def _moving(self) -> Point | None:
        """The target the vehicle is moving towards; None when it is not moving."""
        target = self._target
        if target is None or self.stuck or not math.dist(target, self.position) > 0.01:
            return None
        return target

    def advance(self, dt: float) -> None:
        """Move the clock and the vehicle on by ``dt`` seconds."""
        self.time += dt
        up = self.position[2]
        self._advance(dt)
        self._climb = (self.position[2] - up) / dt if dt > 0 else 0.0

    def _advance(self, dt: float) -> None:
        if self.armed:
            self.battery = max(0.0, self.battery - self.drain_per_second * dt)
        if self._target_heading is not None:
            delta = (self._target_heading - self.heading + 540) % 360 - 180
            step = max(-self.yaw_rate * dt, min(self.yaw_rate * dt, delta))
            self.heading = (self.heading + step) % 360
            if abs(delta) <= self.yaw_rate * dt:
                self._target_heading = None
        if self._circle is not None and self._target is not None and self._moving() is None:
            centre, radius, angle = self._circle  # on the circle: round it at its speed
            angle += self.speed * dt / radius
            self._circle = (centre, radius, angle)
            self._target = (centre[0] + radius * math.cos(angle),
                            centre[1] + radius * math.sin(angle), centre[2])
        target = self._moving()
        if target is not None:
            self.position = _towards(self.position, target, self.speed * dt,
                                     self.climb_rate * dt)
        elif self._landing and self._target is not None:
            self._target = None  # over the landing point: descend from here
        elif self.mission is not None and not self.mission.finished:
            index = self.mission.action_index + 1
            if index < len(self._mission_points):
                self.mission = replace(self.mission, action_index=index, item=index + 1)
                self._target = self._mission_points[index]
            else:
                self.mission = replace(self.mission, finished=True)
        elif self._landing and not self.stuck:
            n, e, u = self.position
            self.position = (n, e, max(0.0, u - self.climb_rate * dt))
            if self.position[2] <= 0.0:
                self._landing, self.armed, self._target = False, False, None
                self.mode = "LAND" if self.mode != "RTL" else self.mode


def _towards(position: Point, target: Point, horizontal: float, vertical: float) -> Point:
    n, e, u = position
    tn, te, tu = target
    distance = math.hypot(tn - n, te - e)
    if distance <= horizontal:
        n, e = tn, te
    else:
        n, e = n + (tn - n) / distance * horizontal, e + (te - e) / distance * horizontal
    u = tu if abs(tu - u) <= vertical else u + math.copysign(vertical, tu - u)
    return (n, e, u)


def _mission_point(action: BoundAction, start: Point, here: Point) -> Point:
    """Where a mission action leads, for the fake vehicle (a crude stand-in for AUTO)."""
    if "coordinates" in action.values:
        return action.point("coordinates")
    if action.name == "TAKE_OFF":
        return (start[0], start[1], action.number("altitude"))
    return here
