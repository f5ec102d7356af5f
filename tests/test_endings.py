"""The one table of how a run ends (tml.run.endings): as documented, and the same cause
ending a run the same way in ``tml run`` and ``tml serve`` on the simulator."""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
import typing
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.connected_flight import wait_for_task
from tests.lossy_proxy import LossyProxy
from tests.process_lines import simulator
from tests.serving import SHORT
from tml.engine import Status
from tml.run.endings import CAUSES, WORST_FIRST, Ending

ROOT = Path(__file__).resolve().parent.parent
MISSION = SHORT.replace(b"(40,0,10)", b"(200,0,10)").decode()  # a leg to act on
# A cause that comes from a process started during the leg (``tml command``) needs a leg
# longer than that start may take on a busy machine: 1 km, 100 s of the vehicle's time
# (10 s at the simulator's 10x; 2 km would break the return reserve).
FAR = SHORT.replace(b"(40,0,10)", b"(1000,0,10)").decode()


def mission_for(cause: str) -> str:
    """The mission flown to show ``cause``: the whole short one for a completion."""
    return MISSION if cause == "completed" else FAR


LINK_LOST_LIMIT = 1.0
RTL_MODE = 6  # ArduCopter's custom_mode


# --- the table and its documentation ---------------------------------------------------------

def documented_rows() -> list[list[str]]:
    """The rows of docs/run.md's "How a run ends" table, cell by cell."""
    doc = (ROOT / "docs" / "run.md").read_text(encoding="utf-8")
    section = doc.split("## How a run ends", 1)[1].split("\n## ", 1)[0]
    return [[cell.strip() for cell in line.strip().strip("|").split("|")]
            for line in section.splitlines() if re.match(r"\| `[A-Z_]+` \|", line)]


def test_the_documented_table_is_the_code_s_table() -> None:
    # Every row of the code is documented as it is, and every documented row is in the
    # code: name, status, exit code and meaning.
    documented = {row[0].strip("`"): row for row in documented_rows()}
    assert list(documented) == [ending.name for ending in Ending]
    for ending in Ending:
        name, status, code, meaning = documented[ending.name][:4]
        assert status == (f"`{ending.status}`" if ending.status else "none"), name
        assert code == (str(int(ending.exit_code)) if ending.exit_code is not None
                        else "none"), name
        assert meaning == ending.meaning, name


def test_the_documented_order_of_the_worst_is_the_code_s() -> None:
    doc = (ROOT / "docs" / "run.md").read_text(encoding="utf-8")
    said = doc.split("the worst decides, in this order", 1)[1].split("(only when", 1)[0]
    assert re.findall(r"`([A-Z_]+)`", said) == [ending.name for ending in WORST_FIRST]


def test_every_row_names_the_tests_that_show_it() -> None:
    # (That each named test exists is tests/test_docs_tests.py's to check.)
    for row in documented_rows():
        assert re.search(r"tests/[\w/]+\.py::\w+", row[-1]), row


def test_every_status_of_the_table_is_one_the_api_may_answer() -> None:
    from tml.serve.api import RunView

    said = typing.get_args(RunView.model_fields["status"].annotation)
    assert {e.status for e in Ending if e.status} <= set(said)


def test_the_worst_vehicle_decides_and_a_cause_before_the_mission_s_status() -> None:
    completed, aborted, failed = Status.COMPLETED.value, Status.ABORTED.value, \
        Status.FAILED.value
    assert Ending.of([]) is Ending.COMPLETED
    assert Ending.of([(completed, ""), (completed, "")]) is Ending.COMPLETED
    assert Ending.of([(completed, ""), (aborted, "")]) is Ending.ABORTED
    # Never "completed" unless every vehicle completed.
    assert Ending.of([(completed, ""), (Status.RUNNING.value, "")]) is Ending.ABORTED
    assert Ending.of([(completed, ""), (completed, "lost in thought")]) is Ending.ABORTED
    assert Ending.of([(aborted, "stop"), (completed, "")]) is Ending.STOPPED
    # A vehicle taken over fails its work: the cause says why.
    assert Ending.of([(failed, "taken")]) is Ending.TAKEN
    assert Ending.of([(aborted, "operator"), (aborted, "operator")]) is Ending.OPERATOR
    assert Ending.of([(failed, "taken"), (failed, "")]) is Ending.FAILED
    assert Ending.of([(failed, "link"), (aborted, "stop")]) is Ending.LINK_LOST
    assert Ending.of([(aborted, "error"), (failed, "link")]) is Ending.ERROR
    assert all(Ending.of([("", ending.cause)]) is ending for ending in CAUSES.values())
    assert [e for e in Ending if e not in WORST_FIRST] == [
        Ending.INTERRUPTED, Ending.INVALID, Ending.USAGE, Ending.NOT_CLEARED]


# --- the same cause in tml run and tml serve ---------------------------------------------------

CAUSES_FLOWN = {
    "completed": Ending.COMPLETED,
    # The service's command goes through its run (OPERATOR); tml command at a tml run's
    # address switches the mode beside the run (TAKEN), or goes through the run where it
    # can (Runner.take_over: OPERATOR): the same status and exit code either way.
    "operator rtl": Ending.OPERATOR,
    "another ground station": Ending.TAKEN,
    "interrupted": Ending.STOPPED,
    "link lost": Ending.LINK_LOST,
}


@contextlib.contextmanager
def vehicle() -> Iterator[tuple[int, LossyProxy]]:
    """A simulated vehicle in its own process, and a proxy in front of it (the run's
    address: the link-lost flight cuts it)."""
    with simulator("--fast-boot", "--speedup", "10") as port, \
            LossyProxy(port, loss=0.0) as proxy:
        yield port, proxy


def switch_to_rtl(port: int) -> None:
    """Another ground station (a plain pymavlink client, system 250) switches vehicle 1 to
    RTL, and sees it shown."""
    from pymavlink import mavutil

    other: Any = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=250,
                                            dialect="ardupilotmega")
    try:
        end = time.monotonic() + 60
        while True:
            assert time.monotonic() < end, "the vehicle never showed RTL"
            other.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_DO_SET_MODE, 0,
                                        mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                                        RTL_MODE, 0, 0, 0, 0, 0)
            beat = other.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
            if beat is not None and beat.get_srcSystem() == 1 and beat.custom_mode == RTL_MODE:
                return
    finally:
        other.close()


def lost_and_back(proxy: LossyProxy, said_lost: Callable[[], bool]) -> None:
    """Cut the link until the run says the vehicle is lost past its limit, then let it
    come back (the safe state is commanded again and shown)."""
    proxy.cut(math.inf)
    end = time.monotonic() + 120
    while not said_lost():
        assert time.monotonic() < end, "the run never gave up on the link"
        time.sleep(0.05)
    proxy.restore()


def run_ending(cause: str, tmp_path: Path) -> tuple[str, int, str, int]:
    """``tml run`` of the mission with ``cause`` while it flies: (the status its last line
    says, its exit code, the status and the exit code of its log's last line)."""
    tmp_path.mkdir()
    mission = tmp_path / "long.xml"
    mission.write_text(mission_for(cause))
    log = tmp_path / "flight.jsonl"
    with vehicle() as (port, proxy):
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        process = subprocess.Popen(
            [sys.executable, "-m", "tml", "run", str(mission), "--connect", proxy.address,
             "-q", "--log", str(log), "--link-lost-limit", str(LINK_LOST_LIMIT)],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
        try:
            wait_for_task(process, log, "Out", "running", 120)
            if cause == "operator rtl":
                # At the run's own address: the way an operator reaches the vehicle it flies.
                done = subprocess.run([sys.executable, "-m", "tml", "command", "rtl",
                                       "--connect", proxy.address],
                                      capture_output=True, text=True, timeout=120)
                assert done.returncode == 0, done.stdout + done.stderr
            elif cause == "another ground station":
                switch_to_rtl(port)
            elif cause == "interrupted":
                process.send_signal(signal.SIGINT)
            elif cause == "link lost":
                lost_and_back(proxy, lambda: "link lost for more than" in log.read_text())
            out, _ = process.communicate(timeout=240)
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()
    said = re.search(r"^run (\w+) \(exit (\d)\): (.*)$", out, re.M)
    assert said, out
    last = json.loads(log.read_text().splitlines()[-1])
    assert int(said.group(2)) == process.returncode
    return said.group(1), process.returncode, last["status"], last["exit_code"]


@contextlib.contextmanager
def service_at(address: str, tmp_path: Path) -> Iterator[Any]:
    """A service flying the vehicle at ``address``, as ``tml serve --connect`` opens it."""
    tmp_path.mkdir()
    from tml.run.session import SessionOptions, open_session
    from tml.serve.hangar import Hangar
    from tml.serve.service import Service, ServiceOptions
    from tml.serve.storage import Storage, database_url
    from tml.world import World

    hangars: list[Hangar] = []

    def notify() -> None:
        for hangar in hangars:
            hangar.notify()

    options = SessionOptions(connect=(address,), program="tml serve", quiet=True)
    with open_session(options, World(), notify=notify) as session:
        hangars.append(Hangar(session.vehicles, session.clock))
        storage = Storage(database_url(None, tmp_path))
        service = Service(storage, hangars[0], ServiceOptions(
            link_lost_limit=LINK_LOST_LIMIT, stop_timeout=60, command_timeout=120))
        try:
            yield service
        finally:
            service.stop()
            storage.close()


def serve_ending(cause: str, tmp_path: Path) -> tuple[str, int]:
    """A ``tml serve`` run of the mission with ``cause`` while it flies: its status and
    exit code, as the API shows them."""
    with vehicle() as (port, proxy), service_at(proxy.address, tmp_path) as service:
        mission = service.upload("long.xml", mission_for(cause).encode()).id
        run = service.start_run(mission, [1]).id
        live = service.live(run)

        def said(text: str) -> bool:
            return any(text in line for _, line in list(live.log.lines))

        end = time.monotonic() + 120
        while not said('"task":"Out","state":"running"'):
            assert time.monotonic() < end and not live.ended, "never: Out running"
            live.wake.wait(0.05)
        if cause == "operator rtl":
            answer, done = service.command(1, "rtl")
            assert done and answer.run == run, answer
        elif cause == "another ground station":
            switch_to_rtl(port)
        elif cause == "interrupted":
            service.abort(run)
        elif cause == "link lost":
            lost_and_back(proxy, lambda: said("link lost for more than"))
        assert live.join(240), "the run did not end"
        found = service.run(run)
        return found.status, found.exit_code


@pytest.mark.parametrize("cause", list(CAUSES_FLOWN))
def test_the_same_cause_ends_tml_run_and_tml_serve_the_same_way(cause: str,
                                                                  tmp_path: Path) -> None:
    ending = CAUSES_FLOWN[cause]
    expected = (ending.status, int(ending.code))
    said, code, logged, logged_code = run_ending(cause, tmp_path / "run")
    assert (said, code) == expected, "tml run"
    assert (logged, logged_code) == expected, "tml run's flight log"
    assert serve_ending(cause, tmp_path / "serve") == expected, "tml serve"
