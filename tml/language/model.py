"""The mission language as frozen dataclasses.

Every node carries the :class:`~tml.errors.Location` (file, line, column) of the XML
element it came from, so that every later stage (checks, verifier, interpreter, flight
log) can point the author at the source. Nothing here knows about XML or MAVLink.

Values are kept as the author wrote them (argument values are strings); the action
catalogue (:mod:`tml.language.actions`) gives them types and units, and the semantic checks
(:mod:`tml.language.check`) report what does not fit.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterator
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING

from tml.errors import Location

if TYPE_CHECKING:  # loaded only by missions that have an <environment>
    from tml.world import World


class Comparison(StrEnum):
    """The comparison words of TML conditions (the paper's, plus ``known`` and ``includes``)."""

    EQUAL = "equal"
    NOT_EQUAL = "not equal to"
    LESS = "less than"
    LESS_OR_EQUAL = "less than or equal to"
    GREATER = "greater than"
    GREATER_OR_EQUAL = "greater than or equal to"
    KNOWN = "known"
    INCLUDES = "includes"


class TerminationMode(StrEnum):
    """What the interpreter does after an event handler's actions have run."""

    CONTINUE = "CONTINUE"
    NEXT_TASK = "NEXT_TASK"
    REPEAT_TASK = "REPEAT_TASK"
    ABORT_TASK = "ABORT_TASK"
    ABORT_MISSION = "ABORT_MISSION"
    END_MISSION = "END_MISSION"
    JUMP_TO_TASK = "JUMP_TO_TASK"


class Dispatch(StrEnum):
    """How a task's actions reach the vehicle."""

    COMMAND = "command"  # each action sent as commands in GUIDED mode and watched
    MISSION = "mission"  # the task's actions compiled to mission items, flown in AUTO


class Composition(StrEnum):
    """How a task's sub-tasks run (Dolphin's composition operators)."""

    SEQUENCE = "sequence"  # one after the other, in document order (Dolphin's >>)
    PARALLEL = "parallel"  # all at once; done when all are done (Dolphin's |)
    FIRST = "first"  # all at once; done when the first is done, the others are stopped
    CHOICE = "choice"  # the first whose conditions hold, waiting for one (Dolphin's oneOf)


class ConditionKind(StrEnum):
    """What a condition reads: a parameter, a memorized label, or the current task."""

    PARAMETER = "parameter"
    LABEL = "label"
    CURRENT_TASK = "current_task"


class EventTrigger(StrEnum):
    """When an event handler fires again while its conditions hold."""

    EDGE = "edge"  # once each time the conditions become true
    LEVEL = "level"  # on every evaluation while they are true


@dataclass(frozen=True)
class Argument:
    """``<argument name=... value=...|label=.../>`` as written."""

    name: str
    value: str | None
    label: str | None
    location: Location


@dataclass(frozen=True)
class Action:
    """``<action name=...>`` with its arguments, in a terminal task or an event handler."""

    name: str
    arguments: tuple[Argument, ...]
    location: Location

    def argument(self, *names: str) -> Argument | None:
        """The first argument whose normalized name is one of ``names`` (normalized too)."""
        wanted = {normalize_name(n) for n in names}
        for argument in self.arguments:
            if normalize_name(argument.name) in wanted:
                return argument
        return None


@dataclass(frozen=True)
class Condition:
    """``<condition .../>``: reads a parameter, a label or the current task.

    For ``current_task`` conditions ``subject`` is the task name or a ``/``-separated path
    and ``comparison``/``value`` are unused (the test is "the task is running").
    """

    kind: ConditionKind
    subject: str
    comparison: Comparison | None
    value: str | None
    location: Location
    role: str | None = None  # read this role's vehicle instead of the task's own


@dataclass(frozen=True)
class Skill:
    """``<skill name=.../>``: active for the whole task (or mission) that declares it."""

    name: str
    location: Location


@dataclass(frozen=True)
class Region:
    """Where a role's vehicles must be when they are picked: a circle or a polygon.

    Points are (north, east) metres from the mission's home, whatever the author wrote.
    """

    points: tuple[tuple[float, float], ...]  # the centre of a circle, or the polygon's corners
    location: Location
    radius: float | None = None  # set for a circle

    @property
    def is_circle(self) -> bool:
        """True for a circle (one centre and a radius)."""
        return self.radius is not None


@dataclass(frozen=True)
class Role:
    """``<role name=...>``: vehicles a task can be flown by, picked when first needed."""

    name: str
    location: Location
    count: int = 1
    vehicle_type: str | None = None  # "quadcopter", "multicopter", "UAV" ...
    payloads: tuple[str, ...] = ()
    region: Region | None = None
    pick_timeout: float = 30.0  # s to wait for enough free vehicles that qualify


@dataclass(frozen=True)
class Loop:
    """``<loop>``: repeat the task while its conditions hold (checked before each round),
    or forever when it has none."""

    conditions: tuple[Condition, ...]
    location: Location


@dataclass(frozen=True)
class Task:
    """``<task name=...>``: a terminal task holds one action, others hold sub-tasks.

    The orchestration fields (role, composition, wait_for, until, time_limit, on_error,
    loop, release) bring Dolphin's operators; a task that uses none of them behaves as in
    the TML paper.
    """

    name: str
    path: tuple[str, ...]  # names from the top-level task down to this one
    location: Location
    skills: tuple[Skill, ...] = ()
    conditions: tuple[Condition, ...] = ()
    repeat: int = 1
    repeat_location: Location | None = None
    # The MAV_FRAME of the DO_JUMP an exported <repeat> is written as (None: 0).
    repeat_frame: int | None = None
    action: Action | None = None
    children: tuple[Task, ...] = ()
    dispatch: Dispatch = Dispatch.COMMAND  # inherited from the parent task when not given
    role: str | None = None  # the role flying the task, inherited when not given
    role_location: Location | None = None  # where role= is written on this task
    composition: Composition = Composition.SEQUENCE
    wait_for: tuple[Condition, ...] = ()  # wait until all hold before starting
    until: tuple[Condition, ...] = ()  # stop the task (as done) once all hold
    time_limit: float | None = None  # s: stop the task (as done) when it has run this long
    on_error: tuple[Task, ...] = ()  # run in its place when an action in it fails
    loop: Loop | None = None
    release: tuple[str, ...] = ()  # roles whose vehicles are freed when the task ends
    release_location: Location | None = None

    @property
    def orchestrated(self) -> bool:
        """True when the task itself uses an orchestration operator (not its sub-tasks)."""
        return (self.composition is not Composition.SEQUENCE or bool(self.wait_for)
                or bool(self.until) or self.time_limit is not None or bool(self.on_error)
                or self.loop is not None or bool(self.release))

    @property
    def is_terminal(self) -> bool:
        """True when the task holds an action rather than sub-tasks."""
        return self.action is not None

    @property
    def path_name(self) -> str:
        """The task's path written as in ``currentTask="phase one/take off"``."""
        return "/".join(self.path)

    def walk(self) -> Iterator[Task]:
        """This task and all its descendants, depth-first, in document order."""
        # A stack rather than nested generators: each task is handed over once, not once
        # per level above it.
        stack = [self]
        while stack:
            task = stack.pop()
            yield task
            stack.extend(reversed(task.on_error))
            stack.extend(reversed(task.children))


@dataclass(frozen=True)
class Termination:
    """``<termination mode=... task=.../>`` of an event handler."""

    mode: TerminationMode
    location: Location
    task: str | None = None  # target of JUMP_TO_TASK


@dataclass(frozen=True)
class Event:
    """``<event name=...>``: conjunctive conditions, actions, and a termination."""

    name: str
    conditions: tuple[Condition, ...]
    actions: tuple[Action, ...]
    termination: Termination
    location: Location
    trigger: EventTrigger = EventTrigger.EDGE
    role: str | None = None  # only vehicles flying this role evaluate the handler


@dataclass(frozen=True)
class ParameterDeclaration:
    """``<parameter name=... type=.../>``: a detection parameter fed by a skill or companion."""

    name: str
    type: str  # "number", "string", "boolean" or "set"
    location: Location
    description: str = ""


@dataclass(frozen=True)
class Mission:
    """A whole mission file."""

    name: str
    location: Location
    tasks: tuple[Task, ...]
    skills: tuple[Skill, ...] = ()
    events: tuple[Event, ...] = ()
    parameters: tuple[ParameterDeclaration, ...] = ()
    world: World | None = None
    source: str = ""  # the file's text, kept to quote lines in diagnostics
    roles: tuple[Role, ...] = ()

    def role(self, name: str) -> Role | None:
        """The declared role called ``name``."""
        return next((r for r in self.roles if r.name == name), None)

    @property
    def file(self) -> str:
        """The path the mission was read from."""
        return self.location.file

    def walk(self) -> Iterator[Task]:
        """Every task, depth-first, in document order."""
        for task in self.tasks:
            yield from task.walk()

    def actions(self) -> Iterator[tuple[Task | Event, Action]]:
        """Every action with the task or event that holds it, in document order."""
        for task in self.walk():
            if task.action is not None:
                yield task, task.action
        for event in self.events:
            for action in event.actions:
                yield event, action


_CAMEL_BOUNDARY = re.compile(r"(?<=[a-z0-9])(?=[A-Z])")


@functools.lru_cache(maxsize=4096)
def normalize_name(name: str) -> str:
    """Canonical form of an argument or parameter name: lower case, words joined by ``_``.

    ``"relative point"``, ``"Relative-Point"``, ``"relative_point"`` and ``"relativePoint"``
    are one name.
    """
    spaced = _CAMEL_BOUNDARY.sub(" ", name)
    words = spaced.replace("-", " ").replace("_", " ").split()
    return "_".join(word.lower() for word in words)

