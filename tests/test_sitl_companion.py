"""The companion computer: skills switched by PARAM_SET on component 191, detections reported."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.companion import Companion, object_numbers
from tml.world import World, WorldObject

ARUCO = WorldObject("aruco", "7", 10.0, 0.0)
ITEM = WorldObject("item", "red ball", 10.0, 2.0)
FAR = WorldObject("aruco", "9", 200.0, 0.0)
WORLD = World(objects=(ARUCO, ITEM, FAR))


def companion() -> Companion:
    return Companion(1, WORLD, lambda position: None)


def switch(c: Companion, name: str, value: float) -> list:
    return c.handle(M.MAVLink_param_set_message(1, 191, name.encode(), value, 2))


def detections(messages: list) -> list[tuple[str, int]]:
    return [(m.name, m.value) for m in messages if m.get_type() == "NAMED_VALUE_INT"]


def test_nothing_is_reported_until_a_skill_is_on():
    c = companion()
    out = c.step(1.0, (10.0, 0.0, 10.0), 0.0)
    assert detections(out) == []
    assert [m.get_type() for m in out] == ["HEARTBEAT"]
    assert out[0].type == M.MAV_TYPE_ONBOARD_CONTROLLER and out[0].get_srcComponent() == 191


def test_aruco_skill_reports_markers_in_the_footprint_only():
    c = companion()
    (echo,) = switch(c, "RECOG_ARUCO", 1)
    assert echo.param_id == "RECOG_ARUCO" and echo.param_value == 1
    out = c.step(1.0, (10.0, 0.0, 10.0), 0.0)
    assert detections(out) == [("ARUCO", 7)]
    (vector,) = [m for m in out if m.get_type() == "DEBUG_VECT"]
    assert (vector.name, vector.x, vector.y) == ("ARUCO", 10.0, 0.0)
    assert "Detected aruco 7 7" in [m.text for m in out if m.get_type() == "STATUSTEXT"]
    assert detections(c.step(2.0, (100.0, 0.0, 10.0), 0.0)) == []  # out of view
    assert detections(c.step(3.0, (10.0, 0.0, 60.0), 0.0)) == []  # beyond CAM_RANGE
    switch(c, "RECOG_ARUCO", 0)
    assert detections(c.step(4.0, (10.0, 0.0, 10.0), 0.0)) == []


def test_items_are_numbered_by_rank_and_self_location_uses_markers():
    c = companion()
    switch(c, "RECOG_ITEMS", 1)
    switch(c, "SELF_LOCATE", 1)
    out = c.step(1.0, (10.0, 1.0, 10.0), 90.0)
    assert detections(out) == [("ITEM", 1)]
    (fix,) = [m for m in out if m.get_type() == "VISION_POSITION_ESTIMATE"]
    assert (fix.x, fix.y, fix.z) == (10.0, 1.0, -10.0)
    assert object_numbers(WORLD) == {ARUCO: 7, ITEM: 1, FAR: 9}


def test_parameters_are_listed_on_component_191():
    c = companion()
    names = {m.param_id for m in c.handle(M.MAVLink_param_request_list_message(1, 191))}
    assert {"AVOID_OBST", "RECOG_MARKERS", "RECOG_ARUCO", "SELF_LOCATE", "RECOG_ITEMS",
            "RECOG_BUCKETS", "CAM_HFOV", "DET_RATE"} <= names


def test_bucket_and_marker_skills_report_their_kinds_only():
    world = World(objects=(
        WorldObject("bucket", "blue", 10.0, 0.0), WorldObject("bucket", "3", 12.0, 0.0),
        WorldObject("marker", "H", 10.0, 1.0), WorldObject("frame", "red", 11.0, -1.0),
        WorldObject("aruco", "7", 10.0, 0.5),
    ))
    c = Companion(1, world, lambda position: None)
    over = (11.0, 0.0, 10.0)
    switch(c, "RECOG_BUCKETS", 1)
    out = c.step(1.0, over, 0.0)
    assert sorted(detections(out)) == [("BUCKET", 1), ("BUCKET", 3)]
    assert "Detected bucket 1 blue" in [m.text for m in out if m.get_type() == "STATUSTEXT"]
    switch(c, "RECOG_BUCKETS", 0)
    switch(c, "RECOG_MARKERS", 1)
    assert sorted(detections(c.step(2.0, over, 0.0))) == [("FRAME", 1), ("MARKER", 1)]
    assert detections(c.step(3.0, (11.0, 40.0, 10.0), 0.0)) == []  # all out of view


def test_without_a_position_only_the_heartbeat_goes_out():
    c = companion()
    switch(c, "RECOG_ARUCO", 1)
    assert [m.get_type() for m in c.step(1.0, None, 0.0)] == ["HEARTBEAT"]
    assert detections(c.step(1.6, (10.0, 0.0, 10.0), 0.0)) == [("ARUCO", 7)]
