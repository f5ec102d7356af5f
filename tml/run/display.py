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
from rich.tree import Tree

from tml.engine import Change, TaskState, View
from tml.language.model import Mission, Task
from tml.vehicle import VehicleState, awaiting

Views = Sequence[tuple[View, VehicleState | None]]

MARKS = {
    TaskState.PENDING: ("·", "dim"), TaskState.RUNNING: ("▶", "bold yellow"),
    TaskState.DONE: ("✓", "green"), TaskState.SKIPPED: ("↷", "cyan"),
    TaskState.FAILED: ("✗", "bold red"), TaskState.ABORTED: ("■", "red"),
}
EVENTS_SHOWN = 6


def _task_label(task: Task, views: Views) -> Text:
    text = Text()
    for view, _ in views:
        mark, style = MARKS[view.task_states.get(task.path_name, TaskState.PENDING)]
        text.append(mark, style)
    text.append(f" {task.name}")
    if task.action is not None:
        text.append(f"  {task.action.name}", "dim")
    return text


def _tree(mission: Mission, views: Views) -> Tree:
    tree = Tree(Text(f"mission {mission.name!r}", "bold"))

    def add(node: Tree, tasks: Sequence[Task]) -> None:
        for task in tasks:
            add(node.add(_task_label(task, views)), task.children)

    add(tree, mission.tasks)
    return tree


def _bar(progress: float | None, width: int = 10) -> str:
    if progress is None:
        return ""
    filled = round(max(0.0, min(1.0, progress)) * width)
    return "█" * filled + "░" * (width - filled) + f" {progress:4.0%}"


def _vehicles(views: Views) -> Table:
    # The tree shows where each task is; the table keeps to one short line per vehicle.
    table = Table(box=None, pad_edge=False, expand=False)
    # Fixed widths for the figures, so that only the action's text is ever cut short.
    roles = any(view.role for view, _ in views)
    if roles:  # a fleet: which role each vehicle flies
        table.add_column("role", no_wrap=True, min_width=4)
    for column, width in (("id", 2), ("status", 9), ("mode", 8), ("n, e, up (m)", 19),
                          ("m/s", 4), ("hdg", 4), ("batt", 4), ("link", 8)):
        table.add_column(column, no_wrap=True, min_width=width)
    table.add_column("progress", no_wrap=True, min_width=15)
    table.add_column("action", no_wrap=True, overflow="ellipsis")
    for view, state in views:
        action = view.current_action or "-"
        if view.current_task:
            action += f" ({view.current_task.rsplit('/', 1)[-1]})"
        position = state.position if state else None
        table.add_row(
            *([view.role or "-"] if roles else []),
            str(state.vehicle_id) if state else "?", view.status.value,
            state.mode if state else "",
            "-" if position is None else
            f"{position[0]:6.1f} {position[1]:6.1f} {position[2]:5.1f}",
            f"{state.ground_speed:4.1f}" if state else "",
            f"{state.heading:3.0f}°" if state else "",
            "-" if state is None or state.battery is None else f"{state.battery:3.0f}%",
            state.link if state else "", _bar(view.progress), action)
    return table


def _events(views: Views) -> Text:
    fired = sorted((t, index, name) for index, (view, _) in enumerate(views)
                   for t, name in view.events)
    text = Text("events: ", "bold")
    if not fired:
        text.append("none yet", "dim")
    for t, index, name in fired[-EVENTS_SHOWN:]:
        state = views[index][1]
        who = f" (vehicle {state.vehicle_id})" if len(views) > 1 and state is not None else ""
        text.append(f"\n  {t:7.1f} s  {name}{who}", "magenta")
    return text


def _waiting(views: Views) -> Text | None:
    """What vehicles still lack to be ready (before the first task, or lost since)."""
    lines = [f"vehicle {state.vehicle_id}: waiting for {', '.join(missing)}"
             for _, state in views if state is not None
             for missing in [awaiting(state)] if missing]
    return Text("\n".join(lines), "yellow") if lines else None


def render(mission: Mission, views: Views) -> RenderableType:
    """The whole view: header, task tree, vehicles, what is awaited, events."""
    header = Text(f"{mission.name}  t = {max((v.mission_time for v, _ in views), default=0):.1f} s",
                  "bold")
    reasons = [v.reason for v, _ in views if v.reason]
    waiting = _waiting(views)
    parts: list[RenderableType] = [header, _tree(mission, views), _vehicles(views),
                                   *([waiting] if waiting else []), _events(views)]
    if reasons:
        parts.append(Text("ended: " + "; ".join(reasons), "bold"))
    return Group(*parts)


def render_text(mission: Mission, views: Views, width: int = 160) -> str:
    """The view as plain text (no colours), e.g. for tests and logs."""
    text = io.StringIO()
    console = Console(file=text, width=width, color_system=None, force_terminal=False)
    console.print(render(mission, views))
    return text.getvalue()


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
            self._live.update(render(self.mission, views), refresh=True)

    def say(self, message: str) -> None:
        """Print a line above the live view."""
        self._live.console.print(message)


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

    def update(self, views: Views, force: bool = False) -> None:
        """Print what changed since the last update."""
        for index, (view, vehicle) in enumerate(views):
            who = f"vehicle {vehicle.vehicle_id if vehicle else index + 1}" \
                + (f" ({view.role})" if view.role else "")
            missing = awaiting(vehicle) if vehicle is not None else ()
            if missing != self._awaiting.get(index, ()):
                self._awaiting[index] = missing
                self.console.print(f"{who}: waiting for {', '.join(missing)}" if missing
                                   else f"{who}: ready")
            for change in view.changes[self._printed.get(index, 0):]:
                if change.vehicle_id is None:  # the same in every vehicle's view: once
                    if change not in self._shared:
                        self._shared.add(change)
                        self.console.print(f"[{change.time:7.1f} s] {change.task}: "
                                           f"{change.state.value}")
                else:
                    self.console.print(f"[{change.time:7.1f} s] {who}: {change.task}: "
                                       f"{change.state.value}")
            self._printed[index] = len(view.changes)
            for t, name in view.events:
                if (index, t, name) not in self._events:
                    self._events.add((index, t, name))
                    self.console.print(f"[{t:7.1f} s] {who}: event {name!r}")

    def say(self, message: str) -> None:
        """Print a line."""
        self.console.print(message)
