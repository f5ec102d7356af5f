"""``tml verify``: arguments and the command itself.

Exit codes: 0 feasible, 1 infeasible or invalid mission (a terrain file the mission names
that cannot be read, too), 2 usage or I/O error (a missing file, a bad profile, world or
``--terrain`` file, a vehicle that cannot be reached for ``--profile vehicle``).
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from tml.errors import ExitCode

if TYPE_CHECKING:
    from tml.terrain import Terrain
    from tml.verify.profile import VehicleProfile
    from tml.world import World

VEHICLE_PROFILE = "vehicle"  # --profile vehicle --connect ADDRESS: from its parameters


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml verify``."""
    parser.add_argument("missions", nargs="+", metavar="FILE",
                        help="mission files (each verified with the same profile and world)")
    parser.add_argument("--profile", default="quadcopter", metavar="P",
                        help="vehicle profile: quadcopter (default), fixed-wing, rover, a "
                             "TOML file, or vehicle to fill the profile of the vehicle's kind "
                             "from the parameters of the vehicle at --connect")
    parser.add_argument("--connect", metavar="ADDRESS",
                        help="--profile vehicle: the vehicle's MAVLink address "
                             "(tcp:127.0.0.1:5760 ...)")
    parser.add_argument("--timeout", type=float, default=30.0, metavar="S",
                        help="--profile vehicle: seconds to wait for the vehicle's heartbeat "
                             "(default 30)")
    parser.add_argument("--world", metavar="W",
                        help="world file laid over the mission's <environment>")
    parser.add_argument("--terrain", metavar="PATH",
                        help="terrain data: an SRTM .hgt tile, an EPSG:4326 GeoTIFF or a "
                             "directory of them; every path is judged above the ground "
                             "(instead of the mission's <terrain>)")
    parser.add_argument("--battery", type=float, default=100.0, metavar="PERCENT",
                        help="battery charge at the start (default: 100)")
    parser.add_argument("--format", choices=("table", "json"), default="table",
                        help="output format (default: table)")


def run(args: argparse.Namespace) -> ExitCode:
    """Run ``tml verify``; return the exit code."""
    from tml.errors import TmlError
    from tml.language.build import load_world
    from tml.verify.profile import load_profile

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
        terrain = _load_terrain(args.terrain) if args.terrain else None
    except OSError as exc:
        print(f"tml verify: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return ExitCode.USAGE
    except TmlError as exc:
        print(f"tml verify: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    codes: list[ExitCode] = []
    documents: list[str] = []
    for index, path in enumerate(args.missions):
        if index and args.format != "json":
            print()
        code, document = _verify_one(path, args, profile, world, terrain)
        codes.append(code)
        if document is not None:
            documents.append(document)
    if args.format == "json" and documents:
        print(documents[0] if len(args.missions) == 1 else
              "[\n" + ",\n".join(documents) + "\n]")
    return max(codes)  # a usage error over an infeasible mission over a feasible one


def _load_terrain(path: str) -> Terrain:
    from tml.terrain import load_terrain

    return load_terrain(path)


def _verify_one(path: str, args: argparse.Namespace, profile: VehicleProfile,
                world: World | None, terrain: Terrain | None = None
                ) -> tuple[ExitCode, str | None]:
    """Verify one mission file and print its report (a JSON document is returned instead);
    the exit code it alone would give."""
    from tml.errors import TmlError
    from tml.language.diagnostics import format_human_all, format_json
    from tml.language.validation import validate_file
    from tml.verify.motion import PredictedState
    from tml.verify.static import verify_mission
    from tml.world import World

    try:
        result = validate_file(path)
    except OSError as exc:
        print(f"tml verify: {exc.filename or path}: {exc.strerror or exc}", file=sys.stderr)
        return ExitCode.USAGE, None
    if result.errors or result.mission is None:
        if args.format == "json":
            return ExitCode.INVALID, format_json([(result.file, False, result.diagnostics)])
        for text in format_human_all(result.diagnostics, {result.file: result.source}):
            print(text)
        print(f"{result.file}: invalid mission, not verified")
        return ExitCode.INVALID, None
    mission = result.mission
    for text in format_human_all(result.diagnostics, {result.file: result.source}):
        print(text, file=sys.stderr)  # a valid mission's warnings
    merged = (mission.world or World()).merged(world)
    named = merged.terrain
    if terrain is None and named is not None:
        try:
            terrain = _load_terrain(named.path)
        except TmlError as exc:
            where = f"{named.location}: " if named.location else ""
            said = sys.stderr if args.format == "json" else sys.stdout  # JSON: no document
            print(f"{where}terrain source {named.source!r}: {exc}", file=said)
            print(f"{result.file}: terrain data unusable, not verified", file=said)
            return ExitCode.INVALID, None
    start = PredictedState(battery=args.battery, heading=merged.home_or_default.heading)
    report = verify_mission(mission, profile, world, start, terrain)
    code = ExitCode.OK if report.feasible else ExitCode.INVALID
    if args.format == "json":
        from tml.verify.report import report_json

        return code, report_json(report)
    from tml.run.display import output_console
    from tml.verify.report import print_report

    print_report(report, output_console())
    return code, None


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
