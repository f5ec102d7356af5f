"""Local frame conversions (tml.geo)."""

from __future__ import annotations

import pymap3d
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


@settings(max_examples=300, deadline=None)
@given(
    home=st.tuples(st.floats(-89.0, 89.0), st.floats(-180.0, 180.0), st.floats(-400.0, 8000.0)),
    point=st.tuples(st.floats(-90e3, 90e3), st.floats(-90e3, 90e3), st.floats(-1000.0, 9000.0)),
)
def test_conversions_agree_with_pymap3d(home: tuple[float, float, float],
                                        point: tuple[float, float, float]) -> None:
    """tml.geo computes pymap3d's enu2geodetic and geodetic2enu (the same formulas on floats)."""
    north, east, up = point
    expected = [float(v) for v in pymap3d.enu2geodetic(east, north, up, *home)]
    assert geo.to_global(north, east, up, *home) == pytest.approx(expected, rel=0, abs=1e-8)
    e, n, u = (float(v) for v in pymap3d.geodetic2enu(*expected, *home))
    assert geo.to_local(*expected, *home) == pytest.approx((n, e, u), rel=0, abs=1e-6)


def test_points_at_the_poles_and_the_centre() -> None:
    """The closed form's special cases, as pymap3d takes them: straight above a pole, and
    the Earth's centre (latitude 0, an altitude of minus the semi-major axis)."""
    assert geo.to_global(0.0, 0.0, 100.0, 90.0, 0.0, 0.0) == pytest.approx((90.0, 0.0, 100.0))
    centre = geo.to_global(0.0, 0.0, -geo.SEMIMAJOR, 0.0, 0.0, 0.0)
    assert centre == pytest.approx((0.0, 0.0, -geo.SEMIMAJOR))
