"""The map tiles of the page of ``tml serve``: an MBTiles file, a tile URL, or none.

Theory of operation
-------------------
The page draws its map over raster tiles when the operator names a source:

- ``--tiles FILE.mbtiles``: the MBTiles specification's SQLite file (a ``tiles`` table of
  ``zoom_level``, ``tile_column``, ``tile_row``, ``tile_data`` and a ``metadata`` table of
  names and values). The service serves its tiles itself at ``/tiles/{z}/{x}/{y}.png``, so
  that the page works with no network. MBTiles rows count from the south (TMS) while the
  page asks by XYZ (rows from the north, as Leaflet and every web map do): row = 2^z - 1 - y.
  The file is checked when the service starts (:func:`open_mbtiles`): one that is not
  SQLite, has no ``tiles`` table, holds no tile, or holds vector tiles (``format`` pbf, or
  tile data that is not PNG, JPEG or WebP) is refused with the reason, and the service does
  not start. It is read read-only, one connection per request (SQLite's own locking), so
  the operator's file is never changed.
- ``--tile-url TEMPLATE`` (with ``--tile-attribution``): a tile server the browser asks
  itself (``https://tiles.example.org/{z}/{x}/{y}.png``); the page's Content-Security-Policy
  lets images come from that one origin besides the service (:mod:`tml.serve.guard`).

What the page needs to know is :meth:`TileSource.description` (``GET /tiles``).
Attributions are plain text: the tags of an MBTiles file's HTML attribution are taken out.
"""

from __future__ import annotations

import re
import sqlite3
from contextlib import closing
from dataclasses import dataclass
from html.parser import HTMLParser
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from tml.errors import TmlError

# The first bytes of each raster format a browser shows, and its media type.
SIGNATURES = ((b"\x89PNG\r\n\x1a\n", "image/png"), (b"\xff\xd8\xff", "image/jpeg"),
              (b"RIFF", "image/webp"))
RASTER_FORMATS = {"png", "jpg", "jpeg", "webp"}


class TilesError(TmlError):
    """A tile source that cannot be used: says which and why."""


@dataclass(frozen=True)
class TileSource:
    """Where the page's tiles come from. ``mbtiles``: the file the service serves them from;
    ``url``: the template the browser asks instead; neither: no tiles (the page draws the
    map in metres on a grid)."""

    mbtiles: Path | None = None
    url: str | None = None
    attribution: str = ""
    min_zoom: int = 0
    max_zoom: int = 19
    bounds: tuple[float, float, float, float] | None = None  # west, south, east, north

    def description(self) -> dict[str, Any]:
        """What the page reads from ``GET /tiles``."""
        if self.mbtiles is None and self.url is None:
            return {"source": None}
        return {"source": "mbtiles" if self.mbtiles else "url",
                "url": "/tiles/{z}/{x}/{y}" if self.mbtiles else self.url,
                "attribution": self.attribution, "minzoom": self.min_zoom,
                "maxzoom": self.max_zoom, "bounds": self.bounds}

    def origin(self) -> str | None:
        """The origin (scheme://host:port) the browser fetches tiles from, when it is not the
        service: the one the Content-Security-Policy allows for images."""
        if self.url is None:
            return None
        parts = urlsplit(self.url)
        return f"{parts.scheme}://{parts.netloc}"

    def tile(self, z: int, x: int, y: int) -> tuple[bytes, str] | None:
        """The tile at zoom ``z``, column ``x``, row ``y`` counted from the north (XYZ), and
        its media type; None when the file has none there. Raises sqlite3.Error when the
        file cannot be read any more."""
        if self.mbtiles is None or not (0 <= x < 2 ** z and 0 <= y < 2 ** z):
            return None
        with closing(_connect(self.mbtiles)) as database:
            found = database.execute(
                "SELECT tile_data FROM tiles WHERE zoom_level = ? AND tile_column = ? AND "
                "tile_row = ?", (z, x, 2 ** z - 1 - y)).fetchone()
        if found is None or not isinstance(found[0], bytes):
            return None
        return found[0], _media_type(found[0]) or "application/octet-stream"


def tile_url(template: str, attribution: str = "") -> TileSource:
    """The source of ``--tile-url``: an http(s) URL with {z}, {x} and {y}."""
    parts = urlsplit(template)
    if parts.scheme not in ("http", "https") or not parts.netloc:
        raise TilesError(f"--tile-url {template!r}: expected an http:// or https:// URL, "
                         "e.g. https://tiles.example.org/{z}/{x}/{y}.png")
    missing = [name for name in ("{z}", "{x}", "{y}") if name not in template]
    if missing:
        raise TilesError(f"--tile-url {template!r}: the URL has no {', '.join(missing)}: "
                         "the page puts the zoom, column and row of each tile there")
    if re.search(r"[\s\"'<>\\]", template):
        raise TilesError(f"--tile-url {template!r}: spaces, quotes, <, > and \\ are not "
                         "taken in the URL")
    return TileSource(url=template, attribution=attribution.strip())


def open_mbtiles(path: Path) -> TileSource:
    """The source of ``--tiles``: ``path`` checked (see the module docstring); raises
    TilesError saying why it cannot be used."""
    where = f"--tiles {path}"
    if not path.is_file():
        raise TilesError(f"{where}: no such file")
    with path.open("rb") as file:
        head = file.read(16)
    if not head:
        raise TilesError(f"{where}: the file is empty: expected an MBTiles file (SQLite)")
    if head != b"SQLite format 3\x00":
        raise TilesError(f"{where}: not an MBTiles file: it is not an SQLite database")
    try:
        with closing(_connect(path)) as database:
            names = {row[0] for row in database.execute(
                "SELECT name FROM sqlite_master WHERE type IN ('table', 'view')")}
            if "tiles" not in names:
                raise TilesError(f"{where}: not an MBTiles file: it has no 'tiles' table")
            metadata = dict(database.execute("SELECT name, value FROM metadata").fetchall()
                            ) if "metadata" in names else {}
            zooms = database.execute(
                "SELECT MIN(zoom_level), MAX(zoom_level) FROM tiles").fetchone()
            sample = database.execute("SELECT tile_data FROM tiles LIMIT 1").fetchone()
    except sqlite3.Error as error:
        raise TilesError(f"{where}: the file cannot be read as MBTiles: {error}") from None
    kind = str(metadata.get("format", "")).strip().lower()
    gzipped = sample is not None and isinstance(sample[0], bytes) and \
        sample[0].startswith(b"\x1f\x8b")  # vector tiles are stored gzipped
    if kind == "pbf" or gzipped:
        raise TilesError(f"{where}: it holds vector tiles (pbf): the page shows "
                         "raster tiles (PNG, JPEG, WebP); make a raster MBTiles file "
                         "(docs/serve.md)")
    if kind and kind not in RASTER_FORMATS:
        raise TilesError(f"{where}: its tiles are {kind!r}: the page shows PNG, JPEG or "
                         "WebP tiles")
    if sample is None or zooms[0] is None:
        raise TilesError(f"{where}: the file holds no tile")
    if not isinstance(sample[0], bytes) or _media_type(sample[0]) is None:
        raise TilesError(f"{where}: its tiles are not PNG, JPEG or WebP images: the page "
                         "shows raster tiles")
    return TileSource(mbtiles=path, attribution=_plain_text(str(metadata.get(
        "attribution", ""))), min_zoom=int(zooms[0]), max_zoom=int(zooms[1]),
        bounds=_bounds(str(metadata.get("bounds", ""))))


def _connect(path: Path) -> sqlite3.Connection:
    """A read-only connection to ``path`` (never writing the operator's file)."""
    return sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)


def _media_type(data: bytes) -> str | None:
    for signature, media_type in SIGNATURES:
        if data.startswith(signature) and (media_type != "image/webp" or data[8:12] == b"WEBP"):
            return media_type
    return None


def _bounds(text: str) -> tuple[float, float, float, float] | None:
    """The metadata's bounds (west,south,east,north in degrees), or None when unreadable."""
    try:
        west, south, east, north = (float(v) for v in text.split(","))
    except ValueError:
        return None
    if -180 <= west < east <= 180 and -90 <= south < north <= 90:
        return west, south, east, north
    return None


class _Text(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.parts: list[str] = []

    def handle_data(self, data: str) -> None:
        self.parts.append(data)


def _plain_text(html: str) -> str:
    """An attribution's text without its tags (MBTiles allows HTML there)."""
    parser = _Text()
    parser.feed(html)
    parser.close()
    return " ".join("".join(parser.parts).split())
