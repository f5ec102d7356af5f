"""The options every command that flies takes to say which vehicles (``tml run``,
``tml serve``), and how they become a flight session's typed options
(:class:`tml.run.session.SessionOptions`): the only place an argparse Namespace meets the
session. The simulator's option values are checked by its own rules, and it is started,
through :mod:`tml.simulator`.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tml.run.session import SessionOptions


def _sim_param(text: str) -> tuple[str, float]:
    from tml.simulator import param_setting

    return param_setting(text)


def _sim_frames(text: str) -> list[str]:
    from tml.simulator import parse_frames

    try:
        return parse_frames(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _sim_battery(text: str) -> tuple[str, float]:
    from tml.simulator import battery_start

    return battery_start(text)


def _fast_boot() -> type[argparse.Action]:
    from tml.simulator import FastBoot

    return FastBoot


MAX_SIM_VEHICLES = 250
"""Simulated vehicles one ``tml run --sim`` flies at most: each takes three sockets in this
process, and pymavlink watches its sockets with select(), which cannot see a descriptor
past 1023."""


def positive(text: str) -> float:
    """A number above 0 (an argparse type)."""
    from tml.simulator import positive as check

    return check(text)


def _mavlink_id(what: str) -> Callable[[str], int]:
    """An argparse type: a MAVLink ``what`` id ("system", "component"), 1 to 255."""
    def parse(text: str) -> int:
        if not text.strip().isdigit() or not 1 <= int(text) <= 255:
            raise argparse.ArgumentTypeError(f"expected a MAVLink {what} id from 1 to 255, "
                                             f"got {text!r}")
        return int(text)
    return parse


system_id = _mavlink_id("system")
component_id = _mavlink_id("component")


def non_negative(text: str) -> float:
    """A number of 0 or more (an argparse type)."""
    from tml.simulator import non_negative as check

    return check(text)


def _sim_vehicles(text: str) -> int:
    from tml.simulator import count

    number = count(text)
    if number > MAX_SIM_VEHICLES:
        raise argparse.ArgumentTypeError(
            f"at most {MAX_SIM_VEHICLES} simulated vehicles (each takes three sockets, and "
            f"pymavlink's select() sees none past descriptor 1023), got {text}")
    return number


def add_vehicle_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options that say which vehicles to open (``tml run``, ``tml serve``):
    the simulator or MAVLink addresses, and how their links are watched."""
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--sim", action="store_true",
                       help="fly on the embedded simulator (loopback, free ports)")
    where.add_argument("--connect", action="append", metavar="ADDRESS",
                       help="fly the vehicle at this MAVLink address (tcp:HOST:PORT, "
                            "udpin:0.0.0.0:14550, /dev/ttyACM0 ...); repeatable")
    parser.add_argument("--sysid", type=system_id, action="append", default=[], metavar="N",
                        help="--connect: fly the vehicle with this MAVLink system id "
                             "(repeatable, in this order); needed when an address hears "
                             "several vehicles (default: the one vehicle heard)")
    parser.add_argument("--vehicles", type=_sim_vehicles, default=1, metavar="N",
                        help="--sim: number of simulated vehicles (default 1)")
    parser.add_argument("--speedup", type=positive, default=1.0, metavar="K",
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
    parser.add_argument("--link-lost-limit", type=positive, default=10.0, metavar="S",
                        help="abort a run after its link is lost this long (default 10 s)")
    parser.add_argument("--timeout", type=positive, default=30.0, metavar="S",
                        help="seconds to wait for each vehicle's first heartbeat (default 30)")
    parser.add_argument("--ready-timeout", type=non_negative, default=180.0, metavar="S",
                        help="seconds to wait, before the first task, for every vehicle to "
                             "report position, home, GPS and battery and to be armable "
                             "(default 180; 0 does not wait)")
    parser.add_argument("--clock", choices=("wall", "vehicle"), default="wall",
                        help="--connect: the mission's clock: the ground station's (wall, "
                             "default) or the first vehicle's own (vehicle: time limits in "
                             "vehicle seconds, e.g. for SITL run with --speedup); --sim "
                             "always uses the simulator's")
    parser.add_argument("--require-gcs-failsafe", action="store_true",
                        help="refuse to fly a vehicle whose own failsafe does not act when "
                             "it loses this ground station (ArduPilot FS_GCS_ENABLE 0 or not "
                             "reported); without it, --connect only warns")


def session_options(args: argparse.Namespace, program: str, *, lockstep: bool = False,
                    quiet: bool = False, force: bool = False, safe_state: str = "rtl",
                    safe_state_timeout: float = 120.0) -> SessionOptions:
    """The typed options of a flight session from the arguments of
    :func:`add_vehicle_arguments`, and the ones a command has of its own."""
    from tml.run.session import SessionOptions, SimulatorOptions
    from tml.simulator import open_simulator

    simulator = None
    if args.sim:
        simulator = SimulatorOptions(vehicles=args.vehicles, speedup=args.speedup,
                                     params=dict(args.sim_param), frames=tuple(args.sim_frame))
    return SessionOptions(
        connect=tuple(args.connect or ()), system_ids=tuple(dict.fromkeys(args.sysid)),
        simulator=simulator,
        open_simulator=open_simulator if args.sim else None, outputs=tuple(args.out),
        signing_key_file=args.signing_key_file, timeout=args.timeout, clock=args.clock,
        lockstep=lockstep and args.sim, link_lost_limit=args.link_lost_limit,
        ready_timeout=args.ready_timeout, require_gcs_failsafe=args.require_gcs_failsafe,
        safe_state=safe_state, safe_state_timeout=safe_state_timeout, force=force,
        quiet=quiet, program=program)


def vehicle_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with the signing key or an address of :func:`add_vehicle_arguments`,
    said with the option and the value; None when nothing is."""
    if args.sim and args.sysid:
        return ("--sysid picks vehicles on --connect addresses; the simulator's are "
                "numbered 1 to --vehicles")
    return _signing_problem(args) or _address_problem(args)


def _signing_problem(args: argparse.Namespace) -> str | None:
    import os

    from tml.errors import TmlError
    from tml.signing import ENVIRONMENT, signing_key

    if args.signing_key_file is None and ENVIRONMENT not in os.environ:
        return None
    try:
        signing_key(args.signing_key_file)
    except OSError as error:
        return f"--signing-key-file {args.signing_key_file}: {error.strerror or error}"
    except TmlError as error:
        return f"signing key: {error}"
    return None


def _address_problem(args: argparse.Namespace) -> str | None:
    from tml.mavlink.link import address_problem

    for option, addresses, output in (("--connect", args.connect or [], False),
                                      ("--out", args.out, True)):
        for address in addresses:
            problem = address_problem(address, output=output)
            if problem is not None:
                return f"{option} {address}: {problem}"
    return None
