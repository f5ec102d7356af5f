"""A companion computer (MAVLink component 191) that runs the recognition skills.

It speaks only standard MAVLink, on the same link as the autopilot, so a real onboard
computer can take its place:

- HEARTBEAT at 1 Hz, type ONBOARD_CONTROLLER, autopilot INVALID (ground stations do not
  mistake it for the vehicle).
- A skill is switched on or off with PARAM_SET addressed to component 191: ``AVOID_OBST``,
  ``RECOG_MARKERS``, ``RECOG_ARUCO``, ``SELF_LOCATE``, ``RECOG_ITEMS``, ``RECOG_BUCKETS``
  (1 on, 0 off); camera footprint parameters ``CAM_HFOV``/``CAM_VFOV`` (degrees) and
  ``CAM_RANGE`` (m), and ``DET_RATE`` (reports per second).
- While a recognition skill is on, each matching world object inside the footprint of the
  downward camera is reported ``DET_RATE`` times a second with NAMED_VALUE_INT (name = the
  kind's tag, value = the object's number) and DEBUG_VECT (same name, same time stamp,
  x/y/z = the object's north/east/up in metres from home). An object's number is its
  ``ident`` when that is an integer, else its 1-based rank among the world's objects of
  its kind; the first sighting of an object is also announced with STATUSTEXT
  ``"Detected <kind> <number> <ident>"``.
- SELF_LOCATE: while a marker (any kind of marker) is in view, VISION_POSITION_ESTIMATE
  carries the vehicle's position (local NED) worked out from it.
- AVOID_OBST: the vehicle stops ``AVOID_MARGIN`` short of obstacles (the model asks
  :attr:`Companion.avoiding`), and DISTANCE_SENSOR reports the nearest obstacle.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.messages import COMPANION, stamp, statustext
from sitl.params import COMPANION_DEFAULTS, Params, param_replies
from tml.world import World, WorldObject

SKILL_KINDS = {
    "RECOG_MARKERS": ("marker", "frame"),
    "RECOG_ARUCO": ("aruco",),
    "RECOG_ITEMS": ("item", "subject"),
    "RECOG_BUCKETS": ("bucket",),
}
TAGS = {
    "marker": "MARKER", "aruco": "ARUCO", "item": "ITEM", "bucket": "BUCKET",
    "frame": "FRAME", "subject": "SUBJECT",
}
MARKER_KINDS = ("marker", "aruco", "frame")


def object_numbers(world: World) -> dict[WorldObject, int]:
    """The number each object is reported with (see the module docstring)."""
    numbers: dict[WorldObject, int] = {}
    ranks: dict[str, int] = {}
    for obj in world.objects:
        ranks[obj.kind] = ranks.get(obj.kind, 0) + 1
        numbers[obj] = int(obj.ident) if obj.ident.strip().lstrip("-").isdigit() else (
            ranks[obj.kind]
        )
    return numbers


def in_footprint(
    obj: WorldObject, position: tuple[float, float, float], heading: float, params: Params
) -> bool:
    """True when ``obj`` is inside the downward camera's view from ``position``."""
    height = position[2] - obj.altitude
    if not 0.5 <= height <= params["CAM_RANGE"]:
        return False
    half_width = height * math.tan(math.radians(params["CAM_HFOV"]) / 2)
    half_length = height * math.tan(math.radians(params["CAM_VFOV"]) / 2)
    dn, de = obj.north - position[0], obj.east - position[1]
    yaw = math.radians(heading)
    forward = dn * math.cos(yaw) + de * math.sin(yaw)
    right = -dn * math.sin(yaw) + de * math.cos(yaw)
    return abs(forward) <= half_length and abs(right) <= half_width


class Companion:
    """The onboard computer of one vehicle. ``nearest_obstacle`` gives metres or None."""

    def __init__(
        self, system_id: int, world: World,
        nearest_obstacle: Callable[[tuple[float, float, float]], float | None],
    ) -> None:
        self.system_id = system_id
        self.world = world
        self.params = Params(COMPANION_DEFAULTS)
        self._numbers = object_numbers(world)
        self._nearest_obstacle = nearest_obstacle
        self._next_heartbeat = 0.0
        self._next_report = 0.0
        self.next_due = 0.0  # when :meth:`step` has something to say next
        self._seen: set[WorldObject] = set()

    @property
    def avoiding(self) -> bool:
        """True while the obstacle-avoidance skill is on."""
        return self.params["AVOID_OBST"] > 0

    def handle(self, msg: Any) -> list[Any]:
        """Replies to a message addressed to component 191 (the parameter protocol)."""
        return [self._stamp(reply) for reply in param_replies(self.params, msg)]

    def step(self, time: float, position: tuple[float, float, float] | None,
             heading: float) -> list[Any]:
        """Messages due at vehicle ``time`` with the vehicle at ``position`` (north, east,
        up from home); with ``position`` None (not known yet) only the HEARTBEAT."""
        if time < self.next_due:
            return []  # most control steps: nothing is due
        out: list[Any] = []
        if time >= self._next_heartbeat:
            self._next_heartbeat = time + 1.0
            out.append(mavlink.MAVLink_heartbeat_message(
                mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                mavlink.MAV_STATE_ACTIVE, 3,
            ))
        rate = self.params["DET_RATE"]
        if position is not None and rate > 0 and time >= self._next_report:
            self._next_report = time + 1.0 / rate
            out.extend(self._report(time, position, heading))
        self.next_due = min(self._next_heartbeat, self._next_report)
        return [self._stamp(msg) for msg in out]

    def _report(
        self, time: float, position: tuple[float, float, float], heading: float
    ) -> list[Any]:
        out: list[Any] = []
        stamp_ms = int(time * 1000)
        kinds = {k for skill, ks in SKILL_KINDS.items() if self.params[skill] > 0 for k in ks}
        visible = [o for o in self.world.objects if in_footprint(o, position, heading, self.params)]
        for obj in visible:
            if obj.kind not in kinds:
                continue
            tag, number = TAGS[obj.kind].encode(), self._numbers[obj]
            if obj not in self._seen:
                self._seen.add(obj)
                out.append(statustext(6, f"Detected {obj.kind} {number} {obj.ident}"))
            out.append(mavlink.MAVLink_named_value_int_message(stamp_ms, tag, number))
            out.append(mavlink.MAVLink_debug_vect_message(
                tag, stamp_ms * 1000, obj.north, obj.east, obj.altitude
            ))
        if self.params["SELF_LOCATE"] > 0 and any(o.kind in MARKER_KINDS for o in visible):
            out.append(mavlink.MAVLink_vision_position_estimate_message(
                stamp_ms * 1000, position[0], position[1], -position[2], 0.0, 0.0,
                math.radians(heading),
            ))
        if self.avoiding:
            distance = self._nearest_obstacle(position)
            if distance is not None:
                out.append(mavlink.MAVLink_distance_sensor_message(
                    stamp_ms, 20, 4000, min(4000, round(distance * 100)),
                    mavlink.MAV_DISTANCE_SENSOR_LASER, 0, mavlink.MAV_SENSOR_ROTATION_NONE, 0,
                ))
        return out

    def _stamp(self, msg: Any) -> Any:
        return stamp(msg, self.system_id, COMPANION)
