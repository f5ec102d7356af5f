"""tml.terrain: SRTM and GeoTIFF tiles the tests write (a synthetic hill), bilinear heights,
sampling along a line, and every bad file a TerrainError naming the file and why."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from terrain_files import (
    GROUND,
    HILL_HEIGHT,
    HILL_NORTH,
    METRES_PER_DEGREE,
    grid,
    hill,
    write_geotiff,
    write_hgt,
)

from tml.errors import TerrainError, TerrainNotCovered
from tml.terrain import VOID, load_terrain, read_hgt, tile_name
from tml.world import DEFAULT_HOME

HOME = (DEFAULT_HOME.latitude, DEFAULT_HOME.longitude)
TOP = (HOME[0] + HILL_NORTH / METRES_PER_DEGREE, HOME[1])


def test_tile_names_are_the_south_west_corner() -> None:
    assert tile_name(-35.36, 149.16) == "S36E149.hgt"
    assert tile_name(35.0, -71.5) == "N35W072.hgt"
    assert tile_name(0.5, 0.5) == "N00E000.hgt"


def test_an_hgt_tile_lies_where_its_name_says(tmp_path: Path) -> None:
    tile = read_hgt(write_hgt(tmp_path))
    assert (tile.south, tile.north, tile.west, tile.east) == (-36.0, -35.0, 149.0, 150.0)
    assert tile.samples.shape == (1201, 1201)
    assert tile.step_lat == pytest.approx(3 / 3600)


@pytest.mark.parametrize("side", [1201, 3601])
def test_heights_at_the_samples_are_the_samples(tmp_path: Path, side: int) -> None:
    path = write_hgt(tmp_path, side=side)
    terrain = load_terrain(path)
    lats, lons = grid(-36.0, 149.0, side)
    row, col = np.unravel_index(np.argmax(hill(lats, lons)), lats.shape)
    peak = terrain.height(float(lats[row, col]), float(lons[row, col]))
    assert peak == pytest.approx(round(float(hill(lats, lons)[row, col])))
    assert terrain.height(*HOME) == pytest.approx(GROUND, abs=0.5)


def test_heights_between_samples_are_bilinear(tmp_path: Path) -> None:
    path = tmp_path / "N10E020.hgt"
    samples = np.zeros((1201, 1201), dtype=">i2")
    samples[0, 0], samples[0, 1], samples[1, 0], samples[1, 1] = 100, 200, 300, 500
    samples.tofile(path)
    terrain = load_terrain(path)
    step = 1 / 1200
    # Row 0 is the north edge (latitude 11), column 0 the west edge (longitude 20).
    assert terrain.height(11.0, 20.0) == 100
    assert terrain.height(11.0, 20.0 + step / 2) == pytest.approx(150)
    assert terrain.height(11.0 - step / 2, 20.0 + step / 2) == pytest.approx(275)
    assert terrain.height(11.0 - step / 4, 20.0 + step * 3 / 4) == pytest.approx(
        0.75 * (100 * 0.25 + 200 * 0.75) + 0.25 * (300 * 0.25 + 500 * 0.75))


def test_a_geotiff_reads_the_same_hill(tmp_path: Path) -> None:
    terrain = load_terrain(write_geotiff(tmp_path / "hill.tif"))
    assert terrain.height(*TOP) == pytest.approx(GROUND + HILL_HEIGHT, abs=0.5)
    assert terrain.height(*HOME) == pytest.approx(GROUND, abs=0.5)
    # 0.04 degrees over 400 samples, pixel is point.
    assert terrain.resolution == pytest.approx(0.0001)


def test_a_pixel_is_area_geotiff_puts_samples_at_pixel_centres(tmp_path: Path) -> None:
    point = load_terrain(write_geotiff(tmp_path / "point.tif")).tiles[0]
    area = load_terrain(write_geotiff(tmp_path / "area.tif",
                                      keys={1024: 2, 1025: 1, 2048: 4326})).tiles[0]
    assert area.west == pytest.approx(point.west + point.step_lon / 2)
    assert area.north == pytest.approx(point.north - point.step_lat / 2)


def test_a_directory_is_every_tile_in_it(tmp_path: Path) -> None:
    write_hgt(tmp_path)
    write_hgt(tmp_path, latitude=-35.3, longitude=150.2)  # the tile east of it
    (tmp_path / "notes.txt").write_text("not a tile")
    terrain = load_terrain(tmp_path)
    assert len(terrain.tiles) == 2
    assert terrain.height(-35.5, 150.5) == pytest.approx(GROUND, abs=0.5)
    with pytest.raises(TerrainNotCovered, match=r"tile S37E149\.hgt is missing") as found:
        terrain.height(-36.5, 149.5)
    assert found.value.tile == "S37E149.hgt"
    assert str(tmp_path) in str(found.value)


def test_samples_along_a_line_are_half_a_sample_apart(tmp_path: Path) -> None:
    terrain = load_terrain(write_hgt(tmp_path))
    metres = 1000.0
    end = (HOME[0] + metres / METRES_PER_DEGREE, HOME[1])
    fractions, heights = terrain.along(HOME, end, metres)
    spacing = terrain.spacing(HOME[0])
    # 3 arc-second: about 92 m north-south, 75 m east-west at 35 degrees south.
    assert spacing == pytest.approx(3 / 3600 * METRES_PER_DEGREE * math.cos(math.radians(
        abs(HOME[0]))), rel=1e-3)
    assert np.diff(fractions).max() * metres <= spacing / 2
    assert heights.max() == pytest.approx(terrain.height(*TOP), abs=5)
    assert heights[0] == pytest.approx(GROUND, abs=0.5)


def test_a_void_is_refused_where_it_is_used(tmp_path: Path) -> None:
    path = write_hgt(tmp_path)
    samples = np.fromfile(path, dtype=">i2").reshape(1201, 1201)
    samples[600, 600] = VOID
    samples.tofile(path)
    terrain = load_terrain(path)
    assert terrain.height(-35.9, 149.1) == pytest.approx(GROUND, abs=0.5)  # far from it
    with pytest.raises(TerrainNotCovered, match=r"a void .* voids are refused"):
        terrain.height(-35.5, 149.5)


def test_a_geotiff_nodata_value_is_a_void(tmp_path: Path) -> None:
    at_home = np.float32(hill(np.array(HOME[0]), np.array(HOME[1])))  # the centre sample
    terrain = load_terrain(write_geotiff(tmp_path / "hill.tif", nodata=str(at_home)))
    with pytest.raises(TerrainNotCovered, match="void"):
        terrain.height(*HOME)
    assert terrain.height(*TOP) == pytest.approx(GROUND + HILL_HEIGHT, abs=0.5)


def _truncated(tmp_path: Path) -> Path:
    path = write_hgt(tmp_path)
    path.write_bytes(path.read_bytes()[:-1000])
    return path


def _garbage(tmp_path: Path) -> Path:
    path = tmp_path / "S36E149.hgt"
    np.full((1201, 1201), 30000, dtype=">i2").tofile(path)
    return path


def _badly_named(tmp_path: Path) -> Path:
    path = write_hgt(tmp_path)
    return path.rename(tmp_path / "hill.hgt")


def _projected(tmp_path: Path) -> Path:
    return write_geotiff(tmp_path / "utm.tif", keys={1024: 1, 3072: 32755})


def _nad27(tmp_path: Path) -> Path:
    return write_geotiff(tmp_path / "nad27.tif", keys={1024: 2, 2048: 4267})


def _navd88(tmp_path: Path) -> Path:
    return write_geotiff(tmp_path / "navd.tif", keys={1024: 2, 2048: 4326, 4096: 5703})


def _truncated_tiff(tmp_path: Path) -> Path:
    path = write_geotiff(tmp_path / "cut.tif")
    path.write_bytes(path.read_bytes()[:200])
    return path


def _plain_tiff(tmp_path: Path) -> Path:
    import tifffile

    path = tmp_path / "plain.tif"
    tifffile.imwrite(path, np.zeros((4, 4), dtype=np.int16))
    return path


def _huge_tiff(tmp_path: Path) -> Path:
    # A header that claims 100000 x 100000 samples in a file of a few hundred bytes.
    import tifffile

    path = write_geotiff(tmp_path / "huge.tif", side=3, degrees=0.001)
    data = bytearray(path.read_bytes())
    with tifffile.TiffFile(path) as tif:
        for code in (256, 257):  # ImageWidth, ImageLength
            tag = tif.pages[0].tags[code]
            offset, kind = tag.valueoffset, tag.dtype
            size = 4 if kind == 4 else 2
            data[offset:offset + size] = (100_000).to_bytes(size, "little") \
                if size == 4 else (60_000).to_bytes(2, "little")
    path.write_bytes(bytes(data))
    return path


def _not_tiff(tmp_path: Path) -> Path:
    path = tmp_path / "photo.tif"
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(100))
    return path


def _other_suffix(tmp_path: Path) -> Path:
    path = tmp_path / "ground.dem"
    path.write_bytes(bytes(8))
    return path


def _empty_directory(tmp_path: Path) -> Path:
    return tmp_path


def _missing(tmp_path: Path) -> Path:
    return tmp_path / "nowhere" / "S36E149.hgt"


BAD = {
    "truncated hgt": (_truncated, r"2,883,802 bytes.*truncated or not SRTM"),
    "wrong size": (lambda p: (p / "N00E000.hgt").write_bytes(bytes(20)) and p / "N00E000.hgt",
                   r"20 bytes: an SRTM tile is 2,884,802 bytes"),
    "corrupt heights": (_garbage, r"heights from 30000 to 30000 m.*corrupt"),
    "not a tile name": (_badly_named, "not an SRTM tile name"),
    "projected GeoTIFF": (_projected, r"projected coordinates \(EPSG:32755\).*EPSG:4326"),
    "other datum": (_nad27, r"EPSG:4267, not WGS84"),
    "other vertical datum": (_navd88, r"vertical datum EPSG:5703.*EGM96"),
    "truncated GeoTIFF": (_truncated_tiff, "not a readable GeoTIFF"),
    "TIFF without keys": (_plain_tiff, "without GeoTIFF keys"),
    "not a TIFF": (_not_tiff, "not a readable GeoTIFF"),
    "huge GeoTIFF": (_huge_tiff, r"samples: more than 169,000,000"),
    "other suffix": (_other_suffix, "not terrain data"),
    "empty directory": (_empty_directory, "a directory without .hgt or GeoTIFF"),
    "missing": (_missing, "no such file or directory"),
}


@pytest.mark.parametrize("case", BAD, ids=list(BAD))
def test_bad_terrain_files_are_refused_with_the_file_and_why(tmp_path: Path,
                                                              case: str) -> None:
    make, reason = BAD[case]
    path = make(tmp_path)
    with pytest.raises(TerrainError, match=reason) as found:
        load_terrain(path)
    assert found.value.path.endswith(path.name)
    assert str(found.value).startswith(found.value.path)


def test_geotiff_without_tifffile_names_the_extra(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_geotiff(tmp_path / "hill.tif")
    monkeypatch.setitem(__import__("sys").modules, "tifffile", None)  # not installed
    with pytest.raises(TerrainError, match=r"needs tifffile.*tml-flight\[terrain\]"):
        load_terrain(path)
