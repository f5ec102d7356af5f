"""The AUTO-mode mission executor, after ArduPilot's AP_Mission.

Two cursors walk the item list. The *navigation* cursor holds one NAV command (take off,
waypoint, loiter, land, RTL, delay) that moves the vehicle; when it completes, the vehicle
sends MISSION_ITEM_REACHED and the cursor moves to the next NAV command, following DO_JUMP
(with its repeat count) on the way. The DO and CONDITION commands passed over on the way
there are the *do* list of the new NAV command, and each of them runs once, as on
ArduPilot (``AP_Mission::advance_current_nav_cmd``): the first starts just before the NAV
command (so its "Mission: N" text comes first), the others right after it. DO commands
act at once; a CONDITION command (delay, yaw) holds back the DO commands after it until
it is satisfied, and whatever the do list has not reached when the NAV command completes
is dropped. So a DO command placed after a waypoint acts on the leg *from* that waypoint,
and the DO commands before the first NAV command run when the mission starts. After the
last NAV command only the first DO command runs: ArduPilot's mission is complete as soon
as the search for a next NAV command reaches the end of the list.
Every command started is announced with STATUSTEXT "Mission: N <name>"; commands the
executor does not know are skipped with "Skipping invalid cmd #<id>".

A multicopter flies waypoints, the approach to a loiter and to a NAV_LAND point as
ArduCopter's waypoint navigator flies them (S-curve legs, :mod:`sitl.track`; a plane or a
rover flies each leg its own way, done within its waypoint radius); a NAV_WAYPOINT without a
hold time whose next NAV command is another waypoint or a timed or unlimited loiter blends
into the leg after it and counts as reached at the apex of the turn, as ArduCopter's
``ModeAuto::set_next_wp`` arranges; any other item stops on its point. The take-off climbs
with the position controller as ``auto_takeoff`` does.
NAV_LAND with a latitude or longitude flies to that point at the altitude the vehicle
has when the item starts, and only then descends (ArduCopter's ``ModeAuto::do_land``
ignores the item's altitude); without one it descends where the vehicle is.
DO_CHANGE_SPEED's param1 says which speed param2 sets: 0 (airspeed) and 1 (ground
speed) the horizontal speed, 2 the climb speed, 3 the descent speed; a speed that is not
positive (-1: no change) changes nothing (``ModeAuto::do_change_speed``).

The executor moves nothing itself: it tells the vehicle what to do through the
:class:`Pilot` interface (fly to, circle, land, return home) and asks it where it is.
How each of those is flown is the vehicle's: a fixed-wing (``lands_vertically`` False)
starts NAV_LAND's glide at once instead of flying over the point first, and one that
``orbits`` circles a loiter item's centre at its radius itself, the turns being counted
at its own rate around the circle; NAV_RETURN_TO_LAUNCH is done when the vehicle says it
has ``returned`` (landed, for a multicopter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from sitl.items import MissionItem

# MAV_CMD ids the executor knows.
NAV_WAYPOINT, NAV_LOITER_UNLIM, NAV_LOITER_TURNS, NAV_LOITER_TIME = 16, 17, 18, 19
NAV_RETURN_TO_LAUNCH, NAV_LAND, NAV_TAKEOFF, NAV_DELAY = 20, 21, 22, 93
CONDITION_DELAY, CONDITION_YAW = 112, 115
DO_JUMP, DO_CHANGE_SPEED, DO_SET_HOME = 177, 178, 179
DO_DIGICAM_CONTROL, DO_SET_CAM_TRIGG_DIST, DO_GRIPPER = 203, 206, 211
DO_SET_ROI_LOCATION, DO_SET_ROI_NONE, DO_SET_ROI = 195, 197, 201
IMAGE_START_CAPTURE, IMAGE_STOP_CAPTURE = 2000, 2001

NAMES = {
    NAV_WAYPOINT: "WP", NAV_LOITER_UNLIM: "LoitUnlim", NAV_LOITER_TURNS: "LoitTurns",
    NAV_LOITER_TIME: "LoitTime", NAV_RETURN_TO_LAUNCH: "RTL", NAV_LAND: "Land",
    NAV_TAKEOFF: "Takeoff", NAV_DELAY: "Delay", CONDITION_DELAY: "CondDelay",
    CONDITION_YAW: "CondYaw", DO_JUMP: "Jump", DO_CHANGE_SPEED: "ChangeSpeed",
    DO_SET_HOME: "SetHome", DO_DIGICAM_CONTROL: "DigiCamCtrl",
    DO_SET_CAM_TRIGG_DIST: "SetCamTrigDst", DO_GRIPPER: "Gripper",
    DO_SET_ROI_LOCATION: "SetROILocation", DO_SET_ROI_NONE: "SetROINone", DO_SET_ROI: "SetROI",
    IMAGE_START_CAPTURE: "ImageStart", IMAGE_STOP_CAPTURE: "ImageStop",
}
NAV_COMMANDS = frozenset({
    NAV_WAYPOINT, NAV_LOITER_UNLIM, NAV_LOITER_TURNS, NAV_LOITER_TIME, NAV_RETURN_TO_LAUNCH,
    NAV_LAND, NAV_TAKEOFF, NAV_DELAY,
})
# Below this id a MAV_CMD is a navigation command in ArduPilot's numbering.
NAV_LAST = 95
# NAV commands a waypoint flies on into without stopping (ModeAuto::set_next_wp).
BLENDS_INTO = frozenset({NAV_WAYPOINT, NAV_LOITER_UNLIM, NAV_LOITER_TIME})
# DO_CHANGE_SPEED param1 (MAVLink SPEED_TYPE).
SPEED_AIR, SPEED_GROUND, SPEED_CLIMB, SPEED_DESCENT = 0, 1, 2, 3

Vector = tuple[float, float, float]


class Pilot(Protocol):
    """What the executor needs from the vehicle."""

    time: float
    control_period: float  # seconds per control step
    lands_vertically: bool
    orbits: bool
    says_circles: bool  # "Mission: starting circle i/N", as ArduCopter's verify_circle

    @property
    def position(self) -> Vector: ...  # read-only: the model derives it from its state
    @property
    def heading(self) -> float: ...

    def item_position(self, item: MissionItem) -> Vector: ...
    def fly_to(self, target: Vector) -> None: ...
    def take_off(self, target: Vector) -> None: ...
    def loiter_at(self, centre: Vector, radius: float, clockwise: bool) -> None: ...
    def circle_rate(self, radius: float) -> float: ...
    def returned(self) -> bool: ...
    def fly_leg(self, target: Vector, following: Vector | None = None) -> None: ...
    def leg_done(self, target: Vector, radius: float) -> bool: ...
    def hold(self) -> None: ...
    def land_at(self, north: float, east: float) -> None: ...
    def return_home(self) -> None: ...
    def has_landed(self) -> bool: ...
    def set_speed(self, speed_type: int, speed: float) -> None: ...
    def set_yaw(self, heading: float, rate: float) -> None: ...
    def yaw_settled(self) -> bool: ...
    def set_home_from(self, item: MissionItem) -> None: ...
    def do_command(self, item: MissionItem) -> None: ...
    def look_at(self, point: Vector | None) -> None: ...  # nose at a point (None: let go)
    def text(self, severity: int, message: str) -> None: ...
    def reached(self, seq: int) -> None: ...


@dataclass
class _Nav:
    index: int
    target: Vector
    phase: str = "go"  # go -> hold/circle/descend -> done
    since: float = 0.0
    angle: float = 0.0  # loiter turns: degrees travelled
    centre: Vector | None = None  # loiter turns of a vehicle that does not orbit: the centre
    start: float = 0.0  # ... and the bearing from it (degrees) where the circle starts
    closing: str = ""  # a STATUSTEXT said once the item is reached


class AutoMission:
    """Runs the items (seq 0 = home, never flown) for one AUTO session."""

    def __init__(self, items: list[MissionItem], pilot: Pilot, waypoint_radius: float) -> None:
        self.items = items
        self.pilot = pilot
        self.waypoint_radius = waypoint_radius
        self.nav: _Nav | None = None
        self.finished = False
        self._dos: list[int] = []
        self._condition_started: float | None = None
        self._jumps: dict[int, int] = {}

    @property
    def current(self) -> int:
        """The seq MISSION_CURRENT reports: the NAV command in progress."""
        if self.nav is not None:
            return self.nav.index
        return max(0, len(self.items) - 1) if self.finished else 0

    def start(self, index: int = 1) -> None:
        """Begin (or resume) at ``index``."""
        self.finished = False
        self._jumps.clear()
        self._advance(max(1, index))

    def update(self) -> None:
        """One control step: progress the NAV command, then the DO cursor."""
        if self.finished or self.nav is None:
            return
        if self._update_nav(self.nav):
            done = self.nav.index
            self.pilot.reached(done)
            if self.nav.closing:
                self.pilot.text(6, self.nav.closing)
            self._advance(done + 1)
        self._run_dos()

    def _advance(self, index: int) -> None:
        pending: list[int] = []  # the DO/CONDITION items between here and the next NAV
        while index < len(self.items):
            item = self.items[index]
            if item.command == DO_JUMP:
                index = self._jump(index, item)
                continue
            if item.command in NAV_COMMANDS:
                self.nav = _Nav(index, self.pilot.item_position(item), since=self.pilot.time)
                self._dos, self._condition_started = pending, None
                self._run_dos(limit=1)
                self._announce(item)
                self._start_nav(self.nav, item)
                self._run_dos()
                return
            if item.command < NAV_LAST:
                self.pilot.text(4, f"Skipping invalid cmd #{item.command}")
            else:
                pending.append(index)
            index += 1
        self.nav = None
        self._dos, self._condition_started = pending[:1], None
        self._run_dos()
        self._dos = []
        self.finished = True
        if self.pilot.has_landed():
            return
        self.pilot.hold()

    def _jump(self, index: int, item: MissionItem, count: bool = True) -> int:
        repeats = int(item.param2)
        done = self._jumps.get(index, 0)
        target = int(item.param1)
        if (repeats < 0 or done < repeats) and 1 <= target < len(self.items):
            if count:
                self._jumps[index] = done + 1
            return target
        return index + 1

    def _next_nav(self, index: int) -> MissionItem | None:
        """The NAV command after ``index``, following jumps without counting them."""
        seen: set[int] = set()
        while index < len(self.items) and index not in seen:
            seen.add(index)
            item = self.items[index]
            if item.command == DO_JUMP:
                index = self._jump(index, item, count=False)
            elif item.command in NAV_COMMANDS:
                return item
            else:
                index += 1
        return None

    def _announce(self, item: MissionItem) -> None:
        name = NAMES.get(item.command, str(item.command))
        self.pilot.text(6, f"Mission: {item.seq} {name}")

    def _start_nav(self, nav: _Nav, item: MissionItem) -> None:
        pilot = self.pilot
        if item.command == NAV_TAKEOFF:
            here = pilot.position
            nav.target = (here[0], here[1], nav.target[2])
            pilot.take_off(nav.target)
            return
        if item.command == NAV_RETURN_TO_LAUNCH:
            pilot.return_home()
            return
        elif item.command == NAV_DELAY:
            nav.target = pilot.position
            pilot.hold()
            nav.phase = "hold"
            return
        elif item.command == NAV_LAND:
            here = pilot.position
            if item.x == 0 and item.y == 0:
                pilot.land_at(here[0], here[1])
                nav.phase = "descend"
                return
            if not pilot.lands_vertically:  # glides down to the point from here
                pilot.land_at(nav.target[0], nav.target[1])
                nav.phase = "descend"
                return
            nav.target = (nav.target[0], nav.target[1], here[2])
        elif item.command == NAV_LOITER_TURNS and not pilot.orbits:
            # As ArduCopter's ModeAuto::circle_movetoedge_start: round at once from the
            # bearing the vehicle is at (ahead along its heading when over the centre),
            # moving out as it goes; from more than 3 m outside the circle, to its nearest
            # edge first.
            centre, here = nav.target, pilot.position
            away = math.hypot(here[0] - centre[0], here[1] - centre[1])
            nav.start = pilot.heading if away < 0.5 else math.degrees(
                math.atan2(here[1] - centre[1], here[0] - centre[0]))
            radius, start = abs(item.param3) or 10.0, math.radians(nav.start)
            nav.centre = centre
            if away <= radius + 3.0:
                self._start_circle(nav, item)
                return
            nav.target = (centre[0] + radius * math.cos(start),
                          centre[1] + radius * math.sin(start), centre[2])
        following = None
        if item.command == NAV_WAYPOINT and item.param1 <= 0:
            after = self._next_nav(nav.index + 1)
            if after is not None and after.command in BLENDS_INTO:
                following = pilot.item_position(after)
        pilot.fly_leg(nav.target, following)

    def _update_nav(self, nav: _Nav) -> bool:
        item, pilot = self.items[nav.index], self.pilot
        command = item.command
        if command == NAV_RETURN_TO_LAUNCH:
            return pilot.returned()
        if command == NAV_DELAY:
            return pilot.time - nav.since >= item.param1
        if nav.phase == "descend":
            return pilot.has_landed()
        if command == NAV_TAKEOFF:
            return abs(pilot.position[2] - nav.target[2]) < 0.2
        if nav.phase == "go":
            # ArduCopter keeps no acceptance radius in a NAV_WAYPOINT: its waypoint
            # navigator decides (WPNAV_RADIUS); a plane or a rover its WP_RADIUS.
            radius = self.waypoint_radius if command == NAV_WAYPOINT else 1.0
            if not pilot.leg_done(nav.target, radius):
                return False
            nav.phase, nav.since = "hold", pilot.time
            if command == NAV_LAND:
                pilot.land_at(nav.target[0], nav.target[1])
                nav.phase = "descend"
                return False
            if command == NAV_LOITER_TURNS:
                self._start_circle(nav, item)
            if pilot.orbits and command in (NAV_LOITER_UNLIM, NAV_LOITER_TIME,
                                            NAV_LOITER_TURNS):
                pilot.loiter_at(nav.target, abs(item.param3), item.param3 >= 0)
        if command == NAV_WAYPOINT:
            return pilot.time - nav.since >= item.param1
        if command == NAV_LOITER_TIME:
            return pilot.time - nav.since >= item.param1
        if command == NAV_LOITER_TURNS:
            return self._circle(nav, item)
        return False  # NAV_LOITER_UNLIM: until the mode changes or the mission is moved on

    def _start_circle(self, nav: _Nav, item: MissionItem) -> None:
        nav.phase = "circle"
        self.pilot.look_at(nav.centre)  # AutoYaw's CIRCLE mode: the nose at the centre
        if self.pilot.says_circles:
            self.pilot.text(6, f"Mission: starting circle 1/{round(item.param1)}")

    def _circle(self, nav: _Nav, item: MissionItem) -> bool:
        radius = abs(item.param3) or 10.0
        clockwise = item.param3 >= 0
        before = nav.angle
        nav.angle += self.pilot.circle_rate(radius) * self.pilot.control_period
        if self.pilot.orbits:  # it flies the circle itself
            return nav.angle >= 360.0 * max(item.param1, 0.0)
        turns = int(nav.angle // 360.0)
        said = f"Mission: starting circle {turns + 1}/{round(item.param1)}"
        centre = nav.target if nav.centre is None else nav.centre
        if nav.angle >= 360.0 * max(item.param1, 0.0):
            if self.pilot.says_circles:  # ArduCopter says it after the item is reached
                nav.closing = said
            self.pilot.look_at(None)
            self.pilot.fly_to(self.pilot.position)  # leaves from the edge, as ArduCopter
            return True
        if turns > int(before // 360.0) and self.pilot.says_circles:
            self.pilot.text(6, said)
        bearing = math.radians(nav.start + (nav.angle if clockwise else -nav.angle))
        self.pilot.fly_to((
            centre[0] + radius * math.cos(bearing), centre[1] + radius * math.sin(bearing),
            centre[2],
        ))
        return False

    def _run_dos(self, limit: int | None = None) -> None:
        """Run the do list up to a CONDITION not yet satisfied, or ``limit`` new items."""
        started = 0
        while self._dos and (limit is None or started < limit):
            item = self.items[self._dos[0]]
            if item.command in (CONDITION_DELAY, CONDITION_YAW):
                if self._condition_started is None:
                    started += 1
                    self._announce(item)
                    self._condition_started = self.pilot.time
                    if item.command == CONDITION_YAW:
                        self._start_yaw(item)
                if not self._condition_done(item):
                    return
                self._condition_started = None
                self._dos.pop(0)
                continue
            self._dos.pop(0)
            started += 1
            self._announce(item)
            self._run_do(item)

    def _start_yaw(self, item: MissionItem) -> None:
        heading = item.param1
        if item.param4:
            direction = -1.0 if item.param3 < 0 else 1.0
            heading = self.pilot.heading + direction * item.param1
        self.pilot.set_yaw(heading % 360.0, item.param2 or 60.0)

    def _condition_done(self, item: MissionItem) -> bool:
        assert self._condition_started is not None
        if item.command == CONDITION_DELAY:
            return self.pilot.time - self._condition_started >= item.param1
        return self.pilot.yaw_settled()

    def _run_do(self, item: MissionItem) -> None:
        pilot = self.pilot
        if item.command == DO_CHANGE_SPEED:
            if item.param2 > 0 and int(item.param1) in (
                    SPEED_AIR, SPEED_GROUND, SPEED_CLIMB, SPEED_DESCENT):
                pilot.set_speed(int(item.param1), item.param2)
        elif item.command == DO_SET_HOME:
            pilot.set_home_from(item)
        elif item.command in NAMES:
            pilot.do_command(item)
        else:
            pilot.text(4, f"Skipping invalid cmd #{item.command}")
