"""The terminal view, rendered to text."""

from __future__ import annotations

import io
from dataclasses import replace
from pathlib import Path

import pytest
from fake_vehicle import FakeVehicle
from rich.console import Console

from tml.engine import Change, Interpreter, Status, TaskState
from tml.language.validation import load_mission, validate_file
from tml.run.display import LineDisplay, render_text, rounds
from tml.run.fold import fold
from tml.vehicle import AutopilotMessage

XML = b"""<mission name="Show">
  <task name="Take off"><action name="TAKE_OFF"><argument name="altitude" value="5"/></action>
  </task>
  <task name="Leg"><action name="GO_TO_POINT"><argument name="coordinates" value="(50, 0, 5)"/>
  </action></task>
  <event_handling><event name="Far"><condition parameter="DISTANCE_TO_HOME"
    comparison="greater than" value="10"/><termination mode="CONTINUE"/></event>
  </event_handling>
</mission>"""


def flown(seconds: float, xml: bytes = XML):
    mission = validate_file("show.xml", xml).mission
    vehicle = FakeVehicle()
    interp = Interpreter(mission, [1])
    for request in interp.start(0.0, {1: vehicle.state()}).requests:
        vehicle.submit(request)
    for tick in range(1, round(seconds * 10) + 1):
        vehicle.advance(0.1)
        t = tick / 10
        for request in interp.step(t, {1: vehicle.state()}, {1: vehicle.poll()}).requests:
            vehicle.submit(request)
    return mission, [(interp.views()[1], vehicle.state())]


def test_view_shows_tree_states_action_progress_telemetry_and_events() -> None:
    mission, views = flown(6.0)
    text = render_text(mission, views)
    lines = text.splitlines()
    assert lines[0] == "Show  mission time 6.0 s"
    assert any("✓ ├─ Take off" in line and "TAKE_OFF" in line for line in lines)
    assert any("▶ └─ Leg" in line for line in lines)
    block = _block(lines, "vehicle 1")
    assert "GUIDED armed" in block[0] and "%" in block[0] and "link ok" in block[0]
    # 160 columns: how it stands and how it moves on one line, its work on the next.
    assert "GPS 3D 10 sat  n " in block[0] and "hdg " in block[0]
    assert len(block) == 2 and "GO_TO_POINT (Leg)" in block[1]
    narrow = _block(render_text(mission, views, 80).splitlines(), "vehicle 1")
    assert len(narrow) == 3 and narrow[1].startswith("   n ") and "(Leg)" in narrow[2]
    assert any("Far" in line for line in lines[lines.index(
        next(line for line in lines if line.startswith("events:"))):])


def _block(lines: list[str], name: str) -> list[str]:
    """A vehicle's lines in the view: the one that begins with its name, and those under it."""
    first = next(i for i, line in enumerate(lines) if line.startswith(name + " ")
                 or line == name)
    end = next((i for i in range(first + 1, len(lines)) if not lines[i].startswith("   ")),
               len(lines))
    return lines[first:end]


def test_view_before_anything_happened() -> None:
    mission = validate_file("show.xml", XML).mission
    interp = Interpreter(mission, [1])
    text = render_text(mission, [(interp.views()[1], None)], wall="14:03:22")
    assert "· ├─ Take off" in text and "events: none yet" in text
    assert text.splitlines()[0] == "Show  mission time -  14:03:22"  # not started yet
    assert "vehicle 1  no telemetry yet" in text


def test_line_display_prints_each_change_once() -> None:
    _, views = flown(6.0)
    out = io.StringIO()
    display = LineDisplay(Console(file=out, width=200, color_system=None))
    display.update(views)
    display.update(views)
    printed = out.getvalue().splitlines()
    assert sum("Take off: done" in line for line in printed) == 1
    assert sum("event 'Far'" in line for line in printed) == 1
    display.say("vehicle 1: ReturnToLaunch")
    assert out.getvalue().endswith("vehicle 1: ReturnToLaunch\n")


NESTED = b"""<mission name="Nested">
  <task name="Take off"><action name="TAKE_OFF"><argument name="altitude" value="5"/></action>
  </task>
  <task name="Survey">
    <task name="Mark"><action name="MEMORIZE_POINT"><argument name="coordinates" label="p"/>
    </action></task>
    <task name="Leg"><action name="GO_TO_POINT"><argument name="coordinates" value="(5, 0, 5)"/>
    </action></task>
  </task>
</mission>"""


def test_line_display_prints_every_change_once_in_the_order_it_happened() -> None:
    _, views = flown(12.0, NESTED)
    out = io.StringIO()
    display = LineDisplay(Console(file=out, width=200, color_system=None))
    display.update(views)
    display.update(views)
    printed = [line.split("vehicle 1: ", 1)[1] for line in out.getvalue().splitlines()
               if "vehicle 1: " in line and ": " in line.split("vehicle 1: ", 1)[1]]
    assert printed == ["Take off: running", "Take off: done", "Survey: running",
                       "Survey/Mark: running", "Survey/Mark: done", "Survey/Leg: running",
                       "Survey/Leg: done", "Survey: done"]


ROOT = Path(__file__).resolve().parent.parent


def fly(path: str, seconds: float, vehicles: list[FakeVehicle] | None = None):
    """A mission file flown on fake vehicles for ``seconds``: the mission and the views."""
    mission = load_mission(ROOT / path)
    vehicles = vehicles or [FakeVehicle()]
    interp = Interpreter(mission, [v.vehicle_id for v in vehicles])
    states = {v.vehicle_id: v.state() for v in vehicles}
    output = interp.start(0.0, states)
    for tick in range(0, round(seconds * 10) + 1):
        for request in output.requests:
            next(v for v in vehicles if v.vehicle_id == request.vehicle_id).submit(request)
        for vehicle in vehicles:
            vehicle.advance(0.1)
        output = interp.step((tick + 1) / 10, {v.vehicle_id: v.state() for v in vehicles},
                             {v.vehicle_id: v.poll() for v in vehicles})
    views = interp.views()
    return mission, [(views[v.vehicle_id], v.state()) for v in vehicles]


def _fits(text: str, width: int, height: int) -> list[str]:
    lines = text.splitlines()
    assert len(lines) <= height, text
    assert max(len(line) for line in lines) <= width, text
    return lines


@pytest.mark.parametrize("size", [(80, 24), (120, 40)])
def test_a_long_mission_fits_the_terminal_folded_around_the_running_task(size) -> None:
    width, height = size
    vehicle = FakeVehicle(capabilities=frozenset({"camera", "gripper", "flip"}))
    mission, views = fly("missions/catalogue_tour.xml", 120.0, [vehicle])
    vehicle.say(4, "EKF variance")
    views = [(views[0][0], vehicle.state())]
    running = views[0][0].current_task
    assert running, "a task is running two minutes in"
    lines = _fits(render_text(mission, views, width, height), width, height)
    assert any(line.startswith("vehicle 1 ") and "GUIDED" in line for line in lines)
    assert any(line.startswith("events:") for line in lines)
    assert any(line.startswith("autopilot:") for line in lines)
    assert any(line.strip() == "warning: EKF variance" for line in lines)
    assert any("▶ " in line and running.rsplit("/", 1)[-1] in line for line in lines)
    if height == 24:
        assert any("more task" in line for line in lines)  # the rest counted, not shown
    full = render_text(mission, views, width)  # no height: nothing folded
    assert "more task" not in full and len(full.splitlines()) > 24


def test_the_fold_keeps_ancestors_and_near_siblings() -> None:
    mission = load_mission(ROOT / "missions/catalogue_tour.xml")
    tasks = [t for t in mission.walk() if len(t.path) > 1]
    focus = tasks[len(tasks) // 2]
    lines = fold(mission.tasks, [focus.path_name], 12)
    assert len(lines) <= 12
    shown = [line.task.path for line in lines if line.task is not None]
    assert all(focus.path[:i] in shown for i in range(1, len(focus.path) + 1))
    hidden = sum(line.hidden + line.folded for line in lines)
    assert hidden + len(shown) == sum(1 for t in mission.walk()
                                      if not any(t in h.walk() for o in mission.walk()
                                                 for h in o.on_error))
    assert fold(mission.tasks, [focus.path_name], None) == fold(mission.tasks, [], 1000)


def test_a_fleet_has_a_header_over_the_marks_of_each_vehicle() -> None:
    vehicles = [FakeVehicle(vehicle_id=1), FakeVehicle(vehicle_id=2),
                FakeVehicle(vehicle_id=3)]
    mission, views = fly("missions/fleet_compositions.xml", 20.0, vehicles)
    lines = _fits(render_text(mission, views, 80, 24), 80, 24)
    header = lines[1]
    assert header.startswith(" 1 2 3") and "vehicle" in header
    assert lines[0].startswith(f"{mission.name}  mission time ")
    named = [line.split()[1] for line in lines if line.startswith("vehicle ")]
    assert named == ["1", "2", "3"]


def test_a_plan_flown_by_the_autopilot_shows_its_item() -> None:
    mission, views = fly("missions/mission_dispatch.xml", 6.0)
    text = render_text(mission, views, 80, 24)
    assert "[autopilot mission]" in text
    said = views[0][1].mission
    assert said is not None and said.items == 13
    assert f"item {said.item}/13 " in _block(text.splitlines(), "vehicle 1")[2]


def test_a_survey_shows_the_item_the_autopilot_flies_and_its_progress() -> None:
    # A survey is one action of many items: "item 2/2" for minutes said nothing.
    mission, views = fly("missions/mission_dispatch.xml", 6.0)
    view, state = views[0]
    state = replace(state, mission=replace(state.mission, item=43, items=145))
    view = replace(view, current_task="Photo flight/Circle the first field twice",
                   current_action="LOITER", progress=42 / 145)
    line = _block(render_text(mission, [(view, state)], 80, 24).splitlines(), "vehicle 1")[2]
    assert "███░░░░░░░  29%  item 43/145 LOITER (Circle the first field twice)" in line


def test_the_work_of_a_vehicle_takes_the_width_there_is() -> None:
    mission, views = fly("missions/mission_dispatch.xml", 6.0)
    view, state = views[0]
    view = replace(view, current_task="Photo flight/" + "A long task name " * 4,
                   current_action="SURVEY_AREA", progress=None)
    for width in (80, 120):
        line = _block(render_text(mission, [(view, state)], width, 24).splitlines(),
                      "vehicle 1")[2]
        wanted = "SURVEY_AREA (" + "A long task name " * 4
        assert wanted[:width - 20] in line and len(line) <= width
    line = _block(render_text(mission, [(view, state)], 120, 24).splitlines(), "vehicle 1")[2]
    assert "…" not in line  # 120 columns hold it whole


def test_figures_are_labelled_with_units_and_never_negative_zero() -> None:
    mission, views = fly("missions/paper_example1.xml", 0.0)
    view, state = views[0]
    state = replace(state, position=(-0.01, 0.04, 7.0), climb=-0.01, ground_speed=0.0,
                    armed=True, landed=False, gps_fix=3, satellites=12, voltage=12.36,
                    battery=64.6, heading=359.7, mode="GUIDED")
    block = _block(render_text(mission, [(view, state)], 80, 24).splitlines(), "vehicle 1")
    assert "GUIDED armed  link ok  batt 12.4 V 65%  GPS 3D 12 sat" in block[0]
    assert block[1] == ("   n 0.0 e 0.0 up 7.0 m  climb +0.0 m/s  home 0.0 m  speed 0.0 m/s"
                        "  hdg 0°")
    assert "-0" not in "\n".join(block)
    lost = replace(state, armed=False, gps_fix=1, satellites=None, voltage=None,
                   battery=None, link="lost", position=None)
    block = _block(render_text(mission, [(view, lost)], 80, 24).splitlines(), "vehicle 1")
    assert "GUIDED disarmed  link lost  batt -  GPS no fix" in block[0]
    assert block[1].startswith("   n - e - up - m")


def test_a_vehicle_keeps_to_three_lines_on_80_columns() -> None:
    # Far out and fast, in a fleet with roles: what does not fit its line is left out,
    # the least needed first (heading, then speed), never wrapped onto a fourth line.
    mission, _, views = _fleet_views()
    view, state = views[0]
    state = replace(state, position=(-130.5, -263.4, 120.0), ground_speed=12.3, climb=-2.5,
                    heading=359.0)
    view = replace(view, status=Status.COMPLETED, role="surveyor")
    block = _block(render_text(mission, [(view, state), views[1]], 80, 24).splitlines(),
                   "vehicle 1")
    assert len(block) <= 3 and all(len(line) <= 80 for line in block)
    assert block[1] == ("   n -130.5 e -263.4 up 120.0 m  climb -2.5 m/s  home 294.0 m"
                        "  speed 12.3 m/s")
    assert block[0] == ("vehicle 1 (surveyor)  completed  AUTO disarmed  link ok"
                        "  batt 12.6 V 100%")


def test_the_legend_says_what_each_mark_means() -> None:
    mission, views = fly("missions/paper_example1.xml", 0.0)
    text = render_text(mission, views, 80, 24)
    legend = next(line for line in text.splitlines() if "↷ skipped" in line)
    for words in ("· pending", "▶ running", "✓ done", "↷ skipped", "✗ failed", "■ aborted"):
        assert words in legend
    assert len(legend) <= 80


def _fleet_views():
    vehicles = [FakeVehicle(vehicle_id=1), FakeVehicle(vehicle_id=2)]
    mission, views = fly("missions/dolphin_fleet_survey.xml", 5.0, vehicles)
    return mission, vehicles, views


def test_the_end_says_each_outcome_once_for_the_vehicles_it_is_theirs() -> None:
    mission, _, views = _fleet_views()
    done = [(replace(v, reason="all tasks done"), s) for v, s in views]
    text = render_text(mission, done, 80, 24)
    assert "ended: vehicles 1, 2: all tasks done" in text
    assert "all tasks done; all tasks done" not in text
    apart = [done[0], (replace(done[1][0], reason="link lost for more than 10 s"), done[1][1])]
    assert "ended: vehicle 1: all tasks done; vehicle 2: link lost for more than 10 s" \
        in render_text(mission, apart, 120, 24)
    (alone,) = fly("missions/paper_example1.xml", 0.0)[1]
    assert "ended: all tasks done" in render_text(
        mission, [(replace(alone[0], reason="all tasks done"), alone[1])], 80, 24)


def test_each_vehicle_keeps_its_own_autopilot_messages() -> None:
    mission, vehicles, _ = _fleet_views()
    vehicles[1].say(4, "EKF variance")
    for n in range(5):  # vehicle 1 says more, later
        vehicles[0].say(6, f"Mission: {n + 40} WP")
    views = [(v, s.state()) for (v, _), s in zip(_fleet_views()[2], vehicles, strict=True)]
    lines = _fits(render_text(mission, views, 80, 24), 80, 24)
    said = lines[lines.index("autopilot:") + 1:]
    assert said[:2] == ["  vehicle 1 (v1): info: Mission: 44 WP",
                        "  vehicle 2 (v2): warning: EKF variance"]
    tall = render_text(mission, views, 120, 50).splitlines()
    assert "  vehicle 1 (v1): info: Mission: 42 WP" in tall  # its last three, when room


def test_a_reason_not_to_arm_is_no_alarm() -> None:
    mission, views = fly("missions/paper_example1.xml", 0.0)
    view, state = views[0]
    said = (AutopilotMessage(1, 2, "PreArm: Mode not armable"),
            AutopilotMessage(2, 2, "EKF failsafe"))
    text = render_text(mission, [(view, replace(state, messages=said))], 80)
    assert "info: PreArm: Mode not armable" in text and "critical: EKF failsafe" in text


def test_a_large_fleet_gets_a_line_a_vehicle() -> None:
    vehicles = [FakeVehicle(vehicle_id=i) for i in range(1, 7)]
    mission, views = fly("missions/fleet_compositions.xml", 20.0, vehicles)
    lines = _fits(render_text(mission, views, 80, 24), 80, 24)
    assert [line.split()[1] for line in lines if line.startswith("vehicle ")] \
        == ["1", "2", "3", "4", "5", "6"]
    assert not any(line.startswith("   n ") for line in lines)


def _change(time: float, task: str, state: TaskState, vid: int | None, number: int) -> Change:
    return Change(time, task, state, vid, number)


def test_a_fleet_prints_a_sub_tasks_end_before_its_tasks() -> None:
    # Both sorties end in the step that ends their round: each vehicle's view holds its own
    # sortie's change and the round's (a task no vehicle flies).
    _, _, views = _fleet_views()
    round_done = _change(90.0, "Shift/Round", TaskState.DONE, None, 12)
    north = _change(90.0, "Shift/Round/Sortie north", TaskState.DONE, 1, 10)
    south = _change(90.0, "Shift/Round/Sortie south", TaskState.DONE, 2, 11)
    (v1, s1), (v2, s2) = views
    ended = [(replace(v1, changes=(north, round_done)), s1),
             (replace(v2, changes=(south, round_done), role=""), s2)]
    out = io.StringIO()
    display = LineDisplay(Console(file=out, width=200, color_system=None))
    display.update([(replace(v1, changes=()), s1), (replace(v2, changes=()), s2)])
    display.update(ended)
    printed = [line for line in out.getvalue().splitlines() if line.startswith("[")]
    assert printed == ["[   90.0 s] vehicle 1 (v1): Shift/Round/Sortie north: done",
                       "[   90.0 s] vehicle 2 (v2): Shift/Round/Sortie south: done",
                       "[   90.0 s] Shift/Round: done"]  # its role kept once released


def test_why_nothing_moves_while_the_vehicle_boots() -> None:
    mission, views = fly("missions/paper_example1.xml", 0.0)
    state = replace(views[0][1], ready=False, armable=False, gps_fix=1,
                    prearm="PreArm: Need Position Estimate", battery=None)
    text = render_text(mission, [(views[0][0], state)], 80, 24)
    assert "vehicle 1: waiting for battery status, GPS fix, pre-arm checks, autopilot: " \
           "PreArm: Need…" in text or "vehicle 1: waiting for battery status, GPS fix" in text


HOSTILE = XML.replace(b'name="Show"', b'name="Show \xe2\x80\xae[bold]x\xc2\x9b"').replace(
    b'task name="Leg"', b'task name="Leg[/x]\xe2\x80\xaegel"')
ESCAPE = "\x1b]0;PWNED\x07"


def _hostile_views():
    mission, views = flown(6.0, HOSTILE)
    view, state = views[0]
    state = replace(state, mode=f"GUIDED{ESCAPE}", prearm=f"PreArm: {ESCAPE}",
                    messages=(AutopilotMessage(1, 2, f"EKF {ESCAPE} failsafe\u202e"),))
    return mission, [(view, state)]


def test_the_view_escapes_control_characters_and_bidi_overrides() -> None:
    mission, views = _hostile_views()
    text = render_text(mission, views, 200)
    for bad in ("\x1b", "\x07", "\u202e", "\x9b"):
        assert bad not in text
    assert "\\x1b]0;PWNED\\x07" in text and "\\u202e" in text
    assert "[/x]" in text and "[bold]" in text  # shown as written, not taken for markup


def test_the_line_display_escapes_what_it_prints() -> None:
    _, views = _hostile_views()
    out = io.StringIO()
    display = LineDisplay(Console(file=out, width=200, color_system=None))
    display.update(views)
    display.say(f"vehicle 1: switched to LAND{ESCAPE} [/oops]")
    printed = out.getvalue()
    for bad in ("\x1b", "\x07", "\u202e"):
        assert bad not in printed
    assert "Leg[/x]\\u202egel: running" in printed
    assert printed.endswith("vehicle 1: switched to LAND\\x1b]0;PWNED\\x07 [/oops]\n")


ROUNDS = b"""<mission name="Rounds">
  <task name="Take off"><action name="TAKE_OFF"><argument name="altitude" value="5"/></action>
  </task>
  <task name="Patrol"><repeat times="3"/>
    <task name="Out"><action name="GO_TO_POINT"><argument name="coordinates" value="(9, 0, 5)"/>
    </action></task>
    <task name="Back"><action name="GO_TO_POINT"><argument name="coordinates" value="(0, 0, 5)"/>
    </action></task>
  </task>
</mission>"""


def _in_round_two(vehicle: int = 1) -> list[Change]:
    """Take off; round 1 of Patrol (Out, Back), and round 2's Out begun and aborted."""
    steps = [("Take off", TaskState.RUNNING), ("Take off", TaskState.DONE),
             ("Patrol", TaskState.RUNNING), ("Patrol/Out", TaskState.RUNNING),
             ("Patrol/Out", TaskState.DONE), ("Patrol/Back", TaskState.RUNNING),
             ("Patrol/Back", TaskState.DONE), ("Patrol/Out", TaskState.RUNNING),
             ("Patrol/Out", TaskState.ABORTED), ("Patrol", TaskState.ABORTED)]
    return [Change(float(n), task, state, vehicle, n + 1) for n, (task, state) in enumerate(steps)]


def test_rounds_are_read_from_the_changes() -> None:
    found = rounds(_in_round_two(), {"Patrol"})
    assert found.now == {"Patrol": 2}
    assert found.earlier == {"Patrol/Back": 1}  # done in round 1, not yet run in round 2
    assert rounds(_in_round_two(), set()).now == {}  # a task run again, but no repeat
    # A task begun again begins its sub-tasks anew: the sub-tasks' states are from before.
    again = [*_in_round_two(), Change(20.0, "Patrol", TaskState.RUNNING, 1, 11)]
    assert rounds(again, {"Patrol"}).earlier == {"Patrol/Out": 0, "Patrol/Back": 0}


def test_rounds_are_counted_on_as_the_changes_grow() -> None:
    changes = _in_round_two()
    for end in range(1, len(changes) + 1):  # a redraw after each change: the new ones read
        grown = rounds(changes[:end], {"Patrol"})
        fresh = rounds([replace(c) for c in changes[:end]], {"Patrol"})  # read anew
        assert grown == fresh
    assert grown.now == {"Patrol": 2}


def test_two_vehicles_changes_that_begin_and_end_alike_are_counted_apart() -> None:
    # The fleet's changes (a task no vehicle flies) are in both views, the same objects.
    start, end = (Change(0.0, "Patrol", TaskState.RUNNING, None, 1),
                  Change(9.0, "Patrol", TaskState.DONE, None, 9))
    one = (start, *_in_round_two(1)[3:8], end)  # Out, Back and Out again: round 2
    two = (start, *_in_round_two(2)[3:7], Change(6.5, "Patrol/Back", TaskState.DONE, 2, 8),
           end)
    assert len(one) == len(two)
    assert rounds(one, {"Patrol"}, "1").now == {"Patrol": 2}
    assert rounds(two, {"Patrol"}, "2").now == {}  # vehicle 2 flew one round
    assert rounds(one, {"Patrol"}, "1").now == {"Patrol": 2}


def test_a_task_done_after_an_aborted_one_says_its_round() -> None:
    mission, views = flown(0.5, ROUNDS)
    view, state = views[0]
    changes = _in_round_two()
    states = {c.task: c.state for c in changes}
    shown = render_text(mission, [(replace(view, changes=tuple(changes), task_states=states,
                                           status=Status.ABORTED), state)], 80, 24)
    lines = shown.splitlines()
    assert lines[2] == "■ └─ Patrol  round 2 of 3"
    assert lines[3] == "■    ├─ Out  GO_TO_POINT"  # this round's
    assert lines[4] == "✓    └─ Back  GO_TO_POINT  (round 1)"


def test_a_task_an_event_holds_is_interrupted_not_running() -> None:
    mission, views = flown(1.0)  # the take-off runs
    view, state = views[0]
    held = replace(view, held=("Take off",), current_action="LAND",
                   events=((1.0, "Far"),))
    text = render_text(mission, [(held, state)], 80, 24)
    lines = text.splitlines()
    assert lines[1].startswith("‖ ├─ Take off  TAKE_OFF")
    assert "‖ interrupted" in text
    assert any(line.strip().endswith("LAND (event 'Far')") for line in lines)
    assert "LAND (Take off)" not in text


def test_events_none_once_the_mission_ended() -> None:
    mission, views = flown(0.5)
    view, state = views[0]
    assert "events: none yet" in render_text(mission, [(view, state)], 80, 24)
    ended = render_text(mission, [(replace(view, status=Status.COMPLETED), state)], 80, 24)
    assert "events: none" in ended.splitlines() and "none yet" not in ended


def test_after_the_end_the_tree_shows_the_levels_that_fit() -> None:
    mission = load_mission(ROOT / "missions/dolphin_fleet_relay.xml")
    assert [line.task.name for line in fold(mission.tasks, [], 1) if line.task] == ["Relay"]
    lines = fold(mission.tasks, [], 4)  # Relay, Round, the two sorties, folded
    assert [(line.task.name, line.folded) for line in lines if line.task] == [
        ("Relay", 0), ("Round", 0), ("Sortie north", 5), ("Sortie south", 5)]


def test_the_legend_fits_80_columns_and_explains_every_mark_shown() -> None:
    vehicle = FakeVehicle(capabilities=frozenset({"camera", "gripper", "flip"}))
    mission, views = fly("missions/catalogue_tour.xml", 120.0, [vehicle])
    lines = render_text(mission, views, 80, 24).splitlines()
    legend = next(line for line in lines if "(+n) folded" in line)
    assert len(legend) <= 80
    tree = "".join(lines[1:lines.index(legend)])
    for mark, word in (("·", "pending"), ("▶", "running"), ("✓", "done"), ("↷", "skipped")):
        assert mark in tree and f"{mark} {word}" in legend
    wide = render_text(mission, views, 100, 24).splitlines()  # room for every mark
    assert any("‖ interrupted  ✓ done" in line and "■ aborted" in line for line in wide)
