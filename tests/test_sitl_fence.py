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


def test_uploaded_zones_are_polygons_and_circles_to_be_inside_or_out_of():
    items = [(5001, 4, corner) for corner in ((0, 0), (0, 100), (100, 100), (100, 0))]
    items += [(5004, 10.0, (50.0, 50.0))]
    items += [(5002, 3, corner) for corner in ((80, 80), (80, 95), (95, 95))]
    items += [(5003, 200.0, (0.0, 0.0))]
    inclusions, exclusions = fence.uploaded_zones(items)
    assert (len(inclusions), len(exclusions)) == (2, 2)
    home = (0.0, 0.0, 0.0)

    def at(north: float, east: float) -> str:
        return fence.breach((north, east, 10), params(), home, inclusions[0],
                            inclusions=inclusions[1:], exclusions=exclusions)

    assert at(20, 20) == ""
    assert at(52, 48) == "exclusion zone"  # inside the circle
    assert at(85, 90) == "exclusion zone"  # inside the excluded triangle
    assert at(-5, 20) == "polygon"
    assert fence.breach((52, 48, 10), params(FENCE_TYPE=1), home, inclusions[0],
                        exclusions=exclusions) == ""  # zones only with bit 4


def test_a_polygon_short_of_its_count_is_left_out():
    inclusions, exclusions = fence.uploaded_zones(
        [(5002, 4, (0, 0)), (5002, 4, (0, 10)), (5002, 4, (10, 10)),
         (5004, 5.0, (50, 50))])
    assert inclusions == [] and len(exclusions) == 1
