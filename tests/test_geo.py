"""Local frame conversions (tml.geo)."""

from __future__ import annotations

import pytest

from tml import geo

HOME = (-35.363261, 149.165230, 584.0)


def test_round_trip() -> None:
    lat, lon, alt = geo.to_global(120.0, -45.0, 30.0, *HOME)
    north, east, up = geo.to_local(lat, lon, alt, *HOME)
    assert (north, east, up) == pytest.approx((120.0, -45.0, 30.0), abs=1e-6)


def test_axes() -> None:
    lat, lon, _ = geo.to_global(100.0, 0.0, 0.0, *HOME)
    assert lat > HOME[0] and lon == pytest.approx(HOME[1])
    lat, lon, _ = geo.to_global(0.0, 100.0, 0.0, *HOME)
    assert lon > HOME[1] and lat == pytest.approx(HOME[0], abs=1e-6)


def test_distances() -> None:
    assert geo.horizontal_distance((0, 0, 5), (3, 4, 50)) == 5
    assert geo.distance((0, 0, 0), (2, 3, 6)) == 7
