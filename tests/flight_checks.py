"""Checks of a flight log shared by the simulator's flight tests and the interop suite."""

from __future__ import annotations

import math


def check_imav2016(lines: list[dict]) -> None:
    """missions/imav2016.xml flown to its end: item A and bucket A recognised by the
    companion's skills and memorized near where they lie, the item picked up and dropped
    (both gripper commands accepted), the transport done, the landing at the operating zone.
    """
    fired = [line["event"] for line in lines if line["kind"] == "event"]
    assert set(fired) == {"Bucket A found", "Item A found"}  # via RECOGNIZE_ITEMS/BUCKETS
    skills = {(line["skill"], line["enabled"]) for line in lines
              if line["kind"] == "request" and line["message"] == "SetSkill"}
    assert {("RECOGNIZE_ITEMS", True), ("RECOGNIZE_BUCKETS", True)} <= skills
    memorized = {line["label"]: line["point"] for line in lines
                 if line["kind"] == "decision" and line["message"].startswith("memorized")}
    assert math.dist(memorized["item A coordinates"][:2], (8, 2)) < 2.5  # seen from above
    assert math.dist(memorized["bucket A coordinates"][:2], (8, -2)) < 2.5
    grips = [line for line in lines if line["kind"] == "request" and line["message"] == "Gripper"]
    assert [g["grab"] for g in grips] == [True, False]
    ok = {line["request_id"] for line in lines if line["kind"] == "result" and line["ok"]}
    assert all(g["request_id"] in ok for g in grips)
    states = {line["task"]: line["state"] for line in lines if line["kind"] == "task"}
    assert states["Transport item A"] == "done"
    landed = [line for line in lines if line["kind"] == "telemetry" and line["landed"]
              and line["position"] is not None][-1]
    zone = memorized["operating zone"]
    assert math.dist(landed["position"][:2], zone[:2]) < 1.0


def check_catalogue_tour(lines: list[dict]) -> None:
    """missions/catalogue_tour.xml flown to its end: the window seen during the survey, the
    crate and the bin recognised and memorized, the crate delivered with the gripper."""
    fired = {line["event"] for line in lines if line["kind"] == "event"}
    assert {"Crate seen", "Bin seen", "Window seen during a survey"} <= fired
    memorized = {line["label"] for line in lines
                 if line["kind"] == "decision" and line["message"].startswith("memorized")}
    assert {"crate", "bin"} <= memorized
    states = {line["task"]: line["state"] for line in lines if line["kind"] == "task"}
    assert states["Inspection/Deliver the crate"] == "done"
    grips = [line for line in lines if line["kind"] == "request" and line["message"] == "Gripper"]
    assert [g["grab"] for g in grips] == [True, False]


def _telemetry(lines: list[dict], vehicle: int = 1) -> list[dict]:
    return [line for line in lines if line["kind"] == "telemetry"
            and line["position"] is not None and line["vehicle"] == vehicle]


def _done(lines: list[dict]) -> dict[str, tuple[float, float]]:
    """task -> (start, end) mission time of the tasks done."""
    started = {line["task"]: line["t"] for line in lines
               if line["kind"] == "task" and line["state"] == "running"}
    return {line["task"]: (started[line["task"]], line["t"]) for line in lines
            if line["kind"] == "task" and line["state"] == "done" and line["task"] in started}


def check_plane_patrol(lines: list[dict]) -> None:
    """missions/plane_patrol.xml flown to its end: took off in TAKEOFF mode, flew the legs
    at speed, circled the point at about its radius, landed near home and disarmed."""
    done = _done(lines)
    assert {"Launch", "Patrol", "Orbit", "Over home", "Land"} <= set(done)
    telemetry = _telemetry(lines)
    # Never hovering: every airborne sample of the flight is at speed.
    flight = [line for line in telemetry if line["armed"] and not line["landed"]
              and line["position"][2] > 20]
    assert min(line["ground_speed"] for line in flight) > 15
    # The take-off is TAKEOFF mode, not GUIDED.
    modes = [line["mode"] for line in telemetry if line["armed"]]
    assert modes[0] == "TAKEOFF" and "GUIDED" not in modes[:modes.index("AUTO")]
    # The patrol legs reach 400 m north, then 400 m east. ArduPlane passes a waypoint
    # within WP_RADIUS at 25 m/s and the log samples the position once a second, so the
    # sample just after the last waypoint counts too.
    patrol = [line["position"] for line in telemetry
              if done["Patrol"][0] <= line["t"] <= done["Patrol"][1] + 2]
    assert max(p[0] for p in patrol) > 330 and max(p[1] for p in patrol) > 330
    # Two circles around (200, 400) at about their 80 m radius (ArduPlane flies them a
    # little wide).
    orbit = [line["position"] for line in telemetry
             if done["Orbit"][1] - 30 <= line["t"] <= done["Orbit"][1]]
    radii = [math.dist(p[:2], (200, 400)) for p in orbit]
    assert radii and all(60 < r < 120 for r in radii), radii
    # It lands along its approach and stops near home, on the ground and disarmed.
    landed = [line for line in telemetry if line["landed"] and line["t"] > done["Land"][0]]
    assert landed and math.dist(landed[0]["position"][:2], (0, 0)) < 100
    assert not telemetry[-1]["armed"]


def check_rover_delivery(lines: list[dict]) -> None:
    """missions/rover_delivery.xml flown to its end: drove at 0 m to both points, stood still
    unloading, slower on the second leg, ended at home disarmed, never asked to take off or
    land."""
    done = _done(lines)
    telemetry = _telemetry(lines)
    assert all(line["position"][2] == 0.0 for line in telemetry)  # no altitude, ever
    at = {task: min((line for line in telemetry if line["t"] >= end),
                    key=lambda line: line["t"])["position"] for task, (_, end) in done.items()}
    assert math.dist(at["To the drop point"][:2], (40, 0)) <= 3.5
    assert math.dist(at["Second drop/To the second point"][:2], (40, 25)) <= 3.5
    # Stopped while unloading (after slowing down from the drive: Rover brakes gently).
    unloading = [line for line in telemetry
                 if done["Unload"][1] - 4 <= line["t"] <= done["Unload"][1]]
    assert unloading and all(line["ground_speed"] < 0.3 for line in unloading)
    assert math.dist(unloading[0]["position"], unloading[-1]["position"]) < 1.0
    # SET_SPEED 2 m/s holds for the second leg.
    leg = done["Second drop/To the second point"]
    second = [line["ground_speed"] for line in telemetry if leg[0] <= line["t"] <= leg[1]]
    assert 1.5 < max(second) <= 2.5  # Rover overshoots its speed a little
    assert math.dist(telemetry[-1]["position"][:2], (0, 0)) <= 3.5
    assert not telemetry[-1]["armed"]
    requests = {line["message"] for line in lines if line["kind"] == "request"}
    assert not requests & {"TakeOff", "Land"}


def check_uav_surface(lines: list[dict]) -> None:
    """missions/dolphin_uav_surface.xml flown to its end: the scout flew, the rover drove
    only once the scout was up and met it under its last point, and both came home and
    disarmed."""
    scout, rover = _telemetry(lines, 1), _telemetry(lines, 2)
    assert max(line["position"][2] for line in scout) > 14
    assert all(line["position"][2] == 0.0 for line in rover)
    # The rover sets off only once the scout is above 10 m (wait_for on the other role).
    moving = min(line["t"] for line in rover if line["ground_speed"] > 0.5)
    climbed = min(line["t"] for line in scout if line["position"][2] > 10)
    assert moving >= climbed - 1.0
    # It holds at the rendezvous under the scout's last point, and both end at home.
    assert any(math.dist(line["position"][:2], (30, 20)) < 3.5 for line in rover)
    for track in (scout, rover):
        assert math.dist(track[-1]["position"][:2], (0, 0)) < 3.5
        assert not track[-1]["armed"]


def check_fenced_patrol(lines: list[dict]) -> None:
    """missions/fenced_patrol.xml: the fence and rally points went on the vehicle before
    anything was asked of it, the read-back matched, the patrol never breached them, and the
    vehicle's RTL ("come home") landed at the rally point nearer than home."""
    (told,) = [line for line in lines if line["kind"] == "safeguard"]
    assert told["ok"], told["message"]
    for part in ("inclusion polygon of 4 corners", "exclusion circle water tower",
                 "FENCE_ALT_MAX 40 m", "2 rally points", "not uploaded: shed",
                 "read back matched"):
        assert part in told["message"], told["message"]
    first_request = next(line for line in lines if line["kind"] == "request")
    assert told["t"] <= first_request["t"]
    assert not [line for line in lines if line["kind"] == "autopilot"
                and "fence breached" in line["text"].lower()]
    landed = [line for line in lines if line["kind"] == "telemetry" and line["landed"]
              and line["position"] is not None][-1]
    assert math.dist(landed["position"][:2], (-25, 70)) < 5.0, landed["position"]


LOG_CHECKS = {"imav2016": check_imav2016, "catalogue_tour": check_catalogue_tour,
              "plane_patrol": check_plane_patrol, "rover_delivery": check_rover_delivery,
              "dolphin_uav_surface": check_uav_surface, "fenced_patrol": check_fenced_patrol}
"""mission -> what its flight log must show besides the outcome, on any vehicle."""
