"""Record, or compare with a record, everything ``tml verify`` reports: the missions in
missions/ with every profile (and with the example world), and the missions of
benchmarks/verify.py, as JSON reports (the numbers ``--format json`` prints) plus the
length of every leg the planner planned.

A change to the planner or the constraints that is only about speed must leave these the
same to the centimetre:

    .venv/bin/python benchmarks/verify_snapshot.py record /tmp/before.json
    (change the code)
    .venv/bin/python benchmarks/verify_snapshot.py compare /tmp/before.json

``--quick`` leaves out the benchmark's 1,000-action missions among 1,000 obstacles.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from verify import mission_text, obstacles  # noqa: E402

from tml.language.build import load_world  # noqa: E402
from tml.language.model import Mission  # noqa: E402
from tml.language.validation import validate_file  # noqa: E402
from tml.verify import static  # noqa: E402
from tml.verify.motion import FlightModel  # noqa: E402
from tml.verify.profile import VehicleProfile, load_profile  # noqa: E402
from tml.verify.report import report_document  # noqa: E402
from tml.world import World  # noqa: E402

TOLERANCE = 0.01  # m, %, s: the centimetre


MODELS: list[FlightModel] = []


class _Recorded(FlightModel):
    """A flight model that keeps itself, to read the legs its planner planned."""

    def __init__(self, profile: VehicleProfile, world: World | None = None) -> None:
        super().__init__(profile, world)
        MODELS.append(self)


def _verify(mission: Mission, profile: VehicleProfile, world: World | None
            ) -> dict[str, object]:
    """The JSON report, and every leg the planners planned as (start, end, length; -1:
    no way), in a stable order."""
    MODELS.clear()
    report = static.verify_mission(mission, profile, world)
    legs = sorted([*start, *end, -1.0 if found is None else found.length]
                  for model in MODELS for (start, end), found in model.planner._cache.items())
    # Files named from the checkout, so that two checkouts compare.
    document = json.loads(json.dumps(report_document(report)).replace(f"{ROOT}/", ""))
    return {"report": document, "legs": legs}


def cases(quick: bool) -> dict[str, object]:
    found: dict[str, object] = {}
    static.FlightModel = _Recorded  # type: ignore[attr-defined]
    worlds = {"": None, "+field_works": load_world(str(ROOT / "missions/worlds/field_works.xml"))}
    for path in sorted((ROOT / "missions").glob("*.xml")):
        mission = validate_file(path).mission
        assert mission is not None, path
        for name in ("quadcopter", "fixed-wing", "rover"):
            profile = load_profile(name)
            for suffix, world in worlds.items():
                found[f"{path.stem}/{name}{suffix}"] = _verify(mission, profile, world)
    profile = load_profile("quadcopter")
    for obstacle_count in (10, 100, 1000):
        for action_count in (10, 100, 1000):
            if quick and obstacle_count * action_count >= 1000 * 1000:
                continue
            rng = random.Random(1 * 7919 + obstacle_count * 31 + action_count)
            world_obstacles = obstacles(obstacle_count, rng)
            text = mission_text(action_count, world_obstacles, profile.min_clearance, rng)
            mission = validate_file("bench.xml", text).mission
            assert mission is not None
            world = World(obstacles=world_obstacles)
            found[f"bench/{action_count}x{obstacle_count}"] = _verify(mission, profile, world)
            print(f"bench {action_count} x {obstacle_count}", file=sys.stderr, flush=True)
    return found


def _legs(before: list[list[float]], after: list[list[float]], where: str) -> list[str]:
    """Legs planned in both records must have the same length; a change may plan fewer
    legs (those whose length decides nothing), never others."""
    lengths = {tuple(leg[:6]): leg[6] for leg in before}
    return [f"{where}: leg {leg[:6]} planned, not before" if tuple(leg[:6]) not in lengths
            else f"{where}: leg {leg[:6]}: {lengths[tuple(leg[:6])]} != {leg[6]}"
            for leg in after if tuple(leg[:6]) not in lengths
            or not math.isclose(lengths[tuple(leg[:6])], leg[6], abs_tol=TOLERANCE)]


def differences(before: object, after: object, where: str = "") -> list[str]:
    """Where two records differ: numbers by more than TOLERANCE, anything else at all."""
    if where.endswith("/legs"):
        return _legs(before, after, where)  # type: ignore[arg-type]
    if isinstance(before, dict) and isinstance(after, dict):
        if before.keys() != after.keys():
            return [f"{where}: keys {sorted(before)} != {sorted(after)}"]
        return [d for key in before for d in differences(before[key], after[key],
                                                          f"{where}/{key}")]
    if isinstance(before, list) and isinstance(after, list):
        if len(before) != len(after):
            return [f"{where}: {len(before)} items != {len(after)}"]
        return [d for index, (b, a) in enumerate(zip(before, after, strict=True))
                for d in differences(b, a, f"{where}[{index}]")]
    numbers = (int, float)
    if isinstance(before, numbers) and isinstance(after, numbers) \
            and not isinstance(before, bool) and not isinstance(after, bool):
        if math.isclose(before, after, abs_tol=TOLERANCE):
            return []
        return [f"{where}: {before} != {after}"]
    return [] if before == after else [f"{where}: {before!r} != {after!r}"]


def main() -> None:
    global TOLERANCE
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("action", choices=("record", "compare"))
    parser.add_argument("file")
    parser.add_argument("--quick", action="store_true",
                        help="without the 1,000 actions among 1,000 obstacles")
    parser.add_argument("--tolerance", type=float, default=0.01,
                        help="largest difference of a number (default: 0.01)")
    args = parser.parse_args()
    TOLERANCE = args.tolerance
    found = cases(args.quick)
    if args.action == "record":
        Path(args.file).write_text(json.dumps(found))
        print(f"{len(found)} cases recorded in {args.file}")
        return
    recorded = json.loads(Path(args.file).read_text())
    if args.quick:
        recorded = {k: v for k, v in recorded.items() if k in found}
    wrong = differences(recorded, json.loads(json.dumps(found)))
    for line in wrong[:50]:
        print(line)
    print(f"{len(found)} cases, {len(wrong)} differences")
    sys.exit(1 if wrong else 0)


if __name__ == "__main__":
    main()
