"""``tml run --resume``: refusals, said before any vehicle is reached, and a run killed with
SIGKILL and resumed on a simulator that outlives it."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from typing import Any

import pytest

from tml.commands.cli import main
from tml.run.journal import read

ROOT = Path(__file__).resolve().parent.parent
FAST = ["--sim-param", "SIM_GPS_LOCKTIME=0.5", "--sim-param", "SIM_EKF_GPS_TIME=1",
        "--speedup", "40"]
HOP = ('<mission name="Hop">\n'
       '  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="4"/>'
       '</action></task>\n'
       '  <task name="Over"><action name="GO_TO_POINT"><argument name="coordinates" '
       'value="(30, 0, 4)"/></action></task>\n'
       '  <task name="Back"><action name="GO_TO_POINT"><argument name="coordinates" '
       'value="(0, 0, 4)"/></action></task>\n'
       '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')
ADDRESS = "tcp:127.0.0.1:5790"  # nothing listens: a refusal must come before connecting


def harness() -> Any:
    """benchmarks/resume.py, whose kill-and-resume the benchmark and this test share."""
    spec = importlib.util.spec_from_file_location("resume_benchmark",
                                                  ROOT / "benchmarks" / "resume.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def interrupted(tmp_path: Path) -> tuple[Path, Path]:
    """A mission file and the log of its run, cut after the second task began (as a
    SIGKILL leaves it), the run line naming ADDRESS as its vehicle."""
    mission = tmp_path / "hop.xml"
    mission.write_text(HOP)
    log = tmp_path / "flight.jsonl"
    assert main(["run", str(mission), "--sim", "-q", "--log", str(log), *FAST]) == 0
    lines = read(str(log))
    cut = next(i for i, line in enumerate(lines)
               if line.get("task") == "Over" and line.get("state") == "running")
    lines[0]["connect"] = [ADDRESS]
    log.write_text("".join(json.dumps(line) + "\n" for line in lines[:cut + 3])
                   + '{"t": 9.5, "kind": "telem')  # the line the kill cut short
    return mission, log


def refusal(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    assert main(["run", *args]) == 2
    return capsys.readouterr().err


def test_a_run_that_ended_is_not_resumed(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    mission = tmp_path / "hop.xml"
    mission.write_text(HOP)
    log = tmp_path / "flight.jsonl"
    assert main(["run", str(mission), "--sim", "-q", "--log", str(log), *FAST]) == 0
    capsys.readouterr()
    said = refusal(capsys, str(mission), "--connect", ADDRESS, "--resume", str(log))
    assert "cannot resume" in said and "the run ended (exit code 0)" in said


def test_another_mission_file_or_other_vehicles_are_refused(
        interrupted: tuple[Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    mission, log = interrupted
    other = tmp_path / "other.xml"
    other.write_text(HOP.replace('value="4"', 'value="6"'))
    said = refusal(capsys, str(other), "--connect", ADDRESS, "--resume", str(log))
    assert "flew another mission file" in said and str(mission) in said
    said = refusal(capsys, str(mission), "--connect", "tcp:127.0.0.1:5800", "--resume",
                   str(log))
    assert f"flew the vehicles at {ADDRESS}, not tcp:127.0.0.1:5800" in said


def test_another_vehicle_on_the_same_address_is_refused(
        interrupted: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    # The run flew system 2 of an address that carries several; the vehicle heard there
    # now is system 1: nothing is flown.
    from tests.process_lines import simulator

    mission, log = interrupted
    first, rest = log.read_text().split("\n", 1)
    with simulator("--fast-boot", "--speedup", "10") as port:
        address = f"tcp:127.0.0.1:{port}"
        line = {**json.loads(first), "connect": [address], "system_ids": [2]}
        log.write_text(json.dumps(line) + "\n" + rest)
        said = refusal(capsys, str(mission), "--connect", address, "--resume", str(log),
                       "--timeout", "60")
    assert said.strip().splitlines()[-1] == (
        "tml run: cannot resume: the run flew the vehicle(s) with system id 2, not 1: say "
        "which with --sysid")


def test_resume_options_that_cannot_work_are_usage_errors(
        interrupted: tuple[Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    mission, log = interrupted
    said = refusal(capsys, str(mission), "--sim", "--resume", str(log))
    assert "--resume needs the vehicles of the interrupted run (--connect)" in said
    said = refusal(capsys, str(mission), "--connect", ADDRESS, "--resume", str(log),
                   "--log", str(tmp_path / "new.jsonl"))
    assert "a resumed run adds to its log" in said
    not_a_log = tmp_path / "notes.jsonl"
    not_a_log.write_text('{"kind": "note"}\n')
    said = refusal(capsys, str(mission), "--connect", ADDRESS, "--resume", str(not_a_log))
    assert "notes.jsonl:1: not a flight log line (no 't' and 'kind'): not a tml flight " \
        "log" in said
    said = refusal(capsys, str(mission), "--connect", ADDRESS, "--resume",
                   str(tmp_path / "missing.jsonl"))
    assert "cannot read" in said


def alone_and_killed(tmp_path: Path, text: str, kill: tuple[int, float]) -> list[Any]:
    """The mission flown alone, and killed at ``kill`` and resumed, each on a simulator of
    its own that outlives ``tml run``."""
    from sitl.server import Simulator

    bench = harness()
    mission = tmp_path / "mission.xml"
    mission.write_text(text)
    flown = []
    for point in (None, kill):
        with Simulator(tcp_base_port=0, speedup=10,
                       params={"SIM_GPS_LOCKTIME": 0.5, "SIM_EKF_GPS_TIME": 1}) as sim:
            address = f"tcp:127.0.0.1:{sim.tcp_ports[0]}"
            flown.append(bench.fly(mission, address, tmp_path / f"{point}.jsonl", point))
    return flown


def test_a_run_killed_in_flight_and_resumed_ends_as_one_left_alone(tmp_path: Path) -> None:
    # Killed on the way over, the vehicle flying on.
    alone, resumed = alone_and_killed(tmp_path, HOP, (6, 0.3))
    assert alone.exit_code == resumed.exit_code == 0
    assert resumed.runs == 2  # it was killed, and resumed once
    assert resumed.ends == alone.ends == (("Up", "done"), ("Over", "done"), ("Back", "done"),
                                          ("Down", "done"))
    assert resumed.takeoffs_commanded == resumed.takeoffs_flown == 1


AUTO = HOP.replace('<task name="Over">',
                  '<task name="Plan" dispatch="mission"><task name="Over">') \
    .replace('<task name="Down">', '</task><task name="Down">')


def test_a_plan_flown_in_auto_is_followed_after_a_resume_not_uploaded_again(
        tmp_path: Path) -> None:
    # Killed while the autopilot flies the plan: it flies on, and the resumed run follows.
    alone, resumed = alone_and_killed(tmp_path, AUTO, (8, 1.0))
    assert resumed.runs == 2
    assert alone.exit_code == resumed.exit_code == 0
    assert resumed.ends == alone.ends
    assert alone.uploads == resumed.uploads == 1
    assert resumed.takeoffs_flown == 1


def test_a_log_another_process_writes_is_neither_resumed_nor_written_again(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import os
    import signal
    import subprocess
    import time

    from connected_flight import log_lines

    from tml.run.journal import Journal

    mission = tmp_path / "wait.xml"
    mission.write_text(HOP.replace('<task name="Down">', '<task name="Stay"><action '
                                   'name="WAIT"><argument name="duration" value="120"/>'
                                   '</action></task>\n  <task name="Down">'))
    log = tmp_path / "flight.jsonl"
    writer = subprocess.Popen([sys.executable, "-m", "tml", "run", str(mission), "--sim",
                               "-q", "--log", str(log), "--speedup", "1"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        end = time.monotonic() + 120  # a hang guard
        while not any(line["kind"] == "run" for line in log_lines(log)):
            assert time.monotonic() < end and writer.poll() is None, "the run never began"
            time.sleep(0.05)
        said = refusal(capsys, str(mission), "--connect", ADDRESS, "--resume", str(log))
        assert said == (f"tml run: cannot resume: {log}: another process is writing this "
                        f"flight log (a run still going on): one run writes a log at a "
                        f"time\n")
        said = refusal(capsys, str(mission), "--sim", "-q", "--log", str(log))
        assert said.startswith(f"tml run: --log {log}: another process is writing")
        assert log_lines(log)[0]["message"] == "run started"  # left whole
        assert writer.poll() is None
    finally:
        os.kill(writer.pid, signal.SIGKILL)
        writer.wait(timeout=30)
    Journal.open(str(log), append=True).close()  # a killed writer holds nothing
