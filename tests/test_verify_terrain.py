"""Verify above the ground (tml.verify.terrain, tml verify --terrain, <terrain source>): over a
synthetic hill the tests write as an SRTM tile and as a GeoTIFF, none downloaded."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from terrain_files import GROUND, HILL_NORTH, METRES_PER_DEGREE, write_geotiff, write_hgt

from tml.commands.cli import main
from tml.language.validation import load_mission, validate_file
from tml.terrain import load_terrain
from tml.verify.constraints import Constraint
from tml.verify.profile import load_profile
from tml.verify.static import verify_mission
from tml.world import DEFAULT_HOME

HOME = f'<home latitude="{DEFAULT_HOME.latitude}" longitude="{DEFAULT_HOME.longitude}" ' \
       f'altitude="{GROUND:g}"/>'
TOP = (DEFAULT_HOME.latitude + HILL_NORTH / METRES_PER_DEGREE, DEFAULT_HOME.longitude)


def mission(tmp_path: Path, body: str, terrain: str | None = None, home: str = HOME,
            name: str = "mission.xml") -> Path:
    named = f'<terrain source="{terrain}"/>' if terrain is not None else "<!-- none -->"
    path = tmp_path / name
    path.write_text(f"""<?xml version="1.0" encoding="UTF-8"?>
<mission name="terrain">
  <environment>
    {home}
    {named}
  </environment>
{body}
</mission>
""")
    return path


def go(north: float, east: float, up: float, name: str = "leg") -> str:
    return (f'  <task name="{name}"><action name="GO_TO_POINT"><argument name="coordinates" '
            f'value="{north:g}, {east:g}, {up:g}"/></action></task>')


TAKE_OFF = ('  <task name="climb"><action name="TAKE_OFF"><argument name="altitude" '
            'value="30"/></action></task>')
LAND = '  <task name="home"><action name="RETURN_HOME_AND_LAND"/></task>'
INTO_THE_HILL = "\n".join([TAKE_OFF, go(1200, 0, 30), LAND])  # the leg: line 8
BESIDE_THE_HILL = "\n".join([TAKE_OFF, go(0, 600, 30), LAND])


@pytest.fixture(params=["hgt", "GeoTIFF"])
def tile(request: pytest.FixtureRequest, tmp_path: Path) -> Path:
    if request.param == "hgt":
        return write_hgt(tmp_path)
    return write_geotiff(tmp_path / "hill.tif")


def test_a_flat_mission_into_the_hill_is_refused_with_its_line(
        tmp_path: Path, tile: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = mission(tmp_path, INTO_THE_HILL, tile.name)
    assert main(["verify", str(path)]) == 1
    out = capsys.readouterr().out
    found = [line for line in out.splitlines() if ": terrain: GO_TO_POINT:" in line]
    assert len(found) == 1, out
    assert found[0].startswith(f"{path}:8:")
    # The place is on the hill north of home, far below it.
    assert f"{TOP[1]:.6f}" in found[0] and "must be >= 10.0 m" in found[0]


def test_the_same_flight_beside_the_hill_is_feasible(
        tmp_path: Path, tile: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = mission(tmp_path, BESIDE_THE_HILL, tile.name)
    assert main(["verify", str(path), "--format", "json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["terrain"] == str(tile)
    clearances = [a["terrain_clearance"] for a in document["actions"]]
    # The take-off's climb from the ground is not judged, the point it climbs to is; the
    # leg flies 30 m over the flat ground (the hill 850 m away adds nothing), and so does
    # the way home until its landing, whose descent is not judged.
    assert clearances[0] == pytest.approx(30, abs=0.1)
    assert clearances[1] == pytest.approx(30, abs=0.1)
    assert clearances[2] == pytest.approx(30, abs=0.1)


def test_the_table_shows_the_lowest_clearance_above_the_ground(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tile = write_hgt(tmp_path)
    path = mission(tmp_path, INTO_THE_HILL)
    assert main(["verify", str(path), "--terrain", str(tile)]) == 1
    out = capsys.readouterr().out
    assert "above ground m" in out
    leg = next(line for line in out.splitlines() if "GO_TO_POINT" in line and "│" in line)
    lowest = float(leg.split("│")[-2])
    # As low as the line comes over the hill sampled every metre.
    terrain = load_terrain(tile)
    dense = terrain.heights(DEFAULT_HOME.latitude + np.linspace(0, 1200, 1201)
                            / METRES_PER_DEGREE, np.full(1201, DEFAULT_HOME.longitude))
    assert lowest == pytest.approx(GROUND + 30 - dense.max(), abs=1.0)
    assert lowest < -100


def test_without_terrain_nothing_is_judged_above_the_ground(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = mission(tmp_path, INTO_THE_HILL)
    assert main(["verify", str(path)]) == 1  # the return reserve alone
    out = capsys.readouterr().out
    assert ": terrain:" not in out and "above ground" not in out


def test_a_terrain_relative_position_flies_at_its_real_altitude(tmp_path: Path) -> None:
    tile = write_hgt(tmp_path)
    terrain = load_terrain(tile)
    def flown(reference: str) -> tuple[float, float, float | None]:
        body = "\n".join([TAKE_OFF, f"""  <task name="over"><action name="GO_TO_POSITION">
    <argument name="latitude" value="{TOP[0]}"/><argument name="longitude" value="{TOP[1]}"/>
    <argument name="altitude" value="40"/>
    <argument name="altitude_reference" value="{reference}"/></action></task>""", LAND])
        path = mission(tmp_path, body, name=f"{reference}.xml")
        profile = replace(load_profile("quadcopter"), max_altitude=400.0)
        report = verify_mission(load_mission(path), profile, terrain=terrain)
        row = report.rows[1]
        return row.path[-1][2], row.battery, row.terrain_clearance

    up, battery, clearance = flown("terrain")
    ground = terrain.height(*TOP)
    assert up == pytest.approx(ground + 40 - GROUND, abs=0.5)  # m above home
    assert clearance == pytest.approx(30, abs=0.1)  # the lowest: where it starts, 30 m up
    relative_up, relative_battery, relative_clearance = flown("relative")
    assert relative_up == pytest.approx(40)
    assert relative_clearance is not None and relative_clearance < 0  # into the hill
    assert battery < relative_battery  # the climb costs battery


def test_a_path_beyond_the_data_names_the_missing_tile(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tile = write_geotiff(tmp_path / "hill.tif")  # 0.04 degrees: about 1.8 km each way
    path = mission(tmp_path, "\n".join([TAKE_OFF, go(0, 1900, 30), LAND]), tile.name)
    assert main(["verify", str(path)]) == 1
    out = capsys.readouterr().out
    assert f"{path}:8:20: terrain: GO_TO_POINT: no terrain data at " in out
    assert f"outside {tile} (latitude " in out and "SRTM tile S36E149.hgt holds the place" in out
    assert "no data" in out  # in the table
    # A directory of tiles names the tile missing from it.
    (tmp_path / "tiles").mkdir()
    write_hgt(tmp_path / "tiles")
    far = mission(tmp_path, "\n".join([TAKE_OFF, go(0, 1900, 30), LAND]), "tiles",
                  home=HOME.replace(str(DEFAULT_HOME.longitude), "149.99"), name="far.xml")
    assert main(["verify", str(far)]) == 1
    out = capsys.readouterr().out
    assert f"{far}:8:20: terrain: GO_TO_POINT: no terrain data at " in out
    assert f"tile S36E150.hgt is missing from {tmp_path / 'tiles'}" in out


def test_home_off_the_ground_is_warned(tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    tile = write_hgt(tmp_path)
    high = HOME.replace(f'altitude="{GROUND:g}"', 'altitude="620"')
    path = mission(tmp_path, BESIDE_THE_HILL, tile.name, home=high)
    main(["verify", str(path)])
    out = capsys.readouterr().out
    assert "warning: the ground under home is 584 m above the EGM96 geoid" in out
    assert "36 m below <home>'s altitude 620 m" in out


def test_a_take_off_is_judged_where_it_climbs_to_and_a_wait_is_not_judged_again(
        tmp_path: Path) -> None:
    tile = write_hgt(tmp_path)
    low = ('  <task name="climb"><action name="TAKE_OFF"><argument name="altitude" '
           'value="4"/></action></task>')
    wait = ('  <task name="stay"><action name="WAIT"><argument name="duration" '
            'value="5"/></action></task>')
    path = mission(tmp_path, "\n".join([low, wait, '  <task name="down"><action '
                                         'name="LAND"/></task>']))
    report = verify_mission(load_mission(path), load_profile("quadcopter"),
                            terrain=load_terrain(tile))
    found = [(v.location.line, v.value) for v in report.violations
             if v.constraint is Constraint.TERRAIN and v.location]
    assert found == [(7, pytest.approx(4.0))]  # the take-off's hover point, 4 m up
    assert [row.terrain_clearance for row in report.rows] == [pytest.approx(4.0), None, None]


def test_a_ground_vehicle_is_not_judged_above_the_ground(tmp_path: Path) -> None:
    tile = write_hgt(tmp_path)
    path = mission(tmp_path, go(1200, 0, 0))
    report = verify_mission(load_mission(path), load_profile("rover"),
                            terrain=load_terrain(tile))
    assert Constraint.TERRAIN not in {v.constraint for v in report.violations}
    assert report.rows[0].terrain_clearance is None


def test_the_profile_sets_the_minimum(tmp_path: Path) -> None:
    tile = write_hgt(tmp_path)
    path = mission(tmp_path, BESIDE_THE_HILL)
    terrain = load_terrain(tile)
    strict = replace(load_profile("quadcopter"), min_terrain_clearance=40.0)
    found = [v for v in verify_mission(load_mission(path), strict, terrain=terrain).violations
             if v.constraint is Constraint.TERRAIN]
    assert [v.location.line for v in found if v.location] == [7, 8, 9]
    assert all(v.limit == 40.0 and v.value == pytest.approx(29.5, abs=0.6) for v in found)
    assert load_profile("quadcopter").min_terrain_clearance == 10.0


def test_a_mission_names_its_terrain_relative_to_its_file(tmp_path: Path) -> None:
    (tmp_path / "tiles").mkdir()
    write_hgt(tmp_path / "tiles")
    path = mission(tmp_path, BESIDE_THE_HILL, "tiles")
    world = load_mission(path).world
    assert world is not None and world.terrain is not None
    assert world.terrain.path == str(tmp_path / "tiles")
    assert world.terrain.location is not None and world.terrain.location.line == 5


def test_a_missing_terrain_source_is_an_error_with_its_place(tmp_path: Path) -> None:
    path = mission(tmp_path, BESIDE_THE_HILL, "nowhere.hgt")
    result = validate_file(path)
    [found] = result.errors
    assert (found.code, found.location.line, found.location.column) == ("E253", 5, 14)
    assert "terrain source 'nowhere.hgt': no such file or directory" in found.message


def test_a_terrain_source_no_file_can_have_is_an_error_not_a_traceback(tmp_path: Path) -> None:
    path = mission(tmp_path, BESIDE_THE_HILL, "a" * 5000)
    [found] = validate_file(path).errors
    assert (found.code, found.location.line) == ("E253", 5)
    assert "File name too long" in found.message


def test_a_rewritten_tile_in_a_directory_is_read_again(tmp_path: Path) -> None:
    write_hgt(tmp_path)
    assert load_terrain(tmp_path).height(*TOP) > GROUND + 100
    tile = tmp_path / "S36E149.hgt"
    np.full((1201, 1201), 700, dtype=">i2").tofile(tile)
    assert load_terrain(tmp_path).height(*TOP) == 700


def test_an_unusable_tile_the_mission_names_is_refused_with_its_place(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tile = write_hgt(tmp_path)
    tile.write_bytes(tile.read_bytes()[:1000])
    path = mission(tmp_path, BESIDE_THE_HILL, tile.name)
    assert main(["verify", str(path)]) == 1
    out = capsys.readouterr().out
    assert f"{path}:5:5: terrain source 'S36E149.hgt': {tile}: 1,000 bytes" in out
    assert "Traceback" not in out
    assert main(["verify", str(path), "--format", "json"]) == 1
    said = capsys.readouterr()
    assert said.out == "" and "terrain data unusable, not verified" in said.err


def test_an_unusable_terrain_option_is_a_usage_error(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = mission(tmp_path, BESIDE_THE_HILL)
    projected = write_geotiff(tmp_path / "utm.tif", keys={1024: 1, 3072: 32755})
    assert main(["verify", str(path), "--terrain", str(projected)]) == 2
    err = capsys.readouterr().err
    assert f"tml verify: {projected}: in projected coordinates (EPSG:32755)" in err


EXAMPLE = Path(__file__).resolve().parent.parent / "missions" / "terrain_hill.xml"


def test_the_example_tile_is_the_hill_the_tests_write(tmp_path: Path) -> None:
    shipped = EXAMPLE.parent / "terrain" / "S36E149.hgt"
    assert shipped.read_bytes() == write_hgt(tmp_path).read_bytes()  # made, not downloaded


def test_the_example_mission_climbs_the_hill_above_the_ground(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["verify", str(EXAMPLE), "--format", "json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["terrain"] == str(EXAMPLE.parent / "terrain")
    take_off, up, home = document["actions"]
    flank = load_terrain(EXAMPLE.parent / "terrain").height(-35.360117, 149.165230)
    assert 35 < flank - GROUND < 40  # 350 m north, on the hill's south flank
    # The take-off is judged where it climbs to; the climb's lowest point is where it
    # starts, 30 m over home; the way home's is where it starts too, 665 m AMSL over the
    # flank.
    assert [a["terrain_clearance"] for a in document["actions"]] == [
        30.0, 30.0, round(665 - flank, 3)]
    assert up["path"][-1][2] == pytest.approx(665 - GROUND)
    assert up["battery"] < take_off["battery"] and home["battery"] < up["battery"]
