"""Diagnostics: every problem found in a mission file, and how they are printed.

A diagnostic has a place (file:line:column), a stable code, a severity, a message and a
hint. Three formats: ``human`` (the offending line with a caret under the column),
``json`` (one object per file with the list of diagnostics) and ``github`` (workflow
command annotations, so problems show on the pull request's diff).

Everything printed from a file passes through :func:`printable`: control characters and
bidirectional overrides in a quoted line, a name or a file name are shown escaped, so a
file cannot move the cursor, retitle the terminal or reorder what the reader sees. A
file's text is split into lines once however many diagnostics quote it, and a code
repeated in one file is shown :data:`REPEATS_SHOWN` times and then counted, so printing
stays linear in the number of diagnostics.
"""

from __future__ import annotations

import functools
import re
from collections import Counter
from collections.abc import Iterable, Iterator, Mapping
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


_SAID_WITH_A = ("uav", "ugv", "usv", "uni", "use", "usu", "one")
"""Beginnings of words written with a vowel but said with a consonant ("a UAV")."""


def indefinite(noun: str) -> str:
    """``noun`` after its indefinite article: "an altitude", "a latitude", "a UAV"."""
    word = noun.lstrip().lower()
    vowel = word[:1] in ("a", "e", "i", "o", "u") and not word.startswith(_SAID_WITH_A)
    return f"{'an' if vowel else 'a'} {noun}"


def sort_key(diagnostic: Diagnostic) -> tuple[str, int, int, str]:
    """Order diagnostics by place, then code."""
    loc = diagnostic.location
    return (loc.file, loc.line, loc.column, diagnostic.code)


# C0 and C1 control characters but tab and newline, DEL, and the bidirectional embeddings,
# overrides and isolates (U+202A-U+202E, U+2066-U+2069).
_UNPRINTABLE = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")
_UNPRINTABLE_OR_NEWLINE = re.compile(f"{_UNPRINTABLE.pattern}|\n")
_NAMED = {"\n": "\\n", "\r": "\\r"}


def _escape(match: re.Match[str]) -> str:
    char = match.group(0)
    code = ord(char)
    return _NAMED.get(char) or (f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}")


def printable(text: str, newlines: bool = True) -> str:
    """``text`` safe to print to a terminal: control characters (but tab, and newline
    unless ``newlines`` is False) and bidi overrides written as ``\\x1b``, ``\\u202e``."""
    return (_UNPRINTABLE if newlines else _UNPRINTABLE_OR_NEWLINE).sub(_escape, text)


@functools.lru_cache(maxsize=4)
def _source_lines(text: str) -> list[str]:
    # Diagnostics of one file come together: split its text once, not once per diagnostic.
    return text.splitlines()


def format_human(diagnostic: Diagnostic, sources: Mapping[str, str]) -> str:
    """``file:line:col: error E123: message``, the source line, a caret, and the hint."""
    loc = diagnostic.location
    lines = [printable(f"{loc}: {diagnostic.severity.value} {diagnostic.code}: "
                       f"{diagnostic.message}")]
    text = sources.get(loc.file)
    if text is not None and loc.line >= 1:
        source_lines = _source_lines(text)
        if loc.line <= len(source_lines):
            line, column = _quoted(source_lines[loc.line - 1].expandtabs(1), loc.column)
            escaped = printable(line, newlines=False)
            lines.append(f"  {loc.line:>4} | {escaped}")
            if column >= 1:
                # The caret stands under the column: count what escaping added before it.
                shift = len(printable(line[:column - 1], newlines=False))
                lines.append(f"       | {' ' * shift}^")
    if diagnostic.hint:
        lines.append(printable(f"  hint: {diagnostic.hint}"))
    return "\n".join(lines)


QUOTE_WIDTH = 120
"""Characters of a source line quoted at most: a longer line is cut around the column."""


def _quoted(line: str, column: int) -> tuple[str, int]:
    """The part of ``line`` to quote and the column in it: a line of a whole file written
    on one line would otherwise be printed whole with each of its diagnostics."""
    if len(line) <= QUOTE_WIDTH:
        return line, column
    start = max(0, min(column - 1 - QUOTE_WIDTH // 2, len(line) - QUOTE_WIDTH))
    end = start + QUOTE_WIDTH
    head = "…" if start else ""
    tail = "…" if end < len(line) else ""
    return head + line[start:end] + tail, column - start + len(head) if column >= 1 else 0


def _github_data(text: str) -> str:
    """A workflow command's message, escaped as GitHub reads it back."""
    return text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def _github_property(text: str) -> str:
    """A workflow command's property value: ':' and ',' would end it early."""
    return _github_data(text).replace(":", "%3A").replace(",", "%2C")


REPEATS_SHOWN = 20
"""Diagnostics of one code in one file shown in human form before the rest are counted."""


def format_human_all(diagnostics: Iterable[Diagnostic],
                     sources: Mapping[str, str]) -> Iterator[str]:
    """Each diagnostic as :func:`format_human` prints it, the first :data:`REPEATS_SHOWN` of
    each code in each file; then, for a code with more, one line saying how many more."""
    counts: Counter[tuple[str, str]] = Counter()
    for diagnostic in diagnostics:
        key = (diagnostic.location.file, diagnostic.code)
        counts[key] += 1
        if counts[key] <= REPEATS_SHOWN:
            yield format_human(diagnostic, sources)
    for (file, code), count in counts.items():
        if count > REPEATS_SHOWN:
            yield printable(f"{file}: and {count - REPEATS_SHOWN} more {code} not shown "
                            f"({count} in all)")


def format_github(diagnostic: Diagnostic) -> str:
    """A GitHub Actions workflow command that annotates the file at the line."""
    loc = diagnostic.location
    level = "error" if diagnostic.is_error else "warning"
    text = diagnostic.message + (f" ({diagnostic.hint})" if diagnostic.hint else "")
    column = f",col={loc.column}" if loc.column else ""
    return printable(f"::{level} file={_github_property(loc.file)},line={loc.line}{column},"
                     f"title={_github_property(diagnostic.code)}::{_github_data(text)}",
                     newlines=False)


def format_json(results: Iterable[tuple[str, bool, list[Diagnostic]]]) -> str:
    """One JSON document: for each file, whether it is valid and its diagnostics."""
    import json  # here: only this output needs it, so start-up does without

    return json.dumps(
        [{"file": file, "valid": valid, "diagnostics": [d.to_dict() for d in diags]}
         for file, valid, diags in results],
        indent=2,
    )
