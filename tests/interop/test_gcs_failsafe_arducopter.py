"""ArduCopter SITL: whose HEARTBEATs its GCS failsafe hears -- why every instance of a
``tml serve`` cluster sends as system 255 (docs/serve.md, "Beyond one machine").

A copter hovers at 10 m in GUIDED with ``FS_GCS_ENABLE`` 1 (RTL) and ``FS_GCS_TIMEOUT`` 5
s, flown up by a plain pymavlink ground station (tests/interop/ground_station.py). That
station closes, and a tml link takes over: as system 255 (another instance of a cluster,
its own component id), the copter stays in GUIDED; as system 251, it returns home once the
first went silent for the timeout. A copter flown up by a station sending as 251 from the
start never arms its failsafe at all. An independent pymavlink observer on the copter's
second port (system 250, which sends no HEARTBEAT) reads its mode and its clock. Vehicle
time is the copter's own ``time_boot_ms``; the runs wait for states, with hang guards.

So ``tml run --require-gcs-failsafe`` refuses a copter whose ``MAV_GCS_SYSID`` is not the
system tml sends as, and flies one whose is.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from ardupilot_sitl import SitlVehicle
from ground_station import GUIDED, GroundStation
from hop_flight import HOP
from pymavlink import mavutil

from tml.mavlink.link import Link

M = mavutil.mavlink
TIMEOUT = 5.0  # FS_GCS_TIMEOUT, s of the copter's time
PARAMS = {"FS_GCS_ENABLE": 1, "FS_GCS_TIMEOUT": TIMEOUT}
HANG = 120.0  # wall s: a hang guard, not a time limit of the verdict


class Observer:
    """The copter's mode and clock, read on its second port."""

    def __init__(self, sitl: SitlVehicle) -> None:
        self.conn: Any = mavutil.mavlink_connection(sitl.companion_address, source_system=250,
                                                    source_component=191)
        self.system_id = sitl.system_id
        self.mode = ""
        self.time = 0.0  # s since the copter booted
        self.modes: list[tuple[float, str]] = []

    def read(self, seconds: float) -> None:
        """Read what arrives for ``seconds`` of wall time (asking for ATTITUDE, the clock)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.conn.mav.request_data_stream_send(self.system_id, 1,
                                                   M.MAV_DATA_STREAM_EXTRA1, 4, 1)
            msg = self.conn.recv_match(blocking=True, timeout=0.2)
            if msg is None or msg.get_srcSystem() != self.system_id \
                    or msg.get_srcComponent() != 1:
                continue
            if msg.get_type() == "ATTITUDE":
                self.time = msg.time_boot_ms / 1000
            elif msg.get_type() == "HEARTBEAT":
                mode = mavutil.mode_string_v10(msg)
                if mode != self.mode:
                    self.mode = mode
                    self.modes.append((self.time, mode))

    def until(self, what: str, done: Any) -> None:
        end = time.monotonic() + HANG
        while not done():
            assert time.monotonic() < end, f"hung waiting for {what}: modes {self.modes}"
            self.read(0.2)

    def close(self) -> None:
        self.conn.close()


def _flown_up(sitl: SitlVehicle, source_system: int) -> None:
    """Fly the copter to 10 m in GUIDED from a station sending as ``source_system``, and
    close that station."""
    station = GroundStation(sitl.address)
    station.conn.mav.srcSystem = source_system
    try:
        station.connect()
        station.set_mode(GUIDED)
        station.arm()
        station.take_off()
    finally:
        station.close()


def _after_silence(observer: Observer, sitl: SitlVehicle, source_system: int | None,
                   component: int = 26) -> tuple[float, str]:
    """From 1 s after the last station closed, a tml link as ``source_system`` speaks to
    the copter (None: nobody). The copter's mode once three FS_GCS_TIMEOUTs of its time
    have passed since, or the mode it left GUIDED for; and how long after (its time)."""
    observer.until("the copter's clock", lambda: observer.time > 0.0)
    silent_since = observer.time
    observer.read(1.0)

    def decided() -> bool:
        return observer.time - silent_since > 3 * TIMEOUT or observer.mode != "GUIDED"

    if source_system is None:
        observer.until("three FS_GCS_TIMEOUTs, or a failsafe", decided)
    else:
        with Link(sitl.address, source_system=source_system, source_component=component):
            observer.until("three FS_GCS_TIMEOUTs, or a failsafe", decided)
    return observer.time - silent_since, observer.mode


@pytest.mark.timeout(600)
def test_a_second_station_as_system_255_keeps_the_failsafe_quiet_one_as_251_does_not(
        ardupilot: Any) -> None:
    (sitl,) = ardupilot(speedup=1, params=PARAMS)
    observer = Observer(sitl)
    try:
        _flown_up(sitl, 255)
        after, mode = _after_silence(observer, sitl, 255)
        assert mode == "GUIDED", (after, observer.modes)  # a takeover: no failsafe
        # That one closed too; one as 251 now: the failsafe acts on 255's silence.
        after, mode = _after_silence(observer, sitl, 251)
        assert mode == "RTL", (after, observer.modes)
        assert after <= TIMEOUT + 3.0, (after, observer.modes)
    finally:
        observer.close()


@pytest.mark.timeout(600)
def test_a_copter_that_never_heard_system_255_has_no_gcs_failsafe(ardupilot: Any) -> None:
    (sitl,) = ardupilot(speedup=1, params=PARAMS)
    observer = Observer(sitl)
    try:
        _flown_up(sitl, 251)
        after, mode = _after_silence(observer, sitl, None)
        # Nobody speaks to it, and nothing ever said was the GCS's: still in GUIDED after
        # three timeouts.
        assert mode == "GUIDED", (after, observer.modes)
    finally:
        observer.close()


@pytest.mark.timeout(600)
@pytest.mark.parametrize("station", [250, 255])
def test_tml_run_refuses_a_copter_whose_failsafe_hears_another_station(
        ardupilot: Any, tmp_path: Path, station: int) -> None:
    # At speed-up 10 tml's 1 Hz HEARTBEAT is 10 s of the copter's time apart: a timeout
    # of 30 s lets it fly.
    (sitl,) = ardupilot(params={**PARAMS, "FS_GCS_TIMEOUT": 30, "MAV_GCS_SYSID": station})
    mission = tmp_path / "hop.xml"
    mission.write_text(HOP)
    run = subprocess.run([sys.executable, "-m", "tml", "run", str(mission), "--connect",
                          sitl.address, "--clock", "vehicle", "--timeout", "120",
                          "--require-gcs-failsafe"], capture_output=True, text=True,
                         timeout=500)
    said = run.stdout + run.stderr
    assert "Traceback" not in said
    if station == 255:
        assert run.returncode == 0 and "MAV_GCS_SYSID" not in said, said
        return
    assert run.returncode == 4, said
    assert ("vehicle 1: MAV_GCS_SYSID is 250 and tml sends as system 255: the vehicle's "
            "GCS failsafe hears only system 250's HEARTBEATs") in said
    assert "not flown (--require-gcs-failsafe)" in said
