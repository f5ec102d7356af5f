"""Flight reports: a log read back, drawn, paged, and its tracks for map tools."""

from __future__ import annotations

import io
import json
from pathlib import Path

import gpxpy
import pytest
from fake_vehicle import FakeVehicle
from lxml import etree
from report_checks import boxes_apart, texts_fit

from tml.commands.cli import main
from tml.language.validation import load_mission
from tml.report.figures import figure, png
from tml.report.flight import read_flight
from tml.report.pages import page
from tml.report.scene import scene
from tml.report.tracks import gpx, kml
from tml.run.journal import Journal
from tml.run.runner import Runner

ROOT = Path(__file__).resolve().parent.parent
MISSION = "missions/paper_example1.xml"  # relative, as a user names it: the log keeps it


class Sim:
    def __init__(self, vehicle: FakeVehicle) -> None:
        self.vehicle = vehicle
        self.time = 0.0

    def clock(self) -> float:
        return self.time

    def wait(self, _timeout: float) -> None:
        self.time = round(self.time + 0.1, 6)
        self.vehicle.advance(0.1)
        if self.time == 2.0:
            self.vehicle.say(4, "Battery 1 is low")


@pytest.fixture
def log(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The flight log of the paper's Example 1 flown on a fake vehicle."""
    monkeypatch.chdir(ROOT)
    sim = Sim(FakeVehicle())
    path = tmp_path / "flight.jsonl"
    journal = Journal.open(str(path))
    Runner(load_mission(MISSION), [sim.vehicle], clock=sim.clock, wait=sim.wait,
           journal=journal).run()
    journal.close()
    return path


def test_the_flight_is_read_back_from_its_log(log: Path) -> None:
    flight = read_flight(str(log))
    assert flight.mission == "Mission example" and flight.mission_file == MISSION
    assert flight.exit_code == 0 and flight.outcome == "vehicle 1: completed (all tasks done)"
    (track,) = flight.tracks.values()
    assert max(s.up for s in track) == pytest.approx(10.0, abs=0.5)  # TAKE_OFF's default
    assert all(s.latitude is not None for s in track)
    assert [(s.task, s.state) for s in flight.tasks] == [
        ("Initial take off", "done"), ("Navigate avoiding obstacles", "done"),
        ("Navigate avoiding obstacles/Stabilize at origin", "done"),
        ("Navigate avoiding obstacles/Go to destination", "done"), ("Final landing", "done")]
    assert all(s.end is not None and s.end >= s.start for s in flight.tasks)
    assert [(m.kind, m.severity, m.text) for m in flight.marks] == [
        ("autopilot", "warning", "Battery 1 is low")]
    # The plan of the mission file the log names: home, up 10 m, (3, 4, 1.5), landed.
    (planned,) = flight.planned.values()
    assert planned[2] == pytest.approx((3.0, 4.0, 1.5), abs=0.01)


def test_the_picture_is_a_png_of_a_readable_size(log: Path) -> None:
    data = png(read_flight(str(log)))
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    assert width == 1300 and 900 <= height <= 1400


def test_the_page_embeds_the_picture_and_tables_of_tasks_and_events(log: Path) -> None:
    text = page(read_flight(str(log)))
    root = etree.fromstring(text.encode(), etree.HTMLParser())
    (image,) = root.iter("img")
    assert image.get("src").startswith("data:image/png;base64,iVBOR")
    tables = root.findall(".//table")
    tasks = [[c.text for c in row.findall("td")] for row in tables[0].findall("tr")[1:]]
    assert [row[0] for row in tasks][-1] == "Final landing" and tasks[-1][-1] == "done"
    events = [[c.text for c in row.findall("td")] for row in tables[1].findall("tr")[1:]]
    assert events[0][3:] == ["autopilot (warning)", "Battery 1 is low"]
    assert events[0][1].count(":") == 2  # its wall-clock time, 12:34:56.789
    assert "http" not in text.replace("http://", "")  # nothing fetched: it opens offline


def test_tracks_for_map_tools_follow_the_log(log: Path) -> None:
    flight = read_flight(str(log))
    lines = [json.loads(line) for line in log.read_text().splitlines()]
    telemetry = [line for line in lines if line["kind"] == "telemetry" and line["global"]]
    parsed = gpxpy.parse(io.StringIO(gpx(flight)))
    (track,) = parsed.tracks
    points = track.segments[0].points
    assert len(points) == len(telemetry)
    assert (points[3].latitude, points[3].longitude, points[3].elevation) == pytest.approx(
        tuple(telemetry[3]["global"]))
    assert (points[4].time - points[3].time).total_seconds() == pytest.approx(
        telemetry[4]["t"] - telemetry[3]["t"])
    root = etree.fromstring(kml(flight).encode())
    (coordinates,) = root.iter("{http://www.opengis.net/kml/2.2}coordinates")
    assert len((coordinates.text or "").split()) == len(telemetry)


def test_report_command_writes_each_format(log: Path, tmp_path: Path, capsys) -> None:
    for form in ("html", "png", "gpx", "kml"):
        assert main(["report", str(log), "-o", str(tmp_path / f"r.{form}")]) == 0
        assert (tmp_path / f"r.{form}").stat().st_size > 0
    assert main(["report", str(log)]) == 0  # html beside the log
    assert log.with_suffix(".html").is_file()
    assert "tml report: " in capsys.readouterr().out


@pytest.mark.parametrize("content, code, message", [
    (None, 2, "No such file or directory"),
    ("not json\n", 1, "flight.jsonl:1: not a JSON line"),
    ('{"a": 1}\n', 1, "not a flight log line"),
    ("", 1, "no run in this log"),
])
def test_report_of_what_is_no_log_says_why(tmp_path: Path, capsys, content: str | None,
                                           code: int, message: str) -> None:
    path = tmp_path / "flight.jsonl"
    if content is not None:
        path.write_text(content)
    assert main(["report", str(path)]) == code
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_report_output_errors_exit_2(log: Path, capsys) -> None:
    assert main(["report", str(log), "-o", "report.pdf"]) == 2
    assert "-o report.pdf: say --format html|png|gpx|kml" in capsys.readouterr().err
    assert main(["report", str(log), "-o", "/nonexistent/dir/r.png"]) == 2
    assert "cannot write" in capsys.readouterr().err



def _log(tmp_path: Path, lines: list[dict]) -> Path:
    path = tmp_path / "flight.jsonl"
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def _telemetry(t: float, vehicle: int, up: float, armed: bool, **more) -> dict:
    return {"t": t, "kind": "telemetry", "vehicle": vehicle, "position": [0.0, 0.0, up],
            "battery": 90.0, "mode": "GUIDED", "armed": armed, **more}


def _task(t: float, task: str, state: str, vehicle: int | None = None) -> dict:
    line = {"t": t, "kind": "task", "task": task, "state": state}
    return {**line, "vehicle": vehicle} if vehicle is not None else line


def test_times_are_mission_time_from_the_first_task_not_the_run(tmp_path: Path) -> None:
    # The run waits 40 s for its vehicle to be ready: the report counts from the mission.
    path = _log(tmp_path, [
        {"t": 2.0, "kind": "run", "mission": "m", "file": "", "mission_time": None},
        {"t": 3.0, "kind": "autopilot", "vehicle": 1, "severity": "info", "text": "Ready",
         "mission_time": None},
        {"t": 42.0, "kind": "mission", "vehicle": 1, "message": "mission 'm' started",
         "mission_time": 0.0},
        {**_task(42.0, "A", "running", 1), "mission_time": 0.0},
        {**_telemetry(43.0, 1, 5.0, True), "mission_time": 1.0},
        {**_task(52.0, "A", "done", 1), "mission_time": 10.0},
        {**_telemetry(53.0, 1, 0.0, False), "mission_time": 11.0},
    ])
    flight = read_flight(str(path))
    assert (flight.start, flight.mission_start, flight.origin) == (2.0, 42.0, 42.0)
    drawn = figure(flight)
    timeline = drawn.axes[-1]
    assert timeline.get_xlabel() == "mission time (s): since the first task started"
    left, right = timeline.get_xlim()
    assert -1.0 < left <= 0.0 and 11.0 <= right < 12.0
    assert drawn.axes[1].get_xlim() == (left, right)  # altitude on the same time base
    root = etree.fromstring(page(flight).encode(), etree.HTMLParser())
    tasks, marks = ([[c.text for c in row.findall("td")] for row in table.findall("tr")[1:]]
                    for table in root.findall(".//table"))
    assert tasks == [["A", None, "1", "0.0", "10.0", "10.0", "done"]]
    assert marks[0][0] == "-39.0"  # said before the mission started: negative


def test_a_log_without_mission_time_counts_from_its_mission_line(tmp_path: Path) -> None:
    path = _log(tmp_path, [{"t": 2.0, "kind": "run", "mission": "m", "file": ""},
                           {"t": 30.0, "kind": "mission", "vehicle": 1, "elapsed": 100.0},
                           _task(31.0, "A", "running", 1)])
    assert read_flight(str(path)).origin == -70.0  # resumed after 100 s of mission
    path = _log(tmp_path, [{"t": 2.0, "kind": "run", "mission": "m", "file": ""},
                           _telemetry(3.0, 1, 0.0, False)])
    flight = read_flight(str(path))  # the mission never started: the run's time
    assert flight.origin == 2.0 and flight.time_label == "time since the run started (s)"


def test_a_fleets_tasks_keep_tree_order_on_the_timeline(tmp_path: Path) -> None:
    # Both sorties start side by side; vehicle 1's take-off starts after vehicle 2's
    # sortie: by start it would sit under vehicle 2's.
    path = _log(tmp_path, [
        {"t": 0.0, "kind": "run", "mission": "m", "file": ""},
        _task(0.0, "Round", "running"),
        _task(0.0, "Round/North", "running", 1),
        _task(0.0, "Round/South", "running", 2),
        _task(1.1, "Round/North/Take off", "running", 1),
        _task(1.3, "Round/South/Take off", "running", 2),
        _task(9.0, "Round/North/Take off", "done", 1),
        _task(9.5, "Round/South/Take off", "done", 2),
        _task(9.0, "Round/North", "done", 1),
        _task(9.5, "Round/South", "done", 2),
        _task(9.5, "Round", "done"),
        _task(10.0, "Round", "running"),  # a second round: its own sorties under it
        _task(10.0, "Round/North", "running", 1),
        _task(12.0, "Round/North", "done", 1),
        _task(12.0, "Round", "done"),
    ])
    flight = read_flight(str(path))
    assert [(s.task, s.vehicle, s.start) for s in flight.tasks] == [
        ("Round", None, 0.0), ("Round/North", 1, 0.0), ("Round/North/Take off", 1, 1.1),
        ("Round/South", 2, 0.0), ("Round/South/Take off", 2, 1.3),
        ("Round", None, 10.0), ("Round/North", 1, 10.0)]
    labels = [t.get_text() for t in figure(flight).axes[-1].get_yticklabels()]
    assert labels[1:3] == ["· North [v1]", "· · Take off [v1]"]


def test_a_reason_not_to_arm_after_landing_is_no_warning(tmp_path: Path) -> None:
    path = _log(tmp_path, [
        {"t": 0.0, "kind": "run", "mission": "m", "file": ""},
        _telemetry(1.0, 1, 5.0, True),
        {"t": 2.0, "kind": "autopilot", "vehicle": 1, "severity": "info",
         "text": "Disarming motors"},
        {"t": 2.05, "kind": "autopilot", "vehicle": 1, "severity": "critical", "level": 2,
         "text": "PreArm: Mode not armable"},
        {"t": 6.0, "kind": "autopilot", "vehicle": 1, "severity": "critical",
         "text": "EKF failsafe"},
    ])
    flight = read_flight(str(path))
    assert [(m.t, m.severity, m.said) for m in flight.marks] == [
        (2.0, "info", ""), (2.05, "info", "critical"), (6.0, "critical", "")]
    root = etree.fromstring(page(flight).encode(), etree.HTMLParser())
    marks = [[c.text for c in row.findall("td")]
             for row in root.findall(".//table")[1].findall("tr")[1:]]
    assert marks[1][3] == "autopilot (info, said critical)"
    warnings = [line for line in figure(flight).axes[-1].get_lines()
                if line.get_linestyle() == ":"]
    assert len(warnings) == 1  # the EKF failsafe only


def test_gpx_times_are_when_it_flew_at_the_vehicles_pace(tmp_path: Path) -> None:
    where = {"global": [-35.0, 149.0, 600.0]}
    path = _log(tmp_path, [
        {"t": 0.0, "kind": "run", "mission": "m", "file": ""},
        _telemetry(10.0, 1, 5.0, True, wall="2026-05-01T14:00:00.000+02:00", **where),
        _telemetry(30.0, 1, 5.0, True, wall="2026-05-01T14:00:01.000+02:00", **where),
    ])
    (track,) = gpxpy.parse(io.StringIO(gpx(read_flight(str(path))))).tracks
    first, second = track.segments[0].points
    assert first.time.isoformat() == "2026-05-01T12:00:00+00:00"
    assert (second.time - first.time).total_seconds() == 20.0  # the vehicle's 20 s


def test_event_labels_never_overlap(tmp_path: Path) -> None:
    # Ten events half a second apart, one fired on two vehicles at once, one at the end.
    lines = [{"t": 0.0, "kind": "run", "mission": "m", "file": ""},
             _task(0.0, "Patrol", "running", 1), _task(0.0, "Patrol", "running", 2),
             _telemetry(0.0, 1, 0.0, True), _telemetry(100.0, 1, 0.0, True)]
    lines += [{"t": 10.0 + k / 2, "kind": "event", "vehicle": 1,
               "event": f"Obstacle number {k} ahead"} for k in range(10)]
    lines += [{"t": 50.0, "kind": "event", "vehicle": v, "event": "Low battery"}
              for v in (2, 1)]
    lines += [{"t": 99.9, "kind": "event", "vehicle": 1, "event": "Geofence breached"},
              _task(100.0, "Patrol", "done", 1), _task(100.0, "Patrol", "done", 2)]
    flight = read_flight(str(_log(tmp_path, lines)))
    drawn = scene(flight)
    boxes_apart(drawn)
    assert {label.lane for label in drawn.labels} == {0, 1, 2}  # at most three lanes
    assert len(drawn.labels) + drawn.labels_left_out == 12  # the two at 50 s are one
    said = {label.text: label for label in drawn.labels}
    assert "Low battery (vehicles 1, 2)" in said
    assert said["Geofence breached"].right  # at the right edge: it ends at its event
    assert said["Geofence breached"].box[1] == pytest.approx(99.9)
    texts_fit(figure(flight, drawn))
    title = figure(flight, drawn).axes[-1].get_title(loc="left")
    assert f"{drawn.labels_left_out} event label(s) left out" in title


def test_a_log_without_positions_on_the_globe_keeps_each_vehicle_from_its_home(
        tmp_path: Path) -> None:
    path = _log(tmp_path, [{"t": 0.0, "kind": "run", "mission": "m", "file": ""},
                           _telemetry(1.0, 2, 5.0, True), _telemetry(1.0, 1, 5.0, True)])
    drawn = scene(read_flight(str(path)))
    assert not drawn.frame.shared and drawn.vehicles == (1, 2)
    assert [track.vehicle for track in drawn.tracks] == [1, 2]
    assert figure(read_flight(str(path))).axes[0].get_xlabel() == \
        "east (m from each vehicle's own home)"


def test_an_event_handlers_actions_are_rows_with_their_event(tmp_path: Path) -> None:
    name = "Battery below 30 % on the way back from the far field"
    path = _log(tmp_path, [
        {"t": 0.0, "kind": "run", "mission": "m", "file": ""},
        _task(0.0, "Leg", "running", 1),
        {"t": 5.0, "kind": "event", "vehicle": 1, "event": name},
        {"t": 5.0, "kind": "action", "vehicle": 1, "action": "MEMORIZE_POINT", "line": 9,
         "message": f"MEMORIZE_POINT (event {name!r})"},  # at once: no row
        {"t": 5.0, "kind": "action", "vehicle": 1, "action": "RETURN_HOME_AND_LAND",
         "task": None, "message": "RETURN_HOME_AND_LAND started", "arguments": {}},
        {"t": 5.0, "kind": "task", "vehicle": 1, "task": "Leg", "state": "aborted"},
        {"t": 30.0, "kind": "action", "vehicle": 1, "action": "RETURN_HOME_AND_LAND",
         "task": None, "message": "RETURN_HOME_AND_LAND failed: timeout: no landing",
         "reason": "timeout"},
    ])
    rows = scene(read_flight(str(path))).rows
    assert [(r.task, r.event == name, r.start, r.end, r.state) for r in rows] == [
        ("Leg", False, 0.0, 5.0, "aborted"),
        ("RETURN_HOME_AND_LAND", True, 5.0, 30.0, "failed")]
    assert rows[1].label == "event 'Battery below 30 % on…': RETURN_HOME_AND_LAND"
    assert len(rows[1].label) == 52
