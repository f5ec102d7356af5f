"""How a verification report is printed: a rich table per action, or one JSON document."""

from __future__ import annotations

import json
import math

from rich.console import Console
from rich.table import Table

from tml.verify.static import Report


def _cell(value: float, digits: int = 1) -> str:
    return "-" if math.isinf(value) else f"{value:.{digits}f}"


def print_report(report: Report, console: Console) -> None:
    """The table of predicted actions, the notes, the violations and the verdict."""
    table = Table(title=f"{report.file} with profile {report.profile.name}")
    table.add_column("line", justify="right", no_wrap=True)
    table.add_column("task", overflow="fold", min_width=16)
    table.add_column("action", no_wrap=True)
    for heading in ("distance m", "time s", "battery %", "clearance m"):
        table.add_column(heading, justify="right", no_wrap=True)
    for row in report.rows:
        task = f"event {row.event}" if row.event else row.task
        table.add_row(str(row.line), task, row.action, _cell(row.distance),
                      _cell(row.duration), _cell(row.battery), _cell(row.clearance))
    console.print(table)
    for note in report.notes:
        console.print(f"note: {note}", markup=False, highlight=False)
    if report.approximate:
        console.print("note: too many alternative ways through the mission; the ones with "
                      "the least battery were kept", highlight=False)
    for violation in report.violations:
        where = f" (in {violation.task})" if violation.task else ""
        console.print(f"{violation}{where}", markup=False, highlight=False)
    end = report.end
    summary = f", ends after {end.time:.1f} s with {end.battery:.1f}% battery" if end else ""
    verdict = "feasible" if report.feasible else \
        f"INFEASIBLE: {len(report.violations)} constraint(s) broken"
    console.print(f"{report.file}: {verdict}{summary}", markup=False, highlight=False)


def report_json(report: Report) -> str:
    """The report as one JSON document (see docs/verify.md for its fields)."""
    end = report.end
    return json.dumps({
        "file": report.file,
        "profile": report.profile.name,
        "feasible": report.feasible,
        "approximate": report.approximate,
        "actions": [row.to_dict() for row in report.rows],
        "violations": [v.to_dict() | {"task": v.task} for v in report.violations],
        "notes": report.notes,
        "end": None if end is None else {
            "position": [round(v, 3) for v in end.position], "battery": round(end.battery, 3),
            "time": round(end.time, 3), "flying": end.flying},
    }, indent=2)
