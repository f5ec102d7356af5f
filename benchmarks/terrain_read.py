"""Read time of a 1 arc-second terrain tile (3601 x 3601 samples), by reader.

Writes a synthetic SRTM tile and the same heights as an EPSG:4326 GeoTIFF (int16, and
deflate-compressed int16), then times: tml.terrain's .hgt reader (numpy alone), its GeoTIFF
reader (tifffile), and rasterio (GDAL) where it is installed; best of five each, and the
ratio against the .hgt read measured in the same run. Run by hand:

    python benchmarks/terrain_read.py
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from terrain_files import grid, hill

from tml.terrain import read_geotiff, read_hgt

SIDE = 3601


def best(run: Callable[[], object], times: int = 5) -> float:
    found = []
    for _ in range(times):
        start = time.perf_counter()
        run()
        found.append(time.perf_counter() - start)
    return min(found)


def main() -> None:
    import tifffile

    with tempfile.TemporaryDirectory() as folder:
        lats, lons = grid(-36.0, 149.0, SIDE)
        heights = np.round(hill(lats, lons)).astype(np.int16)
        hgt = Path(folder) / "S36E149.hgt"
        heights.astype(">i2").tofile(hgt)
        step = 1.0 / (SIDE - 1)
        tags = [(33550, "d", 3, (step, step, 0.0), True),
                (33922, "d", 6, (0.0, 0.0, 0.0, 149.0, -35.0, 0.0), True),
                (34735, "H", 16, (1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 2,
                                  2048, 0, 1, 4326), True)]
        plain, packed = Path(folder) / "plain.tif", Path(folder) / "deflate.tif"
        tifffile.imwrite(plain, heights, extratags=tags)
        tifffile.imwrite(packed, heights, extratags=tags, compression="zlib",
                         tile=(256, 256))
        base = best(lambda: read_hgt(hgt))
        rows = [(".hgt, numpy (tml.terrain.read_hgt)", base)]
        rows.append((".hgt, numpy.fromfile alone (no checks)",
                     best(lambda: np.fromfile(hgt, dtype=">i2"))))
        rows.append(("GeoTIFF, tifffile.imread alone (no checks)",
                     best(lambda: tifffile.imread(plain))))
        rows.append(("GeoTIFF deflate, tifffile.imread alone (no checks)",
                     best(lambda: tifffile.imread(packed))))
        rows.append(("GeoTIFF, tifffile (tml.terrain.read_geotiff)",
                     best(lambda: read_geotiff(plain))))
        rows.append(("GeoTIFF deflate, tifffile (tml.terrain.read_geotiff)",
                     best(lambda: read_geotiff(packed))))
        try:
            import rasterio
        except ImportError:
            print("rasterio: not installed, not measured")
        else:
            def with_rasterio(path: Path) -> object:
                with rasterio.open(path) as dataset:
                    return dataset.read(1)

            rows.append(("GeoTIFF, rasterio (GDAL)", best(lambda: with_rasterio(plain))))
            rows.append(("GeoTIFF deflate, rasterio (GDAL)",
                         best(lambda: with_rasterio(packed))))
        for name, seconds in rows:
            print(f"{name:55s} {seconds * 1000:8.1f} ms  {seconds / base:6.2f} x .hgt")


if __name__ == "__main__":
    main()
