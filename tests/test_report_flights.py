"""Reports and the live view of real flights on the simulator: the four-vehicle relay of the
README (``missions/dolphin_fleet_relay.xml``), ``missions/battery_event.xml`` on one vehicle
and on two, and the missions that take photos and see things. Each flight is ``tml run``
with the live view on an 80x24 terminal; the report is tested on its data
(:mod:`tml.report.scene`: one frame, the rows, the labels, the markers), on the page's
tables and on the boxes of the picture's texts as matplotlib draws them, never on pixels.

Run as a script, ``python tests/test_report_flights.py`` flies the relay and battery_event
again and rewrites ``test-artifacts/reports/``: the relay's report (PNG and HTML) and the
live view's last screen of both flights at 80x24 (test-artifacts/reports/README.md says
what each shows).
"""

from __future__ import annotations

import itertools
import math
import sys
from pathlib import Path

import pytest
from lxml import etree
from report_checks import boxes_apart, texts_fit
from shared_flights import FAST, FLEET, Flight, flown, fly

from tml.report.figures import figure, png
from tml.report.flight import read_flight
from tml.report.pages import page
from tml.report.scene import TITLE_CHARS, scene

# A guard against a hang, not a time limit: a flight in lock-step with the simulator is
# slower, never different, on a busy machine.
pytestmark = pytest.mark.timeout(900)

ROOT = Path(__file__).resolve().parent.parent
ARTIFACTS = ROOT / "test-artifacts" / "reports"
RELAY = ["--vehicles", "4", *FLEET]
"""The README's relay: two vehicles survey while the two others recharge (the flight
tests/test_flights.py and tests/test_fleet_flights.py check too: flown once for all)."""
LOW = ["--sim-battery", "40", "--link-lost-limit", "60"]
"""The README's battery_event: 40 % at the start, below 30 % in the second round."""


@pytest.fixture(scope="module")
def relay(tmp_path_factory: pytest.TempPathFactory) -> Flight:
    return flown(tmp_path_factory, "dolphin_fleet_relay", RELAY)


@pytest.fixture(scope="module")
def battery(tmp_path_factory: pytest.TempPathFactory) -> Flight:
    return flown(tmp_path_factory, "battery_event", LOW)


@pytest.fixture(scope="module")
def battery_pair(tmp_path_factory: pytest.TempPathFactory) -> Flight:
    return flown(tmp_path_factory, "battery_event", [*LOW, "--vehicles", "2"])


def table(text: str, number: int) -> list[list[str]]:
    """The cells of the page's table ``number`` (0: the tasks), row by row."""
    root = etree.fromstring(text.encode(), etree.HTMLParser())
    found = root.findall(".//table")[number]
    return [["".join(c.itertext()) for c in row.findall("td")] for row in found.findall("tr")[1:]]


def test_relay_report_draws_the_fleet_in_one_frame_vehicles_in_order(relay: Flight) -> None:
    assert relay.code == 0
    flight = read_flight(str(relay.log))
    drawn = scene(flight)
    assert drawn.vehicles == (1, 2, 3, 4)
    assert [track.vehicle for track in drawn.tracks] == [1, 2, 3, 4]
    # One frame, from vehicle 1's home; each vehicle's own home where it is in it.
    frame = drawn.frame
    assert frame.shared and frame.origin_vehicle == 1 and frame.homes[1] == (0.0, 0.0)
    homes = [frame.homes[v] for v in (1, 2, 3, 4)]
    for a, b in itertools.combinations(homes, 2):
        assert math.dist(a, b) > 3.0  # four pads apart, not one point
    for track in drawn.tracks:
        assert math.dist(track.points[0], frame.homes[track.vehicle]) < 0.5
    # Vehicles 1 and 3 flew role v1 from their own pads: the same pattern, shifted.
    one, three = drawn.tracks[0].points, drawn.tracks[2].points
    assert max(n for n, _ in one) == pytest.approx(max(n for n, _ in three), abs=1.0)
    assert min(e for _, e in three) == pytest.approx(homes[2][1], abs=1.0)
    planned = {(line.role, line.vehicle): line.points[0] for line in drawn.planned}
    assert sorted(planned) == [("v1", 1), ("v1", 3), ("v2", 2), ("v2", 4)]
    for (_, vehicle), start in planned.items():
        assert math.dist(start, frame.homes[vehicle]) < 0.5  # drawn from its own home
    # Round by round, each round's sorties vehicle by vehicle.
    sorties = [(r.task.rsplit("/", 1)[-1], r.vehicle) for r in drawn.rows
               if r.task.endswith(("Sortie north", "Sortie south"))]
    assert sorties == [("Sortie north", 1), ("Sortie south", 2), ("Sortie north", 3),
                       ("Sortie south", 4), ("Sortie north", 1), ("Sortie south", 2)]
    assert [r.round for r in drawn.rows if r.task == "Relay/Round"] == [1, 2, 3]
    assert drawn.title == ("Survey relay — vehicles 1, 2, 3, 4: completed (all tasks done)",)
    assert all(len(line) <= TITLE_CHARS for line in drawn.title)
    texts_fit(figure(flight, drawn))
    tasks = table(page(flight), 0)
    assert len(tasks) == len(drawn.rows)
    assert [row[1] for row in tasks if row[0] == "Relay/Round"] == ["round 1", "round 2",
                                                                    "round 3"]


def test_relay_live_view_ends_saying_what_happened(relay: Flight) -> None:
    text = relay.last
    lines = text.splitlines()
    assert len(lines) <= 23  # one line spare under the view
    assert lines[0].startswith("Survey relay  mission time ")
    assert lines[1] == " 1 2 3 4  vehicle"
    # Nothing is flown any more: the tree shows as many levels as fit, not one line.
    assert lines[2].startswith(" ✓ ✓ ✓ ✓ └─ Relay  round 3")
    # Vehicles 3 and 4 flew the sorties the round before: their marks say so.
    assert " ✓ · ✓ ·       ├─ Sortie north  (earlier round: 3)  (+5)" in lines
    assert " · ✓ · ✓       └─ Sortie south  (earlier round: 4)  (+5)" in lines
    assert "events: none" in lines and "events: none yet" not in text
    assert lines[-1] == "ended: vehicles 1, 2, 3, 4: all tasks done"
    assert "critical" not in text  # ArduCopter's PreArm after landing is no alarm
    assert all(len(line) <= 80 for line in lines)


def test_battery_event_report_shows_the_handler_and_the_rounds(battery: Flight) -> None:
    assert battery.code == 3
    flight = read_flight(str(battery.log))
    drawn = scene(flight)
    (fired,) = [m.t - flight.origin for m in flight.marks if m.kind == "event"]
    rows = [(r.task.rsplit("/", 1)[-1], r.round, r.state) for r in drawn.rows]
    # The second round explains a corner done after the aborted one: each row says its round.
    assert rows == [
        ("Take off", 0, "done"), ("Patrol the square", 0, "aborted"),
        ("North-west corner", 1, "done"), ("North-east corner", 1, "done"),
        ("South-east corner", 1, "done"), ("South-west corner", 1, "done"),
        ("North-west corner", 2, "done"), ("North-east corner", 2, "done"),
        ("South-east corner", 2, "aborted"), ("LAND", 0, "done")]
    cut, handler = drawn.rows[-2], drawn.rows[-1]
    assert cut.end == pytest.approx(fired) and cut.when == "round 2 of 5"
    # The event's landing: on the timeline and in the table, from the event to touchdown.
    assert handler.event == "Low battery" and handler.start == pytest.approx(fired)
    assert handler.end is not None and handler.end > fired + 10
    assert handler.label == "event 'Low battery': LAND"
    (label,) = drawn.labels
    assert label.text == "Low battery" and label.t == pytest.approx(fired, abs=0.05)
    boxes_apart(drawn)
    texts_fit(figure(flight, drawn))
    tasks = table(page(flight), 0)
    assert tasks[-1][0] == "event 'Low battery': LAND" and tasks[-1][-1] == "done"
    assert float(tasks[-1][3]) == pytest.approx(fired, abs=0.05)
    assert [row[1] for row in tasks][2:9] == ["round 1 of 5"] * 4 + ["round 2 of 5"] * 3


def test_battery_event_live_view_interrupted_then_aborted(battery: Flight) -> None:
    # While the event's landing flies, the corner it cut is interrupted, not running.
    during = battery.held
    assert during is not None
    assert "‖ │  ├─ South-east corner  GO_TO_POINT" in during
    assert "‖ ├─ Patrol the square  round 2 of 5" in during
    assert "LAND (event 'Low battery')" in during
    assert not [line for line in during.splitlines() if line.startswith("▶")]
    text = battery.last
    lines = text.splitlines()
    assert "■ │  ├─ South-east corner  GO_TO_POINT" in lines
    assert "■ ├─ Patrol the square  round 2 of 5" in lines
    # Done after the aborted corner: last round's, and it says so.
    assert "✓ │  └─ South-west corner  GO_TO_POINT  (round 1)" in lines
    assert not [line for line in lines if line.startswith("▶")]
    events = lines.index("events: ")
    assert "Low battery" in lines[events + 1]
    assert lines[-1] == "ended: event 'Low battery' aborted the mission"
    assert "critical" not in text


def test_two_vehicles_on_one_event_apart_in_order_one_label(battery_pair: Flight) -> None:
    flight = read_flight(str(battery_pair.log))
    drawn = scene(flight)
    one, two = (track.points for track in drawn.tracks)
    east = drawn.frame.homes[2][1] - drawn.frame.homes[1][1]
    assert east > 3.0  # not drawn over each other: vehicle 2 flew its square from its pad
    assert max(e for _, e in two) - max(e for _, e in one) == pytest.approx(east, abs=1.0)
    assert [r.vehicle for r in drawn.rows if r.task == "Take off"] == [1, 2]
    assert [r.vehicle for r in drawn.rows if r.task == "Patrol the square"] == [1, 2]
    assert [r.vehicle for r in drawn.rows if r.event] == [1, 2]
    (label,) = drawn.labels  # one event on both at once: one label naming both
    assert label.text == "Low battery (vehicles 1, 2)"
    assert drawn.title[0].startswith(
        "Patrol with a battery event — vehicles 1, 2: aborted (event 'Low battery'")
    texts_fit(figure(flight, drawn))


@pytest.mark.parametrize("name, kind, count", [
    ("jump_and_repeat", "photo", 3),  # CAPTURE_PHOTO of an event handler, three times
    ("mission_dispatch", "photo", 3),  # START_CAPTURING and two photo tasks of a plan
    ("imav2016", "detection", 3),  # the buckets and items the companion recognises
])
def test_photos_and_detections_are_marked_where_they_were(
        tmp_path_factory: pytest.TempPathFactory, name: str, kind: str, count: int) -> None:
    flew = flown(tmp_path_factory, name, [])  # as tests/test_flights.py flies it
    assert flew.code == 0
    flight = read_flight(str(flew.log))
    drawn = scene(flight)
    found = [m for m in drawn.markers if m.kind == kind]
    assert len(found) == count
    (track,) = flight.tracks.values()
    for marker in found:
        at = [s for s in track if s.t - flight.origin <= marker.t + 1e-6][-1]
        assert (marker.north, marker.east) == pytest.approx((at.north, at.east), abs=0.05)
    legend = figure(flight, drawn).axes[0].get_legend()
    assert f"{kind} ({count})" in [t.get_text() for t in legend.get_texts()]
    assert len(table(page(flight), 1)) == count  # the table of photos and detections


def write_artifacts(folder: Path = ARTIFACTS) -> None:
    """Fly the relay and battery_event and write their reports and last screens."""
    import tempfile

    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as work:
        relay = fly(Path(work), "dolphin_fleet_relay", [*FAST, *RELAY])
        battery = fly(Path(work), "battery_event", [*FAST, *LOW])
        flight = read_flight(str(relay.log))
        (folder / "relay_report.png").write_bytes(png(flight))
        (folder / "relay_report.html").write_text(page(flight), encoding="utf-8")
        (folder / "battery_event_report.png").write_bytes(png(read_flight(str(battery.log))))
        for name, flown in (("relay", relay), ("battery_event", battery)):
            (folder / f"{name}_live_80x24.txt").write_text(flown.last,
                                                           encoding="utf-8")


if __name__ == "__main__":
    sys.exit(write_artifacts())
