"""The camera's answers and CAMERA_FEEDBACK on ArduCopter SITL and on the simulator.

ArduCopter 4.7 reads ``CAM1_TYPE`` at boot only, and its defaults file does not set it:
the camera vehicle is given it over MAVLink and rebooted (run without ``--wipe``). A plain
pymavlink client then, on the ground once the GPS has its fix, takes a picture with
DO_DIGICAM_CONTROL (shot 1) and one with IMAGE_START_CAPTURE (one picture), and sets a
trigger distance; on both vehicles each command must be answered alike and each picture
must send one CAMERA_FEEDBACK with the same numbering and fields, from where the vehicle
is. Without a camera both must answer alike and send no CAMERA_FEEDBACK. The commands are
half a second of the vehicle's time apart: within CAM1_DURATION (0.1 s) of a picture
ArduCopter takes none (a unit test covers that in the simulator).
"""

from __future__ import annotations

from typing import Any

from ground_station import GroundStation, M, python_sitl

SPEEDUP = 5.0


def _pictures(address: str) -> list[tuple[Any, ...]]:
    """Per command: (command, result, CAMERA_FEEDBACK's img_idx, cam_idx, flags,
    completed_captures, metres from the vehicle, metres above home), None fields when no
    feedback came."""
    station = GroundStation(address, timeout=60.0)
    answers: list[tuple[Any, ...]] = []
    try:
        station.connect()
        here = station.wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT" and m.lat != 0,
                            "a GPS position")
        for command, params in ((M.MAV_CMD_DO_DIGICAM_CONTROL, (0, 0, 0, 0, 1)),
                                (M.MAV_CMD_IMAGE_START_CAPTURE, (0, 0, 1)),
                                (M.MAV_CMD_DO_SET_CAM_TRIGG_DIST, (25, 0, 0))):
            # Half a second of the vehicle's time apart: the shutter is held 0.1 s.
            after = here.time_boot_ms + 500
            here = station.wait(lambda m, after=after: m.get_type() == "GLOBAL_POSITION_INT"
                                and m.time_boot_ms >= after, "half a second on")
            station.command(command, *params)
            result = station.ack(command)
            feedback = None
            if command != M.MAV_CMD_DO_SET_CAM_TRIGG_DIST:
                try:
                    feedback = station.wait(lambda m: m.get_type() == "CAMERA_FEEDBACK",
                                            "CAMERA_FEEDBACK", timeout=3.0)
                except AssertionError:
                    feedback = None
            if feedback is None:
                answers.append((command, result, None, None, None, None, None, None))
                continue
            apart = 111_320 * max(abs(feedback.lat - here.lat), abs(feedback.lng - here.lon)) / 1e7
            answers.append((command, result, feedback.img_idx, feedback.cam_idx, feedback.flags,
                            feedback.completed_captures, round(apart), round(feedback.alt_rel)))
    finally:
        station.close()
    return answers


def test_pictures_send_the_same_camera_feedback_on_arducopter_and_the_simulator(
        ardupilot: Any) -> None:
    (sitl,) = ardupilot(speedup=SPEEDUP, reboot_params={"CAM1_TYPE": 1})
    arducopter = _pictures(sitl.address)
    with python_sitl(SPEEDUP) as address:
        simulator = _pictures(address)
    print("ArduCopter", arducopter, "simulator", simulator)
    accepted = M.MAV_RESULT_ACCEPTED
    assert arducopter == simulator == [
        (M.MAV_CMD_DO_DIGICAM_CONTROL, accepted, 1, 0, M.CAMERA_FEEDBACK_PHOTO, 0, 0, 0),
        (M.MAV_CMD_IMAGE_START_CAPTURE, accepted, 2, 0, M.CAMERA_FEEDBACK_PHOTO, 0, 0, 0),
        (M.MAV_CMD_DO_SET_CAM_TRIGG_DIST, accepted, None, None, None, None, None, None)]


def test_without_a_camera_arducopter_and_the_simulator_answer_alike(ardupilot: Any) -> None:
    (sitl,) = ardupilot(speedup=SPEEDUP)
    arducopter = _pictures(sitl.address)
    with python_sitl(SPEEDUP, "--param", "CAM1_TYPE=0") as address:
        simulator = _pictures(address)
    print("ArduCopter", arducopter, "simulator", simulator)
    none = (None,) * 6
    assert arducopter == simulator == [
        (M.MAV_CMD_DO_DIGICAM_CONTROL, M.MAV_RESULT_ACCEPTED, *none),
        (M.MAV_CMD_IMAGE_START_CAPTURE, M.MAV_RESULT_FAILED, *none),
        (M.MAV_CMD_DO_SET_CAM_TRIGG_DIST, M.MAV_RESULT_ACCEPTED, *none)]
