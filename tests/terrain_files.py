"""Small elevation files the terrain tests write for themselves (none is downloaded): a
synthetic hill on flat ground, as an SRTM .hgt tile and as a GeoTIFF."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import numpy.typing as npt

from tml.terrain import tile_name
from tml.world import DEFAULT_HOME

GROUND = DEFAULT_HOME.altitude  # the flat ground around the hill: home's altitude AMSL
HILL_HEIGHT = 150.0  # m above the ground at its top
HILL_NORTH = 600.0  # m north of home
HILL_RADIUS = 150.0  # m: the hill's Gaussian width
METRES_PER_DEGREE = 111_320.0


def hill(latitudes: npt.NDArray[np.float64], longitudes: npt.NDArray[np.float64],
         home: tuple[float, float] = (DEFAULT_HOME.latitude, DEFAULT_HOME.longitude)
         ) -> npt.NDArray[np.float64]:
    """The ground's height: flat at :data:`GROUND` with a round hill north of home."""
    north = (latitudes - home[0]) * METRES_PER_DEGREE - HILL_NORTH
    east = (longitudes - home[1]) * METRES_PER_DEGREE * math.cos(math.radians(home[0]))
    heights: npt.NDArray[np.float64] = GROUND + HILL_HEIGHT * np.exp(
        -(north**2 + east**2) / (2 * HILL_RADIUS**2))
    return heights


def grid(south: float, west: float, side: int, degrees: float = 1.0
         ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Latitudes and longitudes of a side x side grid, row 0 at the north edge."""
    lats = south + degrees - np.arange(side) * degrees / (side - 1)
    lons = west + np.arange(side) * degrees / (side - 1)
    return np.meshgrid(lats, lons, indexing="ij")


def write_hgt(directory: Path, latitude: float = DEFAULT_HOME.latitude,
              longitude: float = DEFAULT_HOME.longitude, side: int = 1201) -> Path:
    """The SRTM tile holding a place, with the hill (big-endian int16 metres)."""
    south, west = math.floor(latitude), math.floor(longitude)
    lats, lons = grid(south, west, side)
    path = directory / tile_name(latitude, longitude)
    np.round(hill(lats, lons)).astype(">i2").tofile(path)
    return path


def write_geotiff(path: Path, latitude: float = DEFAULT_HOME.latitude,
                  longitude: float = DEFAULT_HOME.longitude, side: int = 401,
                  degrees: float = 0.04, keys: dict[int, int] | None = None,
                  nodata: str | None = None) -> Path:
    """A GeoTIFF of ``degrees`` square centred on a place, with the hill (float32, pixel is
    point), in EPSG:4326 unless ``keys`` says other GeoKeys."""
    import tifffile

    south, west = latitude - degrees / 2, longitude - degrees / 2
    lats, lons = grid(south, west, side, degrees)
    step = degrees / (side - 1)
    geokeys = keys if keys is not None else {1024: 2, 1025: 2, 2048: 4326}
    directory = [1, 1, 0, len(geokeys)]
    for key, value in sorted(geokeys.items()):
        directory += [key, 0, 1, value]
    extratags: list[tuple[int, str, int, object, bool]] = [
        (33550, "d", 3, (step, step, 0.0), True),
        (33922, "d", 6, (0.0, 0.0, 0.0, west, south + degrees, 0.0), True),
        (34735, "H", len(directory), tuple(directory), True)]
    if nodata is not None:
        extratags.append((42113, "s", 0, nodata, True))
    tifffile.imwrite(path, hill(lats, lons).astype(np.float32), extratags=extratags)
    return path
