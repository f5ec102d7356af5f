"""The mission's fence and rally points as the items and parameters put on a vehicle."""

from __future__ import annotations

from dataclasses import replace

import pytest

from tml import geo
from tml.mavlink.mission import MissionType, ardupilot_form, read_back_differences
from tml.mavlink.safeguards import fence_action, has_safeguards, safeguards
from tml.world import (
    DEFAULT_HOME,
    Cylinder,
    Geofence,
    Home,
    Prism,
    RallyPoint,
    World,
)

SQUARE = ((-100.0, -100.0), (100.0, -100.0), (100.0, 100.0), (-100.0, 100.0))
WORLD = World(
    geofence=Geofence(SQUARE, min_altitude=2.0, max_altitude=60.0),
    obstacles=(Cylinder("mast", 30.0, 0.0, 3.0),
               Prism("block", ((50.0, 50.0), (60.0, 50.0), (60.0, 60.0)), top=80.0),
               Prism("hangar", ((-50.0, -50.0), (-40.0, -50.0), (-40.0, -40.0)), top=8.0),
               Cylinder("bridge", 0.0, 50.0, 5.0, bottom=20.0)),
    rally=(RallyPoint(-20.0, 10.0, 15.0), RallyPoint(20.0, -10.0, 25.4)),
)


def local(item, home: Home = DEFAULT_HOME) -> tuple[float, float]:
    north, east, _ = geo.to_local(item.x / 1e7, item.y / 1e7, home.altitude, home.latitude,
                                  home.longitude, home.altitude)
    return north, east


def test_the_geofence_and_the_obstacles_that_reach_the_sky_become_the_fence() -> None:
    put = safeguards(WORLD, DEFAULT_HOME)
    commands = [item.command for item in put.fence]
    assert commands == [5001] * 4 + [5004] + [5002] * 3
    assert [item.seq for item in put.fence] == list(range(8))
    assert {item.mission_type for item in put.fence} == {MissionType.FENCE}
    assert [item.param1 for item in put.fence] == [4] * 4 + [3.0] + [3] * 3
    for item, corner in zip(put.fence, SQUARE, strict=False):
        assert local(item) == pytest.approx(corner, abs=0.02)
    assert local(put.fence[4]) == pytest.approx((30.0, 0.0), abs=0.02)
    # The hangar can be flown over and the bridge under: ArduPilot's zones reach the sky.
    assert put.left_out == ["hangar (can be flown over)", "bridge (can be flown under)"]
    assert put.parameters == {"FENCE_ALT_MAX": 60.0, "FENCE_TYPE": 5, "FENCE_ENABLE": 1}
    assert "FENCE_ALT_MIN" not in put.parameters  # a copter takes off below it
    assert put.summary.startswith("inclusion polygon of 4 corners; exclusion circle mast; ")


def test_rally_points_are_relative_altitudes_around_the_vehicles_home() -> None:
    elsewhere = Home(48.0, 11.0, 500.0)
    put = safeguards(WORLD, elsewhere)
    assert [(item.command, item.frame, item.z) for item in put.rally] == [
        (5100, 3, 15.0), (5100, 3, 25.4)]
    assert {item.mission_type for item in put.rally} == {MissionType.RALLY}
    assert local(put.rally[0], elsewhere) == pytest.approx((-20.0, 10.0), abs=0.02)
    assert "2 rally points" in put.summary


def test_keeping_the_vehicles_fence_uploads_the_rally_points_only() -> None:
    put = safeguards(WORLD, DEFAULT_HOME, fence=False)
    assert (put.fence, put.parameters, len(put.rally)) == ([], {}, 2)
    assert not put.has_fence


def test_a_ceiling_alone_needs_no_items() -> None:
    put = safeguards(World(geofence=Geofence(max_altitude=50.0)), DEFAULT_HOME)
    assert put.fence == [] and put.parameters == {"FENCE_ALT_MAX": 50.0, "FENCE_TYPE": 1,
                                                  "FENCE_ENABLE": 1}
    assert not has_safeguards(None) and not has_safeguards(World())
    assert has_safeguards(World(rally=(RallyPoint(0, 0, 10),)))


def test_what_arducopter_reads_back_of_them_matches() -> None:
    put = safeguards(WORLD, DEFAULT_HOME)
    # ArduPilot reads fences back without altitude and rally altitudes in whole metres.
    fence_back = [replace(item, z=0.0, autocontinue=0) for item in put.fence]
    rally_back = [replace(item, z=float(int(item.z)), autocontinue=0) for item in put.rally]
    assert read_back_differences(put.fence, fence_back, ardupilot_form) == []
    assert read_back_differences(put.rally, rally_back, ardupilot_form) == []


def test_the_vehicles_fence_action_is_said_and_report_only_is_a_warning() -> None:
    assert fence_action(1.0) == "FENCE_ACTION 1 (RTL or land)"
    assert fence_action(0.0) == "FENCE_ACTION 0 (report only): a breach is only reported"
    assert fence_action(None) == "FENCE_ACTION not reported"
    assert fence_action(9.0) == "FENCE_ACTION 9 (unknown)"
