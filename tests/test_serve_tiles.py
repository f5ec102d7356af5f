"""The map tiles of ``tml serve`` (tml.serve.tiles): an MBTiles file checked at start-up and
served with its rows flipped, a tile URL checked, the page's Content-Security-Policy
widened by that URL's one origin, and every bad source refused with why."""

from __future__ import annotations

import gzip
import sqlite3
from collections.abc import Callable
from contextlib import closing
from pathlib import Path

import pytest
from mbtiles import png, write_mbtiles
from serving import Served

from tml.commands.cli import main
from tml.serve.guard import POLICY
from tml.serve.tiles import TilesError, TileSource, open_mbtiles, tile_url

RED, BLUE = png([[(255, 0, 0)] * 4] * 4), png([[(0, 0, 255)] * 4] * 4)


def raw_mbtiles(path: Path, rows: list[tuple[int, int, int, bytes]],
                metadata: dict[str, str] | None = None) -> Path:
    """An MBTiles file with these (zoom_level, tile_column, tile_row, tile_data) rows, as
    the file stores them (rows from the south)."""
    with closing(sqlite3.connect(path)) as database, database:
        database.execute("CREATE TABLE metadata (name TEXT, value TEXT)")
        database.execute("CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, "
                         "tile_row INTEGER, tile_data BLOB)")
        database.executemany("INSERT INTO metadata VALUES (?, ?)",
                             list((metadata or {}).items()))
        database.executemany("INSERT INTO tiles VALUES (?, ?, ?, ?)", rows)
    return path


def test_rows_count_from_the_south_in_the_file_and_from_the_north_on_the_page(
        tmp_path: Path) -> None:
    # Zoom 1: the file's row 1 is the northern half of the world, row 0 the southern.
    source = open_mbtiles(raw_mbtiles(tmp_path / "f.mbtiles", [(1, 0, 1, RED), (1, 0, 0, BLUE)],
                                      {"format": "png"}))
    assert source.tile(1, 0, 0) == (RED, "image/png"), "the north-west tile"
    assert source.tile(1, 0, 1) == (BLUE, "image/png"), "the south-west tile"
    assert source.tile(1, 1, 0) is None, "a tile the file lacks"
    assert source.tile(1, 2, 0) is None and source.tile(1, 0, 2) is None, "off the world"


def test_the_description_names_the_zooms_and_a_plain_attribution(tmp_path: Path) -> None:
    path = write_mbtiles(tmp_path / "field.mbtiles", {(17, 1, 2): RED, (19, 5, 6): BLUE}, {
        "attribution": '<a href="https://example.org">Field survey</a> &amp; <b>us</b>',
        "bounds": "149.16,-35.37,149.17,-35.36"})
    assert open_mbtiles(path).description() == {
        "source": "mbtiles", "url": "/tiles/{z}/{x}/{y}", "attribution": "Field survey & us",
        "minzoom": 17, "maxzoom": 19, "bounds": (149.16, -35.37, 149.17, -35.36)}
    assert TileSource().description() == {"source": None}


def _empty(path: Path) -> None:
    path.write_bytes(b"")


def _text(path: Path) -> None:
    path.write_text("<svg>not a database</svg>\n" * 10)


def _corrupt(path: Path) -> None:
    write_mbtiles(path, {(1, 0, 0): RED})
    data = bytearray(path.read_bytes())
    data[100:4096] = b"\xff" * (4096 - 100)  # the first page's b-tree, overwritten
    path.write_bytes(bytes(data))


def _no_tiles_table(path: Path) -> None:
    with closing(sqlite3.connect(path)) as database, database:
        database.execute("CREATE TABLE places (name TEXT)")


def _no_tile(path: Path) -> None:
    raw_mbtiles(path, [], {"format": "png"})


def _vector(path: Path) -> None:
    raw_mbtiles(path, [(0, 0, 0, b"\x1a\x03abc")], {"format": "pbf", "json": "{}"})


def _gzipped(path: Path) -> None:
    raw_mbtiles(path, [(0, 0, 0, gzip.compress(b"\x1a\x03abc"))])


def _not_an_image(path: Path) -> None:
    raw_mbtiles(path, [(0, 0, 0, b"GIF89a......")])


BAD_FILES: list[tuple[Callable[[Path], None], str]] = [
    (_empty, "the file is empty: expected an MBTiles file (SQLite)"),
    (_text, "not an MBTiles file: it is not an SQLite database"),
    (_corrupt, "the file cannot be read as MBTiles: "),
    (_no_tiles_table, "not an MBTiles file: it has no 'tiles' table"),
    (_no_tile, "the file holds no tile"),
    (_vector, "it holds vector tiles (pbf): the page shows raster tiles"),
    (_gzipped, "it holds vector tiles (pbf): the page shows raster tiles"),
    (_not_an_image, "its tiles are not PNG, JPEG or WebP images"),
]


@pytest.mark.parametrize(("make", "said"), BAD_FILES, ids=[m.__name__ for m, _ in BAD_FILES])
def test_a_file_that_is_not_a_raster_mbtiles_file_is_refused_with_why(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], make: Callable[[Path], None],
        said: str) -> None:
    path = tmp_path / "bad.mbtiles"
    make(path)
    before = path.read_bytes()
    with pytest.raises(TilesError, match=r"^--tiles .*bad\.mbtiles: ") as refused:
        open_mbtiles(path)
    assert said in str(refused.value)
    # The command says it and stops before anything is served (the documented exit 2).
    assert main(["serve", "--sim", "--tiles", str(path), "--data", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert err == f"tml serve: {refused.value}\n" and "Traceback" not in err
    assert path.read_bytes() == before, "the operator's file is left as it was"
    assert not (tmp_path / "d").exists(), "refused before the database was made"


def test_a_missing_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "none.mbtiles"
    assert main(["serve", "--sim", "--tiles", str(missing), "--data", str(tmp_path)]) == 2
    assert capsys.readouterr().err == f"tml serve: --tiles {missing}: no such file\n"


@pytest.mark.parametrize(("args", "said"), [
    (["--tile-url", "ftp://tiles.example.org/{z}/{x}/{y}.png"],
     "expected an http:// or https:// URL"),
    (["--tile-url", "https://tiles.example.org/{z}/{x}.png"], "the URL has no {y}"),
    (["--tile-url", "https://tiles.example.org/{z}/{x}/{y}.png?a='b'"],
     "spaces, quotes, <, > and \\ are not taken"),
    (["--tile-url", "https://t.example.org/{z}/{x}/{y}.png", "--tiles", "f.mbtiles"],
     "--tiles and --tile-url: give one of them"),
    (["--tile-attribution", "Someone"], "--tile-attribution goes with --tile-url"),
])
def test_a_tile_url_option_that_cannot_work_is_refused_with_why(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str],
        said: str) -> None:
    assert main(["serve", "--sim", *args, "--data", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("tml serve: ") and said in err and "Traceback" not in err


def test_the_service_serves_the_files_tiles_to_the_page_without_a_token(
        tmp_path: Path) -> None:
    path = write_mbtiles(tmp_path / "f.mbtiles", {(2, 1, 0): RED, (2, 1, 3): BLUE})
    with Served(tmp_path, token="secret", tiles=open_mbtiles(path)) as served:
        assert served.client.get("/status").status_code == 401, "the API needs the token"
        described = served.client.get("/tiles")
        assert described.status_code == 200
        assert described.json()["source"] == "mbtiles"
        red = served.client.get("/tiles/2/1/0")
        assert (red.status_code, red.headers["content-type"], red.content) == (
            200, "image/png", RED)
        assert served.client.get("/tiles/2/1/3").content == BLUE
        assert red.headers["content-security-policy"] == POLICY
        missing = served.client.get("/tiles/2/2/0")
        assert (missing.status_code, missing.json()) == (404, {"error": "no tile 2/2/0"})
        assert served.client.get("/tiles/2/9/0").status_code == 404, "off the world"
        assert served.client.get("/tiles/31/0/0").status_code == 422
        assert served.client.get("/tiles/2/1/x").status_code == 422
        # The file taken away while the service runs: said, never a server error.
        path.unlink()
        gone = served.client.get("/tiles/2/1/0")
        assert gone.status_code == 503
        assert gone.json()["error"].startswith("the tiles file cannot be read: ")


def test_without_tiles_the_page_is_told_so(tmp_path: Path) -> None:
    with Served(tmp_path) as served:
        assert served.client.get("/tiles").json() == {
            "source": None, "url": None, "attribution": None, "minzoom": None,
            "maxzoom": None, "bounds": None}
        assert served.client.get("/tiles/0/0/0").json() == {
            "error": "this service serves no tiles (no --tiles file)"}
        assert served.client.get("/").headers["content-security-policy"] == POLICY


def test_a_tile_url_lets_images_come_from_its_one_origin(tmp_path: Path) -> None:
    source = tile_url("https://tiles.example.org:8443/field/{z}/{x}/{y}.png", " Survey ")
    with Served(tmp_path, tiles=source) as served:
        assert served.client.get("/tiles").json()["url"] == source.url
        assert served.client.get("/tiles").json()["attribution"] == "Survey"
        for path in ("/", "/page/map.js", "/status", "/no/such/route"):
            policy = served.client.get(path).headers["content-security-policy"]
            assert policy == POLICY.replace(
                "img-src 'self' data:;", "img-src 'self' data: https://tiles.example.org:8443;")
        refused = served.client.get("/status", headers={"Host": "evil.example"})
        assert "https://tiles.example.org:8443" in refused.headers["content-security-policy"]
        # The browser asks the tile server itself: the service serves no tile.
        assert served.client.get("/tiles/0/0/0").status_code == 404
