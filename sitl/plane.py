"""A simulated ArduPlane: a fixed-wing that keeps its airspeed, turns with a radius and
cannot hover or take off in GUIDED.

Theory of operation. The model is :class:`sitl.model.VehicleModel` (the same messages,
parameters, mission protocol, failsafes and AUTO executor) with ArduPlane's HEARTBEAT
type, modes (:data:`sitl.modes.PLANE`), parameters (:data:`sitl.params.PLANE_DEFAULTS`,
the values of ArduPilot's plane.parm) and flight. What it does follows ArduPlane SITL as
measured:

- it flies at AIRSPEED_CRUISE (or the speed DO_CHANGE_SPEED set), climbs and sinks at
  TECS_CLMB_MAX / TECS_SINK_MAX, and turns no faster than a coordinated turn at
  ROLL_LIMIT_DEG allows, so its tightest circle grows with its speed;
- it never stops in the air: a point it is sent to is circled (GUIDED, LOITER, RTL and
  the end of a waypoint run), clockwise at WP_LOITER_RAD unless the command gave a radius;
- it takes off only in TAKEOFF mode (a climb along its heading to TKOFF_ALT, then a circle
  around the point TKOFF_DIST ahead) or from a NAV_TAKEOFF in AUTO; NAV_TAKEOFF as a
  command is refused (FAILED), NAV_LAND and CONDITION_YAW are UNSUPPORTED, and a
  SET_POSITION_TARGET_GLOBAL_INT changes only the altitude: DO_REPOSITION moves it;
- RTL climbs to RTL_ALTITUDE and circles home (it does not land); an AUTO mission that
  ends in the air switches to RTL ("Mission complete, changing mode to RTL");
- NAV_LAND glides from where the item starts along a straight line to the touchdown,
  flares at LAND_FLARE_ALT, rolls out, and disarms LAND_DISARMDELAY s later;
- while disarmed on the ground, home follows the vehicle (ArduPlane keeps resetting it
  until it arms), so after a landing home is where it stopped;
- it draws 11.4 A cruising level at 22 m/s, as ArduPlane SITL's simulated battery does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.model import TICK, Vector, VehicleModel
from sitl.modes import PLANE
from sitl.params import PLANE_DEFAULTS
from sitl.physics import Limits
from sitl.results import Result

M = mavlink
GRAVITY = 9.81
ROLL_ACCEL = 3.0  # m/s² of airspeed change
GROUND_ACCEL = 6.0  # m/s² on the take-off run
ROLLOUT_DECEL = 4.0  # m/s² braking after touch-down
FLARE_SINK = 1.5  # m/s below LAND_FLARE_ALT
LIFT_OFF = 1.2  # times AIRSPEED_MIN: rotate and climb
CLIMB_ANGLE = 15.0  # degrees of climb at most (less than TECS_CLMB_MAX when slow)
FALLING = Limits(speed=10.0, descent=10.0, accel_z=9.8, jerk_z=1000.0)  # disarmed in the air
CRUISE_AMPS, CRUISE_SPEED = 11.4, 22.0  # ArduPlane SITL's current in level cruise
CLIMB_AMPS = 2.0  # A per m/s of climb


@dataclass
class _Goal:
    """What the plane is flying: ``kind`` orbit, direct, climb, glide or level."""

    kind: str
    point: Vector = (0.0, 0.0, 0.0)
    radius: float = 0.0
    clockwise: bool = True
    start: Vector = (0.0, 0.0, 0.0)  # where a glide (or a leg) started
    then: _Goal | None = None  # after a climb


class PlaneModel(VehicleModel):
    """An ArduPlane-like vehicle (see the module docstring)."""

    mav_type = M.MAV_TYPE_FIXED_WING
    mode_table = PLANE
    parameter_table = PLANE_DEFAULTS
    initial_mode = "MANUAL"
    lands_vertically = False
    orbits = True
    yaws_to_roi = False  # DO_SET_ROI points a camera mount only, not the vehicle
    flies_s_curves = False

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.airspeed = 0.0
        self._goal: _Goal | None = None
        self._disarm_at: float | None = None

    # ------------------------------------------------------------ what it flies
    @property
    def loiter_radius(self) -> float:
        """WP_LOITER_RAD: the circle flown around a point without a radius of its own."""
        return abs(self.params["WP_LOITER_RAD"])

    def _cruise(self) -> float:
        return self.speeds.horizontal or self.params["AIRSPEED_CRUISE"]

    def _orbit(self, centre: Vector, radius: float = 0.0, clockwise: bool = True) -> _Goal:
        self._goal = _Goal("orbit", centre, abs(radius) or self.loiter_radius, clockwise)
        self._landing = None
        return self._goal

    def _orbit_here(self) -> None:
        self._orbit(self.position)

    def _climb_out(self, altitude: float, then: _Goal | None) -> None:
        self._goal = _Goal("climb", (0.0, 0.0, altitude), then=then)

    def _enter(self, name: str, previous: str, flying: bool) -> None:
        self._disarm_at = None
        if name in ("GUIDED", "LOITER", "CIRCLE") and flying:
            self._orbit_here()
        elif name == "RTL" and flying:
            self._start_rtl()
        elif name == "TAKEOFF" and self.armed:
            self._start_takeoff()
        elif name == "AUTO":
            self._start_auto(self._mission_current or 1)
        elif flying:
            self._goal = _Goal("level")
        else:
            self._goal = None

    def _start_takeoff(self) -> None:
        """TAKEOFF mode: climb along the heading, then circle the point TKOFF_DIST ahead."""
        altitude = self.params["TKOFF_ALT"]
        here, heading = self.position, math.radians(self.heading)
        distance = self.params["TKOFF_DIST"]
        ahead = (here[0] + distance * math.cos(heading), here[1] + distance * math.sin(heading),
                 max(altitude, here[2]))
        circle = _Goal("orbit", ahead, self.loiter_radius)
        if not self.landed:
            self._goal = _Goal("climb", (0.0, 0.0, ahead[2]), then=circle) \
                if here[2] < altitude else circle
            return
        self._text(M.MAV_SEVERITY_INFO, f"Takeoff to {altitude:.0f}m for {distance:.1f}m "
                                        f"heading {self.heading:.1f} deg")
        self._climb_out(altitude, circle)

    def _start_auto(self, index: int) -> None:
        from sitl import auto

        if not self.armed or len(self.mission_items) < 2:
            return
        self.auto = auto.AutoMission(self.mission_items, self, abs(self.params["WP_RADIUS"]))
        self.auto.start(index)

    def _start_rtl(self) -> None:
        home = self._home_local()
        self._orbit((home[0], home[1], self.params["RTL_ALTITUDE"]),
                    self.params["RTL_RADIUS"] or self.loiter_radius)

    def _update_rtl(self) -> None:
        """RTL circles home until told otherwise: nothing changes on the way."""

    # ------------------------------------------------------------ arming
    def _arm(self, forced: bool) -> Result:
        result = super()._arm(forced)
        if result == Result.ACCEPTED and self.landed:
            self._disarm_at = None
            if self.mode == "TAKEOFF":
                self._text(M.MAV_SEVERITY_INFO, "Triggered AUTO. GPS speed = 0.0")
                self._start_takeoff()
            elif self.mode == "AUTO" and self.auto is None:
                self._start_auto(self._mission_current or 1)
        return result

    def disarm(self) -> None:
        """Stop the motor (in flight, the plane glides down)."""
        super().disarm()
        self._goal, self._disarm_at = None, None

    def _current(self) -> float:
        """Amperes drawn: ArduPlane SITL cruising level at 22 m/s draws 11.4 A (measured),
        growing with the square of the airspeed and with the climb; nothing on the ground
        with the motor idle."""
        if not self.armed or (self.landed and self.airspeed == 0.0):
            return 0.0
        climb = max(self.body.velocity[2], 0.0)
        return CRUISE_AMPS * (self.airspeed / CRUISE_SPEED) ** 2 + CLIMB_AMPS * climb

    def _auto_disarm(self) -> None:
        """ArduPlane disarms LAND_DISARMDELAY s after an automatic landing, never idle."""
        if self.armed and self._disarm_at is not None and self.time >= self._disarm_at:
            self.disarm()
            self._text(M.MAV_SEVERITY_INFO, "Auto disarmed")

    # ------------------------------------------------------------ commands
    def _execute(self, command: int, p: list[float], extra: list[Any]) -> Result:
        if command == M.MAV_CMD_NAV_TAKEOFF:
            return Result.FAILED  # only a quadplane takes off on command
        if command in (M.MAV_CMD_NAV_LAND, M.MAV_CMD_CONDITION_YAW,
                       M.MAV_CMD_DO_PAUSE_CONTINUE):  # a plane's pause is not imitated
            return Result.UNSUPPORTED
        return super()._execute(command, p, extra)

    def _reposition(self, p: list[float]) -> Result:
        """DO_REPOSITION: circle the point (param3 the radius, param4 non-zero
        counter-clockwise) in GUIDED; taken on the ground too, where nothing moves."""
        change_mode = round(p[1]) & M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE
        if not change_mode and self.mode != "GUIDED":
            return Result.FAILED
        if self.mode != "GUIDED" and not self.set_mode("GUIDED"):
            return Result.FAILED
        target = self._reposition_target(p)
        clockwise = math.isnan(p[3]) or p[3] == 0
        radius = p[2] if not math.isnan(p[2]) and p[2] > 0 else 0.0
        if self.armed and not self.landed:
            self._orbit(target, radius, clockwise)
        return Result.ACCEPTED

    def _global_target(self, msg: Any) -> None:
        """ArduPlane takes only the altitude of a SET_POSITION_TARGET_GLOBAL_INT."""
        if self.mode != "GUIDED" or self._goal is None or msg.type_mask & 0b100:
            return
        base = 0.0 if msg.coordinate_frame in (0, 5) else self.home.altitude
        up = msg.alt + base - self.origin.altitude
        self._goal.point = (*self._goal.point[:2], up)

    def _local_target(self, msg: Any) -> None:
        """Not a way to move a plane (ArduPlane changes at most the altitude)."""

    # ------------------------------------------------------------ Pilot API
    def fly_to(self, target: Vector) -> None:
        """Fly at ``target`` (a waypoint flown through; circled if nothing follows it)."""
        self._goal = _Goal("direct", target, start=self.position)
        self._landing = None

    def take_off(self, target: Vector) -> None:
        """NAV_TAKEOFF: climb along the heading to the item's altitude."""
        if self.landed:
            self._text(M.MAV_SEVERITY_INFO, f"Takeoff to {target[2]:.0f}m")
        self._climb_out(target[2], None)

    def hold(self) -> None:
        """Circle here; at the end of an AUTO mission, RTL as ArduPlane does."""
        if self.mode == "AUTO" and self.auto is not None and self.auto.finished:
            self._text(M.MAV_SEVERITY_INFO, "Mission complete, changing mode to RTL")
            self.set_mode("RTL")
            return
        self._orbit_here()

    def loiter_at(self, centre: Vector, radius: float, clockwise: bool) -> None:
        """A loiter item: circle its centre (at WP_LOITER_RAD without a radius)."""
        self._orbit(centre, radius, clockwise)

    def circle_rate(self, radius: float) -> float:
        """Degrees per second around a circle of ``radius`` at the present airspeed."""
        return math.degrees(max(self.airspeed, 1.0) / max(radius, 1.0))

    def land_at(self, north: float, east: float) -> None:
        """Glide from here along a straight line to touch down at (north, east)."""
        self._goal = _Goal("glide", (north, east, 0.0), start=self.position)
        self._landing = (north, east)

    def return_home(self) -> None:
        """NAV_RETURN_TO_LAUNCH: back over home at RTL_ALTITUDE, circling."""
        self._start_rtl()

    def returned(self) -> bool:
        """Over home: within the circle flown around it."""
        home = self._home_local()
        return math.hypot(self.position[0] - home[0], self.position[1] - home[1]) <= \
            (self.params["RTL_RADIUS"] or self.loiter_radius) * 1.5

    def arrived(self, target: Vector, radius: float) -> bool:
        """Within ``radius`` of the waypoint, past it (ArduPlane's finish line: the line
        through the waypoint across the leg), or already circling it."""
        here = self.position
        dn, de = here[0] - target[0], here[1] - target[1]
        if math.hypot(dn, de) <= radius:
            return True
        goal = self._goal
        if goal is not None and goal.kind == "orbit" and goal.point[:2] == target[:2]:
            return True
        if goal is None or goal.kind != "direct":
            return False
        leg = (target[0] - goal.start[0], target[1] - goal.start[1])
        return math.hypot(*leg) > 1.0 and dn * leg[0] + de * leg[1] > 0

    def set_yaw(self, heading: float, rate: float, direction: int = 0) -> None:
        """A plane's heading is its course: nothing to turn to."""

    # ------------------------------------------------------------ flight
    def _fly(self) -> None:
        body = self.body
        if not self.armed:
            self.airspeed = 0.0
            if self.landed:
                body.stop()
                self._home_follows()
                return
            body.shape_velocity((0.0, 0.0, -5.0), FALLING, TICK)
            return
        goal = self._goal
        if self.landed and (goal is None or goal.kind != "climb"):
            self.airspeed = max(0.0, self.airspeed - ROLLOUT_DECEL * TICK)
            self._roll_on()
            return
        if goal is None:
            goal = self._goal = _Goal("level")
        course, altitude, speed = self._steer(goal)
        self._fly_toward(course, altitude, speed, goal)

    def _steer(self, goal: _Goal) -> tuple[float, float, float]:
        """(course in degrees, altitude, airspeed) the goal asks for now."""
        here = self.position
        cruise = self._cruise()
        if goal.kind == "climb":
            if here[2] >= goal.point[2] - 0.01 and not self.landed:
                self._goal = goal.then or _Goal("level")
                return self._steer(self._goal)
            return self.heading, goal.point[2], cruise
        if goal.kind == "level":
            return self.heading, here[2], cruise
        centre = goal.point
        dn, de = centre[0] - here[0], centre[1] - here[1]
        distance = math.hypot(dn, de)
        to_centre = math.degrees(math.atan2(de, dn))
        if goal.kind == "direct":
            if distance < self._turn_radius(cruise):  # nothing moved it on: circle it
                return self._steer(self._orbit(centre))
            return to_centre, centre[2], cruise
        if goal.kind == "glide":
            # Down the line from where the glide started, aimed so that the flare (below
            # LAND_FLARE_ALT, course held) puts the wheels on the touchdown point.
            flare = self.params["LAND_FLARE_ALT"]
            if here[2] <= flare:
                return self.heading, 0.0, cruise
            start = goal.start
            float_out = flare / FLARE_SINK * cruise
            total = max(math.hypot(centre[0] - start[0], centre[1] - start[1]) - float_out,
                        1.0)
            share = min(1.0, max(distance - float_out, 0.0) / total)
            return to_centre, start[2] * share, cruise
        # orbit: the tangent, turned in toward the circle by how far off it the plane is
        radius = max(goal.radius, self._turn_radius(cruise))
        outward = to_centre + 180.0
        lead = max(0.3 * radius, 15.0)
        correction = math.degrees(math.atan2(distance - radius, lead))
        turn = 1.0 if goal.clockwise else -1.0
        return outward + turn * (90.0 + correction), centre[2], cruise

    def _turn_radius(self, speed: float) -> float:
        bank = math.radians(min(max(self.params["ROLL_LIMIT_DEG"], 5.0), 85.0))
        return speed * speed / (GRAVITY * math.tan(bank))

    def _fly_toward(self, course: float, altitude: float, speed: float, goal: _Goal) -> None:
        body, p = self.body, self.params
        before = body.position
        on_ground = self.landed
        if on_ground:  # the take-off run: along the runway heading, gathering speed
            self.airspeed = min(speed, self.airspeed + GROUND_ACCEL * TICK)
            course = self.heading
        else:
            self.airspeed += max(-ROLL_ACCEL * TICK, min(ROLL_ACCEL * TICK,
                                                         speed - self.airspeed))
            rate = math.degrees(GRAVITY * math.tan(math.radians(
                min(max(p["ROLL_LIMIT_DEG"], 5.0), 85.0))) / max(self.airspeed, 1.0))
            body.turn(course % 360.0, rate, TICK)
        heading = math.radians(self.heading)
        climb = 0.0
        flying_speed = self.airspeed >= LIFT_OFF * p["AIRSPEED_MIN"]
        if flying_speed or not on_ground:
            ceiling = min(p["TECS_CLMB_MAX"],
                          self.airspeed * math.sin(math.radians(CLIMB_ANGLE)))
            error = altitude - body.position[2]
            climb = max(-p["TECS_SINK_MAX"], min(ceiling, error))
            if goal.kind == "glide" and body.position[2] <= p["LAND_FLARE_ALT"]:
                climb = -FLARE_SINK  # the flare: a gentle sink to the ground
                self.airspeed = max(p["AIRSPEED_MIN"],
                                    self.airspeed - ROLL_ACCEL * TICK)
        n, e, u = body.position
        vn, ve = self.airspeed * math.cos(heading), self.airspeed * math.sin(heading)
        u_next = u + climb * TICK
        if climb > 0 and u_next > altitude >= u:
            u_next = altitude  # level off on the altitude asked for
        body.position = (n + vn * TICK, e + ve * TICK, max(0.0, u_next))
        body.velocity = (vn, ve, climb)
        if self._blocked(body.position):
            body.position = before
            body.stop()
            self.airspeed = 0.0
        if self.landed and body.position[2] > 0.05:
            self.landed = False
            self._text(M.MAV_SEVERITY_INFO, "Takeoff")
        elif not on_ground and body.position[2] <= 0.0:
            self.landed = True  # touch-down (the roll-out follows)
            self._goal = None
            self._text(M.MAV_SEVERITY_INFO,
                       f"SIM Hit ground at {max(-climb, 0.0):.2f} m/s")

    def _roll_on(self) -> None:
        """On the ground: roll on along the heading until stopped."""
        body = self.body
        heading = math.radians(self.heading)
        n, e, _ = body.position
        v = self.airspeed
        body.position = (n + v * math.cos(heading) * TICK, e + v * math.sin(heading) * TICK,
                         0.0)
        body.velocity = (v * math.cos(heading), v * math.sin(heading), 0.0)

    def _check_landed(self) -> None:
        """A landing is over once the roll-out has stopped: disarm LAND_DISARMDELAY later."""
        if self.landed and self._landing is not None and self.airspeed <= 0.0:
            self._landing = None
            self.body.stop()
            self._disarm_at = self.time + self.params["LAND_DISARMDELAY"]

    def _home_follows(self) -> None:
        """Disarmed on the ground, ArduPlane moves home to where the vehicle is."""
        if not self.position_ok:
            return
        home = self._home_local()
        if math.hypot(self.position[0] - home[0], self.position[1] - home[1]) > 1.0:
            self._set_home_here()

