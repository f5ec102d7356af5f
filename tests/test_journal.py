"""The JSON-lines flight log."""

from __future__ import annotations

import io
import json
import math
from datetime import datetime, timedelta, timezone
from types import MappingProxyType

import pytest

from tml.run.journal import (
    Journal,
    JournalBusy,
    autopilot_fields,
    jsonable,
    read,
    telemetry_fields,
)
from tml.vehicle import AutopilotMessage, MissionProgress, VehicleState
from tml.world import Home

NOON = datetime(2026, 5, 1, 12, 0, 0, 125000, tzinfo=timezone(timedelta(hours=2)))


def test_lines_are_json_with_time_kind_and_vehicle(tmp_path) -> None:
    path = tmp_path / "flight.jsonl"
    journal = Journal.open(str(path))
    journal.wall = lambda: NOON
    journal.write(1.23456, "event", 2, event="Low battery", read=[{"value": 24.0}])
    journal.write(2.0, "run", message="run ended", exit_code=3)
    journal.close()
    assert journal.stream.closed and journal.lines == 2
    wall = "2026-05-01T12:00:00.125+02:00"
    assert read(str(path)) == [
        {"t": 1.235, "kind": "event", "vehicle": 2, "mission_time": None, "wall": wall,
         "event": "Low battery", "read": [{"value": 24.0}]},
        {"t": 2.0, "kind": "run", "mission_time": None, "wall": wall, "message": "run ended",
         "exit_code": 3}]


def test_fields_cannot_hide_time_kind_or_vehicle() -> None:
    stream = io.StringIO()
    Journal(stream, wall=lambda: NOON).write(
        3.0, "request", 1, {"message": "SetSpeed", "kind": "ground", "wall": "x",
                            "mission_time": 1})
    assert json.loads(stream.getvalue()) == {
        "t": 3.0, "kind": "request", "vehicle": 1, "mission_time": None,
        "wall": "2026-05-01T12:00:00.125+02:00", "message": "SetSpeed",
        "request_kind": "ground", "request_wall": "x", "request_mission_time": 1}


def test_mission_time_counts_from_the_line_that_says_the_mission_started() -> None:
    stream = io.StringIO()
    journal = Journal(stream)
    journal.write(41.5, "ready", 1, message="ready")
    journal.write(41.6, "mission", 1, message="mission 'm' started")
    journal.write(50.0, "telemetry", 1)
    journal.write(80.0, "mission", 1, message="mission completed", status="completed")
    journal.write(81.0, "run", message="run ended")
    times = [json.loads(line)["mission_time"] for line in stream.getvalue().splitlines()]
    assert times == [None, 0.0, 8.4, 38.4, 39.4]
    assert journal.mission_start == 41.6 and journal.mission_time(40.0) == pytest.approx(-1.6)
    walls = [json.loads(line)["wall"] for line in stream.getvalue().splitlines()]
    assert all(datetime.fromisoformat(w).utcoffset() is not None for w in walls)


def test_a_resumed_mission_counts_on_from_the_interrupted_runs_time() -> None:
    stream = io.StringIO()
    journal = Journal(stream)
    journal.write(5.0, "mission", 1, message="mission 'm' resumed after 120.0 s",
                  elapsed=120.0)
    journal.write(6.0, "task", 1, task="A", state="done")
    assert [json.loads(line)["mission_time"] for line in stream.getvalue().splitlines()] \
        == [120.0, 121.0]


def test_a_silent_journal_still_knows_the_mission_time() -> None:
    journal = Journal(None)
    journal.write(3.0, "mission", None, message="mission 'm' started")
    assert journal.mission_time(10.0) == 7.0


def test_values_are_made_json_safe() -> None:
    value = {"set": frozenset({"b", "a"}), "point": (1.0, 2.0), "inf": math.inf,
             "proxy": MappingProxyType({"k": 1}), 3: object}
    safe = jsonable(value)
    assert json.loads(json.dumps(safe)) == safe
    assert safe["set"] == ["a", "b"] and safe["point"] == [1.0, 2.0] and safe["inf"] == "inf"
    assert safe["proxy"] == {"k": 1} and safe["3"].startswith("<class")


def test_silent_journal_writes_nothing_and_callers_stream_stays_open() -> None:
    silent = Journal.open(None)
    silent.write(0.0, "run")
    assert silent.lines == 0
    stream = io.StringIO()
    journal = Journal(stream)
    journal.write(0.0, "run")
    journal.close()
    assert not stream.closed and stream.getvalue().startswith('{"t":0.0,"kind":"run"')


def test_telemetry_fields() -> None:
    state = VehicleState(1, 5.0, position=(1.234, -5.678, 10.0), battery=80.0,
                         mission=MissionProgress(3, 2), armed=True, landed=False,
                         detections=MappingProxyType({"RECOGNIZED_ITEMS": frozenset({"A"})}))
    fields = telemetry_fields(state)
    assert fields["position"] == [1.23, -5.68, 10.0]
    assert fields["mission"] == {"plan": 3, "action": 2, "finished": False, "item": 0,
                                 "items": 0}
    assert fields["detections"] == {"RECOGNIZED_ITEMS": ["A"]}
    assert json.dumps(fields)


def test_telemetry_gives_the_position_on_the_globe_too() -> None:
    home = Home(-35.363261, 149.165230, 584.0)
    fields = telemetry_fields(VehicleState(1, 5.0, position=(100.0, 0.0, 20.0), home=home))
    lat, lon, alt = fields["global"]
    assert lat == pytest.approx(home.latitude + 100.0 / 110_950, abs=2e-6)  # 100 m north
    assert lon == pytest.approx(home.longitude, abs=1e-7)
    assert alt == pytest.approx(604.0, abs=0.01)  # AMSL: home's 584 m + 20 m
    assert telemetry_fields(VehicleState(1, 5.0, position=(1.0, 2.0, 3.0)))["global"] is None
    assert telemetry_fields(VehicleState(1, 5.0, home=home))["global"] is None


def test_autopilot_fields_name_the_severity() -> None:
    message = AutopilotMessage(3, 2, "PreArm: Need Position Estimate")
    assert autopilot_fields(message) == {"severity": "critical", "level": 2,
                                         "text": "PreArm: Need Position Estimate"}


def test_telemetry_carries_what_an_operator_reads() -> None:
    state = VehicleState(1, 5.0, position=(3.0, 4.0, 7.0), battery=65.0, voltage=12.345,
                         satellites=11, gps_fix=3, climb=-0.456,
                         mission=MissionProgress(3, 1, item=43, items=145))
    fields = telemetry_fields(state)
    assert (fields["voltage"], fields["satellites"], fields["climb"]) == (12.35, 11, -0.46)
    assert fields["mission"]["item"] == 43 and fields["mission"]["items"] == 145


class FullDisk:
    """A stream that takes ``room`` lines and then fails as a full disk does."""

    def __init__(self, room: int) -> None:
        self.room = room
        self.text: list[str] = []

    def write(self, text: str, /) -> int:
        if len(self.text) >= self.room:
            raise OSError(28, "No space left on device")
        self.text.append(text)
        return len(text)

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


def test_a_log_that_cannot_be_written_is_said_once_and_stops_nothing() -> None:
    said: list[str] = []
    journal = Journal(FullDisk(room=2), on_failure=said.append)
    for t in range(5):
        journal.write(float(t), "telemetry", 1, mode="GUIDED")
    assert (journal.lines, journal.unwritten) == (2, 3)
    assert journal.failure == "could not write line 3: No space left on device"
    assert said == ["flight log: could not write line 3: No space left on device; "
                    "the flight goes on without it"]


def test_one_writer_at_a_time_and_a_refused_one_changes_nothing(tmp_path) -> None:
    path = str(tmp_path / "flight.jsonl")
    first = Journal.open(path)
    first.write(0.0, "run", message="run started")
    for append in (False, True):  # a second run given the same --log, a --resume
        with pytest.raises(JournalBusy, match="another process is writing this flight log"):
            Journal.open(path, append=append)
    assert [line["message"] for line in read(path)] == ["run started"]
    first.close()
    again = Journal.open(path, append=True)  # closed: free again
    again.write(1.0, "run", message="run resumed")
    again.close()
    assert [line["message"] for line in read(path)] == ["run started", "run resumed"]


def test_a_device_is_no_log_to_lock_two_runs_may_share_dev_null() -> None:
    first, second = Journal.open("/dev/null"), Journal.open("/dev/null")
    first.write(0.0, "run", message="run started")
    second.write(0.0, "run", message="run started")
    assert (first.lines, second.lines) == (1, 1)
    first.close()
    second.close()


def test_decisions_are_synced_line_by_line_or_once_for_a_group(tmp_path, monkeypatch) -> None:
    synced: list[int] = []  # the lines written at each sync
    journal = Journal.open(str(tmp_path / "flight.jsonl"))
    monkeypatch.setattr("tml.run.journal.os.fsync", lambda fd: synced.append(journal.lines))
    journal.write(1.0, "decision", 1, message="one")
    journal.write(1.0, "telemetry", 1, battery=50)  # not a decision: flushed, not synced
    assert synced == [0]  # (counted after the sync)
    with journal.grouped():
        journal.write(2.0, "event", 1, event="Low battery")
        with journal.grouped():  # nested: the outer group syncs
            journal.write(2.0, "decision", 1, message="land")
        journal.write(2.0, "request", 1, request="Land")
        assert synced == [0]  # nothing yet: the caller acts after the group
    assert synced == [0, 5]  # one sync, with every line of the group written
    with journal.grouped():
        journal.write(3.0, "telemetry", 1, battery=40)
    assert synced == [0, 5]  # no decision in it: no sync
    journal.close()
    assert [line["kind"] for line in read(str(tmp_path / "flight.jsonl"))] == [
        "decision", "telemetry", "event", "decision", "request", "telemetry"]


def test_another_threads_decision_is_synced_at_once_during_a_group(tmp_path,
                                                                   monkeypatch) -> None:
    import threading
    synced: list[int] = []
    journal = Journal.open(str(tmp_path / "flight.jsonl"))
    monkeypatch.setattr("tml.run.journal.os.fsync", lambda fd: synced.append(journal.lines))
    with journal.grouped():
        journal.write(1.0, "decision", 1, message="grouped")
        other = threading.Thread(target=journal.write, args=(1.0, "control", None),
                                 kwargs={"message": "paused"})
        other.start()
        other.join(30)
        assert synced == [1]  # the other thread's line, synced as it was written
    assert synced == [1, 2]
    journal.close()
