"""The JSON-lines flight log."""

from __future__ import annotations

import io
import json
import math
from types import MappingProxyType

import pytest

from tml.run.journal import Journal, autopilot_fields, jsonable, read, telemetry_fields
from tml.vehicle import AutopilotMessage, MissionProgress, VehicleState
from tml.world import Home


def test_lines_are_json_with_time_kind_and_vehicle(tmp_path) -> None:
    path = tmp_path / "flight.jsonl"
    journal = Journal.open(str(path))
    journal.write(1.23456, "event", 2, event="Low battery", read=[{"value": 24.0}])
    journal.write(2.0, "run", message="run ended", exit_code=3)
    journal.close()
    assert journal.stream.closed and journal.lines == 2
    assert read(str(path)) == [
        {"t": 1.235, "kind": "event", "vehicle": 2, "event": "Low battery",
         "read": [{"value": 24.0}]},
        {"t": 2.0, "kind": "run", "message": "run ended", "exit_code": 3}]


def test_fields_cannot_hide_time_kind_or_vehicle() -> None:
    stream = io.StringIO()
    Journal(stream).write(3.0, "request", 1, {"message": "SetSpeed", "kind": "ground"})
    assert json.loads(stream.getvalue()) == {"t": 3.0, "kind": "request", "vehicle": 1,
                                             "message": "SetSpeed", "request_kind": "ground"}


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
                                         "text": "PreArm: Need Position Estimate",
                                         "armed": None}
    said = AutopilotMessage(4, 2, "PreArm: Mode not armable", armed=False)
    assert autopilot_fields(said)["armed"] is False


def test_telemetry_carries_what_an_operator_reads() -> None:
    state = VehicleState(1, 5.0, position=(3.0, 4.0, 7.0), battery=65.0, voltage=12.345,
                         satellites=11, gps_fix=3, climb=-0.456,
                         mission=MissionProgress(3, 1, item=43, items=145))
    fields = telemetry_fields(state)
    assert (fields["voltage"], fields["satellites"], fields["climb"]) == (12.35, 11, -0.46)
    assert fields["mission"]["item"] == 43 and fields["mission"]["items"] == 145
