"""The QGC WPL 110 waypoint file: what MAVProxy's ``wp load`` and Mission Planner read.

One line ``QGC WPL 110``, then one line per item, its fields separated by tabs: index,
current, frame, command, params 1-4, x (latitude), y (longitude), z (altitude),
autocontinue. Line 0 is home (frame 0, altitude AMSL): ArduPilot keeps home in item 0, so
the mission's items are numbered from 1, as ``wp load`` sends them. MAVProxy's fence list
is the same layout, of fence items from index 0 and no home; its rally list is ``RALLY``
lines (:func:`read_rally`). Both are read and written here (:func:`write_fence`,
:func:`write_rally`).
"""

from __future__ import annotations

from tml.mavlink.codec import mavlink
from tml.mavlink.mission import MissionItem
from tml.plans.planned import Plan
from tml.plans.qgc import (
    PlanFile,
    PlanFileError,
    Zone,
    global_corners,
    item_from_params,
    item_params,
)
from tml.world import Cylinder, Home, World

HEADER = "QGC WPL 110"


def _number(value: float | None) -> str:
    number = float(value or 0.0)
    return str(int(number)) if number.is_integer() and abs(number) < 1e15 else repr(number)


def write_wpl(plan: Plan) -> str:
    """The waypoint file text of ``plan``."""
    home = plan.home
    lines = [HEADER, "\t".join(["0", "1", "0", str(mavlink.MAV_CMD_NAV_WAYPOINT), "0", "0",
                                "0", "0", _number(home.latitude), _number(home.longitude),
                                _number(home.altitude), "1"])]
    for item in plan.items:
        fields = [str(item.seq + 1), "0", str(item.frame), str(item.command),
                  *(_number(v) for v in item_params(item)), str(item.autocontinue)]
        lines.append("\t".join(fields))
    return "\n".join(lines) + "\n"


FENCE_VERTEX_INCLUSION, FENCE_VERTEX_EXCLUSION = 5001, 5002
FENCE_CIRCLE_INCLUSION, FENCE_CIRCLE_EXCLUSION = 5003, 5004
FENCE_RETURN_POINT, RALLY_POINT = 5000, 5100
FENCE_COMMANDS = frozenset({FENCE_VERTEX_INCLUSION, FENCE_VERTEX_EXCLUSION,
                            FENCE_CIRCLE_INCLUSION, FENCE_CIRCLE_EXCLUSION,
                            FENCE_RETURN_POINT, RALLY_POINT})
"""The commands of a fence or rally list (MAVProxy's ``fence save``, ``rally save``)."""
RALLY = "RALLY"
RALLY_DEFAULTS = (40.0, 0.0, 0)
"""A ``RALLY`` line's break altitude (m), landing direction and flags as MAVProxy's
``rally add`` writes them (its rally_breakalt and rally_flags settings): what a TML rally
point, which has none of the three, is written back with."""


def write_fence(world: World) -> str:
    """The fence list of ``world``, as MAVProxy's ``fence save`` writes it (and ``fence
    load`` reads it): a waypoint file of fence items from index 0, with no home line. The
    geofence's polygon is inclusion vertices (each with the corner count in param1), each
    prism exclusion vertices, each cylinder an exclusion circle (the radius in param1)."""
    home = world.home_or_default
    items: list[tuple[int, float, list[float]]] = []  # command, param1, [lat, lon]
    if world.geofence is not None and world.geofence.polygon:
        fence = world.geofence
        corners = global_corners(home, fence.polygon, fence.written)
        items += [(FENCE_VERTEX_INCLUSION, len(corners), c) for c in corners]
    for obstacle in world.obstacles:
        if isinstance(obstacle, Cylinder):
            centre, = global_corners(home, ((obstacle.north, obstacle.east),),
                                     obstacle.written)
            items.append((FENCE_CIRCLE_EXCLUSION, obstacle.radius, centre))
        else:
            corners = global_corners(home, obstacle.polygon, obstacle.written)
            items += [(FENCE_VERTEX_EXCLUSION, len(corners), c) for c in corners]
    lines = [HEADER]
    for index, (command, param1, (lat, lon)) in enumerate(items):
        lines.append("\t".join([str(index), "0", "0", str(command), _number(param1), "0", "0",
                                "0", _number(lat), _number(lon), "0", "0"]))
    return "\n".join(lines) + "\n"


def write_rally(world: World) -> str:
    """The rally list of ``world``, as MAVProxy's ``rally save`` writes it: a line
    ``RALLY lat lon alt break_alt land_dir flags`` per point, the altitude above home, the
    other three :data:`RALLY_DEFAULTS`."""
    home = world.home_or_default
    lines = []
    for point in world.rally:
        (lat, lon), = global_corners(home, ((point.north, point.east),), point.written)
        lines.append("\t".join([RALLY, *(_number(v) for v in (
            lat, lon, point.altitude, RALLY_DEFAULTS[0], RALLY_DEFAULTS[1])),
            str(RALLY_DEFAULTS[2])]))
    return "".join(line + "\n" for line in lines)


def read_wpl(text: str, name: str = "waypoints") -> PlanFile:
    """The items and home of a waypoint file's text.

    Line 0 is home when it is in ArduPilot's home form (a NAV_WAYPOINT in frame 0, as
    ``wp save`` writes it); any other line 0 (MAVSDK's sample starts with a NAV_TAKEOFF) is
    the first item. A fence or rally list (commands 5000-5004, 5100) becomes zones and
    rally points. A line that starts with ``#`` is a comment, as ``wp load`` reads it.
    MAVProxy's older rally list (``RALLY`` lines, :func:`read_rally`) is read too."""
    lines = [(number, line) for number, line in enumerate(text.splitlines(), start=1)
             if line.strip() and not line.lstrip().startswith("#")]
    if lines and lines[0][1].split()[0].upper() == RALLY:
        return read_rally(lines, name)
    if not lines or not lines[0][1].startswith("QGC WPL"):
        where = lines[0][0] if lines else 1
        raise PlanFileError(f"{name}:{where}: not a waypoint file (the first line is not "
                            f"'{HEADER}')")
    items: list[MissionItem] = []
    sources: list[str] = []
    losses: list[str] = []
    fence: list[tuple[str, MissionItem]] = []
    home = None
    for number, line in lines[1:]:
        fields = line.split()
        if len(fields) != 12:
            raise PlanFileError(f"{name}:{number}: expected 12 fields, got {len(fields)}")
        try:
            index, frame, command = int(fields[0]), int(fields[2]), int(fields[3])
            params = [float(v) for v in fields[4:11]]
            autocontinue = bool(int(float(fields[11])))
        except ValueError as error:
            raise PlanFileError(f"{name}:{number}: {error}") from None
        if index == 0 and home is None and not items and not fence \
                and command == mavlink.MAV_CMD_NAV_WAYPOINT and frame == 0:
            home = Home(params[4], params[5], params[6])
            continue
        source = f"item {index} (line {number})"
        try:
            item = item_from_params(len(items), frame, command, params, autocontinue, losses,
                                    source)
        except PlanFileError as error:
            raise PlanFileError(f"{name}:{number}: {error}") from None
        if command in FENCE_COMMANDS:
            fence.append((source, item))
            continue
        items.append(item)
        sources.append(source)
    zones, rally = _fence(fence, losses)
    return PlanFile(tuple(items), home, zones, rally, (), tuple(sources), tuple(losses))


def _fence(fence: list[tuple[str, MissionItem]],
           losses: list[str]) -> tuple[tuple[Zone, ...], tuple[tuple[float, float, float], ...]]:
    """The zones and rally points of a fence or rally list's items: consecutive vertices
    make a polygon of as many corners as their param1 says."""
    zones: list[Zone] = []
    rally: list[tuple[float, float, float]] = []
    corners: list[tuple[float, float]] = []
    for source, item in fence:
        point = (item.x / 1e7, item.y / 1e7)
        if item.command in (FENCE_VERTEX_INCLUSION, FENCE_VERTEX_EXCLUSION):
            corners.append(point)
            if len(corners) == int(item.param1):
                zones.append(Zone(tuple(corners), item.command == FENCE_VERTEX_INCLUSION))
                corners = []
        elif item.command in (FENCE_CIRCLE_INCLUSION, FENCE_CIRCLE_EXCLUSION):
            zones.append(Zone((point,), item.command == FENCE_CIRCLE_INCLUSION, item.param1))
        elif item.command == RALLY_POINT:
            rally.append((*point, item.z))
        else:
            losses.append(f"{source}: the fence's return point has no TML form: left out")
    if corners:
        losses.append(f"a polygon of {len(corners)} corner(s) whose count does not match its "
                      "items' param1: left out")
    return tuple(zones), tuple(rally)


def read_rally(lines: list[tuple[int, str]], name: str) -> PlanFile:
    """The rally points of MAVProxy's rally list (pymavlink's ``MAVRallyLoader``): one
    ``RALLY lat lon alt break_alt land_dir flags`` line per point, the altitude above home.
    A break altitude, landing direction or flags other than MAVProxy's defaults
    (:data:`RALLY_DEFAULTS`) has no TML form: a loss."""
    rally: list[tuple[float, float, float]] = []
    losses: list[str] = []
    for number, line in lines:
        fields = line.split()
        if len(fields) != 7 or fields[0].upper() != RALLY:
            raise PlanFileError(f"{name}:{number}: expected 'RALLY lat lon alt break_alt "
                                f"land_dir flags', got {line.strip()!r}")
        try:
            lat, lon, alt, break_alt, land_dir = (float(v) for v in fields[1:6])
            flags = int(fields[6])
        except ValueError as error:
            raise PlanFileError(f"{name}:{number}: {error}") from None
        if (break_alt, land_dir, flags) != RALLY_DEFAULTS:
            losses.append(f"rally point {len(rally) + 1} (line {number}): break altitude "
                          f"{break_alt:g} m, landing direction {land_dir:g}, flags {flags} "
                          "(a TML rally point has none: written back as "
                          f"{RALLY_DEFAULTS[0]:g}, {RALLY_DEFAULTS[1]:g}, {RALLY_DEFAULTS[2]})")
        rally.append((lat, lon, alt))
    return PlanFile((), rally=tuple(rally), losses=tuple(losses))
