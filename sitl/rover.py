"""A simulated ArduPilot Rover: a ground vehicle that drives to points and stops.

Theory of operation. The model is :class:`sitl.model.VehicleModel` with Rover's HEARTBEAT
type, modes (:data:`sitl.modes.ROVER`), parameters (:data:`sitl.params.ROVER_DEFAULTS`,
the values of ArduPilot's rover.parm) and driving. What it does follows Rover SITL as
measured:

- it stays on the ground: its altitude is 0 and EXTENDED_SYS_STATE says UNDEFINED;
- it drives at WP_SPEED (or the speed DO_CHANGE_SPEED set, taken only while it drives to
  a point), accelerating at ATC_ACCEL_MAX, turning no tighter than TURN_RADIUS or the
  lateral grip ATC_TURN_MAX_G allows, slowing down for turns and, at about 0.6 m/s² as
  Rover SITL does (its jerk-limited S-curves), to stop on its point or in HOLD;
- GUIDED drives to a SET_POSITION_TARGET_GLOBAL_INT and stops on it (MISSION_ITEM_REACHED
  0); HOLD stops; RTL (and SMART_RTL) drives home and stops there, still armed ("Reached
  destination"); AUTO flies the mission and stays in AUTO, stopped, at its end; AUTO
  without a mission is refused ("No Mission. Can't set AUTO.");
- NAV_TAKEOFF, NAV_LAND and CONDITION_YAW are UNSUPPORTED; it never disarms by itself;
- it draws 12.5 A driving at 5 m/s and nothing stopped, as Rover SITL's battery does.
"""

from __future__ import annotations

import math
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.model import TICK, Vector, VehicleModel
from sitl.modes import ROVER
from sitl.params import ROVER_DEFAULTS
from sitl.results import Result

M = mavlink
GRAVITY = 9.81
STOPPED_WITHIN = 0.5  # metres from its point at which a rover stops
BRAKING = 0.6  # m/s²: how hard Rover SITL slows down for its point or in HOLD (measured)
AMPS_PER_SPEED = 2.5  # A per m/s driven (Rover SITL: 12.5 A at 5 m/s)
SLOWEST_TURN = 0.5  # m/s: the speed it keeps while turning toward a point behind it


class RoverModel(VehicleModel):
    """A Rover-like vehicle (see the module docstring)."""

    mav_type = M.MAV_TYPE_GROUND_ROVER
    mode_table = ROVER
    parameter_table = ROVER_DEFAULTS
    initial_mode = "MANUAL"
    reports_landed_state = False
    yaws_to_roi = False  # DO_SET_ROI points a camera mount only, not the vehicle
    says_circles = False  # Rover's LOITER_TURNS says nothing per circle (measured)
    flies_s_curves = False

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.speed = 0.0
        self._announce_arrival = False  # GUIDED: MISSION_ITEM_REACHED 0 on arrival

    # ------------------------------------------------------------ modes
    def set_mode(self, name: str) -> bool:
        """As the base model; AUTO needs a mission."""
        if name == "AUTO" and self.mode != "AUTO" and len(self.mission_items) < 2:
            self._text(M.MAV_SEVERITY_WARNING, "No Mission. Can't set AUTO.")
            return False
        return super().set_mode(name)

    def _starts_with_takeoff(self) -> bool:
        return True  # Rover's AUTO needs no take-off item (it is always "on the ground")

    def _enter(self, name: str, previous: str, flying: bool) -> None:
        self._announce_arrival = False
        self.speeds.horizontal = None  # every mode starts at WP_SPEED (Rover re-initialises wp_nav)
        if name in ("RTL", "SMART_RTL") and self.armed:
            self._start_rtl()
        elif name == "AUTO":
            self._start_auto(self._mission_current or 1)
        # GUIDED, HOLD, LOITER, MANUAL ...: stopped until told where to go

    def _start_auto(self, index: int) -> None:
        from sitl import auto

        if not self.armed or len(self.mission_items) < 2:
            return
        self.auto = auto.AutoMission(self.mission_items, self, self.params["WP_RADIUS"])
        self.auto.start(index)

    def _start_rtl(self) -> None:
        home = self._home_local()
        self.rtl.phase = "return"
        self._go((home[0], home[1], 0.0))

    def _update_rtl(self) -> None:
        if self.rtl.phase == "return" and self._target is None:
            self.rtl.phase = ""
            self._text(M.MAV_SEVERITY_INFO, "Reached destination")

    def _current(self) -> float:
        """Amperes drawn: Rover SITL draws 12.5 A driving at 5 m/s and nothing stopped
        (measured), in proportion to its speed."""
        return AMPS_PER_SPEED * self.speed if self.armed else 0.0

    def _auto_disarm(self) -> None:
        """Rover never disarms by itself."""

    # ------------------------------------------------------------ commands
    def _execute(self, command: int, p: list[float], extra: list[Any]) -> Result:
        if command in (M.MAV_CMD_NAV_TAKEOFF, M.MAV_CMD_NAV_LAND, M.MAV_CMD_CONDITION_YAW,
                       M.MAV_CMD_DO_PAUSE_CONTINUE):  # a rover's pause is not imitated
            return Result.UNSUPPORTED
        return super()._execute(command, p, extra)

    def _change_speed(self, speed_type: float, speed: float) -> Result:
        """Rover takes a speed in AUTO, and in GUIDED only while it drives to a point."""
        if self.mode == "GUIDED" and self._target is None:
            return Result.FAILED
        return super()._change_speed(speed_type, speed)

    def _guided_ready(self) -> bool:
        return self.mode == "GUIDED" and self.armed

    def _go(self, target: Vector) -> None:
        super()._go((target[0], target[1], 0.0))
        self._announce_arrival = self.mode == "GUIDED"

    def _reposition(self, p: list[float]) -> Result:
        change_mode = round(p[1]) & M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE
        if self.mode != "GUIDED" and not change_mode:
            return Result.DENIED
        if not self.armed or (self.mode != "GUIDED" and not self.set_mode("GUIDED")):
            return Result.FAILED
        self._go(self._reposition_target(p))
        return Result.ACCEPTED

    # ------------------------------------------------------------ Pilot API
    def fly_to(self, target: Vector) -> None:
        """Drive to ``target`` and stop there."""
        self._go(target)

    def take_off(self, target: Vector) -> None:
        """A rover has nothing to take off from."""

    def hold(self) -> None:
        """Stop."""
        self._target = None

    def land_at(self, north: float, east: float) -> None:
        """A rover has nothing to land: it stops."""
        self._target = None

    def return_home(self) -> None:
        """NAV_RETURN_TO_LAUNCH: drive home."""
        self._start_rtl()

    def circle_rate(self, radius: float) -> float:
        """Degrees per second round NAV_LOITER_TURNS: 20, at most 5 m/s along the circle
        (Rover has no WPNAV_ parameters; ArduPilot Rover measured 1 turn of 10 m in 23 s)."""
        return min(20.0, math.degrees(5.0 / radius))

    def returned(self) -> bool:
        """Home, stopped."""
        return self.rtl.phase == "" and self._target is None

    def arrived(self, target: Vector, radius: float) -> bool:
        """Within ``radius`` metres of ``target`` on the ground."""
        return math.hypot(self.position[0] - target[0],
                          self.position[1] - target[1]) <= max(radius, STOPPED_WITHIN)

    def set_yaw(self, heading: float, rate: float, direction: int = 0) -> None:
        """A rover turns only while it drives."""

    # ------------------------------------------------------------ driving
    def _fly(self) -> None:
        body, p = self.body, self.params
        target = self._target if self.armed else None
        before = body.position
        accel = max(p["ATC_ACCEL_MAX"], 0.1)
        if target is None:
            self.speed = max(0.0, self.speed - BRAKING * TICK)
            course = self.heading
        else:
            dn, de = target[0] - before[0], target[1] - before[1]
            distance = math.hypot(dn, de)
            if distance <= STOPPED_WITHIN:
                self._arrive()
                self.speed = max(0.0, self.speed - BRAKING * TICK)
                course = self.heading
            else:
                course = math.degrees(math.atan2(de, dn))
                error = math.radians((course - self.heading + 180.0) % 360.0 - 180.0)
                cruise = self.speeds.horizontal or p["WP_SPEED"] or p["CRUISE_SPEED"]
                wanted = min(cruise, math.sqrt(2.0 * BRAKING * max(distance - STOPPED_WITHIN,
                                                                   0.0)))
                wanted = max(min(wanted, SLOWEST_TURN), wanted * max(0.0, math.cos(error)))
                self.speed += max(-BRAKING * TICK, min(accel * TICK, wanted - self.speed))
        if self.speed > 0.0 or target is not None:
            body.turn(course % 360.0, self._turn_rate(), TICK)
        heading = math.radians(self.heading)
        vn, ve = self.speed * math.cos(heading), self.speed * math.sin(heading)
        body.position = (before[0] + vn * TICK, before[1] + ve * TICK, 0.0)
        body.velocity = (vn, ve, 0.0)
        if self._blocked(body.position):
            body.position = before
            body.stop()
            self.speed = 0.0

    def _turn_rate(self) -> float:
        """Degrees per second: no tighter than TURN_RADIUS, nor than the grip allows."""
        p = self.params
        speed = max(self.speed, SLOWEST_TURN)
        radius = max(p["TURN_RADIUS"], speed * speed / (max(p["ATC_TURN_MAX_G"], 0.05)
                                                       * GRAVITY))
        return math.degrees(speed / radius)

    def _arrive(self) -> None:
        self._target = None
        if self._announce_arrival:
            self._announce_arrival = False
            self._outbox.append(M.MAVLink_mission_item_reached_message(0))
