"""Fuzzing the missions of missions/ through validation, verification and the engine.

Each case takes one mission and mutates it the way a careless editor or a hostile file
would: elements deleted or duplicated, attribute values swapped or replaced by extreme
numbers (NaN, INF, 1e309, 10^23 ...) and huge strings, deep nesting, flipped bytes. The
result goes through what ``tml validate`` does (diagnostics rendered for the terminal),
then, if valid, what ``tml verify`` does (the report rendered), then the engine's first
seconds on fake vehicles. Nothing may raise but tml's own errors, hang, or take memory
without bound (tests/fuzzing.py). Profiles and running more cases: docs/reliability.md.
"""

from __future__ import annotations

import copy
import io
from pathlib import Path

from fake_vehicle import FakeVehicle
from fuzzing import fuzz_settings, memory_bound, time_bound
from hypothesis import given
from hypothesis import strategies as st
from lxml import etree

from tml.engine import Interpreter, Status
from tml.errors import TmlError
from tml.language.diagnostics import format_human_all
from tml.language.validation import validate_file
from tml.verify.motion import PredictedState
from tml.verify.profile import load_profile
from tml.verify.report import print_report
from tml.verify.static import verify_mission
from tml.world import World

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = sorted((ROOT / "missions").glob("*.xml"))
SOURCES = {path: path.read_bytes() for path in MISSIONS}
EXTREMES = ("nan", "NaN", "inf", "-INF", "1e309", "-1e309", "1e300", "-1e300", "1e-320",
            "99999999999999999999999", "0", "-0", "-1", "", " ", "0x10", "1_000",
            "(nan, 0, 5)", "(1e309, 0, 5)", "(0, 0, -1e300)", "(0, 0)", "(1, 2, 3, 4)",
            "x" * 5000, "9" * 400, "@CONTROL@")
CONTROL = "\u202e\x1b]0;x\x07".encode()
"""Written in place of @CONTROL@ once serialized (lxml refuses control characters)."""
STEPS = 50
"""Engine steps of 0.1 s flown on the fake vehicles (the first five seconds)."""


ATTRIBUTES = sorted({name for data in SOURCES.values()
                     for element in etree.fromstring(data).iter() if isinstance(element.tag, str)
                     for name in element.attrib if not name.startswith("{")})
"""Every attribute name the missions use: one may be given to an element that lacks it."""


def _elements(root: etree._Element) -> list[etree._Element]:
    return [e for e in root.iter() if isinstance(e.tag, str) and e is not root]


@st.composite
def mutated(draw: st.DrawFn) -> tuple[Path, bytes]:
    """(the mission's path, its mutated bytes)."""
    path = draw(st.sampled_from(MISSIONS))
    root = etree.fromstring(SOURCES[path])
    for _ in range(draw(st.integers(1, 4))):
        elements = _elements(root)
        if not elements:
            break
        element = draw(st.sampled_from(elements))
        parent = element.getparent()
        how = draw(st.sampled_from(("delete", "duplicate", "swap", "extreme", "nest",
                                    "move", "add")))
        if how == "delete" and parent is not None:
            parent.remove(element)
        elif how == "duplicate" and parent is not None:
            for _ in range(draw(st.integers(1, 50))):
                element.addnext(copy.deepcopy(element))
        elif how == "swap":
            other = draw(st.sampled_from(elements))
            mine, theirs = dict(element.attrib), dict(other.attrib)
            element.attrib.clear()
            other.attrib.clear()
            element.attrib.update(theirs)
            other.attrib.update(mine)
        elif how == "extreme":
            names = list(element.attrib) or ["value"]
            element.set(draw(st.sampled_from(names)), draw(st.sampled_from(EXTREMES)))
        elif how == "add":
            element.set(draw(st.sampled_from(ATTRIBUTES)), draw(st.sampled_from(EXTREMES)))
        elif how == "nest" and parent is not None:
            inner = element
            for level in range(draw(st.integers(1, 300))):
                wrapper = etree.Element(element.tag, name=f"level {level}")
                inner.addprevious(wrapper)
                wrapper.append(inner)
                inner = wrapper
        elif how == "move" and parent is not None:
            target = draw(st.sampled_from(elements))
            if element not in target.iterancestors() and target is not element:
                target.append(element)
    data = etree.tostring(root, xml_declaration=True, encoding="UTF-8").replace(
        b"@CONTROL@", CONTROL)
    flips = draw(st.lists(st.tuples(st.integers(0, len(data) - 1), st.integers(1, 255)),
                          max_size=3))
    if flips:
        buffer = bytearray(data)
        for index, mask in flips:
            buffer[index] ^= mask
        data = bytes(buffer)
    return path, data


def check_mission(path: Path, data: bytes) -> None:
    """Validate, verify and start ``data`` (read as if at ``path``): only tml's errors."""
    with time_bound(), memory_bound():
        try:
            result = validate_file(str(path), data)
            for text in format_human_all(result.diagnostics, {result.file: result.source}):
                assert "\x1b" not in text
            mission = result.mission
            if result.errors or mission is None:
                return
            home = (mission.world or World()).home_or_default
            report = verify_mission(mission, load_profile("quadcopter"), None,
                                    PredictedState(battery=100.0, heading=home.heading))
            from rich.console import Console

            print_report(report, Console(file=io.StringIO(), width=100))
            fly(mission)
        except TmlError:
            pass


def fly(mission) -> None:  # type: ignore[no-untyped-def]
    """The engine's first STEPS steps with fake vehicles, one per role (or one)."""
    vehicles = [FakeVehicle(vehicle_id=i + 1) for i in range(max(1, len(mission.roles)))]
    ids = [v.vehicle_id for v in vehicles]
    engine = Interpreter(mission, ids)
    out = engine.start(0.0, {v.vehicle_id: v.state() for v in vehicles})
    now = 0.0
    for _ in range(STEPS):
        for request in out.requests:
            next(v for v in vehicles if v.vehicle_id == request.vehicle_id).submit(request)
        if engine.status is not Status.RUNNING:
            return
        now = round(now + 0.1, 6)
        for vehicle in vehicles:
            vehicle.advance(0.1)
        out = engine.step(now, {v.vehicle_id: v.state() for v in vehicles},
                          {v.vehicle_id: v.poll() for v in vehicles})


@fuzz_settings(1000)
@given(mutated())
def test_a_mutated_mission_is_refused_or_verified_and_started(case: tuple[Path, bytes]) -> None:
    check_mission(*case)


def test_every_mission_is_checked_unmutated() -> None:
    # The harness itself: each mission of missions/ validates, verifies and starts.
    for path, data in SOURCES.items():
        result = validate_file(str(path), data)
        assert result.errors == [], path
        check_mission(path, data)
