"""Fleets (tml.engine.interpreter with roles and orchestration), driven by FakeVehicles and
an injected clock.

Every test asserts who flew what, when: the records (with their vehicle ids and times),
the requests each vehicle received, and where the vehicles ended up.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from itertools import pairwise

import pytest
from fake_vehicle import FakeVehicle
from test_engine_interpreter import SEEN, goto, hover, mission

from tml.engine import Interpreter, Options, Record, Status, TaskState
from tml.vehicle import (
    Disarm,
    GoTo,
    Hold,
    Land,
    Request,
    ReturnToLaunch,
    SetSkill,
    VehicleState,
)

STEP = 0.1


def take_off(name: str = "Take off", altitude: float = 5) -> str:
    return (f'<task name="{name}"><action name="TAKE_OFF"><argument name="altitude" '
            f'value="{altitude:g}"/></action></task>\n')


def land(name: str = "Land") -> str:
    return f'<task name="{name}"><action name="LAND"/></task>\n'


def condition(parameter: str, comparison: str, value: str, role: str = "") -> str:
    role_attribute = f' role="{role}"' if role else ""
    return (f'<condition parameter="{parameter}" comparison="{comparison}" '
            f'value="{value}"{role_attribute}/>')


def roles(*specs: str) -> str:
    """``<roles>`` from role names, or whole ``<role>`` elements."""
    return "<roles>" + "".join(s if s.startswith("<") else f'<role name="{s}"/>'
                               for s in specs) + "</roles>\n"


class FleetFlight:
    """Flies a mission on N FakeVehicles, 0.1 s a step, recording everything.

    Requests are routed to the vehicle they name; ``sent`` keeps each with the time it
    was sent, ``track`` every state the fleet was given.
    """

    def __init__(self, body: str, vehicles: int | list[FakeVehicle] = 2, events: str = "",
                 extra: str = "", options: Options | None = None,
                 payloads: dict[int, list[str]] | None = None) -> None:
        if isinstance(vehicles, int):
            vehicles = [FakeVehicle(vehicle_id=i) for i in range(1, vehicles + 1)]
        self.vehicles = {v.vehicle_id: v for v in vehicles}
        self.fleet = Interpreter(mission(body, events, extra), list(self.vehicles), options,
                                 payloads)
        self.records: list[Record] = []
        self.sent: list[tuple[float, Request]] = []
        self.track: list[tuple[float, dict[int, VehicleState]]] = []
        self.time = 0.0
        self.take(self.fleet.start(0.0, self.states()))

    def states(self) -> dict[int, VehicleState]:
        return {vid: v.state() for vid, v in self.vehicles.items()}

    def take(self, out) -> None:
        self.records += out.records
        for request in out.requests:
            self.sent.append((self.time, request))
            self.vehicles[request.vehicle_id].submit(request)

    def run(self, seconds: float = 600.0,
            each: Callable[[FleetFlight], None] | None = None) -> FleetFlight:
        end = self.time + seconds
        while self.fleet.status is Status.RUNNING and self.time < end - 1e-9:
            for vehicle in self.vehicles.values():
                vehicle.advance(STEP)
            self.time = round(self.time + STEP, 6)
            if each:
                each(self)
            states = self.states()
            self.track.append((self.time, states))
            self.take(self.fleet.step(self.time, states,
                                      {vid: v.poll() for vid, v in self.vehicles.items()}))
        return self

    # --- what happened ---------------------------------------------------------------------

    def first(self, vid: int, holds: Callable[[VehicleState], bool]) -> float:
        """When the fleet was first given a state of ``vid`` for which ``holds``."""
        return next(t for t, states in self.track if holds(states[vid]))

    def requests(self, kind: type, vid: int | None = None) -> list[tuple[float, Request]]:
        return [(t, r) for t, r in self.sent
                if isinstance(r, kind) and (vid is None or r.vehicle_id == vid)]

    def task(self, path: str, state: str) -> list[Record]:
        """The records of ``path`` entering ``state``."""
        return [r for r in self.records if r.kind == "task" and r.data["task"] == path
                and r.data["state"] == state]

    def began(self, path: str) -> float:
        return self.task(path, "running")[0].time

    def ended(self, path: str) -> float:
        return next(r.time for r in self.records if r.kind == "task"
                    and r.data["task"] == path and r.data["state"] != "running")

    def flown_by(self, path: str) -> set[int | None]:
        return {r.vehicle_id for r in self.task(path, "running")}

    def state_of(self, path: str, vid: int = 1) -> TaskState:
        """The task's state in ``vid``'s view (PENDING: the vehicle never flew it)."""
        return self.fleet.views()[vid].task_states[path]

    def decisions(self, text: str) -> list[Record]:
        return [r for r in self.records if r.kind == "decision" and text in r.data["message"]]

    def picks(self) -> list[Record]:
        return [r for r in self.records if r.kind == "pick"]


def test_parallel_branches_fly_at_the_same_time_on_different_vehicles() -> None:
    body = ('<task name="Both" composition="parallel">'
            '<task name="A" role="a">' + take_off("A up") + goto("A go", "(50, 0, 5)")
            + land("A land") + '</task>'
            '<task name="B" role="b">' + take_off("B up") + goto("B go", "(0, 20, 5)")
            + land("B land") + '</task></task>\n')
    flight = FleetFlight(body, 2, extra=roles("a", "b")).run()
    assert flight.fleet.status is Status.COMPLETED
    assert flight.flown_by("Both/A/A go") == {1} and flight.flown_by("Both/B/B go") == {2}
    assert [r.target for _, r in flight.requests(GoTo, 1)] == [(50, 0, 5)]
    assert [r.target for _, r in flight.requests(GoTo, 2)] == [(0, 20, 5)]
    # Both take off at once; B's shorter leg ends first; the task ends with the slower A.
    assert flight.began("Both/A/A up") == flight.began("Both/B/B up") == 0.0
    assert flight.ended("Both/B") < flight.ended("Both/A")
    assert flight.began("Both/A/A go") < flight.ended("Both/B/B go")
    assert flight.ended("Both") == flight.ended("Both/A")
    assert flight.vehicles[1].position == pytest.approx((50, 0, 0), abs=0.55)
    assert flight.vehicles[2].position == pytest.approx((0, 20, 0), abs=0.55)


def test_first_stops_the_slower_branch_and_the_mission_goes_on() -> None:
    body = ('<task name="Race" composition="first">'
            '<task name="A" role="a">' + take_off("A up") + hover("A wait", 3) + '</task>'
            '<task name="B" role="b">' + take_off("B up") + goto("B far", "(200, 0, 5)")
            + '</task></task>\n'
            '<task name="After" role="b">' + goto("Back", "(0, 0, 5)") + land("Down")
            + '</task>\n')
    flight = FleetFlight(body, 2, extra=roles("a", "b")).run()
    assert flight.fleet.status is Status.COMPLETED
    a_done = flight.ended("Race/A")
    assert flight.ended("Race") == a_done
    [(held_at, _)] = flight.requests(Hold, 2)
    assert held_at == a_done  # told to hold the moment A finished
    assert all(t != a_done for t, _ in flight.requests(Hold, 1))
    assert flight.state_of("Race/B", 2) is TaskState.ABORTED
    assert flight.state_of("Race/B/B far", 2) is TaskState.ABORTED
    assert flight.state_of("Race/A") is TaskState.DONE
    assert flight.began("After/Back") == a_done and flight.flown_by("After/Back") == {2}
    assert flight.vehicles[2].position == pytest.approx((0, 0, 0), abs=0.55)
    # At the end of the mission A's vehicle, still hovering, is brought home.
    assert [t for t, _ in flight.requests(ReturnToLaunch, 1)] == [flight.time]


def test_choice_runs_the_first_child_whose_conditions_hold() -> None:
    body = (take_off() + '<task name="Pick" composition="choice">'
            '<task name="High">' + condition("ALTITUDE", "greater than", "50")
            + '<action name="MOVE"><argument name="coordinates" value="(9, 0, 0)"/></action>'
            '</task><task name="Low">' + condition("ALTITUDE", "less than", "50")
            + '<action name="MOVE"><argument name="coordinates" value="(0, 4, 0)"/></action>'
            '</task><task name="Any"><action name="MOVE"><argument name="coordinates" '
            'value="(0, -4, 0)"/></action></task></task>\n' + land())
    flight = FleetFlight(body, 1).run()
    assert flight.fleet.status is Status.COMPLETED
    assert flight.state_of("Pick/Low") is TaskState.DONE
    assert flight.state_of("Pick/High") is TaskState.SKIPPED
    assert flight.state_of("Pick/Any") is TaskState.SKIPPED
    assert flight.vehicles[1].position == pytest.approx((0, 4, 0), abs=0.55)


def test_choice_with_no_child_holding_waits_until_one_does() -> None:
    body = (take_off() + '<task name="Pick" composition="choice">'
            '<task name="Seen">' + condition("seen", "equal", "yes")
            + '<action name="MOVE"><argument name="coordinates" value="(6, 0, 0)"/></action>'
            '</task><task name="Drained">' + condition("BATTERY_CHARGE_PERCENTAGE", "less than",
                                                       "20")
            + '<action name="MOVE"><argument name="coordinates" value="(0, 6, 0)"/></action>'
            '</task></task>\n' + land())
    flight = FleetFlight(body, 1, extra=SEEN)
    flight.run(each=lambda f: f.vehicles[1].detections.__setitem__("seen", f.time >= 7))
    assert flight.fleet.status is Status.COMPLETED
    [chosen] = flight.decisions("chosen")
    assert chosen.time == 7.0 and "Seen" in chosen.data["message"]
    assert flight.began("Pick/Seen") == 7.0
    assert flight.state_of("Pick/Drained") is TaskState.SKIPPED
    assert flight.vehicles[1].position == pytest.approx((6, 0, 0), abs=0.55)


def test_until_stops_an_endless_loiter_and_the_next_task_runs() -> None:
    body = (take_off() + '<task name="Patrol">'
            '<until>' + condition("BATTERY_CHARGE_PERCENTAGE", "less than", "90") + '</until>'
            '<action name="LOITER"><argument name="radius" value="5"/></action></task>\n'
            '<task name="Home"><action name="RETURN_HOME_AND_LAND"/></task>\n')
    vehicle = FakeVehicle(drain_per_second=1.0)
    flight = FleetFlight(body, [vehicle]).run()
    assert flight.fleet.status is Status.COMPLETED
    # The battery, drained 1 %/s from arming, falls below 90 % after 10 s.
    stopped = flight.ended("Patrol")
    assert stopped == flight.first(1, lambda s: s.battery < 90)
    assert 10.0 <= stopped <= 10.5
    assert flight.state_of("Patrol") is TaskState.DONE
    assert [t for t, _ in flight.requests(Hold, 1)] == [stopped]
    assert flight.began("Home") == stopped
    assert len(flight.requests(ReturnToLaunch, 1)) == 1
    assert vehicle.position[2] == 0 and not vehicle.armed


def test_a_task_stopped_by_until_is_logged_running_once_and_done_once() -> None:
    body = (take_off() + '<task name="Patrol"><until>'
            + condition("BATTERY_CHARGE_PERCENTAGE", "less than", "90") + '</until>'
            '<action name="LOITER"><argument name="radius" value="5"/></action></task>\n'
            + land())
    flight = FleetFlight(body, [FakeVehicle(drain_per_second=1.0)]).run()
    states = [r.data["state"] for r in flight.records
              if r.kind == "task" and r.data["task"] == "Patrol"]
    assert states == ["running", "done"]
    [stopped] = [r for r in flight.records if r.kind == "action" and "stopped" in
                 r.data["message"]]
    assert stopped.data["why"] == "Patrol: its until conditions hold"


def test_wait_for_holds_the_task_until_its_conditions_hold() -> None:
    body = ('<task name="Go"><wait_for>'
            + condition("BATTERY_CHARGE_PERCENTAGE", "greater than or equal to", "90")
            + '</wait_for>' + take_off() + land() + '</task>\n')
    vehicle = FakeVehicle(battery=50.0)

    def charge(flight: FleetFlight) -> None:
        if flight.time >= 4.0:
            vehicle.battery = 95.0
    flight = FleetFlight(body, [vehicle]).run(each=charge)
    assert flight.fleet.status is Status.COMPLETED
    assert flight.began("Go") == 4.0
    assert flight.sent[0][0] == 4.0  # nothing was asked of the vehicle before


def test_wait_for_on_another_roles_vehicle() -> None:
    body = ('<task name="Both" composition="parallel">'
            '<task name="A" role="a">' + take_off("A up", 10) + hover("A wait", 2)
            + land("A land") + '</task>'
            '<task name="B" role="b"><wait_for>' + condition("ALTITUDE", "greater than", "4", "a")
            + '</wait_for>' + take_off("B up") + land("B land") + '</task></task>\n')
    flight = FleetFlight(body, 2, extra=roles("a", "b")).run()
    assert flight.fleet.status is Status.COMPLETED
    a_up = flight.first(1, lambda s: s.altitude > 4)
    assert a_up > 1.0
    assert flight.began("Both/B") == a_up
    assert min(t for t, r in flight.sent if r.vehicle_id == 2) == a_up

def test_time_limit_stops_the_task_and_the_mission_goes_on() -> None:
    body = (take_off() + '<task name="Bounded" time_limit="5">' + hover("Long", 60)
            + '</task>\n' + goto("Next", "(3, 0, 5)") + land())
    flight = FleetFlight(body, 1).run()
    assert flight.fleet.status is Status.COMPLETED
    began = flight.began("Bounded")
    assert flight.ended("Bounded") - began == pytest.approx(5.0, abs=STEP + 1e-6)
    assert flight.state_of("Bounded") is TaskState.DONE
    assert flight.state_of("Bounded/Long") is TaskState.ABORTED
    assert flight.began("Next") == flight.ended("Bounded")
    assert any(t == flight.ended("Bounded") for t, _ in flight.requests(Hold, 1))


def reject_while(vid: int, kind: str, start: float, end: float = 1e9):
    """A script that makes vehicle ``vid`` refuse ``kind`` requests from ``start`` to ``end``."""
    def script(flight: FleetFlight) -> None:
        reject = flight.vehicles[vid].reject
        if start <= flight.time < end:
            reject[kind] = "rejected"
        else:
            reject.pop(kind, None)
    return script


def test_on_error_runs_the_handler_then_the_mission_goes_on_after_the_task() -> None:
    body = (take_off() + '<task name="Guarded">' + goto("Out", "(30, 0, 5)")
            + goto("Further", "(60, 0, 5)")
            + '<on_error>' + goto("Recover", "(0, 8, 5)") + '</on_error></task>\n'
            + goto("After", "(0, 0, 5)") + land())
    vehicle = FakeVehicle()
    flight = FleetFlight(body, [vehicle])
    flight.run(each=reject_while(1, "GoTo", 0.0, 2.05))  # only the first GO_TO, at 2 s
    assert flight.fleet.status is Status.COMPLETED
    assert flight.state_of("Guarded") is TaskState.FAILED
    assert flight.state_of("Guarded/Further") is TaskState.PENDING
    [failed] = flight.decisions("its on_error tasks run")
    assert "rejected" in failed.data["detail"]
    assert flight.began("Guarded/Recover") == failed.time
    assert flight.began("After") == flight.ended("Guarded/Recover")
    assert [r.target for _, r in flight.requests(GoTo, 1)][-2:] == [(0, 8, 5), (0, 0, 5)]
    assert vehicle.position == pytest.approx((0, 0, 0), abs=0.55)


def test_a_failure_inside_the_handler_goes_up_to_the_next_on_error() -> None:
    body = (take_off() + '<task name="Outer"><task name="Inner">' + goto("Out", "(30, 0, 5)")
            + '<on_error>' + goto("Inner fix", "(0, 8, 5)") + '</on_error></task>'
            '<on_error>' + land("Outer fix") + '</on_error></task>\n' + hover("After", 1))
    flight = FleetFlight(body, [FakeVehicle(reject={"GoTo": "rejected"})]).run()
    assert flight.fleet.status is Status.COMPLETED
    assert flight.state_of("Outer/Inner") is TaskState.FAILED
    assert flight.state_of("Outer") is TaskState.FAILED
    assert flight.began("Outer/Outer fix") > flight.began("Outer/Inner/Inner fix")
    assert len(flight.requests(GoTo, 1)) == 2  # Out, then Inner fix: both refused
    assert flight.state_of("After") is TaskState.DONE


def test_unhandled_failure_fails_the_mission_and_every_flying_vehicle_is_made_safe() -> None:
    body = ('<task name="Both" composition="parallel">'
            '<task name="A" role="a">' + take_off("A up") + goto("A go", "(40, 0, 5)")
            + '</task>'
            '<task name="B" role="b">' + take_off("B up") + goto("B go", "(0, 40, 5)")
            + '</task></task>\n')
    flight = FleetFlight(body, 2, extra=roles("a", "b"))
    flight.run(each=reject_while(1, "GoTo", 1.0))
    assert flight.fleet.status is Status.FAILED
    assert "rejected" in flight.fleet.reason
    end = flight.time
    # The sibling is stopped (hold), then both vehicles, in the air, are brought home.
    [(held, _)] = flight.requests(Hold, 2)
    [(home_2, _)] = flight.requests(ReturnToLaunch, 2)
    [(home_1, _)] = flight.requests(ReturnToLaunch, 1)
    assert held == home_2 == home_1 == end
    kinds = [type(r) for _, r in flight.sent if r.vehicle_id == 2]
    assert kinds.index(Hold) < kinds.index(ReturnToLaunch)
    assert flight.state_of("Both/A", 1) is TaskState.FAILED
    assert flight.state_of("Both/B", 2) is TaskState.ABORTED
    [stopped] = [r for r in flight.records if r.kind == "action" and "stopped" in
                 r.data["message"]]
    assert (stopped.time, stopped.vehicle_id) == (end, 2)
    assert stopped.data["message"] == "GO_TO_POINT stopped: a sibling branch failed"


def test_forever_loop_is_ended_by_the_time_limit_and_rounds_are_counted() -> None:
    body = (take_off() + '<task name="Patrol" time_limit="20"><loop/>'
            + goto("Out", "(10, 0, 5)") + goto("Back", "(0, 0, 5)") + '</task>\n' + land())
    flight = FleetFlight(body, 1).run()
    assert flight.fleet.status is Status.COMPLETED
    assert flight.ended("Patrol") - flight.began("Patrol") == pytest.approx(20, abs=STEP + 1e-6)
    rounds = [r.data["round"] for r in flight.decisions(": round ")]
    assert rounds == list(range(2, len(rounds) + 2))
    # A leg of 10 m at 5 m/s takes 2 s: about five rounds of two legs in 20 s.
    assert len(flight.task("Patrol/Out", "running")) == len(rounds) + 1
    assert len(rounds) + 1 in (5, 6)
    assert flight.state_of("Patrol") is TaskState.DONE


def test_forever_loop_is_ended_by_until() -> None:
    body = (take_off() + '<task name="Patrol"><until>' + condition("seen", "equal", "yes")
            + '</until><loop/>' + goto("Out", "(10, 0, 5)") + goto("Back", "(0, 0, 5)")
            + '</task>\n' + land())
    flight = FleetFlight(body, 1, extra=SEEN)
    flight.run(each=lambda f: f.vehicles[1].detections.__setitem__("seen", f.time >= 9))
    assert flight.fleet.status is Status.COMPLETED
    assert flight.ended("Patrol") == 9.0
    assert flight.began("Land") == 9.0


def test_while_loop_ends_when_its_condition_turns_false() -> None:
    body = (take_off() + '<task name="Laps"><loop>'
            + condition("BATTERY_CHARGE_PERCENTAGE", "greater than", "95") + '</loop>'
            + goto("Out", "(10, 0, 5)") + goto("Back", "(0, 0, 5)") + '</task>\n' + land())
    vehicle = FakeVehicle(drain_per_second=0.5)
    flight = FleetFlight(body, [vehicle]).run()
    assert flight.fleet.status is Status.COMPLETED
    [end] = flight.decisions("loop ends")
    laps = len(flight.task("Laps/Back", "done"))
    assert end.data["rounds"] == laps >= 2
    # Each round starts with the battery above 95 %; the round after it is not started.
    starts = [r.time for r in flight.task("Laps/Out", "running")]
    battery = {t: states[1].battery for t, states in flight.track}
    assert all(battery.get(t, 100.0) > 95 for t in starts)
    assert battery[end.time] <= 95
    assert flight.state_of("Laps") is TaskState.DONE


def pick_failure(flight: FleetFlight) -> Record:
    [failed] = [r for r in flight.picks() if r.data["message"].startswith("pick failed")]
    return failed


def test_pick_refuses_wrong_type_missing_payload_and_outside_the_region() -> None:
    role = ('<role name="r" type="hexacopter" pick_timeout="5"><payload name="thermal"/>'
            '<region><circle north="0" east="0" radius="50"/></region></role>')
    vehicles = [FakeVehicle(vehicle_id=1),  # a quadcopter
                FakeVehicle(vehicle_id=2, vehicle_type="hexacopter"),  # no thermal camera
                FakeVehicle(vehicle_id=3, vehicle_type="hexacopter", position=(80.0, 0.0, 0.0),
                            capabilities=frozenset({"thermal"})),
                FakeVehicle(vehicle_id=4, vehicle_type="hexacopter", position=(30.0, 30.0, 0.0),
                            capabilities=frozenset({"thermal"}))]
    flight = FleetFlight(take_off() + land(), vehicles, extra=roles(role)).run()
    assert flight.fleet.status is Status.COMPLETED
    [picked] = flight.picks()
    assert picked.data["vehicles"] == [4] and picked.time == 0.0
    assert flight.flown_by("Take off") == {4}
    assert {r.vehicle_id for _, r in flight.sent} == {4}


def test_pick_that_cannot_be_satisfied_fails_the_task_naming_each_vehicle() -> None:
    role = ('<role name="r" type="hexacopter" pick_timeout="5"><payload name="thermal"/>'
            '<region><polygon><point north="0" east="0"/><point north="0" east="50"/>'
            '<point north="50" east="50"/><point north="50" east="0"/></polygon></region>'
            '</role>')
    vehicles = [FakeVehicle(vehicle_id=1),
                FakeVehicle(vehicle_id=2, vehicle_type="hexacopter"),
                FakeVehicle(vehicle_id=3, vehicle_type="hexacopter", position=(10.0, -5.0, 0.0),
                            capabilities=frozenset({"thermal"}))]
    flight = FleetFlight(take_off() + land(), vehicles, extra=roles(role)).run()
    assert flight.fleet.status is Status.FAILED
    failed = pick_failure(flight)
    assert failed.time == 5.0
    assert failed.data["refused"] == {1: "a quadcopter, not hexacopter", 2: "no thermal",
                                      3: "outside the region (at 10 m N, -5 m E)"}
    for text in ("vehicle 1: a quadcopter", "vehicle 2: no thermal", "vehicle 3: outside"):
        assert text in flight.fleet.reason
    assert flight.sent == []
    assert flight.state_of("Take off") is TaskState.FAILED


def test_a_vehicle_outside_a_circle_region_is_refused() -> None:
    role = ('<role name="r" pick_timeout="1"><region><circle north="10" east="0" radius="50"/>'
            '</region></role>')
    vehicles = [FakeVehicle(vehicle_id=1, position=(70.0, 0.0, 0.0)),
                FakeVehicle(vehicle_id=2, position=(59.0, 5.0, 0.0))]
    flight = FleetFlight(hover("W", 1), vehicles, extra=roles(role)).run()
    assert flight.fleet.status is Status.COMPLETED
    assert flight.picks()[0].data["vehicles"] == [2]
    flight = FleetFlight(hover("W", 1), vehicles[:1], extra=roles(role)).run()
    assert pick_failure(flight).data["refused"] == {1: "outside the region (at 70 m N, 0 m E)"}

def test_payloads_declared_for_the_run_count() -> None:
    role = '<role name="r" pick_timeout="1"><payload name="Thermal"/></role>'
    flight = FleetFlight(take_off() + land(), 2, extra=roles(role),
                         payloads={2: ["thermal"]}).run()
    assert flight.fleet.status is Status.COMPLETED
    assert flight.flown_by("Take off") == {2}


def test_pick_failure_can_be_handled_by_on_error() -> None:
    body = ('<task name="Needs two" role="pair">' + take_off() + land()
            + '<on_error><task name="Alone" role="solo">' + take_off("Solo up") + land("Solo down")
            + '</task></on_error></task>\n')
    extra = roles('<role name="pair" count="2" pick_timeout="3"/>', "solo")
    flight = FleetFlight(body, 1, extra=extra).run()
    assert flight.fleet.status is Status.COMPLETED
    assert pick_failure(flight).time == 3.0
    assert flight.state_of("Needs two") is TaskState.FAILED
    assert flight.began("Needs two/Alone/Solo up") == 3.0
    assert flight.flown_by("Needs two/Alone/Solo up") == {1}


def test_pick_order_is_longest_free_first_then_lowest_id() -> None:
    sortie = ''.join(f'<task name="S{i}" role="r" release="r">' + hover(f"W{i}", 1) + '</task>'
                     for i in range(1, 5))
    flight = FleetFlight(sortie, 3, extra=roles("r")).run()
    assert flight.fleet.status is Status.COMPLETED
    # Never-used vehicles first by id; then the one released longest ago.
    assert [p.data["vehicles"] for p in flight.picks()] == [[1], [2], [3], [1]]
    assert [r.data["role"] for r in flight.records if r.kind == "release"] == ["r"] * 4


def test_a_vehicle_is_never_bound_to_two_roles() -> None:
    body = (f'<task name="A" role="a">{hover("Wa", 1)}</task>'
            f'<task name="B" role="b">{hover("Wb", 1)}</task>\n')
    extra = roles("a", '<role name="b" pick_timeout="2"/>')
    flight = FleetFlight(body, 1, extra=extra).run()
    assert flight.fleet.status is Status.FAILED
    assert pick_failure(flight).data["refused"] == {1: "busy (role 'a')"}


def test_release_sends_a_flying_vehicle_home_and_disarms_an_armed_grounded_one() -> None:
    body = ('<task name="Both" composition="parallel" release="a b">'
            f'<task name="A" role="a">{take_off("Up")}</task>'
            f'<task name="B" role="b">{hover("Idle", 1)}</task></task>\n'
            f'<task name="Later" role="c">{hover("Rest", 2)}</task>\n')
    vehicles = [FakeVehicle(vehicle_id=1), FakeVehicle(vehicle_id=2, armed=True),
                FakeVehicle(vehicle_id=3)]
    flight = FleetFlight(body, vehicles, extra=roles("a", "b", "c")).run()
    assert flight.fleet.status is Status.COMPLETED
    released = flight.ended("Both")
    assert [t for t, _ in flight.requests(ReturnToLaunch, 1)] == [released]
    assert [t for t, _ in flight.requests(Disarm, 2)] == [released]
    assert flight.began("Later") == released and flight.flown_by("Later") == {3}
    with_land = FleetFlight(body, [FakeVehicle(vehicle_id=1), FakeVehicle(vehicle_id=2),
                                   FakeVehicle(vehicle_id=3)],
                            extra=roles("a", "b", "c"), options=Options(safe_state="land")).run()
    assert len(with_land.requests(Land, 1)) == 1 and with_land.requests(ReturnToLaunch) == []
    assert with_land.requests(Disarm) == []  # nothing to do for a vehicle that never armed


def test_a_role_of_two_flies_the_task_on_both_and_ends_with_the_slower() -> None:
    body = ('<task name="Survey" role="team">' + take_off() + goto("Out", "(20, 0, 5)")
            + land() + '</task>\n' + '<task name="After" role="team">'
            + condition("LANDED", "equal", "yes", "team") + hover("Rest", 1) + '</task>\n')
    vehicles = [FakeVehicle(vehicle_id=1), FakeVehicle(vehicle_id=2, speed=2.5),
                FakeVehicle(vehicle_id=3)]
    flight = FleetFlight(body, vehicles, extra=roles('<role name="team" count="2"/>')).run()
    assert flight.fleet.status is Status.COMPLETED
    assert flight.picks()[0].data["vehicles"] == [1, 2]
    assert flight.flown_by("Survey/Out") == {1, 2}
    done = {r.vehicle_id: r.time for r in flight.task("Survey", "done")}
    assert done[1] < done[2]
    assert flight.began("After") == done[2]  # when both are done
    assert flight.flown_by("After") == {1, 2}
    assert [r.vehicle_id for _, r in flight.sent if r.vehicle_id == 3] == []


def test_a_team_is_released_when_its_last_vehicle_is_done() -> None:
    body = ('<task name="Survey" role="team" release="team">' + take_off()
            + goto("Out", "(20, 0, 5)") + land() + '</task>\n'
            '<task name="Next" role="team">' + hover("Rest", 1) + '</task>\n')
    vehicles = [FakeVehicle(vehicle_id=1), FakeVehicle(vehicle_id=2, speed=2.5),
                FakeVehicle(vehicle_id=3)]
    flight = FleetFlight(body, vehicles, extra=roles('<role name="team" count="2"/>')).run()
    assert flight.fleet.status is Status.COMPLETED
    slower = max(r.time for r in flight.task("Survey", "done"))
    released = [r for r in flight.records if r.kind == "release"]
    assert [(r.time, r.vehicle_id) for r in released[:2]] == [(slower, 1), (slower, 2)]
    assert flight.requests(ReturnToLaunch) == []  # both had landed
    assert vehicles[1].position == pytest.approx((20, 0, 0), abs=0.55)
    # The re-pick takes the never-used vehicle 3 first, then 1 (tied with 2, lower id).
    assert [p.data["vehicles"] for p in flight.picks()] == [[1, 2], [3, 1]]


def test_a_condition_on_an_unbound_role_reads_unknown() -> None:
    body = ('<task name="A" role="a">'
            '<task name="If b is charged">'
            + condition("BATTERY_CHARGE_PERCENTAGE", "greater than", "0", "b")
            + '<action name="WAIT"><argument name="duration" value="1"/></action></task>'
            '<task name="If b is unknown">'
            + condition("BATTERY_CHARGE_PERCENTAGE", "known", "no", "b")
            + '<action name="WAIT"><argument name="duration" value="1"/></action></task>'
            '</task>\n'
            '<task name="B" role="b">' + hover("Wb", 1) + '</task>\n')
    flight = FleetFlight(body, 2, extra=roles("a", "b")).run()
    assert flight.fleet.status is Status.COMPLETED
    assert flight.state_of("A/If b is charged") is TaskState.SKIPPED
    assert flight.state_of("A/If b is unknown") is TaskState.DONE
    [skipped] = flight.decisions("skipped")
    assert skipped.data["read"] is None


def test_a_role_condition_on_a_team_holds_only_for_every_vehicle() -> None:
    body = ('<task name="Up" role="team">' + take_off() + '</task>\n'
            '<task name="Scout" role="s"><wait_for>'
            + condition("BATTERY_CHARGE_PERCENTAGE", "less than", "90", "team")
            + '</wait_for>' + hover("Ws", 1) + '</task>\n')
    vehicles = [FakeVehicle(vehicle_id=1, drain_per_second=2.0),
                FakeVehicle(vehicle_id=2, drain_per_second=1.0), FakeVehicle(vehicle_id=3)]
    extra = roles('<role name="team" count="2"/>', "s")
    flight = FleetFlight(body, vehicles, extra=extra).run(seconds=60)
    assert flight.fleet.status is Status.COMPLETED
    assert flight.began("Scout") == flight.first(2, lambda s: s.battery < 90)
    assert flight.began("Scout") > flight.first(1, lambda s: s.battery < 90)
    assert flight.flown_by("Scout") == {3}


def seen_on(vid: int, at: float) -> Callable[[FleetFlight], None]:
    def script(flight: FleetFlight) -> None:
        flight.vehicles[vid].detections["seen"] = flight.time >= at
    return script


def memorize(name: str, role: str = "") -> str:
    role_attribute = f' role="{role}"' if role else ""
    return (f'<event name="{name}"{role_attribute}>' + condition("seen", "equal", "yes")
            + '<action name="MEMORIZE_POINT"><argument name="coordinates" label="spot"/>'
            '</action><termination mode="CONTINUE"/></event>')


PARALLEL_HOVER = ('<task name="Both" composition="parallel">'
                  f'<task name="A" role="a">{take_off("A up")}{hover("A hover", 10)}'
                  f'{land("A land")}</task>'
                  f'<task name="B" role="b">{take_off("B up")}{hover("B hover", 10)}'
                  f'{land("B land")}</task></task>\n')


def fired(flight: FleetFlight) -> list[tuple[float, int | None, str]]:
    return [(r.time, r.vehicle_id, r.data["event"]) for r in flight.records if r.kind == "event"]


def test_an_event_with_a_role_fires_only_for_that_roles_vehicle() -> None:
    events = memorize("On a", role="a")
    both = lambda f: (seen_on(1, 6.0)(f), seen_on(2, 4.0)(f))  # noqa: E731
    flight = FleetFlight(PARALLEL_HOVER, 2, events, roles("a", "b") + SEEN).run(each=both)
    assert flight.fleet.status is Status.COMPLETED
    assert fired(flight) == [(6.0, 1, "On a")]


def test_an_event_without_a_role_fires_on_each_vehicles_own_state() -> None:
    events = memorize("Seen")
    both = lambda f: (seen_on(1, 6.0)(f), seen_on(2, 4.0)(f))  # noqa: E731
    flight = FleetFlight(PARALLEL_HOVER, 2, events, roles("a", "b") + SEEN).run(each=both)
    assert fired(flight) == [(4.0, 2, "Seen"), (6.0, 1, "Seen")]
    assert flight.fleet.views()[1].labels["spot"] == pytest.approx((0, 0, 5), abs=0.6)


def test_end_mission_from_one_vehicle_ends_the_whole_mission() -> None:
    events = ('<event name="Found" role="b">' + condition("seen", "equal", "yes")
              + '<termination mode="END_MISSION"/></event>')
    flight = FleetFlight(PARALLEL_HOVER, 2, events, roles("a", "b") + SEEN)
    flight.run(each=seen_on(2, 5.0))
    assert flight.fleet.status is Status.COMPLETED
    assert "Found" in flight.fleet.reason and flight.time == 5.0
    # Vehicle 1, stopped in its hover, and vehicle 2 are both sent home at once.
    assert [t for t, _ in flight.requests(ReturnToLaunch, 1)] == [5.0]
    assert [t for t, _ in flight.requests(ReturnToLaunch, 2)] == [5.0]
    assert flight.state_of("Both/A/A hover") is TaskState.ABORTED
    assert flight.task("Both/A/A land", "running") == []


def test_a_lost_vehicle_fails_its_task_and_is_never_picked_again() -> None:
    body = ('<task name="Both" composition="parallel">'
            f'<task name="A" role="a">{take_off("A up")}{goto("A go", "(60, 0, 5)")}'
            f'{land("A land")}</task>'
            f'<task name="B" role="b" release="b">{take_off("B up")}{hover("B hover", 20)}'
            f'<on_error><task name="Spare" role="c" release="c">{hover("Cover", 1)}</task>'
            '</on_error></task></task>\n'
            f'<task name="Again" role="b">{hover("Wb", 1)}</task>\n')
    flight = FleetFlight(body, 3, extra=roles("a", "b", "c"))
    flight.run(seconds=5)
    flight.take(flight.fleet.lost(flight.time, 2, "link lost"))
    lost_at = flight.time
    flight.run()
    assert flight.fleet.status is Status.COMPLETED
    [failed] = flight.decisions("its on_error tasks run")
    assert failed.time == lost_at and "vehicle 2: link lost" in failed.data["detail"]
    assert flight.state_of("Both/B", 2) is TaskState.FAILED
    assert flight.began("Both/B/Spare/Cover") == lost_at
    # Released, vehicle 2 is still sent the safe state in case its link comes back, but
    # it is not picked again: b goes to vehicle 3 once c has freed it.
    assert [type(r) for t, r in flight.sent if r.vehicle_id == 2 and t >= lost_at] == \
        [Hold, ReturnToLaunch]
    assert [p.data["vehicles"] for p in flight.picks()] == [[1], [2], [3], [3]]
    assert flight.flown_by("Again/Wb") == {3}
    # Vehicle 1 flew on regardless.
    assert flight.ended("Both/A") > lost_at
    assert flight.vehicles[1].position == pytest.approx((60, 0, 0), abs=0.55)


def test_a_lost_vehicle_without_a_handler_fails_the_mission() -> None:
    flight = FleetFlight(PARALLEL_HOVER, 2, extra=roles("a", "b")).run(seconds=5)
    flight.take(flight.fleet.lost(flight.time, 1, "link lost"))
    assert flight.fleet.status is Status.FAILED
    assert "vehicle 1: link lost" in flight.fleet.reason
    assert [type(r) for _, r in flight.sent if r.vehicle_id == 2][-2:] == [Hold, ReturnToLaunch]


def test_a_vehicle_that_ignores_every_request_never_stalls_the_other() -> None:
    kinds = {"SetMode", "Arm", "TakeOff", "GoTo", "Hold", "Land", "ReturnToLaunch", "Disarm"}
    body = ('<task name="Both" composition="parallel">'
            f'<task name="A" role="a">{take_off("A up")}{goto("A go", "(40, 0, 5)")}'
            f'{land("A land")}</task>'
            f'<task name="B" role="b">{take_off("B up")}{land("B land")}</task></task>\n')
    silent = FakeVehicle(vehicle_id=2, ignore=kinds)
    flight = FleetFlight(body, [FakeVehicle(vehicle_id=1), silent],
                         extra=roles("a", "b")).run(seconds=15)
    # Vehicle 1 moved on every step of its leg and finished while vehicle 2 never answered.
    norths = [states[1].position[0] for t, states in flight.track if 2.2 < t < 9.8]
    assert all(b > a for a, b in pairwise(norths))
    assert flight.task("Both/A", "done") and flight.vehicles[1].position == \
        pytest.approx((40, 0, 0), abs=0.55)
    assert flight.fleet.status is Status.RUNNING and silent.position == (0, 0, 0)
    # The runner calls the silent vehicle lost: the mission, without a handler, fails.
    flight.take(flight.fleet.lost(flight.time, 2, "no heartbeat for 5 s"))
    assert flight.fleet.status is Status.FAILED
    assert "vehicle 2: no heartbeat for 5 s" in flight.fleet.reason


def test_a_mission_without_roles_or_orchestration_is_a_fleet_of_one() -> None:
    """Every record is its one vehicle's, the mission's own included; each task says it
    runs once and how it ended once, after its sub-tasks."""
    body = (take_off() + goto("Out", "(8, 3, 5)") + '<task name="Look"><skill '
            'name="RECOGNIZE_ITEMS"/>' + hover("Scan", 2) + '</task>\n' + land())
    flight = FleetFlight(body, 1, memorize("Seen"), SEEN).run(each=seen_on(1, 4.0))
    assert flight.fleet.status is Status.COMPLETED
    assert {r.vehicle_id for r in flight.records} == {1}
    lines = [(r.data["task"], r.data["state"]) for r in flight.records if r.kind == "task"]
    assert lines == [("Take off", "running"), ("Take off", "done"), ("Out", "running"),
                     ("Out", "done"), ("Look", "running"), ("Look/Scan", "running"),
                     ("Look/Scan", "done"), ("Look", "done"), ("Land", "running"),
                     ("Land", "done")]
    skills = [(t, r.enabled) for t, r in flight.requests(SetSkill, 1)]
    assert skills == [(flight.began("Look"), True), (flight.ended("Look"), False)]
    assert [(r.time, r.data["event"]) for r in flight.records if r.kind == "event"] == \
        [(4.0, "Seen")]


def test_a_mission_without_roles_but_with_until_flies_on_its_one_vehicle() -> None:
    body = (take_off() + '<task name="Patrol"><until>' + condition("seen", "equal", "yes")
            + '</until>' + goto("Far", "(100, 0, 5)") + '</task>\n' + land())
    flight = FleetFlight(body, 1, extra=SEEN).run(each=seen_on(1, 6.0))
    assert flight.fleet.status is Status.COMPLETED
    assert flight.ended("Patrol") == 6.0 and flight.began("Land") == 6.0
    assert {r.vehicle_id for _, r in flight.sent} == {1}
    assert 15 < flight.vehicles[1].position[0] < 25 and flight.vehicles[1].position[2] == 0


def test_abort_sends_every_bound_flying_vehicle_to_the_safe_state() -> None:
    flight = FleetFlight(PARALLEL_HOVER, 3, extra=roles("a", "b")).run(seconds=5)
    out = flight.fleet.abort(flight.time, flight.states(), "operator pressed Ctrl-C")
    flight.take(out)
    assert flight.fleet.status is Status.ABORTED
    assert flight.fleet.reason == "operator pressed Ctrl-C"
    # Both branches are stopped without a hold: the safe state is the one command.
    assert sorted((r.vehicle_id, r.name) for r in out.requests) == \
        [(1, "ReturnToLaunch"), (2, "ReturnToLaunch")]
    assert flight.state_of("Both/A/A hover") is TaskState.ABORTED
    assert flight.state_of("Both/B/B hover", 2) is TaskState.ABORTED
    for _ in range(300):  # the vehicles carry the requests out on their own
        for vehicle in flight.vehicles.values():
            vehicle.advance(STEP)
    assert all(v.position[2] == 0 and not v.armed for v in flight.vehicles.values())
    assert flight.vehicles[3].submitted == []


def test_a_pick_waits_for_a_vehicle_another_role_releases() -> None:
    body = ('<task name="Both" composition="parallel">'
            f'<task name="A" role="a" release="a">{hover("Wa", 3)}</task>'
            f'<task name="B" role="b">{hover("Wb", 1)}</task></task>\n')
    extra = roles("a", '<role name="b" pick_timeout="10"/>')
    flight = FleetFlight(body, 1, extra=extra).run()
    assert flight.fleet.status is Status.COMPLETED
    released = flight.ended("Both/A")
    [_, b] = flight.picks()
    assert b.time == released and b.data["waited"] == released
    assert flight.began("Both/B/Wb") == released and flight.flown_by("Both/B/Wb") == {1}


def test_a_lost_vehicle_is_named_in_a_pick_failure() -> None:
    flight = FleetFlight(hover("W", 1), 2, extra=roles('<role name="r" pick_timeout="2" '
                                                        'type="hexacopter"/>'))
    flight.take(flight.fleet.lost(0.0, 2, "link lost"))
    flight.run()
    assert pick_failure(flight).data["refused"] == {1: "a quadcopter, not hexacopter",
                                                    2: "link lost"}


def test_time_limit_does_not_count_the_wait_for_wait() -> None:
    body = (take_off() + '<task name="Later" time_limit="5"><wait_for>'
            + condition("seen", "equal", "yes") + '</wait_for>' + hover("Long", 60)
            + '</task>\n' + land())
    flight = FleetFlight(body, 1, extra=SEEN).run(each=seen_on(1, 4.0))
    assert flight.fleet.status is Status.COMPLETED
    assert flight.began("Later") == 4.0
    assert flight.ended("Later") == pytest.approx(9.0, abs=STEP + 1e-6)


def test_a_choice_wait_is_bounded_by_its_time_limit() -> None:
    body = (take_off() + '<task name="Pick" composition="choice" time_limit="4">'
            '<task name="Seen">' + condition("seen", "equal", "yes")
            + '<action name="MOVE"><argument name="coordinates" value="(6, 0, 0)"/></action>'
            '</task></task>\n' + land())
    flight = FleetFlight(body, 1, extra=SEEN).run()
    assert flight.fleet.status is Status.COMPLETED
    assert flight.ended("Pick") - flight.began("Pick") == pytest.approx(4.0, abs=STEP + 1e-6)
    assert flight.decisions("chosen") == [] and flight.requests(GoTo) == []
    assert flight.state_of("Pick") is TaskState.DONE


def test_abort_mission_from_one_vehicle_aborts_the_whole_mission() -> None:
    events = ('<event name="Fault" role="a">' + condition("seen", "equal", "yes")
              + '<termination mode="ABORT_MISSION"/></event>')
    flight = FleetFlight(PARALLEL_HOVER, 2, events, roles("a", "b") + SEEN)
    flight.run(each=seen_on(1, 5.0))
    assert flight.fleet.status is Status.ABORTED and "Fault" in flight.fleet.reason
    assert flight.time == 5.0
    assert {r.vehicle_id for _, r in flight.requests(ReturnToLaunch)} == {1, 2}
    assert flight.state_of("Both/B/B hover", 2) is TaskState.ABORTED


def test_a_relay_loop_takes_the_vehicle_free_longest_in_each_round() -> None:
    body = ('<task name="Relay" role="r" time_limit="30"><loop/>'
            '<task name="Sortie" release="r">' + take_off() + hover("Watch", 2) + land()
            + '</task></task>\n')
    flight = FleetFlight(body, 3, extra=roles("r")).run()
    assert flight.fleet.status is Status.COMPLETED
    picked = [p.data["vehicles"][0] for p in flight.picks()]
    assert picked[:5] == [1, 2, 3, 1, 2]
    sorties = flight.task("Relay/Sortie/Watch", "running")
    assert [r.vehicle_id for r in sorties] == picked
    # Each sortie starts once the previous vehicle has landed and been released (the
    # next round begins on the next step).
    releases = [r.time for r in flight.records if r.kind == "release"]
    picks = [p.time for p in flight.picks()][1:]
    assert all(0 < pick - release <= STEP + 1e-6
               for pick, release in zip(picks, releases, strict=False))


def test_a_forever_loop_is_ended_by_a_first_sibling() -> None:
    body = (take_off() + '<task name="Race" composition="first">'
            + hover("Timer", 7)
            + '<task name="Patrol"><loop/>' + goto("Out", "(10, 0, 5)") + goto("Back", "(0, 0, 5)")
            + '</task></task>\n' + land())
    flight = FleetFlight(body, 1).run()
    assert flight.fleet.status is Status.COMPLETED
    assert flight.ended("Race") == flight.ended("Race/Timer") == flight.began("Land")
    assert flight.state_of("Race/Patrol") is TaskState.ABORTED


def test_an_on_error_with_the_same_role_picks_another_vehicle_when_one_is_lost() -> None:
    body = (f'<task name="B" role="b">{take_off("B up")}{hover("B hover", 20)}'
            f'<on_error><task name="Cover">{hover("Cover hover", 1)}</task></on_error>'
            '</task>\n')
    flight = FleetFlight(body, 2, extra=roles("b")).run(seconds=5)
    flight.take(flight.fleet.lost(flight.time, 1, "link lost"))
    flight.run()
    assert flight.fleet.status is Status.COMPLETED
    assert [p.data["vehicles"] for p in flight.picks()] == [[1], [2]]
    assert flight.flown_by("B/Cover/Cover hover") == {2}


# --- regressions ------------------------------------------------------------------------------


def test_a_region_is_read_in_the_missions_frame_when_both_homes_are_known() -> None:
    """A vehicle's position is converted from its own home to the mission's before the
    region is tested: here the vehicle stands at its own home, which is 100 m north of the
    mission's."""
    from tml import geo
    from tml.world import DEFAULT_HOME, Home

    south = geo.to_global(-100.0, 0.0, 0.0, DEFAULT_HOME.latitude, DEFAULT_HOME.longitude,
                          DEFAULT_HOME.altitude)
    mission_home = Home(south[0], south[1], DEFAULT_HOME.altitude)
    environment = (f'<environment><home latitude="{mission_home.latitude:.8f}" '
                   f'longitude="{mission_home.longitude:.8f}" '
                   f'altitude="{mission_home.altitude:g}"/></environment>\n')
    role = ('<role name="r" pick_timeout="2"><region><circle north="100" east="0" '
            'radius="20"/></region></role>')
    vehicles = [FakeVehicle(vehicle_id=1, home=mission_home),  # at the mission's home
                FakeVehicle(vehicle_id=2)]  # at its own home, 100 m north of it
    flight = FleetFlight(take_off() + land(), vehicles, extra=environment + roles(role)).run()
    assert flight.fleet.status is Status.COMPLETED
    assert [p.data["vehicles"] for p in flight.picks()] == [[2]]
    assert flight.flown_by("Take off") == {2}
    alone = FleetFlight(take_off() + land(), vehicles[:1], extra=environment + roles(role))
    alone.run()
    assert pick_failure(alone).data["refused"] == {1: "outside the region (at 0 m N, 0 m E)"}


def test_a_skill_declared_by_a_bounded_task_and_its_sub_task_stays_on_until_the_task_ends(
) -> None:
    """Skill uses are counted per vehicle: the sub-task's end does not switch off the skill
    that the task around it (orchestrated by its time limit) still uses."""
    body = ('<task name="Outer" time_limit="500"><skill name="RECOGNIZE_ITEMS"/>'
            + take_off() + '<task name="Inner"><skill name="RECOGNIZE_ITEMS"/>'
            + hover("Look", 2) + '</task>' + hover("After", 3) + '</task>\n' + land())
    vehicle = FakeVehicle()
    on_while: list[tuple[float, bool]] = []
    flight = FleetFlight(body, [vehicle])
    flight.run(each=lambda f: on_while.append((f.time, "RECOGNIZE_ITEMS" in vehicle.skills)))
    assert flight.fleet.status is Status.COMPLETED
    outer = (flight.began("Outer"), flight.ended("Outer"))
    switches = [(t, r.enabled) for t, r in flight.requests(SetSkill, 1)]
    assert switches == [(outer[0], True), (outer[1], False)]
    assert all(on for t, on in on_while if outer[0] < t <= outer[1])


def test_work_that_would_start_on_a_lost_vehicle_fails_at_once() -> None:
    body = (take_off() + '<task name="Guarded">' + hover("Long", 60)
            + '<on_error>' + land("Down") + '</on_error></task>\n')
    flight = FleetFlight(body, 1).run(seconds=5)
    flight.take(flight.fleet.lost(flight.time, 1, "link lost"))
    assert flight.fleet.status is Status.FAILED
    assert flight.fleet.reason == "link: vehicle 1: link lost"
    assert flight.state_of("Guarded/Down") is TaskState.FAILED
    assert flight.requests(Land) == []  # nothing more is sent to it but the safe state
    assert [type(r) for t, r in flight.sent if t == flight.time] == [Hold, ReturnToLaunch]


def _team(body: str) -> str:
    """``body`` flown by every vehicle of a role of four."""
    return f'<task name="Team" role="all">{body}</task>\n'


LOW_BATTERY = ('<event name="Low" role="all">'
               + condition("BATTERY_CHARGE_PERCENTAGE", "less than", "93")
               + '<action name="LAND"/><termination mode="NEXT_TASK"/></event>')
SEEN_EVENT = ('<event name="Seen" role="all">' + condition("seen", "equal", "yes")
              + '<action name="WAIT"><argument name="duration" value="2"/></action>'
              + '<termination mode="CONTINUE"/></event>')


class LaggingVehicle(FakeVehicle):
    """Its picture arrives 0.5 s late: a state is ``current`` only 0.5 s after the latest
    request, though nothing it shows changes then (tml.vehicle.VehicleState.current)."""

    asked_at: float | None = None

    def submit(self, request: Request) -> None:
        self.asked_at = self.time
        super().submit(request)

    def state(self) -> VehicleState:
        return replace(super().state(), heard=self.time - 0.5, asked=self.asked_at)


HOPS_WHEN_SEEN = ('<event name="Seen" role="all">' + condition("seen", "equal", "yes")
                  + '<action name="GO_TO_POINT"><argument name="coordinates" '
                    'value="(20, 0, 5)"/></action>'
                  + '<action name="GO_TO_POINT"><argument name="coordinates" '
                    'value="(0, 0, 5)"/></action><termination mode="CONTINUE"/></event>')


@pytest.mark.parametrize("scenario", ["waits", "low battery", "time limit", "lost",
                                      "requests between waits", "seen during a wait",
                                      "a picture older than the request",
                                      "an event's hops, each picture older than its request"])
def test_a_team_member_that_waits_is_not_ticked_and_nothing_differs(
        scenario: str, monkeypatch: pytest.MonkeyPatch) -> None:
    # A team's branches that wait (a WAIT, a request's answer) are not ticked until their
    # time, a change of what they read, or something done to their work: the flight must
    # be the same as when every branch is ticked at every step, with fewer ticks.
    from tml.engine import composites
    from tml.engine.leaves import ActionLeaf

    body, events, each = {
        "waits": (_team(take_off() + hover("Hover", 20) + land()), "", None),
        "low battery": (_team(take_off() + hover("Hover", 300) + land()), LOW_BATTERY, None),
        "time limit": (_team(take_off() + '<task name="Bounded" time_limit="7">'
                             + hover("Long", 60) + "</task>" + land()), "", None),
        "lost": (_team(take_off() + hover("Hover", 20) + land()), "",
                 lambda f: f.take(f.fleet.lost(f.time, 3, "link lost"))
                 if f.time == 12.0 else None),
        "requests between waits": (_team(take_off() + hover("H1", 3) + goto("Go", "(20, 0, 5)")
                                         + hover("H2", 4) + land()), "", None),
        "seen during a wait": (_team(take_off() + hover("Hover", 20) + land()), SEEN_EVENT,
                               lambda f: f.vehicles[2].detections.__setitem__(
                                   "seen", 9.0 <= f.time < 9.5)),
        # Each GO_TO arrives within a step; its arrival counts only once current.
        "a picture older than the request": (_team(take_off() + goto("Go", "(20, 0, 5)")
                                                   + goto("Back", "(0, 0, 5)") + land()),
                                             "", None),
        # The same in an event's handler, driven only when its vehicle shows more: seen
        # for one step, then nothing changes but whether the picture is current.
        "an event's hops, each picture older than its request": (
            _team(take_off() + hover("Hover", 20) + land()), HOPS_WHEN_SEEN,
            lambda f: f.vehicles[2].detections.__setitem__("seen", abs(f.time - 9.0) < 1e-6)),
    }[scenario]
    ticks: list[int] = []
    step = ActionLeaf.step

    def counted(self: ActionLeaf) -> object:
        ticks.append(1)
        return step(self)
    monkeypatch.setattr(ActionLeaf, "step", counted)

    def fly(asleep: bool) -> tuple[list[Record], list[tuple[float, Request]], int]:
        ticks.clear()
        with monkeypatch.context() as patch:
            if not asleep:
                patch.setattr(composites.Asleep, "sleeps", lambda *_: False)
            make = LaggingVehicle if "older" in scenario else FakeVehicle
            vehicles = [make(vehicle_id=i, drain_per_second=0.0 if "older" in scenario
                             else 0.2 * i, speed=500.0 if "older" in scenario else 5.0)
                        for i in range(1, 5)]
            flight = FleetFlight(body, vehicles, events=events,
                                 extra=roles('<role name="all" count="4"/>')
                                 + (SEEN if "seen" in scenario or "event" in scenario
                                    else ""))
            flight.run(each=each)
        assert flight.fleet.status is not Status.RUNNING
        return flight.records, flight.sent, len(ticks)

    records, sent, every = fly(asleep=False)
    records_asleep, sent_asleep, fewer = fly(asleep=True)
    assert records_asleep == records
    assert sent_asleep == sent
    assert not [r for r in records if r.data.get("reason") == "timeout"]
    if "event" in scenario:  # the vehicle seen hopped there and back, and went on
        assert [r.vehicle_id for r in records if r.kind == "decision"
                and r.data.get("termination") == "CONTINUE"] == [2]
    # Most steps find every branch waiting; a flight of quick hops has fewer such steps.
    assert fewer < every * (1.0 if "older" in scenario else 0.6)


def test_a_view_between_steps_shows_the_time_and_the_wait_at_that_moment() -> None:
    # A WAIT is not stepped until it ends (tml.engine.wake): the display's view, asked
    # between steps, shows the mission time and the WAIT's progress at the moment asked.
    flight = FleetFlight(take_off() + hover("Hover", 20) + land(), 1)
    while not flight.task("Hover", "running"):
        flight.run(seconds=STEP)
    flight.run(seconds=1.0)  # its Hold answered: the WAIT runs
    last = flight.time
    now, later = flight.fleet.views(last)[1], flight.fleet.views(last + 5.0)[1]
    assert later.current_action == "WAIT"
    assert now.progress is not None and later.progress is not None
    assert later.progress - now.progress == pytest.approx(5.0 / 20)
    assert later.mission_time == pytest.approx(last + 5.0)
    assert flight.fleet.views()[1].mission_time == pytest.approx(last)  # the last step's
