"""``tml verify``: arguments and the command itself.

Exit codes: 0 feasible, 1 infeasible or invalid mission, 2 usage or I/O error (a missing
file, a bad profile or world file, a vehicle that cannot be reached for ``--profile
vehicle``).
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from tml.errors import ExitCode

if TYPE_CHECKING:
    from tml.verify.profile import VehicleProfile

VEHICLE_PROFILE = "vehicle"  # --profile vehicle --connect ADDRESS: from its parameters


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml verify``."""
    parser.add_argument("mission", metavar="FILE")
    parser.add_argument("--profile", default="quadcopter", metavar="P",
                        help="vehicle profile: 'quadcopter', 'fixed-wing', a TOML file, or "
                             "'vehicle' to fill the quadcopter profile from the parameters "
                             "of the vehicle at --connect (default: quadcopter)")
    parser.add_argument("--connect", metavar="ADDRESS",
                        help="--profile vehicle: the vehicle's MAVLink address "
                             "(tcp:127.0.0.1:5760 ...)")
    parser.add_argument("--timeout", type=float, default=30.0, metavar="S",
                        help="--profile vehicle: seconds to wait for the vehicle's heartbeat "
                             "(default 30)")
    parser.add_argument("--world", metavar="W",
                        help="world file laid over the mission's <environment>")
    parser.add_argument("--battery", type=float, default=100.0, metavar="PERCENT",
                        help="battery charge at the start (default: 100)")
    parser.add_argument("--format", choices=("table", "json"), default="table",
                        help="output format (default: table)")


def run(args: argparse.Namespace) -> ExitCode:
    """Run ``tml verify``; return the exit code."""
    from tml.errors import TmlError
    from tml.language.build import load_world
    from tml.language.diagnostics import format_human, format_json
    from tml.language.validation import validate_file
    from tml.verify.motion import PredictedState
    from tml.verify.profile import load_profile
    from tml.verify.static import verify_mission
    from tml.world import World

    if not 0 <= args.battery <= 100:
        print(f"tml verify: --battery {args.battery:g}: must be between 0 and 100",
              file=sys.stderr)
        return ExitCode.USAGE
    if (args.profile == VEHICLE_PROFILE) != (args.connect is not None):
        print("tml verify: --profile vehicle reads the profile from a vehicle: give both it "
              "and --connect ADDRESS", file=sys.stderr)
        return ExitCode.USAGE
    try:
        profile = (_vehicle_profile(args.connect, args.timeout)
                   if args.profile == VEHICLE_PROFILE else load_profile(args.profile))
        world = load_world(args.world) if args.world else None
        result = validate_file(args.mission)
    except OSError as exc:
        print(f"tml verify: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return ExitCode.USAGE
    except TmlError as exc:
        print(f"tml verify: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    if result.errors or result.mission is None:
        if args.format == "json":
            print(format_json([(result.file, False, result.diagnostics)]))
        else:
            for diagnostic in result.diagnostics:
                print(format_human(diagnostic, {result.file: result.source}))
            print(f"{result.file}: invalid mission, not verified")
        return ExitCode.INVALID
    mission = result.mission
    home = (mission.world or World()).merged(world).home_or_default
    start = PredictedState(battery=args.battery, heading=home.heading)
    report = verify_mission(mission, profile, world, start)
    if args.format == "json":
        from tml.verify.report import report_json

        print(report_json(report))
    else:
        from tml.run.display import output_console
        from tml.verify.report import print_report

        print_report(report, output_console())
    return ExitCode.OK if report.feasible else ExitCode.INVALID


def _vehicle_profile(address: str, timeout: float) -> VehicleProfile:
    """The shipped profile of the kind of the vehicle at ``address`` (the first one heard
    there) filled in from its parameters; says on stderr what was read. Raises a
    VehicleError when no vehicle answers."""
    from tml.mavlink.adapter import MavlinkVehicle
    from tml.mavlink.link import Link, parse_address
    from tml.verify.profile import describe_parameters, profile_from_vehicle, shipped_for

    parse_address(address)
    with Link(address) as link:
        info = link.wait_vehicle(None, timeout)
        vehicle = MavlinkVehicle(link, info.system_id, connect_timeout=timeout)
        try:
            profile, params = profile_from_vehicle(vehicle.read_parameters,
                                                   shipped_for(vehicle.state().vehicle_type))
        finally:
            vehicle.close()
    print(f"tml verify: {profile.name} profile from vehicle {info.system_id}'s parameters: "
          + describe_parameters(params), file=sys.stderr)
    return profile
