"""The height of the ground, from digital elevation models the operator provides.

Two kinds of file, never fetched (tml has no network access for terrain):

- SRTM ``.hgt`` tiles, the files ArduPilot's terrain generator starts from. A tile covers
  one degree square; its name is its south-west corner (``N35E149.hgt``: 35 to 36 N, 149
  to 150 E; ``S36E149.hgt``: 36 to 35 S). It holds 1201 x 1201 samples (3 arc-second) or
  3601 x 3601 (1 arc-second), big-endian signed 16-bit metres, row by row from the north
  edge, column by column from the west edge; the edge rows and columns are shared with the
  neighbouring tiles. -32768 is a void (no data).
- GeoTIFF rasters in EPSG:4326 (latitude and longitude on WGS84), one band, read with
  tifffile (the optional ``terrain`` extra). Another projection or datum is refused with
  the reason, as are rotated grids; GDAL's nodata value and -32768 are voids.

Vertical datum: heights are metres above the EGM96 geoid, as SRTM's are, as ArduPilot's
terrain data is and as the AMSL altitudes of ``<home>`` and of ``altitude_reference="amsl"``
are. A GeoTIFF that names another vertical datum is refused.

A height between samples is interpolated bilinearly from the four samples around it. A
place outside every tile is an error naming the tile that would hold it; a place whose
four samples include a void is an error too (voids are refused, never filled in: a guess
of the ground is no basis for a clearance).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tml.errors import TerrainError, TerrainNotCovered

Array = npt.NDArray[np.float64]

VOID = -32768
"""SRTM's value for a sample with no data."""

SRTM_SIZES = {1201: 3.0, 3601: 1.0}
"""Samples a side of an SRTM tile -> arc-seconds between samples."""

LOWEST, HIGHEST = -1000.0, 9000.0
"""Heights (m) outside which a sample is not ground on Earth: a tile holding one is corrupt."""

MAX_SAMPLES = 13_000 * 13_000
"""The most samples a GeoTIFF may hold (a 3 x 3 degree mosaic at 1 arc-second is 10801 x
10801): a file claiming more is refused before anything is decompressed."""

METRES_PER_DEGREE = 111_320.0
"""Metres a degree of latitude spans, near enough to space samples along a path."""

_TILE_NAME = re.compile(r"([NS])(\d{2})([EW])(\d{3})$", re.I)
GEOTIFF_SUFFIXES = (".tif", ".tiff")
_EXTRA = "pip install 'tml-flight[terrain]'"


def tile_name(latitude: float, longitude: float) -> str:
    """The SRTM tile that holds a place: ``N35E149.hgt``, ``S36W071.hgt``."""
    south, west = math.floor(latitude), math.floor(longitude)
    return (f"{'N' if south >= 0 else 'S'}{abs(south):02d}"
            f"{'E' if west >= 0 else 'W'}{abs(west):03d}.hgt")


@dataclass(frozen=True, eq=False)
class Tile:
    """One grid of heights: ``samples[0, 0]`` at (``north``, ``west``), rows ``step_lat``
    degrees apart going south, columns ``step_lon`` apart going east."""

    path: str
    north: float
    west: float
    step_lat: float
    step_lon: float
    samples: npt.NDArray[Any]
    nodata: float | None = None

    @property
    def south(self) -> float:
        return self.north - (int(self.samples.shape[0]) - 1) * self.step_lat

    @property
    def east(self) -> float:
        return self.west + (int(self.samples.shape[1]) - 1) * self.step_lon

    def covers(self, latitudes: Array, longitudes: Array) -> npt.NDArray[np.bool_]:
        """Which of the places lie within the tile's samples (edges included)."""
        return ((latitudes >= self.south) & (latitudes <= self.north)
                & (longitudes >= self.west) & (longitudes <= self.east))

    def heights(self, latitudes: Array, longitudes: Array) -> Array:
        """Bilinear heights at places the tile covers; NaN where a sample used is a void."""
        rows, cols = self.samples.shape
        y = (self.north - latitudes) / self.step_lat
        x = (longitudes - self.west) / self.step_lon
        row = np.clip(np.floor(y).astype(np.int64), 0, rows - 2)
        col = np.clip(np.floor(x).astype(np.int64), 0, cols - 2)
        dy, dx = y - row, x - col
        corners = []
        for i, j in ((0, 0), (0, 1), (1, 0), (1, 1)):
            raw = self.samples[row + i, col + j]
            corner = raw.astype(np.float64)
            corner[raw == VOID] = np.nan
            if self.nodata is not None:  # compared as the raster's type, as GDAL does
                corner[raw == self.samples.dtype.type(self.nodata)] = np.nan
            corners.append(corner)
        top = corners[0] * (1 - dx) + corners[1] * dx
        bottom = corners[2] * (1 - dx) + corners[3] * dx
        heights: Array = top * (1 - dy) + bottom * dy
        return heights


class Terrain:
    """The ground as a set of tiles: heights at places, sampled along paths."""

    def __init__(self, tiles: Sequence[Tile], source: str = "") -> None:
        self.tiles = tuple(tiles)
        self.source = source

    @property
    def resolution(self) -> float:
        """Degrees between samples of the finest tile (either axis)."""
        return min(min(t.step_lat, t.step_lon) for t in self.tiles)

    def spacing(self, latitude: float) -> float:
        """Metres between samples of the finest tile near ``latitude`` (the shorter axis)."""
        shrink = max(math.cos(math.radians(latitude)), 1e-6)
        return METRES_PER_DEGREE * min(min(t.step_lat, t.step_lon * shrink)
                                       for t in self.tiles)

    def heights(self, latitudes: npt.ArrayLike, longitudes: npt.ArrayLike) -> Array:
        """Heights (m above EGM96) at places (degrees); raises :class:`TerrainNotCovered`
        for the first place no tile covers or whose samples include a void."""
        lat = np.atleast_1d(np.asarray(latitudes, dtype=np.float64))
        lon = np.atleast_1d(np.asarray(longitudes, dtype=np.float64))
        found = np.full(lat.shape, np.nan)
        done = np.zeros(lat.shape, dtype=bool)
        void_tile = np.full(lat.shape, -1)
        for index, tile in enumerate(self.tiles):
            todo = ~done & tile.covers(lat, lon)
            if not todo.any():
                continue
            values = tile.heights(lat[todo], lon[todo])
            good = ~np.isnan(values)
            where = np.flatnonzero(todo)
            found[where[good]] = values[good]
            done[where[good]] = True
            void_tile[where[~good]] = index  # a neighbouring tile may still have data there
        missing = np.flatnonzero(~done)
        if missing.size:
            first = int(missing[0])
            la, lo = float(lat[first]), float(lon[first])
            if void_tile[first] >= 0:
                path = self.tiles[int(void_tile[first])].path
                raise TerrainNotCovered(
                    f"{path}: a void (no data) at {la:.6f}, {lo:.6f}: voids are refused, "
                    "not filled in; use a tile with the void filled", la, lo, path)
            name = tile_name(la, lo)
            if len(self.tiles) == 1 and not Path(self.source).is_dir():
                t = self.tiles[0]
                raise TerrainNotCovered(
                    f"no terrain data at {la:.6f}, {lo:.6f}: outside {t.path} (latitude "
                    f"{t.south:g} to {t.north:g}, longitude {t.west:g} to {t.east:g}); "
                    f"SRTM tile {name} holds the place", la, lo, name)
            raise TerrainNotCovered(
                f"no terrain data at {la:.6f}, {lo:.6f}: tile {name} is missing"
                + (f" from {self.source}" if self.source else ""), la, lo, name)
        return found

    def height(self, latitude: float, longitude: float) -> float:
        """The height (m above EGM96) at one place."""
        return float(self.heights([latitude], [longitude])[0])

    def along(self, start: tuple[float, float], end: tuple[float, float],
              metres: float) -> tuple[Array, Array]:
        """Samples of the ground on the line from ``start`` to ``end`` (latitude,
        longitude), ``metres`` long: the fractions of the way (0 to 1), at least one every
        half sample spacing of the data, and the heights there."""
        spacing = self.spacing(max(abs(start[0]), abs(end[0]))) / 2
        count = max(1, math.ceil(metres / spacing))
        fractions = np.linspace(0.0, 1.0, count + 1)
        latitudes = start[0] + fractions * (end[0] - start[0])
        longitudes = start[1] + fractions * (end[1] - start[1])
        return fractions, self.heights(latitudes, longitudes)


def read_hgt(path: Path) -> Tile:
    """One SRTM tile; a name that is no tile's, a size that is no SRTM size or heights no
    ground has are errors saying so."""
    match = _TILE_NAME.match(path.stem)
    if path.suffix.lower() != ".hgt" or match is None:
        raise TerrainError("not an SRTM tile name: a tile is named after its south-west "
                           "corner, e.g. N35E149.hgt or S36W071.hgt", str(path))
    ns, lat, ew, lon = match.groups()
    south = int(lat) * (1 if ns.upper() == "N" else -1)
    west = int(lon) * (1 if ew.upper() == "E" else -1)
    if not (-90 <= south < 90 and -180 <= west < 180):
        raise TerrainError(f"no such tile on Earth (corner {south}, {west})", str(path))
    size = path.stat().st_size
    side = next((n for n in SRTM_SIZES if size == 2 * n * n), None)
    if side is None:
        raise TerrainError(
            f"{size:,} bytes: an SRTM tile is {2 * 1201 * 1201:,} bytes (3 arc-second, "
            f"1201 x 1201 samples) or {2 * 3601 * 3601:,} (1 arc-second, 3601 x 3601); "
            "this one is truncated or not SRTM", str(path))
    samples = np.fromfile(path, dtype=">i2").reshape(side, side)
    _plausible(samples, None, str(path))
    step = 1.0 / (side - 1)
    return Tile(str(path), south + 1.0, float(west), step, step, samples)


def _plausible(samples: npt.NDArray[Any], nodata: float | None, path: str) -> None:
    """Refuse a grid whose heights (voids aside) no ground on Earth has: a corrupt file."""
    valid = samples[(samples != VOID) & ~np.isnan(samples.astype(np.float64))]
    if nodata is not None:
        valid = valid[valid != samples.dtype.type(nodata)]
    if valid.size == 0:
        raise TerrainError("every sample is a void: no heights in the file", path)
    low, high = float(valid.min()), float(valid.max())
    if low < LOWEST or high > HIGHEST:
        raise TerrainError(f"heights from {low:g} to {high:g} m: ground on Earth lies "
                           f"between {LOWEST:g} and {HIGHEST:g} m; the file is corrupt or "
                           "not an elevation model in metres", path)


# GeoTIFF tags and keys (GeoTIFF 1.1, OGC 19-008r4).
_PIXEL_SCALE, _TIEPOINT, _TRANSFORMATION, _GEOKEYS, _GDAL_NODATA = (
    33550, 33922, 34264, 34735, 42113)
_MODEL_TYPE, _RASTER_TYPE, _GEOGRAPHIC_TYPE, _GEODETIC_DATUM = 1024, 1025, 2048, 2050
_PROJECTED_TYPE, _VERTICAL_TYPE = 3072, 4096
_GEOGRAPHIC, _PIXEL_IS_POINT, _WGS84, _WGS84_DATUM, _USER_DEFINED = 2, 2, 4326, 6326, 32767
_EGM96_HEIGHT = 5773


def _geokeys(directory: Sequence[int]) -> dict[int, int]:
    """The short-valued keys of a GeoKeyDirectoryTag (key id -> value)."""
    count = directory[3]
    keys: dict[int, int] = {}
    for i in range(count):
        key, location, _, value = directory[4 + 4 * i: 8 + 4 * i]
        if location == 0:
            keys[key] = value
    return keys


def read_geotiff(path: Path) -> Tile:
    """One GeoTIFF raster in EPSG:4326; another projection, a rotated grid, a file tifffile
    cannot read or heights no ground has are errors saying so."""
    try:
        import tifffile
    except ImportError:
        raise TerrainError(f"reading GeoTIFF needs tifffile, which is not installed: "
                           f"{_EXTRA}", str(path)) from None
    where = str(path)
    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            if not isinstance(page, tifffile.TiffPage):
                raise TerrainError("its first image is not a full TIFF page", where)
            tags = {tag.code: tag.value for tag in page.tags}
            if _GEOKEYS not in tags:
                raise TerrainError("a TIFF without GeoTIFF keys: it says nowhere where "
                                   "it lies", where)
            keys = _geokeys(tags[_GEOKEYS])
            _wgs84(keys, where)
            if _PIXEL_SCALE not in tags or _TIEPOINT not in tags:
                reason = ("a rotated or sheared grid (ModelTransformation)"
                          if _TRANSFORMATION in tags else "no ModelPixelScale and "
                          "ModelTiepoint: where its samples lie is not said")
                raise TerrainError(f"{reason}; only north-up grids are read", where)
            if math.prod(page.shape) > MAX_SAMPLES:
                raise TerrainError(f"a raster of {' x '.join(map(str, page.shape))} samples:"
                                   f" more than {MAX_SAMPLES:,}, the most tml reads from "
                                   "one file; cut it into tiles", where)
            samples = page.asarray()
    except TerrainError:
        raise
    except Exception as exc:  # tifffile's errors on a corrupt or truncated file vary
        raise TerrainError(f"not a readable GeoTIFF: {exc or type(exc).__name__}",
                           where) from None
    if samples.ndim != 2 or min(samples.shape) < 2 or samples.dtype.kind not in "iuf":
        raise TerrainError(f"a raster of shape {samples.shape} ({samples.dtype}): heights "
                           "are one band of numbers, at least 2 x 2", where)
    scale_x, scale_y = float(tags[_PIXEL_SCALE][0]), float(tags[_PIXEL_SCALE][1])
    column, row, _, x, y, _ = (float(v) for v in tags[_TIEPOINT][:6])
    if scale_x <= 0 or scale_y <= 0:
        raise TerrainError(f"pixel scale {scale_x:g} x {scale_y:g}: not a north-up grid",
                           where)
    # Pixel-is-area (the default): the tiepoint is the corner of its pixel, whose sample
    # lies at the pixel's centre.
    centre = 0.0 if keys.get(_RASTER_TYPE) == _PIXEL_IS_POINT else 0.5
    west = x + (centre - column) * scale_x
    north = y - (centre - row) * scale_y
    nodata = _nodata(tags.get(_GDAL_NODATA), where)
    _plausible(samples, nodata, where)
    tile = Tile(where, north, west, scale_y, scale_x, samples, nodata)
    if tile.south < -90 or tile.north > 90 or tile.west < -180 or tile.east > 180:
        raise TerrainError(f"spans {tile.south:g} to {tile.north:g} latitude, {tile.west:g} "
                           f"to {tile.east:g} longitude: not degrees on Earth", where)
    return tile


def _wgs84(keys: dict[int, int], where: str) -> None:
    """Refuse a GeoTIFF that is not in latitude/longitude on WGS84 above EGM96."""
    if keys.get(_MODEL_TYPE) != _GEOGRAPHIC:
        code = keys.get(_PROJECTED_TYPE)
        named = f" (EPSG:{code})" if code and code != _USER_DEFINED else ""
        raise TerrainError(f"in projected coordinates{named}, not latitude/longitude: only "
                           "EPSG:4326 is read; reproject it (gdalwarp -t_srs EPSG:4326)",
                           where)
    crs = keys.get(_GEOGRAPHIC_TYPE)
    if crs != _WGS84 and not (crs in (None, _USER_DEFINED)
                              and keys.get(_GEODETIC_DATUM) == _WGS84_DATUM):
        raise TerrainError(f"in geographic coordinates EPSG:{crs}, not WGS84: only "
                           "EPSG:4326 is read; reproject it (gdalwarp -t_srs EPSG:4326)",
                           where)
    vertical = keys.get(_VERTICAL_TYPE)
    if vertical not in (None, _EGM96_HEIGHT, _USER_DEFINED):
        raise TerrainError(f"heights in vertical datum EPSG:{vertical}: tml reads heights "
                           "above the EGM96 geoid (EPSG:5773), as SRTM's and ArduPilot's",
                           where)


def _nodata(value: object, where: str) -> float | None:
    if value is None:
        return None
    try:
        return float(str(value).strip("\x00 "))
    except ValueError:
        raise TerrainError(f"GDAL_NODATA {value!r} is not a number", where) from None


def read_tile(path: Path) -> Tile:
    """A tile by its suffix: ``.hgt`` (SRTM) or ``.tif``/``.tiff`` (GeoTIFF)."""
    if path.suffix.lower() == ".hgt":
        return read_hgt(path)
    if path.suffix.lower() in GEOTIFF_SUFFIXES:
        return read_geotiff(path)
    raise TerrainError("not terrain data: tml reads SRTM .hgt tiles and GeoTIFF "
                       "(.tif, .tiff) in EPSG:4326", str(path))


@lru_cache(maxsize=8)
def _load(resolved: str, stamp: tuple[tuple[str, int, int], ...]) -> Terrain:
    path = Path(resolved)
    if path.is_dir():
        files = sorted(p for p in path.iterdir()
                       if p.is_file() and p.suffix.lower() in (".hgt", *GEOTIFF_SUFFIXES))
        if not files:
            raise TerrainError("a directory without .hgt or GeoTIFF (.tif, .tiff) files",
                               resolved)
        return Terrain([read_tile(p) for p in files], resolved)
    return Terrain([read_tile(path)], resolved)


def load_terrain(path: str | Path) -> Terrain:
    """The terrain of one file or of every ``.hgt``, ``.tif`` and ``.tiff`` file in a
    directory (read once per process while the files are unchanged); a path that is not
    there or cannot be read is a :class:`TerrainError`."""
    try:
        resolved = Path(path).resolve()
        # A directory's own time does not change when a tile in it is rewritten.
        found = [resolved, *resolved.iterdir()] if resolved.is_dir() else [resolved]
        stamp = tuple((p.name, p.stat().st_mtime_ns, p.stat().st_size) for p in found)
        return _load(str(resolved), stamp)
    except FileNotFoundError:
        raise TerrainError("no such file or directory", str(path)) from None
    except (OSError, RuntimeError) as exc:  # unreadable, a name too long, a loop of links
        raise TerrainError(getattr(exc, "strerror", None) or str(exc), str(path)) from None
