"""The fleet missions flown end to end on the simulator: who flew what, and when.

Each test runs ``tml run FILE --sim --vehicles N`` and reads the JSON-lines flight log:
``pick`` and ``release`` records say which vehicles a role had, ``task``, ``action`` and
``decision`` records carry the vehicle that flew them, and ``telemetry`` gives every
vehicle's battery, position and whether it is on the ground, once a second of vehicle time.

The Dolphin missions fly with a 1700 mAh battery and a 64 A charging pad at home. Hovering
draws 28.1 A and surveying at 10 m/s 30.3 A, as ArduCopter SITL does (sitl/physics.py
``flight_current``, measured in docs/simulator.md), that is 0.46-0.50 % of the pack a second:
from full to the listings' 30 % takes about two and a half minutes of vehicle time, and the
return and landing (about 50 s) leaves 5-15 %. The pad puts back 64 A x 1 s / 3.6 = 17.8 mAh
a second, about 1 % a second: back to 90 % in about 80 s. So a round lasts about 200 s of
vehicle time and a vehicle landed after a round is ready again
80 s later. The simulator runs at 50x at most; a round of four vehicles costs about 10 s of
wall time on two cores. ``--link-lost-limit`` is raised because a busy machine can stall
the simulator's thread for longer than 10 s of vehicle time (0.2 s of wall time at 50x).
Each flight is the one tests/test_flights.py checks the outcome of, flown once for both
(tests/shared_flights.py).
"""

from __future__ import annotations

import math
import statistics

import pytest
from shared_flights import FLEET, flown

# A guard against a hang, not a time limit: a flight in lock-step with the simulator is
# slower, never different, on a busy machine (tests/test_timebase.py), and one of a fleet
# beside three CPU spinners takes several minutes.
pytestmark = pytest.mark.timeout(900)

Log = list[dict]


def fly(factory: pytest.TempPathFactory, name: str, vehicles: int, battery: bool) -> Log:
    """The flight of ``name`` on ``vehicles`` vehicles, with the fleet's battery and pad
    (:data:`shared_flights.FLEET`) or only its longer link-lost limit: the same command
    line as tests/test_flights.py's, so the one flight serves both."""
    options = (["--vehicles", str(vehicles)] if vehicles > 1 else []) + \
        (FLEET if battery else ["--link-lost-limit", "60"])
    flight = flown(factory, name, options)
    code, lines = flight.code, flight.lines
    assert code == 0, [line for line in lines if line["kind"] in ("mission", "error")]
    assert not [line for line in lines if line["kind"] == "error"]
    return lines


def of(lines: Log, kind: str, vehicle: int | None = None) -> Log:
    return [line for line in lines if line["kind"] == kind
            and (vehicle is None or line.get("vehicle") == vehicle)]


def picks(lines: Log) -> list[tuple[str, tuple[int, ...]]]:
    return [(line["role"], tuple(line["vehicles"])) for line in of(lines, "pick")
            if "vehicles" in line]


def airborne(lines: Log, vehicle: int) -> list[tuple[float, float]]:
    """The intervals (first, last telemetry time) in which the vehicle was flying (armed and
    off the ground; it disarms on touching down, a moment before it reports landed)."""
    intervals: list[tuple[float, float]] = []
    start = last = None
    for line in of(lines, "telemetry", vehicle):
        if line["armed"] and not line["landed"]:
            start = line["t"] if start is None else start
            last = line["t"]
        elif start is not None:
            intervals.append((start, last))
            start = None
    assert start is None, f"vehicle {vehicle} was still flying at the end"
    return intervals


def overlap(a: tuple[float, float], b: tuple[float, float]) -> float:
    return min(a[1], b[1]) - max(a[0], b[0])


def battery_before(lines: Log, vehicle: int, t: float) -> float:
    """The last battery reading of the vehicle at or before ``t``."""
    return [line for line in of(lines, "telemetry", vehicle) if line["t"] <= t][-1]["battery"]


def read_when(lines: Log, vehicle: int, decision: str) -> list[float]:
    """The value each ``decision`` of the vehicle read (its one condition's), in order: what
    the engine decided on, where the 1 Hz telemetry lines show only samples around it."""
    return [line["read"][0]["value"] for line in of(lines, "decision", vehicle)
            if decision in line["message"]]


def test_single_vehicle_flies_rounds_each_ending_landed_at_home(
        tmp_path_factory: pytest.TempPathFactory) -> None:
    lines = fly(tmp_path_factory, "dolphin_fleet_single", 1, True)
    assert picks(lines) == [("v1", (1,)), ("v1", (1,))]  # picked again after each release
    releases = [line["t"] for line in of(lines, "release", 1)]
    flights = airborne(lines, 1)
    assert len(releases) == len(flights) == 2
    for (_, down), released in zip(flights, releases, strict=True):
        assert down < released
        # Landed when released; disarmed (by the release, or the autopilot) soon after.
        after = [line for line in of(lines, "telemetry", 1)
                 if released <= line["t"] <= released + 10]
        assert after and all(line["landed"] and line["position"][2] < 0.5 for line in after)
        assert not after[-1]["armed"]
        assert math.hypot(*after[-1]["position"][:2]) < 2.0  # at home, on its charging pad
    # The until ends each circling at 30 %; the second round waits on the pad for 90 %.
    untils = read_when(lines, 1, "stopped, its until conditions hold")
    assert len(untils) == 2 and all(29 <= battery < 30 for battery in untils)
    assert battery_before(lines, 1, releases[0]) < 30
    charged = read_when(lines, 1, "Round: its conditions are met")
    assert len(charged) == 2 and charged[1] >= 90
    assert flights[1][0] - releases[0] > 30  # it charged before it took off again
    # Each round uploads its own plan, and the second is followed from its first item.
    plans = [line["plan_id"] for line in of(lines, "request", 1)
             if line["message"] == "FlyMission"]
    assert len(plans) == 2 and plans[0] != plans[1]
    second = [line["task"].rsplit("/", 1)[-1] for line in of(lines, "task", 1)
              if line["t"] >= flights[1][0] - 5 and line["state"] == "running"
              and line["task"].startswith("Shift/Round/Survey Area/Fly/")]
    assert second[:3] == ["Take off", "Move", "Move and loiter"]
    ends = [line for line in of(lines, "decision") if "loop ends" in line["message"]]
    assert [line["rounds"] for line in ends] == [2]


def test_survey_flies_both_areas_at_once(
        tmp_path_factory: pytest.TempPathFactory) -> None:
    lines = fly(tmp_path_factory, "dolphin_fleet_survey", 2, True)
    assert picks(lines) == [("v1", (1,)), ("v2", (2,))] * 2
    north, south = airborne(lines, 1), airborne(lines, 2)
    assert len(north) == len(south) == 2
    for a, b in zip(north, south, strict=True):
        assert overlap(a, b) > 100  # both in the air together for most of the round

    def norths(vehicle: int) -> list[float]:
        return sorted(line["position"][0] for line in of(lines, "telemetry", vehicle)
                      if line["armed"] and not line["landed"])

    # Each swept its own side of home (a turn overshoots the area by a few metres).
    first, second = norths(1), norths(2)
    assert first[0] > -10 and first[-1] > 25 and statistics.median(first) > 2
    assert second[-1] < 10 and second[0] < -25 and statistics.median(second) < -2
    for vehicle in (1, 2):
        untils = read_when(lines, vehicle, "stopped, its until conditions hold")
        assert len(untils) == 2 and all(29 <= battery < 30 for battery in untils)
        # Round 2 picked the same vehicle back at once; it waited on the pad for 90 %.
        waits = [line["t"] for line in of(lines, "decision", vehicle)
                 if "waiting for its conditions" in line["message"]]
        flights = airborne(lines, vehicle)
        assert battery_before(lines, vehicle, waits[1]) < 30
        charged = [line for line in of(lines, "decision", vehicle)
                   if line["message"].endswith(": its conditions are met")]
        assert len(charged) == 2 and charged[1]["read"][0]["value"] >= 90
        assert waits[1] < charged[1]["t"] <= flights[1][0]


def test_relay_sends_the_rested_pair_while_the_other_recharges(
        tmp_path_factory: pytest.TempPathFactory) -> None:
    lines = fly(tmp_path_factory, "dolphin_fleet_relay", 4, True)
    # Longest free first: 1 and 2, then 3 and 4 (never used), then 1 and 2 again.
    assert picks(lines) == [("v1", (1,)), ("v2", (2,)), ("v1", (3,)), ("v2", (4,)),
                            ("v1", (1,)), ("v2", (2,))]
    flights = {v: airborne(lines, v) for v in (1, 2, 3, 4)}
    assert [len(flights[v]) for v in (1, 2, 3, 4)] == [2, 2, 1, 1]
    rounds = [(flights[1][0], flights[2][0]), (flights[3][0], flights[4][0]),
              (flights[1][1], flights[2][1])]
    for a, b in rounds:
        assert overlap(a, b) > 100  # two vehicles surveying at once
    released = sorted({line["t"] for line in of(lines, "release")})
    assert len(released) == 3  # each pair is released together when both have landed
    for (a, b), (c, d), free in zip(rounds, rounds[1:], released, strict=False):
        assert max(a[1], b[1]) < free < min(c[0], d[0])  # the next pair goes after the release
    for vehicle in (1, 2, 3, 4):
        untils = read_when(lines, vehicle, "stopped, its until conditions hold")
        assert len(untils) == len(flights[vehicle])
        assert all(29 <= battery < 30 for battery in untils)
    for vehicle in (1, 2):  # landed low, recharged while 3 and 4 flew, up again at 90 %+
        assert battery_before(lines, vehicle, released[0]) < 30
        charged = read_when(lines, vehicle, ": its conditions are met")
        assert len(charged) == 2 and charged[1] >= 90
    ends = [line for line in of(lines, "decision") if "loop ends" in line["message"]]
    assert [line["rounds"] for line in ends] == [3]


def test_compositions_first_choice_time_limit_on_error_and_roles(
        tmp_path_factory: pytest.TempPathFactory) -> None:
    lines = fly(tmp_path_factory, "fleet_compositions", 3, False)
    assert picks(lines) == [("lead", (1,)), ("pair", (2, 3))]  # count="2": both at once

    def first(kind: str, vehicle: int | None, text: str) -> float:
        return next(line["t"] for line in of(lines, kind, vehicle) if text in line["message"])

    # wait_for on the lead's altitude: the pair starts climbing only once the lead is up.
    lead_up = first("action", 1, "TAKE_OFF started")
    for vehicle in (2, 3):
        climb = first("action", vehicle, "TAKE_OFF started")
        assert climb >= lead_up + 8 / 2.5  # 8 m at the 2.5 m/s climb rate, at the soonest
        (met,) = [line for line in of(lines, "decision", vehicle)
                  if line["message"].endswith("Pair climbs: its conditions are met")]
        assert met["t"] <= climb
        assert [(r["subject"], r["value"] > 8) for r in met["read"]] == [("ALTITUDE", True)]
    # The pair's own event cuts its climb to 12 m above 7 m; the lead's take-off, outside
    # the role, is flown to its end.
    fired = of(lines, "event")
    assert sorted(line["vehicle"] for line in fired) == [2, 3]
    assert all(line["event"] == "Pair high enough" for line in fired)
    assert all(7 < line["read"][1]["value"] < 9 for line in fired)
    take_offs_done = [line["vehicle"] for line in of(lines, "action")
                      if line["message"] == "TAKE_OFF done"]
    assert take_offs_done == [1]
    # first: the lead's 5 m hop ends the race; the pair's 60 m leg is stopped, held.
    hop = first("task", 1, "Race/Lead hops: done")
    for vehicle in (2, 3):
        stopped = [line for line in of(lines, "action", vehicle)
                   if line["message"] == "MOVE stopped: another branch finished first"]
        assert [line["t"] for line in stopped] == [hop]
        assert first("task", vehicle, "Race/Pair flies far: aborted") == hop
        assert any(line["message"] == "Hold" and line["t"] == hop
                   for line in of(lines, "request", vehicle))
        assert max(line["position"][1] for line in of(lines, "telemetry", vehicle)
                   if line["position"] is not None) < 40
    # choice: the unconditional branch; its forever LOITER stopped by the 15 s time limit.
    states = {line["task"]: line["state"] for line in of(lines, "task")}
    assert states["Lead's turn/Choose/Go home early"] == "skipped"
    assert states["Lead's turn/Choose/Circle a while"] == "done"
    circled = (first("decision", 1, "its time limit of 15 s is reached")
               - first("action", 1, "LOITER started"))
    assert 15 - 1e-6 <= circled < 16
    # on_error: no vehicle carries a winch; the failed pick runs the handler on the pair.
    failed = [line for line in of(lines, "pick") if "refused" in line]
    assert [line["refused"]["1"] for line in failed] == ["no winch"]
    assert states["Winch"] == "failed"
    for vehicle in (2, 3):
        assert first("task", vehicle, "Winch/Pair lands instead: done") > failed[0]["t"]
        assert of(lines, "telemetry", vehicle)[-1]["landed"]
    assert of(lines, "run")[-1]["outcomes"][0]["reason"] == "all tasks done"
