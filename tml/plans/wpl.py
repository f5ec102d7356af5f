"""The QGC WPL 110 waypoint file: what MAVProxy's ``wp load`` and Mission Planner read.

One line ``QGC WPL 110``, then one line per item, its fields separated by tabs: index,
current, frame, command, params 1-4, x (latitude), y (longitude), z (altitude),
autocontinue. Line 0 is home (frame 0, altitude AMSL): ArduPilot keeps home in item 0, so
the mission's items are numbered from 1, as ``wp load`` sends them.
"""

from __future__ import annotations

from tml.mavlink.codec import mavlink
from tml.mavlink.mission import MissionItem
from tml.plans.planned import Plan
from tml.plans.qgc import PlanFile, PlanFileError, item_from_params, item_params
from tml.world import Home

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


def read_wpl(text: str, name: str = "waypoints") -> PlanFile:
    """The items and home of a waypoint file's text (line 0 is home)."""
    lines = [line for line in text.splitlines() if line.strip()]
    if not lines or not lines[0].startswith("QGC WPL"):
        raise PlanFileError(f"{name}:1: not a waypoint file (the first line is not "
                            f"'{HEADER}')")
    items: list[MissionItem] = []
    home = None
    for number, line in enumerate(lines[1:], start=2):
        fields = line.split()
        if len(fields) != 12:
            raise PlanFileError(f"{name}:{number}: expected 12 fields, got {len(fields)}")
        try:
            index, frame, command = int(fields[0]), int(fields[2]), int(fields[3])
            params = [float(v) for v in fields[4:11]]
            autocontinue = bool(int(float(fields[11])))
        except ValueError as error:
            raise PlanFileError(f"{name}:{number}: {error}") from None
        if index == 0 and home is None and not items:
            home = Home(params[4], params[5], params[6])
            continue
        try:
            items.append(item_from_params(len(items), frame, command, params, autocontinue))
        except PlanFileError as error:
            raise PlanFileError(f"{name}:{number}: {error}") from None
    return PlanFile(tuple(items), home)
