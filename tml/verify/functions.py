"""The functions of the TML paper's feasibility model (section 3, table 2).

Points are local ``(north, east, up)`` metres from home; battery charges are percent of a
full battery; consumption rates are percent per metre; times are seconds.
"""

from __future__ import annotations

import math

from tml.verify.planner import Planner, Point3, Trajectory


def distance(x1: Point3, x2: Point3) -> float:
    """Distance(x1, x2): straight-line distance in metres from ``x1`` to ``x2``."""
    return math.dist(x1, x2)


def distance_battery(charge: float, consumption: float) -> float:
    """DistanceBattery(x1, x2): metres that a battery ``charge`` (percent) covers at a
    ``consumption`` rate (percent per metre); 0 for an empty or negative charge."""
    if charge <= 0:
        return 0.0
    if consumption <= 0:
        return math.inf
    return charge / consumption


def distance_obstacle(x1: Point3, planner: Planner) -> float:
    """DistanceObstacle(x1): metres from ``x1`` to the nearest obstacle's surface (inf when
    the world has none)."""
    return planner.clearance_of((x1,))


def length(x1: Trajectory) -> float:
    """Length(x1): length of a trajectory in metres."""
    return x1.length


def speed(path_length: float, now: float, arrival: float) -> float:
    """Speed(x1, x2, x3): the speed (m/s) needed to leave now and arrive at time
    ``arrival`` after flying ``path_length`` metres (the length of Trajectory(x1, x2));
    inf when the arrival time is not in the future and there is a way to go."""
    available = arrival - now
    if path_length <= 0:
        return 0.0
    return path_length / available if available > 0 else math.inf


def trajectory(x1: Point3, x2: Point3, planner: Planner) -> Trajectory | None:
    """Trajectory(x1, x2): the planner's shortest collision-free path, or None."""
    return planner.trajectory(x1, x2)
