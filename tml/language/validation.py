"""The validation pipeline: safe read, XML Schema, model building, semantic checks.

Schema violations stop a file there (the model cannot be built from a document of the
wrong shape); otherwise structural and semantic findings are all reported together.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from tml.errors import Location, MissionError, MissionSemanticError, MissionSyntaxError
from tml.language import build, check, schema, xml
from tml.language.diagnostics import Diagnostic, error, sort_key
from tml.language.model import Mission


@dataclass
class ValidationResult:
    """The outcome of validating one file."""

    file: str
    mission: Mission | None
    diagnostics: list[Diagnostic] = field(default_factory=list)
    source: str = ""

    @property
    def errors(self) -> list[Diagnostic]:
        """The diagnostics that are errors."""
        return [d for d in self.diagnostics if d.is_error]

    def valid(self, strict: bool = False) -> bool:
        """No errors (and, when strict, no warnings either)."""
        return not (self.diagnostics if strict else self.errors)


def validate_file(path: str | Path, data: bytes | None = None,
                  root: str | None = "mission") -> ValidationResult:
    """Validate one mission file (``root="world"``: one world file, whose result holds no
    mission; ``root=None``: a world file when its root element is ``<world>``, else a
    mission); I/O errors (missing file) raise OSError."""
    file = str(path)
    try:
        doc = xml.read_xml(file, data)
    except MissionSyntaxError as exc:
        location = exc.location or Location(file, 1, 1)
        source = "" if exc.code == "E005" else _text_of(path, data)
        hint = _plan_hint(path, data) if exc.code == "E002" else ""
        return ValidationResult(file, None, [error(location, exc.code, exc.message, hint)],
                                source)
    if root is None:  # the name as written, as xml.root_name reads it from the text
        written = etree.QName(doc.root).localname
        if doc.root.prefix:
            written = f"{doc.root.prefix}:{written}"
        root = "world" if written == "world" else "mission"
    problems = schema.validate(doc, root)
    if problems:
        return ValidationResult(file, None, sorted(problems, key=sort_key), doc.text)
    if root == "world":
        _, structural = build.build_world(doc)
        return ValidationResult(file, None, sorted(structural, key=sort_key), doc.text)
    mission, structural = build.build_mission(doc)
    found = structural + check.check(mission)
    return ValidationResult(file, mission, sorted(found, key=sort_key), doc.text)


def load_mission(path: str | Path) -> Mission:
    """A valid mission, or a :class:`MissionError` naming the first error and the count."""
    result = validate_file(path)
    if result.errors or result.mission is None:
        first = result.errors[0]
        more = f" (and {len(result.errors) - 1} more)" if len(result.errors) > 1 else ""
        kind = MissionSyntaxError if first.code < "E200" else MissionSemanticError
        raise kind(first.message + more, first.location, first.code)
    return result.mission


PLAN_SUFFIXES = (".plan", ".waypoints")
"""Suffixes of the plans ``tml import`` reads (QGroundControl's .plan, QGC WPL waypoint
files; a WPL file named .txt is known by its header)."""


def _plan_hint(path: str | Path, data: bytes | None) -> str:
    """For a file that is not XML but looks like a plan ``tml import`` reads (JSON, a QGC
    WPL header, a plan's suffix), the hint to import it; else ""."""
    import shlex

    try:
        raw = data if data is not None else xml.read_bounded(path)
    except (OSError, MissionSyntaxError):
        raw = b""
    start = raw.lstrip(b"\xef\xbb\xbf \t\r\n")
    suffix = Path(path).suffix.lower()
    command = f"tml import {shlex.quote(str(path))} -o " \
        f"{shlex.quote(Path(path).with_suffix('.xml').name)}"
    if start.startswith(b"{") and b'"Plan"' not in raw:
        return f"this is JSON, not a mission; if it is a QGroundControl plan, `{command}` " \
            "makes a mission of it"
    if start.startswith(b"{"):
        what = "a QGroundControl plan"
    elif start.startswith(b"QGC WPL"):
        what = "a QGC WPL waypoint file"
    elif suffix in PLAN_SUFFIXES:
        what = f"a {suffix} file"
    else:
        return ""
    return f"this looks like {what}, not a mission: `{command}` makes a mission of it"


def _text_of(path: str | Path, data: bytes | None) -> str:
    """The text of a file that failed to read as XML, for quoting its lines; "" for a file
    that is not XML at all (a password file, a binary), whose content is never quoted."""
    try:
        raw = data if data is not None else xml.read_bounded(path)
    except (OSError, MissionSyntaxError):
        return ""
    if b"\x00" in raw:  # UTF-16 and binary files: no source line is worth quoting
        return ""
    text = raw.decode("utf-8", "replace")
    return text if text.lstrip("\ufeff \t\r\n").startswith("<") else ""


__all__ = ["MissionError", "ValidationResult", "load_mission", "validate_file"]
