"""Flight reports: a log read back, drawn, paged, and its tracks for map tools."""

from __future__ import annotations

import io
import json
from pathlib import Path

import gpxpy
import pytest
from lxml import etree

from tml.commands.cli import main
from tml.language.validation import load_mission
from tml.report.figures import png
from tml.report.flight import read_flight
from tml.report.pages import page
from tml.report.tracks import gpx, kml
from tml.run.journal import Journal
from tml.run.runner import Runner
from tml.vehicle import FakeVehicle

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
    assert events[0][2:] == ["autopilot (warning)", "Battery 1 is low"]
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

