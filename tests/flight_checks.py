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


LOG_CHECKS = {"imav2016": check_imav2016, "catalogue_tour": check_catalogue_tour}
"""mission -> what its flight log must show besides the outcome, on any vehicle."""
