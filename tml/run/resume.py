"""Resuming an interrupted run from its flight log (``tml run --resume LOG``).

A run whose ground station died (killed, crashed, the machine rebooted) leaves its flight
log (:mod:`tml.run.journal`) ending without a ``run ended`` line. :func:`resume_point`
reads it back and says whether this run may go on from it -- refused, with the reason,
when the log is not a flight log, its run ended, it flew another mission file (another
SHA-256) or other vehicles, or its mission has roles -- and where each vehicle's mission
stood (:func:`tml.engine.resume.progress`). The runner then starts each interpreter from
that progress, its request and plan ids following the interrupted run's.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from tml.engine.resume import Fold, Progress
from tml.errors import TmlError
from tml.language.model import Mission
from tml.run.journal import LogUnreadable, read_log


class ResumeRefused(TmlError):
    """The run cannot be resumed from this log; the message says why."""


@dataclass(frozen=True)
class ResumePoint:
    """Where an interrupted run stood: each vehicle's progress, and the next free id."""

    progress: Mapping[int, Progress]
    next_id: int
    system_ids: tuple[int, ...] = ()
    """Each vehicle's MAVLink system id, as the log's first line has them (empty: a log
    written before they were kept)."""


def file_digest(path: str) -> str:
    """The SHA-256 of a mission file, as the ``run`` line of its flight log keeps it."""
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 16), b""):
            digest.update(block)
    return digest.hexdigest()


def read_lines(path: str) -> list[dict[str, Any]]:
    """The lines of a flight log (:func:`tml.run.journal.read_log`: a last line cut short
    by the crash left out); ResumeRefused with the reason when it cannot be read."""
    try:
        return read_log(path).lines
    except LogUnreadable as refused:
        raise ResumeRefused(str(refused)) from None


def resume_point(path: str, mission: Mission, digest: str,
                 vehicles: Sequence[str]) -> ResumePoint:
    """Where the run logged in ``path`` stood, if ``mission`` (whose file has the SHA-256
    ``digest``) on ``vehicles`` (their addresses) may go on from it; ResumeRefused with the
    reason otherwise. The vehicles are numbered 1, 2 ... in the order given."""
    lines = read_lines(path)
    runs = [line for line in lines if line.get("kind") == "run"]
    if not runs or runs[0].get("message") != "run started":
        raise ResumeRefused(f"{path}: not a flight log of tml run (no 'run started' line)")
    first = runs[0]
    ended = next((line for line in reversed(runs) if line.get("message") == "run ended"),
                 None)
    if ended is not None and runs[-1] is ended:
        raise ResumeRefused(f"{path}: the run ended (exit code {ended.get('exit_code')}) at "
                            f"t={ended.get('t')}: nothing to resume")
    if first.get("sha256") != digest:
        raise ResumeRefused(f"{path}: the run flew another mission file "
                            f"({first.get('file')}, SHA-256 {first.get('sha256')}), "
                            f"not {mission.file} (SHA-256 {digest})")
    if list(first.get("connect") or []) != list(vehicles):
        raise ResumeRefused(f"{path}: the run flew the vehicles at "
                            f"{', '.join(first.get('connect') or []) or 'the simulator'}, "
                            f"not {', '.join(vehicles) or 'the simulator'}")
    ids = [vid for vid in first.get("vehicles") or [] if isinstance(vid, int)]
    point = progress_point(lines, mission, ids)
    flown = tuple(sid for sid in first.get("system_ids") or [] if isinstance(sid, int))
    return ResumePoint(point.progress, point.next_id, flown)


def progress_point(lines: Sequence[Mapping[str, Any]], mission: Mission,
                   vehicles: Sequence[int]) -> ResumePoint:
    """Where each of ``vehicles`` (vehicle ids) stood in a run's log ``lines``, and the
    next free request id; ResumeRefused for a mission that cannot go on from a log (one
    with roles). ``tml run --resume`` and ``tml serve``'s continue both go by it."""
    if mission.roles:
        raise ResumeRefused(f"{mission.file}: a mission with roles cannot be resumed")
    fold = Fold()
    for line in lines:
        fold.see(line)
    found = {vid: fold.progress(vid) for vid in vehicles}
    last = max((p.last_id for p in found.values()), default=0)
    return ResumePoint(found, last + 1)
