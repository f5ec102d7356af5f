"""Which fence limit a position breaks."""

from __future__ import annotations

from sitl import fence
from sitl.params import AUTOPILOT_DEFAULTS, Params
from tml.world import Geofence, World

SQUARE = World(geofence=Geofence(polygon=((-50, -50), (-50, 50), (50, 50), (50, -50))))


def params(**values: float) -> Params:
    return Params(AUTOPILOT_DEFAULTS, {"FENCE_ALT_MAX": 100, "FENCE_RADIUS": 300, **values})


def test_each_enabled_limit_is_named():
    polygon = fence.world_polygon(SQUARE)
    home = (0.0, 0.0, 0.0)
    assert fence.breach((0, 0, 50), params(), home, polygon) == ""
    assert fence.breach((0, 0, 120), params(), home, polygon) == "maximum altitude"
    assert fence.breach((0, 0, 50), params(), home, polygon, ceiling=40) == "maximum altitude"
    assert fence.breach((60, 0, 50), params(), home, polygon) == "polygon"
    assert fence.breach((310, 0, 50), params(), home, None) == "circle"
    assert fence.breach((310, 0, 50), params(), (100.0, 0.0, 0.0), None) == ""  # around home
    assert fence.breach((0, 0, 120), params(FENCE_TYPE=6), home, polygon) == ""  # no altitude


def test_an_uploaded_polygon_replaces_the_worlds():
    assert fence.world_polygon(World()) is None
    uploaded = fence.inclusion_polygon([(0, 0), (0, 100), (100, 100), (100, 0)], SQUARE)
    assert fence.breach((75, 75, 10), params(), (0, 0, 0), uploaded) == ""
    kept = fence.inclusion_polygon([(0, 0), (0, 100)], SQUARE)  # too few vertices
    assert fence.breach((75, 75, 10), params(), (0, 0, 0), kept) == "polygon"
