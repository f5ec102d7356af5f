"""When the camera takes pictures: on command, in series, every N metres; and what a
vehicle without a camera answers."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.camera import Camera
from sitl.params import AUTOPILOT_DEFAULTS, Params
from sitl.results import Result


def camera(fitted: bool = True) -> Camera:
    return Camera(Params(AUTOPILOT_DEFAULTS, {"CAM1_TYPE": 1 if fitted else 0}))


def p(*values: float) -> list[float]:
    return [*values, *[0.0] * (7 - len(values))]


def test_digicam_control_shoots_only_when_asked_to():
    c = camera()
    assert c.command(M.MAV_CMD_DO_DIGICAM_CONTROL, p(0, 0, 0, 0, 1), 0.0, (0, 0, 0)) == (
        Result.ACCEPTED, 1)
    assert c.command(M.MAV_CMD_DO_DIGICAM_CONTROL, p(), 0.0, (0, 0, 0)) == (Result.ACCEPTED, 0)


def test_a_series_takes_count_pictures_interval_apart_or_runs_until_stopped():
    c = camera()
    assert c.command(M.MAV_CMD_IMAGE_START_CAPTURE, p(0, 2, 3), 10.0, (0, 0, 0))[1] == 1
    shots = [t / 10 for t in range(100, 200) if c.update(t / 10, (0, 0, 0))]
    assert shots == [12.0, 14.0]
    c.command(M.MAV_CMD_IMAGE_START_CAPTURE, p(0, 1, 0), 20.0, (0, 0, 0))
    assert sum(c.update(20 + t / 10, (0, 0, 0)) for t in range(1, 51)) == 5
    c.command(M.MAV_CMD_IMAGE_STOP_CAPTURE, p(), 25.0, (0, 0, 0))
    assert sum(c.update(25 + t / 10, (0, 0, 0)) for t in range(1, 51)) == 0


def test_distance_trigger_shoots_every_n_metres_moved_and_sets_the_parameter():
    c = camera()
    assert c.command(M.MAV_CMD_DO_SET_CAM_TRIGG_DIST, p(5, 0, 1), 0.0, (0, 0, 10)) == (
        Result.ACCEPTED, 1)
    assert c.params["CAM1_TRIGG_DIST"] == 5.0
    along = [c.update(t, (0.5 * t, 0.0, 10.0)) for t in range(1, 41)]  # 20 m north
    assert [t for t, n in enumerate(along, start=1) if n] == [10, 20, 30, 40]
    assert c.update(41, (20.0, 0.0, 0.0)) == 0  # straight down: no horizontal move
    c.command(M.MAV_CMD_DO_SET_CAM_TRIGG_DIST, p(0), 42.0, (20, 0, 10))
    assert sum(c.update(t, (t, 0.0, 10.0)) for t in range(43, 80)) == 0


def test_a_series_takes_the_place_of_the_distance_trigger_while_it_runs():
    c = camera()
    c.params.set("CAM1_TRIGG_DIST", 1)
    c.command(M.MAV_CMD_IMAGE_START_CAPTURE, p(0, 5, 2), 0.0, (0, 0, 0))
    shots = [t for t in range(1, 11) if c.update(t, (float(t) * 3, 0.0, 10.0))]
    assert shots[0] == 5  # the series' second picture; no distance shot before it
    assert shots[1:] == list(range(6, 11))  # then every 3 m moved, the series over


def test_a_ground_station_may_set_the_trigger_distance_directly():
    c = camera()
    c.params.set("CAM1_TRIGG_DIST", 10)
    shots = [t for t in range(0, 40) if c.update(t, (float(t), 0.0, 10.0))]
    assert shots == [10, 20, 30]


def test_without_a_camera_commands_answer_as_arducopter_sitl_and_nothing_is_taken():
    c = camera(fitted=False)
    answers = {command: c.command(command, p(10, 1, 1, 0, 1), 0.0, (0, 0, 0)) for command in (
        M.MAV_CMD_DO_DIGICAM_CONTROL, M.MAV_CMD_IMAGE_START_CAPTURE,
        M.MAV_CMD_IMAGE_STOP_CAPTURE, M.MAV_CMD_DO_SET_CAM_TRIGG_DIST)}
    assert answers == {M.MAV_CMD_DO_DIGICAM_CONTROL: (Result.ACCEPTED, 0),
                       M.MAV_CMD_IMAGE_START_CAPTURE: (Result.FAILED, 0),
                       M.MAV_CMD_IMAGE_STOP_CAPTURE: (Result.ACCEPTED, 0),
                       M.MAV_CMD_DO_SET_CAM_TRIGG_DIST: (Result.ACCEPTED, 0)}
    assert c.params["CAM1_TRIGG_DIST"] == 0.0
    c.params.set("CAM1_TRIGG_DIST", 1)
    assert sum(c.update(t, (float(t) * 5, 0.0, 10.0)) for t in range(20)) == 0


def test_cam1_type_counts_from_the_boot():
    c = camera(fitted=False)
    c.params.set("CAM1_TYPE", 1)
    assert c.command(M.MAV_CMD_IMAGE_START_CAPTURE, p(0, 0, 1), 0.0, (0, 0, 0)) == (
        Result.FAILED, 0)
    assert Camera(c.params).fitted


def test_no_picture_while_the_shutter_is_held_for_the_last_one():
    c = camera()  # CAM1_DURATION 0.1 s, as ArduCopter SITL's
    assert c.command(M.MAV_CMD_DO_DIGICAM_CONTROL, p(0, 0, 0, 0, 1), 1.0, (0, 0, 0)) == (
        Result.ACCEPTED, 1)
    assert c.command(M.MAV_CMD_IMAGE_START_CAPTURE, p(0, 0, 1), 1.05, (0, 0, 0)) == (
        Result.FAILED, 0)
    assert c.command(M.MAV_CMD_DO_DIGICAM_CONTROL, p(0, 0, 0, 0, 1), 1.05, (0, 0, 0)) == (
        Result.ACCEPTED, 0)
    assert c.command(M.MAV_CMD_IMAGE_START_CAPTURE, p(0, 0, 1), 1.1, (0, 0, 0)) == (
        Result.ACCEPTED, 1)
    assert c.command(M.MAV_CMD_IMAGE_START_CAPTURE, p(0, 1, 2), 1.15, (0, 0, 0)) == (
        Result.ACCEPTED, 0)  # a series waits for the shutter
    assert [t for t in (1.2, 1.25, 2.1, 2.2, 3.0) if c.update(t, (0, 0, 0))] == [1.2, 2.2]
