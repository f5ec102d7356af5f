"""``tml command rtl|land|hold|disarm``: tell one vehicle to return, land, hold or disarm,
now, and confirm it from what the vehicle does.

Theory of operation
-------------------
A ``tml run`` that flies the vehicle (its control socket for this address and system id,
:mod:`tml.run.control`) takes the command: the run pauses (hold) or ends into the
commanded state, and answers once the vehicle's telemetry confirmed it. Else the link is
opened (:class:`~tml.mavlink.link.Link`, signed with ``--signing-key-file``, component
:data:`COMMAND_COMPONENT`); without ``--sysid`` the vehicles on it are listened to, and
several are refused (which one is the operator's to say). The vehicle's HEARTBEAT is
waited for, the telemetry the rule judges by is asked for and waited for (HEARTBEAT, the
landed state, the position), and the rule of :func:`tml.engine.safety.operator_request`
says what to send -- or refuses, with the reason, what would be unsafe (a disarm in the
air) or what the vehicle cannot do (a rover landing). A hold is a mode that holds by
itself (:data:`~tml.engine.safety.HOLDING_MODES`: nothing keeps a GUIDED target once
this command has gone); RTL, LAND and disarm are carried out as a run carries them out
(:class:`~tml.mavlink.adapter.MavlinkVehicle`). The command is done only when the
vehicle's telemetry confirms it by its motion (:class:`~tml.engine.confirm.Confirmation`).

Exit codes: 0 done and confirmed (or nothing to do: a vehicle on the ground and disarmed
told to return, land, hold or disarm); 2 a usage error (several vehicles without
``--sysid`` too), or a command refused as unsafe or impossible, with the reason; 4 no
vehicle or telemetry within ``--timeout``, the vehicle refused the command, or its
telemetry did not confirm it within ``--timeout`` (what was seen is said).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from tml.errors import ExitCode

if TYPE_CHECKING:
    from tml.mavlink.adapter import MavlinkVehicle
    from tml.mavlink.link import Link
    from tml.vehicle import RequestResult, VehicleState

PROGRAM = "tml command"
POLL_PERIOD = 0.05  # s between two looks at the vehicle's state while waiting


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the arguments of ``tml command``."""
    from tml.commands.vehicles import positive, system_id
    from tml.engine.safety import OPERATOR_COMMANDS

    parser.add_argument("command", choices=OPERATOR_COMMANDS,
                        help="rtl: return to launch; land: land where it is; hold: stop "
                             "where it is (a multicopter hovers, a fixed-wing circles, a "
                             "rover stops); disarm: stop the motors, only on the ground")
    parser.add_argument("--connect", required=True, metavar="ADDRESS",
                        help="the vehicle's MAVLink address (tcp:HOST:PORT, "
                             "udpin:0.0.0.0:14550, /dev/ttyACM0 ...)")
    parser.add_argument("--sysid", type=system_id, metavar="N",
                        help="the vehicle's MAVLink system id (needed when the address "
                             "carries several vehicles)")
    parser.add_argument("--signing-key-file", metavar="FILE",
                        help="MAVLink 2 signing: the file holds 64 hex digits or a "
                             "passphrase (else the key of TML_SIGNING_KEY, if set)")
    parser.add_argument("--timeout", type=positive, default=30.0, metavar="S",
                        help="seconds to wait for each step: the heartbeat, the telemetry, "
                             "the vehicle's answer, the telemetry showing it done "
                             "(default 30)")


def run(args: argparse.Namespace) -> ExitCode:
    """Carry out ``tml command``; the exit code (module docstring)."""
    from tml.errors import TmlError
    from tml.mavlink.link import Link, address_problem
    from tml.run.control import runs_at
    from tml.signing import signing_key

    problem = address_problem(args.connect)
    if problem is not None:
        return _say(ExitCode.USAGE, f"--connect {args.connect}: {problem}")
    try:
        key = signing_key(args.signing_key_file)
    except OSError as error:
        return _say(ExitCode.USAGE, f"--signing-key-file {args.signing_key_file}: "
                                    f"{error.strerror or error}")
    except TmlError as error:
        return _say(ExitCode.USAGE, f"signing key: {error}")
    # A run that flies the vehicle takes the command (tml.run.control); the vehicle
    # itself only when none does.
    # Without --sysid, the vehicles the address carries are heard first: with several,
    # which one is the operator's to say.
    runs = runs_at(args.connect)
    if args.sysid is not None and args.sysid in runs:
        through = _through_run(args, args.sysid)
        if through is not None:
            return through
    try:
        link = Link(args.connect, signing_key=key, source_component=COMMAND_COMPONENT,
                    system_ids=None if args.sysid is None else [args.sysid])
    except (OSError, TmlError) as error:
        return _say(ExitCode.FAILURE, f"cannot open {args.connect}: {error}"
                                      f"{_run_hint(args, runs)}")
    try:
        with link:
            return _command(link, args)
    except SeveralVehicles as error:
        return _say(ExitCode.USAGE, str(error))
    except TmlError as error:
        return _say(ExitCode.FAILURE, f"{error}{_run_hint(args, runs)}")


def _run_hint(args: argparse.Namespace, runs: list[int]) -> str:
    """Why the vehicle may not be heard: a run holds the address (a serial port, or a TCP
    port that takes one client), and --sysid would reach it through its control socket."""
    if not runs or args.sysid is not None:
        return ""
    return (f" (a run flies the vehicle with system id {', '.join(map(str, runs))} at "
            f"{args.connect}: give --sysid to command it through the run)")


COMMAND_COMPONENT = 91
"""The MAVLink component id ``tml command`` sends as (system 255, the ground station the
vehicle's GCS failsafe hears; ``tml run`` is component 190 and ``tml serve`` 90)."""


class SeveralVehicles(Exception):
    """The address carries several vehicles and none was named (exit 2)."""


def _through_run(args: argparse.Namespace, system_id: int) -> ExitCode | None:
    """Send the command through the run flying vehicle ``system_id``; its exit code, or
    None when no run took it (it ended meanwhile)."""
    from tml.run.control import ask_run

    answer = ask_run(args.connect, system_id, args.command, args.timeout)
    if answer is None or answer.outcome == "no run":
        return None
    if answer.exit_code == ExitCode.OK:
        print(f"{answer.message} [through the run]")
        return ExitCode(answer.exit_code)
    return _say(ExitCode(answer.exit_code), f"{answer.message} [through the run]")


def _command(link: Link, args: argparse.Namespace) -> ExitCode:
    from tml.mavlink.adapter import MavlinkVehicle

    system_id = _vehicle(link, args.sysid, args.timeout)
    if args.sysid is None and system_id in _runs(args.connect):  # found by listening
        through = _through_run(args, system_id)
        if through is not None:
            return through
    vehicle = MavlinkVehicle(link, system_id, connect_timeout=args.timeout)
    try:
        return _carry_out(vehicle, args.command, args.timeout)
    finally:
        vehicle.close()


def _runs(address: str) -> list[int]:
    from tml.run.control import runs_at

    return runs_at(address)


def _vehicle(link: Link, system_id: int | None, timeout: float) -> int:
    """The system id of the vehicle to command: ``system_id``, waited for; else the one
    vehicle heard (others have DISCOVERY_WAIT s after the first to say hello). Raises
    :class:`SeveralVehicles` when more than one is heard."""
    from tml.run.session import DISCOVERY_WAIT

    first = link.wait_vehicle(system_id, timeout).system_id
    if system_id is not None:
        return first
    time.sleep(DISCOVERY_WAIT)  # other vehicles on the same link say hello too
    heard = sorted({first, *link.vehicles()})
    if len(heard) > 1:
        raise SeveralVehicles(f"{link.address}: vehicles with system ids "
                              f"{', '.join(map(str, heard))} heard: say which with --sysid N")
    return first


def _carry_out(vehicle: MavlinkVehicle, command: str, timeout: float) -> ExitCode:
    """Wait for the telemetry, ask the rule, send, and wait for the answer and the
    telemetry that confirms it (tml.engine.confirm)."""
    from dataclasses import replace

    from tml.engine.confirm import Confirmation
    from tml.engine.safety import CommandRefusal, holding_mode, operator_request
    from tml.errors import CommandRejected, VehicleError
    from tml.mavlink.targets import TargetWatch
    from tml.run.control import own_time

    vid = vehicle.vehicle_id
    vehicle.mav.request_rates()
    targets = TargetWatch(vehicle.link, vehicle.system_id)  # what it flies to in GUIDED
    targets.ask(vehicle.mav)
    state = _wait(vehicle, lambda s: _telemetry_in(vehicle, s), timeout)
    if state is None:
        return _say(ExitCode.FAILURE, f"vehicle {vid}: no telemetry within {timeout:g} s "
                                      f"(heartbeat, landed state and position)")
    try:
        request = operator_request(state, command)
    except CommandRefusal as refusal:
        return _say(ExitCode.USAGE, f"vehicle {vid}: {command} refused: {refusal}")
    if request is None:
        print(f"vehicle {vid}: nothing to do: {_where(state)}")
        return ExitCode.OK
    targets.clear()  # those reported after the command
    if command == "hold":
        mode = holding_mode(state)
        try:
            vehicle.mav.set_mode(mode)
        except CommandRejected as error:
            return _say(ExitCode.FAILURE, f"vehicle {vid}: hold ({mode}) refused by the "
                                          f"vehicle: {error}")
        except VehicleError as error:
            return _say(ExitCode.FAILURE, f"vehicle {vid}: hold ({mode}): {error}")
    else:
        request = replace(request, request_id=1)
        vehicle.submit(request)
        result = _answer(vehicle, timeout)
        if result is None:
            return _say(ExitCode.FAILURE, f"vehicle {vid}: {command}: no answer within "
                                          f"{timeout:g} s")
        if not result.ok:
            return _say(ExitCode.FAILURE, f"vehicle {vid}: {command} refused by the "
                                          f"vehicle: {result.reason} {result.detail}".rstrip())
    confirmation = Confirmation(command)
    shown = _wait(vehicle, lambda s: confirmation.see(s, own_time(vehicle, s), targets.latest),
                  timeout)
    if shown is None:
        return _say(ExitCode.FAILURE, f"vehicle {vid}: {command} not confirmed within "
                                      f"{timeout:g} s (wanted {confirmation.criterion()}; "
                                      f"seen {confirmation.seen()})")
    print(f"vehicle {vid}: {command} done: {confirmation.seen()}")
    return ExitCode.OK


def _telemetry_in(vehicle: MavlinkVehicle, state: VehicleState) -> bool:
    """Whether the readings the rule judges by have arrived: the HEARTBEAT, the position,
    and the landed state (which a ground vehicle may never send)."""
    from tml.language.kinds import Kind, kind_of

    arrived = vehicle.link.arrivals(vehicle.system_id)
    landed = "EXTENDED_SYS_STATE" in arrived or kind_of(state.vehicle_type) is Kind.GROUND
    return "HEARTBEAT" in arrived and "GLOBAL_POSITION_INT" in arrived and landed \
        and state.link != "lost"


def _wait(vehicle: MavlinkVehicle, until: Callable[[VehicleState], bool],
          timeout: float) -> VehicleState | None:
    """The first state for which ``until`` holds, within ``timeout`` s; None after."""
    end = time.monotonic() + timeout
    while True:
        state = vehicle.state()
        if until(state):
            return state
        if time.monotonic() >= end:
            return None
        time.sleep(POLL_PERIOD)


def _answer(vehicle: MavlinkVehicle, timeout: float) -> RequestResult | None:
    """The result of the one request sent (numbered 1), within ``timeout`` s."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        for result in vehicle.poll():
            if result.request_id == 1:
                return result
        time.sleep(POLL_PERIOD)
    return None


def _where(state: VehicleState) -> str:
    """Mode, armed and where the vehicle is, in a few words."""
    armed = "armed" if state.armed else "disarmed"
    ground = "on the ground" if state.landed else f"{state.altitude:.1f} m up"
    return f"mode {state.mode or '?'}, {armed}, {ground}"


def _say(code: ExitCode, message: str) -> ExitCode:
    print(f"{PROGRAM}: {message}", file=sys.stderr)
    return code
