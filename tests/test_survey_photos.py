"""SURVEY_PHOTOS (tml.actions.survey_photos): the plan from the camera, the photos predicted
by distance, the GUIDED procedure, the mission items flown in the simulator, the item time
and the motion model of ``tml verify``."""

from __future__ import annotations

import math
import re

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M
from test_engine_interpreter import Flight
from test_mavlink_compile import act, compiled, fly, local

from tml.actions import areas, survey_photos
from tml.actions.guided import Limits
from tml.actions.motion import PredictedState
from tml.engine import Status
from tml.language.kinds import Kind, refusal
from tml.mavlink.compile import CompileError
from tml.verify.constraints import assess_action
from tml.verify.profile import load_profile

CAMERA = {"sensor_width": "6.17", "sensor_height": "4.55", "focal_length": "4.5"}
"""A 1/2.3-inch sensor behind a 4.5 mm lens."""


def _survey(**values: str):  # type: ignore[no-untyped-def]
    return act("SURVEY_PHOTOS", **CAMERA, **values)


# --- the plan -----------------------------------------------------------------------------

def test_the_passes_and_the_trigger_distance_come_from_the_footprint_and_the_overlaps() -> None:
    plan = survey_photos.photo_plan(_survey(length="40", width="20", altitude="20",
                                            front_overlap="75", side_overlap="50"), 5.0)
    across, along = 20 * 6.17 / 4.5, 20 * 4.55 / 4.5
    assert plan.altitude == 20
    assert plan.footprint == pytest.approx((across, along))
    assert plan.spacing == pytest.approx(across * 0.5)
    assert plan.trigger_distance == pytest.approx(along * 0.25)


@pytest.mark.parametrize(("values", "apart"), [
    ({"sensor_width": "0.0001"}, "passes 0.000178 m apart"),  # a cloud of passes
    ({"sensor_height": "0.0001"}, "photos 0.000133 m apart"),  # ... and of photos
    ({"altitude": "1000", "focal_length": "0.001"}, "passes 2.47e+06 m apart"),
])
def test_passes_or_photos_closer_or_farther_than_a_surveys_passes_may_be_are_refused(
        values: dict[str, str], apart: str) -> None:
    bound = act("SURVEY_PHOTOS", **{**CAMERA, "length": "40", "width": "20",
                                    "altitude": "20", **values})
    with pytest.raises(ValueError, match=re.escape(f"would take its {apart}, outside 0.5 to "
                                                   "10000 m")):
        survey_photos.photo_plan(bound, 20.0)


def test_a_ground_resolution_sets_the_altitude_and_none_keeps_the_current_one() -> None:
    bound = _survey(length="40", width="20", ground_resolution="2", image_width="4000")
    assert survey_photos.photo_plan(bound, 5.0).altitude == pytest.approx(
        0.02 * 4.5 * 4000 / 6.17)
    assert survey_photos.photo_plan(_survey(length="40", width="20"), 17.0).altitude == 17


def test_photos_are_taken_each_time_the_vehicle_is_the_distance_from_the_last() -> None:
    line = survey_photos.photo_points([(0.0, 0.0, 10.0), (30.0, 0.0, 10.0)], 10.0)
    assert [p[0] for p in line] == pytest.approx([0, 10, 20, 30])
    # Round a corner the distance is the straight line from the last photo, as ArduPilot
    # measures it, not the path flown: from (8, 0), 8 m is reached at (10, sqrt(60)).
    corner = survey_photos.photo_points([(0.0, 0.0, 5.0), (10.0, 0.0, 5.0),
                                         (10.0, 10.0, 5.0)], 8.0)
    assert len(corner) == 3
    assert corner[1][:2] == pytest.approx((8, 0))
    assert corner[2][:2] == pytest.approx((10, math.sqrt(60)))
    assert survey_photos.photo_points([(0.0, 0.0, 5.0), (1.0, 0.0, 5.0)], 0.0) == []


# --- GUIDED -------------------------------------------------------------------------------

def test_the_trigger_is_set_at_the_base_point_and_cleared_after_the_last_pass() -> None:
    body = ('<task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="20"/>'
            '</action></task><task name="Photos"><action name="SURVEY_PHOTOS">'
            + "".join(f'<argument name="{k}" value="{v}"/>' for k, v in CAMERA.items())
            + '<argument name="coordinates" value="(10, 0, 0)"/>'
            '<argument name="length" value="30"/><argument name="width" value="20"/>'
            '<argument name="direction" value="NORTH_EAST"/>'
            '<argument name="altitude" value="20"/></action></task>')
    flight = Flight(body).run(600)
    assert flight.interp.status is Status.COMPLETED
    sent = [r for r in flight.requests if type(r).__name__ in ("GoTo", "Camera")]
    plan = survey_photos.photo_plan(_survey(length="30", width="20", altitude="20"), 20.0)
    passes = survey_photos.passes((10.0, 0.0, 20.0), _survey(length="30", width="20",
                                                             direction="NORTH_EAST"), plan)
    cameras = [i for i, r in enumerate(sent) if type(r).__name__ == "Camera"]
    assert cameras == [1, len(sent) - 1]
    assert sent[0].target == passes[0]
    assert sent[1].operation == "distance"
    assert sent[1].distance == pytest.approx(plan.trigger_distance)
    assert [r.target for r in sent[2:-1]] == passes[1:]
    assert (sent[-1].operation, sent[-1].distance) == ("distance", 0.0)


# --- mission items ------------------------------------------------------------------------

def test_its_items_set_the_trigger_at_the_base_and_clear_it_once_the_last_pass_is_flown(
        ) -> None:
    bound = _survey(coordinates="(10, 0, 0)", length="30", width="20", altitude="20",
                    direction="NORTH_EAST")
    plan = survey_photos.photo_plan(bound, 10.0)
    passes = survey_photos.passes((10.0, 0.0, 20.0), bound, plan)
    items = compiled(bound).items
    commands = [i.command for i in items]
    wp, trigger = M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_DO_SET_CAM_TRIGG_DIST
    assert commands == [wp, trigger, *[wp] * (len(passes) - 1), wp, trigger]
    assert local(items[0]) == pytest.approx(passes[0], abs=0.05)
    assert (items[1].param1, items[1].param3) == (pytest.approx(plan.trigger_distance), 1)
    assert local(items[-2]) == local(items[-3]) == pytest.approx(passes[-1], abs=0.05)
    assert (items[-1].param1, items[-1].param3) == (0, 0)


def test_the_items_flown_in_the_simulator_take_the_photos_verify_predicts() -> None:
    bound = _survey(coordinates="(10, 0, 0)", length="30", width="20", altitude="15",
                    direction="NORTH_EAST")
    plan = compiled(act("TAKE_OFF", altitude="15"), bound, act("LAND"), start=(0, 0, 0))
    _, out = fly(plan.items, limit=900)
    photos = [m for m in out if m.get_type() == "CAMERA_FEEDBACK"]
    step = assess_action(bound, PredictedState(position=(0.0, 0.0, 15.0), flying=True),
                         load_profile("quadcopter")).step
    assert len(step.photos) > 10
    assert abs(len(photos) - len(step.photos)) <= 1


def test_the_item_time_is_the_lawnmower_at_the_planned_spacing() -> None:
    limits = Limits(speed=5.0)
    bound = _survey(length="40", width="20", altitude="20")
    spacing = survey_photos.photo_plan(bound, 0.0).spacing
    assert survey_photos.survey_photos_time(limits, "", (0.0, 0.0, 20.0), bound) \
        == areas.lawnmower_time(limits, "", (0.0, 0.0, 20.0), bound, spacing)
    assert spacing < 20  # more passes than one each side: the time counts them


# --- tml verify ---------------------------------------------------------------------------

def test_verify_predicts_the_photos_along_the_passes_and_says_how_many() -> None:
    bound = _survey(coordinates="(10, 0, 0)", length="40", width="20", altitude="20",
                    direction="NORTH_EAST")
    step = assess_action(bound, PredictedState(position=(0.0, 0.0, 20.0), flying=True),
                         load_profile("quadcopter")).step
    plan = survey_photos.photo_plan(bound, 20.0)
    expected = survey_photos.photo_points(
        survey_photos.passes((10.0, 0.0, 20.0), bound, plan), plan.trigger_distance)
    assert step.photos == tuple(expected)
    assert step.photos[0] == (10.0, 0.0, 20.0)
    assert any(note.startswith(f"{len(expected)} photos predicted, one every "
                               f"{plan.trigger_distance:.1f} m") for note in step.notes)


# --- what cannot be photographed ------------------------------------------------------------

def test_a_ground_vehicle_cannot_photograph_an_area() -> None:
    bound = _survey(length="40", width="20")
    reason = refusal(bound, Kind.GROUND, "rover")
    assert reason is not None and reason.startswith("a rover has no altitude")
    assert refusal(bound, Kind.MULTICOPTER) is None


def test_below_a_metre_it_is_refused_with_why_not_a_traceback() -> None:
    bound = _survey(length="40", width="20")  # no altitude: where the vehicle is
    with pytest.raises(CompileError, match=r"SURVEY_PHOTOS would photograph from 0\.0 m"):
        compiled(bound, start=(0.0, 0.0, 0.0))
    step = assess_action(bound, PredictedState(position=(0.0, 0.0, 0.5), flying=True),
                         load_profile("quadcopter")).step
    assert step.photos == ()
    assert any("below 1 m" in note and note.endswith("not predicted") for note in step.notes)
    flight = Flight('<task name="Up"><action name="TAKE_OFF"><argument name="altitude" '
                    'value="0.6"/></action></task><task name="Photos"><action '
                    'name="SURVEY_PHOTOS">'
                    + "".join(f'<argument name="{k}" value="{v}"/>' for k, v in CAMERA.items())
                    + '<argument name="length" value="30"/><argument name="width" value="20"/>'
                    '</action></task>').run(120)
    assert flight.interp.status is Status.ABORTED
    failed = [r.data for r in flight.records if r.kind == "action" and "reason" in r.data]
    assert [(f["action"], f["reason"]) for f in failed] == [("SURVEY_PHOTOS", "infeasible")]
    assert failed[0]["detail"].startswith("SURVEY_PHOTOS would photograph from 0.")
    assert not [r for r in flight.requests if type(r).__name__ == "Camera"]
