"""The world model (tml.world)."""

from __future__ import annotations

from tml.world import DEFAULT_HOME, Cylinder, Geofence, Home, World, WorldObject


def test_merged_lays_the_other_world_over() -> None:
    base = World(home=Home(1, 2, 3), obstacles=(Cylinder("a", 0, 0, 1),),
                 objects=(WorldObject("item", "A", 1, 1),))
    other = World(geofence=Geofence(max_altitude=50), obstacles=(Cylinder("b", 5, 5, 1),))
    merged = base.merged(other)
    assert merged.home == Home(1, 2, 3)
    assert merged.geofence.max_altitude == 50
    assert [o.name for o in merged.obstacles] == ["a", "b"]
    assert len(merged.objects) == 1
    assert base.merged(None) is base


def test_default_home_is_ardupilot_sitl_location() -> None:
    assert World().home_or_default == DEFAULT_HOME
    assert round(DEFAULT_HOME.latitude, 3) == -35.363
