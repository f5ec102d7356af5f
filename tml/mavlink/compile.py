"""Compile a run of actions (``dispatch="mission"``) to MAVLink mission items.

Theory of operation
-------------------
:func:`compile_mission` walks the actions of a :class:`~tml.vehicle.FlyMission` in order
with a *cursor*: where the vehicle is expected to be (local north, east, up from home) and
which way it faces once the items so far have been flown. Actions relative to the last
position (MOVE, relative GO_TO_POINT, LOITER without a centre, SURVEY_AREA without a base
point, SET_ALTITUDE) are resolved against the cursor, so the items always carry explicit
coordinates and the autopilot never has to guess what "here" meant.

Every local point is converted to WGS84 with :mod:`tml.geo` against the vehicle's home.
Altitudes go in frame GLOBAL_RELATIVE_ALT_INT (above home), GLOBAL_INT when the author gave
``altitude_reference="amsl"`` and GLOBAL_TERRAIN_ALT_INT for ``terrain`` (their twins without
_INT, GLOBAL_RELATIVE_ALT ..., with ``frame_encoding="float"``). Items are numbered
from 0; :meth:`tml.mavlink.autopilot.Autopilot.upload` shifts them behind ArduPilot's home
item. ``action_index[i]`` says which action item ``i`` came from, so that MISSION_CURRENT
and MISSION_ITEM_REACHED tell the interpreter which action is being flown.

The table of what each action becomes is in docs/run.md. The points of the patterns (the
survey's lawnmower, the expanding square, moves in the body frame) come from
:mod:`tml.patterns`, where the scripts and the verifier take them too: the items carry the
path the interpreter flies with commands and the verifier checks. The module is pure: no
I/O, no clock; pymavlink is used for the MAV_CMD and MAV_FRAME numbers only.

For a fixed-wing (:mod:`tml.language.kinds`) the landings (LAND, LANDING_POINT,
RETURN_HOME_AND_LAND) become a landing sequence, as ArduPlane lands: a waypoint where the
final approach starts and NAV_LAND at the touchdown (:func:`glide_items`); ArduPlane's
NAV_RETURN_TO_LAUNCH would only circle home.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from tml.geo import Point, to_global, to_local
from tml.language.actions import GLOBAL_FRAME_NUMBERS, RAW_PARAMS, BoundAction
from tml.language.kinds import Kind, landing_approach
from tml.mavlink.codec import mavlink
from tml.mavlink.mission import LOITER_TURNS_MAX, MissionItem
from tml.patterns import displaced, expanding_square, survey
from tml.world import Home

FRAMES = {
    "relative": mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    "amsl": mavlink.MAV_FRAME_GLOBAL_INT,
    "terrain": mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
}
FLOAT_FRAMES = {
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_INT: mavlink.MAV_FRAME_GLOBAL,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
}
"""Each global frame tml writes -> its twin without _INT (frame_encoding="float"): the same
position (MAVLink made the _INT frames synonyms of their twins), named as ArduPilot's and
QGroundControl's files name it."""
SPEED_TYPES = {"airspeed": 0, "ground": 1, "climb": 2, "descent": 3}
PRECISION_MODES = {"disabled": 0, "opportunistic": 1, "required": 2}


class CompileError(ValueError):
    """An action that cannot become mission items (says which and why)."""


@dataclass(frozen=True)
class CompiledMission:
    """Mission items (seq 0..N-1) and, for each, the index of the action it came from."""

    items: tuple[MissionItem, ...]
    action_index: tuple[int, ...]

    def action_at(self, seq: int) -> int | None:
        """The action index of item ``seq`` (0-based, as compiled), or None if out of range."""
        return self.action_index[seq] if 0 <= seq < len(self.action_index) else None


@dataclass
class _Cursor:
    """Where the vehicle will be, and facing, when the items so far are flown."""

    position: Point
    heading: float


@dataclass
class _Builder:
    home: Home
    cursor: _Cursor
    items: list[MissionItem] = field(default_factory=list)
    owners: list[int] = field(default_factory=list)
    written: set[int] = field(default_factory=set)  # items given as MISSION_ITEM, kept as is
    action: int = 0
    kind: Kind = Kind.MULTICOPTER

    def add(self, command: int, *, point: Point | None = None, reference: str = "relative",
            params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
            altitude: float | None = None, raw: tuple[int, int, float] | None = None,
            frame: int = mavlink.MAV_FRAME_MISSION) -> None:
        """Append an item; ``point`` (local) becomes its position in the reference's frame,
        ``altitude`` alone means "here, at that altitude", ``raw`` is (x, y, z) as sent
        (with ``point``: the exact position the author wrote, ``point`` only moving the
        cursor)."""
        x, y, z = raw or (0, 0, 0.0)
        if point is not None:
            frame = FRAMES[reference]
        if point is not None and raw is None:
            latitude, longitude, amsl = to_global(*point, self.home.latitude,
                                                  self.home.longitude, self.home.altitude)
            x, y = round(latitude * 1e7), round(longitude * 1e7)
            z = amsl if reference == "amsl" else point[2]
        elif altitude is not None:  # a position "here" (lat = lon = 0) at an altitude
            frame, z = FRAMES["relative"], altitude
        self.items.append(MissionItem(seq=len(self.items), frame=frame, command=command,
                                      param1=params[0], param2=params[1], param3=params[2],
                                      param4=params[3], x=x, y=y, z=z))
        self.owners.append(self.action)

    def waypoint(self, point: Point, reference: str = "relative",
                 exact: tuple[int, int, float] | None = None) -> None:
        """Fly to ``point`` (at ``exact``, its x, y, z as written, when given) and move the
        cursor there."""
        self.add(mavlink.MAV_CMD_NAV_WAYPOINT, point=point, reference=reference, raw=exact)
        self.cursor.position = point


def compile_mission(actions: tuple[BoundAction, ...] | list[BoundAction], home: Home,
                    start: Point, heading: float = 0.0,
                    kind: Kind = Kind.MULTICOPTER) -> CompiledMission:
    """Mission items for ``actions`` flown from ``start`` (local) facing ``heading`` by a
    vehicle of ``kind``.

    Raises :class:`CompileError` for an action that has no mission-item form or whose
    argument is a label the interpreter did not resolve.
    """
    builder = _Builder(home, _Cursor(start, heading), kind=kind)
    for index, action in enumerate(actions):
        builder.action = index
        if action.labels.keys() - action.values.keys():
            missing = sorted(action.labels.keys() - action.values.keys())
            raise CompileError(f"{action.name}: argument {missing[0]!r} reads label "
                               f"{action.labels[missing[0]]!r}, which has no value yet")
        compiler = _COMPILERS.get(action.name)
        if compiler is None:
            raise CompileError(f"{action.name} cannot be flown as a mission item")
        first = len(builder.items)
        compiler(builder, action)
        if action.values.get("frame_encoding") == "float":
            builder.items[first:] = [replace(item, frame=FLOAT_FRAMES.get(item.frame, item.frame))
                                     for item in builder.items[first:]]
    _close_trailing_commands(builder)
    return CompiledMission(tuple(builder.items), tuple(builder.owners))


def _close_trailing_commands(b: _Builder) -> None:
    """End with a waypoint where the vehicle is when more than one DO/CONDITION item follows
    the last navigation item: ArduPilot ends the mission at the first of them otherwise
    (AP_Mission finds no next navigation command), and the others never run."""
    trailing = 0
    for item in reversed(b.items):
        if item.command < mavlink.MAV_CMD_NAV_LAST:
            break
        if item.seq in b.written:  # the author wrote the items: they stay as written
            return
        trailing += 1
    if trailing > 1 and len(b.items) > trailing:
        b.waypoint(b.cursor.position)


# --- one function per action ------------------------------------------------------------

def _plus(a: Point, b: Point) -> Point:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def _global_point(b: _Builder, action: BoundAction,
                  reference: str = "relative") -> tuple[Point, str]:
    """The local point of latitude/longitude/altitude arguments whose altitude is measured
    from ``reference``, and the reference."""
    altitude = action.number("altitude", b.cursor.position[2])
    amsl = altitude if reference == "amsl" else b.home.altitude + altitude
    north, east, up = to_local(action.number("latitude"), action.number("longitude"), amsl,
                               b.home.latitude, b.home.longitude, b.home.altitude)
    return (north, east, up if reference == "amsl" else altitude), reference


def _written(b: _Builder, action: BoundAction) -> tuple[int, int, float]:
    """The x, y, z of latitude/longitude/altitude arguments exactly as written: degrees to
    1e-7-degree integers with no detour through the local frame (which moves a point far
    from home), the altitude as given."""
    return (round(action.number("latitude") * 1e7), round(action.number("longitude") * 1e7),
            action.number("altitude", b.cursor.position[2]))


def _take_off(b: _Builder, action: BoundAction) -> None:
    altitude = action.number("altitude")
    b.add(mavlink.MAV_CMD_NAV_TAKEOFF, altitude=altitude,
          params=(action.number("pitch"), 0.0, 0.0, 0.0))
    n, e, _ = b.cursor.position
    b.cursor.position = (n, e, altitude)


def _glide(b: _Builder, touchdown: Point | None) -> None:
    """A fixed-wing's landing sequence from the cursor: to where the approach starts, then
    NAV_LAND at the touchdown (ArduPlane descends along the line between the two)."""
    approach, ground = landing_approach(b.cursor.position, b.cursor.heading, touchdown)
    b.waypoint(approach)
    b.add(mavlink.MAV_CMD_NAV_LAND, point=ground)
    b.cursor.position = ground


def glide_items(home: Home, here: Point, heading: float,
                touchdown: Point | None) -> list[MissionItem]:
    """The landing sequence of a fixed-wing at ``here`` facing ``heading`` (items 0..N-1):
    straight ahead without a ``touchdown``, else into it."""
    builder = _Builder(home, _Cursor(here, heading), kind=Kind.FIXED_WING)
    _glide(builder, touchdown)
    return builder.items


def _land(b: _Builder, action: BoundAction) -> None:
    if b.kind is Kind.FIXED_WING:
        _glide(b, None)
        return
    b.add(mavlink.MAV_CMD_NAV_LAND, point=b.cursor.position)
    b.cursor.position = (*b.cursor.position[:2], 0.0)


def _go_to_point(b: _Builder, action: BoundAction) -> None:
    point = action.point("coordinates", None)
    if point is None:
        point = _plus(b.cursor.position, action.point("relative_coordinates", (0.0, 0.0, 0.0)))
    b.waypoint(point)


def _move(b: _Builder, action: BoundAction) -> None:
    offset = action.point("coordinates", None)
    if offset is not None:
        b.waypoint(_plus(b.cursor.position, offset))
    else:
        b.waypoint(displaced(b.cursor.position, b.cursor.heading, action.choice("direction"),
                             action.number("distance")))


def _move_forwards(b: _Builder, action: BoundAction) -> None:
    b.waypoint(displaced(b.cursor.position, b.cursor.heading, "forward",
                         action.number("distance")))


def _move_from_home(b: _Builder, action: BoundAction) -> None:
    b.waypoint(action.point("coordinates", (0.0, 0.0, b.cursor.position[2])))


def _go_to_position(b: _Builder, action: BoundAction) -> None:
    point, reference = _global_point(b, action, action.choice("altitude_reference"))
    b.waypoint(point, reference, _written(b, action))


def _loiter_centre(b: _Builder, action: BoundAction) -> tuple[Point, str]:
    if "latitude" in action.values:
        return _global_point(b, action, action.choice("altitude_reference"))
    return _local_centre(b, action), "relative"


def _local_centre(b: _Builder, action: BoundAction) -> Point:
    point = action.point("coordinates", None)
    if point is not None:
        return point
    relative = action.point("relative_coordinates", None)
    if relative is not None:
        return _plus(b.cursor.position, relative)
    return action.point("from_home", b.cursor.position)


def _loiter_at(b: _Builder, centre: Point, reference: str, radius: float,
               turns: float | None = None, duration: float | None = None,
               exact: tuple[int, int, float] | None = None) -> None:
    if turns is not None:
        # ArduPilot keeps at most LOITER_TURNS_MAX turns in an item: more are several items
        # over the same centre, flown one after the other without leaving the circle.
        left = turns
        while left > 0:
            b.add(mavlink.MAV_CMD_NAV_LOITER_TURNS, point=centre, reference=reference,
                  params=(min(left, LOITER_TURNS_MAX), 0.0, radius, 0.0), raw=exact)
            left -= LOITER_TURNS_MAX
    elif duration is not None:
        b.add(mavlink.MAV_CMD_NAV_LOITER_TIME, point=centre, reference=reference,
              params=(duration, 0.0, radius, 0.0), raw=exact)
    else:
        b.add(mavlink.MAV_CMD_NAV_LOITER_UNLIM, point=centre, reference=reference,
              params=(0.0, 0.0, radius, 0.0), raw=exact)
    b.cursor.position = centre


def _loiter(b: _Builder, action: BoundAction) -> None:
    exact = _written(b, action) if "latitude" in action.values else None
    _loiter_at(b, *_loiter_centre(b, action), action.number("radius"),
               action.number("turns", None), action.number("duration", None), exact)


def _landing_point(b: _Builder, action: BoundAction) -> None:
    exact = None
    if "latitude" in action.values:
        point, reference = _global_point(b, action, action.choice("altitude_reference"))
        exact = _written(b, action)
    else:
        point, reference = action.point("coordinates", b.cursor.position), "relative"
    if b.kind is Kind.FIXED_WING:
        _glide(b, (point[0], point[1], 0.0))
        return
    _land_at(b, action, point, reference, exact)


def _land_at(b: _Builder, action: BoundAction, point: Point, reference: str,
             exact: tuple[int, int, float] | None = None) -> None:
    precision = PRECISION_MODES[action.choice("precision_mode")]
    yaw = action.number("yaw", None)
    if yaw is not None:
        # ArduCopter keeps its heading while it descends: turn first, then land facing yaw.
        _yaw_item(b, yaw % 360.0, relative=False)
    # ArduCopter flies to a NAV_LAND's position at its present altitude and ignores the
    # item's altitude: the approach altitude is given, so that a simulator or autopilot
    # that does fly to it does not descend on the way.
    point = (point[0], point[1], b.cursor.position[2]) if reference == "relative" else point
    if exact is not None and reference == "relative":
        exact = (exact[0], exact[1], point[2])
    b.add(mavlink.MAV_CMD_NAV_LAND, point=point, reference=reference,
          params=(0.0, float(precision), 0.0, 0.0 if yaw is None else yaw), raw=exact)
    b.cursor.position = (point[0], point[1], 0.0)


def _return_home(b: _Builder, action: BoundAction) -> None:
    b.waypoint((0.0, 0.0, b.cursor.position[2]))


def _return_home_and_loiter(b: _Builder, action: BoundAction) -> None:
    _loiter_at(b, (0.0, 0.0, b.cursor.position[2]), "relative", action.number("radius"))


def _return_home_and_land(b: _Builder, action: BoundAction) -> None:
    if b.kind is Kind.FIXED_WING:
        _glide(b, (0.0, 0.0, 0.0))
        return
    if action.number("yaw", None) is None and action.choice("precision_mode") == "disabled":
        b.add(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)
        b.cursor.position = (0.0, 0.0, 0.0)
        return
    # RTL carries neither a heading nor a precision-landing mode: fly home, then land.
    b.waypoint((0.0, 0.0, b.cursor.position[2]))
    _land_at(b, action, b.cursor.position, "relative")


def _set_speed(b: _Builder, action: BoundAction) -> None:
    kind = SPEED_TYPES[action.choice("speed_type")]
    b.add(mavlink.MAV_CMD_DO_CHANGE_SPEED, params=(kind, action.number("speed"), -1.0, 0.0))


def _set_altitude(b: _Builder, action: BoundAction) -> None:
    reference = action.choice("altitude_reference")
    altitude = action.number("altitude")
    up = altitude - b.home.altitude if reference == "amsl" else altitude
    n, e, _ = b.cursor.position
    # A waypoint above the expected position: DO_CHANGE_ALTITUDE only changes the altitude
    # of the navigation command in progress, which may already be done (and ArduCopter 4.7
    # refuses it in a mission upload as UNSUPPORTED).
    b.waypoint((n, e, up), reference)


def _wait(b: _Builder, action: BoundAction) -> None:
    # NAV_DELAY param1 is seconds; params 2-4 (a time of day) are -1: not used.
    b.add(mavlink.MAV_CMD_NAV_DELAY, params=(action.number("duration"), -1.0, -1.0, -1.0))


def _stabilize(b: _Builder, action: BoundAction) -> None:
    b.add(mavlink.MAV_CMD_NAV_DELAY, params=(0.0, -1.0, -1.0, -1.0))


def _yaw_item(b: _Builder, angle: float, relative: bool) -> None:
    # A turn by an angle goes its sign's way; a heading from north the shorter way
    # (param3 0): ArduCopter keeps to a direction given even then (AutoYaw::set_fixed_yaw),
    # and would turn 315 degrees clockwise for a heading 45 degrees anticlockwise.
    direction = (-1.0 if angle < 0 else 1.0) if relative else 0.0
    b.add(mavlink.MAV_CMD_CONDITION_YAW,
          params=(abs(angle), 0.0, direction, 1.0 if relative else 0.0))
    b.cursor.heading = (b.cursor.heading + angle if relative else angle) % 360.0


def _rotate_yaw(b: _Builder, action: BoundAction) -> None:
    angle = action.number("angle", None)
    if angle is not None:
        _yaw_item(b, angle, relative=True)
    else:
        _yaw_item(b, action.number("orientation_angle") % 360.0, relative=False)


def _survey_area(b: _Builder, action: BoundAction) -> None:
    if "latitude" in action.values:
        base, _ = _global_point(b, action)
    else:
        base = action.point("coordinates", b.cursor.position)
    altitude = action.number("altitude", b.cursor.position[2])
    for point in survey((base[0], base[1], altitude), action.number("length"),
                        action.number("width"), action.number("spacing"),
                        action.choice("direction")):
        b.waypoint(point)


def _explore_space(b: _Builder, action: BoundAction) -> None:
    for point in expanding_square(b.cursor.position, action.number("radius"),
                                  action.number("spacing")):
        b.waypoint(point)


def _capture_photo(b: _Builder, action: BoundAction) -> None:
    # param5 (shoot) travels in the item's x field.
    b.add(mavlink.MAV_CMD_DO_DIGICAM_CONTROL, raw=(1, 0, 0.0))


def _capture_photos(b: _Builder, action: BoundAction) -> None:
    b.add(mavlink.MAV_CMD_IMAGE_START_CAPTURE,
          params=(0.0, action.number("interval"), action.number("count"), 0.0))


def _start_capturing(b: _Builder, action: BoundAction) -> None:
    b.add(mavlink.MAV_CMD_IMAGE_START_CAPTURE,
          params=(0.0, action.number("interval"), 0.0, 0.0))


def _stop_capturing(b: _Builder, action: BoundAction) -> None:
    b.add(mavlink.MAV_CMD_IMAGE_STOP_CAPTURE)


def _pick_up_item(b: _Builder, action: BoundAction) -> None:
    b.add(mavlink.MAV_CMD_DO_GRIPPER, params=(1.0, mavlink.GRIPPER_ACTION_GRAB, 0.0, 0.0))


def _drop_item(b: _Builder, action: BoundAction) -> None:
    b.add(mavlink.MAV_CMD_DO_GRIPPER, params=(1.0, mavlink.GRIPPER_ACTION_RELEASE, 0.0, 0.0))


def _set_home(b: _Builder, action: BoundAction) -> None:
    if "latitude" not in action.values:
        b.add(mavlink.MAV_CMD_DO_SET_HOME, params=(1.0, 0.0, 0.0, 0.0))
        return
    b.add(mavlink.MAV_CMD_DO_SET_HOME, frame=mavlink.MAV_FRAME_GLOBAL_INT,
          raw=(round(action.number("latitude") * 1e7),
               round(action.number("longitude") * 1e7), action.number("altitude")))


def _mission_item(b: _Builder, action: BoundAction) -> None:
    command, frame = _table_number(action.text("command")), _table_number(action.text("frame"))
    params = tuple(action.number(name) for name in RAW_PARAMS)
    placed = frame in GLOBAL_FRAME_NUMBERS
    x, y = (round(v * 1e7) if placed else round(v) for v in params[4:6])
    b.items.append(MissionItem(seq=len(b.items), frame=frame, command=command,
                               param1=params[0], param2=params[1], param3=params[2],
                               param4=params[3], x=x, y=y, z=params[6],
                               autocontinue=int(action.flag("autocontinue"))))
    b.owners.append(b.action)
    b.written.add(len(b.items) - 1)
    if placed and (x or y) and math.isfinite(params[6]) and command < mavlink.MAV_CMD_NAV_LAST:
        amsl = params[6] if frame in (mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_INT) \
            else b.home.altitude + params[6]
        north, east, up = to_local(x / 1e7, y / 1e7, amsl, b.home.latitude,
                                   b.home.longitude, b.home.altitude)
        b.cursor.position = (north, east, up)


def _table_number(text: str) -> int:
    """The number of a MAV_CMD or MAV_FRAME the language checked (a name or a number)."""
    return int(text) if text.isdigit() else int(getattr(mavlink, text))


_COMPILERS = {
    "TAKE_OFF": _take_off,
    "LAND": _land,
    "GO_TO_POINT": _go_to_point,
    "MOVE": _move,
    "MOVE_FORWARDS": _move_forwards,
    "MOVE_FROM_HOME": _move_from_home,
    "GO_TO_POSITION": _go_to_position,
    "ROTATE_YAW": _rotate_yaw,
    "STABILIZE": _stabilize,
    "WAIT": _wait,
    "EXPLORE_SPACE": _explore_space,
    "PICK_UP_ITEM": _pick_up_item,
    "DROP_ITEM": _drop_item,
    "LOITER": _loiter,
    "LANDING_POINT": _landing_point,
    "RETURN_HOME": _return_home,
    "RETURN_HOME_AND_LOITER": _return_home_and_loiter,
    "RETURN_HOME_AND_LAND": _return_home_and_land,
    "SET_SPEED": _set_speed,
    "SET_ALTITUDE": _set_altitude,
    "SURVEY_AREA": _survey_area,
    "CAPTURE_PHOTO": _capture_photo,
    "CAPTURE_PHOTOS": _capture_photos,
    "START_CAPTURING": _start_capturing,
    "STOP_CAPTURING": _stop_capturing,
    "SET_HOME": _set_home,
    "MISSION_ITEM": _mission_item,
}


def has_items(action_name: str) -> bool:
    """Whether the action called ``action_name`` (canonical) has a mission-item form."""
    return action_name in _COMPILERS
