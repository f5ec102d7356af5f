"""The interrupt-at-every-moment campaign on ArduCopter SITL (tests/interrupt_campaign.py
says how the missions, moments and verdicts are made): the GUIDED, ``dispatch="mission"``
and event-handler missions, interrupted at twelve seeded moments by SIGINT, SIGTERM,
``POST /runs/{id}/abort`` and a 20 s link cut, and one more cut with ArduCopter's GCS
failsafe on (``FS_GCS_ENABLE`` 1); every case must leave the copter disarmed
on the ground, seen so by an observer of its own on the vehicle's second serial port
(SERIAL1), and adds its row to test-artifacts/interrupt-campaign-arducopter.md.

Each pytest-xdist worker flies its cases one after another on one ArduCopter, started once
(booting to armable takes some 40 s of vehicle time) and started again after a case that
failed. It runs at ten times real time; while a link cut lasts the observer sets
``SIM_SPEEDUP`` to 2, so that the 20 s of vehicle time last long enough on tml's wall
clock for it to give the vehicle up (after a 2 s ``--link-lost-limit``), as at real time.
The vehicle's own GCS failsafe is off (``FS_GCS_ENABLE`` 0, ArduCopter's default) but for
the failsafe case, flown at twice real time throughout (tml's one HEARTBEAT a wall second
must come within FS_GCS_TIMEOUT, 5 s of the copter's time, in plain flight); the table
says who brought the vehicle back, tml or the failsafe.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path

import pytest
from ardupilot_sitl import Launcher, SitlVehicle, vehicles
from interrupt_campaign import (
    ARTIFACTS,
    CUTS,
    FAILSAFE,
    Moment,
    Row,
    failsafe_moments,
    fly_case,
    recorded,
    schedule,
    watching,
)

pytestmark = pytest.mark.interop

SEED = 21
MOMENTS = [*schedule(SEED, ["guided", "auto", "event"], per_mission=4, spread=1),
           *failsafe_moments(SEED, ["guided"])]
TABLE = ARTIFACTS / "interrupt-campaign-arducopter.md"
SPEEDUP = 10.0
RETURN = {"RTL_LOIT_TIME": 0, "RTL_ALT": 1000, "LAND_SPEED": 100}  # a quicker return home
HOW = ("ArduCopter SITL (../shared/ardupilot), `pytest -m interop "
       f"tests/interop/test_interrupt_campaign_arducopter.py` (seed {SEED}): tml run "
       "--connect (SIGINT, SIGTERM) or tml serve --connect (abort) in a process of its own, "
       "through a proxy that drops every frame both ways for 20 s of vehicle time on a link "
       "cut (cut-failsafe: with ArduCopter's GCS failsafe on, FS_GCS_ENABLE 1). The "
       "observer is a pymavlink client on the copter's SERIAL1.")


class Copter:
    """One ArduCopter for a worker's cases, started again after a case that failed."""

    def __init__(self, launcher: Launcher) -> None:
        self.launcher = launcher
        self._stack = ExitStack()
        self.sitl: SitlVehicle | None = None

    def get(self) -> SitlVehicle:
        if self.sitl is None or self.sitl.process.poll() is not None:
            self.close()
            (self.sitl,) = self._stack.enter_context(
                vehicles(self.launcher, 1, "copter", speedup=SPEEDUP, params=RETURN))
        return self.sitl

    def close(self) -> None:
        self._stack.close()  # the vehicle stopped by its pid
        self.sitl = None


@pytest.fixture(scope="module")
def copter(launcher: Launcher) -> Iterator[Copter]:
    found = Copter(launcher)
    try:
        yield found
    finally:
        found.close()


@pytest.mark.timeout(900)
@pytest.mark.parametrize("moment", MOMENTS, ids=[m.id for m in MOMENTS])
def test_an_interrupt_at_any_moment_leaves_arducopter_safe(
        copter: Copter, tmp_path: Path, moment: Moment) -> None:
    options = ["--link-lost-limit", "2"] if moment.interrupt in CUTS else []

    def fly() -> Row:
        sitl = copter.get()
        with watching([sitl.port], [sitl.system_id], False, [sitl.companion_address],
                      ask_streams=True) as watch:
            observer = watch.observers[0]
            end = time.monotonic() + 120
            while observer.latest() is None or observer.now() == 0.0:
                assert time.monotonic() < end, "the observer hears nothing on SERIAL1"
                time.sleep(0.05)
            failsafe = moment.interrupt == FAILSAFE
            observer.set_param("FS_GCS_ENABLE", 1 if failsafe else 0)
            # tml's HEARTBEAT comes once a wall second: with the failsafe on, the copter
            # must hear it within FS_GCS_TIMEOUT (5 s) of its time in plain flight.
            speedup = 2.0 if failsafe else SPEEDUP
            observer.set_param("SIM_SPEEDUP", speedup)
            try:
                return fly_case(moment, watch, tmp_path, options, slow=lambda cut: (
                    observer.set_param("SIM_SPEEDUP", 2.0 if cut else speedup)))
            finally:
                observer.set_param("SIM_SPEEDUP", SPEEDUP)

    try:
        row = recorded(moment, TABLE, MOMENTS, "The interrupt campaign on ArduCopter SITL",
                       HOW, fly)
    except BaseException:
        copter.close()  # whatever state it was left in, the next case starts afresh
        raise
    if not row.ok:
        copter.close()
    assert row.ok, row
