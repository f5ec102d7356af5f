"""The run loop with FakeVehicles and an injected clock: outcomes, journal, safety."""

from __future__ import annotations

import io
import itertools
import json
import threading
from dataclasses import replace

import pytest
from fake_vehicle import FakeVehicle

from tml.engine import Status
from tml.errors import ControlRefused, ExitCode
from tml.language.failures import FailureReason
from tml.language.validation import validate_file
from tml.run.journal import DECISIONS, Journal, read
from tml.run.runner import Runner, RunOptions
from tml.vehicle import (
    SHOWN_FIELDS,
    Arm,
    Disarm,
    Hold,
    Land,
    RequestResult,
    ReturnToLaunch,
    TakeOff,
    VehicleState,
)

TAKE_OFF = ('<task name="Take off"><action name="TAKE_OFF"><argument name="altitude" '
            'value="5"/></action></task>')
GO = ('<task name="Go"><action name="GO_TO_POINT"><argument name="coordinates" '
      'value="(20, 0, 5)"/></action></task>')
LAND = '<task name="Land"><action name="LAND"/></task>'


def mission(body: str, events: str = ""):
    xml = f'<mission name="m">{body}'
    if events:
        xml += f"<event_handling>{events}</event_handling>"
    result = validate_file("m.xml", (xml + "</mission>").encode())
    assert result.errors == [], result.errors
    return result.mission


class Sim:
    """Fake vehicles moved on 0.1 s each time the runner waits."""

    def __init__(self, *vehicles: FakeVehicle) -> None:
        self.vehicles = vehicles
        self.time = 0.0
        self.hooks: list = []

    def clock(self) -> float:
        return self.time

    def wait(self, _timeout: float) -> None:
        self.time = round(self.time + 0.1, 6)
        for vehicle in self.vehicles:
            vehicle.advance(0.1)
        for hook in self.hooks:
            hook(self)


def run(body: str, events: str = "", vehicles: int = 1, options: RunOptions | None = None,
        hooks=(), broken_engine: bool = False, fake: type[FakeVehicle] = FakeVehicle):
    sim = Sim(*(fake(vehicle_id=i + 1) for i in range(vehicles)))
    sim.hooks.extend(hooks)
    log = io.StringIO()
    said: list[str] = []
    runner = Runner(mission(body, events), sim.vehicles, clock=sim.clock,
                    options=options or RunOptions(), journal=Journal(log), wait=sim.wait,
                    on_safety=said.append)
    if broken_engine:
        engine = runner.crews[0].engine
        step = engine.step

        def explode_in_flight(now, states, results):  # type: ignore[no-untyped-def]
            if now > 3.0:
                raise RuntimeError("boom")
            return step(now, states, results)
        engine.step = explode_in_flight  # type: ignore[method-assign]
    outcome = runner.run()
    lines = [json.loads(line) for line in log.getvalue().splitlines()]
    return outcome, sim, lines, said, runner


def test_completed_mission_exits_zero_and_logs_everything() -> None:
    outcome, sim, lines, said, _ = run(TAKE_OFF + GO + LAND)
    assert outcome.exit_code == ExitCode.OK
    assert [v.status for v in outcome.vehicles] == [Status.COMPLETED]
    kinds = {line["kind"] for line in lines}
    assert {"run", "mission", "task", "action", "request", "result", "telemetry"} <= kinds
    assert lines[0]["message"] == "run started" and lines[-1]["exit_code"] == 0
    telemetry = [line for line in lines if line["kind"] == "telemetry"]
    assert len(telemetry) >= 5
    times = [line["t"] for line in telemetry[:-1]]  # the last one: the state left in
    assert not telemetry[-1]["armed"] and telemetry[-1]["landed"]
    assert all(b - a >= 1.0 - 1e-6 for a, b in itertools.pairwise(times))
    assert not sim.vehicles[0].armed and said == []


def test_every_vehicle_flies_the_mission() -> None:
    outcome, _, lines, _, _ = run(TAKE_OFF + GO + LAND, vehicles=2)
    assert [v.vehicle_id for v in outcome.vehicles] == [1, 2]
    assert outcome.exit_code == ExitCode.OK
    assert {line.get("vehicle") for line in lines if line["kind"] == "telemetry"} == {1, 2}


def test_abort_mission_event_exits_three() -> None:
    events = ('<event name="Far"><condition parameter="DISTANCE_TO_HOME" '
              'comparison="greater than" value="10"/><action name="LAND"/>'
              '<termination mode="ABORT_MISSION"/></event>')
    outcome, sim, _, _, _ = run(TAKE_OFF + GO + LAND, events)
    assert outcome.exit_code == ExitCode.ABORTED
    assert outcome.vehicles[0].status is Status.ABORTED
    assert sim.vehicles[0].position[2] == 0.0 and not sim.vehicles[0].armed
    assert 10 < sim.vehicles[0].position[0] < 20


def test_stop_commands_the_safe_state_and_says_so() -> None:
    def interrupt(sim: Sim) -> None:
        if sim.time == 4.0:
            runner_box[0].stop("interrupted (SIGINT)")

    runner_box: list = []
    sim = Sim(FakeVehicle())
    sim.hooks.append(interrupt)
    log = io.StringIO()
    said: list[str] = []
    runner = Runner(mission(TAKE_OFF + GO + LAND), sim.vehicles, clock=sim.clock,
                    options=RunOptions(safe_state="land"), journal=Journal(log),
                    wait=sim.wait, on_safety=said.append)
    runner_box.append(runner)
    outcome = runner.run()
    assert outcome.exit_code == ExitCode.ABORTED
    assert outcome.vehicles[0].reason == "interrupted (SIGINT)"
    assert isinstance(sim.vehicles[0].submitted[-1], Land)
    assert any("aborting: interrupted" in s for s in said)
    assert any("Land" in s for s in said)


def test_link_lost_beyond_the_limit_aborts_with_exit_four() -> None:
    class Deaf(FakeVehicle):
        def state(self) -> VehicleState:
            state = super().state()
            return state if self.time < 3.0 else VehicleState(**{**state.__dict__,
                                                                 "link": "lost"})

    outcome, sim, lines, _, _ = run(TAKE_OFF + GO + LAND, options=RunOptions(
        link_lost_limit=2.0), fake=Deaf)
    assert outcome.exit_code == ExitCode.FAILURE
    assert outcome.vehicles[0].cause == "link"
    assert "link lost" in outcome.vehicles[0].reason
    assert isinstance(sim.vehicles[0].submitted[-1], ReturnToLaunch)
    aborted = next(line for line in lines if line["kind"] == "safety")
    assert 5.0 <= aborted["t"] < 6.0


def test_interpreter_exception_commands_the_safe_state_without_it() -> None:
    outcome, sim, lines, said, _ = run(TAKE_OFF + GO + LAND, broken_engine=True)
    assert outcome.exit_code == ExitCode.FAILURE
    assert isinstance(sim.vehicles[0].submitted[-1], ReturnToLaunch)
    assert any("ReturnToLaunch (interpreter error" in s for s in said)
    assert outcome.vehicles[0].cause == "error"
    errors = [line for line in lines if line["kind"] == "error"]
    assert errors and "boom" in errors[0]["message"] and "Traceback" in errors[0]["traceback"]


def test_unhandled_action_failure_exits_four() -> None:
    sim = Sim(FakeVehicle(reject={"TakeOff": "rejected"}))
    runner = Runner(mission(TAKE_OFF + LAND), sim.vehicles, clock=sim.clock, wait=sim.wait)
    outcome = runner.run()
    assert outcome.vehicles[0].status is Status.FAILED
    assert outcome.exit_code == ExitCode.FAILURE


def test_vehicle_left_flying_in_auto_is_brought_back() -> None:
    body = ('<task name="Fly" dispatch="mission"><task name="Up"><action name="TAKE_OFF">'
            '<argument name="altitude" value="5"/></action></task>'
            '<task name="There">' + GO[len('<task name="Go">'):] + '</task>')
    events = ('<event name="Stop"><condition parameter="ALTITUDE" comparison="greater than" '
              'value="3"/><termination mode="END_MISSION"/></event>')
    outcome, sim, lines, said, _ = run(body, events, options=RunOptions(safe_state="hold"))
    assert outcome.exit_code == ExitCode.OK
    vehicle = sim.vehicles[0]
    safety = [line for line in lines if line["kind"] == "safety"]
    assert safety and safety[0]["request"] == "Hold", "the run must say what it did"
    assert isinstance(vehicle.submitted[-1], Hold) and vehicle.mission is None
    assert any("uploaded mission" in s for s in said)


FLEET = ('<roles><role name="scout" type="quadcopter"><payload name="sidescan"/></role>'
         '<role name="spare"/></roles>'
         '<task name="Both" composition="parallel">'
         '<task name="Scout" role="scout">' + TAKE_OFF + GO + LAND + '</task>'
         '<task name="Spare" role="spare">' + TAKE_OFF.replace("Take off", "Up")
         + LAND.replace("Land", "Down") + '</task></task>')


def test_a_mission_with_roles_picks_vehicles_with_the_payloads_given() -> None:
    sim = Sim(*(FakeVehicle(vehicle_id=i + 1) for i in range(3)))
    log = io.StringIO()
    runner = Runner(mission(FLEET), sim.vehicles, clock=sim.clock, wait=sim.wait,
                    journal=Journal(log), payloads={3: ["sidescan"]})
    outcome = runner.run()
    assert outcome.exit_code == ExitCode.OK
    picks = {line["role"]: line["vehicles"] for line in map(json.loads, log.getvalue().split(
        "\n")[:-1]) if line["kind"] == "pick"}
    assert picks == {"scout": [3], "spare": [1]}  # only 3 carries the sidescan
    assert sim.vehicles[2].submitted and sim.vehicles[0].submitted
    assert not sim.vehicles[1].submitted  # never picked, never commanded
    assert [view.role for view, _ in runner.views()] == ["", "", ""]  # released at the end


def test_a_lost_vehicle_fails_its_branch_and_the_other_is_stopped_safely() -> None:
    class Deaf(FakeVehicle):
        def state(self) -> VehicleState:
            state = super().state()
            return state if self.time < 1.0 else VehicleState(**{**state.__dict__,
                                                                 "link": "lost"})

    sim = Sim(FakeVehicle(vehicle_id=1), Deaf(vehicle_id=2))
    runner = Runner(mission(FLEET), sim.vehicles, clock=sim.clock, wait=sim.wait,
                    options=RunOptions(link_lost_limit=2.0), payloads={1: ["sidescan"]})
    outcome = runner.run()
    assert outcome.exit_code == ExitCode.FAILURE
    assert [v.cause for v in outcome.vehicles] == ["", "link"]
    assert "vehicle 2: link lost" in outcome.vehicles[0].reason
    # The healthy vehicle's branch was stopped and it was sent home, as was the lost one.
    assert isinstance(sim.vehicles[0].submitted[-1], ReturnToLaunch)
    assert any(isinstance(r, Hold) for r in sim.vehicles[0].submitted)
    assert isinstance(sim.vehicles[1].submitted[-1], ReturnToLaunch)


class Booting(FakeVehicle):
    """A vehicle that reports nothing but its heartbeat until ``reports_at`` and cannot arm
    (no position estimate, an autopilot saying why) until ``armable_at``."""

    reports_at = 2.0
    armable_at = 6.0

    def state(self) -> VehicleState:
        state = super().state()
        changes: dict[str, object] = {}
        if self.time < self.reports_at:
            changes.update(gps_fix=None, battery=None, position=None, home=None)
        if self.time < self.armable_at:
            changes.update(ready=False, armable=False, gps_fix=changes.get("gps_fix", 1),
                           prearm="PreArm: Need Position Estimate")
        return VehicleState(**{**state.__dict__, **changes})


GPS_GATED = ('<task name="Only with a fix"><condition parameter="GPS_FIX" '
             'comparison="greater than or equal to" value="3"/>' + TAKE_OFF + LAND + '</task>')


def test_the_first_task_waits_until_the_vehicle_is_ready() -> None:
    sim = Sim(Booting())
    log = io.StringIO()
    runner = Runner(mission(GPS_GATED), sim.vehicles, clock=sim.clock, wait=sim.wait,
                    journal=Journal(log))
    outcome = runner.run()
    lines = [json.loads(line) for line in log.getvalue().splitlines()]
    assert outcome.exit_code == ExitCode.OK
    ready = [(line["t"], line["awaiting"]) for line in lines if line["kind"] == "ready"]
    unarmable = ["GPS fix", "pre-arm checks", "autopilot: PreArm: Need Position Estimate"]
    assert ready[0] == (0.0, ["GPS status", "position", "home position", "battery status",
                              *unarmable])
    assert ready[1][1] == unarmable and 2.0 <= ready[1][0] < 2.2
    assert ready[2][1] == [] and 6.0 <= ready[2][0] < 6.2
    states = {line["task"]: line["state"] for line in lines if line["kind"] == "task"}
    assert states["Only with a fix"] == "done"  # GPS_FIX was never read before it arrived
    first_request = next(line for line in lines if line["kind"] == "request")
    assert first_request["t"] >= ready[2][0]


def test_each_autopilot_message_is_logged_once_with_its_severity() -> None:
    def talk(sim: Sim) -> None:
        if sim.time == 0.5:
            sim.vehicles[0].say(2, "PreArm: Need Position Estimate")
        if sim.time == 3.0:
            sim.vehicles[0].say(6, "Mode change to GUIDED")
            sim.vehicles[0].say(4, "Battery 1 is low")

    _, _, lines, _, _ = run(TAKE_OFF + LAND, hooks=[talk])
    told = [(line["t"], line["vehicle"], line["severity"], line["level"], line["text"])
            for line in lines if line["kind"] == "autopilot"]
    assert [t[1:] for t in told] == [(1, "critical", 2, "PreArm: Need Position Estimate"),
                                     (1, "info", 6, "Mode change to GUIDED"),
                                     (1, "warning", 4, "Battery 1 is low")]
    assert [t[0] for t in told] == [0.5, 3.0, 3.0]


def test_a_vehicle_never_ready_fails_the_run_with_the_autopilots_reason() -> None:
    never = Booting()
    never.armable_at = 1e9
    sim = Sim(never)
    said: list[str] = []
    runner = Runner(mission(TAKE_OFF + LAND), sim.vehicles, clock=sim.clock, wait=sim.wait,
                    options=RunOptions(ready_timeout=5.0), on_safety=said.append)
    outcome = runner.run()
    assert outcome.exit_code == ExitCode.FAILURE
    (vehicle,) = outcome.vehicles
    assert (vehicle.status, vehicle.cause) == (Status.FAILED, "ready")
    assert vehicle.reason == ("not ready after 5 s: waiting for GPS fix, pre-arm checks, "
                              "autopilot: PreArm: Need Position Estimate")
    assert sim.vehicles[0].submitted == [] and said == ["vehicle 1: " + vehicle.reason]
    assert 5.0 < sim.time < 5.3


def test_an_operator_s_command_through_the_run_ends_it_taken_into_that_state() -> None:
    # The run's own safe state is RTL; the operator's LAND wins, on every vehicle, and the
    # run ends taken by the operator (docs/run.md, How a run ends: OPERATOR).
    from tml.run.endings import Ending

    sim = Sim(FakeVehicle(), FakeVehicle(vehicle_id=2))
    log = io.StringIO()
    runner = Runner(mission(TAKE_OFF + GO + LAND), sim.vehicles, clock=sim.clock,
                    journal=Journal(log), wait=sim.wait)
    sim.hooks.append(lambda s: runner.take_over("land") if s.time == 4.0 else None)
    outcome = runner.run()
    assert (outcome.ending, outcome.exit_code) == (Ending.OPERATOR, ExitCode.FAILURE)
    assert [(v.status, v.reason, v.cause) for v in outcome.vehicles] == [
        (Status.ABORTED, "operator command: land", "operator")] * 2
    assert all(isinstance(v.submitted[-1], Land) for v in sim.vehicles)
    end = json.loads(log.getvalue().splitlines()[-1])
    assert (end["status"], end["exit_code"]) == ("taken", 4)


def test_a_stop_while_waiting_aborts_without_commanding_anything() -> None:
    sim = Sim(Booting(), FakeVehicle(vehicle_id=2))
    runner = Runner(mission(TAKE_OFF + LAND), sim.vehicles, clock=sim.clock, wait=sim.wait)
    sim.hooks.append(lambda s: runner.stop("interrupted (SIGINT)") if s.time >= 1.0 else None)
    outcome = runner.run()
    assert outcome.exit_code == ExitCode.ABORTED
    assert [v.reason for v in outcome.vehicles] == ["interrupted (SIGINT)"] * 2
    assert all(v.submitted == [] for v in sim.vehicles)


def test_ready_timeout_zero_starts_at_once() -> None:
    sim = Sim(Booting())
    log = io.StringIO()
    runner = Runner(mission(GPS_GATED), sim.vehicles, clock=sim.clock, wait=sim.wait,
                    journal=Journal(log), options=RunOptions(ready_timeout=0))
    runner.run()
    lines = [json.loads(line) for line in log.getvalue().splitlines()]
    assert not [line for line in lines if line["kind"] == "ready"]
    states = {line["task"]: line["state"] for line in lines if line["kind"] == "task"}
    assert states["Only with a fix"] == "skipped"  # read before the GPS said anything


def test_controls_asked_from_another_thread_are_applied_between_steps() -> None:
    vehicle = FakeVehicle()
    sim = Sim(vehicle)
    frozen, there, later = threading.Event(), threading.Event(), threading.Event()
    marks: dict[str, float] = {}

    def wait(timeout: float) -> None:
        if frozen.is_set():  # time stands still while the test asks for its control
            runner.wake.wait(0.01)
            runner.wake.clear()
            return
        sim.wait(timeout)
        if vehicle.position[0] > 5 and not there.is_set():
            frozen.set()
            there.set()
        if "paused" in marks and sim.time > marks["paused"] + 30:
            later.set()

    log = io.StringIO()
    runner = Runner(mission(TAKE_OFF + GO + LAND), [vehicle], clock=sim.clock,
                    journal=Journal(log), wait=wait)
    with pytest.raises(ControlRefused, match="not started"):
        runner.control("pause")
    outcome: list = []
    thread = threading.Thread(target=lambda: outcome.append(runner.run()))
    thread.start()
    assert there.wait(60)
    with pytest.raises(ControlRefused, match="E240: JUMP_TO_TASK target 'Nowhere'"):
        runner.control("jump", "Nowhere")
    runner.control("pause")
    assert runner.paused and isinstance(vehicle.submitted[-1], Hold)
    where = vehicle.position
    marks["paused"] = sim.time
    frozen.clear()  # 30 s pass, paused
    assert later.wait(60)
    frozen.set()
    assert vehicle.position == pytest.approx(where, abs=0.6)
    runner.control("resume")
    assert not runner.paused
    frozen.clear()
    thread.join(60)
    assert outcome[0].exit_code == ExitCode.OK
    with pytest.raises(ControlRefused, match="has ended"):
        runner.control("resume")
    controls = [json.loads(line) for line in log.getvalue().splitlines()
                if '"kind":"control"' in line]
    assert [c["control"] for c in controls] == ["pause", "resume"]
    assert controls[1]["paused"] > 30


def test_absurd_telemetry_ignored_is_logged_counted_and_said_once() -> None:
    def garble(sim: Sim) -> None:
        vehicle = sim.vehicles[0]
        if 1.0 <= sim.time <= 3.0:  # 21 absurd messages in 2 s
            vehicle.rejected += 1
            vehicle.rejected_last = "SYS_STATUS.battery_remaining = 127 (not -1 to 100)"

    _, _, lines, said, _ = run(TAKE_OFF + GO + LAND, hooks=[garble])
    told = [line for line in lines if line["kind"] == "rejected"]
    assert 2 <= len(told) <= 4  # at the telemetry's pace, not once per message
    assert told[-1]["count"] == 21 and sum(int(line["message"].split()[1]) for line in told) == 21
    assert all(line["last"].startswith("SYS_STATUS.battery_remaining = 127") for line in told)
    assert [s for s in said if "absurd" in s] == [
        "vehicle 1: absurd telemetry ignored (SYS_STATUS.battery_remaining = 127 "
        "(not -1 to 100))"]


def test_a_vehicle_taken_by_the_autopilot_is_commanded_no_more() -> None:
    sent: list[int] = []

    def take(sim: Sim) -> None:
        vehicle = sim.vehicles[0]
        if sim.time == 3.0:  # in the leg: the autopilot lands it (an EKF failsafe)
            vehicle.mode, vehicle.taken = "LAND", "LAND"
            sent.append(len(vehicle.submitted))

    outcome, sim, lines, said, _ = run(TAKE_OFF + GO + LAND, hooks=[take])
    assert outcome.exit_code == ExitCode.FAILURE
    assert outcome.vehicles[0].cause == "taken"
    assert "switched to LAND outside tml" in outcome.vehicles[0].reason
    assert len(sim.vehicles[0].submitted) == sent[0]  # nothing sent after, no safe state
    assert said[0] == "vehicle 1 switched to LAND outside tml: tml commands it no more"
    taken = [line for line in lines if line["kind"] == "taken"]
    assert len(taken) == 1 and taken[0]["mode"] == "LAND"


def test_a_take_over_says_the_autopilots_warning() -> None:
    def breach(sim: Sim) -> None:
        vehicle = sim.vehicles[0]
        if sim.time == 3.0:  # ArduCopter's fence: a warning, then RTL
            vehicle.say(4, "Polygon fence breached")
            vehicle.mode, vehicle.taken = "RTL", "RTL"

    outcome, *_ = run(TAKE_OFF + GO + LAND, hooks=[breach])
    assert outcome.vehicles[0].reason.endswith(
        "switched to RTL outside tml (autopilot: Polygon fence breached)")


def test_a_take_over_says_the_autopilots_first_most_severe_words_of_the_moment() -> None:
    # As ArduCopter SITL says a breach in AUTO: notices, the breach first, then what it
    # does, then "cleared" once back inside -- all before the take-over is believed.
    def breach(sim: Sim) -> None:
        vehicle = sim.vehicles[0]
        if sim.time == 3.0:
            vehicle.say(5, "Polygon fence breached")
            vehicle.say(6, "Manual recovery started")
            vehicle.say(5, "Fence breach cleared")
        if sim.time == 4.0:
            vehicle.mode, vehicle.taken = "RTL", "RTL"

    outcome, *_ = run(TAKE_OFF + GO + LAND, hooks=[breach])
    assert outcome.vehicles[0].reason.endswith(
        "switched to RTL outside tml (autopilot: Polygon fence breached)")


class Outage(FakeVehicle):
    """A vehicle whose link is down from 3 s to 23 s: what is sent meanwhile is lost."""

    def down(self) -> bool:
        return 3.0 <= self.time < 23.0

    def state(self) -> VehicleState:
        state = super().state()
        return replace(state, link="lost") if self.down() else state

    def submit(self, request) -> None:  # type: ignore[no-untyped-def]
        if not self.down():
            super().submit(request)
            return
        self.submitted.append(request)  # sent into the dead link, never carried out
        self._results.append(RequestResult(self.vehicle_id, request.request_id, False,
                                           FailureReason.TIMEOUT, "link lost"))


def test_the_safe_state_is_commanded_until_the_vehicle_shows_it() -> None:
    outcome, sim, lines, _, _ = run(TAKE_OFF + GO + LAND, options=RunOptions(
        link_lost_limit=10.0), fake=Outage)
    vehicle = sim.vehicles[0]
    assert outcome.exit_code == ExitCode.FAILURE
    rtl = [r for r in vehicle.submitted if isinstance(r, ReturnToLaunch)]
    assert len(rtl) >= 2 and rtl[0].request_id < rtl[-1].request_id  # again after the outage
    assert vehicle.mode == "RTL" and sim.time >= 23.0  # shown once the link came back
    confirmed = [line for line in lines if line["kind"] == "safety"
                 and line.get("confirmed")]
    assert len(confirmed) == 1 and confirmed[0]["mode"] == "RTL"


def test_a_vehicle_heard_again_after_an_outage_is_told_its_safe_state_at_once() -> None:
    # Given up at 13 s, the RTL sent into the dead link is lost; the next one goes the
    # moment the link is back (23 s), not a safe_state_period later.
    outcome, sim, lines, _, _ = run(TAKE_OFF + GO + LAND, options=RunOptions(
        link_lost_limit=10.0, safe_state_period=60.0), fake=Outage)
    assert outcome.exit_code == ExitCode.FAILURE
    back = [line for line in lines if line["kind"] == "safety"
            and "the link came back" in line.get("message", "")]
    assert len(back) == 1 and 23.0 <= back[0]["t"] < 23.5, back
    confirmed = [line for line in lines if line["kind"] == "safety" and line.get("confirmed")]
    assert confirmed and confirmed[0]["t"] < 24.0 and sim.vehicles[0].mode == "RTL"


class Spooling(FakeVehicle):
    """A copter that spins up for a second after its take-off request, still on the
    ground, and refuses a disarm from then on (ArduCopter refuses one once it climbs)."""

    lift_at: float | None = None

    def _apply(self, request):  # type: ignore[no-untyped-def]
        if isinstance(request, Disarm) and self.lift_at is not None:
            return "rejected"
        if request.name == "TakeOff":
            self.lift_at = self.time + 1.0
        return super()._apply(request)

    def _advance(self, dt: float) -> None:
        if self.lift_at is None or self.time >= self.lift_at:
            super()._advance(dt)


def test_a_disarm_overtaken_by_the_take_off_becomes_the_safe_state_at_once() -> None:
    # Stopped while spinning up: the fresh picture says armed on the ground, so it is told
    # to disarm, which it refuses; seen in the air, it is told RTL at once, not a
    # safe_state_period later.
    sim = Sim(Spooling())
    runner = Runner(mission(TAKE_OFF + GO + LAND), sim.vehicles, clock=sim.clock,
                    options=RunOptions(safe_state_period=60.0), wait=sim.wait)
    vehicle = sim.vehicles[0]
    sim.hooks.append(lambda s: runner.stop("interrupted (SIGINT)")
                     if vehicle.lift_at is not None else None)
    outcome = runner.run()
    assert outcome.exit_code == ExitCode.ABORTED
    asked = [r.name for r in vehicle.submitted if r.name in ("Disarm", "ReturnToLaunch")]
    assert asked == ["Disarm", "ReturnToLaunch"] and vehicle.mode == "RTL"
    assert sim.time < vehicle.lift_at + 1.0  # (lift_at: set once, by the take-off)


def test_a_safe_state_never_shown_is_given_up_after_its_bound() -> None:
    class Gone(Outage):
        def down(self) -> bool:
            return self.time >= 3.0

    _, sim, _, said, _ = run(TAKE_OFF + GO + LAND, options=RunOptions(
        link_lost_limit=2.0, safe_state_timeout=30.0), fake=Gone)
    assert 35.0 <= sim.time < 40.0  # 2 s + 30 s after the link went, then it gives up
    assert said[-1].startswith("vehicle 1: safe state not confirmed within 30 s")


class Revised(FakeVehicle):
    """A fake that tells its revision as MavlinkVehicle does, and counts its states read."""

    def __init__(self, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(**kwargs)
        self.number = 0
        self.reads = 0

    def revision(self) -> int:
        return self.number

    def state(self) -> VehicleState:
        self.reads += 1
        return super().state()


HOVER = ('<task name="Hover"><action name="WAIT"><argument name="duration" value="30"/>'
         '</action></task>')
LOW_BATTERY = ('<event name="Low"><condition parameter="BATTERY_CHARGE_PERCENTAGE" '
               'comparison="less than" value="25"/><action name="LAND"/>'
               '<termination mode="END_MISSION"/></event>')


def fly_revised(drop_at: float, announce: bool, refresh: float) -> tuple[list, Revised, Sim]:
    """Take off, hover; at ``drop_at`` the battery drops to 10 %, told in the revision or not."""
    vehicle = Revised(drain_per_second=0.0)
    sim = Sim(vehicle)
    reads_while_hovering: list[int] = []

    def drop(sim: Sim) -> None:
        if sim.time == drop_at:
            reads_while_hovering.append(vehicle.reads)
            vehicle.battery = 10.0
            vehicle.number += announce
    sim.hooks.append(drop)
    log = io.StringIO()
    runner = Runner(mission(TAKE_OFF + HOVER, LOW_BATTERY), [vehicle], clock=sim.clock,
                    options=RunOptions(refresh=refresh), journal=Journal(log), wait=sim.wait)
    runner.run()
    lines = [json.loads(line) for line in log.getvalue().splitlines()]
    return lines, vehicle, sim


def test_a_change_the_vehicle_announces_reaches_the_interpreter_at_the_next_wake() -> None:
    lines, _, _ = fly_revised(drop_at=8.0, announce=True, refresh=1000.0)
    (event,) = [line for line in lines if line["kind"] == "event"][:1]
    assert event["t"] == pytest.approx(8.0)


def test_a_change_the_vehicle_does_not_announce_is_seen_after_refresh_seconds() -> None:
    # (At 8.3: between two telemetry lines, which rebuild the state at whole seconds.)
    lines, _, _ = fly_revised(drop_at=8.3, announce=False, refresh=0.5)
    (event,) = [line for line in lines if line["kind"] == "event"][:1]
    assert 8.3 < event["t"] <= 8.8 + 1e-6


def test_a_vehicle_that_says_nothing_changed_is_not_read_on_every_wake() -> None:
    refresh = 0.5
    _, vehicle, sim = fly_revised(drop_at=20.0, announce=True, refresh=refresh)
    wakes = sim.time / 0.1
    # Read on results and the telemetry line, else every ``refresh`` s: not on each wake.
    assert vehicle.reads < wakes / 2


class Watched(Revised):
    """A fake that tells its changes as MavlinkVehicle.watch does: after each move, the
    fields of its state that changed."""

    def __init__(self, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(**kwargs)
        self.watchers: list = []

    def watch(self, watcher):  # type: ignore[no-untyped-def]
        self.watchers.append(watcher)
        return lambda: self.watchers.remove(watcher)

    def tell(self, fields: frozenset[str] | None) -> None:
        self.number += 1
        for watcher in list(self.watchers):
            watcher(fields)

    def advance(self, dt: float) -> None:
        before = FakeVehicle.state(self)
        super().advance(dt)
        after = FakeVehicle.state(self)
        changed = frozenset(n for n in SHOWN_FIELDS if getattr(before, n) != getattr(after, n))
        if changed:
            self.tell(changed)


QUIET = RunOptions(refresh=1000.0, telemetry_period=1000.0)  # looked at on changes alone


def test_a_change_of_a_field_nothing_reads_is_not_looked_at_and_one_read_is_at_once(
        ) -> None:
    vehicle = Watched(drain_per_second=0.0)
    sim = Sim(vehicle)
    reads: dict[float, int] = {}

    def script(sim: Sim) -> None:
        if sim.time == 8.0:  # pushed aside: a hover reads no position, its event a battery
            vehicle.position = (3.0, 0.0, vehicle.position[2])
            vehicle.tell(frozenset({"position"}))
        if sim.time in (8.0, 9.9):
            reads[sim.time] = vehicle.reads
        if sim.time == 10.0:
            vehicle.battery = 10.0
            vehicle.tell(frozenset({"battery"}))
    sim.hooks.append(script)
    log = io.StringIO()
    Runner(mission(TAKE_OFF + HOVER, LOW_BATTERY), [vehicle], clock=sim.clock, options=QUIET,
           journal=Journal(log), wait=sim.wait).run()
    lines = [json.loads(line) for line in log.getvalue().splitlines()]
    assert reads[9.9] == reads[8.0]  # the moves back to the hover point: not looked at
    (event,) = [line for line in lines if line["kind"] == "event"][:1]
    assert event["t"] == pytest.approx(10.0)


def test_in_a_fleet_a_wake_looks_only_at_the_vehicles_that_changed() -> None:
    fleet = [Watched(vehicle_id=n, drain_per_second=0.0) for n in range(1, 11)]
    sim = Sim(*fleet)
    reads: dict[float, list[int]] = {}

    def script(sim: Sim) -> None:
        if sim.time in (9.0, 9.9, 10.1):
            reads[sim.time] = [v.reads for v in fleet]
        if sim.time == 10.0:
            fleet[3].battery = 10.0
            fleet[3].tell(frozenset({"battery"}))
    sim.hooks.append(script)
    body = ('<roles><role name="fleet" count="10" type="quadcopter"/></roles>'
            '<task name="Patrol" role="fleet">' + TAKE_OFF + HOVER + '</task>')
    low = LOW_BATTERY.replace('<event name="Low"', '<event name="Low" role="fleet"')
    outcome = Runner(mission(body, low), fleet, clock=sim.clock, options=QUIET,
                     journal=Journal(io.StringIO()), wait=sim.wait).run()
    assert reads[9.9] == reads[9.0]  # hovering, unchanged: nobody looked at
    looked = [after - before for before, after in zip(reads[9.9], reads[10.1], strict=True)]
    assert looked[3] >= 1 and looked[:3] + looked[4:] == [0] * 9
    assert isinstance(fleet[3].submitted[-1], Land)  # its event fired
    assert outcome.exit_code is ExitCode.OK


class Calm(Watched):
    """A watched fake that also says how long time alone changes nothing of its state."""

    quiet = 3.0

    def calm(self) -> float:
        return self.quiet


def test_a_vehicle_whose_time_changes_nothing_is_not_refreshed_before_it_says() -> None:
    vehicle = Calm(drain_per_second=0.0)
    sim = Sim(vehicle)
    reads: dict[float, int] = {}

    def count(sim: Sim) -> None:
        if sim.time in (8.0, 9.9, 14.0):
            reads[sim.time] = vehicle.reads
    sim.hooks.append(count)
    Runner(mission(TAKE_OFF + HOVER, LOW_BATTERY), [vehicle], clock=sim.clock,
           options=RunOptions(refresh=0.25, telemetry_period=1000.0), journal=Journal(None),
           wait=sim.wait).run()
    assert reads[9.9] - reads[8.0] <= 1  # not every 0.25 s: at most once in 3 s
    assert reads[14.0] - reads[8.0] >= 1  # but once its calm is over


def test_the_display_shows_what_the_vehicle_shows_even_when_no_look_needed_it() -> None:
    vehicle = Calm(drain_per_second=0.0)
    sim = Sim(vehicle)
    shown: dict[float, object] = {}

    def push(sim: Sim) -> None:
        if sim.time == 8.0:  # nothing reads a hovering vehicle's position
            vehicle.position = (3.0, 0.0, vehicle.position[2])
            vehicle.tell(frozenset({"position"}))

    def update(runner: Runner) -> None:
        if sim.time in (7.9, 8.0):
            (_, state), = runner.views()
            shown[sim.time] = state.position if state is not None else None
    sim.hooks.append(push)
    runner = Runner(mission(TAKE_OFF + HOVER), [vehicle], clock=sim.clock, options=QUIET,
                    journal=Journal(None), wait=sim.wait, on_update=update)
    runner.run()
    assert shown[7.9][0] < 0.5 and shown[8.0][0] > 2.0  # type: ignore[index]


def test_each_change_of_the_link_is_journaled_when_a_wake_sees_it() -> None:
    class Flaky(FakeVehicle):
        """Silent from 2.2 s: degraded, then lost from 3 s, back at 4 s."""

        def state(self) -> VehicleState:
            state = super().state()
            if 2.2 <= self.time < 4.0:
                return replace(state, link="degraded" if self.time < 3.0 else "lost")
            return state

    outcome, _, lines, _, _ = run(TAKE_OFF + GO + LAND, fake=Flaky)
    assert outcome.exit_code == ExitCode.OK
    changes = [(line["t"], line["was"], line["link"]) for line in lines
               if line["kind"] == "link"]
    assert [(was, link) for _, was, link in changes] == [
        ("ok", "degraded"), ("degraded", "lost"), ("lost", "ok")]
    assert [t for t, _, _ in changes] == pytest.approx([2.2, 3.0, 4.0], abs=0.11)


def test_the_link_coming_back_while_the_safe_state_is_awaited_is_journaled() -> None:
    _, _, lines, _, _ = run(TAKE_OFF + GO + LAND, options=RunOptions(
        link_lost_limit=10.0), fake=Outage)
    changes = [(line["t"], line["link"]) for line in lines if line["kind"] == "link"]
    assert [link for _, link in changes] == ["lost", "ok"]
    ended = next(line["t"] for line in lines if line["kind"] == "mission"
                 and "status" in line)
    assert changes[0][0] == pytest.approx(3.0, abs=0.11)
    assert changes[1][0] == pytest.approx(23.0, abs=0.11) and changes[1][0] > ended


FENCED = ('<environment><geofence max_altitude="50"><point north="-100" east="-100"/>'
          '<point north="100" east="-100"/><point north="100" east="100"/>'
          '<point north="-100" east="100"/></geofence>'
          '<rally><point north="-20" east="0" altitude="15"/></rally></environment>')


def test_the_missions_fence_goes_on_each_vehicle_before_the_first_take_off() -> None:
    outcome, sim, lines, _, _ = run(FENCED + TAKE_OFF + LAND, vehicles=2)
    assert outcome.exit_code == ExitCode.OK
    for vehicle in sim.vehicles:
        first = vehicle.submitted[0]
        assert (first.name, first.fence) == ("Safeguard", True)  # type: ignore[attr-defined]
        assert first.world.rally[0].altitude == 15  # type: ignore[attr-defined]
        assert [r.name for r in vehicle.submitted].count("Safeguard") == 1
    told = [line for line in lines if line["kind"] == "safeguard"]
    assert [(line["vehicle"], line["ok"]) for line in told] == [(1, True), (2, True)]
    first_request = next(line for line in lines if line["kind"] == "request")
    assert first_request["t"] >= max(line["t"] for line in told)


def test_a_fence_the_vehicle_refuses_fails_the_run_before_anything_flies() -> None:
    sim = Sim(FakeVehicle(reject={"Safeguard": "rejected"}))
    log = io.StringIO()
    runner = Runner(mission(FENCED + TAKE_OFF + LAND), sim.vehicles, clock=sim.clock,
                    wait=sim.wait, journal=Journal(log))
    outcome = runner.run()
    assert outcome.exit_code == ExitCode.FAILURE
    (vehicle,) = outcome.vehicles
    assert (vehicle.status, vehicle.cause) == (Status.FAILED, "ready")
    assert vehicle.reason == ("the mission's fence and rally points could not be put on the "
                              "vehicle: rejected")
    assert [r.name for r in sim.vehicles[0].submitted] == ["Safeguard"]


def test_keeping_the_vehicles_fence_still_sends_the_rally_points() -> None:
    _, sim, _, _, _ = run(FENCED + TAKE_OFF + LAND, options=RunOptions(vehicle_fence=False))
    first = sim.vehicles[0].submitted[0]
    assert (first.name, first.fence) == ("Safeguard", False)  # type: ignore[attr-defined]
    _, sim, _, _, _ = run(TAKE_OFF + LAND)  # nothing to put on the vehicle
    assert "Safeguard" not in [r.name for r in sim.vehicles[0].submitted]


class WithSkills(FakeVehicle):
    """A fake vehicle that says which skills it switches: none until ``companion_at``,
    then AVOID_OBSTACLES (its companion computer heard); RECOGNIZE_ITEMS never."""

    companion_at = 2.0

    def state(self) -> VehicleState:
        from types import MappingProxyType

        heard = self.time >= self.companion_at
        return replace(super().state(), skills=MappingProxyType({
            "AVOID_OBSTACLES": "" if heard else "needs a companion computer (component 191), "
                                                "not heard yet"}))


SKILLED = '<task name="Look"><skill name="AVOID_OBSTACLES"/>' + TAKE_OFF + LAND + '</task>'


def test_a_skill_waits_for_its_companion_and_one_nothing_switches_is_refused_at_once() -> None:
    outcome, sim, lines, _, _ = run(SKILLED, fake=WithSkills)
    assert outcome.exit_code == ExitCode.OK
    ready = [line["message"] for line in lines if line["kind"] == "ready"]
    assert ready == ["waiting for skill AVOID_OBSTACLES (needs a companion computer "
                     "(component 191), not heard yet)", "ready"]
    requests = [line for line in lines if line["kind"] == "request"]
    assert requests[0]["t"] >= WithSkills.companion_at  # nothing before it was heard
    items = SKILLED.replace('<skill name="AVOID_OBSTACLES"/>',
                            '<skill name="AVOID_OBSTACLES"/><skill name="RECOGNIZE_ITEMS"/>')
    outcome, sim, _, _, _ = run(items, fake=WithSkills)
    (vehicle,) = outcome.vehicles
    assert (outcome.exit_code, vehicle.status, vehicle.cause) == (
        ExitCode.FAILURE, Status.FAILED, "ready")
    assert vehicle.reason == ("the mission's skill RECOGNIZE_ITEMS: nothing on this vehicle "
                              "switches it")
    assert sim.vehicles[0].submitted == [] and sim.time < 0.5  # at once, nothing sent


class Rebooting(FakeVehicle):
    """A fake vehicle whose autopilot rebooted once before the run (a vehicle kept open by
    a service), and, when ``again_at`` is set, once more then: disarmed, on the ground."""

    again_at: float | None = None

    def state(self) -> VehicleState:
        reboots = 2 if self.again_at is not None and self.time >= self.again_at else 1
        if reboots == 2:
            self.armed = False
        return replace(super().state(), reboots=reboots,
                       rebooted=f"rebooted {'while armed' if reboots == 2 else 'disarmed'} "
                                "(its clock went from 40.0 s back to 0.5 s)")


def test_a_reboot_during_the_run_ends_the_vehicles_work_one_before_it_does_not() -> None:
    outcome, *_ = run(TAKE_OFF + GO + LAND, fake=Rebooting)
    assert outcome.exit_code == ExitCode.OK  # rebooted before this run: not its business

    class Again(Rebooting):
        again_at = 3.0

    outcome, _, lines, said, _ = run(TAKE_OFF + GO + LAND, fake=Again)
    (vehicle,) = outcome.vehicles
    assert (outcome.exit_code, vehicle.status, vehicle.cause) == (
        ExitCode.FAILURE, Status.FAILED, "rebooted")
    assert said[0] == ("vehicle 1 rebooted while armed (its clock went from 40.0 s back to "
                       "0.5 s): tml commands it no more")
    (taken,) = [line for line in lines if line["kind"] == "taken"]
    assert taken["reboot"] is True
    after = [line for line in lines if line["t"] >= taken["t"]
             and line["kind"] in ("request", "safety")]
    assert after == []  # nothing sent to it after


def test_a_change_alone_steps_again_only_after_the_rest_a_long_step_earns() -> None:
    # Each step takes 0.2 s of the runner's clock (a large fleet's step): a vehicle that
    # changes at every wake steps the interpreter again only 0.2 s after the step ended
    # (the steps take at most half of the time); a request's result steps it at once; the
    # mission flies as before; the loop sleeps the rest on its time base, which a
    # simulator's clock outruns.
    from tml.timebase import Timebase

    sim = Sim(FakeVehicle())
    slept: list[float] = []

    class TenTimesSlower(Timebase):  # the runner's clock is a simulator's at 10x
        def now(self) -> float:
            return sim.time / 10

        def sleep(self, seconds: float) -> None:
            slept.append(seconds)

    runner = Runner(mission(TAKE_OFF + GO + LAND), sim.vehicles, clock=sim.clock,
                    options=RunOptions(rate=1.0), wait=sim.wait, timebase=TenTimesSlower())
    engine = runner.crews[0].engine
    step = engine.step
    steps: list[tuple[float, float, bool]] = []  # began, ended, with results

    def slow(now, states, results):  # type: ignore[no-untyped-def]
        out = step(now, states, results)
        sim.time = round(sim.time + 0.2, 6)
        steps.append((now, sim.time, any(results.values())))
        return out
    engine.step = slow  # type: ignore[method-assign]
    outcome = runner.run()
    assert outcome.exit_code == ExitCode.OK
    rested = [(a, b) for a, b in itertools.pairwise(steps) if not b[2]]
    assert rested and all(b[0] >= a[1] + 0.2 - 1e-9 for a, b in rested)
    early = [b for a, b in itertools.pairwise(steps) if b[0] < a[1] + 0.2 - 1e-9]
    assert early and all(with_results for _, _, with_results in early)
    # The rest is slept on the time base: 0.2 s of the clock is 0.02 s of it.
    assert slept and max(slept) <= 0.02 + 1e-9


def test_the_runner_looks_steps_and_asks_with_the_right_of_way() -> None:
    # Its turn is done in one piece: the thread reading the links gives way meanwhile
    # (tml.timebase.Timebase.right_of_way), from the look to the requests it submits.
    import contextlib
    from collections.abc import Iterator

    from tml.timebase import Timebase

    sim = Sim(FakeVehicle())
    holding = [False]
    seen: list[tuple[str, bool]] = []

    class Watched(Timebase):
        @contextlib.contextmanager
        def right_of_way(self) -> Iterator[None]:
            holding[0] = True
            try:
                yield
            finally:
                holding[0] = False

    vehicle = sim.vehicles[0]
    state, submit = vehicle.state, vehicle.submit

    def looked():  # type: ignore[no-untyped-def]
        seen.append(("look", holding[0]))
        return state()

    def asked(request):  # type: ignore[no-untyped-def]
        seen.append(("ask", holding[0]))
        submit(request)
    vehicle.state = looked  # type: ignore[method-assign]
    vehicle.submit = asked  # type: ignore[method-assign]
    runner = Runner(mission(TAKE_OFF + LAND), sim.vehicles, clock=sim.clock,
                    wait=sim.wait, timebase=Watched())
    engine = runner.crews[0].engine
    step = engine.step

    def stepped(now, states, results):  # type: ignore[no-untyped-def]
        seen.append(("step", holding[0]))
        return step(now, states, results)
    engine.step = stepped  # type: ignore[method-assign]
    assert runner.run().exit_code == ExitCode.OK
    flying = seen[seen.index(("step", True)):]  # the start is stepped before the loop
    assert {kind for kind, _ in flying} == {"look", "step", "ask"}
    assert all(held for kind, held in flying if kind in ("step", "ask"))
    assert sum(held for kind, held in flying if kind == "look") > 1


def test_a_request_goes_out_after_its_decisions_are_on_the_disk_in_one_sync(
        tmp_path, monkeypatch) -> None:
    # A log read back after the machine went down holds every decision the vehicles were
    # commanded on (tml run --resume); the decisions of one engine call share one sync.
    sim = Sim(FakeVehicle(vehicle_id=1), FakeVehicle(vehicle_id=2))
    journal = Journal.open(str(tmp_path / "flight.jsonl"))
    order: list[tuple[str, int]] = []  # ("sync" | "submit", lines written by then)
    monkeypatch.setattr("tml.run.journal.os.fsync",
                        lambda fd: order.append(("sync", journal.lines)))
    for vehicle in sim.vehicles:
        submit = vehicle.submit

        def submitted(request, submit=submit):  # type: ignore[no-untyped-def]
            order.append(("submit", journal.lines))
            submit(request)
        vehicle.submit = submitted  # type: ignore[method-assign]
    runner = Runner(mission(TAKE_OFF + LAND), sim.vehicles, clock=sim.clock,
                    journal=journal, wait=sim.wait)
    assert runner.run().exit_code == ExitCode.OK
    journal.close()
    submits = [i for i, (what, _) in enumerate(order) if what == "submit"]
    assert len(submits) >= 4  # take-off and landing of both
    for i in submits:
        last_sync = max(j for j in range(i) if order[j][0] == "sync")
        assert order[last_sync][1] == order[i][1]  # nothing written after it, unsynced
    decided = sum(line["kind"] in DECISIONS for line in read(str(tmp_path / "flight.jsonl")))
    assert sum(what == "sync" for what, _ in order) < decided  # grouped, not line by line


def test_a_wait_is_stepped_at_its_end_and_when_what_an_event_reads_changes() -> None:
    # During a 30 s WAIT the battery falls at every wake, which no rule of this mission
    # reads: the interpreter is not stepped for it (tml.engine.wake). A detection an
    # event reads steps it at the wake that shows it, and the WAIT ends at its time.
    seen_at = 20.0

    def see(sim: Sim) -> None:
        sim.vehicles[0].detections["seen"] = sim.time >= seen_at

    seen = ('<event name="Seen"><condition parameter="seen" comparison="equal" value="yes"/>'
            '<action name="MEMORIZE_POINT"><argument name="coordinates" label="p"/></action>'
            '<termination mode="CONTINUE"/></event>')
    sim = Sim(FakeVehicle(drain_per_second=0.5))
    sim.hooks.append(see)
    log = io.StringIO()
    runner = Runner(mission('<parameter name="seen" type="boolean"/>' + TAKE_OFF + HOVER
                            + LAND, seen), sim.vehicles, clock=sim.clock,
                    options=RunOptions(rate=1.0), journal=Journal(log), wait=sim.wait)
    engine = runner.crews[0].engine
    step = engine.step
    steps: list[float] = []

    def counted(now, states, results):  # type: ignore[no-untyped-def]
        steps.append(now)
        return step(now, states, results)
    engine.step = counted  # type: ignore[method-assign]
    assert runner.run().exit_code == ExitCode.OK
    lines = [json.loads(line) for line in log.getvalue().splitlines()]
    hover = [line["t"] for line in lines if line.get("task") == "Hover"]
    began, ended = hover[0], hover[-1]
    assert 30.0 <= ended - began <= 30.0 + 0.1 + 1e-9
    fired = next(line["t"] for line in lines if line["kind"] == "event")
    assert seen_at <= fired <= seen_at + 0.1 + 1e-9
    # In the WAIT: its Hold's result, the detection, the end (and the rate's 1 s ticks
    # until the engine has said what it waits for); not one step per battery reading.
    during = [t for t in steps if began < t < ended]
    assert len(during) <= 5, during


class BootingAndTroubled(Booting):
    """A vehicle not ready before ``armable_at`` whose link is lost from ``lost_at``, or
    whose autopilot reboots at ``reboot_at``, while the run waits for it."""

    armable_at = 60.0
    lost_at: float | None = None
    reboot_at: float | None = None

    def state(self) -> VehicleState:
        state = super().state()
        if self.lost_at is not None and self.time >= self.lost_at:
            state = replace(state, link="lost")
        if self.reboot_at is not None and self.time >= self.reboot_at:
            state = replace(state, reboots=1,
                            rebooted="rebooted disarmed (its clock went from 3.0 s back to "
                                     "0.5 s)")
        return state


@pytest.mark.parametrize("trouble", ["link", "rebooted"])
def test_a_vehicle_lost_or_rebooted_while_waited_for_ends_the_run_as_in_flight(
        trouble: str) -> None:
    """Waiting for its vehicles, a run ends on a link lost past the limit and on a reboot
    as it would in flight, before anything is sent: a rebooted vehicle ready again would
    otherwise be flown by a mission that let it go at its first step."""
    vehicle = BootingAndTroubled()
    vehicle.armable_at = 5.0 if trouble == "rebooted" else 60.0
    if trouble == "link":
        vehicle.lost_at = 3.0
    else:
        vehicle.reboot_at = 3.0
    sim = Sim(vehicle)
    said: list[str] = []
    log = io.StringIO()
    runner = Runner(mission(TAKE_OFF + LAND), sim.vehicles, clock=sim.clock, wait=sim.wait,
                    options=RunOptions(link_lost_limit=2.0), on_safety=said.append,
                    journal=Journal(log))
    outcome = runner.run()
    (ended,) = outcome.vehicles
    assert (outcome.exit_code, ended.status, ended.cause) == (
        ExitCode.FAILURE, Status.FAILED, trouble)
    assert sim.vehicles[0].submitted == []  # nothing sent, before or after
    if trouble == "link":
        assert ended.reason == "link lost for more than 2 s" and 5.0 < sim.time < 5.3
        assert said == ["vehicle 1: link lost for more than 2 s"]
    else:
        assert ended.reason.startswith("rebooted disarmed") and sim.time < 3.2
        assert said == [f"vehicle 1 {ended.reason}: tml commands it no more"]
        lines = [json.loads(line) for line in log.getvalue().splitlines()]
        assert [line["reboot"] for line in lines if line["kind"] == "taken"] == [True]


def test_a_vehicle_never_heard_is_waited_for_not_given_up_as_lost() -> None:
    vehicle = BootingAndTroubled()
    vehicle.lost_at = 0.0
    sim = Sim(vehicle)
    runner = Runner(mission(TAKE_OFF + LAND), sim.vehicles, clock=sim.clock, wait=sim.wait,
                    options=RunOptions(link_lost_limit=2.0, ready_timeout=5.0))
    (ended,) = runner.run().vehicles
    assert (ended.cause, ended.reason) == ("ready", "not ready after 5 s: waiting for heartbeat")


def test_a_vehicle_in_the_air_is_told_its_safe_state_when_the_run_ends_while_waiting() -> None:
    """A resumed run waits for its vehicles flying as they are (a skill's companion, a
    link): a run that ends there leaves none of them hovering without a controller."""
    flying = FakeVehicle()
    flying.submit(Arm(1, request_id=1))
    flying.submit(TakeOff(1, 10.0, request_id=2))
    while flying.position[2] < 10.0:
        flying.advance(0.1)
    flying.poll()
    vehicle = BootingAndTroubled()
    vehicle.lost_at = 1.0
    sim = Sim(flying, vehicle)
    said: list[str] = []
    runner = Runner(mission(TAKE_OFF + LAND), sim.vehicles, clock=sim.clock, wait=sim.wait,
                    options=RunOptions(link_lost_limit=2.0), on_safety=said.append)
    outcome = runner.run()
    assert [v.cause for v in outcome.vehicles] == ["ready", "link"]
    assert [r.name for r in flying.submitted[2:]] == ["ReturnToLaunch"]
    assert sim.vehicles[1].submitted == []  # on the ground: left as it is
    assert said[1] == ("vehicle 1: ReturnToLaunch (the run ended before its first task: "
                       "link lost for more than 2 s)")


def test_a_vehicle_landing_when_the_engine_breaks_is_left_to_land_and_the_runner_says_so(
        ) -> None:
    sim = Sim(FakeVehicle())
    log = io.StringIO()
    said: list[str] = []
    runner = Runner(mission(TAKE_OFF + LAND), sim.vehicles, clock=sim.clock, wait=sim.wait,
                    journal=Journal(log), on_safety=said.append)
    engine = runner.crews[0].engine
    step = engine.step

    def explode_while_landing(now, states, results):  # type: ignore[no-untyped-def]
        vehicle = sim.vehicles[0]
        if vehicle.mode == "LAND" and vehicle.position[2] > 0.5:
            raise RuntimeError("boom")
        return step(now, states, results)
    engine.step = explode_while_landing  # type: ignore[method-assign]
    outcome = runner.run()
    assert outcome.exit_code == ExitCode.FAILURE
    lines = [json.loads(line) for line in log.getvalue().splitlines()]
    safety = [(line["message"], line.get("request"), line.get("confirmed"))
              for line in lines if line["kind"] == "safety"]
    assert safety[0] == ("vehicle landing (LAND): left to land by itself (interpreter "
                         "error: boom)", "", None)
    assert safety[-1][2] is True  # and confirmed
    assert not [r for r in sim.vehicles[0].submitted if isinstance(r, ReturnToLaunch)]
    assert "vehicle 1: vehicle landing (LAND): left to land by itself (interpreter error: " \
           "boom)" in said
