"""When the camera takes pictures: on command, in series, every N metres."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.camera import Camera
from sitl.params import AUTOPILOT_DEFAULTS, Params


def camera() -> Camera:
    return Camera(Params(AUTOPILOT_DEFAULTS))


def p(*values: float) -> list[float]:
    return [*values, *[0.0] * (7 - len(values))]


def test_digicam_control_shoots_only_when_asked_to():
    c = camera()
    assert c.command(M.MAV_CMD_DO_DIGICAM_CONTROL, p(0, 0, 0, 0, 1), 0.0, (0, 0, 0)) == 1
    assert c.command(M.MAV_CMD_DO_DIGICAM_CONTROL, p(), 0.0, (0, 0, 0)) == 0


def test_a_series_takes_count_pictures_interval_apart_or_runs_until_stopped():
    c = camera()
    assert c.command(M.MAV_CMD_IMAGE_START_CAPTURE, p(0, 2, 3), 10.0, (0, 0, 0)) == 1
    shots = [t / 10 for t in range(100, 200) if c.update(t / 10, (0, 0, 0), False)]
    assert shots == [12.0, 14.0]
    c.command(M.MAV_CMD_IMAGE_START_CAPTURE, p(0, 1, 0), 20.0, (0, 0, 0))
    assert sum(c.update(20 + t / 10, (0, 0, 0), False) for t in range(1, 51)) == 5
    c.command(M.MAV_CMD_IMAGE_STOP_CAPTURE, p(), 25.0, (0, 0, 0))
    assert sum(c.update(25 + t / 10, (0, 0, 0), False) for t in range(1, 51)) == 0


def test_distance_trigger_shoots_every_n_metres_flown_and_sets_the_parameter():
    c = camera()
    assert c.command(M.MAV_CMD_DO_SET_CAM_TRIGG_DIST, p(5, 0, 1), 0.0, (0, 0, 10)) == 1
    assert c.params["CAM_TRIGG_DIST"] == 5.0
    along = [c.update(t, (0.5 * t, 0.0, 10.0), True) for t in range(1, 41)]  # 20 m north
    assert [t for t, n in enumerate(along, start=1) if n] == [10, 20, 30, 40]
    assert c.update(41, (40.0, 0.0, 10.0), False) == 0  # on the ground: never
    c.command(M.MAV_CMD_DO_SET_CAM_TRIGG_DIST, p(0), 42.0, (40, 0, 10))
    assert sum(c.update(t, (t, 0.0, 10.0), True) for t in range(43, 80)) == 0


def test_a_ground_station_may_set_the_trigger_distance_directly():
    c = camera()
    c.params.set("CAM_TRIGG_DIST", 10)
    shots = [t for t in range(0, 40) if c.update(t, (float(t), 0.0, 10.0), True)]
    assert shots == [10, 20, 30]
