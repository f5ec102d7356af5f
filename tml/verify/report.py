"""How a verification report is printed: a rich table per action, or one JSON document.

A mission that declares roles gets a role column, findings prefixed with the role and its
vehicles, and an end per role; a mission without roles prints as it always has.
"""

from __future__ import annotations

import json
import math

from rich.console import Console
from rich.table import Table
from rich.text import Text

from tml.language.diagnostics import printable
from tml.verify.constraints import Violation
from tml.verify.motion import PredictedState
from tml.verify.static import Report, Row, vehicles_text


def _cell(value: float, digits: int = 1) -> str:
    return "-" if math.isinf(value) else f"{value:.{digits}f}"


def _ground(clearance: float | None) -> str:
    """The lowest clearance above the ground: ``-`` where nothing is judged (on the ground,
    a take-off's climb), ``no data`` where the terrain data does not cover the path."""
    if clearance is None:
        return "-"
    return "no data" if math.isnan(clearance) else _cell(clearance)


def _charge(battery: float) -> str:
    """The battery column: "empty" once the battery has run out, never a negative charge."""
    return "empty" if battery < 0 else _cell(battery)


def _left(end: PredictedState, rows: list[Row]) -> str:
    """``with 40.0% battery``, or where the battery runs out on the way to ``end``."""
    if end.battery >= 0:
        return f"with {end.battery:.1f}% battery"
    out = next((row for row in rows if row.battery < 0), None)
    if out is None:
        return "with the battery empty"
    where = f"event {out.event}" if out.event else out.task
    return f"with the battery empty: it runs out at line {out.line} ({out.action} in {where})"


def _finding(violation: Violation) -> str:
    whose = f"role {violation.role}, {vehicles_text(violation.vehicles)}: " \
        if violation.role else ""
    where = f" (in {violation.task})" if violation.task else ""
    return f"{whose}{violation}{where}"


def _safe(text: str) -> Text:
    """Text from a mission file as it may be printed: control characters and bidi
    overrides escaped (tml.language.diagnostics.printable), brackets not taken for markup."""
    return Text(printable(text, newlines=False))


def print_report(report: Report, console: Console) -> None:
    """The table of predicted actions, the notes, the violations and the verdict."""
    table = Table(title=_safe(f"{report.file} with profile {report.profile.name}"))
    table.add_column("line", justify="right", no_wrap=True)
    table.add_column("task", overflow="fold", min_width=16)
    if report.roles:
        table.add_column("role (vehicles)", no_wrap=True)
    table.add_column("action", no_wrap=True)
    headings = ["distance m", "time s", "battery %", "clearance m"]
    for heading in headings + (["above ground m"] if report.terrain else []):
        table.add_column(heading, justify="right", no_wrap=True)
    for row in report.rows:
        task = f"event {row.event}" if row.event else row.task
        whose = [f"{row.role} ({', '.join(map(str, row.vehicles))})"] if report.roles else []
        ground = [_ground(row.terrain_clearance)] if report.terrain else []
        table.add_row(str(row.line), _safe(task), *map(_safe, whose), row.action,
                      _cell(row.distance),
                      _cell(row.duration), _charge(row.battery), _cell(row.clearance),
                      *ground)
    console.print(table)
    for note in report.notes:
        console.print(_safe(f"note: {note}"), highlight=False)
    if report.approximate:
        console.print("note: too many alternative ways through the mission; the ones with "
                      "the least battery were kept", highlight=False)
    for warning in report.warnings:
        console.print(_safe(f"warning: {warning}"), highlight=False)
    if report.skills:
        console.print(f"skills the vehicle must provide: {', '.join(report.skills)} (tml run "
                      "waits for the component that switches them before take-off)",
                      highlight=False)
    for violation in report.violations:
        console.print(_safe(_finding(violation)), highlight=False)
    verdict = "feasible" if report.feasible else \
        f"INFEASIBLE: {len(report.violations)} constraint(s) broken"
    if report.roles:
        summary = "".join(f"; role {role} ends after {end.time:.1f} s "
                          + _left(end, [r for r in report.rows if r.role == role])
                          for role, end in report.ends.items())
    else:
        end = report.end
        summary = f", ends after {end.time:.1f} s {_left(end, report.rows)}" if end else ""
    console.print(_safe(f"{report.file}: {verdict}{summary}"), highlight=False)


def _end(end: PredictedState | None) -> dict[str, object] | None:
    return None if end is None else {
        "position": [round(v, 3) for v in end.position],
        "battery": round(max(end.battery, 0.0), 3),  # 0: empty, never negative
        "time": round(end.time, 3), "flying": end.flying}


def _violation(violation: Violation) -> dict[str, object]:
    found = violation.to_dict()
    if violation.role:
        found |= {"role": violation.role, "vehicles": list(violation.vehicles)}
    return found


def _above_ground(row: Row, report: Report) -> dict[str, object]:
    """``terrain_clearance`` of an action, when the report was made over terrain data (null
    where nothing is judged or the data does not cover the path)."""
    if not report.terrain:
        return {}
    value = row.terrain_clearance
    return {"terrain_clearance": None if value is None or math.isnan(value)
            else round(value, 3)}


def report_document(report: Report) -> dict[str, object]:
    """The report as plain values (see docs/verify.md for its fields)."""
    document: dict[str, object] = {
        "file": report.file,
        "profile": report.profile.name,
        "feasible": report.feasible,
        "approximate": report.approximate,
        "actions": [row.to_dict() | _above_ground(row, report) for row in report.rows],
        "violations": [_violation(v) for v in report.violations],
        "notes": report.notes,
        "warnings": report.warnings,
        "skills": list(report.skills),
        "end": _end(report.end),
    }
    if report.terrain:
        document["terrain"] = report.terrain
    if report.roles:
        document["ends"] = {role: _end(end) for role, end in report.ends.items()}
    return document


def report_json(report: Report) -> str:
    """The report as one JSON document (see docs/verify.md for its fields)."""
    return json.dumps(report_document(report), indent=2)
