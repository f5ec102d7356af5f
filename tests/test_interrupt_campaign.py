"""The interrupt-at-every-moment campaign on the embedded simulator (tests/interrupt_campaign.py
says how the missions, moments and verdicts are made): every case leaves every vehicle
disarmed on the ground, seen so by an observer of its own, and adds its row to
test-artifacts/interrupt-campaign.md.

The simulator runs in this process at twenty times real time, with a quicker return home
than ArduCopter's defaults (no loiter over home, a 10 m return altitude, a faster last
descent); tml runs in a process of its own. A link cut runs at twice real time while it
lasts: tml counts a link lost on its own wall clock, so the 20 s of vehicle time must last
there long enough for tml to give the vehicle up, as they would at real time (tml is told
to give up after 2 s of a lost link rather than 10, to keep the cut short). Two more cuts
are made with the vehicle's own GCS failsafe on, which then returns it during the cut;
those fly at twice real time throughout, since tml's one HEARTBEAT a wall second must come
within the failsafe's 5 s of vehicle time in plain flight.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from connected_flight import FAST
from interrupt_campaign import (
    ARTIFACTS,
    CUTS,
    FAILSAFE,
    MISSIONS,
    Moment,
    Row,
    failsafe_moments,
    fly_case,
    recorded,
    schedule,
    watching,
)

from sitl.server import Simulator

SEED = 21
SPEEDUP = 20.0
RETURN = {"RTL_LOIT_TIME": 0, "RTL_ALT": 1000, "LAND_SPEED": 100}  # a copter's return
MOMENTS = [*schedule(SEED, list(MISSIONS), per_mission=6, spread=2),
           *failsafe_moments(SEED, ["guided", "auto"])]
TABLE = ARTIFACTS / "interrupt-campaign.md"
HOW = ("The embedded simulator, `pytest tests/test_interrupt_campaign.py` (seed "
       f"{SEED}): tml run --connect (SIGINT, SIGTERM) or tml serve --connect (abort) in a "
       "process of its own; a link cut drops every frame between tml and the vehicle for "
       "20 s of vehicle time (cut-failsafe: with the vehicle's GCS failsafe on, "
       "FS_GCS_ENABLE 1). The observer is a pymavlink client of its own on each vehicle's "
       "port.")


@pytest.mark.timeout(600)
@pytest.mark.parametrize("moment", MOMENTS, ids=[m.id for m in MOMENTS])
def test_an_interrupt_at_any_moment_leaves_every_vehicle_safe(
        tmp_path: Path, moment: Moment) -> None:
    mission = MISSIONS[moment.mission]
    options = ["--link-lost-limit", "2"] if moment.interrupt in CUTS else []
    params = FAST if mission.ground else {**FAST, **RETURN}
    speedup = SPEEDUP
    if moment.interrupt == FAILSAFE:
        # tml's HEARTBEAT comes once a wall second: sped up further, the vehicle would
        # miss it for longer than FS_GCS_TIMEOUT (5 s) in plain flight.
        params, speedup = {**params, "FS_GCS_ENABLE": 1}, 2.0

    def fly() -> Row:
        with Simulator(vehicles=mission.vehicles, tcp_base_port=0, speedup=speedup,
                       params=params, frames=mission.frames) as sim:
            addresses = [f"tcp:127.0.0.1:{port}" for port in sim.tcp_ports]
            with watching(sim.tcp_ports, range(1, mission.vehicles + 1), mission.ground,
                          addresses, clock=lambda: sim.time) as watch:
                return fly_case(moment, watch, tmp_path, options,
                                slow=lambda cut: sim.set_speedup(2.0 if cut else speedup))

    row = recorded(moment, TABLE, MOMENTS, "The interrupt campaign on the embedded simulator",
                   HOW, fly)
    assert row.ok, row
