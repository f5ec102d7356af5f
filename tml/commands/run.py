"""``tml run``: validate, verify and fly a mission on the simulator or MAVLink vehicles.

Exit codes: those of the one table of endings, :class:`tml.run.endings.Ending` (docs/run.md,
"How a run ends"): 0 completed, 1 invalid (or infeasible, without ``--force``) mission, 2
usage error (a bad option or value, a missing file, a malformed address, a log that cannot
be written, a resume refused: said in one line before anything starts), 3 aborted (by the
mission, Ctrl-C, SIGTERM), 4 taken over or failed (an operator's command through the run,
a mode switched outside tml, an action failed and nothing handled it, no vehicle answered,
the link was lost, the interpreter broke). The run's last line says its status word, exit
code and what it means.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
from typing import TYPE_CHECKING, NamedTuple

from tml.commands.signals import Stopped, on_stop_signals
from tml.commands.vehicles import (
    add_vehicle_arguments,
    non_negative,
    session_options,
    vehicle_problem,
)
from tml.errors import ExitCode
from tml.run.endings import Ending

if TYPE_CHECKING:
    from rich.console import Console

    from tml.language.model import Mission
    from tml.run.display import LineDisplay, LiveDisplay
    from tml.run.journal import Journal
    from tml.run.resume import ResumePoint
    from tml.run.runner import Runner
    from tml.run.session import Refusal, Session, SessionOptions
    from tml.verify.profile import VehicleProfile
    from tml.world import World


class Resumed(NamedTuple):
    """The mission file's SHA-256 (for the log), and where an interrupted run stood when
    ``--resume`` goes on with it (None: a new run)."""

    digest: str
    point: ResumePoint | None


def _payload(text: str) -> tuple[int, tuple[str, ...]]:
    number, _, names = text.partition("=")
    wanted = tuple(n.strip() for n in names.split(",") if n.strip())
    if not number.strip().isdigit() or not wanted:
        raise argparse.ArgumentTypeError(f"expected ID=NAME[,NAME...] (e.g. 2=camera,sidescan), "
                                         f"got {text!r}")
    return int(number), wanted


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
    parser.add_argument("--safe-state-timeout", type=non_negative, default=120.0,
                        metavar="S",
                        help="after the run stopped early, command the safe state again "
                             "until the vehicle shows it, for at most S seconds (default "
                             "120; a link that comes back finds it told again)")
    parser.add_argument("--keep-vehicle-fence", action="store_true",
                        help="leave each vehicle's own fence as it is (by default the "
                             "mission's geofence and obstacles are uploaded as its fence "
                             "before take-off; rally points go up either way)")
    parser.add_argument("--force", action="store_true",
                        help="fly even when the verifier finds the mission infeasible")
    parser.add_argument("--profile", default="quadcopter", metavar="P",
                        help="vehicle profile for the verifier: quadcopter (default), "
                             "fixed-wing, rover, a TOML file, or vehicle to fill the profile "
                             "of the vehicle's kind from the connected vehicle's parameters")


def run(args: argparse.Namespace) -> ExitCode:
    """Run ``tml run``; return the exit code."""
    from tml.errors import TmlError
    from tml.run.display import output_console

    console = output_console()
    errors = output_console(stderr=True)
    problem = _usage_problem(args)
    if problem is not None:
        errors.print(f"tml run: {problem}", markup=False)
        return Ending.USAGE.code
    options = session_options(args, "tml run", lockstep=True, quiet=args.quiet,
                              force=args.force, safe_state=args.safe_state,
                              safe_state_timeout=args.safe_state_timeout)
    options = dataclasses.replace(options, keep_vehicle_fence=args.keep_vehicle_fence)
    try:
        loaded = _load(args, options, errors)
    except OSError as error:
        errors.print(f"tml run: {error.filename or ''}: {error.strerror or error}",
                     markup=False, soft_wrap=True)
        return Ending.USAGE.code
    except TmlError as error:
        errors.print(f"tml run: {error}", markup=False)
        return Ending.USAGE.code
    if not isinstance(loaded, tuple):
        return _exit_code(loaded)
    mission, world, extra, profile = loaded
    from tml.run.journal import Journal, JournalBusy
    from tml.run.resume import ResumeRefused, file_digest, resume_point

    # Before anything starts, and before the log is read to resume from: a log that cannot
    # be written, or that another process still writes, is a usage error.
    try:
        journal = Journal.open(args.log, append=args.resume is not None)
    except JournalBusy as error:
        errors.print(f"tml run: {'cannot resume: ' if args.resume else '--log '}{error}",
                     markup=False)
        return Ending.USAGE.code
    except OSError as error:
        errors.print(f"tml run: --resume {args.resume}: cannot read: "
                     f"{error.strerror or error}" if args.resume is not None else
                     f"tml run: --log {args.log}: cannot write: {error.strerror or error}",
                     markup=False)
        return Ending.USAGE.code
    try:
        try:
            digest = file_digest(args.mission)
            point = None if args.resume is None else resume_point(
                args.resume, mission, digest, args.connect or [])
        except OSError as error:
            errors.print(f"tml run: --resume {args.resume}: cannot read: "
                         f"{error.strerror or error}", markup=False)
            return Ending.USAGE.code
        except ResumeRefused as error:
            errors.print(f"tml run: cannot resume: {error}", markup=False)
            return Ending.USAGE.code
        return _run(args, options, mission, world, extra, profile, journal, console, errors,
                    Resumed(digest, point))
    finally:
        journal.close()


def _exit_code(refusal: Refusal) -> ExitCode:
    from tml.run.session import Refusal

    return (Ending.INVALID if refusal is Refusal.MISSION else Ending.NOT_CLEARED).code


def _usage_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with the mission file or an address given, said with the option and
    the value; None when nothing is."""
    import os

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
    return vehicle_problem(args)


def _run(args: argparse.Namespace, options: SessionOptions, mission: Mission, world: World,
         extra: World | None, profile: VehicleProfile | None, journal: Journal,
         console: Console, errors: Console, resumed: Resumed) -> ExitCode:
    """Open the vehicles, clear the mission and fly; the exit code."""
    from tml.errors import TmlError
    from tml.run.resume import ResumeRefused
    from tml.run.session import Refusal, SeveralVehicles, open_session

    try:
        with open_session(options, world, errors) as session:
            session.check_resume(resumed.point)
            cleared = session.clear(mission, profile, extra)
            if isinstance(cleared, Refusal):
                return _exit_code(cleared)
            return _fly(args, session, mission, world, cleared, console, journal, resumed)
    except Stopped as error:
        error.taken()
        errors.print(f"tml run: {error} before the mission started", markup=False)
        return Ending.STOPPED.code
    except SeveralVehicles as error:
        errors.print(f"tml run: {error}", markup=False)
        return Ending.USAGE.code
    except ResumeRefused as error:
        errors.print(f"tml run: cannot resume: {error}", markup=False)
        return Ending.USAGE.code
    except TmlError as error:
        errors.print(f"tml run: {error}", markup=False)
        return Ending.NOT_CLEARED.code
    except OSError as error:
        errors.print(f"tml run: cannot open the vehicle link: {error}")
        return Ending.NOT_CLEARED.code


def _load(args: argparse.Namespace, options: SessionOptions, errors: Console,
          ) -> tuple[Mission, World, World | None, VehicleProfile | None] | Refusal:
    """The validated (and verified) mission, its world, the --world file's world and the
    verifier's profile (None: read from the vehicle, ``--profile vehicle``); or why not."""
    from tml.language.build import load_world
    from tml.language.diagnostics import format_human_all
    from tml.language.validation import validate_file
    from tml.run.session import VEHICLE_PROFILE, Refusal, verify
    from tml.world import World

    result = validate_file(args.mission)
    if result.errors or result.mission is None:
        for text in format_human_all(result.diagnostics, {result.file: result.source}):
            errors.print(text, markup=False)
        errors.print(f"tml run: {result.file}: invalid mission, not flown")
        return Refusal.MISSION
    mission = result.mission
    for text in format_human_all(result.diagnostics, {result.file: result.source}):
        errors.print(text, markup=False)  # a valid mission's warnings
    extra = load_world(args.world) if args.world else None
    world = (mission.world or World()).merged(extra)
    from tml.verify.profile import load_profile

    if args.profile == VEHICLE_PROFILE:
        return mission, world, extra, None  # verified once the vehicle's parameters are read
    profile = load_profile(args.profile)
    refused = verify(mission, profile, extra, options, errors)
    return refused if refused is not None else (mission, world, extra, profile)


def _fly(args: argparse.Namespace, session: Session, mission: Mission, world: World,
         profile: VehicleProfile, console: Console, journal: Journal,
         resumed: Resumed) -> ExitCode:
    from tml.run.display import LineDisplay, LiveDisplay

    display: LiveDisplay | LineDisplay | None = None
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
    flight = session.flight(
        mission, profile, world, journal, resumed=resumed.point, payloads=payloads,
        on_safety=on_safety,
        on_update=(lambda r: display.update(r.views())) if display else None,
        about={"sha256": resumed.digest})
    runner = flight.runner
    try:
        with on_stop_signals(lambda name: runner.stop(f"interrupted ({name})")), \
                display if display is not None else contextlib.nullcontext(), \
                _control_sockets(session, runner):
            outcome = flight.fly()
            if display is not None:
                display.update(runner.views(), force=True)
        _tell_signing(session, journal, said, runner.clock())
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
    ending = outcome.ending
    console.print(f"run {ending.status} (exit {int(ending.code)}): {ending.meaning}",
                  markup=False, highlight=False)
    return ending.code


def _control_sockets(session: Session,
                     runner: Runner) -> contextlib.AbstractContextManager[object]:
    """The run's control sockets (tml.run.control), one per vehicle at its ``--connect``
    address: ``tml command`` goes through them; a socket that cannot be had is said on
    the error console. None for the embedded simulator of ``--sim``, which nothing else
    reaches."""
    if session.options.sim:
        return contextlib.nullcontext()
    from tml.run.control import listening

    return listening(runner, {(v.link.address, v.system_id): v for v in session.vehicles},
                     on_problem=session.say)


def _tell_signing(session: Session, journal: Journal, said: list[str], now: float) -> None:
    """With signing on, log (and say, when there were any) the messages each link dropped
    unsigned or wrongly signed: a spoofer's, or a ground station with another key."""
    for address, unsigned, bad in session.signing_counts():
        message = (f"{address}: signing: {unsigned} unsigned and {bad} wrongly signed "
                   "message(s) dropped")
        journal.write(now, "signing", None, message=message, address=address,
                      unsigned=unsigned, bad_signature=bad)
        if unsigned or bad:
            said.append(message)
