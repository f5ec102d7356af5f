"""The pre-flight clearance (tml.run.clearance): one set of rules for tml run and tml serve,
its findings as data, said by tml run as it always said them."""

from __future__ import annotations

import io
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import pytest
from fake_vehicle import FakeVehicle
from rich.console import Console

from tml.language.validation import load_mission
from tml.run.clearance import (
    GCS_FAILSAFE,
    ClearanceOptions,
    Cleared,
    FailsafeMissing,
    Incapable,
    Infeasible,
    NoParameters,
    NotCleared,
    ProfileRead,
    Refusal,
    clear,
    say,
)
from tml.verify.profile import load_profile

UP = ('<mission name="Hop">\n'
      '  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="4"/>'
      '</action></task>\n'
      '  <task name="Over"><action name="GO_TO_POINT"><argument name="coordinates" '
      'value="(8, 0, 4)"/></action></task>\n'
      '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')
FAR = UP.replace("(8, 0, 4)", "(40000, 0, 4)")


@dataclass
class Reporting(FakeVehicle):
    """A fake vehicle that reports parameters, as a MAVLink vehicle does."""

    parameters: Mapping[str, float] | None = None
    source_system: int = 255

    def read_parameters(self, names: Iterable[str]) -> Mapping[str, float]:
        return {n: v for n, v in (self.parameters or {}).items() if n in set(names)}

    def read_first(self, names: Sequence[str]) -> tuple[str, float] | None:
        return next(((n, (self.parameters or {})[n]) for n in names
                     if n in (self.parameters or {})), None)


def _mission(tmp_path: Path, text: str = UP):
    path = tmp_path / "m.xml"
    path.write_text(text)
    return load_mission(str(path))


def _said(found: Cleared | NotCleared, force: bool = False) -> list[str]:
    out = io.StringIO()
    say(found.findings, "m.xml", "tml run", force, Console(file=out, width=1000))
    return out.getvalue().splitlines()


def test_a_mission_the_vehicles_can_fly_is_cleared_with_its_profile(tmp_path: Path) -> None:
    quad = load_profile("quadcopter")
    found = clear(_mission(tmp_path), [Reporting(parameters={GCS_FAILSAFE: 1})], quad)
    assert found == Cleared(quad, ())


def test_an_infeasible_mission_is_refused_with_its_report_unless_forced(tmp_path: Path) -> None:
    mission, quad = _mission(tmp_path, FAR), load_profile("quadcopter")
    found = clear(mission, (), quad)
    assert isinstance(found, NotCleared) and found.refusal is Refusal.MISSION
    assert isinstance(found.reason, Infeasible) and not found.reason.report.feasible
    assert _said(found)[-1] == ("tml run: m.xml: infeasible mission, not flown (--force "
                                "flies it anyway)")
    forced = clear(mission, (), quad, options=ClearanceOptions(force=True))
    assert isinstance(forced, Cleared) and isinstance(forced.findings[0], Infeasible)
    assert _said(forced, force=True)[-1] == "tml run: infeasible mission flown anyway (--force)"
    assert isinstance(clear(mission, (), quad, verified=True), Cleared)


def test_actions_a_vehicle_cannot_do_are_refused_naming_it(tmp_path: Path) -> None:
    rover = FakeVehicle(vehicle_id=2, vehicle_type="rover")
    found = clear(_mission(tmp_path), [rover], load_profile("quadcopter"), verified=True)
    assert isinstance(found, NotCleared) and found.refusal is Refusal.MISSION
    assert isinstance(found.reason, Incapable)
    assert {v.vehicles[0] for v in found.reason.violations} == {2}
    said = _said(found)
    assert all("(vehicle 2)" in line for line in said[:-1])
    assert said[-1] == ("tml run: m.xml: mission with actions its vehicles cannot do, not "
                        "flown (--force flies it anyway)")


def test_a_vehicle_without_a_gcs_failsafe_is_warned_about_or_refused(tmp_path: Path) -> None:
    mission, quad = _mission(tmp_path), load_profile("quadcopter")
    silent, set_up = Reporting(parameters={GCS_FAILSAFE: 0}), Reporting(
        vehicle_id=2, parameters={GCS_FAILSAFE: 1})
    warned = clear(mission, [silent, set_up], quad, verified=True)
    assert isinstance(warned, Cleared)
    assert warned.findings == (FailsafeMissing((
        "vehicle 1: FS_GCS_ENABLE is 0: the vehicle does nothing by itself when it loses "
        "this ground station (1 returns home, 5 lands)",), required=False),)
    assert _said(warned)[0].startswith("tml run: warning: vehicle 1: FS_GCS_ENABLE is 0")
    refused = clear(mission, [silent], quad, verified=True,
                    options=ClearanceOptions(require_gcs_failsafe=True, force=True))
    assert isinstance(refused, NotCleared) and refused.refusal is Refusal.VEHICLE
    assert _said(refused)[-1] == "tml run: not flown (--require-gcs-failsafe)"
    unread = clear(mission, [silent], quad, options=ClearanceOptions(gcs_failsafe=False))
    assert unread == Cleared(quad, ())


@pytest.mark.parametrize(("parameters", "source", "problem"), [
    ({"MAV_GCS_SYSID": 255}, 255, None),
    ({"SYSID_MYGCS": 255}, 255, None),
    ({}, 255, None),  # neither name: nothing to compare
    ({"MAV_GCS_SYSID": 250}, 255, "MAV_GCS_SYSID is 250 and tml sends as system 255"),
    ({"SYSID_MYGCS": 250}, 255, "SYSID_MYGCS is 250 and tml sends as system 255"),
    ({"MAV_GCS_SYSID": 255}, 251, "MAV_GCS_SYSID is 255 and tml sends as system 251"),
    # ArduPilot 4.7.1's range: MAV_GCS_SYSID up to MAV_GCS_SYSID_HI
    ({"MAV_GCS_SYSID": 250, "MAV_GCS_SYSID_HI": 255}, 255, None),
    ({"MAV_GCS_SYSID": 250, "MAV_GCS_SYSID_HI": 254}, 255,
     "MAV_GCS_SYSID is 250 and tml sends as system 255"),
    ({"MAV_GCS_SYSID": 250, "MAV_GCS_SYSID_HI": 0}, 255,
     "MAV_GCS_SYSID is 250 and tml sends as system 255"),
])
def test_a_vehicle_whose_failsafe_hears_another_ground_station_is_warned_about(
        tmp_path: Path, parameters: dict[str, float], source: int, problem: str | None) -> None:
    vehicle = Reporting(parameters={GCS_FAILSAFE: 1, **parameters}, source_system=source)
    found = clear(_mission(tmp_path), [vehicle], load_profile("quadcopter"), verified=True)
    assert isinstance(found, Cleared)
    if problem is None:
        assert found.findings == ()
        return
    [missing] = found.findings
    assert isinstance(missing, FailsafeMissing)
    [said] = missing.problems
    assert said.startswith(f"vehicle 1: {problem}: the vehicle's GCS failsafe hears only ")
    assert said.endswith(f"(set {problem.split()[0]} to {source})")


def test_without_a_profile_it_is_read_from_the_first_vehicle(tmp_path: Path) -> None:
    options = ClearanceOptions(gcs_failsafe=False)
    found = clear(_mission(tmp_path), [Reporting(parameters={"WPNAV_SPEED": 700})], None,
                  options=options)
    assert isinstance(found, Cleared) and isinstance(found.findings[0], ProfileRead)
    assert found.profile.name == "quadcopter"
    assert _said(found) == ["tml run: quadcopter profile from vehicle 1's parameters: "
                            "WPNAV_SPEED=700"]
    fake = clear(_mission(tmp_path), [FakeVehicle()], None, options=options)
    assert isinstance(fake, NotCleared) and fake.refusal is Refusal.VEHICLE
    assert fake.reason == NoParameters(1)
