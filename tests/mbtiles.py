"""MBTiles files for the tests: raster tiles made here (PNG written with zlib), stored as
the MBTiles specification says (rows counted from the south, TMS)."""

from __future__ import annotations

import math
import sqlite3
import struct
import zlib
from collections.abc import Iterable, Mapping
from contextlib import closing
from pathlib import Path

Colour = tuple[int, int, int]
# The colours of the quadrants around a point (quadrant_tiles): far apart, none white.
NORTH_EAST, NORTH_WEST, SOUTH_EAST, SOUTH_WEST = (220, 40, 40), (40, 160, 40), \
    (40, 80, 220), (230, 190, 30)
SIZE = 256


def png(rows: list[list[Colour]]) -> bytes:
    """A PNG image (8-bit RGB) of ``rows`` of pixels, the top row first."""
    height, width = len(rows), len(rows[0])
    data = b"".join(b"\x00" + b"".join(bytes(pixel) for pixel in row) for row in rows)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(
            ">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(
        ">IIBBBBB", width, height, 8, 2, 0, 0, 0)) + chunk(b"IDAT", zlib.compress(data)) + \
        chunk(b"IEND", b"")


def world_pixel(latitude: float, longitude: float, zoom: int) -> tuple[float, float]:
    """Web Mercator: the point's pixel (x east, y south) in the whole world's image at
    ``zoom``, tiles of SIZE pixels, row 0 at the north."""
    scale = SIZE * 2 ** zoom
    phi = math.radians(latitude)
    return ((longitude + 180) / 360 * scale,
            (1 - math.log(math.tan(phi) + 1 / math.cos(phi)) / math.pi) / 2 * scale)


def quadrant_tiles(latitude: float, longitude: float, zooms: Iterable[int],
                   around: int = 1) -> dict[tuple[int, int, int], bytes]:
    """Tiles (zoom, column, row from the north) around a point, coloured by the quadrant
    each pixel is in as seen from the point: north-east, north-west, south-east,
    south-west; ``around`` tiles on each side of the point's tile."""
    tiles = {}
    for zoom in zooms:
        px, py = world_pixel(latitude, longitude, zoom)
        column, row = int(px // SIZE), int(py // SIZE)
        for x in range(column - around, column + around + 1):
            # the pixels of this column of tiles west of the point (centres before px)
            west = min(SIZE, max(0, math.ceil(px - 0.5 - x * SIZE)))
            for y in range(row - around, row + around + 1):
                north = min(SIZE, max(0, math.ceil(py - 0.5 - y * SIZE)))
                tiles[zoom, x, y] = png(
                    [[NORTH_WEST] * west + [NORTH_EAST] * (SIZE - west)] * north +
                    [[SOUTH_WEST] * west + [SOUTH_EAST] * (SIZE - west)] * (SIZE - north))
    return tiles


def write_mbtiles(path: Path, tiles: Mapping[tuple[int, int, int], bytes],
                  metadata: Mapping[str, str] | None = None) -> Path:
    """An MBTiles file of ``tiles`` ((zoom, column, row from the north): data), with rows
    stored from the south, and ``metadata``."""
    with closing(sqlite3.connect(path)) as database, database:
        database.execute("CREATE TABLE metadata (name TEXT, value TEXT)")
        database.execute("CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, "
                         "tile_row INTEGER, tile_data BLOB)")
        database.executemany("INSERT INTO metadata VALUES (?, ?)", list(
            {"name": "test", "format": "png", **(metadata or {})}.items()))
        database.executemany("INSERT INTO tiles VALUES (?, ?, ?, ?)", [
            (z, x, 2 ** z - 1 - y, data) for (z, x, y), data in tiles.items()])
    return path
