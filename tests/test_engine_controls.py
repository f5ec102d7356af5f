"""The operator's controls of the interpreter -- pause, resume, jump -- driven by a
FakeVehicle and an injected clock."""

from __future__ import annotations

from dataclasses import replace

import pytest
from fake_vehicle import FakeVehicle
from test_engine_interpreter import LAND, TAKE_OFF, Flight, goto, mission

from tml.engine import Interpreter, Status, TaskState
from tml.errors import ControlRefused
from tml.vehicle import FLIGHT_REQUESTS, GoTo, Hold, Land, TakeOff

WAIT_10 = ('<task name="Wait"><action name="WAIT"><argument name="duration" value="10"/>'
           '</action></task>\n')


def pause(flight: Flight) -> None:
    flight._take(flight.interp.pause(flight.time, {flight.vid: flight.vehicle.state()}))


def resume(flight: Flight) -> None:
    flight._take(flight.interp.resume(flight.time, {flight.vid: flight.vehicle.state()}))


def jump(flight: Flight, target: str) -> None:
    flight._take(flight.interp.jump(flight.time, {flight.vid: flight.vehicle.state()}, target))


def records(flight: Flight, kind: str) -> list[dict]:
    return [{"t": r.time, **r.data} for r in flight.records if r.kind == kind]


def until(flight: Flight, done, limit: float = 120.0) -> Flight:
    """Fly until ``done(flight)`` holds (at most ``limit`` s)."""
    end = flight.time + limit
    while not done(flight) and flight.time < end:
        flight.run(0.1)
    assert done(flight), "the flight never got there"
    return flight


def test_pause_holds_the_vehicle_and_nothing_moves_until_resume() -> None:
    flight = Flight(TAKE_OFF + goto("Far", "(40, 0, 5)") + LAND)
    until(flight, lambda f: f.vehicle.position[0] > 10)
    goto_sent = len(flight.sent(GoTo))
    pause(flight)
    assert flight.interp.paused
    assert isinstance(flight.requests[-1], Hold)
    assert records(flight, "control")[-1]["control"] == "pause"
    where, seen, elapsed, shown = flight.vehicle.position, len(flight.records), \
        flight.interp.run.log.mission_time, flight.view().mission_time
    flight.run(60)  # a minute paused: the vehicle holds, the mission does nothing
    assert flight.vehicle.position == pytest.approx(where, abs=0.6)
    assert len(flight.records) == seen and flight.interp.status is Status.RUNNING
    # MISSION_ELAPSED_TIME and every time limit stand still; the time a person reads (the
    # flight log's mission_time) goes on, as on a stopwatch.
    assert flight.interp.run.log.mission_time == elapsed
    assert flight.view().mission_time == pytest.approx(shown + 60.0)
    assert flight.view().task_states["Far"] is TaskState.RUNNING
    resume(flight)
    assert not flight.interp.paused
    # The interrupted action goes on, as after CONTINUE: its last request again.
    assert len(flight.sent(GoTo)) == goto_sent + 1
    assert flight.sent(GoTo)[-1].target == flight.sent(GoTo)[goto_sent - 1].target
    resumed = records(flight, "control")[-1]
    assert (resumed["control"], resumed["paused"]) == ("resume", pytest.approx(60.0))
    flight.run()
    assert flight.interp.status is Status.COMPLETED
    assert flight.view().task_states["Far"] is TaskState.DONE


def test_a_wait_goes_on_with_the_time_it_had_left() -> None:
    flight = Flight(TAKE_OFF + WAIT_10 + LAND)
    until(flight, lambda f: f.view().current_task == "Wait")
    started = records(flight, "action")[-1]["t"]
    flight.run(4.0)
    pause(flight)
    flight.run(100.0)
    resume(flight)
    resumed = flight.time
    until(flight, lambda f: f.view().task_states["Wait"] is TaskState.DONE)
    done = next(r["t"] for r in records(flight, "action") if r["message"] == "WAIT done")
    assert done - resumed == pytest.approx(10.0 - (resumed - 100.0 - started), abs=0.25)


def test_a_time_limit_and_the_elapsed_times_stop_counting_while_paused() -> None:
    body = TAKE_OFF + ('<task name="Bounded" time_limit="10"><action name="WAIT">'
                       '<argument name="duration" value="60"/></action></task>\n') + LAND
    events = ('<event name="Long task"><condition parameter="TASK_ELAPSED_TIME" '
              'comparison="greater than" value="8"/><action name="MEMORIZE_POINT">'
              '<argument name="coordinates" label="late"/></action>'
              '<termination mode="CONTINUE"/></event>')
    flight = Flight(body, events)
    until(flight, lambda f: f.view().current_task == "Bounded")
    began = flight.time
    flight.run(5.0)
    pause(flight)
    flight.run(50.0)
    resume(flight)
    resumed = flight.time
    until(flight, lambda f: f.view().task_states["Bounded"] is TaskState.DONE)
    stopped = next(r["t"] for r in records(flight, "decision")
                   if "time limit" in r["message"])
    assert stopped - resumed == pytest.approx(10.0 - (resumed - 50.0 - began), abs=0.25)
    fired = next(r["t"] for r in records(flight, "event"))
    assert fired - resumed == pytest.approx(8.0 - (resumed - 50.0 - began), abs=0.25)


def test_no_event_fires_while_paused_and_it_fires_on_resume() -> None:
    events = ('<event name="Low battery"><condition parameter="BATTERY_CHARGE_PERCENTAGE" '
              'comparison="less than" value="50"/><action name="LAND"/>'
              '<termination mode="ABORT_MISSION"/></event>')
    flight = Flight(TAKE_OFF + goto("Far", "(40, 0, 5)") + LAND, events)
    until(flight, lambda f: f.vehicle.position[0] > 5)
    pause(flight)
    flight.vehicle.battery = 20.0
    flight.run(10.0)
    assert records(flight, "event") == []
    resume(flight)
    flight.run(0.1)
    assert [r["event"] for r in records(flight, "event")] == ["Low battery"]


def test_jump_goes_on_from_the_task_and_stops_what_runs() -> None:
    flight = Flight(TAKE_OFF + WAIT_10 + goto("Out", "(10, 0, 5)") + LAND)
    until(flight, lambda f: f.view().current_task == "Wait")
    jump(flight, "Out")
    assert records(flight, "control")[-1]["task"] == "Out"
    assert flight.view().task_states["Wait"] is TaskState.ABORTED
    assert flight.view().current_task == "Out"
    flight.run()
    assert flight.interp.status is Status.COMPLETED
    assert flight.vehicle.position[0] == pytest.approx(10.0, abs=0.6)


def test_a_jump_asked_while_paused_is_made_on_resume() -> None:
    flight = Flight(TAKE_OFF + goto("Far", "(40, 0, 5)") + goto("Near", "(0, 5, 5)") + LAND)
    until(flight, lambda f: f.vehicle.position[0] > 5)
    pause(flight)
    jump(flight, "Near")
    assert flight.view().task_states["Far"] is TaskState.RUNNING  # nothing moves yet
    sent = len(flight.sent(GoTo))
    resume(flight)
    assert flight.view().task_states["Far"] is TaskState.ABORTED
    assert [g.target for g in flight.sent(GoTo)[sent:]] == [(0.0, 5.0, 5.0)]  # not Far again
    flight.run()
    assert flight.interp.status is Status.COMPLETED


@pytest.mark.parametrize(("target", "said"), [
    ("Nowhere", "E240: JUMP_TO_TASK target 'Nowhere': no task has this name"),
    ("Twice", "E244: JUMP_TO_TASK target 'Twice' is ambiguous"),
    ("A/Nope", "E240: JUMP_TO_TASK target 'A/Nope': no task has this path")])
def test_a_jump_the_language_refuses_is_refused_with_its_reason(target: str, said: str) -> None:
    body = TAKE_OFF + ('<task name="A"><task name="Twice"><action name="STABILIZE"/></task>'
                       '</task><task name="B"><task name="Twice"><action name="STABILIZE"/>'
                       '</task></task>\n') + LAND
    flight = Flight(body)
    with pytest.raises(ControlRefused, match=said.replace("(", r"\(")):
        jump(flight, target)
    assert flight.interp.status is Status.RUNNING


def test_a_jump_in_a_mission_with_orchestration_is_refused() -> None:
    body = TAKE_OFF + ('<task name="Both" composition="parallel">'
                       '<task name="L"><action name="STABILIZE"/></task>'
                       '<task name="R"><action name="STABILIZE"/></task></task>\n') + LAND
    with pytest.raises(ControlRefused, match="E283: JUMP_TO_TASK is not allowed in a mission "
                                             "with roles or orchestration"):
        jump(Flight(body), "L")


def test_controls_are_refused_when_they_make_no_sense() -> None:
    flight = Flight(TAKE_OFF + LAND)
    with pytest.raises(ControlRefused, match="not paused"):
        resume(flight)
    pause(flight)
    with pytest.raises(ControlRefused, match="paused already"):
        pause(flight)
    resume(flight)
    flight.run()
    for control in (pause, resume):
        with pytest.raises(ControlRefused, match=r"has ended \(completed\)"):
            control(flight)
    fresh = Interpreter(mission(TAKE_OFF), [1])
    with pytest.raises(ControlRefused, match="not started"):
        fresh.pause(0.0, {1: FakeVehicle().state()})


def test_abort_while_paused_sends_the_safe_state() -> None:
    flight = Flight(TAKE_OFF + goto("Far", "(40, 0, 5)") + LAND)
    until(flight, lambda f: f.vehicle.position[0] > 5)
    pause(flight)
    flight._take(flight.interp.abort(flight.time, {1: flight.vehicle.state()}, "operator"))
    assert flight.interp.status is Status.ABORTED
    assert flight.vehicle.mode == "RTL"


@pytest.mark.parametrize("taken", [False, True], ids=["link-lost", "taken"])
def test_a_vehicle_lost_or_taken_while_paused_ends_the_run_as_it_would_running(
        taken: bool) -> None:
    """Paused, nothing would take the failure up until resume (which may never come): the
    run ends as the unhandled failure ends it running -- a lost vehicle told its safe
    state for when it is heard again, a taken one commanded no more."""
    flight = Flight(TAKE_OFF + WAIT_10 + LAND)
    until(flight, lambda f: f.view().task_states.get("Wait") is TaskState.RUNNING)
    pause(flight)
    sent = len(flight.requests)
    flight._take(flight.interp.lost(flight.time, 1, "link lost for more than 2 s", taken))
    assert flight.interp.status is Status.FAILED
    assert flight.interp.reason.startswith("taken: vehicle 1" if taken else "link: vehicle 1")
    asked = [r.name for r in flight.requests[sent:]]
    assert asked == ([] if taken else ["ReturnToLaunch"])
    assert [r["message"] for r in records(flight, "safety")] == (
        [] if taken else ["vehicle in the air: ReturnToLaunch (link: vehicle 1: link lost for "
         "more than 2 s)"])


def test_an_abort_while_the_vehicle_lands_leaves_it_to_land_and_says_so() -> None:
    flight = Flight(TAKE_OFF + LAND)
    until(flight, lambda f: f.vehicle.mode == "LAND" and f.vehicle.position[2] < 4.0)
    sent = len(flight.requests)
    flight._take(flight.interp.abort(flight.time, {1: flight.vehicle.state()}, "operator"))
    assert flight.requests[sent:] == []  # not sent back up to return
    (said,) = records(flight, "safety")
    assert (said["message"], said["request"]) == (
        "vehicle landing (LAND): left to land by itself (operator)", "")


def test_a_vehicle_paused_on_the_ground_is_not_asked_again_on_resume() -> None:
    # Paused while its take-off was on its way: the vehicle was on the ground, so it was
    # not told to hold; the answer came during the pause. Sent again, the take-off would be
    # refused by a vehicle already climbing (ArduCopter: MAV_RESULT_FAILED).
    flight = Flight(TAKE_OFF + LAND)
    until(flight, lambda f: bool(f.sent(TakeOff)))
    pause(flight)
    assert not any(isinstance(r, Hold) for r in flight.requests)
    flight.run(3.0)
    resume(flight)
    flight.run()
    assert flight.interp.status is Status.COMPLETED
    assert len(flight.sent(TakeOff)) == 1


class LateTelemetry(FakeVehicle):
    """A vehicle whose telemetry arrives ``lag`` seconds late: each state is the picture of
    ``lag`` s ago, saying when it was heard and when the latest requests were made."""

    def __init__(self, lag: float) -> None:
        super().__init__()
        self.lag = lag
        self.pictures: list = []
        self.asked: float | None = None
        self.flight_asked: float | None = None

    def submit(self, request) -> None:
        self.asked = self.time
        if isinstance(request, FLIGHT_REQUESTS):
            self.flight_asked = self.time
        super().submit(request)

    def state(self):
        self.pictures.append(super().state())
        seen = [p for p in self.pictures if p.time <= self.time - self.lag] or self.pictures[:1]
        return replace(seen[-1], time=self.time, heard=seen[-1].time, asked=self.asked,
                       flight_asked=self.flight_asked)


def test_a_jump_to_land_during_take_off_is_not_judged_on_the_picture_before_it() -> None:
    # The operator jumps to the landing task right after the take-off request was answered:
    # the telemetry still shows the vehicle on the ground, disarmed, from before it.
    flight = Flight(TAKE_OFF + WAIT_10 + LAND, vehicle=LateTelemetry(lag=1.5))
    until(flight, lambda f: any(r["message"] == "TakeOff done" for r in records(f, "result")))
    assert flight.vehicle.state().landed  # the picture of before the take-off
    jump(flight, "Land")
    until(flight, lambda f: flight.interp.status is not Status.RUNNING)
    landed = [r for r in records(flight, "action") if r["message"].startswith("LAND")]
    assert [r["message"] for r in landed] == ["LAND started", "LAND done"]
    assert flight.sent(Land), "LAND was judged done without a land command"
    assert landed[1]["t"] > landed[0]["t"] + 1.5  # on telemetry heard after the command
    assert flight.vehicle.state().landed and not flight.vehicle.state().armed
