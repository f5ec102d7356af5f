"""``tml run``: validate, verify and fly a mission on the simulator or MAVLink vehicles.

Exit codes: 0 the mission completed on every vehicle, 1 invalid (or infeasible, without
``--force``) mission, 2 usage error (a bad option or value, a missing file, a malformed
address, a log that cannot be written: said in one line before anything starts), 3 the
mission was aborted (ABORT_MISSION, an infeasible action, Ctrl-C), 4 a vehicle or link
failure (an action failed and nothing handled it, no vehicle answered, the link was lost,
the interpreter broke).
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, NamedTuple

from tml.commands.signals import Stopped, on_stop_signals
from tml.errors import ExitCode

if TYPE_CHECKING:
    from tml.language.model import Mission
    from tml.run.journal import Journal
    from tml.run.resume import ResumePoint
    from tml.timebase import Flag, Timebase
    from tml.world import World

VEHICLE_PROFILE = "vehicle"  # --profile vehicle: read from the connected vehicle


class Resumed(NamedTuple):
    """The mission file's SHA-256 (for the log), and where an interrupted run stood when
    ``--resume`` goes on with it (None: a new run)."""

    digest: str
    point: ResumePoint | None


def _sim_param(text: str) -> tuple[str, float]:
    from sitl.cli import param_setting

    return param_setting(text)


def _sim_frames(text: str) -> list[str]:
    from sitl.frames import parse_frames

    try:
        return parse_frames(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _sim_battery(text: str) -> tuple[str, float]:
    from sitl.cli import battery_start

    return battery_start(text)


def _fast_boot() -> type[argparse.Action]:
    from sitl.cli import FastBoot

    return FastBoot


MAX_SIM_VEHICLES = 250
"""Simulated vehicles one ``tml run --sim`` flies at most: each takes three sockets in this
process, and pymavlink watches its sockets with select(), which cannot see a descriptor
past 1023."""


def _positive(text: str) -> float:
    from sitl.cli import positive

    return positive(text)


def _non_negative(text: str) -> float:
    from sitl.cli import non_negative

    return non_negative(text)


def _sim_vehicles(text: str) -> int:
    from sitl.cli import count

    number = count(text)
    if number > MAX_SIM_VEHICLES:
        raise argparse.ArgumentTypeError(
            f"at most {MAX_SIM_VEHICLES} simulated vehicles (each takes three sockets, and "
            f"pymavlink's select() sees none past descriptor 1023), got {text}")
    return number


def _payload(text: str) -> tuple[int, tuple[str, ...]]:
    number, _, names = text.partition("=")
    wanted = tuple(n.strip() for n in names.split(",") if n.strip())
    if not number.strip().isdigit() or not wanted:
        raise argparse.ArgumentTypeError(f"expected ID=NAME[,NAME...] (e.g. 2=camera,sidescan), "
                                         f"got {text!r}")
    return int(number), wanted


def add_vehicle_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options that say which vehicles to open (``tml run``, ``tml serve``):
    the simulator or MAVLink addresses, and how their links are watched."""
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--sim", action="store_true",
                       help="fly on the embedded simulator (loopback, free ports)")
    where.add_argument("--connect", action="append", metavar="URL",
                       help="fly the vehicle at this MAVLink address (tcp:HOST:PORT, "
                            "udpin:0.0.0.0:14550, /dev/ttyACM0 ...); repeatable")
    parser.add_argument("--vehicles", type=_sim_vehicles, default=1, metavar="N",
                        help="--sim: number of simulated vehicles (default 1)")
    parser.add_argument("--speedup", type=_positive, default=1.0, metavar="K",
                        help="--sim: run simulated time K times faster (default 1)")
    parser.add_argument("--sim-frame", type=_sim_frames, default=["copter"],
                        metavar="FRAME[,FRAME...]",
                        help="--sim: copter (default), plane or rover; a list gives vehicle "
                             "1, 2 ... theirs, the last repeating (e.g. copter,rover)")
    parser.add_argument("--sim-param", type=_sim_param, action="append", default=[],
                        metavar="NAME=VALUE",
                        help="--sim: set a simulator parameter (e.g. SIM_EKF_GPS_TIME=2)")
    parser.add_argument("--sim-battery", type=_sim_battery, action="append", dest="sim_param",
                        metavar="PERCENT",
                        help="--sim: the charge of every simulated battery at the start, 0 to "
                             "100 (default 100), e.g. to see a low-battery event fire")
    parser.add_argument("--sim-fast-boot", action=_fast_boot(), dest="sim_param",
                        help="--sim: the GPS locks after 1 s and the EKF uses it after 2 s of "
                             "vehicle time instead of ArduCopter's 10 and 41 s: the vehicles "
                             "are armable at once")
    parser.add_argument("--out", action="append", default=[], metavar="ADDRESS",
                        help="copy every vehicle message to this address, so QGroundControl "
                             "or MAVProxy can watch (e.g. udpout:127.0.0.1:14551); "
                             "repeatable")
    parser.add_argument("--signing-key-file", metavar="FILE",
                        help="MAVLink 2 signing: sign what is sent and drop (and count) what "
                             "comes unsigned or wrongly signed; the file holds 64 hex digits "
                             "or a passphrase (else the key of TML_SIGNING_KEY, if set)")
    parser.add_argument("--link-lost-limit", type=_positive, default=10.0, metavar="S",
                        help="abort a run after its link is lost this long (default 10 s)")
    parser.add_argument("--timeout", type=_positive, default=30.0, metavar="S",
                        help="seconds to wait for each vehicle's first heartbeat (default 30)")
    parser.add_argument("--ready-timeout", type=_non_negative, default=180.0, metavar="S",
                        help="seconds to wait, before the first task, for every vehicle to "
                             "report position, home, GPS and battery and to be armable "
                             "(default 180; 0 does not wait)")
    parser.add_argument("--clock", choices=("wall", "vehicle"), default="wall",
                        help="--connect: the mission's clock: the ground station's (wall, "
                             "default) or the first vehicle's own (vehicle: time limits in "
                             "vehicle seconds, e.g. for SITL run with --speedup); --sim "
                             "always uses the simulator's")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml run``."""
    parser.add_argument("mission", metavar="FILE")
    add_vehicle_arguments(parser)
    parser.add_argument("--world", metavar="FILE",
                        help="world file laid over the mission's <environment>")
    parser.add_argument("--payload", type=_payload, action="append", default=[],
                        metavar="ID=NAME[,NAME...]",
                        help="what vehicle ID carries, for the payloads a <role> asks for "
                             "(beyond the camera and gripper the vehicle reports); repeatable")
    parser.add_argument("--log", metavar="FILE", help="write the JSON-lines flight log here")
    parser.add_argument("--resume", metavar="LOG",
                        help="go on with the interrupted run whose --log is LOG, on the same "
                             "vehicles (--connect): tasks done stay done, the running one "
                             "goes on; the log is added to (refused, exit 2, for a run that "
                             "ended or flew another file or other vehicles)")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no live view; print only the outcome")
    parser.add_argument("--safe-state", choices=("rtl", "land", "hold"), default="rtl",
                        help="what a flying vehicle is told when the run stops early "
                             "(default rtl; a vehicle on the ground is disarmed)")
    parser.add_argument("--safe-state-timeout", type=_non_negative, default=120.0,
                        metavar="S",
                        help="after the run stopped early, command the safe state again "
                             "until the vehicle shows it, for at most S seconds (default "
                             "120; a link that comes back finds it told again)")
    parser.add_argument("--require-gcs-failsafe", action="store_true",
                        help="refuse to fly a vehicle whose own failsafe does not act when "
                             "it loses this ground station (ArduPilot FS_GCS_ENABLE 0 or not "
                             "reported); without it, --connect only warns")
    parser.add_argument("--force", action="store_true",
                        help="fly even when the verifier finds the mission infeasible")
    parser.add_argument("--profile", default="quadcopter", metavar="P",
                        help="vehicle profile for the verifier: quadcopter (default), "
                             "fixed-wing, a TOML file, or 'vehicle' to fill the quadcopter "
                             "profile from the connected vehicle's parameters")


def run(args: argparse.Namespace) -> ExitCode:
    """Run ``tml run``; return the exit code."""
    from tml.errors import TmlError
    from tml.run.display import output_console

    console = output_console()
    errors = output_console(stderr=True)
    problem = _usage_problem(args)
    if problem is not None:
        errors.print(f"tml run: {problem}", markup=False)
        return ExitCode.USAGE
    try:
        loaded = _load(args, errors)
    except OSError as error:
        errors.print(f"tml run: {error.filename or ''}: {error.strerror or error}",
                     markup=False, soft_wrap=True)
        return ExitCode.USAGE
    except TmlError as error:
        errors.print(f"tml run: {error}", markup=False)
        return ExitCode.USAGE
    if isinstance(loaded, ExitCode):
        return loaded
    mission, world, extra, profile = loaded
    from tml.run.journal import Journal
    from tml.run.resume import ResumeRefused, file_digest, resume_point

    try:
        digest = file_digest(args.mission)
        point = None if args.resume is None else resume_point(args.resume, mission, digest,
                                                              args.connect or [])
    except OSError as error:
        errors.print(f"tml run: --resume {args.resume}: cannot read: "
                     f"{error.strerror or error}", markup=False)
        return ExitCode.USAGE
    except ResumeRefused as error:
        errors.print(f"tml run: cannot resume: {error}", markup=False)
        return ExitCode.USAGE
    try:  # before anything starts: a log that cannot be written is a usage error
        journal = Journal.open(args.log, append=args.resume is not None)
    except OSError as error:
        errors.print(f"tml run: --log {args.log}: cannot write: {error.strerror or error}",
                     markup=False)
        return ExitCode.USAGE
    try:
        return _run(args, mission, world, extra, profile, journal, console, errors,
                    Resumed(digest, point))
    finally:
        journal.close()


def _usage_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with the mission file or an address given, said with the option and
    the value; None when nothing is."""
    import os

    from tml.mavlink.link import address_problem

    if args.resume is not None:
        if args.sim:
            return ("--resume needs the vehicles of the interrupted run (--connect): the "
                    "simulator of --sim ended with it")
        if args.log is not None and args.log != args.resume:
            return f"--log {args.log}: a resumed run adds to its log, --resume {args.resume}"
        args.log = args.resume
    path = args.mission
    if not os.path.exists(path):
        return f"{path}: No such file or directory"
    if os.path.isdir(path):
        return f"{path}: is a directory, not a mission file"
    if not os.access(path, os.R_OK):
        return f"{path}: Permission denied"
    if _signing_on(args):
        from tml.errors import TmlError
        from tml.signing import signing_key

        try:
            signing_key(args.signing_key_file)
        except OSError as error:
            return f"--signing-key-file {args.signing_key_file}: {error.strerror or error}"
        except TmlError as error:
            return f"signing key: {error}"
    for option, addresses, output in (("--connect", args.connect or [], False),
                                      ("--out", args.out, True)):
        for address in addresses:
            problem = address_problem(address, output=output)
            if problem is not None:
                return f"{option} {address}: {problem}"
    return None


def _run(args: argparse.Namespace, mission: Mission, world: World, extra: World | None,
         profile: Any, journal: Journal, console: Any, errors: Any,
         resumed: Resumed) -> ExitCode:
    """Open the vehicles and fly; the exit code."""
    from tml.errors import TmlError

    try:
        with open_vehicles(args, world, errors, lockstep=True) as (vehicles, wake, clock,
                                                                   timebase):
            refused = _preflight(args, mission, vehicles, errors) or _gcs_failsafe(
                args, vehicles, errors)
            if refused is not None:
                return refused
            if args.profile == VEHICLE_PROFILE:
                profile = _vehicle_profile(vehicles[0], errors)
                refused = _verify(args, mission, extra, profile, errors)
                if refused is not None:
                    return refused
            return _fly(args, mission, world, profile, vehicles, wake, clock, timebase, console,
                        journal, resumed)
    except Stopped as error:
        errors.print(f"tml run: {error} before the mission started", markup=False)
        return ExitCode.ABORTED
    except TmlError as error:
        errors.print(f"tml run: {error}", markup=False)
        return ExitCode.FAILURE
    except OSError as error:
        errors.print(f"tml run: cannot open the vehicle link: {error}")
        return ExitCode.FAILURE


def _load(args: argparse.Namespace,
          errors: Any) -> tuple[Mission, World, World | None, Any] | ExitCode:
    """The validated (and verified) mission, its world, the --world file's world and the
    verifier's profile; or an exit code."""
    from tml.language.build import load_world
    from tml.language.diagnostics import format_human_all
    from tml.language.validation import validate_file
    from tml.world import World

    result = validate_file(args.mission)
    if result.errors or result.mission is None:
        for text in format_human_all(result.diagnostics, {result.file: result.source}):
            errors.print(text, markup=False)
        errors.print(f"tml run: {result.file}: invalid mission, not flown")
        return ExitCode.INVALID
    mission = result.mission
    extra = load_world(args.world) if args.world else None
    world = (mission.world or World()).merged(extra)
    from tml.verify.profile import load_profile

    if args.profile == VEHICLE_PROFILE:
        return mission, world, extra, None  # verified once the vehicle's parameters are read
    profile = load_profile(args.profile)
    refused = _verify(args, mission, extra, profile, errors)
    return refused if refused is not None else (mission, world, extra, profile)


def _verify(args: argparse.Namespace, mission: Mission, extra: World | None, profile: Any,
            errors: Any) -> ExitCode | None:
    """Verify the mission with ``profile``; the exit code if it must not be flown."""
    from tml.verify.report import print_report
    from tml.verify.static import verify_mission

    report = verify_mission(mission, profile, extra)
    if report.feasible:
        return None
    print_report(report, errors)
    return _refused(args, mission, "infeasible mission", errors)


def _refused(args: argparse.Namespace, mission: Mission, what: str, errors: Any) -> ExitCode | None:
    """ExitCode.INVALID for a mission refused as ``what``; None when --force flies it anyway."""
    if not args.force:
        errors.print(f"tml run: {mission.file}: {what}, not flown (--force flies it anyway)")
        return ExitCode.INVALID
    errors.print(f"tml run: {what} flown anyway (--force)")
    return None


def _preflight(args: argparse.Namespace, mission: Mission, vehicles: list[Any],
               errors: Any) -> ExitCode | None:
    """Refuse, before anything is sent, a mission with actions the connected vehicles
    cannot do at all (tml.verify.inflight.preflight); the exit code if not flown."""
    from tml.verify.inflight import preflight

    found = preflight(mission, {v.vehicle_id: v.state().vehicle_type for v in vehicles})
    if not found:
        return None
    for violation in found:
        whose = f" (role {violation.role})" if violation.role else ""
        errors.print(f"{violation} (vehicle {violation.vehicles[0]}{whose})", markup=False,
                     highlight=False)
    return _refused(args, mission, "mission with actions its vehicles cannot do", errors)


GCS_FAILSAFE = "FS_GCS_ENABLE"
"""ArduPilot's parameter for what a vehicle does by itself when its ground station falls
silent (0: nothing; 1 RTL, 5 LAND ...; see docs/run.md)."""


def _gcs_failsafe(args: argparse.Namespace, vehicles: list[Any],
                  errors: Any) -> ExitCode | None:
    """Read each vehicle's own reaction to a lost ground station before anything is sent:
    without one, a vehicle whose link dies hovers until its battery runs out. Warns (with
    ``--connect``), or refuses with ``--require-gcs-failsafe``; the exit code if not flown."""
    if not args.require_gcs_failsafe and args.sim:
        return None  # the simulator is in this process: its link does not die alone
    missing = []
    for vehicle in vehicles:
        value = vehicle.read_parameters([GCS_FAILSAFE]).get(GCS_FAILSAFE)
        if value is None:
            missing.append(f"vehicle {vehicle.vehicle_id}: {GCS_FAILSAFE} not reported: what "
                           "the vehicle does when it loses this ground station is unknown")
        elif value == 0:
            missing.append(f"vehicle {vehicle.vehicle_id}: {GCS_FAILSAFE} is 0: the vehicle "
                           "does nothing by itself when it loses this ground station (1 "
                           "returns home, 5 lands)")
    for problem in missing:
        errors.print(f"tml run: {'' if args.require_gcs_failsafe else 'warning: '}{problem}",
                     markup=False)
    if missing and args.require_gcs_failsafe:
        errors.print("tml run: not flown (--require-gcs-failsafe)", markup=False)
        return ExitCode.FAILURE
    return None


def _vehicle_profile(vehicle: Any, errors: Any) -> Any:
    """The shipped profile of the vehicle's kind filled in from its own parameters."""
    from tml.verify.profile import describe_parameters, profile_from_vehicle, shipped_for

    profile, params = profile_from_vehicle(vehicle.read_parameters,
                                           shipped_for(vehicle.state().vehicle_type))
    errors.print(f"tml run: {profile.name} profile from vehicle {vehicle.vehicle_id}'s "
                 "parameters: " + describe_parameters(params), markup=False)
    return profile


@contextlib.contextmanager
def open_vehicles(args: argparse.Namespace, world: World, errors: Any = None,
                  notify: Callable[[], None] | None = None, lockstep: bool = False,
                  ) -> Iterator[tuple[list[Any], Flag, Any, Timebase]]:
    """Start the simulator or open the links; yield (vehicles, wake flag, clock, time base).

    The wake flag is set on every message that changes what a vehicle shows and on every
    request result, or ``notify`` is called
    instead when given (a service with several runs wakes each of them); ``errors``, when
    given, is told which address is waited for. With ``lockstep``, the embedded simulator
    moves its time on only when tml waits for it (:class:`tml.timebase.Lockstep`): the
    time base yielded is then the simulator's, for the runner to wait on and take part in.
    """
    import time

    from tml.errors import TmlError
    from tml.mavlink.adapter import MavlinkVehicle
    from tml.mavlink.clock import VehicleClock
    from tml.mavlink.link import Link
    from tml.signing import signing_key
    from tml.timebase import SYSTEM, Flag, Lockstep

    timebase: Timebase = Lockstep() if args.sim and lockstep else SYSTEM
    wake = Flag(timebase)
    # OSError, TmlError: said by the caller
    key = signing_key(getattr(args, "signing_key_file", None))
    addresses: list[tuple[str, int | None]]
    news = notify or wake.set
    # In lock-step the opening, the pre-flight checks and the run take part in the
    # simulator's time (tml.timebase): it moves on only while this thread waits for it.
    # Closing (the stack, left after) does not: the workers finish with time moving.
    with contextlib.ExitStack() as stack, timebase.taking_part():
        if args.sim:
            from sitl.server import Simulator

            sim = Simulator(vehicles=args.vehicles, speedup=args.speedup, tcp_base_port=0,
                            world=world, params=dict(args.sim_param), frames=args.sim_frame,
                            signing_key=key,
                            lockstep=timebase if isinstance(timebase, Lockstep) else None)
            stack.enter_context(sim)
            clock = lambda: sim.time  # noqa: E731 - the vehicles' own time
            addresses = [(f"tcp:127.0.0.1:{port}", index + 1)
                         for index, port in enumerate(sim.tcp_ports)]
        else:
            clock = time.monotonic
            addresses = [(url, None) for url in args.connect]
        vehicles: list[MavlinkVehicle] = []
        link_clock = None  # the runner's clock
        vehicle_clock: VehicleClock | None = None
        for address, system_id in addresses:
            link = stack.enter_context(Link(address, outputs=args.out, signing_key=key,
                                            timebase=timebase))
            link.on_change(lambda _system_id: news())
            if not system_id and errors is not None and not getattr(args, "quiet", False):
                # Said once: pymavlink's own retry messages are kept from the terminal.
                errors.print(f"tml run: waiting up to {args.timeout:g} s for a vehicle "
                             f"at {address}", markup=False)
            ids = [system_id] if system_id else _discover(link, args.timeout)
            if not args.sim and args.clock == "vehicle" and not vehicles:
                # The first vehicle's clock times the mission and every vehicle's link.
                clock = vehicle_clock = VehicleClock(link, ids[0])
                # Link health stays on the local clock: see tml.mavlink.adapter.
                link_clock = time.monotonic
            for sid in ids:
                vehicle = MavlinkVehicle(
                    link, sid, clock=clock, world=world,
                    vehicle_id=len(vehicles) + 1 if not args.sim else sid,
                    connect_timeout=args.timeout, on_result=news, link_clock=link_clock)
                stack.callback(vehicle.close)
                vehicle.prepare()
                vehicles.append(vehicle)
        if vehicle_clock is not None and not vehicle_clock.wait_started(args.timeout):
            raise TmlError(f"vehicle {vehicles[0].vehicle_id} sent no time stamp "
                           f"(time_boot_ms) in {args.timeout:g} s; --clock vehicle needs "
                           "one")
        yield vehicles, wake, clock, timebase


def _signing_on(args: argparse.Namespace) -> bool:
    import os

    from tml.signing import ENVIRONMENT

    return args.signing_key_file is not None or ENVIRONMENT in os.environ


def _tell_signing(args: argparse.Namespace, vehicles: list[Any], journal: Journal,
                  said: list[str], now: float) -> None:
    """With signing on, log (and say, when there were any) the messages each link dropped
    unsigned or wrongly signed: a spoofer's, or a ground station with another key."""
    if not _signing_on(args):
        return
    links = {id(v.link): v.link for v in vehicles}
    for link in links.values():
        unsigned, bad = link.signing_counts
        message = (f"{link.address}: signing: {unsigned} unsigned and {bad} wrongly signed "
                   "message(s) dropped")
        journal.write(now, "signing", None, message=message, address=link.address,
                      unsigned=unsigned, bad_signature=bad)
        if unsigned or bad:
            said.append(message)


def _discover(link: Any, timeout: float) -> list[int]:
    """The system ids of the vehicles on a link: the first one, and any heard within 1 s."""
    import time

    first = link.wait_vehicle(None, timeout)
    time.sleep(1.0)  # other vehicles on the same link (a radio, a router) say hello too
    return sorted({first.system_id, *link.vehicles()})


def _fly(args: argparse.Namespace, mission: Mission, world: World, profile: Any,
         vehicles: list[Any], wake: Flag, clock: Any, timebase: Timebase, console: Any,
         journal: Journal, resumed: Resumed) -> ExitCode:
    from tml.run.checked import checked_options
    from tml.run.display import LineDisplay, LiveDisplay
    from tml.run.runner import Runner
    from tml.vehicle import IdSource

    options = checked_options(profile, world, safe_state=args.safe_state,
                              link_lost_limit=args.link_lost_limit,
                              ready_timeout=args.ready_timeout,
                              safe_state_timeout=args.safe_state_timeout)
    display: Any = None
    if not args.quiet:
        display = LiveDisplay(mission, console) if console.is_terminal else LineDisplay(console)
    said: list[str] = []

    def on_safety(message: str) -> None:
        said.append(message)
        if display is not None:
            display.say(message)

    journal.on_failure = on_safety  # a log that cannot be written never stops the flight

    payloads: dict[int, list[str]] = {}
    for number, names in args.payload:
        payloads.setdefault(number, []).extend(names)
    point = resumed.point
    runner = Runner(mission, vehicles, clock=clock, options=options, journal=journal,
                    wake=wake, timebase=timebase, on_safety=on_safety, payloads=payloads,
                    on_update=(lambda r: display.update(r.views())) if display else None,
                    ids=None if point is None else IdSource(point.next_id),
                    resume=None if point is None else point.progress,
                    about={"sha256": resumed.digest, "connect": args.connect or []})
    try:
        with on_stop_signals(lambda name: runner.stop(f"interrupted ({name})")), \
                display if display is not None else contextlib.nullcontext():
            outcome = runner.run()
            if display is not None:
                display.update(runner.views(), force=True)
        _tell_signing(args, vehicles, journal, said, runner.clock())
    finally:
        journal.close()  # flushed and closed before the outcome is said
    from tml.language.diagnostics import printable

    for vehicle in outcome.vehicles:
        console.print(printable(f"vehicle {vehicle.vehicle_id}: mission "
                                f"{vehicle.status.value}: {vehicle.reason}", False),
                      markup=False)
    if args.quiet:
        for message in said:
            console.print(printable(message, False), markup=False)
    if args.log:
        console.print(f"flight log: {args.log} ({journal.lines} lines"
                      + (f"; {journal.failure}, {journal.unwritten} lines not written)"
                         if journal.failure else ")"), markup=False)
    return outcome.exit_code
