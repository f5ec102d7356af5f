"""Diagnostics: every problem found in a mission file, and how they are printed.

A diagnostic has a place (file:line:column), a stable code, a severity, a message and a
hint. Three formats: ``human`` (the offending line with a caret under the column),
``json`` (one object per file with the list of diagnostics) and ``github`` (workflow
command annotations, so problems show on the pull request's diff).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from enum import StrEnum

from tml.errors import Location


class Severity(StrEnum):
    """Errors make a file invalid; warnings do so only with ``--strict``."""

    ERROR = "error"
    WARNING = "warning"


@dataclass(frozen=True)
class Diagnostic:
    """One problem in a mission file."""

    location: Location
    code: str
    message: str
    hint: str = ""
    severity: Severity = Severity.ERROR

    @property
    def is_error(self) -> bool:
        """True for errors, False for warnings."""
        return self.severity is Severity.ERROR

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready dictionary."""
        data = asdict(self)
        data.pop("location")
        data["severity"] = self.severity.value
        return {"file": self.location.file, "line": self.location.line,
                "column": self.location.column, **data}


def error(location: Location, code: str, message: str, hint: str = "") -> Diagnostic:
    """An error diagnostic."""
    return Diagnostic(location, code, message, hint, Severity.ERROR)


def warning(location: Location, code: str, message: str, hint: str = "") -> Diagnostic:
    """A warning diagnostic."""
    return Diagnostic(location, code, message, hint, Severity.WARNING)


def sort_key(diagnostic: Diagnostic) -> tuple[str, int, int, str]:
    """Order diagnostics by place, then code."""
    loc = diagnostic.location
    return (loc.file, loc.line, loc.column, diagnostic.code)


def format_human(diagnostic: Diagnostic, sources: Mapping[str, str]) -> str:
    """``file:line:col: error E123: message``, the source line, a caret, and the hint."""
    loc = diagnostic.location
    lines = [f"{loc}: {diagnostic.severity.value} {diagnostic.code}: {diagnostic.message}"]
    text = sources.get(loc.file)
    if text is not None and loc.line >= 1:
        source_lines = text.splitlines()
        if loc.line <= len(source_lines):
            line = source_lines[loc.line - 1].expandtabs(1)
            lines.append(f"  {loc.line:>4} | {line}")
            if loc.column >= 1:
                lines.append(f"       | {' ' * (loc.column - 1)}^")
    if diagnostic.hint:
        lines.append(f"  hint: {diagnostic.hint}")
    return "\n".join(lines)


def _github_data(text: str) -> str:
    """A workflow command's message, escaped as GitHub reads it back."""
    return text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def _github_property(text: str) -> str:
    """A workflow command's property value: ':' and ',' would end it early."""
    return _github_data(text).replace(":", "%3A").replace(",", "%2C")


def format_github(diagnostic: Diagnostic) -> str:
    """A GitHub Actions workflow command that annotates the file at the line."""
    loc = diagnostic.location
    level = "error" if diagnostic.is_error else "warning"
    text = diagnostic.message + (f" ({diagnostic.hint})" if diagnostic.hint else "")
    column = f",col={loc.column}" if loc.column else ""
    return (f"::{level} file={_github_property(loc.file)},line={loc.line}{column},"
            f"title={_github_property(diagnostic.code)}::{_github_data(text)}")


def format_json(results: Iterable[tuple[str, bool, list[Diagnostic]]]) -> str:
    """One JSON document: for each file, whether it is valid and its diagnostics."""
    return json.dumps(
        [{"file": file, "valid": valid, "diagnostics": [d.to_dict() for d in diags]}
         for file, valid, diags in results],
        indent=2,
    )
