"""The task tree folded to a number of lines, around the tasks being flown.

A mission of a hundred tasks does not fit a terminal of 24 lines. :func:`fold` keeps what
tells where the mission is: every task on the way down to a task being flown (its
ancestors), and the tasks next to each of them, as many as the lines allow (twelve on
each side, then eleven ... none); each run of tasks left out becomes one line that says
how many it stands for. A task shown that is not on such a way is shown folded, its
sub-tasks counted with it. When the whole tree fits, nothing is folded; when no task is
being flown (before the first, after the last), the tree is shown level by level, as
deep as fits.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from tml.language.model import Task

RADII = tuple(range(12, -1, -1))
"""Tasks kept on each side of a task on the way to the focus, tried in this order: as
many as fit."""


@dataclass(frozen=True)
class Line:
    """One line of the tree: a task, or (``task`` None) ``hidden`` tasks left out."""

    guide: str  # "│  ├─ ": where the line hangs in the tree
    task: Task | None
    hidden: int = 0  # for a placeholder: how many tasks it stands for
    folded: int = 0  # for a task shown folded: how many sub-tasks it hides


def _size(task: Task) -> int:
    """The task and its sub-tasks (the tree shows no error handlers)."""
    return 1 + sum(_size(child) for child in task.children)


def _every(tasks: Sequence[Task]) -> list[Task]:
    return [t for top in tasks for t in [top, *_every(top.children)]]


def _lines(tasks: Sequence[Task], open_paths: set[tuple[str, ...]], shown: set[int],
           prefix: str = "") -> list[Line]:
    """The lines of ``tasks`` (siblings): those in ``shown`` (by id), runs of the others as
    placeholders; the sub-tasks of a task in ``open_paths`` are laid out the same way."""
    entries: list[tuple[Task | None, int]] = []  # (task, hidden count for a placeholder)
    for sibling in tasks:
        if id(sibling) in shown:
            entries.append((sibling, 0))
        elif entries and entries[-1][0] is None:
            entries[-1] = (None, entries[-1][1] + _size(sibling))
        else:
            entries.append((None, _size(sibling)))
    found: list[Line] = []
    for index, (task, hidden) in enumerate(entries):
        last = index == len(entries) - 1
        guide = prefix + ("└─ " if last else "├─ ")
        if task is None:
            found.append(Line(guide, None, hidden))
            continue
        if task.path in open_paths or not task.children:
            found.append(Line(guide, task))
            found.extend(_lines(task.children, open_paths, shown,
                                prefix + ("   " if last else "│  ")))
        else:
            found.append(Line(guide, task, folded=_size(task) - 1))
    return found


def fold(tasks: Sequence[Task], focus: Sequence[str], budget: int | None) -> list[Line]:
    """The lines of the tree of ``tasks`` in at most ``budget`` lines (None: all), kept
    around the tasks whose paths (``a/b``) are in ``focus``."""
    every = _every(tasks)
    everything = _lines(tasks, {t.path for t in every}, {id(t) for t in every})
    if budget is None or len(everything) <= budget:
        return everything
    wanted = {tuple(path.split("/")) for path in focus if path}
    ways = {path[:i] for path in wanted for i in range(1, len(path) + 1)}
    lines: list[Line] = []
    for radius in RADII if ways else ():
        shown: set[int] = set()
        _near(tasks, ways, radius, shown)
        lines = _lines(tasks, ways, shown)
        if len(lines) <= budget:
            return lines
    if not ways:  # nothing flown now (before the start, after the end): the levels that fit
        lines = _levels(tasks, every, budget)
        if len(lines) <= budget:
            return lines
    # Still too long (a deep tree): the lines nearest the deepest task flown.
    deepest = max(range(len(lines)), key=lambda i: (
        lines[i].task is not None and lines[i].task.path in ways,  # type: ignore[union-attr]
        len(lines[i].guide)))
    start = max(0, min(deepest - budget // 2, len(lines) - budget + 1))
    kept = lines[start:start + max(budget - 1, 1)]
    cut = len(lines) - len(kept)
    mark = Line("", None, cut)
    return [mark, *kept] if start > 0 else [*kept, mark]


def _levels(tasks: Sequence[Task], every: list[Task], budget: int) -> list[Line]:
    """The tree down to the deepest level that fits in ``budget`` lines, the tasks of that
    level folded (at least the top level)."""
    lines = _lines(tasks, set(), {id(t) for t in tasks})
    for depth in range(2, max((len(t.path) for t in every), default=1) + 1):
        deeper = _lines(tasks, {t.path for t in every if len(t.path) < depth},
                        {id(t) for t in every if len(t.path) <= depth})
        if len(deeper) > budget:
            break
        lines = deeper
    return lines


def _near(tasks: Sequence[Task], ways: set[tuple[str, ...]], radius: int,
          shown: set[int]) -> None:
    """Mark (by id) the tasks on the ways and those within ``radius`` of one."""
    on_way = [i for i, t in enumerate(tasks) if t.path in ways]
    for index, task in enumerate(tasks):
        if any(abs(index - i) <= radius for i in on_way):
            shown.add(id(task))
        if task.path in ways:
            _near(task.children, ways, radius, shown)
