"""Resuming an interrupted run (tml.engine.resume): the engine's own records folded into
where the mission stood, and the interpreter going on from there, on a FakeVehicle."""

from __future__ import annotations

import io
import json
from typing import Any

import pytest
from fake_vehicle import FakeVehicle

from tml.engine import Interpreter, Status
from tml.engine.records import TaskState
from tml.engine.resume import Progress, progress
from tml.errors import EngineError
from tml.language.validation import validate_file
from tml.run.journal import Journal
from tml.vehicle import FlyMission, GoTo, IdSource, TakeOff


def task(name: str, action: str, argument: str = "", extra: str = "") -> str:
    return (f'<task name="{name}"{extra}><action name="{action}">{argument}</action></task>\n')


def go_to(point: str) -> str:
    return f'<argument name="coordinates" value="{point}"/>'


PATROL = ('<mission name="Patrol">\n'
          + task("Take off", "TAKE_OFF", '<argument name="altitude" value="5"/>')
          + task("Remember", "MEMORIZE_POINT", '<argument name="coordinates" label="start"/>')
          + '<task name="Patrol"><repeat times="3"/>\n'
          + task("Out", "GO_TO_POINT", go_to("(6, 0, 5)"))
          + task("Pause", "WAIT", '<argument name="duration" value="1"/>')
          + task("Back", "GO_TO_POINT", go_to("(0, 3, 5)"))
          + "</task>\n"
          + task("Limited", "WAIT", '<argument name="duration" value="30"/>',
                 ' time_limit="4"')
          + task("Home", "GO_TO_POINT", '<argument name="coordinates" label="start"/>')
          + task("Land", "LAND")
          + "</mission>\n")


def mission(text: str = PATROL) -> Any:
    result = validate_file("m.xml", text.encode())
    assert result.errors == [], result.errors
    return result.mission


class Station:
    """A ground station: one interpreter stepping a FakeVehicle every 0.1 s, writing its
    records to a flight log as the runner does. Killed by dropping it."""

    def __init__(self, vehicle: FakeVehicle, log: io.StringIO, start: float,
                 resume: Progress | None = None, first_id: int = 1,
                 text: str = PATROL) -> None:
        self.vehicle, self.time = vehicle, start
        self.journal = Journal(log)
        self.engine = Interpreter(mission(text), [1], ids=IdSource(first_id))
        self.requests: list[Any] = []
        self._take(self.engine.start(start, {1: vehicle.state()}, resume))

    def _take(self, out: Any) -> None:
        for record in out.records:
            self.journal.write(record.time, record.kind, record.vehicle_id, record.data)
        for request in out.requests:  # its record is among the records
            self.requests.append(request)
            self.vehicle.submit(request)

    def fly(self, steps: int = 100_000) -> Station:
        for _ in range(steps):
            if self.engine.status is not Status.RUNNING:
                break
            self.vehicle.advance(0.1)
            self.time = round(self.time + 0.1, 6)
            self._take(self.engine.step(self.time, {1: self.vehicle.state()},
                                        {1: self.vehicle.poll()}))
            if self.time % 1.0 < 0.05:  # the runner's telemetry line, once a second
                self.journal.write(self.time, "telemetry", 1)
        return self


def lines(log: io.StringIO) -> list[dict[str, Any]]:
    return [json.loads(line) for line in log.getvalue().splitlines()]


def ends(log: io.StringIO) -> list[tuple[str, str]]:
    return [(line["task"], line["state"]) for line in lines(log)
            if line["kind"] == "task" and line["state"] != "running"]


def interrupted(steps: int, downtime: float = 7.0) -> tuple[io.StringIO, FakeVehicle, Station]:
    """Flown ``steps`` steps, killed, the vehicle left alone ``downtime`` s, resumed to the
    end on the same vehicle and log."""
    vehicle, log = FakeVehicle(), io.StringIO()
    first = Station(vehicle, log, 0.0).fly(steps)
    vehicle.advance(downtime)  # nobody watches: it holds, or finishes what it was told
    found = progress(lines(log), 1)
    second = Station(vehicle, log, first.time + downtime, found, found.last_id + 1)
    second.fly()
    return log, vehicle, second


def test_a_run_killed_anywhere_and_resumed_ends_as_one_left_alone() -> None:
    alone_log = io.StringIO()
    alone = Station(FakeVehicle(), alone_log, 0.0).fly()
    assert alone.engine.status is Status.COMPLETED
    total = int(alone.time * 10)
    for steps in range(1, total, 17):
        log, vehicle, second = interrupted(steps)
        assert second.engine.status is Status.COMPLETED, steps
        assert ends(log) == ends(alone_log), steps  # nothing skipped, nothing twice
        assert [line["message"] for line in lines(log)
                if line["kind"] == "request"].count("TakeOff") == 1, steps
        assert not vehicle.armed and vehicle.position[2] == pytest.approx(0.0, abs=0.01)


def test_a_vehicle_in_the_air_is_not_told_to_take_off_again() -> None:
    log, _, second = interrupted(8, downtime=0.2)  # climbing since 0.2 s
    assert not [r for r in second.requests if isinstance(r, TakeOff)]
    assert any(line["message"].startswith("TAKE_OFF resumed in the air at ")
               for line in lines(log) if line["kind"] == "decision")


HIGH = ('<mission name="High">\n'
        + task("Up", "TAKE_OFF", '<argument name="altitude" value="20"/>')
        + task("Stay", "WAIT", '<argument name="duration" value="15"/>')
        + task("Down", "LAND") + "</mission>\n")


def test_a_take_off_resumed_mid_climb_climbs_on_to_its_altitude() -> None:
    """Killed at 4 m of a take-off to 20 m and resumed at once: the take-off is not
    ignored (the WAIT's hold would stop the climb short), it climbs on and is done only
    when the vehicle is at 20 m."""
    vehicle, log = FakeVehicle(), io.StringIO()
    first = Station(vehicle, log, 0.0, text=HIGH)
    while vehicle.position[2] < 4.0:
        first.fly(1)
    found = progress(lines(log), 1)
    assert found.running.keys() == {"Up"}
    second = Station(vehicle, log, first.time, found, found.last_id + 1, text=HIGH)
    while second.engine.views()[1].task_states.get("Stay") is not TaskState.RUNNING:
        second.fly(1)
    assert vehicle.position[2] == pytest.approx(20.0, abs=0.6)  # when the WAIT begins
    (goto,) = [r for r in second.requests if isinstance(r, GoTo)]
    assert goto.target[2] == 20.0
    assert not [r for r in second.requests if isinstance(r, TakeOff)]
    second.fly()
    assert second.engine.status is Status.COMPLETED
    assert [t for t, state in ends(log)] == ["Up", "Stay", "Down"]


def test_memorized_points_and_the_repeat_round_are_restored() -> None:
    vehicle, log = FakeVehicle(), io.StringIO()
    first = Station(vehicle, log, 0.0)
    while not any(line.get("iteration") == 2 for line in lines(log)):
        first.fly(1)
    first.fly(5)  # round 2, flying Out
    found = progress(lines(log), 1)
    assert found.rounds == {"Patrol": 2}
    assert dict(found.ended) == {"Take off": "done", "Remember": "done"}
    assert set(found.running) == {"Patrol", "Patrol/Out"}
    assert found.labels["start"] == pytest.approx((0.0, 0.0, 5.0), abs=0.6)
    second = Station(vehicle, log, first.time + 1, found, found.last_id + 1).fly()
    assert second.engine.status is Status.COMPLETED
    rounds = [line["iteration"] for line in lines(log) if "iteration" in line]
    assert rounds == [2, 3]  # round 2 is not said twice, round 3 follows
    home = [r for r in second.requests if type(r).__name__ == "GoTo"][-1]
    assert home.target == pytest.approx(found.labels["start"])


def test_a_time_limit_goes_on_from_where_it_stood() -> None:
    vehicle, log = FakeVehicle(), io.StringIO()
    first = Station(vehicle, log, 0.0)
    while "Limited" not in {line.get("task") for line in lines(log)}:
        first.fly(1)
    first.fly(30)  # 3 s of its 4 s
    found = progress(lines(log), 1)
    resumed_at = first.time + 100.0  # the downtime is not counted
    second = Station(vehicle, log, resumed_at, found, found.last_id + 1)
    while "Limited" not in {task for task, _ in ends(log)}:
        second.fly(1)
    # 1 s was left; the log knew the time to its last telemetry line (1 s before at most).
    assert 0.9 <= second.time - resumed_at <= 2.1
    assert second.engine.run.log.mission_time - found.elapsed == pytest.approx(
        second.time - resumed_at)


def test_a_run_resumed_and_killed_again_folds_to_the_same_place() -> None:
    vehicle, log = FakeVehicle(), io.StringIO()
    first = Station(vehicle, log, 0.0).fly(95)  # round 2, flying Back
    found = progress(lines(log), 1)
    second = Station(vehicle, log, first.time, found, found.last_id + 1).fly(1)
    again = progress(lines(log), 1)
    assert again.ended == found.ended and again.rounds == found.rounds
    assert set(again.running) == set(found.running)
    assert again.running == pytest.approx(found.running, abs=0.2)
    assert again.last_id > found.last_id  # the second run's requests are numbered on
    third = Station(vehicle, log, second.time, again, again.last_id + 1).fly()
    assert third.engine.status is Status.COMPLETED


AUTO = ('<mission name="Auto">\n'
        + task("Take off", "TAKE_OFF", '<argument name="altitude" value="5"/>')
        + '<task name="Photo flight" dispatch="mission">\n'
        + "".join(task(f"Leg {n}", "GO_TO_POINT", go_to(f"({4 * n}, 0, 5)")) for n in range(1, 5))
        + "</task>\n" + task("Land", "LAND") + "</mission>\n")


def test_a_plan_the_vehicle_flies_in_auto_is_followed_not_sent_again() -> None:
    alone_log = io.StringIO()
    assert Station(FakeVehicle(), alone_log, 0.0, text=AUTO).fly().engine.status \
        is Status.COMPLETED
    vehicle, log = FakeVehicle(), io.StringIO()
    first = Station(vehicle, log, 0.0, text=AUTO)
    while ("Photo flight/Leg 2", "done") not in ends(log):
        first.fly(1)
    vehicle.advance(0.5)  # the autopilot flies on meanwhile
    found = progress(lines(log), 1)
    [plan] = [r for r in first.requests if isinstance(r, FlyMission)]
    assert found.plans == {"Photo flight": (plan.plan_id, plan.start)}
    second = Station(vehicle, log, first.time + 0.5, found, found.last_id + 1, AUTO).fly()
    assert second.engine.status is Status.COMPLETED
    [followed] = [r for r in second.requests if isinstance(r, FlyMission)]
    assert followed.track and followed.plan_id == plan.plan_id
    assert ends(log) == ends(alone_log)  # each leg said done once


def test_a_plan_the_vehicle_does_not_fly_is_sent_again() -> None:
    vehicle, log = FakeVehicle(), io.StringIO()
    first = Station(vehicle, log, 0.0, text=AUTO)
    while ("Photo flight/Leg 1", "done") not in ends(log):
        first.fly(1)
    vehicle.mode = "GUIDED"  # the pilot took it out of AUTO
    found = progress(lines(log), 1)
    second = Station(vehicle, log, first.time, found, found.last_id + 1, AUTO).fly(1)
    [sent] = [r for r in second.requests if isinstance(r, FlyMission)]
    assert not sent.track and sent.plan_id > found.plans["Photo flight"][0]


RECOVERS = ('<mission name="Recovers">\n'
            + task("Take off", "TAKE_OFF", '<argument name="altitude" value="5"/>')
            + '<task name="Risky"><action name="GO_TO_POINT">' + go_to("(9, 0, 5)")
            + '</action><on_error>\n'
            + task("Breathe", "WAIT", '<argument name="duration" value="2"/>')
            + task("Elsewhere", "GO_TO_POINT", go_to("(0, 6, 5)"))
            + "</on_error></task>\n" + task("Land", "LAND") + "</mission>\n")


def test_on_error_tasks_that_were_running_go_on_in_place_of_their_task() -> None:
    def refusing() -> FakeVehicle:
        vehicle = FakeVehicle()
        vehicle.reject = {"GoTo": "rejected"}  # the risky leg fails at once
        return vehicle

    def until_breathing(station: Station, log: io.StringIO) -> Station:
        while "Risky/Breathe" not in {line.get("task") for line in lines(log)}:
            station.fly(1)
        station.vehicle.reject = {}  # the next leg is taken
        return station

    alone_log = io.StringIO()
    alone = until_breathing(Station(refusing(), alone_log, 0.0, text=RECOVERS),
                            alone_log).fly()
    assert alone.engine.status is Status.COMPLETED
    assert ("Risky", "failed") in ends(alone_log)
    vehicle, log = refusing(), io.StringIO()
    first = until_breathing(Station(vehicle, log, 0.0, text=RECOVERS), log).fly(5)
    found = progress(lines(log), 1)
    assert found.recovering == {"Risky"}
    second = Station(vehicle, log, first.time, found, found.last_id + 1, RECOVERS).fly()
    assert second.engine.status is Status.COMPLETED
    alone_ends = ends(alone_log)
    assert ends(log) == alone_ends  # Breathe ends once, Elsewhere is flown, then Land


def test_the_fold_forgets_what_ended_in_an_earlier_round_and_takes_pauses_out() -> None:
    records = [
        {"t": 10.0, "kind": "mission", "vehicle": 1, "message": "mission 'm' started"},
        {"t": 10.0, "kind": "task", "vehicle": 1, "task": "R", "state": "running"},
        {"t": 11.0, "kind": "task", "vehicle": 1, "task": "R/A", "state": "running"},
        {"t": 12.0, "kind": "task", "vehicle": 1, "task": "R/A", "state": "done"},
        {"t": 12.0, "kind": "task", "vehicle": 1, "task": "R/B", "state": "skipped"},
        {"t": 12.0, "kind": "decision", "vehicle": 1, "task": "R", "iteration": 2},
        {"t": 13.0, "kind": "control", "vehicle": 1, "control": "pause"},
        {"t": 20.0, "kind": "control", "vehicle": 1, "control": "resume", "paused": 7.0},
        {"t": 21.0, "kind": "task", "vehicle": 1, "task": "R/A", "state": "running"},
        {"t": 22.0, "kind": "telemetry", "vehicle": 2, "request_id": 99},
    ]
    found = progress(records, 1)
    assert found.ended == {} and found.rounds == {"R": 2}
    assert found.running == {"R": 0.0, "R/A": 4.0}  # 11 s after the start, 7 s paused
    assert found.elapsed == pytest.approx(4.0) and found.started
    assert progress(records[:1], 2) == Progress(last_id=0)


def test_only_a_mission_without_roles_can_be_resumed() -> None:
    text = ('<mission name="Two"><roles><role name="scout"/></roles>\n<task name="Up" role="scout">'
            '<action name="TAKE_OFF"><argument name="altitude" value="5"/></action></task>'
            '\n</mission>\n')
    engine = Interpreter(mission(text), [1, 2])
    with pytest.raises(EngineError, match="without roles"):
        engine.start(0.0, {1: FakeVehicle().state(), 2: FakeVehicle(vehicle_id=2).state()},
                     Progress(started=True))


LANDING = ('<mission name="Landing">\n'
           + task("Take off", "TAKE_OFF", '<argument name="altitude" value="5"/>')
           + task("Land there", "LANDING_POINT", go_to("(6, 0, 5)"))
           + "</mission>\n")


def test_a_vehicle_that_landed_during_landing_point_ends_it_done_when_resumed() -> None:
    alone_log = io.StringIO()
    alone = Station(FakeVehicle(), alone_log, 0.0, text=LANDING).fly()
    assert alone.engine.status is Status.COMPLETED
    landing = min(line["t"] for line in lines(alone_log)  # over the point, told to land
                  if line["kind"] == "request" and line["message"] == "Land")
    for steps in range(int(landing * 10) + 1, int(alone.time * 10), 7):
        vehicle, log = FakeVehicle(), io.StringIO()
        first = Station(vehicle, log, 0.0, text=LANDING).fly(steps)
        vehicle.advance(60.0)  # nobody watches: it lands where it was told, and disarms
        assert not vehicle.state().flying, steps
        found = progress(lines(log), 1)
        second = Station(vehicle, log, first.time + 60.0, found, found.last_id + 1,
                         text=LANDING).fly()
        assert second.engine.status is Status.COMPLETED, (steps, second.engine.reason)
        assert ends(log) == ends(alone_log), steps
