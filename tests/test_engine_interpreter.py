"""The interpreter (tml.engine.interpreter), driven by a FakeVehicle and an injected clock."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import pytest
from fake_vehicle import FakeVehicle

from tml.engine import Interpreter, Options, Status, TaskState, View
from tml.engine.context import Duty
from tml.engine.scripts import LANDED_READS
from tml.errors import EngineError
from tml.language.validation import validate_file
from tml.vehicle import (
    Disarm,
    Flip,
    FlyMission,
    GoTo,
    Gripper,
    Hold,
    IdSource,
    Land,
    MissionProgress,
    RequestResult,
    ReturnToLaunch,
    SetSkill,
    TakeOff,
)

TAKE_OFF = '<task name="Take off"><action name="TAKE_OFF"><argument name="altitude" value="5"/>' \
           '</action></task>\n'
LAND = '<task name="Land"><action name="LAND"/></task>\n'


def goto(name: str, point: str) -> str:
    return (f'<task name="{name}"><action name="GO_TO_POINT">'
            f'<argument name="coordinates" value="{point}"/></action></task>\n')


def mission(body: str, events: str = "", extra: str = ""):
    xml = f'<mission name="m">\n{extra}{body}'
    if events:
        xml += f"<event_handling>{events}</event_handling>\n"
    result = validate_file("m.xml", (xml + "</mission>\n").encode())
    assert result.errors == [], result.errors
    return result.mission


class Flight:
    """Flies a mission on a FakeVehicle, 0.1 s a step, recording everything."""

    def __init__(self, body: str, events: str = "", extra: str = "",
                 vehicle: FakeVehicle | None = None, options: Options | None = None) -> None:
        self.vehicle = vehicle or FakeVehicle()
        self.vid = self.vehicle.vehicle_id
        self.interp = Interpreter(mission(body, events, extra), [self.vid], options)
        self.records = []
        self.requests = []
        self.time = 0.0
        self._take(self.interp.start(0.0, {self.vid: self.vehicle.state()}))

    def _take(self, out) -> None:
        self.records += out.records
        self.requests += out.requests
        for request in out.requests:
            self.vehicle.submit(request)

    def run(self, seconds: float = 600.0,
            each: Callable[[Flight], None] | None = None) -> Flight:
        end = self.time + seconds
        while self.interp.status is Status.RUNNING and self.time < end:
            self.vehicle.advance(0.1)
            self.time = round(self.time + 0.1, 6)
            if each:
                each(self)
            self._take(self.interp.step(self.time, {self.vid: self.vehicle.state()},
                                        {self.vid: self.vehicle.poll()}))
        return self

    def view(self) -> View:
        return self.interp.views()[self.vid]

    def started(self) -> list[str]:
        return [r.data["task"] for r in self.records
                if r.kind == "action" and r.data["message"].endswith("started") and r.data["task"]]

    def fired(self) -> list[str]:
        return [r.data["event"] for r in self.records if r.kind == "event"]

    def sent(self, kind: type) -> list:
        return [r for r in self.requests if isinstance(r, kind)]


def test_depth_first_order_and_completion() -> None:
    body = TAKE_OFF + ('<task name="A"><task name="A1"><action name="WAIT"><argument '
                       'name="duration" value="1"/></action></task>'
                       '<task name="A2"><task name="A2a"><action name="STABILIZE"/></task></task>'
                       '</task>\n') + goto("B", "(5, 0, 5)") + LAND
    flight = Flight(body).run()
    assert flight.interp.status is Status.COMPLETED
    assert flight.started() == ["Take off", "A/A1", "A/A2/A2a", "B", "Land"]
    assert flight.vehicle.position == pytest.approx((5, 0, 0), abs=0.55)
    assert not flight.vehicle.armed
    assert set(flight.view().task_states.values()) == {TaskState.DONE}


def test_repeat_of_terminal_and_non_terminal_tasks() -> None:
    body = TAKE_OFF + ('<task name="Twice"><repeat times="2"/>'
                       '<task name="Hop"><repeat times="3"/><action name="MOVE">'
                       '<argument name="coordinates" value="(1, 0, 0)"/></action></task>'
                       '<task name="Pause"><action name="WAIT"><argument name="duration" '
                       'value="0.5"/></action></task></task>\n') + LAND
    flight = Flight(body).run()
    assert flight.started() == ["Take off"] + (["Twice/Hop"] * 3 + ["Twice/Pause"]) * 2 + ["Land"]
    assert flight.vehicle.position[0] == pytest.approx(6.0, abs=0.55)


def test_false_condition_skips_the_task_and_logs_the_value_read() -> None:
    body = TAKE_OFF + ('<task name="High only"><condition parameter="ALTITUDE" '
                       'comparison="greater than" value="20"/><action name="MOVE">'
                       '<argument name="coordinates" value="(9, 0, 0)"/></action></task>\n'
                       '<task name="Low only"><condition parameter="ALTITUDE" '
                       'comparison="less than" value="20"/><action name="MOVE">'
                       '<argument name="coordinates" value="(0, 2, 0)"/></action></task>\n') + LAND
    flight = Flight(body).run()
    assert flight.started() == ["Take off", "Low only", "Land"]
    [skip] = [r for r in flight.records if r.kind == "decision" and "skipped" in r.data["message"]]
    assert skip.data["task"] == "High only" and skip.data["read"] == pytest.approx(5.0, abs=0.6)
    assert skip.data["expected"] == "20" and skip.data["line"] == 3
    assert flight.view().task_states["High only"] is TaskState.SKIPPED


def test_take_off_when_flying_does_nothing() -> None:
    flight = Flight(TAKE_OFF + TAKE_OFF.replace("Take off", "Again") + LAND).run()
    assert len(flight.sent(TakeOff)) == 1
    assert any("already flying" in r.data["message"] for r in flight.records)
    assert flight.interp.status is Status.COMPLETED


def hover(name: str = "Hover", seconds: int = 30) -> str:
    return (f'<task name="{name}"><action name="WAIT"><argument name="duration" '
            f'value="{seconds}"/></action></task>\n')


SEEN = '<parameter name="seen" type="boolean"/>\n'


def event(termination: str, actions: str = "", trigger: str = "edge",
          conditions: str = '<condition parameter="seen" comparison="equal" value="yes"/>') -> str:
    return (f'<event name="E" trigger="{trigger}">{conditions}{actions}'
            f'<termination mode="{termination}"/></event>')


def see_at(t: float, until: float = 1e9) -> Callable[[Flight], None]:
    def script(flight: Flight) -> None:
        flight.vehicle.detections["seen"] = t <= flight.time < until
    return script


def test_edge_triggered_event_fires_once_while_true() -> None:
    flight = Flight(TAKE_OFF + hover() + LAND, event("CONTINUE", '<action name="MEMORIZE_POINT">'
                    '<argument name="coordinates" label="p"/></action>'), SEEN)
    flight.run(each=see_at(8.0))
    assert flight.fired() == ["E"]
    assert flight.interp.status is Status.COMPLETED


def test_edge_triggered_event_fires_again_after_going_false() -> None:
    def toggling(flight: Flight) -> None:
        flight.vehicle.detections["seen"] = 8 <= flight.time < 9 or 12 <= flight.time < 13
    flight = Flight(TAKE_OFF + hover() + LAND, event("CONTINUE", '<action name="MEMORIZE_POINT">'
                    '<argument name="coordinates" label="p"/></action>'), SEEN)
    flight.run(each=toggling)
    assert flight.fired() == ["E", "E"]


WAIT_3 = '<action name="WAIT"><argument name="duration" value="3"/></action>'


def test_an_edge_that_falls_and_rises_during_the_handling_fires_again_after_it() -> None:
    # True at 8-9 s and again from 10 s; the handling of the first firing lasts 3 s: the
    # fall and the rise came while it ran, and the event fires again once it is over.
    def toggling(flight: Flight) -> None:
        flight.vehicle.detections["seen"] = 8 <= flight.time < 9 or flight.time >= 10
    flight = Flight(TAKE_OFF + hover() + LAND, event("CONTINUE", WAIT_3), SEEN)
    flight.run(each=toggling)
    fired = [r.time for r in flight.records if r.kind == "event"]
    assert len(fired) == 2 and 8 <= fired[0] < 9 and fired[1] >= 11, fired


def test_an_edge_that_holds_through_the_handling_does_not_fire_again() -> None:
    flight = Flight(TAKE_OFF + hover() + LAND, event("CONTINUE", WAIT_3), SEEN)
    flight.run(each=see_at(8.0))
    assert flight.fired() == ["E"]


def test_the_handlers_own_action_does_not_arm_its_event_again() -> None:
    # CURRENT_ACTION is the handler's WAIT while it runs: not a fall of "WAIT is running
    # and seen" (a photo taken by "window seen during a survey" must not re-fire it).
    conditions = ('<condition parameter="CURRENT_ACTION" comparison="equal" value="WAIT"/>'
                  '<condition parameter="seen" comparison="equal" value="yes"/>')
    flight = Flight(TAKE_OFF + hover() + LAND, event("CONTINUE", WAIT_3,
                                                     conditions=conditions), SEEN)
    flight.run(each=see_at(8.0))
    assert flight.fired() == ["E"]


def test_one_handler_fires_at_a_time_in_document_order() -> None:
    # Both become true at 8 s: the first written fires; the second, armed all along, fires
    # only once the first's handling (a 3 s WAIT) is over, not while it runs.
    first = event("CONTINUE", WAIT_3).replace('name="E"', 'name="First"')
    second = event("CONTINUE", WAIT_3).replace('name="E"', 'name="Second"')
    flight = Flight(TAKE_OFF + hover() + LAND, first + second, SEEN)
    flight.run(each=see_at(8.0))
    fired = [(r.data["event"], r.time) for r in flight.records if r.kind == "event"]
    assert [name for name, _ in fired] == ["First", "Second"], fired
    assert 8 <= fired[0][1] < 8.5 and fired[1][1] >= fired[0][1] + 3, fired


def test_level_triggered_event_fires_on_every_step_while_true() -> None:
    flight = Flight(TAKE_OFF + hover() + LAND, event("CONTINUE", '<action name="MEMORIZE_POINT">'
                    '<argument name="coordinates" label="p"/></action>', trigger="level"), SEEN)
    flight.run(each=see_at(8.0, 9.0))
    assert 9 <= len(flight.fired()) <= 11  # 1 s of 0.1 s steps


def test_memorizing_event_does_not_disturb_the_running_action() -> None:
    flight = Flight(TAKE_OFF + goto("Far", "(40, 0, 5)") + LAND,
                    event("CONTINUE", '<action name="MEMORIZE_POINT"><argument '
                          'name="coordinates" label="spot"/></action>'), SEEN)
    flight.run(each=see_at(6.0))
    assert flight.sent(Hold) == []
    spot = flight.view().labels["spot"]
    assert 0 < spot[0] < 40 and spot[2] == pytest.approx(5.0)
    assert flight.vehicle.position == pytest.approx((40, 0, 0), abs=0.55)


def test_continue_after_a_moving_event_action_resumes_the_stopped_action() -> None:
    flight = Flight(TAKE_OFF + goto("Far", "(40, 0, 5)") + LAND,
                    event("CONTINUE", '<action name="MOVE"><argument name="coordinates" '
                          'value="(0, 5, 0)"/></action>'), SEEN)
    flight.run(each=see_at(6.0))
    assert len(flight.sent(Hold)) == 1
    gotos = flight.sent(GoTo)
    assert gotos[0].target == gotos[-1].target == (40, 0, 5)  # sent again after the event
    assert len(gotos) == 3
    assert flight.interp.status is Status.COMPLETED
    assert flight.vehicle.position == pytest.approx((40, 0, 0), abs=0.55)


@dataclass
class LaggingVehicle(FakeVehicle):
    """A FakeVehicle that answers each request ``lag`` seconds late, as a real link does."""

    lag: float = 0.3
    _late: list[tuple[float, RequestResult]] = field(default_factory=list)

    def poll(self) -> list[RequestResult]:
        self._late += [(self.time + self.lag, r) for r in super().poll()]
        due = [r for t, r in self._late if t <= self.time + 1e-9]
        self._late = [(t, r) for t, r in self._late if t > self.time + 1e-9]
        return due


def test_continue_resumes_an_action_stopped_before_its_request_was_answered() -> None:
    """The event stops the action while its GoTo is on its way; the answer, coming while
    the handler runs, is not the resumed action's: the GoTo is sent again."""
    far = (40, 0, 5)
    flight = Flight(TAKE_OFF + goto("Far", str(far)) + LAND,
                    event("CONTINUE", '<action name="CAPTURE_PHOTO"/>'), SEEN,
                    vehicle=LaggingVehicle())

    def sees_once_the_goto_is_sent(f: Flight) -> None:
        f.vehicle.detections["seen"] = any(g.target == far for g in f.sent(GoTo))

    flight.run(seconds=120, each=sees_once_the_goto_is_sent)
    assert flight.fired() == ["E"]
    assert [g.target for g in flight.sent(GoTo)] == [far, far]
    assert flight.interp.status is Status.COMPLETED
    assert flight.vehicle.position == pytest.approx((40, 0, 0), abs=0.55)


def test_next_task_abandons_the_current_task() -> None:
    flight = Flight(TAKE_OFF + hover() + goto("After", "(3, 0, 5)") + LAND,
                    event("NEXT_TASK"), SEEN)
    flight.run(each=see_at(8.0))
    assert flight.started() == ["Take off", "Hover", "After", "Land"]
    assert flight.time < 25  # the 30 s hover was cut short
    assert flight.interp.status is Status.COMPLETED


def test_repeat_task_starts_the_current_task_again() -> None:
    flight = Flight(TAKE_OFF + hover(seconds=5) + LAND, event("REPEAT_TASK"), SEEN)
    flight.run(each=see_at(5.0))
    assert flight.started() == ["Take off", "Hover", "Hover", "Land"]


def test_abort_task_abandons_the_task_the_event_is_scoped_to() -> None:
    body = TAKE_OFF + ('<task name="Search">' + hover("Look", 20) + hover("Look more", 20)
                       + '</task>\n') + goto("After", "(2, 0, 5)") + LAND
    flight = Flight(body, event("ABORT_TASK", conditions='<condition current_task="Search"/>'
                                '<condition parameter="seen" comparison="equal" value="yes"/>'),
                    SEEN)
    flight.run(each=see_at(8.0))
    assert flight.started() == ["Take off", "Search/Look", "After", "Land"]
    states = flight.view().task_states
    assert states["Search"] is TaskState.ABORTED and states["Search/Look more"] is TaskState.PENDING


def test_current_task_condition_holds_for_ancestors_only_while_they_run() -> None:
    body = TAKE_OFF + '<task name="Search">' + hover("Look", 5) + '</task>\n' + hover("Rest", 20)
    flight = Flight(body + LAND, event("CONTINUE", '<action name="MEMORIZE_POINT"><argument '
                    'name="coordinates" label="x"/></action>',
                    conditions='<condition current_task="Search"/>'
                    '<condition parameter="seen" comparison="equal" value="yes"/>'), SEEN)
    flight.run(each=see_at(12.0))  # "Look" is over by then
    assert flight.fired() == []


def test_jump_to_task_continues_from_the_named_task() -> None:
    body = (TAKE_OFF + hover("First", 30) + goto("Skipped", "(9, 9, 5)")
            + '<task name="Target group">' + goto("Target", "(0, 4, 5)") + '</task>\n' + LAND)
    events = ('<event name="E"><condition parameter="seen" comparison="equal" value="yes"/>'
              '<termination mode="JUMP_TO_TASK" task="Target"/></event>')
    flight = Flight(body, events, SEEN).run(each=see_at(8.0))
    assert flight.started() == ["Take off", "First", "Target group/Target", "Land"]
    assert flight.vehicle.position == pytest.approx((0, 4, 0), abs=0.55)


def test_jump_backwards_repeats_earlier_tasks() -> None:
    body = TAKE_OFF + goto("Out", "(5, 0, 5)") + hover("Wait", 20) + LAND
    events = ('<event name="E"><condition current_task="Wait"/><condition parameter="seen" '
              'comparison="equal" value="yes"/><termination mode="JUMP_TO_TASK" task="Out"/>'
              '</event>')
    flight = Flight(body, events, SEEN).run(each=see_at(9.0, 9.05))
    assert flight.started() == ["Take off", "Out", "Wait", "Out", "Wait", "Land"]


def test_end_mission_completes_and_brings_the_vehicle_back() -> None:
    flight = Flight(TAKE_OFF + hover() + LAND, event("END_MISSION"), SEEN).run(each=see_at(8.0))
    assert flight.interp.status is Status.COMPLETED
    assert "ended the mission" in flight.interp.reason
    assert len(flight.sent(ReturnToLaunch)) == 1  # never left hovering unattended


def test_abort_mission_after_landing_needs_no_further_command() -> None:
    flight = Flight(TAKE_OFF + hover() + LAND, event("ABORT_MISSION", '<action name="LAND"/>'),
                    SEEN).run(each=see_at(8.0))
    assert flight.interp.status is Status.ABORTED
    assert flight.sent(ReturnToLaunch) == [] and flight.sent(Disarm) == []
    assert not flight.vehicle.armed and flight.vehicle.position[2] == 0


def test_abort_mission_in_the_air_commands_the_safe_state() -> None:
    flight = Flight(TAKE_OFF + hover() + LAND, event("ABORT_MISSION"), SEEN,
                    options=Options(safe_state="land")).run(each=see_at(8.0))
    assert flight.interp.status is Status.ABORTED
    assert len(flight.sent(Land)) == 1 and flight.sent(ReturnToLaunch) == []


def _ends(flight: Flight) -> dict[str, tuple[float, object]]:
    """Each task's last end in the log: its stamp and the mission time it was decided."""
    return {r.data["task"]: (r.time, r.data.get("decided")) for r in flight.records
            if r.kind == "task" and r.data["state"] != "running"}


def test_a_task_an_event_cuts_is_stamped_when_the_handler_took_over() -> None:
    # The handler lands (some seconds) and aborts the mission: the hover and the task around
    # it stopped flying when the event fired, not when the landing ended.
    body = TAKE_OFF + '<task name="Patrol">' + hover("Hover", 60) + '</task>\n' + LAND
    flight = Flight(body, event("ABORT_MISSION", '<action name="LAND"/>'), SEEN)
    flight.run(each=see_at(8.0))
    (fired,) = [r for r in flight.records if r.kind == "event"]
    ends = _ends(flight)
    assert ends["Patrol/Hover"][0] == ends["Patrol"][0] == fired.time
    decided = ends["Patrol"][1]
    assert isinstance(decided, float) and decided > fired.time + 1.0  # the landing took time
    (stopped,) = [r for r in flight.records if r.kind == "action"
                  and r.data["message"].startswith("WAIT stopped")]
    assert stopped.time == fired.time
    changes = {(c.task, c.state): c for c in flight.view().changes}
    assert changes[("Patrol/Hover", TaskState.ABORTED)].time == pytest.approx(fired.time)
    assert changes[("Patrol/Hover", TaskState.ABORTED)].number \
        < changes[("Patrol", TaskState.ABORTED)].number  # a sub-task's end before its task's
    assert flight.view().events == ((pytest.approx(fired.time), "E"),)


def test_next_task_stamps_the_abandoned_task_when_the_event_fired() -> None:
    flight = Flight(TAKE_OFF + hover() + goto("After", "(3, 0, 5)") + LAND,
                    event("NEXT_TASK", '<action name="WAIT"><argument name="duration" '
                          'value="4"/></action>'), SEEN)
    flight.run(each=see_at(8.0))
    (fired,) = [r for r in flight.records if r.kind == "event"]
    stamp, decided = _ends(flight)["Hover"]
    assert stamp == fired.time and decided == pytest.approx(fired.time + 4.0, abs=0.25)
    assert _ends(flight)["After"][1] is None  # ended by itself: stamped when it ended


def test_a_task_stopped_without_an_event_is_stamped_when_it_stops() -> None:
    flight = Flight(TAKE_OFF + '<task name="Bounded" time_limit="3">' + hover("Inner", 30)
                    + '</task>\n' + LAND).run()
    ends = _ends(flight)
    assert ends["Bounded/Inner"] == (ends["Bounded"][0], None)


def test_memory_labels_feed_go_to_point_and_known_conditions() -> None:
    body = (TAKE_OFF + goto("Out", "(6, 2, 5)")
            + '<task name="Remember"><action name="MEMORIZE_POINT"><argument name="coordinates" '
              'label="spot"/></action></task>\n' + goto("Away", "(0, 0, 5)")
            + '<task name="Back"><condition label="spot" comparison="known" value="yes"/>'
              '<action name="GO_TO_POINT"><argument name="coordinates" label="spot"/></action>'
              '</task>\n'
            + '<task name="Never"><condition label="other" comparison="known" value="yes"/>'
              '<action name="WAIT"><argument name="duration" value="1"/></action></task>\n'
            + LAND)
    never = ('<event name="Never"><condition parameter="ALTITUDE" comparison="greater than" '
             'value="1000"/><action name="MEMORIZE_POINT"><argument name="coordinates" '
             'label="other"/></action><termination mode="CONTINUE"/></event>')
    flight = Flight(body, never).run()
    assert flight.view().labels["spot"] == pytest.approx((6, 2, 5), abs=0.55)
    assert "Never" not in flight.started() and "Back" in flight.started()
    assert flight.vehicle.position == pytest.approx((6, 2, 0), abs=0.55)


def test_rejected_command_is_an_action_failure_an_event_can_handle() -> None:
    vehicle = FakeVehicle(reject={"Arm": "rejected"})
    events = ('<event name="Arming refused"><condition parameter="ACTION_FAILURE" '
              'comparison="equal" value="rejected"/><termination mode="END_MISSION"/></event>')
    flight = Flight(TAKE_OFF + LAND, events, vehicle=vehicle).run()
    assert flight.fired() == ["Arming refused"]
    assert flight.interp.status is Status.COMPLETED


def test_unhandled_failure_ends_the_mission_as_failed() -> None:
    flight = Flight(TAKE_OFF + LAND, vehicle=FakeVehicle(reject={"TakeOff": "rejected"})).run()
    assert flight.interp.status is Status.FAILED
    assert "TAKE_OFF failed (rejected)" in flight.interp.reason
    assert len(flight.sent(Disarm)) == 1  # armed on the ground: disarmed


def test_timeout_is_derived_from_distance_and_speed() -> None:
    vehicle = FakeVehicle()
    flight = Flight(TAKE_OFF + goto("Far", "(50, 0, 5)") + LAND, vehicle=vehicle)
    flight.run(each=lambda f: setattr(f.vehicle, "stuck", f.time > 3))
    assert flight.interp.status is Status.FAILED
    assert "GO_TO_POINT failed (timeout)" in flight.interp.reason
    # 50 m at 5 m/s = 10 s, times 2, plus 15 s of slack = 35 s after the action started.
    started = next(r.time for r in flight.records if r.data.get("message") == "GO_TO_POINT started")
    assert flight.time - started == pytest.approx(35.0, abs=0.3)


def test_timeout_can_be_handled_by_repeating_the_task() -> None:
    events = ('<event name="Retry"><condition parameter="ACTION_FAILURE" comparison="equal" '
              'value="timeout"/><termination mode="REPEAT_TASK"/></event>')
    flight = Flight(TAKE_OFF + goto("Far", "(50, 0, 5)") + LAND, events)
    flight.run(each=lambda f: setattr(f.vehicle, "stuck", 3 < f.time < 40))
    assert flight.fired() == ["Retry"]
    assert flight.interp.status is Status.COMPLETED


def test_a_mission_with_an_action_the_vehicle_cannot_do_is_refused_before_take_off() -> None:
    body = TAKE_OFF + '<task name="Grab"><action name="PICK_UP_ITEM"/></task>\n' + LAND
    flight = Flight(body).run()
    assert flight.interp.status is Status.FAILED
    assert flight.interp.reason == ("PICK_UP_ITEM (line 3) needs a gripper (ArduPilot's "
                                    "GRIP_ENABLE set), and vehicle 1 has none (refused before "
                                    "take-off)")
    assert flight.requests == []  # not even the take-off
    flip = TAKE_OFF + '<task name="Flip"><action name="FLIP"/></task>\n' + LAND
    refused = Flight(flip).run()
    assert refused.requests == [] and "FLIP (line 3) needs a FLIP flight mode" in (
        refused.interp.reason)
    with_gripper = Flight(body, vehicle=FakeVehicle(capabilities=frozenset({"gripper"}))).run()
    assert with_gripper.interp.status is Status.COMPLETED
    assert [g.grab for g in with_gripper.sent(Gripper)] == [True]


def test_a_flip_climbs_to_the_flip_altitude_first_and_comes_back_down_after() -> None:
    body = TAKE_OFF + ('<task name="Flip"><repeat times="2"/><action name="FLIP">'
                       '<argument name="direction" value="left"/></action></task>\n') + LAND
    vehicle = FakeVehicle(capabilities=frozenset({"flip"}))
    altitudes: list[float] = []
    flight = Flight(body, vehicle=vehicle).run(
        each=lambda f: altitudes.append(f.vehicle.position[2]))
    assert flight.interp.status is Status.COMPLETED
    assert [f.direction for f in flight.sent(Flip)] == ["left", "left"] and vehicle.flips == 2
    assert max(altitudes) == pytest.approx(10.0, abs=0.6)  # Limits.flip_altitude
    goes = [g.target[2] for g in flight.sent(GoTo)]
    assert goes == pytest.approx([10.0, 5.0, 10.0, 5.0], abs=0.6)  # up, flip, back down


def test_skills_are_switched_on_with_their_task_and_off_after() -> None:
    body = ('<skill name="AVOID_OBSTACLES"/>' + TAKE_OFF
            + '<task name="Look"><skill name="RECOGNIZE_ITEMS"/>' + hover("Scan", 2)
            + '</task>\n' + LAND)
    flight = Flight(body).run()
    switches = [(r.skill, r.enabled) for r in flight.sent(SetSkill)]
    assert switches == [("AVOID_OBSTACLES", True), ("RECOGNIZE_ITEMS", True),
                        ("RECOGNIZE_ITEMS", False), ("AVOID_OBSTACLES", False)]
    assert flight.vehicle.skills == set()


def test_detections_named_after_objects_feed_conditions() -> None:
    events = ('<event name="Item A found"><condition parameter="Item A found" '
              'comparison="equal" value="yes"/><action name="MEMORIZE_POINT"><argument '
              'name="coordinates" label="item A"/></action><termination mode="CONTINUE"/>'
              '</event>')
    extra = '<parameter name="Item A found" type="boolean"/>\n'
    flight = Flight(TAKE_OFF + hover("Scan", 10) + LAND, events, extra)
    flight.run(each=lambda f: f.vehicle.detections.__setitem__(
        "RECOGNIZED_ITEMS", frozenset({"A"}) if f.time > 7 else frozenset()))
    assert flight.fired() == ["Item A found"] and "item A" in flight.view().labels


def test_runner_abort_commands_the_safe_state() -> None:
    flight = Flight(TAKE_OFF + hover() + LAND).run(seconds=8)
    out = flight.interp.abort(flight.time, {1: flight.vehicle.state()}, "operator pressed Ctrl-C")
    assert [type(r) for r in out.requests] == [ReturnToLaunch]
    assert flight.interp.status is Status.ABORTED
    assert any(r.kind == "safety" for r in out.records)


def test_abort_on_the_ground_disarms_an_armed_vehicle() -> None:
    vehicle = FakeVehicle(armed=True)
    interp = Interpreter(mission(hover()), [1])
    interp.start(0.0, {1: vehicle.state()})
    out = interp.abort(0.1, {1: vehicle.state()}, "link lost")
    assert [type(r) for r in out.requests] == [Disarm]


def test_mission_dispatch_sends_one_plan_and_follows_its_progress() -> None:
    body = TAKE_OFF + ('<task name="Auto" dispatch="mission">' + goto("P1", "(10, 0, 5)")
                       + goto("P2", "(10, 10, 5)") + '</task>\n') + LAND
    seen_tasks: list[str] = []
    flight = Flight(body)
    flight.run(each=lambda f: seen_tasks.append(f.view().current_task))
    [plan] = flight.sent(FlyMission)
    assert [a.name for a in plan.actions] == ["GO_TO_POINT", "GO_TO_POINT"]
    assert plan.start == pytest.approx((0, 0, 5), abs=0.6)
    assert "Auto/P1" in seen_tasks and "Auto/P2" in seen_tasks
    assert flight.interp.status is Status.COMPLETED
    assert flight.vehicle.position == pytest.approx((10, 10, 0), abs=0.55)


def test_mission_dispatch_that_never_starts_times_out() -> None:
    body = TAKE_OFF + '<task name="Auto" dispatch="mission">' + goto("P1", "(10, 0, 5)") + \
        '</task>\n'
    vehicle = FakeVehicle(ignore={"FlyMission"})
    flight = Flight(body, vehicle=vehicle, options=Options(mission_stall=20)).run()
    assert flight.interp.status is Status.FAILED
    assert "did not start" in flight.interp.reason


def test_mission_dispatch_can_be_interrupted_by_an_event() -> None:
    body = TAKE_OFF + '<task name="Auto" dispatch="mission">' + goto("P1", "(60, 0, 5)") + \
        '</task>\n' + LAND
    flight = Flight(body, event("NEXT_TASK"), SEEN).run(each=see_at(8.0))
    assert len(flight.sent(Hold)) == 1
    assert flight.view().task_states["Auto"] is TaskState.ABORTED
    assert flight.interp.status is Status.COMPLETED
    assert flight.vehicle.position[0] < 60


def test_pre_check_makes_an_infeasible_action_abort() -> None:
    def too_far(bound, state, labels, mission_time) -> list[str]:
        target = bound.values.get("coordinates")
        return ["c2 battery range: 50 m > 20 m"] if target and target[0] > 20 else []
    flight = Flight(TAKE_OFF + goto("Far", "(50, 0, 5)") + LAND,
                    options=Options(pre_check=too_far)).run()
    assert flight.interp.status is Status.ABORTED
    assert "infeasible" in flight.interp.reason and "c2 battery range" in flight.interp.reason
    assert [g.target for g in flight.sent(GoTo)] == []


def test_view_reports_current_action_and_progress() -> None:
    flight = Flight(TAKE_OFF + goto("Far", "(40, 0, 5)") + LAND).run(seconds=7)
    view = flight.view()
    assert view.current_task == "Far" and view.current_action == "GO_TO_POINT"
    assert 0.0 < view.progress < 1.0
    assert view.task_states["Take off"] is TaskState.DONE
    assert view.task_states["Far"] is TaskState.RUNNING


def test_a_landing_waits_for_what_its_end_reads_and_shows_its_progress_meanwhile() -> None:
    low = '<condition parameter="BATTERY_CHARGE_PERCENTAGE" comparison="less than" value="5"/>'
    flight = Flight(TAKE_OFF + LAND, event("NEXT_TASK", conditions=low))
    flight.run(seconds=2.5)  # up, and the descent begun
    assert flight.view().current_action == "LAND" and flight.vehicle.armed
    reads = flight.interp.wake().reads
    assert reads is not None
    # Stepped again when it shows landed or disarmed (or the event's battery), not at
    # every position of the descent: those only move the progress the display reads.
    assert reads[flight.vid] == LANDED_READS | {"battery"}
    first = flight.view().progress
    flight.run(seconds=0.5)
    assert flight.view().current_action == "LAND"
    assert first is not None and 0.0 < first < flight.view().progress < 1.0


def test_mission_progress_type_is_shared_with_vehicles() -> None:
    assert MissionProgress(1, 0).finished is False


def test_engine_imports_no_io() -> None:
    code = ("import sys, tml.engine; print(sorted(m for m in ('pymavlink', 'socket', 'lxml', "
            "'threading', 'select') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_requests_with_a_kind_field_are_logged() -> None:
    body = TAKE_OFF + ('<task name="Slow"><action name="SET_SPEED"><argument name="speed" '
                       'value="2"/><argument name="speed_type" value="climb"/></action>'
                       '</task>\n') + LAND
    flight = Flight(body).run()
    assert flight.interp.status is Status.COMPLETED
    [logged] = [r for r in flight.records if r.kind == "request" and r.data["message"] ==
                "SetSpeed"]
    assert logged.data["kind"] == "climb" and logged.data["speed"] == 2.0


def test_mission_dispatch_resolves_labels_before_sending() -> None:
    body = (TAKE_OFF + goto("Out", "(6, 2, 5)")
            + '<task name="Remember"><action name="MEMORIZE_POINT"><argument name="coordinates" '
              'label="spot"/></action></task>\n' + goto("Away", "(0, 0, 5)")
            + '<task name="Auto" dispatch="mission"><task name="Back"><action name="GO_TO_POINT">'
              '<argument name="coordinates" label="spot"/></action></task></task>\n' + LAND)
    flight = Flight(body).run()
    [plan] = flight.sent(FlyMission)
    assert plan.actions[0].labels == {}
    assert plan.actions[0].values["coordinates"] == pytest.approx((6, 2, 5), abs=0.55)
    assert flight.interp.status is Status.COMPLETED


def test_refused_mission_fails_at_once() -> None:
    body = TAKE_OFF + '<task name="Auto" dispatch="mission">' + goto("P1", "(10, 0, 5)") + \
        '</task>\n' + LAND
    flight = Flight(body, vehicle=FakeVehicle(reject={"FlyMission": "rejected"})).run()
    assert flight.interp.status is Status.FAILED
    assert "refused the mission" in flight.interp.reason
    assert flight.time < 15  # not after the 300 s stall limit


def plan_flight(action: str, seconds: float) -> Interpreter:
    """A dispatch="mission" plan whose vehicle stays on its first item for ``seconds``."""
    interp = Interpreter(mission(
        f'<task name="Auto" dispatch="mission"><task name="A">{action}</task></task>\n'), [1])
    flying = FakeVehicle(armed=True, position=(0.0, 0.0, 10.0)).state()
    out = interp.start(0.0, {1: flying})
    [plan] = [r for r in out.requests if isinstance(r, FlyMission)]
    time = 0.0
    while interp.status is Status.RUNNING and time < seconds:
        time += 1.0
        state = replace(flying, time=time, mission=MissionProgress(plan.plan_id, 0))
        interp.step(time, {1: state})
    return interp


def test_endless_loiter_in_a_mission_never_stalls() -> None:
    interp = plan_flight('<action name="LOITER"/>', 2000.0)
    assert interp.status is Status.RUNNING and interp.views()[1].current_task == "Auto/A"


def test_mission_item_time_limit_comes_from_the_action() -> None:
    interp = plan_flight('<action name="WAIT"><argument name="duration" value="5"/></action>',
                         2000.0)
    assert interp.status is Status.FAILED
    assert "WAIT not done within 25 s" in interp.reason  # 2 x 5 s + 15 s


def test_plan_tasks_the_autopilot_went_past_are_logged_flown() -> None:
    # ArduCopter runs the DO items between two waypoints at once: its MISSION_CURRENT may
    # name the next waypoint before a camera item in between was ever current.
    interp = Interpreter(mission(
        '<task name="Auto" dispatch="mission">' + goto("P1", "(10, 0, 10)")
        + '<task name="Photo"><action name="CAPTURE_PHOTO"/></task>'
        + goto("P2", "(20, 0, 10)") + '<task name="Last photo"><action name="CAPTURE_PHOTO"/>'
        '</task></task>\n'), [1])
    flying = FakeVehicle(armed=True, position=(0.0, 0.0, 10.0)).state()
    out = interp.start(0.0, {1: flying})
    [plan] = [r for r in out.requests if isinstance(r, FlyMission)]
    records = list(out.records)
    for time, index, finished in ((1.0, 0, False), (2.0, 2, False), (3.0, 2, True)):
        progress = MissionProgress(plan.plan_id, index, finished)
        records += interp.step(time, {1: replace(flying, time=time, mission=progress)}).records
    lines = [(r.data["task"], r.data["state"]) for r in records if r.kind == "task"]
    for task in ("Auto/P1", "Auto/Photo", "Auto/P2", "Auto/Last photo"):
        assert lines.index((task, "running")) < lines.index((task, "done")), task
    assert interp.status is Status.COMPLETED


# --- one engine: ids, explicit states, the log --------------------------------------------------


def test_requests_and_plans_are_numbered_from_the_source_the_engine_is_given() -> None:
    ids = IdSource(first=500)
    body = TAKE_OFF + '<task name="Auto" dispatch="mission">' + goto("P1", "(5, 0, 5)") + \
        '</task>\n' + LAND
    one = Interpreter(mission(body), [1], ids=ids)
    two = Interpreter(mission(body), [2], ids=ids)
    sent = one.start(0.0, {1: FakeVehicle().state()}).requests
    sent += two.start(0.0, {2: FakeVehicle(vehicle_id=2).state()}).requests
    numbers = [r.request_id for r in sent]
    assert numbers[0] == 500 and len(set(numbers)) == len(numbers)
    flight = Flight(body).run()
    [plan] = flight.sent(FlyMission)
    ids_seen = [r.request_id for r in flight.requests]
    assert len(set(ids_seen)) == len(ids_seen) and plan.plan_id not in (0, plan.request_id)


def test_a_vehicle_s_duty_changes_only_as_its_table_allows() -> None:
    flight = Flight(TAKE_OFF + LAND)
    pilot = flight.interp.run.pilots[1]
    pilot.become(Duty.LOST)
    with pytest.raises(EngineError, match="vehicle 1 cannot go from lost to watching"):
        pilot.become(Duty.WATCHING)


def task_lines(flight: Flight) -> list[tuple[str, str]]:
    return [(r.data["task"], r.data["state"]) for r in flight.records if r.kind == "task"]


def test_next_task_leaves_the_running_task_aborted() -> None:
    flight = Flight(TAKE_OFF + hover() + LAND, event("NEXT_TASK"), SEEN).run(each=see_at(8.0))
    assert task_lines(flight).count(("Hover", "running")) == 1
    assert ("Hover", "aborted") in task_lines(flight)
    assert flight.view().task_states["Hover"] is TaskState.ABORTED


def test_abort_task_without_current_task_abandons_only_the_running_task() -> None:
    body = TAKE_OFF + ('<task name="Search">' + hover("Look", 20) + hover("Look more", 5)
                       + '</task>\n') + LAND
    flight = Flight(body, event("ABORT_TASK"), SEEN).run(each=see_at(8.0, 8.05))
    assert flight.started() == ["Take off", "Search/Look", "Search/Look more", "Land"]
    states = flight.view().task_states
    assert states["Search/Look"] is TaskState.ABORTED and states["Search"] is TaskState.DONE


def test_a_failure_answered_by_a_memorizing_event_lets_the_task_go_on() -> None:
    events = ('<event name="Note it"><condition parameter="ACTION_FAILURE" comparison="equal" '
              'value="rejected"/><action name="MEMORIZE_POINT"><argument name="coordinates" '
              'label="refused here"/></action><termination mode="CONTINUE"/></event>')
    vehicle = FakeVehicle(reject={"GoTo": "rejected"})
    flight = Flight(TAKE_OFF + goto("Out", "(9, 0, 5)") + LAND, events, vehicle=vehicle)
    flight.run(seconds=120)
    assert flight.fired() == ["Note it"] and "refused here" in flight.view().labels
    assert flight.interp.status is Status.COMPLETED
    assert flight.started() == ["Take off", "Out", "Land"]


def test_each_task_state_change_is_logged_once_children_first() -> None:
    body = TAKE_OFF + ('<task name="Group"><task name="Mark"><action name="MEMORIZE_POINT">'
                       '<argument name="coordinates" label="p"/></action></task>'
                       + hover("Look", 30) + '</task>\n') + LAND
    flight = Flight(body, event("END_MISSION"), SEEN).run(each=see_at(8.0))
    assert task_lines(flight) == [
        ("Take off", "running"), ("Take off", "done"), ("Group", "running"),
        ("Group/Mark", "running"), ("Group/Mark", "done"), ("Group/Look", "running"),
        ("Group/Look", "aborted"), ("Group", "aborted")]


def test_a_plan_resumed_after_an_event_says_its_item_runs_once() -> None:
    body = TAKE_OFF + ('<task name="Auto" dispatch="mission">' + goto("P1", "(30, 0, 5)")
                       + goto("P2", "(30, 10, 5)") + '</task>\n') + LAND
    flight = Flight(body, event("CONTINUE", '<action name="CAPTURE_PHOTO"/>'), SEEN)
    flight.run(each=see_at(6.0))
    assert flight.interp.status is Status.COMPLETED
    assert len(flight.sent(FlyMission)) == 2  # the rest of the plan, sent again
    lines = task_lines(flight)
    assert lines.count(("Auto/P1", "running")) == 1 and lines.count(("Auto/P1", "done")) == 1
    assert lines.index(("Auto/P2", "done")) < lines.index(("Auto", "done"))


def test_say_out_loud_is_said_by_tml_and_never_sent_to_the_vehicle() -> None:
    flight = Flight(TAKE_OFF + hover("Hover", 2) + LAND,
                    extra='<skill name="SAY_OUT_LOUD_CURRENT_TASK"/>\n')
    flight.run()
    assert flight.interp.status is Status.COMPLETED
    assert not [r for r in flight.requests if isinstance(r, SetSkill)]
    said = [r.data["task"] for r in flight.records if r.kind == "say"]
    assert said == ["Take off", "Hover", "Land"]


@pytest.mark.parametrize("scenario", ["once", "toggling", "during handling", "level",
                                      "current action"])
def test_a_vehicle_whose_state_did_not_change_is_not_checked_again_and_nothing_differs(
        scenario: str, monkeypatch: pytest.MonkeyPatch) -> None:
    # The event handling skips the check of a vehicle whose state shows the same, in the
    # fields its handlers read, as the state its last check fired nothing in: the flight
    # log must be the same as when every step checks.
    from tml.engine import events as module
    from tml.engine.events import Events

    memorize = '<action name="MEMORIZE_POINT"><argument name="coordinates" label="p"/></action>'
    both = ('<condition parameter="CURRENT_ACTION" comparison="equal" value="WAIT"/>'
            '<condition parameter="seen" comparison="equal" value="yes"/>')
    events, script = {
        "once": (event("CONTINUE", memorize), see_at(8.0)),
        "toggling": (event("CONTINUE", memorize),
                     lambda f: f.vehicle.detections.__setitem__(
                         "seen", 8 <= f.time < 9 or 12 <= f.time < 13)),
        "during handling": (event("CONTINUE", WAIT_3),
                            lambda f: f.vehicle.detections.__setitem__(
                                "seen", 8 <= f.time < 9 or f.time >= 10)),
        "level": (event("CONTINUE", memorize, trigger="level"), see_at(8.0, 9.0)),
        "current action": (event("CONTINUE", WAIT_3, conditions=both), see_at(8.0)),
    }[scenario]
    checks: list[int] = []
    check = Events._check

    def counted(self: Events, pilot: object) -> bool:
        checks.append(1)
        return check(self, pilot)  # type: ignore[arg-type]
    monkeypatch.setattr(Events, "_check", counted)

    def fly(skip: bool) -> tuple[list[object], int]:
        checks.clear()
        vehicle = FakeVehicle(drain_per_second=0.0)  # a hover that changes nothing
        with monkeypatch.context() as patch:
            if not skip:
                patch.setattr(module, "same_state", lambda *_: False)
            flight = Flight(TAKE_OFF + hover() + LAND, events, SEEN, vehicle=vehicle)
            flight.run(each=script)
        return list(flight.records), len(checks)

    every_step, every = fly(skip=False)
    skipped, fewer = fly(skip=True)
    assert skipped == every_step
    if scenario == "current action":
        assert fewer == every  # it reads the interpreter's state: checked at every step
    else:
        assert fewer < every / 2  # most of the 30 s hover says nothing new
