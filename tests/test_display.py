"""The terminal view, rendered to text."""

from __future__ import annotations

import io

from rich.console import Console

from tml.engine import Interpreter
from tml.language.validation import validate_file
from tml.run.display import LineDisplay, render_text
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
    assert any("✓ Take off" in line and "TAKE_OFF" in line for line in lines)
    assert any("▶ Leg" in line for line in lines)
    row = next(line for line in lines if line.lstrip().startswith("1 "))
    assert "running" in row and "GO_TO_POINT (Leg)" in row and "GUIDED" in row
    assert "%" in row and "ok" in row
    assert any("Far" in line for line in lines[lines.index(
        next(line for line in lines if line.startswith("events:"))):])


def test_view_before_anything_happened() -> None:
    mission = validate_file("show.xml", XML).mission
    interp = Interpreter(mission, [1])
    text = render_text(mission, [(interp.views()[1], None)])
    assert "· Take off" in text and "events: none yet" in text


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
