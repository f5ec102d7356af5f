"""The flight session: the one way in for ``tml run``, ``tml serve`` and ``tml companion``.

Theory of operation
-------------------
A command parses its arguments into :class:`SessionOptions` (typed: nothing of the command
line parser goes below ``tml/commands``) and opens a :class:`Session` with
:func:`open_session`. The session

1. opens the vehicles: the embedded simulator, through the factory the command passes
   (``tml/run`` does not import ``sitl``), and a link to each of its vehicles; or a link
   per ``--connect`` address, each waited for (``timeout``) and its vehicle found: the
   one it hears, or those named by system id (``--sysid``); a link that hears several
   vehicles when none is named is :class:`SeveralVehicles`, never a guess;
2. wakes whoever waits for a request's result when it comes: its own
   :attr:`Session.wake` flag (one runner), or ``notify`` (a service whose runs each have
   their own). A runner is woken by its vehicles' changes itself, only by those of the
   fields something reads (:meth:`tml.mavlink.adapter.MavlinkVehicle.watch`,
   :mod:`tml.run.lookout`);
3. clears a mission for flight before anything is sent (:meth:`Session.clear`, by the
   rules of :mod:`tml.run.clearance`, which ``tml serve`` clears its runs with too): the
   actions the vehicles cannot do at all, the vehicles' own reaction to a lost ground
   station (``FS_GCS_ENABLE``), the verifier's profile read from the vehicle (``--profile
   vehicle``) and the mission verified with it. A refusal is a :class:`Refusal`, which the
   command maps to its exit code;
4. makes the flight of the cleared mission on its vehicles (:meth:`Session.flight`, the
   one use case of :mod:`tml.run.flight`): its runner with their wake flag, clock, time
   base and the options checked against the profile and world (a resumed run goes on
   from its point, on the vehicles it flew: :meth:`Session.check_resume`).

``tml companion`` attaches the simulator's companion computer (through the factory its
command passes, as the simulator's) to the autopilot at one address with the same options
(address, ``--sysid``, ``timeout``): :func:`open_companion`.

In lock-step (``tml run --sim``) the opening, the clearance and the run take part in the
simulator's time (:mod:`tml.timebase`): it moves on only while the thread that opened the
session waits for it; closing does not.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from tml.errors import LinkLost, TmlError

# Said here too: the session's users name the clearance's rules through it.
from tml.run.clearance import GCS_FAILSAFE as GCS_FAILSAFE
from tml.run.clearance import Refusal as Refusal
from tml.timebase import SYSTEM, Flag, Lockstep, Timebase

if TYPE_CHECKING:
    from rich.console import Console

    from tml.language.model import Mission
    from tml.mavlink.adapter import MavlinkVehicle
    from tml.mavlink.link import Link
    from tml.run.clearance import ClearanceOptions, Finding
    from tml.run.flight import Flight, FlightOptions
    from tml.run.journal import Journal
    from tml.run.resume import ResumePoint
    from tml.run.runner import Runner
    from tml.verify.profile import VehicleProfile
    from tml.world import World

VEHICLE_PROFILE = "vehicle"
"""The profile name that means: fill the shipped profile from the vehicle's parameters."""

DISCOVERY_WAIT = 1.0
"""Seconds other vehicles on a link (a radio, a router) have to say hello after the first."""


@dataclass(frozen=True)
class SimulatorOptions:
    """What the embedded simulator is started with (``--vehicles``, ``--sim-*``)."""

    vehicles: int = 1
    speedup: float = 1.0
    params: Mapping[str, float] = field(default_factory=dict)
    frames: tuple[str, ...] = ("copter",)


class Simulated(Protocol):
    """What the session needs of a started simulator."""

    @property
    def tcp_ports(self) -> list[int]: ...

    @property
    def time(self) -> float: ...


SimulatorFactory = Callable[[SimulatorOptions, "World", "bytes | None", "Lockstep | None"],
                            AbstractContextManager[Simulated]]
"""Starts the simulator (options, world, signing key, lock-step time base or None)."""


class Companion(Protocol):
    """What the session needs of a companion computer attached to an autopilot."""

    @property
    def system_id(self) -> int | None: ...

    @property
    def autopilot_component(self) -> int | None: ...

    @property
    def time(self) -> float:
        """The autopilot's clock, seconds since its boot."""

    @property
    def autopilots(self) -> set[int]:
        """The system ids of the autopilots heard while :meth:`open` waited."""

    def open(self, timeout: float, stop: threading.Event | None = None,
             listen: float = 0.0) -> bool:
        """Connect and wait for the autopilot (without a system id, ``listen`` s more for
        others on the link); False when ``stop`` was set meanwhile."""

    def serve(self, stop: threading.Event) -> None:
        """Play the companion until ``stop`` is set."""

    def close(self) -> None: ...


CompanionFactory = Callable[[str, "World", "int | None", Callable[[str], None]], Companion]
"""Makes the companion computer (address, world, the vehicle's system id or None, where it
says what it sees)."""


@dataclass(frozen=True)
class SessionOptions:
    """Everything a command decides about a flight session."""

    connect: tuple[str, ...] = ()
    """The MAVLink addresses of the vehicles (empty with ``simulator``)."""
    system_ids: tuple[int, ...] = ()
    """The vehicles to fly on those addresses, by MAVLink system id (``--sysid``), in
    this order; empty: the one vehicle each address hears."""
    simulator: SimulatorOptions | None = None
    """Fly on the embedded simulator (``--sim``), started by ``open_simulator``."""
    open_simulator: SimulatorFactory | None = None
    open_companion: CompanionFactory | None = None
    """Makes the companion computer :func:`open_companion` attaches (``tml companion``)."""
    outputs: tuple[str, ...] = ()
    """Addresses that get a copy of every vehicle message (``--out``)."""
    signing_key_file: str | None = None
    timeout: float = 30.0
    """Seconds to wait for each address's first HEARTBEAT."""
    clock: str = "wall"
    """``wall`` (the ground station's) or ``vehicle`` (the first vehicle's time stamps)."""
    lockstep: bool = False
    """The simulator in lock-step with this thread (``tml run --sim``)."""
    link_lost_limit: float = 10.0
    ready_timeout: float = 180.0
    safe_state: str = "rtl"
    safe_state_timeout: float = 120.0
    require_gcs_failsafe: bool = False
    keep_vehicle_fence: bool = False
    """Leave each vehicle's fence as it is: only the mission's rally points go up."""
    force: bool = False
    """Fly a mission refused as infeasible or beyond its vehicles anyway."""
    quiet: bool = False
    """Say nothing but problems (no line while a vehicle is waited for)."""
    program: str = "tml run"
    """The name lines said begin with."""
    source_system: int = 255
    """The MAVLink system id this ground station sends as (ArduPilot's default GCS id, the
    one its GCS failsafe hears: the instances of a ``tml serve`` cluster share it)."""
    source_component: int = 190
    """The MAVLink component id it sends as (MAV_COMP_ID_MISSIONPLANNER; the instances of a
    cluster may each have their own, to be told apart in what the vehicles heard)."""
    fenced: bool = False
    """Open the vehicles without a word to them: every link's gate closed from its start
    (its HEARTBEAT included), no telemetry rates asked, no parameter read. The caller
    opens each gate and prepares each vehicle once it may command it (``tml serve
    --cluster``: once it leases the vehicle, tml.serve.cluster)."""

    @property
    def sim(self) -> bool:
        return self.simulator is not None

    @property
    def flight(self) -> FlightOptions:
        """How the session's missions are cleared and flown: the GCS failsafe not read on
        the simulator of this process (its link does not die alone) unless required."""
        from tml.run.flight import FlightOptions

        return FlightOptions(safe_state=self.safe_state, link_lost_limit=self.link_lost_limit,
                             ready_timeout=self.ready_timeout,
                             safe_state_timeout=self.safe_state_timeout,
                             vehicle_fence=not self.keep_vehicle_fence, force=self.force,
                             gcs_failsafe=not self.sim,
                             require_gcs_failsafe=self.require_gcs_failsafe)

    @property
    def signing_on(self) -> bool:
        """Whether the links sign (a key file given, or the environment's key)."""
        from tml.signing import ENVIRONMENT

        return self.signing_key_file is not None or ENVIRONMENT in os.environ


class SeveralVehicles(TmlError):
    """A link hears several vehicles and none was named (``--sysid``): which to fly is
    the operator's to say (exit 2), not tml's to guess."""


class Session:
    """Opened vehicles and what flies them; see the module docstring."""

    def __init__(self, options: SessionOptions, vehicles: list[MavlinkVehicle], wake: Flag,
                 clock: Callable[[], float], timebase: Timebase,
                 errors: Console | None) -> None:
        self.options = options
        self.vehicles = vehicles
        self.wake = wake
        self.clock = clock
        self.timebase = timebase
        self.errors = errors

    def say(self, text: str) -> None:
        """Say a line on the error console (with the program's name)."""
        if self.errors is not None:
            self.errors.print(f"{self.options.program}: {text}", markup=False,
                              highlight=False)

    # -- clearance -----------------------------------------------------------------------

    def clear(self, mission: Mission, profile: VehicleProfile | None,
              extra: World | None = None) -> VehicleProfile | Refusal:
        """Clear ``mission`` for flight on every vehicle of the session, before anything
        is sent (:func:`tml.run.clearance.clear`, what it found said on the error console):
        its actions, the vehicles' GCS failsafe, and, with ``profile`` None (``--profile
        vehicle``), the profile read from the first vehicle and the mission verified with
        it (a ``profile`` given was verified before the vehicles were opened:
        :func:`verify`). The profile to fly with, or why not."""
        from tml.run.clearance import Cleared
        from tml.run.flight import Flight

        found = Flight(mission, self.vehicles, self.options.flight).clear(profile, extra,
                                                                         verified=True)
        self._say(mission, found.findings)
        return found.profile if isinstance(found, Cleared) else found.refusal

    def clearance_options(self) -> ClearanceOptions:
        """The clearance's options of the session's (:attr:`SessionOptions.flight`)."""
        return self.options.flight.clearance()

    def gcs_failsafe(self) -> Refusal | None:
        """Read each vehicle's own reaction to a lost ground station
        (:func:`tml.run.clearance.failsafe_missing`): warns (with ``--connect``), or
        refuses with ``require_gcs_failsafe``."""
        from tml.run.clearance import failsafe_missing

        options = self.clearance_options()
        if not options.gcs_failsafe and not options.require_gcs_failsafe:
            return None
        missing = failsafe_missing(self.vehicles, options.require_gcs_failsafe)
        if missing is None:
            return None
        if self.errors is not None:
            from tml.run.clearance import say

            say([missing], "", self.options.program, self.options.force, self.errors)
        return Refusal.VEHICLE if missing.required else None

    def _say(self, mission: Mission, findings: Iterable[Finding]) -> None:
        if self.errors is not None:
            from tml.run.clearance import say

            say(findings, mission.file, self.options.program, self.options.force, self.errors)

    # -- the run ----------------------------------------------------------------------------

    def check_resume(self, point: ResumePoint | None) -> None:
        """Raise ResumeRefused when the vehicles opened are not the ones the interrupted
        run flew (their system ids, as its log keeps them): one address may carry several
        vehicles, and a run goes on only on its own."""
        from tml.run.resume import ResumeRefused

        opened = tuple(v.system_id for v in self.vehicles)
        if point is not None and point.system_ids and point.system_ids != opened:
            raise ResumeRefused(
                f"the run flew the vehicle(s) with system id {_ids(point.system_ids)}, "
                f"not {_ids(opened)}: say which with --sysid")

    def flight(self, mission: Mission, profile: VehicleProfile, world: World,
               journal: Journal, *, resumed: ResumePoint | None = None,
               payloads: Mapping[int, Iterable[str]] | None = None,
               on_safety: Callable[[str], None] | None = None,
               on_update: Callable[[Runner], None] | None = None,
               about: Mapping[str, object] | None = None) -> Flight:
        """The flight of the cleared ``mission`` on the session's vehicles, its runner
        made (:meth:`tml.run.flight.Flight.start`) with the session's
        :attr:`SessionOptions.flight`, going on from ``resumed`` (an interrupted run's
        point, its request numbers continued) when given. The run's first log line names
        the addresses and each vehicle's system id, and ``about``."""
        from tml.run.flight import Flight
        from tml.vehicle import IdSource

        flight = Flight(mission, self.vehicles, self.options.flight, on_safety=on_safety)
        flight.start(profile, world, journal, clock=self.clock, wake=self.wake,
                     timebase=self.timebase, payloads=payloads, on_update=on_update,
                     ids=None if resumed is None else IdSource(resumed.next_id),
                     resume=None if resumed is None else resumed.progress,
                     about={**(about or {}), "connect": list(self.options.connect),
                            "system_ids": [v.system_id for v in self.vehicles]})
        return flight

    def signing_counts(self) -> list[tuple[str, int, int]]:
        """With signing on, what each link dropped: (address, unsigned, wrongly signed)."""
        if not self.options.signing_on:
            return []
        links: dict[int, Link] = {id(v.link): v.link for v in self.vehicles}
        return [(link.address, *link.signing_counts) for link in links.values()]


def verify(mission: Mission, profile: VehicleProfile, extra: World | None,
           options: SessionOptions, errors: Console | None) -> Refusal | None:
    """Verify ``mission`` with ``profile`` (and the ``extra`` world) before the vehicles are
    opened (:func:`tml.run.clearance.clear` without vehicles), what it found said on
    ``errors``; the refusal if it must not be flown (infeasible, without ``force``)."""
    from tml.run.clearance import NotCleared, say
    from tml.run.flight import Flight, FlightOptions

    found = Flight(mission, (), FlightOptions(force=options.force)).clear(profile, extra)
    if errors is not None:
        say(found.findings, mission.file, options.program, options.force, errors)
    return found.refusal if isinstance(found, NotCleared) else None


@contextlib.contextmanager
def open_session(options: SessionOptions, world: World, errors: Console | None = None,
                 notify: Callable[[], None] | None = None) -> Iterator[Session]:
    """Start the simulator or open the links, and wait for every vehicle; yield the
    session. ``notify``, when given, is called on every change instead of setting the
    session's wake flag. Raises TmlError (no vehicle, a vehicle that signs while no key
    is given ...) and OSError (an address that cannot be opened)."""
    from tml.mavlink.adapter import MavlinkVehicle
    from tml.mavlink.clock import VehicleClock
    from tml.mavlink.link import Link
    from tml.signing import signing_key

    if options.sim and options.open_simulator is None:
        raise TmlError("a simulated session needs a simulator factory")
    timebase: Timebase = Lockstep() if options.sim and options.lockstep else SYSTEM
    wake = Flag(timebase)
    key = signing_key(options.signing_key_file)
    # In lock-step the opening, the pre-flight checks and the run take part in the
    # simulator's time (tml.timebase): it moves on only while this thread waits for it.
    # Closing (the stack, left after) does not: the requests under way finish with time
    # moving.
    with contextlib.ExitStack() as stack, timebase.taking_part():
        clock: Callable[[], float]
        addresses: list[tuple[str, int | None]]
        if options.simulator is not None and options.open_simulator is not None:
            sim = stack.enter_context(options.open_simulator(
                options.simulator, world, key,
                timebase if isinstance(timebase, Lockstep) else None))
            clock = lambda: sim.time  # noqa: E731 - the vehicles' own time
            addresses = [(f"tcp:127.0.0.1:{port}", index + 1)
                         for index, port in enumerate(sim.tcp_ports)]
        else:
            clock = time.monotonic
            addresses = [(url, None) for url in options.connect]
        vehicles: list[MavlinkVehicle] = []
        link_clock = None  # the runner's clock
        vehicle_clock: VehicleClock | None = None
        for address, system_id in addresses:
            link = Link(address, outputs=options.outputs, signing_key=key,
                        timebase=timebase, source_system=options.source_system,
                        source_component=options.source_component)
            if options.fenced:
                link.gate = lambda _target: False
            stack.enter_context(link)
            if not system_id and errors is not None and not options.quiet:
                # Said once: pymavlink's own retry messages are kept from the terminal.
                errors.print(f"{options.program}: waiting up to {options.timeout:g} s for a "
                             f"vehicle at {address}", markup=False, highlight=False)
            ids = [system_id] if system_id else _discover(
                link, options.timeout, options.system_ids, alone=len(addresses) == 1)
            if options.system_ids:  # a vehicle heard on two links is flown on the first
                ids = [sid for sid in ids if sid not in {v.system_id for v in vehicles}]
            if not options.sim and options.clock == "vehicle" and not vehicles:
                # The first vehicle's clock times the mission and every vehicle's link.
                clock = vehicle_clock = VehicleClock(link, ids[0])
                # Link health stays on the local clock: see tml.mavlink.adapter.
                link_clock = time.monotonic
            for sid in ids:
                vehicle = MavlinkVehicle(
                    link, sid, clock=clock, world=world,
                    vehicle_id=len(vehicles) + 1 if not options.sim else sid,
                    connect_timeout=options.timeout, on_result=notify or wake.set,
                    link_clock=link_clock)
                stack.callback(vehicle.close)
                if not options.fenced:
                    vehicle.prepare()
                vehicles.append(vehicle)
        missing = [sid for sid in options.system_ids
                   if sid not in {vehicle.system_id for vehicle in vehicles}]
        if missing:
            heard = sorted({sid for v in vehicles for sid in v.link.vehicles()})
            raise TmlError(f"no vehicle with system id {_ids(missing)} heard on "
                           f"{', '.join(options.connect)} within {options.timeout:g} s "
                           f"(heard: {_ids(heard) or 'none'})")
        if vehicle_clock is not None and not vehicle_clock.wait_started(options.timeout):
            raise TmlError(f"vehicle {vehicles[0].vehicle_id} sent no time stamp "
                           f"(time_boot_ms) in {options.timeout:g} s; --clock vehicle needs "
                           "one")
        yield Session(options, vehicles, wake, clock, timebase, errors)


@contextlib.contextmanager
def open_companion(options: SessionOptions, world: World, stop: threading.Event,
                   on_text: Callable[[str], None]) -> Iterator[Companion | None]:
    """Attach the companion computer of ``options.open_companion`` to the autopilot at the
    one ``connect`` address: the vehicle of the first ``system_ids``, else the one autopilot
    heard, waited for up to ``timeout``. Yield it (None when ``stop`` was set meanwhile);
    closed on leaving. Raises VehicleError when the address cannot be opened or no
    autopilot is heard in time, and :class:`SeveralVehicles` when several are heard and
    none is named."""
    if options.open_companion is None or len(options.connect) != 1:
        raise TmlError("a companion session needs one address and a companion factory")
    companion = options.open_companion(options.connect[0], world,
                                       options.system_ids[0] if options.system_ids else None,
                                       on_text)
    try:
        named = bool(options.system_ids)
        opened = companion.open(options.timeout, stop, 0.0 if named else DISCOVERY_WAIT)
        if opened and not named and len(companion.autopilots) > 1:
            heard = sorted(companion.autopilots)
            raise SeveralVehicles(f"{options.connect[0]}: vehicles with system ids "
                                  f"{_ids(heard)} heard: say which with --sysid N")
        yield companion if opened else None
    finally:
        companion.close()


def _discover(link: Link, timeout: float, wanted: Sequence[int], alone: bool) -> list[int]:
    """The system ids of the vehicles to fly on ``link``: those of ``wanted`` it carries,
    in that order (each waited for when the link is the only one: they are all on it),
    else the one vehicle it hears. Other vehicles have :data:`DISCOVERY_WAIT` after the
    first to say hello. Raises :class:`SeveralVehicles` when more than one is heard and
    none is wanted."""
    if wanted and alone:
        try:
            return [link.wait_vehicle(sid, timeout).system_id for sid in wanted]
        except LinkLost as error:
            heard = sorted(link.vehicles())
            if not heard:
                raise
            raise LinkLost(f"{error} (heard: system id {_ids(heard)})") from None
    first = link.wait_vehicle(None, timeout)
    time.sleep(DISCOVERY_WAIT)  # other vehicles on the same link say hello too
    heard = sorted({first.system_id, *link.vehicles()})
    if wanted:
        return [sid for sid in wanted if sid in heard]
    if len(heard) > 1:
        raise SeveralVehicles(
            f"{link.address}: vehicles with system ids {_ids(heard)} heard: say which to "
            f"fly with --sysid N (repeated for several: --sysid {heard[0]} --sysid "
            f"{heard[1]})")
    return heard


def _ids(system_ids: Sequence[int]) -> str:
    return ", ".join(map(str, system_ids))
