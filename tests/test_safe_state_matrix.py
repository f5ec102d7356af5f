"""Every safe-state rule holds in every state of a run: a matrix of (state x event) cells on
the embedded simulator, each judged by an observer of its own on the vehicle.

*States* (:data:`STATES`): a run ``running`` (``tml run --connect``), ``paused`` (``tml
serve --connect``, ``POST /runs/{id}/pause``), ``waiting`` for its vehicles (the service's
run before the vehicles can arm), ``continuing`` (the service killed with SIGKILL, started
again on its database, ``POST /runs/{id}/continue``) and ``resuming`` (``tml run`` killed
with SIGKILL mid-climb, then ``tml run --resume``).

*Events* (:data:`EVENTS`), each on a vehicle of its own, so that one simulator of four
copters and one tml process serve the four cells of a state: ``link`` (every frame between
tml and the vehicle dropped, through a :class:`~lossy_proxy.LossyProxy`, until tml says it
gave the vehicle up after ``--link-lost-limit``, then let through again), ``failsafe`` (the
vehicle's battery failsafe, raised by setting its BATT_LOW_MAH above what the pack holds:
it lands, BATT_FS_LOW_ACT 1), ``reboot`` (MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, forced, from
another ground station) and ``operator`` (another ground station switches the vehicle to
RTL). The vehicle's own GCS failsafe is off (FS_GCS_ENABLE 0): what happens after a lost
link is tml's doing.

*The verdict* is the observer's (:class:`~interrupt_campaign.Observer`, a plain pymavlink
client on the vehicle's own port, never tml's log): after the event the vehicle ends
disarmed on the ground, and the last mode it was seen armed in is RTL or LAND -- never left
armed in GUIDED with nobody flying it. Then the run's own account: it ended (it is not
still paused, waiting or flying a mission for a vehicle it lost), and how.

A state is flown once for its four cells (:func:`flown`, once per test session, whichever
worker asks first), so the cells of a state share their setup; tml reads the vehicle's
clock (``--clock vehicle``) so that waits and limits are the vehicle's seconds.

*Time.* tml is another process, so the vehicles' time cannot wait for it; the test waits
for states, never delays: each vehicle gets its event at its own state (:func:`strike`:
the moment its flight log says it hovers in the WAIT, or is paused there; sent again
until its observer sees the vehicle take it: the mode, the parameter's echo, the reboot's
disarm), and until then the simulator of a running, paused or continuing run's vehicles
runs at twice real time (:data:`SLOW`), so that however late a busy machine lets tml and
the test get there, the hover has not run out, nor tml's limits in vehicle seconds; after
the events, at ten times (:data:`SPEEDUP`). (A waiting run's vehicles live in real time
until then, a resumed run's at half of it while the resumed run starts.) The wall-clock limits
(:data:`LIMIT`) are hang guards, never verdicts.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import subprocess
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import pytest
from connected_flight import FAST, log_lines
from interrupt_campaign import (
    SAFE_MODES,
    Observer,
    Sample,
    Served,
    Watch,
    on_ground,
    start_tml_run,
    stop,
    watching,
)
from pymavlink import mavutil

from sitl.model import FORCE_REBOOT
from sitl.server import Simulator
from tml.run.endings import Ending

M = mavutil.mavlink
STATES = ("running", "paused", "waiting", "continuing", "resuming")
EVENTS = ("operator", "failsafe", "reboot", "link")
"""In the order of the vehicles that get them (system ids 1 to 4): tml's ``--clock
vehicle`` reads the first vehicle, whose link is never cut."""
LIMIT = 300.0
"""Wall seconds any one state is waited for: a hang guard, never a verdict."""
SPEEDUP = 10.0
SLOW = 2.0
"""The vehicles' speed-up until their events have struck (then SPEEDUP): their hover (250 s
of their time) outlasts two wall minutes of a busy machine's delays, and tml's limits in
their seconds (``--ready-timeout``) a minute; a HEARTBEAT every half wall second keeps the
link well within ``--link-lost-limit`` on tml's wall clock."""
RETURN = {"RTL_LOIT_TIME": 0.0, "RTL_ALT": 1000.0, "LAND_SPEED": 100.0}  # a quick return
PARAMS = {**FAST, **RETURN, "BATT_FS_LOW_ACT": 1.0, "FS_GCS_ENABLE": 0.0}
RESEND = 1.0
"""Wall seconds after which an event the vehicle has not shown taken is sent again."""
LOW_MAH = 100000.0
"""BATT_LOW_MAH that raises the battery failsafe: more than the pack holds."""
SLOW_FIX = {"SIM_GPS_LOCKTIME": 60.0, "SIM_EKF_GPS_TIME": 62.0}
"""A waiting run's vehicles: not armable before 62 s of their time."""
OPTIONS = ("--clock", "vehicle", "--link-lost-limit", "2", "--ready-timeout", "120")
ALTITUDE = 20.0
HIGH = 50.0
"""The take-off a resumed run takes up: long enough a climb for ``tml run --resume`` (some
wall seconds to start) to find the vehicles still climbing."""


def mission(wait: float, altitude: float = ALTITUDE) -> str:
    return ('<mission name="Hover">\n'
            f'  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" '
            f'value="{altitude:g}"/></action></task>\n'
            f'  <task name="Stay"><action name="WAIT"><argument name="duration" '
            f'value="{wait:g}"/></action></task>\n'
            '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')


HOVER = mission(250)  # ended by the event (a longer hover is beyond the battery)
HIGH_HOVER = mission(250, HIGH)
SHORT = mission(2)  # a waiting run some event leaves flying: it flies the whole mission


@dataclass
class Cell:
    """What one vehicle of a state went through: the event's vehicle time, the observer's
    samples after it, and the run's account."""

    event_at: float = math.nan
    landed: Sample | None = None  # the first sample disarmed on the ground after the event
    last_armed: Sample | None = None  # the last sample armed before it
    armed_after: bool = False  # seen armed after the event at all
    run_status: str = ""  # how the run ended for this vehicle (completed, failed, aborted)
    run_reason: str = ""
    lines: list[dict[str, Any]] = field(default_factory=list)  # its flight log's records
    notes: dict[str, Any] = field(default_factory=dict)


@dataclass
class Flown:
    cells: dict[str, Cell]
    said: str = ""


def _sample(data: dict[str, Any] | None) -> Sample | None:
    return None if data is None else Sample(**data)


def flown(state: str, tmp_path_factory: pytest.TempPathFactory) -> Flown:
    """The state flown with its four events, once per test session: the first cell of a
    state to come flies it and leaves its account in a file beside the workers' own
    directories (pytest-xdist hands the cells of a state to either worker), the others
    wait for it under the same lock and read it."""
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    account = shared / f"safe-state-matrix-{state}.json"
    with open(shared / f"safe-state-matrix-{state}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not account.exists():
            try:
                done = FLIGHTS[state](tmp_path_factory.mktemp(state))
                text = json.dumps({"said": done.said, "cells": {
                    event: asdict(cell) for event, cell in done.cells.items()}})
            except Exception as error:  # every cell of the state says it
                text = json.dumps({"error": f"{error!r}"})
            account.write_text(text)
    found = json.loads(account.read_text())
    if "error" in found:
        raise AssertionError(f"the {state} flight failed: {found['error']}")
    return Flown({event: Cell(**{**data, "landed": _sample(data["landed"]),
                                 "last_armed": _sample(data["last_armed"])})
                  for event, data in found["cells"].items()}, found["said"])


# --- the vehicles' side ------------------------------------------------------------------


@contextlib.contextmanager
def vehicles(params: dict[str, float], speedup: float = SPEEDUP
             ) -> Iterator[tuple[Simulator, Watch, list[Any]]]:
    """Four copters, a proxy in front of each (tml's way in), an observer and another
    ground station (the events' sender) on each one's own port."""
    with Simulator(vehicles=len(EVENTS), tcp_base_port=0, speedup=speedup,
                   params=params) as sim:
        addresses = [f"tcp:127.0.0.1:{port}" for port in sim.tcp_ports]
        with watching(sim.tcp_ports, range(1, len(EVENTS) + 1), False, addresses,
                      clock=lambda: sim.time) as watch:
            others = [mavutil.mavlink_connection(address, source_system=251,
                                                 dialect="ardupilotmega")
                      for address in addresses]
            try:
                yield sim, watch, others
            finally:
                for other in others:
                    other.close()


def strike(watch: Watch, others: Sequence[Any], process: subprocess.Popen[str],
           ready: Callable[[int], bool], given_up: Callable[[int], bool],
           cells: dict[str, Cell]) -> None:
    """Each vehicle its event at its own state, the moment ``ready(vehicle)`` (its flight
    log says it hovers in the WAIT, or its run waits), not when the others have caught
    up; the link's cut lasts until ``given_up(vehicle)``. ``process``: tml's."""
    left = list(enumerate(EVENTS))
    end = time.monotonic() + LIMIT
    while left:
        alive(process, f"{[event for _, event in left]} struck", end)
        for index, event in [(i, e) for i, e in left if ready(i + 1)]:
            left.remove((index, event))
            cells[event].event_at = watch.clock()
            if event == "link":
                watch.proxies[index].cut(math.inf)
            else:  # sent again until the observer sees it taken (a frame may be lost)
                send, taken = event_of(event, index + 1, others[index],
                                       watch.observers[index])
                while True:
                    send()
                    sent = time.monotonic()
                    while not taken() and time.monotonic() - sent < RESEND:
                        alive(process, f"{event} taken by vehicle {index + 1}", end)
                        time.sleep(0.02)
                    if taken():
                        break
        time.sleep(0.05)
    link = EVENTS.index("link")
    end = time.monotonic() + LIMIT
    while not given_up(link + 1) and time.monotonic() < end:
        time.sleep(0.05)
    # Never given up (the hang guard): the link cell's failure, not the other cells'.
    cells["link"].notes["given_up"] = given_up(link + 1)
    watch.proxies[link].restore()


def event_of(event: str, sid: int, other: Any, observer: Observer
             ) -> tuple[Callable[[], None], Callable[[], bool]]:
    """How another ground station (``other``) strikes vehicle ``sid`` with ``event``, and
    how its ``observer`` sees that it took it."""
    if event == "operator":  # RTL
        return (lambda: other.mav.command_long_send(
            sid, 1, M.MAV_CMD_DO_SET_MODE, 0, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6, 0, 0, 0,
            0, 0), lambda: (latest := observer.latest()) is not None and latest.mode == "RTL")
    if event == "failsafe":  # more than the pack holds: the battery is low at once
        observer.params.pop("BATT_LOW_MAH", None)
        return (lambda: other.mav.param_set_send(sid, 1, b"BATT_LOW_MAH", LOW_MAH,
                                                 M.MAV_PARAM_TYPE_INT32),
                lambda: observer.params.get("BATT_LOW_MAH") == LOW_MAH)
    assert event == "reboot"  # forced: the new boot is disarmed
    return (lambda: other.mav.command_long_send(
        sid, 1, M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 0, 1, 0, 0, FORCE_REBOOT, 0, 0, 0),
        lambda: (latest := observer.latest()) is not None and not latest.armed)


def judge(watch: Watch, cells: dict[str, Cell]) -> None:
    """The observer's account of each vehicle from its event on, once tml is done with it
    (its run ended, or the hang guard): the last time it was seen armed, and the first
    time after that it was seen disarmed on the ground."""
    for index, event in enumerate(EVENTS):
        observer: Observer = watch.observers[index]
        cell = cells[event]
        down = observer.wait(lambda s: on_ground(s, False), cell.event_at, LIMIT)
        # A rebooted vehicle comes back on the ground where it booted (the simulator's
        # reboot; a real copter falls), armed in GUIDED up to that moment: it is judged
        # from then on -- never armed again (nothing tml sends arms it).
        since = down.time if event == "reboot" and down is not None else cell.event_at
        armed = [s for s in observer.between(since, math.inf) if s.armed]
        cell.armed_after = bool(armed)
        cell.last_armed = armed[-1] if armed else None
        cell.landed = observer.wait(lambda s: on_ground(s, False),
                                    armed[-1].time if armed else cell.event_at, LIMIT)


# --- tml's side --------------------------------------------------------------------------


def records(text: str) -> list[dict[str, Any]]:
    found = []
    for line in text.splitlines():
        with contextlib.suppress(ValueError):
            found.append(json.loads(line))
    return found


def altitude(observer: Observer) -> float:
    """The vehicle's last altitude seen (0 before any)."""
    latest = observer.latest()
    return latest.altitude or 0.0 if latest is not None else 0.0


def task_running(lines: Sequence[dict[str, Any]], vehicle: int, task: str) -> bool:
    return any(line.get("kind") == "task" and line.get("task") == task
               and line.get("state") == "running" and line.get("vehicle") == vehicle
               for line in lines)


def link_given_up(lines: Sequence[dict[str, Any]], vehicle: int) -> bool:
    """The flight log says tml gave the vehicle up for its lost link."""
    for line in lines:
        if line.get("vehicle") == vehicle and "link lost for more than" in str(
                line.get("message", "")):
            return True
        for outcome in line.get("outcomes") or ():
            if outcome.get("vehicle") == vehicle and "link lost for more than" in str(
                    outcome.get("reason", "")):
                return True
    return False


def wait_for(done: Callable[[], bool], what: str,
             process: subprocess.Popen[str] | None = None) -> None:
    """Until ``done()``; fails after LIMIT, or when ``process`` (tml) ended first."""
    end = time.monotonic() + LIMIT
    while not done():
        alive(process, what, end)
        time.sleep(0.05)


def alive(process: subprocess.Popen[str] | None, what: str, end: float) -> None:
    """Fails, saying ``what`` never came, when tml ended or the hang guard (``end``, wall)
    ran out."""
    if process is not None and process.poll() is not None:
        raise AssertionError(f"never: {what}: tml ended: {stop(process)[-1500:]}")
    assert time.monotonic() < end, f"never: {what}"


def cli_flight(tmp_path: Path, resume: bool) -> Flown:
    """``running``: tml run flying the four; ``resuming``: the same killed mid-climb and
    resumed, the take-off going on to its altitude."""
    cells = {event: Cell() for event in EVENTS}
    path, log = tmp_path / "hover.xml", tmp_path / "flight.jsonl"
    path.write_text(HIGH_HOVER if resume else HOVER)
    vids = range(1, len(EVENTS) + 1)
    with vehicles(PARAMS, SPEEDUP if resume else SLOW) as (sim, watch, others):
        process = start_tml_run(path, watch.addresses, log, *OPTIONS)
        try:
            if resume:
                wait_for(lambda: all(altitude(o) > 3.0 for o in watch.observers),
                         "mid-climb", process)
                process.kill()  # SIGKILL: no safe state, the vehicles climb on alone
                process.communicate(timeout=LIMIT)
                # Slowed so that the resumed run (some wall seconds to start) catches them
                # mid-climb; not slower, or the link would look lost on tml's wall clock.
                sim.set_speedup(0.5)
                first = len(log_lines(log))
                process = start_tml_run(path, watch.addresses, log, *OPTIONS,
                                        "--resume", str(log))
                resumed = lambda: log_lines(log)[first:]  # noqa: E731
                wait_for(lambda: all(task_running(resumed(), v, "Stay") for v in vids),
                         "the resumed take-off done", process)
                for index, event in enumerate(EVENTS):  # where the take-off ended
                    latest = watch.observers[index].latest()
                    cells[event].notes["stay_altitude"] = latest.altitude if latest else None
                cells[EVENTS[0]].notes["resumed_lines"] = resumed()
                sim.set_speedup(SPEEDUP)  # a HEARTBEAT every 2 wall s no more
                hovering = lambda v: True  # noqa: E731
            else:
                hovering = lambda v: task_running(log_lines(log), v, "Stay")  # noqa: E731
            strike(watch, others, process, hovering,
                   lambda v: link_given_up(log_lines(log), v), cells)
            sim.set_speedup(SPEEDUP)
            said = stop(process, LIMIT)
            judge(watch, cells)
        finally:
            if process.poll() is None:
                process.kill()
                process.communicate(timeout=30)
    lines = log_lines(log)
    ended = [line for line in lines if line.get("kind") == "run" and "outcomes" in line]
    assert ended, said
    for outcome in ended[-1]["outcomes"]:
        cell = cells[EVENTS[outcome["vehicle"] - 1]]
        cell.run_status, cell.run_reason = outcome["status"], outcome["reason"]
    for index, event in enumerate(EVENTS):
        cells[event].lines = [line for line in lines if line.get("vehicle") == index + 1]
    return Flown(cells, said)


def start_runs(served: Served, text: str) -> list[str]:
    """One run of ``text`` per vehicle; their ids in the order of the vehicles."""
    answer = served.client.post("/missions", content=text.encode(),
                                params={"filename": "hover.xml"},
                                headers={"Content-Type": "application/xml"})
    assert answer.status_code == 201, answer.text
    runs = []
    for vehicle in range(1, len(EVENTS) + 1):
        started = served.client.post("/runs", json={"mission": answer.json()["id"],
                                                    "vehicles": [vehicle]})
        assert started.status_code == 201, started.text
        runs.append(str(started.json()["id"]))
    return runs


def run_log(served: Served, run_id: str) -> list[dict[str, Any]]:
    return records(served.client.get(f"/runs/{run_id}/log").text)


ENDED_OTHERWISE = {e.status for e in Ending if e.status and e.exit_code is not None
                   and e is not Ending.COMPLETED} | {"failed", "aborted"}
"""How a run that did not complete ends (a service's run status, or a vehicle's outcome in
tml run's last line): docs/run.md, How a run ends."""


def served_flight(tmp_path: Path, state: str) -> Flown:
    """``paused``, ``waiting`` and ``continuing``: tml serve flying one run per vehicle."""
    cells = {event: Cell() for event in EVENTS}
    data = tmp_path / "data"
    waiting = state == "waiting"
    # Waiting: in real time until the events have struck, so that the runs are surely
    # waiting then (the service takes a few wall seconds to start), then sped up.
    with vehicles({**PARAMS, **SLOW_FIX} if waiting else PARAMS,
                  1.0 if waiting else SLOW) as (sim, watch, others):
        served = Served(watch.addresses, data, *OPTIONS)
        try:
            runs = start_runs(served, SHORT if state == "waiting" else HOVER)

            def hovering(vehicle: int) -> bool:
                return task_running(run_log(served, runs[vehicle - 1]), vehicle, "Stay")

            def paused(vehicle: int) -> bool:  # paused the moment it hovers
                if not hovering(vehicle):
                    return False
                answer = served.client.post(f"/runs/{runs[vehicle - 1]}/pause")
                assert answer.status_code == 200 and answer.json()["status"] == "paused", \
                    answer.text
                return True

            ready = {"paused": paused, "continuing": hovering}.get(state, lambda v: True)
            if state == "waiting":
                wait_for(lambda: all(served.run(r)["status"] == "waiting" for r in runs)
                         and all(any(line.get("kind") == "ready" for line in run_log(served, r))
                                 for r in runs), "every run waiting", served.process)
            if state == "continuing":
                wait_for(lambda: all(hovering(v) for v in range(1, len(runs) + 1)),
                         "every vehicle hovering", served.process)
                served.process.kill()  # SIGKILL: the service dies, the vehicles hover on
                served.process.communicate(timeout=LIMIT)
                served = Served(watch.addresses, data, *OPTIONS)
                assert all(served.run(r)["status"] == "interrupted" for r in runs)
                continued = []
                for run in runs:
                    answer = served.client.post(f"/runs/{run}/continue")
                    assert answer.status_code == 201, answer.text
                    continued.append(str(answer.json()["id"]))
                runs = continued  # each struck once its continued run hovers
            link = EVENTS.index("link")
            strike(watch, others, served.process, ready,
                   lambda v: link_given_up(run_log(served, runs[link]), v), cells)
            sim.set_speedup(SPEEDUP)
            # A run that never ends (still paused, waiting) is its own cell's failure.
            with contextlib.suppress(AssertionError):
                wait_for(lambda: all(served.ended(r) for r in runs), "every run ended",
                         served.process)
            judge(watch, cells)
            for index, event in enumerate(EVENTS):
                found = served.run(runs[index])
                cell = cells[event]
                cell.run_status, cell.run_reason = found["status"], str(found.get("reason"))
                cell.lines = run_log(served, runs[index])
        finally:
            said = served.close()
    return Flown(cells, said)


FLIGHTS: dict[str, Callable[[Path], Flown]] = {
    "running": lambda path: cli_flight(path, resume=False),
    "resuming": lambda path: cli_flight(path, resume=True),
    "paused": lambda path: served_flight(path, "paused"),
    "waiting": lambda path: served_flight(path, "waiting"),
    "continuing": lambda path: served_flight(path, "continuing"),
}

# --- the cells ---------------------------------------------------------------------------

IN_FLIGHT = [(state, event) for state in STATES if state != "waiting" for event in EVENTS]
WAITING = [("waiting", event) for event in EVENTS]


def _safe(cell: Cell, said: str) -> None:
    """The observer's verdict: disarmed on the ground after the event, and the last mode
    it was armed in is one that brings it down (never GUIDED with nobody flying it)."""
    assert cell.landed is not None, f"never seen disarmed on the ground: {said[-600:]}"
    if cell.last_armed is not None:
        assert cell.last_armed.mode in SAFE_MODES, (cell.last_armed, said[-600:])


@pytest.mark.timeout(900)
@pytest.mark.parametrize(("state", "event"), IN_FLIGHT, ids=[f"{s}-{e}" for s, e in IN_FLIGHT])
def test_a_flying_vehicle_ends_on_the_ground_whatever_happens_in_any_state(
        state: str, event: str, tmp_path_factory: pytest.TempPathFactory) -> None:
    run = flown(state, tmp_path_factory)
    cell = run.cells[event]
    _safe(cell, run.said)
    # The run ended for it (not paused, not flying on a mission for a vehicle it lost).
    assert cell.run_status in ENDED_OTHERWISE, (cell.run_status, cell.run_reason)
    expected = {"link": "link lost for more than 2 s", "operator": "switched to RTL outside tml",
                "failsafe": "switched to LAND outside tml", "reboot": "rebooted while armed"}
    assert expected[event] in cell.run_reason, cell.run_reason
    after = [line for line in cell.lines if line.get("kind") == "safety"]
    if event == "link":  # given up past the limit, commanded when heard again, seen so
        assert cell.notes["given_up"], "tml never gave the vehicle up"
        assert after and after[-1].get("confirmed"), after
        assert cell.last_armed is not None and cell.last_armed.mode == "RTL"
    else:  # taken by another: commanded no more
        taken = next(i for i, line in enumerate(cell.lines) if line.get("kind") == "taken")
        assert [line for line in cell.lines[taken:] if line.get("kind") == "request"] == []
    if state == "resuming":  # the resumed take-off went on to its altitude
        # (within the arrival tolerance, and the observer keeps a sample per half metre)
        assert run.cells[event].notes["stay_altitude"] >= HIGH - 1.5, run.cells[event].notes


@pytest.mark.timeout(900)
@pytest.mark.parametrize(("state", "event"), WAITING, ids=[f"{s}-{e}" for s, e in WAITING])
def test_a_vehicle_waited_for_is_never_flown_into_what_happened_to_it(
        state: str, event: str, tmp_path_factory: pytest.TempPathFactory) -> None:
    run = flown(state, tmp_path_factory)
    cell = run.cells[event]
    _safe(cell, run.said)
    if event == "operator":
        # A mode changed on the ground, disarmed, before the mission is the vehicle's own
        # (its pilot's switch): no take-over; the run flies its mission and lands.
        assert cell.run_status == "completed", (cell.run_status, cell.run_reason)
        return
    # The run ends before its first task, nothing sent: the vehicle never arms.
    assert cell.notes.get("given_up", True), "tml never gave the vehicle up"
    assert not cell.armed_after
    assert cell.run_status in ENDED_OTHERWISE, (cell.run_status, cell.run_reason)
    assert [line for line in cell.lines if line.get("kind") == "request"] == []
    expected = {"link": "link lost for more than 2 s", "reboot": "rebooted disarmed",
                "failsafe": "not ready after 120 s"}
    assert expected[event] in cell.run_reason, cell.run_reason
