"""The flight log's typed records and schema (tml.engine.flightlog), its one reader
(tml.run.journal.read_log) and its one fold (tml.engine.resume.Fold), on logs written by
tml before the schema was versioned (tests/data/flightlogs, README.md there)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from sitl.server import Simulator
from tml.commands.cli import main
from tml.engine import flightlog
from tml.engine.resume import Fold, progress
from tml.language.validation import validate_file
from tml.run.journal import LogUnreadable, read, read_log
from tml.serve.live import TaskBoard

ROOT = Path(__file__).resolve().parent.parent
KEPT = Path(__file__).parent / "data" / "flightlogs"
LOGS = sorted(KEPT.glob("*.jsonl"))


def test_the_published_schema_is_the_record_classes() -> None:
    assert flightlog.SCHEMA_FILE.read_text() == flightlog.schema_text(), \
        "regenerate: python -c 'from tml.engine import flightlog as f; " \
        "f.SCHEMA_FILE.write_text(f.schema_text())'"
    jsonschema.Draft202012Validator.check_schema(flightlog.json_schema())


@pytest.mark.parametrize("log", LOGS, ids=lambda p: p.name)
def test_logs_of_version_1_follow_the_schema(log: Path) -> None:
    validator = jsonschema.Draft202012Validator(json.loads(flightlog.SCHEMA_FILE.read_text()))
    lines = read(str(log))
    assert read_log(str(log)).version == 1
    for number, line in enumerate(lines, 1):
        assert flightlog.problems(line) == [], f"{log.name}:{number}"
        assert not list(validator.iter_errors(line)), f"{log.name}:{number}"


@pytest.mark.parametrize("line, said", [
    ({"t": 1.0, "kind": "task", "task": "Up"}, "task line without 'state'"),
    ({"t": 1.0, "kind": "task", "task": "Up", "state": "done", "vehicle": "1"},
     "'vehicle' is '1'"),
    ({"t": 1.0, "kind": "gossip"}, "kind 'gossip' is not a kind of line"),
    ({"t": "soon", "kind": "run"}, "'t' is 'soon'"),
    ({"t": 1.0, "kind": "telemetry", "battery": "full"}, "'battery' is 'full'"),
])
def test_a_line_that_breaks_the_schema_is_told_and_the_schema_agrees(
        line: dict[str, Any], said: str) -> None:
    validator = jsonschema.Draft202012Validator(flightlog.json_schema())
    assert any(said in problem for problem in flightlog.problems(line))
    assert list(validator.iter_errors(line))


def test_records_are_typed_and_keep_the_fields_their_class_does_not_declare() -> None:
    lines = read(str(KEPT / "service_pause_jump.jsonl"))
    records = [flightlog.parse(line) for line in lines]
    tasks = [r for r in records if isinstance(r, flightlog.TaskLine)]
    assert tasks and all(isinstance(r.task, str) and r.state for r in tasks)
    controls = [r for r in records if isinstance(r, flightlog.ControlLine)]
    assert [(c.control, c.task) for c in controls] == [("pause", None), ("resume", None),
                                                       ("jump", "Again")]
    goto = next(r for r in records if isinstance(r, flightlog.RequestLine)
                and r.message == "GoTo")
    assert flightlog.get(goto, "target") == goto.extra["target"]
    sample = next(r for r in records if isinstance(r, flightlog.TelemetryLine))
    assert flightlog.get(sample, "global") == sample.global_ is not None


def test_the_run_line_of_a_new_log_says_its_version(tmp_path: Path) -> None:
    log = tmp_path / "hop.jsonl"
    assert main(["run", str(KEPT / "hop.xml"), "--sim", "-q", "--sim-fast-boot",
                 "--speedup", "40", "--log", str(log)]) == 0
    found = read_log(str(log))
    assert found.version == flightlog.VERSION == found.lines[0]["log_version"]
    assert all(flightlog.problems(line) == [] for line in found.lines)


def later_version(tmp_path: Path) -> Path:
    lines = (KEPT / "hop_resumed.jsonl").read_text().splitlines()
    first = json.loads(lines[0])
    first["log_version"] = flightlog.VERSION + 1
    log = tmp_path / "later.jsonl"
    log.write_text("\n".join([json.dumps(first), *lines[1:]]) + "\n")
    return log


@pytest.mark.foreign_logs
def test_a_log_of_a_later_version_is_refused_with_the_reason(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = later_version(tmp_path)
    said = f"later.jsonl: a flight log of version {flightlog.VERSION + 1}, written by a " \
           f"later tml; this one reads versions 1 to {flightlog.VERSION}"
    with pytest.raises(LogUnreadable, match=said):
        read_log(str(log))
    assert main(["report", str(log), "-o", str(tmp_path / "r.html")]) == 1
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err
    assert main(["run", str(KEPT / "hop.xml"), "--connect", "tcp:127.0.0.1:5790",
                 "--resume", str(log)]) == 2
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err


def test_the_reader_leaves_out_a_cut_last_line_and_refuses_the_rest(tmp_path: Path) -> None:
    text = (KEPT / "hop_interrupted.jsonl").read_text()
    log = tmp_path / "cut.jsonl"
    log.write_text(text + '{"t": 9.5, "kind": "telem')
    found = read_log(str(log))
    assert found.cut and len(found.lines) == len(text.splitlines())
    log.write_text(text.replace("\n", "\n{oops\n", 1))
    with pytest.raises(LogUnreadable, match=r"cut.jsonl:2: not a JSON line"):
        read_log(str(log))
    log.write_text('["a list"]\n' + text)
    with pytest.raises(LogUnreadable, match=r"cut.jsonl:1: not a flight log line \(no 't' "
                                            r"and 'kind'\): not a tml flight log"):
        read_log(str(log))
    with pytest.raises(LogUnreadable, match=r"larger than 100 bytes, not read"):
        read_log(str(KEPT / "hop_interrupted.jsonl"), max_bytes=100)


@pytest.mark.parametrize("log", LOGS, ids=lambda p: p.name)
def test_logs_of_version_1_still_report(log: Path, tmp_path: Path) -> None:
    # The mission file the log names is where it flew from (another checkout, perhaps
    # gone): the report is drawn with its planned path or without.
    for form in ("html", "gpx"):
        assert main(["report", str(log), "-o", str(tmp_path / f"r.{form}")]) == 0
        assert (tmp_path / f"r.{form}").stat().st_size > 0


def test_an_interrupted_log_of_version_1_still_resumes(tmp_path: Path) -> None:
    lines = (KEPT / "hop_interrupted.jsonl").read_text().splitlines()
    mission = tmp_path / "hop.xml"
    shutil.copy(KEPT / "hop.xml", mission)
    with Simulator(tcp_base_port=0, speedup=10,
                   params={"SIM_GPS_LOCKTIME": 0.5, "SIM_EKF_GPS_TIME": 1}) as sim:
        address = f"tcp:127.0.0.1:{sim.tcp_ports[0]}"
        first = json.loads(lines[0])
        first["connect"] = [address]  # the vehicle is here now (the same SHA-256 flies)
        log = tmp_path / "hop.jsonl"
        log.write_text("\n".join([json.dumps(first, separators=(",", ":")), *lines[1:]])
                       + "\n")
        assert main(["run", str(mission), "--connect", address, "--clock", "vehicle", "-q",
                     "--resume", str(log)]) == 0
    found = read_log(str(log))
    resumed = [line for line in found.lines if line["kind"] == "run"]
    assert [r["message"] for r in resumed] == ["run started", "run resumed", "run ended"]
    assert resumed[1]["log_version"] == flightlog.VERSION
    ends = [(line["task"], line["state"]) for line in found.lines
            if line["kind"] == "task" and line["state"] != "running"]
    assert ends == [("Up", "done"), ("Over", "done"), ("Back", "done"), ("Down", "done")]


def expected_board(lines: list[dict[str, Any]], paths: list[str]) -> dict[str, str]:
    """Vehicle 1's board as a resumed run would fly on from here."""
    stood = progress(lines, 1)
    return {p: stood.ended[p].value if p in stood.ended
            else "running" if p in stood.running else "pending" for p in paths}


def test_the_services_board_and_resume_agree_after_a_repeats_round(tmp_path: Path) -> None:
    # The log of a mission that repeats a patrol three times, every prefix of it: the
    # service's task board shows what a run resumed from there would still fly.
    mission = validate_file(str(ROOT / "missions" / "jump_and_repeat.xml")).mission
    assert mission is not None
    lines = read(str(KEPT / "jump_and_repeat.jsonl"))
    board = TaskBoard(mission, [1])
    rounds_seen = 0
    for number, line in enumerate(lines, 1):
        board.see(line)
        if line["kind"] not in ("task", "decision"):
            continue
        shown = board.snapshot()["1"]
        assert shown == expected_board(lines[:number], board.paths), f"line {number}"
        if line["kind"] == "decision" and "repeat" in line.get("message", "") \
                and line.get("iteration", 0) > 1:
            rounds_seen += 1
            # The legs of the round before are not done in this one: not reached yet.
            assert shown["Patrol/Leg west"] == "pending"
    assert rounds_seen == 2


def test_the_fold_follows_a_pause_and_a_jump() -> None:
    fold = Fold()
    lines = read(str(KEPT / "service_pause_jump.jsonl"))
    for line in lines:
        fold.see(line)
    stood = fold.progress(1)
    assert stood.status == "completed" and stood.started
    # The mission clock a time limit goes on with: the log's mission time (a stopwatch's)
    # less the time paused.
    paused = next(line["paused"] for line in lines if line.get("control") == "resume")
    assert paused > 1
    assert stood.elapsed == pytest.approx(lines[-1]["mission_time"] - paused, abs=0.01)
    tasks = fold.tasks(1)
    assert tasks["Out"].value == "aborted"  # left by the jump
    assert tasks["Again"].value == tasks["Down"].value == "done"
