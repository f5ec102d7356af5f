"""``tml companion``: the simulated companion computer, attached to an autopilot from outside.

Attaches the embedded simulator's companion computer (MAVLink component 191, reached through
:mod:`tml.simulator`) to a vehicle at a connection address -- on ArduPilot, its second
serial port (SERIAL1; SITL instance I: ``tcp:127.0.0.1:5762+10*I``) -- through the flight
session (:func:`tml.run.session.open_companion`: the address, ``--sysid`` and
``--timeout`` as typed options), until SIGINT or SIGTERM. See docs/simulator.md.

Exit codes: 0 stopped by SIGINT or SIGTERM, 2 bad arguments, a malformed address or an
unreadable or invalid world file, an address that hears several autopilots without
``--sysid``, 4 the address cannot be opened or no autopilot was heard
within ``--timeout``.
"""

from __future__ import annotations

import argparse
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from tml.commands.signals import on_stop_signals
from tml.errors import ExitCode

if TYPE_CHECKING:
    from tml.world import World



def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml companion``."""
    from tml.commands.vehicles import positive, system_id

    parser.add_argument("--connect", required=True, metavar="ADDRESS",
                        help="the autopilot's companion port (ArduPilot SITL instance I: "
                             "tcp:127.0.0.1:5762+10*I, its SERIAL1), any address `tml run "
                             "--connect` takes")
    parser.add_argument("--world", required=True, metavar="FILE",
                        help="what the camera can see: a world file (as `tml run --world`) "
                             "or a mission file (its <environment>)")
    parser.add_argument("--sysid", "--system-id", dest="system_id", type=system_id,
                        metavar="N",
                        help="the vehicle's MAVLink system id, as for tml run and tml "
                             "command (default: the one autopilot heard; needed when the "
                             "address carries several)")
    parser.add_argument("--timeout", type=positive, default=30.0, metavar="S",
                        help="seconds to wait for the autopilot's heartbeat (default 30)")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="print nothing but errors (no line per first sighting)")


def load_world_file(path: str) -> World:
    """The world of a world file, or the <environment> of a mission file.

    Raises OSError when the file cannot be read and a MissionError when it is not a valid
    world or mission.
    """
    from tml.language.build import load_world
    from tml.language.validation import load_mission
    from tml.language.xml import read_xml
    from tml.world import World

    if read_xml(path).root.tag == "mission":
        return load_mission(path).world or World()
    return load_world(path)


def run(args: argparse.Namespace) -> ExitCode:
    """Run ``tml companion``; return the exit code."""
    from tml.errors import TmlError, VehicleError
    from tml.mavlink.link import parse_address
    from tml.run.session import SessionOptions, SeveralVehicles, open_companion
    from tml.simulator import open_companion as companion_factory

    def fail(message: str, code: ExitCode) -> ExitCode:
        print(f"tml companion: {message}", file=sys.stderr)
        return code

    try:
        parse_address(args.connect)
    except VehicleError as error:
        return fail(str(error), ExitCode.USAGE)
    try:
        world = load_world_file(args.world)
    except OSError as error:
        return fail(f"{args.world}: {error.strerror or error}", ExitCode.USAGE)
    except TmlError as error:
        return fail(str(error), ExitCode.USAGE)
    options = SessionOptions(
        connect=(args.connect,), system_ids=() if args.system_id is None else (args.system_id,),
        timeout=args.timeout, quiet=args.quiet, program="tml companion",
        open_companion=companion_factory)

    stop = threading.Event()
    stopped_by: list[str] = []
    clock: list[Callable[[], float]] = [lambda: 0.0]  # the autopilot's, once attached

    def on_signal(name: str) -> None:
        stopped_by.append(name)
        stop.set()

    def say(text: str) -> None:
        if not args.quiet:
            print(f"[{clock[0]():8.1f} s] {text}", flush=True)

    with on_stop_signals(on_signal):
        try:
            with open_companion(options, world, stop, say) as companion:
                if companion is None:
                    return ExitCode.OK
                clock[0] = lambda: companion.time
                if not args.quiet:
                    print(f"tml companion: component 191 of system {companion.system_id} "
                          f"attached to {args.connect} (autopilot component "
                          f"{companion.autopilot_component}); {Path(args.world).name}: "
                          f"{len(world.objects)} object(s), {len(world.obstacles)} "
                          "obstacle(s)", flush=True)
                companion.serve(stop)
        except SeveralVehicles as error:
            return fail(str(error), ExitCode.USAGE)
        except VehicleError as error:
            return fail(str(error), ExitCode.FAILURE)
        except OSError as error:
            return fail(f"link to {args.connect} failed: {error}", ExitCode.FAILURE)
    if not args.quiet:
        print(f"tml companion: stopped ({', '.join(stopped_by) or 'asked'})", flush=True)
    return ExitCode.OK
