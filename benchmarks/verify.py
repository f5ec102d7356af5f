"""How the cost of `tml verify` grows with the number of actions and of obstacles.

Generates missions of 10, 100 and 1,000 GO_TO_POINT actions (a random walk in a 2 km
square, legs of up to 150 m, at 10 m) among 10, 100 and 1,000 cylinder obstacles (radius
2-8 m, as tall as the sky), and times static verification with the trajectory planner
against its peer measured in the same run: the same mission verified without obstacles,
where every leg is the straight line (no planning), and against a floor: shapely testing
every leg of the mission and every leg home (straight) against every obstacle grown by the
clearance, in one STRtree query. Prints the times, the ratios and how the time grows.
Times are the process's CPU seconds (best of ``--repeat``): all of it is one thread, and on
a shared, loaded machine CPU time is what the wall clock would show on a quiet one.

    /work/venv/bin/python benchmarks/verify.py [--repeat N] [--seed S]
"""

from __future__ import annotations

import argparse
import math
import random
import time

import shapely

from tml.language.validation import validate_file
from tml.verify.profile import load_profile
from tml.verify.static import verify_mission
from tml.world import Cylinder, World

SIDE = 2000.0


def obstacles(count: int, rng: random.Random) -> tuple[Cylinder, ...]:
    return tuple(Cylinder(f"c{i}", rng.uniform(-SIDE / 2, SIDE / 2),
                          rng.uniform(-SIDE / 2, SIDE / 2), rng.uniform(2, 8))
                 for i in range(count))


def free(point: tuple[float, float], world: tuple[Cylinder, ...], clearance: float) -> bool:
    return all(math.hypot(point[0] - c.north, point[1] - c.east) > c.radius + clearance + 1
               for c in world)


def mission_text(actions: int, world: tuple[Cylinder, ...], clearance: float,
                 rng: random.Random, points: list[tuple[float, float]] | None = None) -> bytes:
    north, east = 0.0, 0.0
    tasks = ['<task name="up"><action name="TAKE_OFF"/></task>']
    while len(tasks) < actions:
        step_n, step_e = rng.uniform(-150, 150), rng.uniform(-150, 150)
        candidate = (max(-SIDE / 2, min(SIDE / 2, north + step_n)),
                     max(-SIDE / 2, min(SIDE / 2, east + step_e)))
        if not free(candidate, world, clearance):
            continue
        north, east = candidate
        if points is not None:
            points.append(candidate)
        tasks.append(f'<task name="leg {len(tasks)}"><action name="GO_TO_POINT">'
                     f'<argument name="coordinates" value="({north:.1f}, {east:.1f}, 10)"/>'
                     f'</action></task>')
    body = "\n".join(tasks)
    return f'<?xml version="1.0"?>\n<mission name="bench">\n{body}\n</mission>\n'.encode()


def floor(points: list[tuple[float, float]], world: tuple[Cylinder, ...],
          clearance: float) -> None:
    """Every leg and every leg home against every grown obstacle, in one query."""
    legs = shapely.linestrings([[a, b] for a, b in zip([(0.0, 0.0), *points], points,
                                                        strict=False)]
                               + [[p, (0.0, 0.0)] for p in points])
    grown = shapely.buffer(shapely.points([(c.north, c.east) for c in world]),
                           [c.radius + clearance for c in world])
    shapely.STRtree(grown).query(legs, predicate="intersects")


def best_of(repeat: int, run: object) -> float:
    times = []
    for _ in range(repeat):
        start = time.process_time()
        run()  # type: ignore[operator]
        times.append(time.process_time() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per case, best kept")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    # The quadcopter's own battery: it runs out after about 2.7 km, so in the long missions
    # most actions fail the reserve check, and each such report plans its way home exactly.
    profile = load_profile("quadcopter")
    print(f"{'actions':>8} {'obstacles':>9} {'planned s':>10} {'straight s':>10} "
          f"{'ratio':>7} {'floor s':>8} {'ratio':>7} {'ms/action':>9}")
    grid: dict[tuple[int, int], float] = {}
    for obstacle_count in (10, 100, 1000):
        for action_count in (10, 100, 1000):
            rng = random.Random(args.seed * 7919 + obstacle_count * 31 + action_count)
            world_obstacles = obstacles(obstacle_count, rng)
            points: list[tuple[float, float]] = []
            text = mission_text(action_count, world_obstacles, profile.min_clearance, rng,
                                points)
            mission = validate_file("bench.xml", text).mission
            assert mission is not None
            world = World(obstacles=world_obstacles)
            planned = best_of(args.repeat, lambda m=mission, w=world: verify_mission(
                m, profile, w))
            straight = best_of(args.repeat, lambda m=mission: verify_mission(m, profile))
            least = best_of(args.repeat, lambda p=points, o=world_obstacles: floor(
                p, o, profile.min_clearance))
            grid[(action_count, obstacle_count)] = planned
            print(f"{action_count:>8} {obstacle_count:>9} {planned:>10.3f} {straight:>10.3f} "
                  f"{planned / straight:>7.1f} {least:>8.4f} {planned / least:>7.0f} "
                  f"{1000 * planned / action_count:>9.2f}", flush=True)
    print("\ngrowth of the planned time (x10 is linear, x13.3 is n log n):")
    for obstacle_count in (10, 100, 1000):
        row = [grid[(a, obstacle_count)] for a in (10, 100, 1000)]
        print(f"  {obstacle_count:>5} obstacles: x{row[1] / row[0]:.1f} from 10 to 100 actions,"
              f" x{row[2] / row[1]:.1f} from 100 to 1,000")
    for action_count in (10, 100, 1000):
        column = [grid[(action_count, o)] for o in (10, 100, 1000)]
        print(f"  {action_count:>5} actions: x{column[1] / column[0]:.1f} from 10 to 100 "
              f"obstacles, x{column[2] / column[1]:.1f} from 100 to 1,000")


if __name__ == "__main__":
    main()
