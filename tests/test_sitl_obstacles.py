"""Contact with, and distance to, the world's obstacles."""

from __future__ import annotations

import pytest

from sitl.obstacles import Obstacles
from tml.world import Cylinder, Prism, World

WORLD = World(obstacles=(
    Cylinder("mast", 20.0, 0.0, 2.0, bottom=0.0, top=15.0),
    Prism("shed", ((0.0, 30.0), (0.0, 40.0), (10.0, 40.0), (10.0, 30.0)), bottom=0.0, top=4.0),
))


def test_contact_at_the_surface_or_within_the_margin_at_the_right_height():
    o = Obstacles(WORLD)
    assert o.touching((17.9, 0.0, 5.0)) is None
    assert o.touching((18.0, 0.0, 5.0)) == "mast"
    assert o.touching((16.5, 0.0, 5.0), margin=1.5) == "mast"
    assert o.touching((5.0, 35.0, 3.0)) == "shed"
    assert o.touching((5.0, 35.0, 6.0)) is None  # above the shed's roof
    assert o.touching((5.0, 35.0, 5.0), margin=1.5) == "shed"


def test_nearest_obstacle_at_this_height():
    o = Obstacles(WORLD)
    assert o.nearest((10.0, 0.0, 5.0)) == pytest.approx(8.0, abs=0.05)
    assert o.nearest((5.0, 25.0, 3.0)) == pytest.approx(5.0)  # the shed is nearer
    assert o.nearest((0.0, 0.0, 30.0)) is None
    assert Obstacles(World()).nearest((0.0, 0.0, 1.0)) is None
