"""The terminal view of a run: task tree with states, current action, telemetry, events.

:func:`render` turns the interpreters' views and the vehicles' last states into one rich
renderable; :class:`LiveDisplay` redraws it in place on a terminal (at most
``refresh_per_second`` times a second, however often the runner asks), and
:class:`LineDisplay` prints one line per change (task state, event, end) for logs and pipes,
in the order the changes happened.
"""

from __future__ import annotations

import io
import time
from collections.abc import Sequence

from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.table import Table
from rich.text import Text

from tml.engine import Change, TaskState, View
from tml.language.diagnostics import printable
from tml.language.model import Dispatch, Mission, Task
from tml.run.fold import fold
from tml.vehicle import VehicleState, awaiting

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
EVENTS_SHOWN = 6


def _mark_width(views: Views) -> int:
    """Columns of one vehicle's mark: wide enough for its number over it, in a fleet."""
    if len(views) < 2:
        return 1
    return max(len(_vehicle_name(i, views)) for i in range(len(views))) + 1


def _vehicle_name(index: int, views: Views) -> str:
    state = views[index][1]
    return str(state.vehicle_id if state is not None else index + 1)


def _tree(mission: Mission, views: Views, budget: int | None) -> Text:
    """The task tree, each task with its mark per vehicle, folded to ``budget`` lines."""
    width = _mark_width(views)
    marks_width = width * len(views)
    text = Text(no_wrap=True, overflow="ellipsis")
    text.append(f"mission {_safe(repr(mission.name))}", "bold")
    if len(views) > 1:  # a header over the marks: which vehicle each column is
        text.append("\n" + "".join(_vehicle_name(i, views).rjust(width)
                                    for i in range(len(views))), "bold")
        text.append("  vehicle", "dim")
    focus = [view.current_task for view, _ in views if view.current_task]
    lines = fold(mission.tasks, focus, None if budget is None else max(budget - 1, 1)
                 - (len(views) > 1))
    for line in lines:
        text.append("\n")
        task = line.task
        if task is None:
            text.append(" " * marks_width + " " + line.guide, "dim")
            text.append(f"… {line.hidden} more task{'s' if line.hidden != 1 else ''}", "dim")
            continue
        for view, _ in views:
            mark, style = MARKS[view.task_states.get(task.path_name, TaskState.PENDING)]
            text.append(mark.rjust(width), style)
        text.append(" " + line.guide, "dim")
        text.append(_safe(task.name))
        if task.action is not None:
            text.append(f"  {task.action.name}", "dim")
        if _plan_root(mission, task):
            text.append("  [autopilot mission]", "cyan")
        if line.folded:
            text.append(f"  (+{line.folded})", "dim")
    return text


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


def _plan_items(mission: Mission, path: str) -> int:
    """How many actions the ``dispatch="mission"`` plan holding the task ``path`` flies
    (repeats unrolled; 0 when the task is not in such a plan)."""
    names = tuple(path.split("/"))
    for length in range(1, len(names) + 1):
        task = next((t for t in mission.walk() if t.path == names[:length]), None)
        if task is not None and task.dispatch is Dispatch.MISSION:
            return _terminal_count(task)
    return 0


def _terminal_count(task: Task) -> int:
    inside = 1 if task.is_terminal else sum(_terminal_count(c) for c in task.children)
    return task.repeat * inside


def _bar(progress: float | None, width: int = 10) -> str:
    if progress is None:
        return ""
    filled = round(max(0.0, min(1.0, progress)) * width)
    return "█" * filled + "░" * (width - filled) + f" {progress:4.0%}"


WIDE = 120
"""Terminal columns from which the table has every column at full width."""


def _vehicles(mission: Mission, views: Views, width: int) -> Table:
    # The tree shows where each task is; the table keeps to one short line per vehicle. At
    # 80 columns the figures keep fixed narrow widths and only the action is cut short.
    wide = width >= WIDE
    table = Table(box=None, pad_edge=False, expand=False, collapse_padding=True)
    roles = any(view.role for view, _ in views)
    if roles:  # a fleet: which role each vehicle flies
        table.add_column("role", no_wrap=True, max_width=12 if wide else 8,
                         overflow="ellipsis")
    columns = [("id", 2), *([("status", 9)] if wide else []), ("mode", 9 if wide else 7),
               ("n, e, up (m)", 19 if wide else 15), ("m/s", 4), ("hdg", 4), ("batt", 4),
               ("link", 8 if wide else 4)]
    for column, size in columns:
        table.add_column(column, no_wrap=True, min_width=size, max_width=size,
                         overflow="ellipsis")
    progress = 15 if wide else 9
    table.add_column("progress", no_wrap=True, min_width=progress, max_width=progress)
    # The action has what is left of the line (a column wider than that would be dropped).
    used = sum(size + 1 for _, size in columns) + progress + 1 + ((12 if wide else 8) + 1
                                                                   if roles else 0)
    table.add_column("action", no_wrap=True, overflow="ellipsis",
                     max_width=max(width - used - 1, 8))
    for view, state in views:
        action = view.current_action or "-"
        if view.current_task:
            action += f" ({view.current_task.rsplit('/', 1)[-1]})"
            items = _plan_items(mission, view.current_task)
            if items and state is not None and state.mission is not None:
                action = f"item {state.mission.action_index + 1}/{items} " + action
        action = _safe(action)
        if view.status.value != "running":
            action = f"{view.status.value}: {action}" if not wide else action
        position = state.position if state else None
        link = state.link if state else ""
        table.add_row(
            *([Text(_safe(view.role or "-"))] if roles else []),
            str(state.vehicle_id) if state else "?",
            *([view.status.value] if wide else []),
            Text(_safe(state.mode)) if state else "",
            "-" if position is None else
            f"{position[0]:.0f} {position[1]:.0f} {position[2]:.0f}" if not wide else
            f"{position[0]:6.1f} {position[1]:6.1f} {position[2]:5.1f}",
            f"{state.ground_speed:4.1f}" if state else "",
            f"{state.heading:3.0f}°" if state else "",
            "-" if state is None or state.battery is None else f"{state.battery:3.0f}%",
            link if wide or link != "degraded" else "degr",
            _bar(view.progress, 10 if wide else 4), Text(action))
    return table


def _events(views: Views, shown: int) -> Text:
    fired = sorted((t, index, name) for index, (view, _) in enumerate(views)
                   for t, name in view.events)
    text = Text("events: ", "bold", no_wrap=True, overflow="ellipsis")
    if not fired:
        text.append("none yet", "dim")
    for t, index, name in fired[-shown:] if shown > 0 else []:
        state = views[index][1]
        who = f" (vehicle {state.vehicle_id})" if len(views) > 1 and state is not None else ""
        text.append(f"\n  {t:7.1f} s  {_safe(name)}{who}", "magenta")
    if fired and shown < len(fired):
        text.append(f"  ({len(fired)} in all)", "dim")
    return text


MESSAGES_SHOWN = 3
"""Autopilot messages in the view (the latest, of every vehicle)."""


def _messages(views: Views, shown: int) -> Text | None:
    """The autopilot's latest messages (STATUSTEXT), worst first in colour."""
    said = [(state.vehicle_id, m) for _, state in views if state is not None
            for m in state.messages]
    if not said or shown <= 0:
        return None
    text = Text("autopilot:", "bold", no_wrap=True, overflow="ellipsis")
    for vid, message in said[-shown:]:
        style = "red" if message.severity <= 3 else "yellow" if message.severity <= 4 else ""
        who = f"vehicle {vid}: " if len(views) > 1 else ""
        text.append(f"\n  {who}{message.severity_name}: {_safe(message.text)}", style)
    return text


def _waiting(views: Views) -> Text | None:
    """What vehicles still lack to be ready (before the first task, or lost since): why
    nothing moves."""
    lines = [_safe(f"vehicle {state.vehicle_id}: waiting for {', '.join(missing)}")
             for _, state in views if state is not None
             for missing in [awaiting(state)] if missing]
    return Text("\n".join(lines), "yellow", no_wrap=True, overflow="ellipsis") \
        if lines else None


def render(mission: Mission, views: Views, width: int = 160,
           height: int | None = None) -> RenderableType:
    """The whole view for a terminal ``width`` columns wide: header, task tree, vehicles,
    what is awaited, the autopilot's messages, events. With a ``height``, it fits in that
    many lines: the events and messages shown shrink to their last few, and the task tree
    is folded around the running tasks into the lines left."""
    elapsed = max((v.mission_time for v, _ in views), default=0)
    header = Text(f"{_safe(mission.name)}  t = {elapsed:.1f} s", "bold", no_wrap=True,
                  overflow="ellipsis")
    reasons = [_safe(v.reason) for v, _ in views if v.reason]
    waiting = _waiting(views)
    events_shown, messages_shown = EVENTS_SHOWN, MESSAGES_SHOWN
    budget = None
    if height is not None:
        fixed = 1 + (1 + len(views)) + (len(waiting.plain.splitlines()) if waiting else 0) \
            + (1 if reasons else 0)
        events_shown = 3 if height < 30 else EVENTS_SHOWN
        messages_shown = 2 if height < 30 else MESSAGES_SHOWN
        fired = sum(len(v.events) for v, _ in views)
        said = sum(len(s.messages) for _, s in views if s is not None)
        extra = 1 + min(events_shown, fired) + (1 + min(messages_shown, said) if said else 0)
        budget = max(height - fixed - extra, 3)
    messages = _messages(views, messages_shown)
    parts: list[RenderableType] = [header, _tree(mission, views, budget),
                                   _vehicles(mission, views, width),
                                   *([waiting] if waiting else []),
                                   *([messages] if messages else []),
                                   _events(views, events_shown)]
    if reasons:
        parts.append(Text("ended: " + "; ".join(reasons), "bold", no_wrap=True,
                          overflow="ellipsis"))
    return Group(*parts)


def render_text(mission: Mission, views: Views, width: int = 160,
                height: int | None = None) -> str:
    """The view as plain text (no colours), e.g. for tests and logs."""
    buffer = io.StringIO()
    console = Console(file=buffer, width=width, color_system=None, force_terminal=False)
    console.print(render(mission, views, width, height))
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
            self._live.update(render(self.mission, views, width, height - 1), refresh=True)

    def say(self, message: str) -> None:
        """Print a line above the live view."""
        self._live.console.print(_safe(message), markup=False)


class LineDisplay:
    """Prints one line per task state change and per event, for pipes and log files: each
    change once, in the order it happened (a sub-task's end before its task's)."""

    def __init__(self, console: Console | None = None) -> None:
        self.console = console or Console(highlight=False)
        self._printed: dict[int, int] = {}  # how many of each view's changes are printed
        self._shared: set[Change] = set()  # the changes of tasks no vehicle flies, printed
        self._events: set[tuple[int, float, str]] = set()
        self._awaiting: dict[int, tuple[str, ...]] = {}

    def __enter__(self) -> LineDisplay:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def _print(self, line: str) -> None:
        self.console.print(_safe(line), markup=False)

    def update(self, views: Views, force: bool = False) -> None:
        """Print what changed since the last update."""
        for index, (view, vehicle) in enumerate(views):
            who = f"vehicle {vehicle.vehicle_id if vehicle else index + 1}" \
                + (f" ({view.role})" if view.role else "")
            missing = awaiting(vehicle) if vehicle is not None else ()
            if missing != self._awaiting.get(index, ()):
                self._awaiting[index] = missing
                self._print(f"{who}: waiting for {', '.join(missing)}" if missing
                                   else f"{who}: ready")
            for change in view.changes[self._printed.get(index, 0):]:
                if change.vehicle_id is None:  # the same in every vehicle's view: once
                    if change not in self._shared:
                        self._shared.add(change)
                        self._print(f"[{change.time:7.1f} s] {change.task}: "
                                           f"{change.state.value}")
                else:
                    self._print(f"[{change.time:7.1f} s] {who}: {change.task}: "
                                       f"{change.state.value}")
            self._printed[index] = len(view.changes)
            for t, name in view.events:
                if (index, t, name) not in self._events:
                    self._events.add((index, t, name))
                    self._print(f"[{t:7.1f} s] {who}: event {name!r}")

    def say(self, message: str) -> None:
        """Print a line."""
        self._print(message)
