"""The item toolkit: what the action modules' item compilers (``dispatch="mission"``) are
made of.

An item compiler (the ``items`` part of an :class:`~tml.actions.definition.ActionDef`)
appends the mission items of one action to a :class:`Builder`, whose *cursor* says where
the vehicle is expected to be (local north, east, up from home) and which way it faces once
the items so far are flown: actions relative to the last position (MOVE, relative
GO_TO_POINT, LOITER without a centre, SURVEY_AREA without a base point, SET_ALTITUDE) are
resolved against it, so the items always carry explicit coordinates and the autopilot
never has to guess what "here" meant. Items are plain :class:`Item` data with the numbers
of :mod:`tml.actions.mav`; :mod:`tml.mavlink.compile` numbers them and makes them MAVLink
mission items (theory of operation there).

Every local point is converted to WGS84 with :mod:`tml.geo` against the vehicle's home.
Altitudes go in frame GLOBAL_RELATIVE_ALT_INT (above home), GLOBAL_INT when the author gave
``altitude_reference="amsl"`` and GLOBAL_TERRAIN_ALT_INT for ``terrain``. For a fixed-wing
(:mod:`tml.language.kinds`) a landing is a landing sequence, as ArduPlane lands: a waypoint
where the final approach starts and NAV_LAND at the touchdown (:func:`glide`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from tml.actions import mav
from tml.geo import Point, to_global, to_local
from tml.language.actions import BoundAction
from tml.language.kinds import Kind, landing_approach
from tml.world import Home

FRAMES = {
    "relative": mav.FRAME_GLOBAL_RELATIVE_ALT_INT,
    "amsl": mav.FRAME_GLOBAL_INT,
    "terrain": mav.FRAME_GLOBAL_TERRAIN_ALT_INT,
}
"""The frame of each altitude reference."""
SPEED_TYPES = {"airspeed": 0, "ground": 1, "climb": 2, "descent": 3}
PRECISION_MODES = {"disabled": 0, "opportunistic": 1, "required": 2}

LOITER_TURNS_MAX = 255
"""The most turns ArduPilot keeps in one NAV_LOITER_TURNS (the low byte of its p1)."""


@dataclass(frozen=True)
class Item:
    """One mission item as an action compiles it: ``x``/``y`` are latitude/longitude in
    degrees * 1e7 in a global frame, ``z`` the altitude in metres."""

    frame: int
    command: int
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    autocontinue: int = 1


@dataclass
class Cursor:
    """Where the vehicle will be, and facing, when the items so far are flown."""

    position: Point
    heading: float


@dataclass
class Builder:
    """The items of a mission being compiled, the cursor, and which action each came from."""

    home: Home
    cursor: Cursor
    items: list[Item] = field(default_factory=list)
    owners: list[int] = field(default_factory=list)
    written: set[int] = field(default_factory=set)  # items given as MISSION_ITEM, kept as is
    action: int = 0
    kind: Kind = Kind.MULTICOPTER

    def add(self, command: int, *, point: Point | None = None, reference: str = "relative",
            params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
            altitude: float | None = None, raw: tuple[int, int, float] | None = None,
            frame: int = mav.FRAME_MISSION) -> None:
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
        self.items.append(Item(frame=frame, command=command, param1=params[0],
                               param2=params[1], param3=params[2], param4=params[3],
                               x=x, y=y, z=z))
        self.owners.append(self.action)

    def waypoint(self, point: Point, reference: str = "relative",
                 exact: tuple[int, int, float] | None = None,
                 params: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)) -> None:
        """Fly to ``point`` (at ``exact``, its x, y, z as written, when given; with
        ``params``, its hold, acceptance radius, pass radius and yaw) and move the cursor
        there."""
        p1, p2, p3, p4 = params
        self.add(mav.NAV_WAYPOINT, point=point, reference=reference, raw=exact,
                 params=(p1, p2, p3, p4))
        self.cursor.position = point


def plus(a: Point, b: Point) -> Point:
    """``a`` moved by ``b``."""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def global_point(b: Builder, action: BoundAction,
                 reference: str = "relative") -> tuple[Point, str]:
    """The local point of latitude/longitude/altitude arguments whose altitude is measured
    from ``reference``, and the reference."""
    altitude = action.number("altitude", b.cursor.position[2])
    amsl = altitude if reference == "amsl" else b.home.altitude + altitude
    north, east, up = to_local(action.number("latitude"), action.number("longitude"), amsl,
                               b.home.latitude, b.home.longitude, b.home.altitude)
    return (north, east, up if reference == "amsl" else altitude), reference


def written_position(b: Builder, action: BoundAction) -> tuple[int, int, float]:
    """The x, y, z of latitude/longitude/altitude arguments exactly as written: degrees to
    1e-7-degree integers with no detour through the local frame (which moves a point far
    from home), the altitude as given."""
    return (round(action.number("latitude") * 1e7), round(action.number("longitude") * 1e7),
            action.number("altitude", b.cursor.position[2]))


def glide(b: Builder, touchdown: Point | None) -> None:
    """A fixed-wing's landing sequence from the cursor: to where the approach starts, then
    NAV_LAND at the touchdown (ArduPlane descends along the line between the two)."""
    approach, ground = landing_approach(b.cursor.position, b.cursor.heading, touchdown)
    b.waypoint(approach)
    b.add(mav.NAV_LAND, point=ground)
    b.cursor.position = ground


def loiter_at(b: Builder, centre: Point, reference: str, radius: float,
              turns: float | None = None, duration: float | None = None,
              exact: tuple[int, int, float] | None = None) -> None:
    if turns is not None:
        # ArduPilot keeps at most LOITER_TURNS_MAX turns in an item: more are several items
        # over the same centre, flown one after the other without leaving the circle.
        left = turns
        while left > 0:
            b.add(mav.NAV_LOITER_TURNS, point=centre, reference=reference,
                  params=(min(left, LOITER_TURNS_MAX), 0.0, radius, 0.0), raw=exact)
            left -= LOITER_TURNS_MAX
    elif duration is not None:
        b.add(mav.NAV_LOITER_TIME, point=centre, reference=reference,
              params=(duration, 0.0, radius, 0.0), raw=exact)
    else:
        b.add(mav.NAV_LOITER_UNLIM, point=centre, reference=reference,
              params=(0.0, 0.0, radius, 0.0), raw=exact)
    b.cursor.position = centre


def land_at(b: Builder, action: BoundAction, point: Point, reference: str,
            exact: tuple[int, int, float] | None = None) -> None:
    precision = PRECISION_MODES[action.choice("precision_mode")]
    yaw = action.number("yaw", None)
    if yaw is not None:
        # ArduCopter keeps its heading while it descends: turn first, then land facing yaw.
        yaw_item(b, yaw % 360.0, relative=False)
    # ArduCopter flies to a NAV_LAND's position at its present altitude and ignores the
    # item's altitude: the approach altitude is given, so that a simulator or autopilot
    # that does fly to it does not descend on the way.
    kept = action.takes("keep_altitude") and bool(action.values.get("keep_altitude"))
    point = (point[0], point[1], b.cursor.position[2]) if reference == "relative" else point
    if exact is not None and reference == "relative" and not kept:
        exact = (exact[0], exact[1], point[2])
    param4 = 0.0 if yaw is None else yaw
    direction = action.values.get("loiter_direction")
    if direction is not None:  # as ArduPilot writes a NAV_LAND back: the sign only
        param4 = -1.0 if direction == "counter-clockwise" else 1.0
    b.add(mav.NAV_LAND, point=point, reference=reference,
          params=(0.0, float(precision), 0.0, param4), raw=exact)
    b.cursor.position = (point[0], point[1], 0.0)


def yaw_item(b: Builder, angle: float, relative: bool) -> None:
    # A turn by an angle goes its sign's way; a heading from north the shorter way
    # (param3 0): ArduCopter keeps to a direction given even then (AutoYaw::set_fixed_yaw),
    # and would turn 315 degrees clockwise for a heading 45 degrees anticlockwise.
    direction = (-1.0 if angle < 0 else 1.0) if relative else 0.0
    b.add(mav.CONDITION_YAW,
          params=(abs(angle), 0.0, direction, 1.0 if relative else 0.0))
    b.cursor.heading = (b.cursor.heading + angle if relative else angle) % 360.0
