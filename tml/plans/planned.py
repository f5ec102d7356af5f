"""What a mission would fly, as the mission items of one autopilot plan.

Theory of operation
-------------------
A plan file holds one vehicle's list of mission items, flown in order in AUTO: no events,
no conditions, no second vehicle. :func:`plan_mission` therefore takes the mission's
*nominal* path: the terminal tasks in document order (of one role, in a mission with
roles), a repeated task's body once and a DO_JUMP back to it with the repeat count (a
repeat that holds another repeat unrolled), and compiles their actions with the mission
compiler
(:mod:`tml.mavlink.compile`), the one that compiles ``dispatch="mission"`` tasks in
flight. Actions flown as GUIDED commands become the mission items that do the same thing
in AUTO; an action with no such item (MEMORIZE_POINT, FLIP, an argument read from a
label only known in flight) or that the vehicle's kind cannot fly is left out, and the
plan says which and why (:attr:`Plan.skipped`). What the plan cannot keep of the
mission's structure (event handlers, conditions, loops, parallel branches, error
handlers) is said in :attr:`Plan.notes`.

Positions are relative to the mission's home (its ``<environment>``, or ArduPilot SITL's
default location), which the plan carries as its planned home.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from itertools import pairwise

from tml.actions.mav import AMSL_FRAMES, GLOBAL_FRAMES
from tml.geo import to_global
from tml.language.actions import BoundAction, bind
from tml.language.kinds import Kind, refusal, role_kinds
from tml.language.model import Composition, Mission, Task
from tml.mavlink.codec import mavlink
from tml.mavlink.compile import CompileError, compile_mission, has_items
from tml.mavlink.mission import MissionItem
from tml.world import Home, World


@dataclass(frozen=True)
class Skipped:
    """An action the plan leaves out, and why."""

    task: str  # the task's path, "phase one/take off"
    action: str
    line: int
    reason: str

    def __str__(self) -> str:
        return f"line {self.line}: task {self.task!r}: {self.action} not exported: {self.reason}"


@dataclass(frozen=True)
class Plan:
    """The mission items of a mission (seq 0..N-1, home not among them), with the task each
    item comes from, and what could not be kept."""

    name: str
    home: Home
    kind: Kind
    world: World
    items: tuple[MissionItem, ...]
    tasks: tuple[str, ...]  # the task path of each item
    skipped: tuple[Skipped, ...] = ()
    notes: tuple[str, ...] = ()
    role: str | None = None

    def position(self, item: MissionItem) -> tuple[float, float, float] | None:
        """Latitude, longitude and altitude AMSL of an item that has a position."""
        if item.frame not in GLOBAL_FRAMES or (item.x == 0 and item.y == 0):
            return None
        altitude = item.z if item.frame in AMSL_FRAMES else self.home.altitude + item.z
        return item.x / 1e7, item.y / 1e7, altitude

    def path(self) -> list[tuple[float, float, float]]:
        """The points flown, from home: latitude, longitude, altitude AMSL.

        A take-off climbs over the point where the vehicle is, a return to launch flies
        home and lands there; the other items with a position are flown to in order.
        """
        here = (self.home.latitude, self.home.longitude, self.home.altitude)
        points = [here]
        for item in self.items:
            position = self.position(item)
            if item.command == mavlink.MAV_CMD_NAV_TAKEOFF:
                position = (here[0], here[1], self.home.altitude + item.z)
            elif item.command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
                points.append((self.home.latitude, self.home.longitude, here[2]))
                position = (self.home.latitude, self.home.longitude, self.home.altitude)
            elif item.command == mavlink.MAV_CMD_NAV_LAND and position is None:
                position = (here[0], here[1], self.home.altitude)
            if position is not None:
                points.append(position)
                here = position
        return points


def same_item(a: MissionItem, b: MissionItem) -> bool:
    """Whether two items are the same item (their seq aside; NaN is NaN)."""
    def same(x: float, y: float) -> bool:
        return x == y or (math.isnan(x) and math.isnan(y))

    return (a.command, a.frame, a.x, a.y, bool(a.autocontinue)) \
        == (b.command, b.frame, b.x, b.y, bool(b.autocontinue)) and all(
            same(x, y) for x, y in zip((a.param1, a.param2, a.param3, a.param4, a.z),
                                       (b.param1, b.param2, b.param3, b.param4, b.z),
                                       strict=True))


def world_left_out(world: World, form: str) -> list[str]:
    """What of ``world`` a file of ``form`` ("plan", "wpl", "fence" or "rally") cannot
    carry: a ``.plan``'s geofence and a fence list's have no altitudes and their exclusion
    zones no top or bottom; a waypoint file holds no fence at all, a fence list no rally
    point and a rally list no fence; neither list holds a home."""
    notes = []
    fence = world.geofence
    if form == "wpl":
        if fence is not None or world.obstacles:
            notes.append("the geofence and obstacles are not in a waypoint file (it holds "
                         "mission items only): export a .plan, or upload them with tml run")
        return notes
    if form in ("fence", "rally") and world.home is not None:
        notes.append(f"the home is not in a {form} list: tml import --home "
                     f"{world.home.latitude},{world.home.longitude},"
                     f"{world.home.altitude:g} places it again")
    if form == "fence" and world.rally:
        notes.append(f"{len(world.rally)} rally point(s) not in a fence list: export "
                     "--format rally")
    if form == "rally":
        if fence is not None or world.obstacles:
            notes.append("the geofence and obstacles are not in a rally list: export "
                         "--format fence")
        return notes
    where, which = ("fence list", "a fence item") if form == "fence" \
        else ("plan", "QGroundControl's geofence")
    if fence is not None:
        for name, value in (("max_altitude", fence.max_altitude),
                            ("min_altitude", fence.min_altitude)):
            if value is not None:
                notes.append(f"the geofence's {name} {value:g} m is not in the {where} "
                             f"({which} has no altitude; ArduPilot takes it as "
                             f"FENCE_ALT_{name[:3].upper()})")
    for obstacle in world.obstacles:
        kept = [f"{name} {value:g} m" for name, value, plain in (
            ("bottom", obstacle.bottom, 0.0), ("top", obstacle.top, float("inf")))
            if value != plain]
        if kept:
            notes.append(f"obstacle {obstacle.name!r}: its {' and '.join(kept)} "
                         f"{'are' if len(kept) > 1 else 'is'} not in the {where} (an "
                         "exclusion zone reaches from the ground up)")
    return notes


def local_to_global(home: Home, north: float, east: float,
                    up: float = 0.0) -> tuple[float, float, float]:
    """Latitude, longitude and altitude AMSL of a point in metres from ``home``."""
    return to_global(north, east, up, home.latitude, home.longitude, home.altitude)


class PlanError(ValueError):
    """A mission that cannot be made into one plan (says why: which role to choose)."""


def plan_mission(mission: Mission, role: str | None = None, kind: Kind | None = None,
                 world: World | None = None) -> Plan:
    """The plan of ``mission`` (of ``role``'s tasks, in a mission with roles) for a vehicle
    of ``kind`` (default: the role's kind, else a multicopter), in the mission's world with
    ``world`` (a world file) laid over it.

    Raises :class:`PlanError` for a role the mission does not declare, and when the
    mission has several roles and none is chosen.
    """
    if mission.roles:
        names = [r.name for r in mission.roles]
        if role is None and len(names) == 1:
            role = names[0]
        if role is None:
            raise PlanError(f"the mission has the roles {', '.join(names)}: "
                            "--role names the one whose plan to write")
        declared = mission.role(role)
        if declared is None:
            raise PlanError(f"the mission has no role {role!r} (roles: {', '.join(names)})")
        if kind is None:
            kinds = role_kinds(declared.vehicle_type)
            kind = Kind.MULTICOPTER if Kind.MULTICOPTER in kinds else min(kinds)
    elif role is not None:
        raise PlanError(f"the mission declares no roles, so there is no role {role!r}")
    kind = kind or Kind.MULTICOPTER
    world = (mission.world or World()).merged(world)
    home = world.home_or_default
    notes = _notes(mission, role)
    skipped: dict[Skipped, None] = {}  # in order, each once (a repeat skips it again)
    flown: list[tuple[Task, BoundAction]] = []
    nominal: list[Task] = []
    repeats: list[_Rounds] = []
    _nominal(mission.tasks, role, notes, nominal, repeats)
    flown_at: list[int] = []  # for each entry of nominal, len(flown) before it
    for task in nominal:
        flown_at.append(len(flown))
        assert task.action is not None
        bound = bind(task.action)
        line = task.action.location.line
        why = refusal(bound, kind)
        if why is None and not has_items(bound.name):
            why = "no mission item does this (it is flown with commands only)"
        if why is None:
            try:  # alone: whether the action has items at all, whatever came before it
                compile_mission([bound], home, (0.0, 0.0, 0.0), home.heading, kind)
            except CompileError as error:
                why = str(error)
        if why is not None:
            skipped.setdefault(Skipped(task.path_name, bound.name, line, why))
        else:
            flown.append((task, bound))
    compiled = compile_mission([b for _, b in flown], home, (0.0, 0.0, 0.0), home.heading,
                               kind)
    flown_at.append(len(flown))
    items, owners = _jumps(compiled.items, compiled.action_index,
                           [(r.task, [flown_at[n] for n in r.starts]) for r in repeats])
    tasks = tuple(flown[index][0].path_name if index >= 0 else task
                  for index, task in owners)
    return Plan(mission.name, home, kind, world, items, tasks, tuple(skipped),
                tuple(notes), role)


JUMP_FRAME = mavlink.MAV_FRAME_GLOBAL
"""The frame of the DO_JUMP a ``<repeat>`` is written as: ArduPilot's ``wp save`` writes its
DO_JUMPs in frame 0, and an import reads such a DO_JUMP back as the repeat."""


@dataclass(frozen=True)
class _Rounds:
    """A repeated task with no repeat inside: where each of its rounds starts in the
    nominal list, and where the last ends."""

    task: Task
    starts: list[int]


def _jumps(items: tuple[MissionItem, ...], action_index: tuple[int, ...],
           repeats: list[tuple[Task, list[int]]]
           ) -> tuple[tuple[MissionItem, ...], list[tuple[int, str]]]:
    """The items with the rounds after the first of each repeat made one DO_JUMP back to
    the first round's first item (its number from 1), repeated ``repeat - 1`` times, where
    every round compiled to the same items as the first (a round of relative moves, flown
    from where the one before ended, is not: it stays unrolled). Also the owner of each
    item: (action index, "") or (-1, the repeated task's path) for a DO_JUMP."""
    def span(start: int, end: int) -> range:  # the items of the actions start..end-1
        first = next((n for n, a in enumerate(action_index) if a >= start), len(items))
        last = next((n for n, a in enumerate(action_index) if a >= end), len(items))
        return range(first, last)

    jump_at: dict[int, tuple[Task, range, int]] = {}  # 2nd round's first item -> jump
    for task, starts in repeats:
        rounds = [span(a, b) for a, b in pairwise(starts)]
        first = rounds[0]
        if first and all(len(r) == len(first) and all(
                same_item(items[x], items[y]) for x, y in zip(first, r, strict=True))
                for r in rounds[1:]):
            jump_at[rounds[1].start] = (task, first, rounds[-1].stop)
    kept: list[MissionItem] = []
    owners: list[tuple[int, str]] = []
    new_seq: dict[int, int] = {}
    n = 0
    while n < len(items):
        if n in jump_at:
            task, first, stop = jump_at[n]
            frame = JUMP_FRAME if task.repeat_frame is None else task.repeat_frame
            kept.append(MissionItem(seq=len(kept), frame=frame,
                                    command=mavlink.MAV_CMD_DO_JUMP,
                                    param1=float(new_seq[first.start] + 1),
                                    param2=float(task.repeat - 1)))
            owners.append((-1, task.path_name))
            n = stop
            continue
        new_seq[n] = len(kept)
        kept.append(replace(items[n], seq=len(kept)))
        owners.append((action_index[n], ""))
        n += 1
    return tuple(kept), owners


def _nominal(tasks: tuple[Task, ...], role: str | None, notes: list[str],
             out: list[Task], repeats: list[_Rounds]) -> None:
    """The terminal tasks flown when nothing goes wrong, in order, repeats unrolled, into
    ``out``; where each round of a repeated task with no repeat inside starts, into
    ``repeats`` (its rounds may become one DO_JUMP, :func:`_jumps`; one with a repeat
    inside stays unrolled, ArduPilot keeping one count per DO_JUMP for the whole mission,
    so an inner DO_JUMP flown again would not repeat again)."""
    for task in tasks:
        children = task.children
        if task.composition in (Composition.CHOICE, Composition.FIRST) and children:
            notes.append(f"task {task.path_name!r} flies one of its sub-tasks "
                         f"({task.composition.value}): the plan has the first, "
                         f"{children[0].name!r}")
            children = children[:1]
        starts = []
        for _ in range(task.repeat):
            starts.append(len(out))
            if task.is_terminal:
                if role is None or task.role == role:
                    out.append(task)
            else:
                _nominal(children, role, notes, out, repeats)
        if task.repeat > 1 and not any(t.repeat > 1 for t in task.walk() if t is not task):
            repeats.append(_Rounds(task, [*starts, len(out)]))


def _notes(mission: Mission, role: str | None) -> list[str]:
    """What of the mission's structure a list of items cannot say."""
    notes = []
    if mission.events:
        notes.append(f"{len(mission.events)} event handler(s) not in the plan: the autopilot "
                     "flies the items without them")
    for task in mission.walk():
        if role is not None and task.role not in (role, None):
            continue
        if task.conditions:
            notes.append(f"task {task.path_name!r} has conditions: the plan flies it always")
        if task.loop is not None:
            notes.append(f"task {task.path_name!r} loops: the plan flies one round")
        if task.on_error:
            notes.append(f"task {task.path_name!r} has an error handler: not in the plan")
        flown = [c for c in task.children if any(
            t.is_terminal and (role is None or t.role == role) for t in c.walk())]
        if task.composition is Composition.PARALLEL and len(flown) > 1:
            notes.append(f"the sub-tasks of {task.path_name!r} run in parallel: the plan "
                         "flies them one after the other")
    return notes
