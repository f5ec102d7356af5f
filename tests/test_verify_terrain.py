"""<terrain source> in a mission: resolved relative to the mission file, checked to exist."""

from __future__ import annotations

from pathlib import Path

from terrain_files import GROUND, HILL_NORTH, METRES_PER_DEGREE, write_hgt

from tml.language.validation import load_mission, validate_file
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
