"""The terminal view of a run: task tree with states, each vehicle's telemetry and work,
the autopilots' messages, events.

:func:`render` turns the interpreters' views and the vehicles' last states into one rich
renderable; :class:`LiveDisplay` redraws it in place on a terminal (at most
``refresh_per_second`` times a second, however often the runner asks), and
:class:`LineDisplay` prints one line per change (task state, event, end) for logs and pipes,
in the order the changes happened.

Every time shown is the mission time -- seconds since the mission's first task started, the
flight log's ``mission_time`` -- and the live view's header adds the wall clock. Each
vehicle gets up to :data:`VEHICLE_LINES` lines, its figures labelled with their units: how
it stands (mode, armed, link, battery voltage and charge, GPS fix and satellites), how it
moves (north, east and up from home, climb rate, distance to home, ground speed, heading),
and what it does (progress, the item of an autopilot plan as the vehicle reports it, the
action and its task). A wide terminal puts the first two on one line; on a narrow one the
figures that do not fit their line are left out, the least needed (written last) first.
Its autopilot's latest messages are kept per vehicle, so that one vehicle's ``Mission: N
WP`` never pushes another's out.

*What the tree says of a task is what happened to it last, and when.* A task whose work an
event handler holds is marked interrupted (``‖``), with the tasks running above it, while
the handler's actions fly (the work line names the event): it is not flying, and what
becomes of it is the handler's termination's to say. A task whose sub-tasks ran more than
once in its current run (a repeat, a loop) says its round (``round 2 of 5``); a sub-task
whose state is from an earlier round, or from an earlier run of its parent, is drawn dim
and says so (``(round 1)``), so that a task done after an aborted one is read as what it
is: last round's. The rounds are read from the vehicle's task changes (:func:`rounds`).
"""

from __future__ import annotations

import io
import time
from collections.abc import Sequence, Set
from dataclasses import dataclass
from datetime import datetime

from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.text import Text

from tml.engine import Change, Status, TaskState, View
from tml.language.diagnostics import printable
from tml.language.model import Dispatch, Mission, Task
from tml.run.fold import fold
from tml.vehicle import SEVERITIES, VehicleState, awaiting

Views = Sequence[tuple[View, VehicleState | None]]

OFF_TERMINAL_WIDTH = 160
"""Columns a table may take when the output is not a terminal (a pipe, a file, a CI log)."""


def output_console(stderr: bool = False) -> Console:
    """The console a command prints to: on a terminal, as wide as it is; off a terminal,
    lines are never wrapped (a pipe or a CI log gets whole lines, and a caret stays under
    its column) and tables may take :data:`OFF_TERMINAL_WIDTH` columns."""
    if Console(stderr=stderr).is_terminal:
        return Console(stderr=stderr, highlight=False)
    return Console(stderr=stderr, highlight=False, soft_wrap=True, width=OFF_TERMINAL_WIDTH)


def _safe(text: str) -> str:
    """Text from a mission file or a vehicle as it may be shown: on one line, control
    characters and bidi overrides escaped (one rule: tml.language.diagnostics.printable)."""
    return printable(text, newlines=False)


MARKS = {
    TaskState.PENDING: ("·", "dim"), TaskState.RUNNING: ("▶", "bold yellow"),
    TaskState.DONE: ("✓", "green"), TaskState.SKIPPED: ("↷", "cyan"),
    TaskState.FAILED: ("✗", "bold red"), TaskState.ABORTED: ("■", "red"),
}
HELD = ("‖", "bold magenta")
"""The mark of a task an event handler interrupted on a vehicle (its work held), and of
the tasks running above it."""
EVENTS_SHOWN = 6


@dataclass(frozen=True)
class Rounds:
    """What a vehicle's task changes tell of the rounds of its tasks."""

    now: dict[str, int]
    """Each task whose sub-tasks ran more than once in its current run: its round (the
    most runs of one of its sub-tasks)."""
    earlier: dict[str, int]
    """Each task whose state is from an earlier round of its parent, or from an earlier
    run of it: the round of its parent it is from (0: an earlier run, a round unsaid)."""


class _Count:
    """The count of :func:`rounds` over the changes of one vehicle's views so far: a
    vehicle's changes only grow, so each redraw reads only the new ones."""

    def __init__(self, first: Change) -> None:
        self.first, self.tail, self.seen = first, first, 0
        self.runs: dict[str, int] = {}  # each task's runs begun
        self.begun: dict[str, dict[str, int]] = {}  # per task: its sub-tasks' runs in its run
        self.last: dict[str, tuple[int, int]] = {}  # per task: (its parent's run, its round)
        self.state: dict[str, TaskState] = {}  # when it changed last, and how

    def follows(self, changes: Sequence[Change]) -> bool:
        """Whether ``changes`` are those counted so far and maybe more."""
        return changes[0] is self.first and len(changes) >= self.seen \
            and (not self.seen or changes[self.seen - 1] is self.tail)

    def take(self, changes: Sequence[Change]) -> None:
        for change in changes[self.seen:]:
            path = change.task
            parent = path.rpartition("/")[0]
            siblings = self.begun.setdefault(parent, {})
            if change.state is TaskState.RUNNING or (
                    change.state is TaskState.SKIPPED
                    and self.state.get(path) is not TaskState.RUNNING):
                siblings[path] = siblings.get(path, 0) + 1
            if change.state is TaskState.RUNNING:
                self.runs[path] = self.runs.get(path, 0) + 1
                self.begun[path] = {}
            self.last[path] = (self.runs.get(parent, 0), siblings.get(path, 1))
            self.state[path] = change.state
            self.tail = change
        self.seen = len(changes)

    def rounds(self, repeating: Set[str]) -> Rounds:
        now = {task: most for task, found in self.begun.items() if task in repeating
               for most in [max(found.values(), default=0)] if most > 1}
        earlier: dict[str, int] = {}
        for path in sorted(self.last, key=lambda found: found.count("/")):  # parents first
            parent = path.rpartition("/")[0]
            run, number = self.last[path]
            if parent in earlier or run != self.runs.get(parent, 0):
                earlier[path] = 0
            elif number < now.get(parent, 1):
                earlier[path] = number
        return Rounds(now, earlier)


_COUNTS: dict[tuple[object, int], _Count] = {}
"""The counts of the vehicles' views drawn, by vehicle and the id of their first change
(which each count holds, so that the id stays its own). By vehicle too: the changes of the
tasks no vehicle flies are in every vehicle's view, the same objects, so two vehicles'
changes may begin and end alike."""
COUNTS_KEPT = 4096


def rounds(changes: Sequence[Change], repeating: Set[str], vehicle: object = None) -> Rounds:
    """The rounds the ``changes`` of a vehicle's view tell, of the tasks in ``repeating``
    (those with a repeat or a loop): a sub-task begun again (running, or skipped without
    running) in the same run of its parent begins the parent's next round; and of every
    task, that a task begun again begins its sub-tasks anew. Counted on from the last
    call's for the same ``vehicle`` when these follow them."""
    if not changes:
        return Rounds({}, {})
    key = (vehicle, id(changes[0]))
    count = _COUNTS.get(key)
    if count is None or not count.follows(changes):
        if len(_COUNTS) >= COUNTS_KEPT:
            _COUNTS.clear()
        count = _COUNTS[key] = _Count(changes[0])
    count.take(changes)
    return count.rounds(repeating)


def _held(view: View) -> set[str]:
    """The tasks shown interrupted on a vehicle: those whose work an event handler holds,
    and the tasks running above them."""
    found: set[str] = set()
    for path in view.held:
        names = path.split("/")
        found.update(way for way in ("/".join(names[:i]) for i in range(1, len(names) + 1))
                     if view.task_states.get(way) is TaskState.RUNNING)
    return found


def _mark_width(views: Views) -> int:
    """Columns of one vehicle's mark: wide enough for its number over it, in a fleet."""
    if len(views) < 2:
        return 1
    return max(len(_vehicle_name(i, views)) for i in range(len(views))) + 1


def _vehicle_name(index: int, views: Views) -> str:
    state = views[index][1]
    return str(state.vehicle_id if state is not None else index + 1)


def _tree(mission: Mission, views: Views, budget: int | None) -> tuple[Text, bool]:
    """The task tree, each task with its mark per vehicle, folded to ``budget`` lines; and
    whether a task is shown folded."""
    width = _mark_width(views)
    marks_width = width * len(views)
    text = Text(no_wrap=True, overflow="ellipsis")
    if len(views) > 1:  # a header over the marks: which vehicle each column is
        text.append("".join(_vehicle_name(i, views).rjust(width)
                            for i in range(len(views))), "bold")
        text.append("  vehicle", "dim")
    focus = [view.current_task for view, _ in views if view.current_task]
    lines = fold(mission.tasks, focus, None if budget is None
                 else max(budget - (len(views) > 1), 1))
    repeating = {t.path_name for t in mission.walk() if t.repeat > 1 or t.loop is not None}
    found = [rounds(view.changes, repeating, _vehicle_name(i, views))
             for i, (view, _) in enumerate(views)]
    held = [_held(view) for view, _ in views]
    for number, line in enumerate(lines):
        if number or len(views) > 1:
            text.append("\n")
        task = line.task
        if task is None:
            text.append(" " * marks_width + " " + line.guide, "dim")
            text.append(f"… {line.hidden} more task{'s' if line.hidden != 1 else ''}", "dim")
            continue
        path = task.path_name
        for index, (view, _) in enumerate(views):
            mark, style = HELD if path in held[index] else \
                MARKS[view.task_states.get(path, TaskState.PENDING)]
            text.append(mark.rjust(width), f"dim {style}" if path in found[index].earlier
                        else style)
        text.append(" " + line.guide, "dim")
        text.append(_safe(task.name))
        if task.action is not None:
            text.append(f"  {task.action.name}", "dim")
        if _plan_root(mission, task):
            text.append("  [autopilot mission]", "cyan")
        said = _round_said(task, views, found)
        if said:
            text.append(f"  {said}", "bold")
        earlier = _earlier_said(path, views, found)
        if earlier:
            text.append(f"  ({earlier})", "dim")
        if line.folded:
            text.append(f"  (+{line.folded})", "dim")
    return text, any(line.folded for line in lines)


def _round_said(task: Task, views: Views, found: list[Rounds]) -> str:
    """A task's round now (``round 2 of 5``; in a fleet, each vehicle's where they
    differ), "" when it has flown no second round."""
    numbers = [r.now.get(task.path_name, 0) for r in found]
    if max(numbers, default=0) < 2:
        return ""
    of = f" of {task.repeat}" if task.loop is None and task.repeat > 1 else ""
    if len(set(numbers)) == 1:
        return f"round {numbers[0]}{of}"
    return "rounds " + ", ".join(f"{_vehicle_name(i, views)}: {n or '-'}"
                                 for i, n in enumerate(numbers)) + of


def _earlier_said(path: str, views: Views, found: list[Rounds]) -> str:
    """Whose state of a task is from an earlier round (``round 1``; in a fleet, the
    vehicles), "" when none is."""
    stale = [i for i, r in enumerate(found) if path in r.earlier
             and views[i][0].task_states.get(path, TaskState.PENDING) is not TaskState.PENDING]
    if not stale:
        return ""
    if len(views) == 1:
        number = found[0].earlier[path]
        return f"round {number}" if number else "an earlier round"
    return "earlier round: " + ", ".join(_vehicle_name(i, views) for i in stale)


def _plan_root(mission: Mission, task: Task) -> bool:
    """Whether ``task`` is the top of a ``dispatch="mission"`` plan (its parent flies with
    commands)."""
    parent = _parent(mission, task)
    return task.dispatch is Dispatch.MISSION and (
        parent is None or parent.dispatch is not Dispatch.MISSION)


def _parent(mission: Mission, task: Task) -> Task | None:
    if len(task.path) < 2:
        return None
    return next((t for t in mission.walk() if t.path == task.path[:-1]), None)


GPS_FIXES = ("no GPS", "no fix", "2D", "3D", "DGPS", "RTK float", "RTK fixed", "static",
             "PPP")
"""GPS_FIX_TYPE by number, as the view names it."""


def _figure(value: float, digits: int = 1, sign: bool = False) -> str:
    """A number as shown: never a negative zero (``-0.0`` is ``0.0``)."""
    if round(value, digits) == 0:
        value = 0.0
    return f"{value:+.{digits}f}" if sign else f"{value:.{digits}f}"


def _bar(progress: float | None, width: int = 10) -> str:
    if progress is None:
        return ""
    filled = round(max(0.0, min(1.0, progress)) * width)
    return "█" * filled + "░" * (width - filled) + f" {progress:4.0%}"


SEPARATOR = "  "
"""Between two figures of a vehicle's lines."""


def _who(index: int, views: Views) -> str:
    view, state = views[index]
    number = state.vehicle_id if state is not None else index + 1
    return f"vehicle {number}" + (f" ({_safe(view.role)})" if view.role else "")


def _status(view: View, state: VehicleState | None) -> list[tuple[str, str]]:
    """How the vehicle stands: mode and armed, link, battery, GPS (the least needed last)."""
    if state is None:
        return [("no telemetry yet", "dim")]
    found: list[tuple[str, str]] = []
    if view.status.value != "running":
        found.append((view.status.value, "bold"))
    found.append((f"{_safe(state.mode) or '-'} " + ("armed" if state.armed else "disarmed"),
                  "bold" if state.armed else ""))
    found.append((f"link {state.link}", "" if state.link == "ok" else
                  "yellow" if state.link == "degraded" else "bold red"))
    volts = "" if state.voltage is None else f"{_figure(state.voltage)} V "
    percent = "-" if state.battery is None else f"{state.battery:.0f}%"
    found.append((f"batt {volts}{percent}", "red" if state.battery is not None
                  and state.battery < 20 else ""))
    if state.gps_fix is None:
        gps = "GPS -"
    else:
        fix = GPS_FIXES[state.gps_fix] if 0 <= state.gps_fix < len(GPS_FIXES) \
            else str(state.gps_fix)
        gps = f"GPS {fix}" + ("" if state.satellites is None else f" {state.satellites} sat")
    found.append((gps, "yellow" if (state.gps_fix or 0) < 3 else ""))
    return found


def _motion(state: VehicleState | None) -> list[tuple[str, str]]:
    """Where the vehicle is and how it moves: metres from home, climb rate, distance to
    home, ground speed, heading (the least needed last)."""
    if state is None:
        return []
    position = state.position
    where = "n - e - up - m" if position is None else (
        f"n {_figure(position[0])} e {_figure(position[1])} up {_figure(position[2])} m")
    home = state.home_distance
    return [(where, ""), (f"climb {_figure(state.climb, sign=True)} m/s", ""),
            (f"home {'-' if home is None else _figure(home)} m", ""),
            (f"speed {_figure(state.ground_speed)} m/s", ""),
            (f"hdg {round(state.heading) % 360}°" if state.heading_known else "hdg -", "")]


def _work(mission: Mission, view: View, state: VehicleState | None) -> str:
    """What the vehicle does: the item of an autopilot plan, the action and its task (an
    event handler's action: the event)."""
    action = view.current_action or "-"
    if view.held and view.events:
        action += f" (event {view.events[-1][1]!r})"
    elif view.current_task:
        action += f" ({view.current_task.rsplit('/', 1)[-1]})"
        said = state.mission if state is not None else None
        if _in_plan(mission, view.current_task) and said is not None and said.items:
            action = f"item {said.item}/{said.items} " + action
    return _safe(action)


def _in_plan(mission: Mission, path: str) -> bool:
    """Whether the task ``path`` is flown in a ``dispatch="mission"`` plan."""
    names = tuple(path.split("/"))
    return any(t.dispatch is Dispatch.MISSION for t in mission.walk()
               if t.path == names[:len(t.path)])


def _packed(first: Text, segments: list[tuple[str, str]], width: int, indent: str,
            lines: int | None = None, drop: bool = False) -> list[Text]:
    """``first`` and then the segments, two spaces apart, wrapped onto lines of ``width``
    columns, each further line beginning with ``indent``; with ``lines``, at most that
    many, the last cut short -- or, with ``drop``, the segments that do not fit left out
    (the least needed come last)."""
    found = [first]
    for segment, style in segments:
        line = found[-1]
        gap = SEPARATOR if line.plain.strip() else ""
        if line.cell_len + len(gap) + len(segment) > width and line.plain.strip():
            if lines is None or len(found) < lines:
                found.append(Text(indent))
                line, gap = found[-1], ""
            elif drop:
                continue
        line.append(gap)
        line.append(segment, style)
    for line in found:
        line.no_wrap, line.overflow = True, "ellipsis"
    return found


def _vehicles(mission: Mission, views: Views, width: int, compact: bool) -> Text:
    """A few lines per vehicle: how it stands, how it moves, what it does (``compact``:
    one line each, cut short)."""
    found: list[Text] = []
    indent = "   "
    for index, (view, state) in enumerate(views):
        name = Text(_who(index, views), "bold")
        working = bool(view.current_action) or view.progress is not None
        work = [(text, "") for text in (_bar(view.progress, 4 if compact else 10),
                                        _work(mission, view, state)) if text and working]
        if compact:  # its state, mode and armed, link, charge, altitude, and the work
            short = [segment for segment in _status(view, state)
                     if not segment[0].startswith(("batt ", "GPS "))]
            if state is not None and state.battery is not None:
                short.append((f"{state.battery:.0f}%", ""))
            if state is not None and state.position is not None:
                short.append((f"up {_figure(state.position[2])} m", ""))
            found.extend(_packed(name, short + work, width, indent, lines=1))
            continue
        status, motion = _status(view, state), _motion(state)
        together = _packed(name.copy(), status + motion, width, indent)
        if len(together) == 1:  # a wide terminal: how it stands and moves on one line
            found.extend(together)
        else:  # a line each, what does not fit left out
            found.extend(_packed(name, status, width, indent, lines=1, drop=True))
            if motion:
                found.extend(_packed(Text(indent), motion, width, indent, lines=1, drop=True))
        if working:
            found.extend(_packed(Text(indent), [("  ".join(t for t, _ in work), "")], width,
                                 indent, lines=1))
    return Text("\n", no_wrap=True, overflow="ellipsis").join(found)


def _events(views: Views, shown: int) -> Text:
    fired = sorted((t, index, name) for index, (view, _) in enumerate(views)
                   for t, name in view.events)
    text = Text("events: ", "bold", no_wrap=True, overflow="ellipsis")
    if not fired:
        ended = bool(views) and all(view.status is not Status.RUNNING for view, _ in views)
        text.append("none" if ended else "none yet", "dim")
    for t, index, name in fired[-shown:] if shown > 0 else []:
        who = f": {_who(index, views)}" if len(views) > 1 else ""
        text.append(f"\n  {t:7.1f} s  {_safe(name)}{who}", "magenta")
    if fired and shown < len(fired):
        text.append(f"  ({len(fired)} in all)", "dim")
    return text


MESSAGES_SHOWN = 3
"""Autopilot messages in the view for each vehicle (its latest)."""


def _messages(views: Views, shown: int) -> Text | None:
    """Each vehicle's latest autopilot messages (STATUSTEXT), the worst in colour: one
    vehicle's messages never push another's out. A reason not to arm said disarmed on the
    ground is shown as info (tml.vehicle.shown_severity)."""
    said = [(index, m) for index, (_, state) in enumerate(views) if state is not None
            for m in state.messages[-shown:]] if shown > 0 else []
    if not said:
        return None
    text = Text("autopilot:", "bold", no_wrap=True, overflow="ellipsis")
    for index, message in said:
        severity = message.shown_severity
        style = "red" if severity <= 3 else "yellow" if severity <= 4 else ""
        who = f"{_who(index, views)}: " if len(views) > 1 else ""
        word = SEVERITIES[severity] if 0 <= severity < len(SEVERITIES) else str(severity)
        text.append(f"\n  {who}{word}: {_safe(message.text)}", style)
    return text


def _said_lines(views: Views, shown: int) -> int:
    """Lines the autopilot's messages take (its heading included)."""
    said = sum(min(len(s.messages), shown) for _, s in views if s is not None)
    return 1 + said if said else 0


def _waiting(views: Views) -> Text | None:
    """What vehicles still lack to be ready (before the first task, or lost since): why
    nothing moves."""
    lines = [_safe(f"vehicle {state.vehicle_id}: waiting for {', '.join(missing)}")
             for _, state in views if state is not None
             for missing in [awaiting(state)] if missing]
    return Text("\n".join(lines), "yellow", no_wrap=True, overflow="ellipsis") \
        if lines else None


LEGEND = (("·", "pending"), ("▶", "running"), ("‖", "interrupted"), ("✓", "done"),
          ("↷", "skipped"), ("✗", "failed"), ("■", "aborted"))


def _legend(width: int, folded: bool, shown: set[str]) -> Text:
    """What the marks of the tree say (and, when a task is ``folded``, what (+n) says):
    every mark, spaced out if the line has the room, else closer; on a line too narrow for
    them all, the marks ``shown`` in the tree."""
    text = Text()
    for gap, marks in (("  ", LEGEND), (" ", LEGEND),
                       (" ", tuple(m for m in LEGEND if m[0] in shown))):
        text = Text(no_wrap=True, overflow="ellipsis")
        for mark, state in marks:
            style = HELD[1] if mark == HELD[0] else MARKS[TaskState(state)][1]
            text.append(mark, style)
            text.append(f" {state}{gap}", "dim")
        if folded:
            text.append("(+n) folded", "dim")
        text.rstrip()
        if text.cell_len <= width:
            break
    return text


def _ended(views: Views) -> Text | None:
    """How the mission ended (or why a vehicle stopped), each outcome once: the vehicles
    that share it named together."""
    outcomes: dict[str, list[str]] = {}
    for index, (view, state) in enumerate(views):
        if view.reason:
            number = state.vehicle_id if state is not None else index + 1
            outcomes.setdefault(_safe(view.reason), []).append(str(number))
    if not outcomes:
        return None
    if len(views) == 1:
        said = next(iter(outcomes))
    else:
        said = "; ".join(f"vehicle{'s' if len(ids) > 1 else ''} {', '.join(ids)}: {reason}"
                         for reason, ids in outcomes.items())
    return Text("ended: " + said, "bold", no_wrap=True, overflow="ellipsis")


def _header(mission: Mission, views: Views, wall: str | None) -> Text:
    """The mission's name, its mission time (``-`` before it started) and the clock."""
    started = any(v.started for v, _ in views)
    elapsed = max((v.mission_time for v, _ in views), default=0.0)
    text = Text(f"{_safe(mission.name)}  ", "bold", no_wrap=True, overflow="ellipsis")
    text.append("mission time " + (f"{elapsed:.1f} s" if started else "-"))
    if wall:
        text.append(f"  {wall}", "dim")
    return text


VEHICLE_LINES = 3
"""Lines each vehicle takes at most in the view (fewer when its figures fit fewer)."""


def render(mission: Mission, views: Views, width: int = 160,
           height: int | None = None, wall: str | None = None) -> RenderableType:
    """The whole view for a terminal ``width`` columns wide: header (mission time, and the
    ``wall`` clock when given), task tree and the legend of its marks, each vehicle's
    status, motion and work, what is awaited, the autopilot's messages, events. With a
    ``height``, it fits in that many lines: the messages and events shown shrink to the
    last few, a fleet too large for its lines gets one line a vehicle, and the task tree
    is folded around the running tasks into the lines left."""
    waiting = _waiting(views)
    ended = _ended(views)
    events_shown, messages_shown = EVENTS_SHOWN, MESSAGES_SHOWN
    budget = None
    compact = False
    vehicles = _vehicles(mission, views, width, compact)
    if height is not None:
        small = height < 30
        events_shown = 3 if small else EVENTS_SHOWN
        messages_shown = 1 if small else MESSAGES_SHOWN
        fired = sum(len(v.events) for v, _ in views)
        fixed = 1 + 1 + (len(waiting.plain.splitlines()) if waiting else 0) \
            + (1 if ended else 0) + _said_lines(views, messages_shown) \
            + 1 + min(events_shown, fired)  # header, legend, ..., events
        taken = len(vehicles.plain.splitlines())
        if taken > height // 2 or fixed + taken + 4 > height:
            compact = True  # a fleet too large for its lines: one line each
            vehicles = _vehicles(mission, views, width, compact)
            if fixed + len(views) + 4 > height:
                messages_shown = 0
                fixed -= _said_lines(views, 1)
        budget = max(height - fixed - len(vehicles.plain.splitlines()), 3)
    messages = _messages(views, messages_shown)
    tree, folded = _tree(mission, views, budget)
    parts: list[RenderableType] = [_header(mission, views, wall),
                                   tree, _legend(width, folded, set(tree.plain)), vehicles,
                                   *([waiting] if waiting else []),
                                   *([messages] if messages else []),
                                   _events(views, events_shown),
                                   *([ended] if ended else [])]
    return Group(*parts)


def render_text(mission: Mission, views: Views, width: int = 160,
                height: int | None = None, wall: str | None = None) -> str:
    """The view as plain text (no colours), e.g. for tests and logs."""
    buffer = io.StringIO()
    console = Console(file=buffer, width=width, color_system=None, force_terminal=False)
    console.print(render(mission, views, width, height, wall))
    return buffer.getvalue()


class LiveDisplay:
    """Redraws the view in place on a terminal."""

    def __init__(self, mission: Mission, console: Console | None = None,
                 refresh_per_second: float = 4.0) -> None:
        self.mission = mission
        self.console = console or Console()
        self.period = 1.0 / refresh_per_second
        self._live = Live(console=self.console, auto_refresh=False, transient=False)
        self._last = 0.0
        self.shown: RenderableType | None = None  # the view drawn last

    def __enter__(self) -> LiveDisplay:
        self._live.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._live.stop()

    def update(self, views: Views, force: bool = False) -> None:
        """Redraw, unless the last redraw was less than a refresh period ago."""
        now = time.monotonic()
        if force or now - self._last >= self.period:
            self._last = now
            width, height = self.console.size
            # One line spare: the cursor stays under the view.
            wall = datetime.now().strftime("%H:%M:%S")
            self.shown = render(self.mission, views, width, height - 1, wall)
            self._live.update(self.shown, refresh=True)

    def say(self, message: str) -> None:
        """Print a line above the live view."""
        self._live.console.print(_safe(message), markup=False)


class LineDisplay:
    """Prints one line per task state change and per event, for pipes and log files: each
    change once, in the order it happened (a sub-task's end before its task's, across the
    vehicles of a fleet too), stamped with its mission time."""

    def __init__(self, console: Console | None = None) -> None:
        self.console = console or Console(highlight=False)
        self._printed: dict[int, int] = {}  # how many of each view's changes are printed
        self._shared: set[Change] = set()  # the changes of tasks no vehicle flies, printed
        self._events: set[tuple[int, float, str]] = set()
        self._awaiting: dict[int, tuple[str, ...]] = {}
        self._roles: dict[int, str] = {}  # the role each vehicle flew last

    def __enter__(self) -> LineDisplay:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def _print(self, line: str) -> None:
        self.console.print(_safe(line), markup=False)

    def update(self, views: Views, force: bool = False) -> None:
        """Print what changed since the last update."""
        lines: list[tuple[float, int, str]] = []  # (mission time, order, line)
        for index, (view, vehicle) in enumerate(views):
            if view.role:
                self._roles[index] = view.role
            role = self._roles.get(index, "")
            who = f"vehicle {vehicle.vehicle_id if vehicle else index + 1}" \
                + (f" ({role})" if role else "")
            missing = awaiting(vehicle) if vehicle is not None else ()
            if missing != self._awaiting.get(index, ()):
                self._awaiting[index] = missing
                self._print(f"{who}: waiting for {', '.join(missing)}" if missing
                            else f"{who}: ready")
            for change in view.changes[self._printed.get(index, 0):]:
                if change.vehicle_id is None:  # the same in every vehicle's view: once
                    if change not in self._shared:
                        self._shared.add(change)
                        lines.append((change.time, change.number,
                                      f"{change.task}: {change.state.value}"))
                else:
                    lines.append((change.time, change.number,
                                  f"{who}: {change.task}: {change.state.value}"))
            self._printed[index] = len(view.changes)
            for t, name in view.events:
                if (index, t, name) not in self._events:
                    self._events.add((index, t, name))
                    lines.append((t, 0, f"{who}: event {name!r}"))
        # Each vehicle's view holds its own changes and the fleet's: one order for all,
        # that of the interpreter (an event before what it did at the same time).
        for t, _, line in sorted(lines, key=lambda found: found[:2]):
            self._print(f"[{t:7.1f} s] {line}")

    def say(self, message: str) -> None:
        """Print a line."""
        self._print(message)
