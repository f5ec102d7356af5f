"""The terminal view, rendered to text."""

from __future__ import annotations

import io
from dataclasses import replace
from pathlib import Path

import pytest
from rich.console import Console

from tml.engine import Interpreter
from tml.language.validation import load_mission, validate_file
from tml.run.display import LineDisplay, render_text
from tml.run.fold import fold
from tml.vehicle import FakeVehicle

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
    assert lines[0].startswith("Show  t = 6.0 s")
    assert any("✓ ├─ Take off" in line and "TAKE_OFF" in line for line in lines)
    assert any("▶ └─ Leg" in line for line in lines)
    row = next(line for line in lines if line.lstrip().startswith("1 "))
    assert "running" in row and "GO_TO_POINT (Leg)" in row and "GUIDED" in row
    assert "%" in row and "ok" in row
    assert any("Far" in line for line in lines[lines.index(
        next(line for line in lines if line.startswith("events:"))):])


def test_view_before_anything_happened() -> None:
    mission = validate_file("show.xml", XML).mission
    interp = Interpreter(mission, [1])
    text = render_text(mission, [(interp.views()[1], None)])
    assert "· ├─ Take off" in text and "events: none yet" in text


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
    assert any(line.startswith("1 ") and "GUIDED" in line for line in lines)  # telemetry
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
    header = lines[2]
    assert header.startswith(" 1 2 3") and "vehicle" in header
    assert lines[1] == f"mission {mission.name!r}"
    table = next(i for i, line in enumerate(lines) if line.startswith("role"))
    assert [line.split()[1] for line in lines[table + 1:table + 4]] == ["1", "2", "3"]


def test_a_plan_flown_by_the_autopilot_shows_its_item() -> None:
    mission, views = fly("missions/mission_dispatch.xml", 6.0)
    text = render_text(mission, views, 80, 24)
    assert "[autopilot mission]" in text
    row = next(line for line in text.splitlines() if line.startswith("1 "))
    index = views[0][1].mission.action_index + 1
    assert f"item {index}/13 " in row


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
    from tml.vehicle import AutopilotMessage

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
