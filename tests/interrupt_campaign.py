"""The interrupt-at-every-moment campaign: five missions of different shape, each
interrupted at seeded moments, and an independent observer's verdict on every vehicle.

*Missions* (:data:`MISSIONS`): a GUIDED hop, a ``dispatch="mission"`` flight flown by the
autopilot in AUTO, a hop with an event handler that sends the vehicle on a detour, a fleet
of two copters flying one mission, and a rover's drive.

*Moments* (:func:`schedule`) are drawn from ``random.Random(seed)``, so every run of the
suite interrupts at the same ones. A moment is a request as the vehicle sees it (the
first ``SET_MODE GUIDED``, ``ARM``, ``NAV_TAKEOFF``, ``MISSION_START`` ... frame that
tml sends up the link) and an offset in vehicle seconds after it: most offsets fall in the
first two seconds after a request, where a half-done request is most easily forgotten,
and some are spread over the whole run (anchored on the first request). Each moment has
one interrupt of :data:`INTERRUPTS`: SIGINT or SIGTERM to ``tml run --connect`` (its own
process, by pid), ``POST /runs/{id}/abort`` on a ``tml serve --connect`` process, or a
20 s cut of the link between tml and the vehicle (every frame dropped both ways for 20 s
of vehicle time, then the link restored). A few more cuts (:func:`failsafe_moments`) are
made with the vehicle's own GCS failsafe on, which then acts during the cut.

*The vehicle's side* is watched through :class:`Watch`: each vehicle is reached by tml
through a :class:`~lossy_proxy.LossyProxy` (which also cuts the link), whose upward
frames name the requests and their vehicle time; an :class:`Observer` -- a plain pymavlink
client of its own on the vehicle's port (the simulator's port takes several clients,
ArduPilot SITL's second serial port), never tml's log -- records every vehicle's mode,
armed state, altitude and landed state.

*The verdict* (:func:`fly_case`) is the observer's: after the interrupt every vehicle is
seen disarmed on the ground (a rover: disarmed); the row says in which modes a flying one
came down (RTL; LAND for one that was landing) and how many vehicle seconds after the
interrupt it was first seen in one and on the ground. For a link cut it also says who acted:
tml once it heard the vehicle again, or the vehicle's own GCS failsafe during the cut.
States are waited for with generous wall-clock hang guards; no fixed sleep decides.

:func:`write_table` renders the rows (each case leaves one JSON file beside the table, so
pytest-xdist workers need not share anything) as a Markdown table in ``test-artifacts/``.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import random
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from lossy_proxy import LossyProxy
from pymavlink import mavutil

from tml.run.endings import Ending

ROOT = Path(__file__).resolve().parent.parent
ARTIFACTS = Path(os.environ.get("TML_TEST_ARTIFACTS") or ROOT / "test-artifacts")
HANG = 240.0
"""Wall seconds any one state is waited for: a hang guard, never a verdict."""
CUT = 20.0
"""Vehicle seconds of a link cut."""
DENSE = 2.0
"""Vehicle seconds after a request within which the dense moments fall."""
INTERRUPTS = ("SIGINT", "SIGTERM", "abort", "cut")
FAILSAFE = "cut-failsafe"
"""A link cut with the vehicle's own GCS failsafe on (FS_GCS_ENABLE 1: RTL)."""
CUTS = ("cut", FAILSAFE)
M = mavutil.mavlink

# --- the missions ------------------------------------------------------------------------


def _task(name: str, action: str, **arguments: object) -> str:
    args = "".join(f'<argument name="{k}" value="{v}"/>' for k, v in arguments.items())
    return f'  <task name="{name}"><action name="{action}">{args}</action></task>\n'


@dataclass(frozen=True)
class CampaignMission:
    """A mission of the campaign: its text, the vehicles that fly it, the requests its
    moments may be anchored on (as the vehicle sees them), and how long its run lasts
    from the first request, in vehicle seconds (the span of the spread moments)."""

    name: str
    shape: str
    text: str
    anchors: tuple[str, ...]
    duration: float
    vehicles: int = 1
    frames: tuple[str, ...] = ("copter",)

    @property
    def ground(self) -> bool:
        """Whether its vehicles are ground vehicles (their safe state is disarmed)."""
        return self.frames == ("rover",)


HOP = ('<mission name="Hop">\n' + _task("Up", "TAKE_OFF", altitude=6)
       + _task("Out", "GO_TO_POINT", coordinates="(25, 0, 6)")
       + _task("Down", "LAND") + "</mission>\n")
AUTO = ('<mission name="Auto hop">\n' + _task("Up", "TAKE_OFF", altitude=6)
        + '  <task name="Flown by the autopilot" dispatch="mission">\n'
        + _task("Out", "GO_TO_POINT", coordinates="(20, 10, 8)")
        + _task("Back", "GO_TO_POINT", coordinates="(0, 0, 8)")
        + _task("Down", "LAND") + "  </task>\n</mission>\n")
DETOUR = ('<mission name="Hop with a detour">\n' + _task("Up", "TAKE_OFF", altitude=6)
          + _task("Out", "GO_TO_POINT", coordinates="(25, 0, 6)")
          + _task("Down", "LAND")
          + '  <event_handling>\n    <event name="High enough">\n'
          + '      <condition parameter="ALTITUDE" comparison="greater than" value="4"/>\n'
          + '      <action name="GO_TO_POINT"><argument name="coordinates" '
          + 'value="(0, 15, 6)"/></action>\n'
          + '      <termination mode="NEXT_TASK"/>\n    </event>\n  </event_handling>\n'
          + "</mission>\n")
DRIVE = ('<mission name="Drive">\n' + _task("Out", "GO_TO_POINT", coordinates="(30, 0, 0)")
         + _task("Across", "GO_TO_POINT", coordinates="(30, 20, 0)")
         + _task("Home", "RETURN_HOME_AND_LAND") + "</mission>\n")

MISSIONS: dict[str, CampaignMission] = {m.name: m for m in (
    CampaignMission("guided", "GUIDED: take off, a leg, land", HOP,
                    ("SET_MODE GUIDED", "ARM", "NAV_TAKEOFF", "NAV_LAND"), 20.0),
    CampaignMission("auto", 'dispatch="mission": a leg flown in AUTO', AUTO,
                    ("ARM", "NAV_TAKEOFF", "SET_MODE AUTO"), 30.0),
    CampaignMission("event", "an event handler's detour", DETOUR,
                    ("ARM", "NAV_TAKEOFF", "NAV_LAND"), 25.0),
    CampaignMission("fleet", "a fleet of two copters", HOP,
                    ("ARM", "NAV_TAKEOFF", "NAV_LAND"), 20.0, vehicles=2),
    CampaignMission("rover", "a rover's drive", DRIVE,
                    ("SET_MODE GUIDED", "ARM", "NAV_RTL"), 25.0, frames=("rover",)),
)}


# --- the moments -------------------------------------------------------------------------


@dataclass(frozen=True)
class Moment:
    """One case: a mission interrupted ``offset`` vehicle seconds after its vehicle (the
    first) saw the request ``anchor`` ("start": its first request)."""

    mission: str
    interrupt: str
    anchor: str
    offset: float

    @property
    def id(self) -> str:
        anchor = self.anchor.replace(" ", "-")
        return f"{self.mission}-{self.interrupt}-{anchor}+{self.offset:.2f}"

    @property
    def label(self) -> str:
        """The moment as the table says it."""
        return f"{self.anchor} + {self.offset:.2f} s"


def schedule(seed: int, missions: Sequence[str], per_mission: int, spread: int,
             interrupts: Sequence[str] = INTERRUPTS) -> list[Moment]:
    """``per_mission`` moments for each of ``missions``: ``spread`` of them anywhere in the
    run (from its first request), the rest within :data:`DENSE` s after one of the
    mission's requests; the interrupts go round ``interrupts`` so that each mission meets
    every kind. The same ``seed`` gives the same moments."""
    rng = random.Random(seed)
    moments: list[Moment] = []
    for index, name in enumerate(missions):
        mission = MISSIONS[name]
        kinds = list(interrupts)
        rng.shuffle(kinds)
        for n in range(per_mission):
            interrupt = kinds[(n + index) % len(kinds)]
            if n < spread:
                anchor, offset = "start", rng.uniform(0.0, mission.duration)
            else:
                anchor, offset = rng.choice(mission.anchors), rng.uniform(0.0, DENSE)
            moments.append(Moment(name, interrupt, anchor, round(offset, 2)))
    return moments


def failsafe_moments(seed: int, missions: Sequence[str]) -> list[Moment]:
    """A link cut with the vehicle's GCS failsafe on for each of ``missions``, within
    :data:`DENSE` s after one of its requests (seeded apart from :func:`schedule`)."""
    rng = random.Random(f"{seed}/failsafe")
    found = []
    for name in missions:
        anchors = MISSIONS[name].anchors
        anchor = rng.choice(anchors[anchors.index("NAV_TAKEOFF"):])  # once it flies
        found.append(Moment(name, FAILSAFE, anchor, round(rng.uniform(0.0, DENSE), 2)))
    return found


# --- what the vehicles see ---------------------------------------------------------------

COPTER_MODES = {0: "STABILIZE", 3: "AUTO", 4: "GUIDED", 5: "LOITER", 6: "RTL", 9: "LAND",
                16: "POSHOLD", 17: "BRAKE", 21: "SMART_RTL"}
ROVER_MODES = {0: "MANUAL", 4: "HOLD", 5: "LOITER", 10: "AUTO", 11: "RTL", 12: "SMART_RTL",
               15: "GUIDED"}


def mode_name(custom_mode: int, rover: bool) -> str:
    """ArduCopter's (ArduRover's) name for a custom mode number."""
    return (ROVER_MODES if rover else COPTER_MODES).get(int(custom_mode), str(custom_mode))


def request_name(msg: Any, rover: bool) -> str | None:
    """The request a frame from the ground station carries, as the campaign names it
    ("ARM", "NAV_TAKEOFF", "SET_MODE GUIDED" ...), or None for anything else."""
    kind = msg.get_type()
    if kind == "SET_MODE":
        return f"SET_MODE {mode_name(msg.custom_mode, rover)}"
    if kind not in ("COMMAND_LONG", "COMMAND_INT"):
        return None
    command = msg.command
    if command == M.MAV_CMD_COMPONENT_ARM_DISARM:
        return "ARM" if msg.param1 == 1 else "DISARM"
    if command == M.MAV_CMD_DO_SET_MODE:
        return f"SET_MODE {mode_name(msg.param2, rover)}"
    names = {M.MAV_CMD_NAV_TAKEOFF: "NAV_TAKEOFF", M.MAV_CMD_MISSION_START: "MISSION_START",
             M.MAV_CMD_NAV_LAND: "NAV_LAND", M.MAV_CMD_NAV_RETURN_TO_LAUNCH: "NAV_RTL",
             M.MAV_CMD_DO_REPOSITION: "DO_REPOSITION"}
    return names.get(command)


@dataclass
class Sample:
    """What the observer last saw of one vehicle."""

    time: float  # vehicle seconds
    mode: str
    armed: bool
    altitude: float | None  # m above home
    landed: bool | None  # EXTENDED_SYS_STATE (None: not reported)


class Observer:
    """A ground station of its own on one vehicle's port: every HEARTBEAT,
    GLOBAL_POSITION_INT and EXTENDED_SYS_STATE of the autopilot, kept with the vehicle time
    it arrived at (``clock``; None: the vehicle's own ``time_boot_ms``), in a thread of
    its own until :meth:`close`. It sends nothing but a request for telemetry streams (an
    ArduPilot serial port other than the first streams nothing unasked)."""

    def __init__(self, address: str, system_id: int, rover: bool,
                 clock: Callable[[], float] | None = None, ask_streams: bool = False) -> None:
        self.system_id, self.rover = system_id, rover
        self._clock = clock
        self.boot_time = 0.0
        self.samples: list[Sample] = []
        self.confirmed = -math.inf  # vehicle time of the latest message a sample stands for
        self.texts: list[tuple[float, str]] = []
        self.params: dict[str, float] = {}  # the PARAM_VALUEs heard
        self._mode, self._armed = "", False
        self._altitude: float | None = None
        self._landed: bool | None = None
        self._heard = False
        self._changed = threading.Condition()
        self._running = True
        self.conn: Any = mavutil.mavlink_connection(address, source_system=250,
                                                    source_component=191,
                                                    dialect="ardupilotmega")
        if ask_streams:
            for stream in (M.MAV_DATA_STREAM_POSITION, M.MAV_DATA_STREAM_EXTENDED_STATUS,
                           M.MAV_DATA_STREAM_EXTRA3):
                self.conn.mav.request_data_stream_send(system_id, 1, stream, 10, 1)
        self._thread = threading.Thread(target=self._read, daemon=True,
                                        name=f"observer {system_id}")
        self._thread.start()

    def now(self) -> float:
        """The vehicle's time."""
        return self._clock() if self._clock is not None else self.boot_time

    def _read(self) -> None:
        while self._running:
            try:
                msg = self.conn.recv_match(blocking=True, timeout=0.2)
            except (OSError, ValueError):
                return
            if msg is None or msg.get_srcSystem() != self.system_id \
                    or msg.get_srcComponent() != 1:
                continue
            kind = msg.get_type()
            if hasattr(msg, "time_boot_ms"):
                self.boot_time = max(self.boot_time, msg.time_boot_ms / 1000.0)
            if kind == "HEARTBEAT":
                self._mode = mode_name(msg.custom_mode, self.rover)
                self._armed = bool(msg.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
                self._heard = True
            elif kind == "GLOBAL_POSITION_INT":
                self._altitude = msg.relative_alt / 1000.0
            elif kind == "EXTENDED_SYS_STATE":
                if msg.landed_state:
                    self._landed = msg.landed_state == M.MAV_LANDED_STATE_ON_GROUND
            elif kind == "STATUSTEXT":
                self.texts.append((self.now(), msg.text))
                continue
            elif kind == "PARAM_VALUE":
                with self._changed:
                    self.params[msg.param_id] = msg.param_value
                    self._changed.notify_all()
                continue
            else:
                continue
            if self._heard:
                sample = Sample(self.now(), self._mode, self._armed, self._altitude,
                                self._landed)
                with self._changed:
                    if not self.samples or (sample.mode, sample.armed, sample.landed) != (
                            self.samples[-1].mode, self.samples[-1].armed,
                            self.samples[-1].landed) or _moved(self.samples[-1], sample):
                        self.samples.append(sample)
                    self.confirmed = sample.time  # the latest sample still holds then
                    self._changed.notify_all()

    def between(self, start: float, end: float) -> list[Sample]:
        """The samples from vehicle time ``start`` to ``end``."""
        with self._changed:
            return [s for s in self.samples if start <= s.time <= end]

    def latest(self) -> Sample | None:
        """The last sample, if any."""
        with self._changed:
            return self.samples[-1] if self.samples else None

    def wait(self, done: Callable[[Sample], bool], after: float, limit: float = HANG
             ) -> Sample | None:
        """The first sample from vehicle time ``after`` on for which ``done`` holds, waited
        for up to ``limit`` wall seconds (None then)."""
        end = time.monotonic() + limit
        with self._changed:
            while True:
                for sample in self.samples:
                    if sample.time >= after and done(sample):
                        return sample
                # Samples are kept on a change only: a vehicle that was (and stays) on the
                # ground when the interrupt came shows no new one, only messages saying the
                # same after it (a fleet's second copter not yet armed on a busy machine).
                last = self.samples[-1] if self.samples else None
                if last is not None and last.time < after <= self.confirmed and done(last):
                    return replace(last, time=after)
                left = end - time.monotonic()
                if left <= 0:
                    return None
                self._changed.wait(min(left, 0.5))

    def set_param(self, name: str, value: float) -> None:
        """Set a parameter of the vehicle and wait for its echo (a simulation control
        such as SIM_SPEEDUP, or the vehicle's own failsafe for a case)."""
        end = time.monotonic() + HANG
        with self._changed:
            self.params.pop(name, None)
            while self.params.get(name) != value:
                assert time.monotonic() < end, f"{name} = {value} was never taken"
                self.conn.mav.param_set_send(self.system_id, 1, name.encode(), value,
                                             M.MAV_PARAM_TYPE_REAL32)
                self._changed.wait(0.5)

    def close(self) -> None:
        self._running = False
        self._thread.join(timeout=5)
        with contextlib.suppress(OSError):
            self.conn.close()


def _moved(a: Sample, b: Sample) -> bool:
    """Whether the altitude changed by more than half a metre (kept, not every reading)."""
    if a.altitude is None or b.altitude is None:
        return a.altitude != b.altitude
    return abs(a.altitude - b.altitude) > 0.5


def on_ground(sample: Sample, rover: bool) -> bool:
    """Disarmed on the ground (a rover: disarmed)."""
    if sample.armed:
        return False
    if rover:
        return True
    if sample.landed is not None:
        return sample.landed and (sample.altitude is None or sample.altitude < 1.0)
    return sample.altitude is not None and sample.altitude < 0.5


SAFE_MODES = frozenset({"RTL", "LAND", "SMART_RTL"})


@dataclass
class Requests:
    """The requests one vehicle saw, in order: (vehicle time, name), from the frames its
    proxy passed up the link."""

    rover: bool
    clock: Callable[[], float]
    seen: list[tuple[float, str]] = field(default_factory=list)
    _arrived: threading.Event = field(default_factory=threading.Event)

    def message(self, msg: Any) -> None:
        name = request_name(msg, self.rover)
        if name is not None:
            self.seen.append((self.clock(), name))
            self._arrived.set()

    def first(self, name: str) -> float | None:
        """When the vehicle first saw ``name`` ("start": any request)."""
        for when, seen in list(self.seen):
            if name in ("start", seen):
                return when
        return None

    def wait(self, name: str, alive: Callable[[], bool], limit: float = HANG) -> float | None:
        """When ``name`` was first seen, waited for while ``alive()``; None when tml ended
        (or the hang guard ran out) first."""
        end = time.monotonic() + limit
        while time.monotonic() < end:
            found = self.first(name)
            if found is not None:
                return found
            if not alive():
                return self.first(name)
            self._arrived.wait(0.05)
            self._arrived.clear()
        return None


# --- one case ----------------------------------------------------------------------------


@dataclass
class Watch:
    """The vehicles of one case and what is between them and tml: a proxy and an
    observer each, and the vehicle clock of the first."""

    proxies: list[LossyProxy]
    observers: list[Observer]
    requests: list[Requests]
    clock: Callable[[], float]

    @property
    def addresses(self) -> list[str]:
        """Where tml reaches each vehicle: its proxy."""
        return [p.address for p in self.proxies]


@contextlib.contextmanager
def watching(ports: Sequence[int], system_ids: Sequence[int], rover: bool,
             observer_addresses: Sequence[str], clock: Callable[[], float] | None = None,
             ask_streams: bool = False) -> Iterator[Watch]:
    """A proxy on each vehicle port of ``ports`` (tml's way in) and an observer on each of
    ``observer_addresses``; ``clock`` the vehicles' time (None: the first observer's
    reading of the vehicle's own time)."""
    proxies: list[LossyProxy] = []
    observers: list[Observer] = []
    try:
        for address, sid in zip(observer_addresses, system_ids, strict=True):
            observers.append(Observer(address, sid, rover, clock, ask_streams))
        vehicle_clock = clock or observers[0].now
        requests = [Requests(rover, vehicle_clock) for _ in ports]
        for port, seen in zip(ports, requests, strict=True):
            proxy = LossyProxy(port, loss=0.0, seed=0, lifetime=3600.0)
            proxy.up.on_message = seen.message
            proxies.append(proxy.start())
        yield Watch(proxies, observers, requests, vehicle_clock)
    finally:
        for observer in observers:
            observer.close()
        for proxy in proxies:
            proxy.stop()


@dataclass
class Row:
    """One line of the table."""

    id: str
    mission: str
    interrupt: str
    moment: str
    at: str  # the moment as met: the request and the offset actually reached
    safe: str  # the safe state the observer saw, per vehicle
    seconds: str  # vehicle seconds from the interrupt to the safe state, per vehicle
    landed: str  # vehicle seconds from the interrupt to disarmed on the ground
    tml: str  # how tml ended
    ok: bool
    commanded: str = ""  # what tml's flight log says it commanded for safety, in order


def wait_vehicle_time(clock: Callable[[], float], until: float, alive: Callable[[], bool],
                      limit: float = HANG) -> None:
    """Until the vehicle clock reads ``until`` (or tml has ended, or the hang guard)."""
    end = time.monotonic() + limit
    while clock() < until and time.monotonic() < end and alive():
        time.sleep(0.002)


def start_tml_run(mission: Path, addresses: Sequence[str], log: Path, *options: str
                  ) -> subprocess.Popen[str]:
    """``tml run --connect`` each of ``addresses``, in its own process."""
    connect = [arg for address in addresses for arg in ("--connect", address)]
    return subprocess.Popen(
        [sys.executable, "-m", "tml", "run", str(mission), *connect, "-q", "--log", str(log),
         *options], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True)


def stop(process: subprocess.Popen[str], timeout: float = HANG) -> str:
    """What the process said, once it has ended (killed by its pid after ``timeout``)."""
    try:
        out, _ = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        out, _ = process.communicate(timeout=30)
        out += "\n(killed: it did not end)"
    return out or ""


class Served:
    """``tml serve --connect`` in its own process, and its HTTP API."""

    def __init__(self, addresses: Sequence[str], data: Path, *options: str) -> None:
        import httpx
        from serving import free_port

        self.port = free_port()
        connect = [arg for address in addresses for arg in ("--connect", address)]
        self.process = subprocess.Popen(
            [sys.executable, "-m", "tml", "serve", *connect, "--port", str(self.port),
             "--data", str(data), *options], stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True, start_new_session=True)
        assert self.process.stdout is not None
        said = ""
        while not (line := self.process.stdout.readline()).startswith("tml serve: http://"):
            assert line, said
            said += line
        self.client = httpx.Client(base_url=f"http://127.0.0.1:{self.port}", timeout=60)
        end = time.monotonic() + HANG
        while True:
            try:
                self.client.get("/status")
                break
            except httpx.TransportError:
                assert self.process.poll() is None and time.monotonic() < end
                time.sleep(0.05)

    def start(self, text: str, profile: str) -> str:
        answer = self.client.post("/missions", content=text.encode(),
                                  params={"filename": "campaign.xml"},
                                  headers={"Content-Type": "application/xml"})
        assert answer.status_code == 201, answer.text
        vehicles = [v["id"] for v in self.client.get("/vehicles").json()]
        started = self.client.post("/runs", json={"mission": answer.json()["id"],
                                                  "vehicles": vehicles, "profile": profile})
        assert started.status_code == 201, started.text
        return str(started.json()["id"])

    def run(self, run_id: str) -> dict[str, Any]:
        return dict(self.client.get(f"/runs/{run_id}").json())

    def ended(self, run_id: str) -> bool:
        # Every status a run that ended in the service has (docs/run.md, How a run ends).
        return self.run(run_id)["status"] in {e.status for e in Ending
                                              if e.status and e.exit_code is not None}

    def close(self) -> str:
        with contextlib.suppress(Exception):
            self.client.close()
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        return stop(self.process)


def fly_case(moment: Moment, watch: Watch, tmp_path: Path, tml_options: Sequence[str] = (),
             cut_seconds: float = CUT, slow: Callable[[bool], None] | None = None) -> Row:
    """Fly ``moment``'s mission through ``watch``, interrupt it at the moment, and judge
    from the observers; the row (``ok``: every vehicle safe). ``slow(True)`` is called as
    a link cut starts and ``slow(False)`` as it ends (a simulator runs the cut nearer real
    time, so that it lasts on tml's wall clock too)."""
    mission = MISSIONS[moment.mission]
    path = tmp_path / "mission.xml"
    path.write_text(mission.text)
    served: Served | None = None
    process: subprocess.Popen[str]
    run_id = ""
    if moment.interrupt == "abort":
        served = Served(watch.addresses, tmp_path / "data", *tml_options)
        process = served.process
        run_id = served.start(mission.text, "rover" if mission.ground else "quadcopter")

        asked = [0.0, True]  # when the service was last asked, and whether it flew then

        def alive() -> bool:
            if process.poll() is not None:
                return False
            if time.monotonic() - asked[0] > 0.2:  # not an HTTP request every few ms
                asked[:] = [time.monotonic(), not served.ended(run_id)]
            return bool(asked[1])
    else:
        process = start_tml_run(path, watch.addresses, tmp_path / "flight.jsonl",
                                *tml_options, *(["--profile", "rover"] if mission.ground
                                                else []))

        def alive() -> bool:
            return process.poll() is None
    said, ended_first = "", False
    try:
        anchor_at = watch.requests[0].wait(moment.anchor, alive)
        if anchor_at is None:
            said = "" if served is not None or process.poll() is None else stop(process)
            raise AssertionError(f"the vehicle never saw {moment.anchor}: "
                                 f"{watch.requests[0].seen} {said}")
        wait_vehicle_time(watch.clock, anchor_at + moment.offset, alive)
        at = watch.clock()
        ended_first = not alive()
        cut_end: float | None = None
        if not ended_first:
            if moment.interrupt == "SIGINT":
                process.send_signal(signal.SIGINT)
            elif moment.interrupt == "SIGTERM":
                process.send_signal(signal.SIGTERM)
            elif moment.interrupt == "abort":
                assert served is not None
                answer = served.client.post(f"/runs/{run_id}/abort")
                assert answer.status_code in (200, 409), answer.text
            else:  # a link cut
                for proxy in watch.proxies:
                    proxy.cut(math.inf)
                if slow is not None:
                    slow(True)
                wait_vehicle_time(watch.clock, at + cut_seconds, lambda: True)
                for proxy in watch.proxies:
                    proxy.restore()
                if slow is not None:
                    slow(False)
                cut_end = watch.clock()
        results = [_judge(observer, at, mission.ground, cut_end)
                   for observer in watch.observers]
        if served is not None:
            end = time.monotonic() + HANG
            while not served.ended(run_id) and time.monotonic() < end:
                time.sleep(0.1)
            status = served.run(run_id)
            said = f"run {status['status']}, exit {status.get('exit_code')}"
            log = served.client.get(f"/runs/{run_id}/log").text
        else:
            out = stop(process)
            said = f"exit {process.returncode}: {_outcome(out)}"
            log = (tmp_path / "flight.jsonl").read_text() \
                if (tmp_path / "flight.jsonl").exists() else ""
        commanded = safety_lines(log)
    finally:
        if served is not None:
            tail = served.close()
            said = said or tail[-300:]
        elif process.poll() is None:
            process.kill()
            process.communicate(timeout=30)
    ok = all(result[3] for result in results)
    offset = at - anchor_at
    return Row(moment.id, moment.mission, moment.interrupt, moment.label,
               f"{moment.anchor} + {offset:.2f} s" + (" (tml had ended)" if ended_first
                                                       else ""),
               "; ".join(r[0] for r in results), "; ".join(r[1] for r in results),
               "; ".join(r[2] for r in results), said, ok, commanded)


def safety_lines(log: str) -> str:
    """The safety steps of a flight log (JSON lines), each as "vehicle: message"."""
    steps = []
    for text in log.splitlines():
        with contextlib.suppress(ValueError):
            line = json.loads(text)
            if line.get("kind") == "safety":
                steps.append(f"{line.get('vehicle')}: {line.get('message', '')}")
    return "; ".join(steps)


def _outcome(out: str) -> str:
    """The line of tml's output that says how the mission ended."""
    lines = [line.strip() for line in out.splitlines() if line.strip()]
    said = [line for line in lines if "mission " in line] or lines[-1:]
    return said[0][:100] if said else ""


def _judge(observer: Observer, at: float, rover: bool, cut_end: float | None
           ) -> tuple[str, str, str, bool]:
    """(safe state seen, seconds to it, seconds to disarmed on the ground, safe) of one
    vehicle interrupted at vehicle time ``at``."""
    landed = observer.wait(lambda s: on_ground(s, rover), at)
    if landed is None:
        last = observer.latest()
        return (f"NOT SAFE: {last}", "-", "-", False)
    safe = observer.wait(lambda s: s.mode in SAFE_MODES or on_ground(s, rover), at, 0)
    assert safe is not None  # the landing itself at least
    if on_ground(safe, rover):
        seen = "disarmed" if rover else "disarmed on the ground"
    else:  # the modes it flew in from the first safe one to the ground
        modes: list[str] = []
        for sample in observer.between(safe.time, landed.time):
            if sample.armed and (modes or sample.mode in SAFE_MODES) \
                    and (not modes or modes[-1] != sample.mode):
                modes.append(sample.mode)
        seen = f"{' → '.join(modes or [safe.mode])}, then landed"
    if cut_end is not None and not on_ground(safe, rover):
        failsafe = any("GCS Failsafe" in text and at <= when <= cut_end
                       for when, text in observer.texts)
        seen += (" (GCS failsafe, during the cut)" if failsafe and safe.time <= cut_end
                 else " (tml, after the link came back)" if safe.time >= cut_end
                 else " (during the cut)")
    return (seen, f"{safe.time - at:.1f}", f"{landed.time - at:.1f}", True)


# --- the table ---------------------------------------------------------------------------


def recorded(moment: Moment, table: Path, moments: Sequence[Moment], title: str, how: str,
             fly: Callable[[], Row]) -> Row:
    """``fly()``'s row for ``moment``, kept for the table (:func:`record`); a case that
    raised is kept as a failed row saying why, and raises on."""
    try:
        row = fly()
    except BaseException as error:
        record(Row(moment.id, moment.mission, moment.interrupt, moment.label, "-",
                   f"error: {str(error).splitlines()[0][:200] if str(error) else repr(error)}",
                   "-", "-", "-", False), table, moments, title, how)
        raise
    record(row, table, moments, title, how)
    return row


def record(row: Row, table: Path, moments: Sequence[Moment], title: str, how: str) -> None:
    """Keep ``row`` beside ``table`` and render the table again from every row kept for
    ``moments`` (each case its own file: pytest-xdist workers share nothing but a lock)."""
    rows = table.with_suffix("")
    rows.mkdir(parents=True, exist_ok=True)
    (rows / f"{row.id}.json").write_text(json.dumps(asdict(row)))
    with (rows / ".lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        write_table(table, moments, title, how)


def write_table(table: Path, moments: Sequence[Moment], title: str, how: str) -> None:
    """The Markdown table of every moment's row (a moment not flown yet says so)."""
    rows = table.with_suffix("")
    shapes = "; ".join(f"{m.name}: {m.shape}" for m in MISSIONS.values()
                       if any(moment.mission == m.name for moment in moments))
    lines = [f"# {title}", "", how, "", f"Missions: {shapes}.", "",
             "| mission | interrupt | moment (request + offset) | met at | safe state seen "
             "by the observer | s to safe | s to on the ground | tml | tml's safety steps "
             "(flight log) |",
             "|---|---|---|---|---|---|---|---|---|"]
    flown = 0
    for moment in moments:
        path = rows / f"{moment.id}.json"
        if not path.exists():
            lines.append(f"| {moment.mission} | {moment.interrupt} | {moment.label} | not "
                         "flown | | | | | |")
            continue
        flown += 1
        row = json.loads(path.read_text())
        mark = "" if row["ok"] else " **(FAILED)**"
        lines.append(f"| {row['mission']} | {row['interrupt']} | {row['moment']} | "
                     f"{row['at']} | {row['safe']}{mark} | {row['seconds']} | "
                     f"{row['landed']} | {row['tml'].replace('|', '/')} | "
                     f"{row.get('commanded', '').replace('|', '/')} |")
    lines += ["", f"{flown} of {len(moments)} moments flown; seconds are the vehicle's."]
    table.write_text("\n".join(lines) + "\n")
