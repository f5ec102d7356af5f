"""The action catalogue: every action tml can fly, with its arguments, types, units and defaults.

It covers the actions of the TML paper and of Aerostack's TML v1 (TAKE_OFF, LAND, GO_TO_POINT,
MOVE, MOVE_FORWARDS, ROTATE_YAW, STABILIZE, WAIT, FLIP, MEMORIZE_POINT and the IMAV 2016 ones)
and every mission command of the Dolphin MAVLink plugin (go to a global position, move
relative to the last position or to home, loiters, landing point, return home, speed,
altitude, delay, survey area, camera, home).

Names are matched after normalization (case, spaces, ``-`` and ``_`` do not matter), and each
argument lists the spellings the paper and Aerostack use as aliases. Units are fixed per
argument: metres, seconds, degrees, metres per second. Local points are ``(north, east, up)``
metres from home (see :mod:`tml.geo`).
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, replace
from enum import Enum, StrEnum
from typing import TypeVar, overload

from tml.errors import MissionSemanticError
from tml.geo import Point
from tml.language.mavlink_tables import MAV_CMD, MAV_FRAME
from tml.language.model import Action, normalize_name
from tml.language.parameters import NUMBER_PATTERN, parse_boolean, parse_number
from tml.language.quantities import Quantity, out_of_range


class Category(StrEnum):
    """Action categories; the verifier checks the constraints of an action's categories."""

    TRANSLATION = "translation"
    ROTATION = "rotation"
    TAKE_OFF_LANDING = "take-off/landing"
    HOVER = "hover"
    CAMERA = "camera"
    MEMORY = "memory"
    PAYLOAD = "payload"
    CONFIGURATION = "configuration"


class ArgType(StrEnum):
    """Types of argument values, each with one written form (see :func:`parse_value`)."""

    NUMBER = "number"  # 2.5, -3, 1e2
    INTEGER = "integer"  # 3
    POINT = "point"  # (north, east, up) in metres, parentheses optional
    STRING = "string"
    CHOICE = "choice"  # one of ArgumentSpec.choices, case-insensitive
    BOOLEAN = "boolean"  # yes/no, true/false, 1/0


ArgumentValue = float | int | bool | str | Point
"""A typed argument value: NUMBER float, INTEGER int, BOOLEAN bool, STRING and CHOICE str,
POINT a local point."""


class LabelUse(StrEnum):
    """How an argument given with ``label=`` uses the label."""

    READ = "read"  # the argument's value is the point memorized under the label
    WRITE = "write"  # the action memorizes a point under the label


@dataclass(frozen=True)
class ArgumentSpec:
    """One argument of an action."""

    name: str
    type: ArgType
    description: str
    unit: str = ""
    # None: no default (optional arguments are then simply absent)
    default: ArgumentValue | None = None
    required: bool = False
    aliases: tuple[str, ...] = ()
    choices: tuple[str, ...] = ()
    minimum: float | None = None
    maximum: float | None = None
    positive: bool = False  # strictly greater than zero
    label: LabelUse | None = None  # whether label= is accepted, and how
    # What a NUMBER or INTEGER measures, whose range bounds it (see tml.language.quantities);
    # a POINT's components are coordinates and an altitude.
    quantity: Quantity | None = None
    # A NUMBER that may be NaN (a mission item's "not set", e.g. a yaw the vehicle keeps).
    nan: bool = False
    # A STRING that names an entry of this table (number -> name, such as MAV_CMD): the
    # name, the name without the table's prefix, or the number.
    table: Mapping[int, str] | None = None


@dataclass(frozen=True)
class ActionSpec:
    """One action: its name, category, arguments and argument rules."""

    name: str
    category: Category
    description: str
    arguments: tuple[ArgumentSpec, ...] = ()
    aliases: tuple[str, ...] = ()
    # Groups of argument names of which exactly one must be given.
    exactly_one_of: tuple[tuple[str, ...], ...] = ()
    # Groups of argument names of which at most one may be given.
    at_most_one_of: tuple[tuple[str, ...], ...] = ()
    # Arguments that must be given together (all or none).
    together: tuple[tuple[str, ...], ...] = ()
    # Vehicle capability the action needs ("gripper", "flip", see CAPABILITIES); a mission
    # holding the action is refused before take-off by a vehicle without it.
    requires: str = ""
    # Whether the action can be compiled to MAVLink mission items (dispatch="mission").
    mission_item: bool = True
    # Whether the action is flown only as a mission item (dispatch="mission").
    mission_only: bool = False

    def argument(self, written: str) -> ArgumentSpec | None:
        """The argument spec that ``written`` names, or None."""
        return self._argument_index.get(normalize_name(written))

    @functools.cached_property
    def _argument_index(self) -> dict[str, ArgumentSpec]:
        return {normalize_name(name): spec for spec in self.arguments
                for name in (spec.name, *spec.aliases)}


def _number(name: str, description: str, unit: str, quantity: Quantity, *,
            default: float | None = None, required: bool = False,
            aliases: tuple[str, ...] = (), minimum: float | None = None,
            maximum: float | None = None, positive: bool = False) -> ArgumentSpec:
    return ArgumentSpec(name, ArgType.NUMBER, description, unit, default=default,
                        required=required, aliases=aliases, minimum=minimum, maximum=maximum,
                        positive=positive, quantity=quantity)


def _integer(name: str, description: str, quantity: Quantity, *, required: bool = False,
             aliases: tuple[str, ...] = ()) -> ArgumentSpec:
    return ArgumentSpec(name, ArgType.INTEGER, description, required=required,
                        aliases=aliases, positive=True, quantity=quantity)


def _point(name: str, description: str, *, required: bool = False,
           aliases: tuple[str, ...] = (), label: LabelUse | None = None) -> ArgumentSpec:
    return ArgumentSpec(name, ArgType.POINT, description, "m", required=required,
                        aliases=aliases, label=label)


_LATITUDE = _number("latitude", "WGS84 latitude", "deg", Quantity.LATITUDE)
_LONGITUDE = _number("longitude", "WGS84 longitude", "deg", Quantity.LONGITUDE)
_ALTITUDE = _number("altitude", "altitude, by default above home (see altitude_reference)", "m",
                    Quantity.ALTITUDE)
_ALTITUDE_REFERENCE = ArgumentSpec(
    "altitude_reference", ArgType.CHOICE,
    "what altitude is measured from: home (relative), mean sea level (amsl) or terrain",
    default="relative", choices=("relative", "amsl", "terrain"),
)
_FRAME_ENCODING = ArgumentSpec(
    "frame_encoding", ArgType.CHOICE,
    "how its mission items name their frame: int (GLOBAL_RELATIVE_ALT_INT, GLOBAL_INT, "
    "GLOBAL_TERRAIN_ALT_INT) or float (GLOBAL_RELATIVE_ALT, GLOBAL, GLOBAL_TERRAIN_ALT, as "
    "ArduPilot's and QGroundControl's files write them); the same position either way",
    default="int", choices=("int", "float"),
)
_RADIUS = _number("radius", "loiter circle radius", "m", Quantity.RADIUS, default=15.0,
                  positive=True)
_YAW = _number(
    "yaw", "heading to land with, clockwise from north; absent: the vehicle chooses", "deg",
    Quantity.ANGLE, minimum=-360.0, maximum=360.0,
)
_PRECISION = ArgumentSpec(
    "precision_mode", ArgType.CHOICE,
    "precision landing: disabled, opportunistic (use a target if seen) or required",
    default="disabled", choices=("disabled", "opportunistic", "required"),
    aliases=("land_mode", "landMode"),
)
_GLOBAL = (_LATITUDE, _LONGITUDE, _ALTITUDE, _ALTITUDE_REFERENCE, _FRAME_ENCODING)
# --- the frame of an item without a position (RETURN_HOME_AND_LAND, SET_SPEED), as a file
# wrote it: ArduPilot's files write 0 (GLOBAL), others 3 or 5, tml 2 (MISSION)
_ITEM_FRAME = ArgumentSpec(
    "frame", ArgType.STRING,
    "the MAV_FRAME its mission items without a position are written in, by name or number "
    "(such an item's frame means nothing to the autopilot; kept as a file wrote it); "
    "absent: MISSION", table=MAV_FRAME)
# --- a DO_GRIPPER item as a file wrote it (PICK_UP_ITEM, DROP_ITEM)
_GRIPPER_ITEM = (
    ArgumentSpec("gripper", ArgType.INTEGER, "the gripper number its DO_GRIPPER item "
                 "carries (param1); absent: 1; ArduPilot has one gripper and ignores it",
                 minimum=0.0, maximum=255.0, quantity=Quantity.ITEM_PARAM),
    _ITEM_FRAME,
)
# --- a NAV_DELAY item as a file wrote it (WAIT)
_DELAY_ITEM = (
    ArgumentSpec("time_of_day", ArgType.INTEGER,
                 "what its NAV_DELAY item's hour, minute and second (params 2-4, a UTC time of "
                 "day that a delay of a time does not use) are written as: ArduPilot's "
                 "autotest files write 0, MAVLink's \"ignore\" is -1; absent: -1",
                 minimum=-1.0, maximum=0.0, quantity=Quantity.ITEM_PARAM),
    _ITEM_FRAME,
)
# --- a NAV_LAND item as ArduPilot writes it back (LANDING_POINT)
_LAND_ITEM = (
    ArgumentSpec("loiter_direction", ArgType.CHOICE,
                 "the direction its NAV_LAND item carries as param4 with no turn before it: "
                 "clockwise 1, counter-clockwise -1 (ArduPilot keeps a NAV_LAND's param4 as "
                 "this sign and writes it back so; ArduCopter lands with the heading it has)",
                 choices=("clockwise", "counter-clockwise")),
    ArgumentSpec("keep_altitude", ArgType.BOOLEAN,
                 "its NAV_LAND item carries the altitude given (ArduCopter ignores it and flies "
                 "over the point at the altitude it has, as this action does); absent: no, the "
                 "item carries the altitude the vehicle arrives at", default=False),
)
# --- the position a NAV_TAKEOFF item carries (TAKE_OFF), as planners write it
_TAKE_OFF_POSITION = tuple(
    replace(s, description=f"{s.description} its mission item carries (ground stations write "
            "where the vehicle stands); a multicopter climbs where it is, as ArduCopter does")
    for s in (_LATITUDE, _LONGITUDE))
# --- a waypoint's params (GO_TO_POSITION): absent, each is what the compiler writes
# when none is given (0); NaN where the item says "not set".
_WAYPOINT = (
    _number("hold", "time to hover at the position once reached (NAV_WAYPOINT param1)", "s",
            Quantity.DURATION, minimum=0.0),
    _number("acceptance_radius", "how near counts as reached; absent or 0: the vehicle's "
            "own (WPNAV_RADIUS) (param2)", "m", Quantity.RADIUS, minimum=0.0),
    _number("pass_radius", "fixed-wing: pass the position at this distance, positive to "
            "the right, negative to the left; 0: through it (param3)", "m",
            Quantity.COORDINATE),
    replace(_number("yaw", "heading to face at the position, clockwise from north; absent "
                    "or NaN: the vehicle chooses (param4; ArduCopter ignores it in AUTO)",
                    "deg", Quantity.ANGLE, minimum=-360.0, maximum=360.0), nan=True),
)
_INTERVAL = _number("interval", "time between photos", "s", Quantity.DURATION, default=2.0,
                    positive=True)
_LOITER_POSITION = (
    _point("coordinates", "centre as a local point; absent: where the vehicle is",
           aliases=("point",), label=LabelUse.READ),
    _point("relative_coordinates", "centre relative to the last position (Dolphin move)",
           aliases=("relative_point", "relative coordinates")),
    _point("from_home", "centre relative to home (Dolphin ...FromHome)"),
    *_GLOBAL,
)
_LOITER_GROUPS = (("coordinates", "relative_coordinates", "from_home", "latitude"),)
_LOITER_TOGETHER = (("latitude", "longitude", "altitude"),)

_AREA = (
    _number("length", "extent along the first axis of direction (north/south)", "m",
            Quantity.DISTANCE, required=True, positive=True),
    _number("width", "extent along the second axis (east/west)", "m",
            Quantity.DISTANCE, required=True, positive=True),
    ArgumentSpec("direction", ArgType.CHOICE, "quadrant the area extends into",
                 default="NORTH_WEST",
                 choices=("NORTH_WEST", "NORTH_EAST", "SOUTH_WEST", "SOUTH_EAST")),
    _point("coordinates", "base point as a local point", aliases=("point",),
           label=LabelUse.READ),
    _LATITUDE, _LONGITUDE,
)
"""The rectangle of SURVEY_AREA and SURVEY_PHOTOS."""


RAW_PARAMS = ("param1", "param2", "param3", "param4", "param5", "param6", "param7")
"""The seven params of a raw mission item, in order."""


def _raw_param(number: int) -> ArgumentSpec:
    meaning = {5: "x: latitude in degrees in a global frame, else a whole number",
               6: "y: longitude in degrees in a global frame, else a whole number",
               7: "z: altitude in metres in a global frame (NaN: not set)"}
    return ArgumentSpec(f"param{number}", ArgType.NUMBER,
                        meaning.get(number, f"param {number} as the command defines it "
                                            "(NaN: not set)"),
                        default=0.0, nan=number not in (5, 6), quantity=Quantity.ITEM_PARAM)


CATALOGUE: tuple[ActionSpec, ...] = (
    # --- TML paper and Aerostack -------------------------------------------------------
    ActionSpec(
        "TAKE_OFF", Category.TAKE_OFF_LANDING,
        "Arm and climb from the current location to the take-off altitude. "
        "Ignored when the vehicle is already flying.",
        (
            _number("altitude", "altitude above home to climb to", "m", Quantity.ALTITUDE,
                    default=10.0,
                    positive=True, aliases=("height",)),
            _number("pitch", "take-off pitch for fixed-wing vehicles (Dolphin takeOff)", "deg",
                    Quantity.ANGLE, default=15.0, minimum=0.0, maximum=90.0),
            _FRAME_ENCODING,
            *_TAKE_OFF_POSITION,
            replace(_WAYPOINT[3], description="heading to face once at the altitude, clockwise "
                    "from north; absent or NaN: the vehicle chooses (NAV_TAKEOFF param4; "
                    "ArduCopter ignores it in AUTO)"),
        ),
        together=(("latitude", "longitude"),),
    ),
    ActionSpec("LAND", Category.TAKE_OFF_LANDING,
               "Descend vertically where the vehicle is until it touches the ground; "
               "the vehicle disarms after landing."),
    ActionSpec(
        "GO_TO_POINT", Category.TRANSLATION,
        "Fly to a point given in the local frame (coordinates, or a memorized label) or "
        "relative to the vehicle's current position (relative_coordinates).",
        (
            _point("coordinates", "destination (north, east, up) from home",
                   aliases=("point",), label=LabelUse.READ),
            _point("relative_coordinates", "displacement (north, east, up) from where the "
                   "vehicle is", aliases=("relative_point",)),
        ),
        exactly_one_of=(("coordinates", "relative_coordinates"),),
    ),
    ActionSpec(
        "MOVE", Category.TRANSLATION,
        "Move relative to the current position: by a displacement (coordinates, as "
        "Dolphin's move north, east, up) or a distance in a direction relative to the heading.",
        (
            _point("coordinates", "displacement (north, east, up)",
                   aliases=("relative_coordinates", "displacement")),
            ArgumentSpec("direction", ArgType.CHOICE, "direction relative to the heading",
                         default="forward",
                         choices=("forward", "backward", "left", "right", "up", "down")),
            _number("distance", "distance to move in the direction", "m", Quantity.DISTANCE,
                    positive=True),
        ),
        exactly_one_of=(("coordinates", "distance"),),
    ),
    ActionSpec(
        "MOVE_FORWARDS", Category.TRANSLATION,
        "Move straight ahead along the current heading.",
        (_number("distance", "distance to move", "m", Quantity.DISTANCE, required=True,
                 positive=True),),
        aliases=("MOVE_FORWARD",),
    ),
    ActionSpec(
        "MOVE_FROM_HOME", Category.TRANSLATION,
        "Fly to a point given relative to home (Dolphin moveFromHome north, east, up).",
        (_point("coordinates", "offset (north, east, up) from home", required=True),),
    ),
    ActionSpec(
        "ROTATE_YAW", Category.ROTATION,
        "Turn in place: by an angle relative to the current heading, or to an absolute "
        "heading (orientation_angle, clockwise from north).",
        (
            _number("angle", "turn, positive clockwise", "deg", Quantity.ANGLE,
                    minimum=-360.0, maximum=360.0,
                    aliases=("rotation_angle",)),
            _number("orientation_angle", "heading to face, clockwise from north", "deg",
                    Quantity.ANGLE, minimum=0.0, maximum=360.0, aliases=("heading", "orientation")),
        ),
        exactly_one_of=(("angle", "orientation_angle"),),
    ),
    ActionSpec("STABILIZE", Category.HOVER,
               "Stop all motion and hold position (ArduPilot BRAKE, then hold in GUIDED)."),
    ActionSpec(
        "WAIT", Category.HOVER,
        "Hover where the vehicle is for a time (Dolphin delay).",
        (_number("duration", "time to wait", "s", Quantity.DURATION, required=True,
                 aliases=("time", "seconds")), *_DELAY_ITEM),
        aliases=("DELAY",),
    ),
    ActionSpec(
        "FLIP", Category.ROTATION,
        "Perform a flip (ArduCopter FLIP mode, entered from ALT_HOLD with the sticks held by RC "
        "override), then fly back to where it began; below 10 m the vehicle climbs to 10 m "
        "first (a flip costs ArduCopter about 4 m). A vehicle without a FLIP mode refuses the "
        "mission before take-off.",
        (ArgumentSpec("direction", ArgType.CHOICE, "direction of the flip", default="front",
                      choices=("front", "back", "left", "right")),),
        requires="flip", mission_item=False,
    ),
    ActionSpec(
        "MEMORIZE_POINT", Category.MEMORY,
        "Remember the vehicle's current position under a label, for GO_TO_POINT and "
        "conditions to read.",
        (_point("coordinates", "the label to store the current position under",
                required=True, aliases=("point",), label=LabelUse.WRITE),),
        mission_item=False,
    ),
    ActionSpec(
        "GO_TO_RECTANGLE", Category.TRANSLATION,
        "Fly to the coloured frame (a door or window) recognised by the camera (IMAV 2016).",
        (ArgumentSpec("frame_color", ArgType.STRING, "colour of the frame to fly to",
                      required=True, aliases=("color", "colour", "frame_colour")),),
        mission_item=False,
    ),
    ActionSpec(
        "EXPLORE_SPACE", Category.TRANSLATION,
        "Search the space around the current position in an expanding square, with the "
        "active recognition skills reporting what they see (IMAV 2016).",
        (
            ArgumentSpec("build_map", ArgType.BOOLEAN, "record a map while exploring",
                         default=False),
            _number("radius", "half-width of the square to explore", "m", Quantity.RADIUS,
                    default=10.0,
                    positive=True),
            _number("spacing", "distance between passes", "m", Quantity.SPACING, default=2.0),
        ),
    ),
    ActionSpec(
        "PICK_UP_ITEM", Category.PAYLOAD,
        "Descend on the item below and close the gripper (IMAV 2016). Needs a gripper.",
        (ArgumentSpec("item", ArgType.STRING, "name of the item, for the log"),
         *_GRIPPER_ITEM),
        requires="gripper",
    ),
    ActionSpec(
        "DROP_ITEM", Category.PAYLOAD,
        "Open the gripper and release the item carried (IMAV 2016). Needs a gripper.",
        _GRIPPER_ITEM,
        requires="gripper",
    ),
    # --- Dolphin MAVLink plugin ----------------------------------------------------------
    ActionSpec(
        "GO_TO_POSITION", Category.TRANSLATION,
        "Fly to a WGS84 position (Dolphin goPos), optionally reached within an acceptance "
        "radius, then facing a heading and holding there for a time (a NAV_WAYPOINT's "
        "params).",
        (*(replace(s, required=True) for s in _GLOBAL[:3]), *_GLOBAL[3:], *_WAYPOINT),
    ),
    ActionSpec(
        "LOITER", Category.HOVER,
        "Fly to a centre and circle it: forever, for a number of turns, or for a time "
        "(Dolphin loiterPos/Turns/Time and moveAndLoiter...). Without a centre, circle "
        "where the vehicle is.",
        (*_LOITER_POSITION,
         _integer("turns", "number of circles", Quantity.TURNS),
         _number("duration", "time to circle", "s", Quantity.DURATION, positive=True,
                 aliases=("time",)),
         _RADIUS),
        at_most_one_of=(*_LOITER_GROUPS, ("turns", "duration")),
        together=_LOITER_TOGETHER,
    ),
    ActionSpec(
        "LANDING_POINT", Category.TAKE_OFF_LANDING,
        "Fly to a point and land there (Dolphin landingPoint), optionally with a yaw and "
        "precision landing.",
        (
            _point("coordinates", "landing point as a local point", aliases=("point",),
                   label=LabelUse.READ),
            *_GLOBAL, _YAW, _PRECISION, *_LAND_ITEM,
        ),
        exactly_one_of=(("coordinates", "latitude"),),
        at_most_one_of=(("yaw", "loiter_direction"),),
        together=_LOITER_TOGETHER,
        aliases=("LAND_AT",),
    ),
    ActionSpec("RETURN_HOME", Category.TRANSLATION,
               "Fly back to home at the current altitude and hold there (Dolphin returnHome)."),
    ActionSpec(
        "RETURN_HOME_AND_LOITER", Category.HOVER,
        "Fly back to home and circle it (Dolphin returnHomeAndLoiter).", (_RADIUS,),
    ),
    ActionSpec(
        "RETURN_HOME_AND_LAND", Category.TAKE_OFF_LANDING,
        "Return to launch and land there (ArduPilot RTL; Dolphin returnHomeAndLand).",
        (_YAW, _PRECISION, _ITEM_FRAME),
        aliases=("RETURN_TO_LAUNCH", "RTL"),
    ),
    ActionSpec(
        "SET_SPEED", Category.CONFIGURATION,
        "Change the speed used by the following moves (Dolphin speed).",
        (
            _number("speed", "new speed", "m/s", Quantity.SPEED, required=True, positive=True),
            ArgumentSpec("speed_type", ArgType.CHOICE, "which speed to change",
                         default="airspeed",
                         choices=("airspeed", "ground", "climb", "descent"),
                         aliases=("type",)),
            _number("throttle", "throttle to set, in percent (DO_CHANGE_SPEED param3); "
                    "absent: -1, no change; ArduCopter ignores it, ArduPlane sets a value "
                    "above 0", "%", Quantity.ITEM_PARAM, minimum=-1.0, maximum=100.0),
            _ITEM_FRAME,
        ),
        aliases=("CHANGE_SPEED", "SPEED"),
    ),
    ActionSpec(
        "SET_ALTITUDE", Category.TRANSLATION,
        "Climb or descend to an altitude where the vehicle is (Dolphin altitude).",
        (replace(_ALTITUDE, required=True), _ALTITUDE_REFERENCE, _FRAME_ENCODING),
        aliases=("CHANGE_ALTITUDE", "ALTITUDE"),
    ),
    ActionSpec(
        "SURVEY_AREA", Category.TRANSLATION,
        "Fly a lawnmower pattern over a rectangle of length x width metres that starts at "
        "the base point (default: where the vehicle is) and extends towards direction "
        "(Dolphin surveyArea).",
        (
            *_AREA[:2],
            _number("spacing", "distance between passes", "m", Quantity.SPACING, default=50.0,
                    aliases=("direction_change",)),
            *_AREA[2:],
            _number("altitude", "survey altitude above home; absent: the current altitude",
                    "m", Quantity.ALTITUDE, positive=True),
        ),
        at_most_one_of=(("coordinates", "latitude"),),
        together=(("latitude", "longitude"),),
    ),
    ActionSpec(
        "SURVEY_PHOTOS", Category.TRANSLATION,
        "Photograph a rectangle as SURVEY_AREA flies it, the passes and the photos spaced for "
        "a camera looking straight down: from its sensor, focal length and the overlaps "
        "wanted, the passes lie a photo's ground width less the side overlap apart, and the "
        "autopilot takes a photo each time the vehicle has flown a photo's ground length "
        "less the front overlap (DO_SET_CAM_TRIGG_DIST, as a command or a mission item).",
        (
            *_AREA,
            _number("altitude", "survey altitude above home; absent: the one giving "
                    "ground_resolution, else the current altitude", "m", Quantity.ALTITUDE,
                    positive=True),
            _number("sensor_width", "width of the camera's sensor (across the passes)", "mm",
                    Quantity.OPTICS, required=True, positive=True),
            _number("sensor_height", "height of the camera's sensor (along the passes)", "mm",
                    Quantity.OPTICS, required=True, positive=True),
            _number("focal_length", "focal length of the lens", "mm", Quantity.OPTICS,
                    required=True, positive=True),
            _integer("image_width", "width of a photo in pixels (with ground_resolution)",
                     Quantity.COUNT),
            _number("ground_resolution", "ground resolution wanted, which sets the altitude: "
                    "altitude = ground_resolution / 100 x focal_length x image_width / "
                    "sensor_width", "cm/px", Quantity.GROUND_RESOLUTION, positive=True,
                    aliases=("gsd",)),
            _number("front_overlap", "overlap of a photo with the next along a pass", "%",
                    Quantity.PERCENTAGE, default=70.0, maximum=95.0),
            _number("side_overlap", "overlap of a pass's photos with the next pass's", "%",
                    Quantity.PERCENTAGE, default=60.0, maximum=95.0),
        ),
        at_most_one_of=(("coordinates", "latitude"), ("altitude", "ground_resolution")),
        together=(("latitude", "longitude"), ("ground_resolution", "image_width")),
    ),
    ActionSpec("CAPTURE_PHOTO", Category.CAMERA, "Take one photo (Dolphin capturePhoto)."),
    ActionSpec(
        "CAPTURE_PHOTOS", Category.CAMERA,
        "Take a number of photos at an interval (Dolphin captureSeveralPhotos).",
        (_integer("count", "number of photos", Quantity.COUNT, required=True,
                  aliases=("photo_count",)),
         _INTERVAL),
    ),
    ActionSpec(
        "START_CAPTURING", Category.CAMERA,
        "Take photos at an interval until STOP_CAPTURING (Dolphin captureUntilStop).",
        (_INTERVAL,), aliases=("CAPTURE_UNTIL_STOPPED", "CAPTURE_UNTIL_STOP"),
    ),
    ActionSpec("STOP_CAPTURING", Category.CAMERA,
               "Stop the photos started by START_CAPTURING (Dolphin stopCapturing)."),
    ActionSpec(
        "SET_HOME", Category.CONFIGURATION,
        "Set the home position to the vehicle's current position, or to a WGS84 position "
        "(Dolphin home).",
        (_LATITUDE, _LONGITUDE,
         _number("altitude", "altitude above mean sea level", "m", Quantity.ALTITUDE),
         _FRAME_ENCODING),
        together=(("latitude", "longitude", "altitude"),),
        aliases=("HOME",),
    ),
    # --- circling a point of interest, facing it ------------------------------------------
    ActionSpec(
        "ORBIT", Category.HOVER,
        "Circle a point of interest at a radius, facing it, for a number of turns or a time. "
        "With commands the circle's targets are sent one after the other, each with the "
        "heading toward the point; as mission items it is DO_SET_ROI_LOCATION, "
        "NAV_LOITER_TURNS, a NAV_WAYPOINT where the circle ends and DO_SET_ROI_NONE (the "
        "autopilot faces the point while it circles, and forgets it afterwards).",
        (
            _point("coordinates", "the point of interest (north, east, up) from home; up is "
                   "the height of what is looked at", aliases=("point",), label=LabelUse.READ),
            _LATITUDE, _LONGITUDE,
            _number("target_altitude", "height above home of the point of interest given "
                    "by latitude and longitude", "m", Quantity.ALTITUDE, default=0.0),
            _number("altitude", "altitude above home the circle is flown at; absent: the "
                    "altitude the vehicle is at", "m", Quantity.ALTITUDE, positive=True),
            _RADIUS,
            _integer("turns", "number of circles", Quantity.TURNS),
            _number("duration", "time to circle (as mission items: the whole turns it "
                    "takes at ArduCopter's CIRCLE_RATE, 20 deg/s)", "s", Quantity.DURATION,
                    positive=True, aliases=("time",)),
            _FRAME_ENCODING,
        ),
        exactly_one_of=(("coordinates", "latitude"), ("turns", "duration")),
        together=(("latitude", "longitude"),),
    ),
    # --- any mission item ----------------------------------------------------------------
    ActionSpec(
        "MISSION_ITEM", Category.CONFIGURATION,
        "One MAVLink mission item exactly as written, for what no other action says (DO_JUMP, "
        "a servo, a spline waypoint ...): the command by name or number, its frame and seven "
        "params, as MAVSDK's mission_raw and plan files carry them. Flown only in a "
        "dispatch=\"mission\" task.",
        (
            ArgumentSpec("command", ArgType.STRING, "the MAV_CMD, by name (MAV_CMD_DO_JUMP or "
                         "DO_JUMP) or number", required=True, table=MAV_CMD),
            ArgumentSpec("frame", ArgType.STRING, "the MAV_FRAME, by name "
                         "(MAV_FRAME_GLOBAL_RELATIVE_ALT or GLOBAL_RELATIVE_ALT) or number",
                         required=True, table=MAV_FRAME),
            *(_raw_param(n) for n in range(1, 8)),
            ArgumentSpec("autocontinue", ArgType.BOOLEAN,
                         "go on to the next item when this one is done", default=True),
        ),
        aliases=("RAW_ITEM", "MISSION_ITEM_INT"), mission_only=True,
    ),
)


def table_entry(table: Mapping[int, str], text: str) -> tuple[int, str] | None:
    """The number and name of ``text`` in ``table`` (a name, the name without the
    prefix the names share, or a number from 0 to 65535), or None. A number the table
    lacks is returned with an empty name."""
    text = text.strip()
    if re.fullmatch(r"\d{1,5}", text):
        number = int(text)
        return (number, table.get(number, "")) if number <= 65535 else None
    key = text.upper()
    for number, name in table.items():
        if key in (name, name.split("_", 2)[-1] if name.startswith("MAV_") else name):
            return number, name
    return None


def raw_item_problems(values: Mapping[str, ArgumentValue]) -> list[str]:
    """Why the params of a raw mission item's bound values cannot be sent (x and y are
    int32 on the wire: degrees * 1e7 in a global frame, whole numbers otherwise)."""
    frame = table_entry(MAV_FRAME, str(values.get("frame", "")))
    problems = []
    for name, quantity in (("param5", Quantity.LATITUDE), ("param6", Quantity.LONGITUDE)):
        value = values.get(name, 0.0)
        assert isinstance(value, float | int)
        if frame is not None and frame[0] in GLOBAL_FRAME_NUMBERS:
            why = out_of_range(quantity, value)
            if why is not None:
                problems.append(f"{name} {value:g} {why}")
        elif not (float(value).is_integer() and -2**31 <= value < 2**31):
            problems.append(f"{name} {value:g}: in frame {frame[1] if frame else '?'} x and y "
                            "are whole numbers from -2147483648 to 2147483647")
    return problems


def raw_item_oddities(values: Mapping[str, ArgumentValue]) -> list[str]:
    """What an autopilot accepts in a raw mission item but looks odd: an altitude beyond
    the range of altitudes (a rover ignores it; an aircraft would climb to it), a
    CONDITION_YAW angle beyond a turn (ArduPilot takes it modulo 360)."""
    odd = []
    command, z, angle = values.get("command"), values.get("param7"), values.get("param1")
    frame = table_entry(MAV_FRAME, str(values.get("frame", "")))
    if str(command).startswith("MAV_CMD_NAV_") and isinstance(z, float | int) \
            and frame is not None and frame[0] in GLOBAL_FRAME_NUMBERS:
        why = out_of_range(Quantity.ALTITUDE, z) if math.isfinite(z) else None
        if why is not None:
            odd.append(f"altitude param7 {z:g} m: {why}; a ground vehicle ignores it, an "
                       "aircraft would climb to it")
    if command == "MAV_CMD_CONDITION_YAW" and isinstance(angle, float | int) \
            and math.isfinite(angle) and not 0 <= angle <= 360:
        odd.append(f"CONDITION_YAW angle param1 {angle:g} deg: ArduPilot turns to it modulo "
                   "360")
    return odd


GLOBAL_FRAME_NUMBERS = frozenset({0, 3, 5, 6, 10, 11})
"""The MAV_FRAMEs whose x and y are latitude and longitude."""


def _key(name: str) -> str:
    return re.sub(r"[\s_\-]+", "_", name.strip()).upper()


_BY_NAME: dict[str, ActionSpec] = {}
for _spec in CATALOGUE:
    for _name in (_spec.name, *_spec.aliases):
        _BY_NAME[_key(_name)] = _spec


CAPABILITIES = {
    "flip": "a FLIP flight mode (ArduCopter's; not fixed wing, rover or PX4)",
    "gripper": "a gripper (ArduPilot's GRIP_ENABLE set)",
    "camera": "a camera",
}
"""What each capability an action may require stands for, as a refusal says it."""


@functools.lru_cache(maxsize=1024)
def lookup(name: str) -> ActionSpec | None:
    """The action spec for a written action name (case and separators ignored), or None."""
    return _BY_NAME.get(_key(name))


def action_names() -> list[str]:
    """Every accepted action name and alias, canonical spelling."""
    return sorted(_BY_NAME)


_NUMBER = NUMBER_PATTERN
# The types parse_value tells apart, bound once: reading an enum member from its class costs
# some 900 instructions more than reading a global (the enum class's attribute lookup).
_A_POINT, _A_BOOLEAN, _A_CHOICE, _A_STRING, _AN_INTEGER = (
    ArgType.POINT, ArgType.BOOLEAN, ArgType.CHOICE, ArgType.STRING, ArgType.INTEGER)
_AXES = (("north", Quantity.COORDINATE), ("east", Quantity.COORDINATE), ("up", Quantity.ALTITUDE))
_POINT = re.compile(rf"^\(?\s*({_NUMBER})\s*,\s*({_NUMBER})\s*,\s*({_NUMBER})\s*\)?$")


def parse_value(spec: ArgumentSpec, raw: str) -> ArgumentValue:
    """The typed value of ``raw`` for ``spec``; raises ValueError saying what was expected."""
    text = raw.strip()
    kind = spec.type
    if kind is _A_POINT:
        match = _POINT.match(text)
        if not match:
            raise ValueError("expected a point '(north, east, up)' of three numbers in metres")
        # Each group is a number as parse_number reads it: only its size may be refused.
        north, east, up = map(float, match.groups())
        if not (math.isfinite(north) and math.isfinite(east) and math.isfinite(up)):
            raise ValueError("expected a point of three finite numbers in metres")
        for (axis, quantity), component in zip(_AXES, (north, east, up), strict=True):
            why = out_of_range(quantity, component)
            if why is not None:
                raise ValueError(f"{axis} {component:g} m {why}")
        return north, east, up
    if kind is _A_BOOLEAN:
        flag = parse_boolean(text)
        if flag is None:
            raise ValueError("expected yes or no")
        return flag
    if kind is _A_CHOICE:
        for choice in spec.choices:
            if text.lower() == choice.lower():
                return choice
        raise ValueError("expected one of " + ", ".join(spec.choices))
    if kind is _A_STRING:
        if not text:
            raise ValueError("expected a non-empty text")
        if spec.table is not None:
            entry = table_entry(spec.table, text)
            if entry is None:
                some = ", ".join(list(spec.table.values())[:3])
                raise ValueError(f"expected a name such as {some} ..., or a number")
            return entry[1] or str(entry[0])
        return text
    if kind is _AN_INTEGER:
        if not re.fullmatch(r"[-+]?\d+", text):
            raise ValueError("expected a whole number")
        # int() refuses a text of thousands of digits; as a float it is out of range
        value: float = int(text) if len(text) <= 18 else float(text)
    elif spec.nan and text.lower() == "nan":
        return math.nan
    else:
        number = parse_number(text)
        if number is None:
            raise ValueError(f"expected a number{' in ' + spec.unit if spec.unit else ''}")
        value = number
    _check_range(spec, value)
    return value


def _check_range(spec: ArgumentSpec, value: float) -> None:
    def unit() -> str:  # the words only for a value refused
        return f" {spec.unit}" if spec.unit else ""

    if spec.positive and value <= 0:
        raise ValueError(f"must be greater than 0{unit()}")
    if spec.minimum is not None and value < spec.minimum:
        raise ValueError(f"must be at least {spec.minimum:g}{unit()}")
    if spec.maximum is not None and value > spec.maximum:
        raise ValueError(f"must be at most {spec.maximum:g}{unit()}")
    why = out_of_range(spec.quantity, value) if spec.quantity is not None else None
    if why is not None:
        raise ValueError(why)


class _Absent(Enum):
    """The default of an accessor called without one: the argument must be there."""

    ABSENT = "absent"


_ABSENT = _Absent.ABSENT
_D = TypeVar("_D")


@dataclass(frozen=True)
class BoundAction:
    """An action with its arguments typed, named canonically, and defaults filled in.

    Read a value with the accessor of its argument's type: :meth:`number`, :meth:`integer`,
    :meth:`point`, :meth:`choice`, :meth:`text`, :meth:`flag`. Each takes the canonical
    argument name and an optional default: without one an absent argument raises KeyError
    (the argument rules make it present), with one (None included) the default is returned.
    Naming an argument the action does not have, or one of another type, raises TypeError.
    """

    spec: ActionSpec
    action: Action
    values: Mapping[str, ArgumentValue]  # canonical argument name -> typed value
    labels: Mapping[str, str]  # canonical argument name -> label given with label=

    @property
    def name(self) -> str:
        """The canonical action name."""
        return self.spec.name

    def takes(self, name: str) -> bool:
        """Whether the action has an argument of canonical name ``name``."""
        spec = self.spec.argument(name)
        return spec is not None and spec.name == name

    @overload
    def number(self, name: str) -> float: ...
    @overload
    def number(self, name: str, default: _D) -> float | _D: ...
    def number(self, name: str, default: object = _ABSENT) -> object:
        """A NUMBER (or INTEGER) argument, as a float."""
        value = self._value(name, ArgType.NUMBER, ArgType.INTEGER)
        if isinstance(value, int | float):
            return float(value)
        return self._absent(name, default)

    @overload
    def integer(self, name: str) -> int: ...
    @overload
    def integer(self, name: str, default: _D) -> int | _D: ...
    def integer(self, name: str, default: object = _ABSENT) -> object:
        """An INTEGER argument."""
        value = self._value(name, ArgType.INTEGER)
        if isinstance(value, int):
            return value
        return self._absent(name, default)

    @overload
    def point(self, name: str) -> Point: ...
    @overload
    def point(self, name: str, default: _D) -> Point | _D: ...
    def point(self, name: str, default: object = _ABSENT) -> object:
        """A POINT argument: (north, east, up) metres."""
        value = self._value(name, ArgType.POINT)
        if isinstance(value, tuple):
            return value
        return self._absent(name, default)

    @overload
    def choice(self, name: str) -> str: ...
    @overload
    def choice(self, name: str, default: _D) -> str | _D: ...
    def choice(self, name: str, default: object = _ABSENT) -> object:
        """A CHOICE argument, spelt as in the argument's choices."""
        value = self._value(name, ArgType.CHOICE)
        if isinstance(value, str):
            return value
        return self._absent(name, default)

    @overload
    def text(self, name: str) -> str: ...
    @overload
    def text(self, name: str, default: _D) -> str | _D: ...
    def text(self, name: str, default: object = _ABSENT) -> object:
        """A STRING argument."""
        value = self._value(name, ArgType.STRING)
        if isinstance(value, str):
            return value
        return self._absent(name, default)

    @overload
    def flag(self, name: str) -> bool: ...
    @overload
    def flag(self, name: str, default: _D) -> bool | _D: ...
    def flag(self, name: str, default: object = _ABSENT) -> object:
        """A BOOLEAN argument."""
        value = self._value(name, ArgType.BOOLEAN)
        if isinstance(value, bool):
            return value
        return self._absent(name, default)

    def _value(self, name: str, *types: ArgType) -> ArgumentValue | None:
        spec = self.spec.argument(name)
        if not self.takes(name) or spec is None or spec.type not in types:
            raise TypeError(f"{self.name} has no {' or '.join(types)} argument {name!r}")
        return self.values.get(name)

    def _absent(self, name: str, default: object) -> object:
        if default is _ABSENT:
            raise KeyError(f"{self.name} has no value for {name!r}")
        return default


def bind(action: Action) -> BoundAction:
    """Type an action's arguments. For actions that passed :mod:`tml.language.check`; raises
    :class:`MissionSemanticError` on the first problem otherwise."""
    spec = lookup(action.name)
    if spec is None:
        raise MissionSemanticError(f"unknown action {action.name!r}", action.location, "E201")
    values: dict[str, ArgumentValue] = {}
    labels: dict[str, str] = {}
    for argument in action.arguments:
        arg_spec = spec.argument(argument.name)
        if arg_spec is None:
            raise MissionSemanticError(
                f"{spec.name} has no argument {argument.name!r}", argument.location, "E210")
        if argument.label is not None:
            labels[arg_spec.name] = argument.label
        elif argument.value is not None:
            try:
                values[arg_spec.name] = parse_value(arg_spec, argument.value)
            except ValueError as exc:
                raise MissionSemanticError(
                    f"argument {argument.name!r} = {argument.value!r}: {exc}",
                    argument.location, "E212") from None
    for arg_spec in spec.arguments:
        if arg_spec.name not in values and arg_spec.name not in labels \
                and arg_spec.default is not None:
            values[arg_spec.name] = arg_spec.default
    return BoundAction(spec, action, values, labels)
