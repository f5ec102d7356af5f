"""Numbers that validated but broke verify and run: every number is bounded to its quantity.

Regression tests for what a numeric sweep over missions/ found: NaN and INF in the
environment crashed the verifier (shapely and GEOS on non-finite geometry), a repeat of
10^23 rounds never ended, a survey of 1e12 m grew without bound, a spacing of 1e-320 m
overflowed and a loiter radius of 1e300 m broke GEOS.
"""

from __future__ import annotations

import re
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from tml.commands.cli import main
from tml.errors import ExitCode
from tml.language import actions, parameters
from tml.language.actions import ArgType
from tml.language.quantities import RANGES, Quantity, out_of_range
from tml.language.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent


def _mission(body: str, environment: str = "") -> str:
    return (f'<mission name="m">\n{environment}'
            '  <task name="Take off"><action name="TAKE_OFF"/></task>\n'
            f'{body}'
            '  <task name="Land"><action name="LAND"/></task>\n</mission>\n')


def _action(name: str, **arguments: str) -> str:
    written = "".join(f'<argument name="{k}" value="{v}"/>' for k, v in arguments.items())
    return f'  <task name="Act"><action name="{name}">{written}</action></task>\n'


def _codes(tmp_path: Path, text: str) -> list[str]:
    path = tmp_path / "m.xml"
    path.write_text(text)
    return [d.code for d in validate_file(path).errors]


@pytest.mark.parametrize("element", [
    '<home latitude="0" longitude="0" altitude="NaN"/>',
    '<home latitude="0" longitude="0" altitude="INF"/>',
    '<home latitude="0" longitude="0" altitude="0" heading="1e300"/>',
    '<cylinder north="10" east="0" radius="NaN"/>',
    '<cylinder north="INF" east="0" radius="5"/>',
    '<cylinder north="10" east="0" radius="1e300"/>',
    '<cylinder north="10" east="0" radius="5" top="-INF"/>',
    '<prism><point north="0" east="0"/><point north="1e300" east="0"/>'
    '<point north="0" east="5"/></prism>',
    '<geofence><point north="0" east="0"/><point north="NaN" east="0"/>'
    '<point north="0" east="5"/></geofence>',
    '<geofence max_altitude="INF"/>',
    '<object kind="marker" id="1" north="0" east="0" altitude="-1e300"/>',
])
def test_a_number_of_the_environment_outside_its_range_is_refused(
        tmp_path: Path, element: str) -> None:
    environment = f"  <environment>{element}</environment>\n"
    assert "E255" in _codes(tmp_path, _mission("", environment))


def test_the_environment_refusal_says_where_what_and_the_range(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "m.xml"
    path.write_text(_mission("", '  <environment>\n    <cylinder north="10" east="0" '
                                 'radius="1e300"/>\n  </environment>\n'))
    assert main(["validate", str(path)]) == ExitCode.INVALID
    out = capsys.readouterr().out
    assert re.search(rf"{re.escape(str(path))}:3:\d+: error E255", out), out
    assert "radius='1e300'" in out and "0 to 10,000 m" in out


@pytest.mark.parametrize(("name", "arguments"), [
    ("SURVEY_AREA", {"length": "100", "width": "1e12"}),
    ("SURVEY_AREA", {"length": "100", "width": "100", "spacing": "1e-320"}),
    ("LOITER", {"radius": "1e300", "turns": "2"}),
    ("LOITER", {"turns": "99999999999999999999999"}),
    ("WAIT", {"duration": "1e12"}),
    ("SET_SPEED", {"speed": "1e6"}),
    ("GO_TO_POINT", {"coordinates": "(1e12, 0, 10)"}),
    ("GO_TO_POINT", {"coordinates": "(0, 0, -1e300)"}),
    ("TAKE_OFF", {"altitude": "1e300"}),
    ("CAPTURE_PHOTOS", {"count": "9" * 5000}),
])
def test_an_argument_outside_its_quantity_range_is_refused(
        tmp_path: Path, name: str, arguments: dict[str, str]) -> None:
    assert _codes(tmp_path, _mission(_action(name, **arguments))) == ["E212"]


def test_a_condition_number_outside_its_parameter_range_is_refused(tmp_path: Path) -> None:
    body = ('  <task name="High"><condition parameter="ALTITUDE" comparison="greater than" '
            'value="1e300"/><action name="WAIT"><argument name="duration" value="1"/>'
            '</action></task>\n')
    assert _codes(tmp_path, _mission(body)) == ["E224"]


def test_a_detection_parameter_is_only_required_to_be_finite(tmp_path: Path) -> None:
    body = ('  <task name="Big"><condition parameter="score" comparison="greater than" '
            'value="1e300"/><action name="WAIT"><argument name="duration" value="1"/>'
            '</action></task>\n')
    declared = '  <parameter name="score" type="number"/>\n'
    assert _codes(tmp_path, _mission(body, declared)) == []


def test_a_huge_repeat_is_refused(tmp_path: Path) -> None:
    body = ('  <task name="Many"><repeat times="99999999999999999999999"/>'
            '<action name="WAIT"><argument name="duration" value="1"/></action></task>\n')
    assert _codes(tmp_path, _mission(body)) == ["E250"]


def test_nested_repeats_multiply_and_are_bounded_together(tmp_path: Path) -> None:
    def nested(outer: int, inner: int) -> str:
        return (f'  <task name="Outer"><repeat times="{outer}"/>'
                f'<task name="Inner"><repeat times="{inner}"/>'
                '<action name="WAIT"><argument name="duration" value="1"/></action>'
                '</task></task>\n')
    assert _codes(tmp_path, _mission(nested(100, 100))) == []
    assert _codes(tmp_path, _mission(nested(1000, 11))) == ["E250"]


def test_every_numeric_argument_and_parameter_measures_a_quantity() -> None:
    numeric = [(spec.name, arg.name) for spec in actions.CATALOGUE for arg in spec.arguments
               if arg.type in (ArgType.NUMBER, ArgType.INTEGER) and arg.quantity is None]
    assert numeric == []
    assert [p.name for p in parameters.BUILT_IN
            if p.type is parameters.ParamType.NUMBER and p.quantity is None] == []


@pytest.mark.parametrize("value", [float("nan"), float("inf"), -float("inf")])
def test_no_quantity_takes_a_non_finite_value(value: float) -> None:
    assert all(out_of_range(q, value) for q in Quantity)


def test_the_ranges_table_in_the_docs_is_the_one_in_the_code() -> None:
    doc = (ROOT / "docs" / "language.md").read_text(encoding="utf-8")
    for quantity, bounds in RANGES.items():
        assert f"| {quantity.value} | {bounds.text()} |" in doc


def _limited() -> None:
    """Bound the sweep's work: CPU seconds and address space, not wall-clock time."""
    resource.setrlimit(resource.RLIMIT_CPU, (300, 300))
    resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))


@pytest.mark.parametrize("mission", sorted(p.name for p in (ROOT / "missions").glob("*.xml")))
def test_extreme_numbers_are_refused_or_verified_without_a_traceback(mission: str) -> None:
    """nan, inf, 1e309, -1e300, 1e12, 1e-320, 0 and a negative number in every kind of
    numeric site of each mission (10^23, 0 and -1 for repeats): validation refuses the
    variant or the verifier reports on it, never an exception of another kind."""
    done = subprocess.run(
        [sys.executable, str(ROOT / "tests" / "number_sweep.py"),
         str(ROOT / "missions" / mission)],
        capture_output=True, text=True, preexec_fn=_limited, check=False)
    assert done.returncode == 0, done.stdout + done.stderr[-2000:]


@pytest.mark.parametrize(("quantity", "value", "said"), [
    (Quantity.ALTITUDE, 20_000.0, "(an altitude: "),
    (Quantity.ANGLE, -400.0, "(an angle: "),
    (Quantity.LATITUDE, 95.0, "(a latitude: "),
    (Quantity.DURATION, 1e6, "(a duration: "),
])
def test_a_range_names_its_quantity_with_the_right_article(quantity: Quantity, value: float,
                                                           said: str) -> None:
    assert said in (out_of_range(quantity, value) or "")


def test_an_altitude_out_of_range_says_an_altitude(tmp_path: Path) -> None:
    path = tmp_path / "high.xml"
    path.write_text(_mission('<task name="Up"><action name="TAKE_OFF">'
                             '<argument name="altitude" value="20000"/></action></task>\n'))
    [diagnostic] = validate_file(path).errors
    assert diagnostic.code == "E212" and "(an altitude: " in diagnostic.message
