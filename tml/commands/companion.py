"""``tml companion``: the simulated companion computer, attached to an autopilot from outside.

Runs :class:`sitl.companion_link.CompanionLink` (the embedded simulator's companion
computer, MAVLink component 191) against a vehicle at a connection address -- on ArduPilot,
its second serial port (SERIAL1; SITL instance I: ``tcp:127.0.0.1:5762+10*I``) -- until
SIGINT or SIGTERM. See docs/simulator.md.

Exit codes: 0 stopped by SIGINT or SIGTERM, 2 bad arguments, a malformed address or an
unreadable or invalid world file, 4 the address cannot be opened or no autopilot was heard
within ``--timeout``.
"""

from __future__ import annotations

import argparse
import sys
import threading
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
                             "command (default: the first autopilot heard)")
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

    from sitl.companion_link import CompanionLink

    stop = threading.Event()
    stopped_by: list[str] = []

    def on_signal(name: str) -> None:
        stopped_by.append(name)
        stop.set()

    def say(text: str) -> None:
        if not args.quiet:
            print(f"[{link.time:8.1f} s] {text}", flush=True)

    link = CompanionLink(args.connect, world, system_id=args.system_id, on_text=say)
    with on_stop_signals(on_signal):
        try:
            if not link.open(args.timeout, stop):
                return ExitCode.OK
            if not args.quiet:
                print(f"tml companion: component 191 of system {link.system_id} attached to "
                      f"{args.connect} (autopilot component {link.autopilot_component}); "
                      f"{Path(args.world).name}: {len(world.objects)} object(s), "
                      f"{len(world.obstacles)} obstacle(s)", flush=True)
            link.serve(stop)
        except VehicleError as error:
            return fail(str(error), ExitCode.FAILURE)
        except OSError as error:
            return fail(f"link to {args.connect} failed: {error}", ExitCode.FAILURE)
        finally:
            link.close()
    if not args.quiet:
        print(f"tml companion: stopped ({', '.join(stopped_by) or 'asked'})", flush=True)
    return ExitCode.OK
