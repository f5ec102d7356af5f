"""Hardened reading of mission and world files: bytes to an XML tree with exact positions.

Reading is defensive because mission files come from anywhere: the bytes must be UTF-8,
no DOCTYPE is accepted (so no entity expansion, no external entities, no network or file
access from the document), and size and nesting depth are bounded. Each of those problems,
an empty file, or XML that is not well-formed gives one :class:`MissionSyntaxError` that
says where, never a traceback. Only regular files are read (a FIFO would block, a device
such as /dev/zero never end), and no more than the size bound of them: a larger file is
refused by its size before its content is read.

lxml reports an element's line only (and the line of the *end* of its start tag), so the
text is scanned once for start tags in document order; the i-th start tag is the i-th
element, which gives every element and attribute an exact line and column.
"""

from __future__ import annotations

import bisect
import errno
import functools
import itertools
import operator
import os
import re
import stat
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from tml.errors import Location, MissionSyntaxError

MAX_BYTES = 8 * 1024 * 1024
MAX_DEPTH = 64

_MARKUP = re.compile(
    r"<!--.*?-->|<!\[CDATA\[.*?\]\]>|<\?.*?\?>|<!DOCTYPE|<(?P<tag>[A-Za-z_][\w.\-:]*)",
    re.S,
)
_ATTRIBUTE = re.compile(r"""\s+([^\s=/>]+)\s*=\s*(?:"[^"]*"|'[^']*')""")
_IS_TAG = operator.attrgetter("lastgroup")  # a start tag, not a comment, CDATA or PI
_LOCATION = functools.partial(tuple.__new__, Location)  # Location(*fields), in C
_ENCODING_DECL = re.compile(rb"^\s*<\?xml[^>]*encoding\s*=\s*[\"']([^\"']+)[\"']")


ROOT_SCAN_BYTES = 64 * 1024
"""How much of a file :func:`root_name` reads to find its root element."""


def root_name(path: str | Path) -> str | None:
    """The name of a file's root element, read from its start (comments, processing
    instructions and a DOCTYPE skipped); None when the file cannot be read or none is
    found there. Tells mission files from other XML (a ``pom.xml``) without parsing."""
    try:
        descriptor = _open_regular(path)
    except OSError:
        return None  # the reader says why (missing, not a regular file) when it is read
    with os.fdopen(descriptor, "rb") as stream:
        head = stream.read(ROOT_SCAN_BYTES).decode("utf-8", "replace")
    for match in _MARKUP.finditer(head):
        if match.group("tag"):
            return match.group("tag")
    return None


@dataclass
class XmlDocument:
    """A parsed, safe XML document with exact positions of elements and attributes."""

    file: str
    text: str
    root: etree._Element
    # Each element's start tag: its character offset and location (found in one sweep).
    starts: dict[etree._Element, tuple[int, Location]] = field(repr=False)

    @functools.cached_property
    def _line_starts(self) -> list[int]:
        # Only attribute positions need it, and only for files with problems.
        return [0] + [m.end() for m in re.finditer("\n", self.text)]

    def location_of_offset(self, offset: int) -> Location:
        """Line and column (1-based, in characters) of a character offset in the text."""
        index = bisect.bisect_right(self._line_starts, offset) - 1
        return Location(self.file, index + 1, offset - self._line_starts[index] + 1)

    def location(self, element: etree._Element, attribute: str | None = None) -> Location:
        """Where an element's start tag (or one of its attributes) begins."""
        found = self.starts.get(element)
        if found is None:
            return Location(self.file, element.sourceline or 0, 0)
        start, where = found
        if attribute is not None:
            offset = _attribute_offset(self.text, start, attribute)
            if offset is not None:
                return self.location_of_offset(offset)
        return where

    def required(self, element: etree._Element, attribute: str) -> str:
        """The value of an attribute the schema requires; a missing one (a document built
        without passing the schema) is a :class:`MissionSyntaxError` at the element."""
        value = element.get(attribute)
        if value is None:
            raise MissionSyntaxError(
                f"<{element_name(element)}> is missing the required attribute {attribute!r}",
                self.location(element), "E104")
        return value

    def element_at(self, xpath: str) -> etree._Element | None:
        """The element an lxml error path (``/mission/task[2]``) names, if any."""
        try:
            found = self.root.getroottree().xpath(xpath)
        except etree.XPathError:
            return None
        return found[0] if found and isinstance(found[0], etree._Element) else None


def element_name(element: etree._Element) -> str:
    """An element's name; "" for a comment or processing instruction. (lxml types a tag
    wider, as bytes or QName, because a program may set one; a parsed tag is a str.)"""
    name = element.tag
    return name if isinstance(name, str) else ""


_TAG_NAME = re.compile(r"<[A-Za-z_][\w.\-:]*")


def _attribute_offset(text: str, start: int, attribute: str) -> int | None:
    """Offset of ``attribute``'s name in the start tag that begins at ``start``, if written."""
    tag = _TAG_NAME.match(text, start)
    if tag is None:
        return None
    # Walk the start tag attribute by attribute, so that a ">" or a name inside an earlier
    # quoted value is not taken for the end of the tag or for the attribute.
    position = tag.end()
    while match := _ATTRIBUTE.match(text, position):
        if match.group(1) == attribute:
            return match.start(1)
        position = match.end()
    return None


def attribute_location(text: str, element: Location, attribute: str) -> Location:
    """Where ``attribute`` is written in the start tag at ``element`` (the location of its
    ``<`` in ``text``, the whole document); ``element`` itself if the attribute is not there.

    For stages that hold only the model and the source text, such as the semantic checks.
    """
    start = 0
    for _ in range(element.line - 1):
        start = text.find("\n", start) + 1
        if start == 0:
            return element
    offset = _attribute_offset(text, start + element.column - 1, attribute)
    if offset is None:
        return element
    line_start = text.rfind("\n", 0, offset) + 1
    return Location(element.file, element.line + text.count("\n", start, line_start),
                    offset - line_start + 1)


def read_xml(source: str | Path, data: bytes | None = None) -> XmlDocument:
    """Read a file (or ``data`` under the name ``source``) safely into an :class:`XmlDocument`.

    Raises :class:`MissionSyntaxError` (with file:line:column and a code) for empty input,
    input that is too large, not UTF-8, has a DOCTYPE, is not well-formed, or nests too deep.
    """
    file = str(source)
    if data is None:
        data = read_bounded(source)
    start = Location(file, 1, 1)
    if len(data) > MAX_BYTES:
        raise _too_large(file, len(data))
    if not data.strip():
        raise MissionSyntaxError("file is empty; expected a <mission> document", start, "E001")
    text = _decode(file, data)

    def at(offset: int) -> Location:
        line_start = text.rfind("\n", 0, offset) + 1
        return Location(file, text.count("\n", 0, offset) + 1, offset - line_start + 1)

    if "<!DOCTYPE" in text:  # refused unless it is inside a comment, CDATA or a PI
        for match in _MARKUP.finditer(text):
            if match.group(0) == "<!DOCTYPE":
                raise MissionSyntaxError(
                    "DOCTYPE declarations are not accepted (no DTDs or entities in mission "
                    "files)", at(match.start()), "E003")
    # The offset of each start tag, then its line and column: every loop runs in C (a
    # regular expression, the lines' lengths summed, map and zip), none in Python.
    offsets = list(map(re.Match.start, filter(_IS_TAG, _MARKUP.finditer(text))))
    lines = text.split("\n")
    line_starts = [0, *map(operator.add, itertools.accumulate(map(len, lines)),
                           itertools.count(1))]
    numbers = list(map(bisect.bisect_right, itertools.repeat(line_starts), offsets))
    before = [0, *map(operator.sub, line_starts, itertools.repeat(1))]  # line n: before[n]
    columns = map(operator.sub, offsets, map(before.__getitem__, numbers))
    places = map(_LOCATION, zip(itertools.repeat(file), numbers, columns, strict=False))
    tags = zip(offsets, places, strict=True)
    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, dtd_validation=False,
        huge_tree=False, remove_blank_text=False, collect_ids=False,
    )
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        line, column = exc.position if exc.position else (1, 0)
        message = re.sub(r", line \d+, column \d+$", "", exc.msg or "not well-formed")
        raise MissionSyntaxError(f"not well-formed XML: {message}",
                                 Location(file, line, column), "E002") from None
    elements = list(root.iter(etree.Element))
    starts = dict(zip(elements, tags, strict=False)) if len(elements) == len(offsets) else {}
    # The first element MAX_DEPTH deep, in document order, as libxml2 finds it.
    too_deep = _at_depth(MAX_DEPTH)(root)
    if isinstance(too_deep, list) and too_deep and isinstance(too_deep[0], etree._Element):
        element = too_deep[0]
        where = starts.get(element)
        raise MissionSyntaxError(
            f"elements nest {MAX_DEPTH + 1} deep; the limit is {MAX_DEPTH}",
            where[1] if where else Location(file, element.sourceline or 1, 0), "E006")
    return XmlDocument(file, text, root, starts)


@functools.cache
def _at_depth(depth: int) -> etree.XPath:
    """The XPath of the elements ``depth`` deep (the root's is 0), in document order."""
    return etree.XPath("/" + "/".join(["*"] * (depth + 1)))


def read_bounded(source: str | Path) -> bytes:
    """The bytes of a regular file of at most :data:`MAX_BYTES`, read with that bound.

    Raises OSError for a file that cannot be opened or is not a regular file (a FIFO, a
    device, a directory: refused before anything is read, so nothing blocks or runs on), and
    :class:`MissionSyntaxError` E005 for a file over the bound, by its size alone.
    """
    descriptor = _open_regular(source)
    try:
        info = os.fstat(descriptor)
        if info.st_size > MAX_BYTES:
            raise _too_large(str(source), info.st_size)
        with os.fdopen(descriptor, "rb", closefd=False) as stream:
            # Its size and one byte more (a buffer of the bound for every file costs more
            # than reading it), then up to the bound if it has grown since fstat.
            data = stream.read(info.st_size + 1)
            if len(data) > info.st_size:
                data += stream.read(MAX_BYTES + 1 - len(data))
    finally:
        os.close(descriptor)
    if len(data) > MAX_BYTES:
        raise _too_large(str(source), len(data))
    return data


def _open_regular(source: str | Path) -> int:
    """A descriptor open for reading on ``source``; OSError if it is not a regular file."""
    # O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer.
    descriptor = os.open(source, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    if not stat.S_ISREG(os.fstat(descriptor).st_mode):
        os.close(descriptor)
        raise OSError(errno.EINVAL, "not a regular file (a FIFO, device or directory); "
                      "missions are read from regular files", str(source))
    return descriptor


def _too_large(file: str, size: int) -> MissionSyntaxError:
    return MissionSyntaxError(
        f"file is {size} bytes; mission files are limited to {MAX_BYTES} bytes",
        Location(file, 1, 1), "E005")


def _decode(file: str, data: bytes) -> str:
    if data.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in data[:4]:
        raise MissionSyntaxError("file is UTF-16; mission files must be UTF-8",
                                 Location(file, 1, 1), "E004")
    declared = _ENCODING_DECL.match(data)
    if declared and declared.group(1).decode("ascii", "replace").lower() not in (
            "utf-8", "utf8", "us-ascii", "ascii"):
        raise MissionSyntaxError(
            f"file declares encoding {declared.group(1).decode('ascii', 'replace')!r}; "
            "mission files must be UTF-8", Location(file, 1, 1), "E004")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise MissionSyntaxError(
            f"byte 0x{data[exc.start]:02x} is not UTF-8; mission files must be UTF-8",
            Location(file, line, column), "E004") from None
