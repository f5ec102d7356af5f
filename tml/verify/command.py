"""``tml verify``: arguments and the command itself.

Exit codes: 0 feasible, 1 infeasible or invalid mission, 2 usage or I/O error (a missing
file, a bad profile or world file).
"""

from __future__ import annotations

import argparse
import sys

EXIT_FEASIBLE, EXIT_INFEASIBLE, EXIT_USAGE = 0, 1, 2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml verify``."""
    parser.add_argument("mission", metavar="FILE")
    parser.add_argument("--profile", default="quadcopter", metavar="P",
                        help="vehicle profile: 'quadcopter', 'fixed-wing' or a TOML file "
                             "(default: quadcopter)")
    parser.add_argument("--world", metavar="W",
                        help="world file laid over the mission's <environment>")
    parser.add_argument("--battery", type=float, default=100.0, metavar="PERCENT",
                        help="battery charge at the start (default: 100)")
    parser.add_argument("--format", choices=("table", "json"), default="table",
                        help="output format (default: table)")


def run(args: argparse.Namespace) -> int:
    """Run ``tml verify``; return the exit code."""
    from tml.diagnostics import format_human, format_json
    from tml.errors import TmlError
    from tml.parse import load_world
    from tml.validation import validate_file
    from tml.verify.motion import VehicleState
    from tml.verify.profile import load_profile
    from tml.verify.static import verify_mission
    from tml.world import World

    if not 0 <= args.battery <= 100:
        print(f"tml verify: --battery {args.battery:g}: must be between 0 and 100",
              file=sys.stderr)
        return EXIT_USAGE
    try:
        profile = load_profile(args.profile)
        world = load_world(args.world) if args.world else None
        result = validate_file(args.mission)
    except OSError as exc:
        print(f"tml verify: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    except TmlError as exc:
        print(f"tml verify: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if result.errors or result.mission is None:
        if args.format == "json":
            print(format_json([(result.file, False, result.diagnostics)]))
        else:
            for diagnostic in result.diagnostics:
                print(format_human(diagnostic, {result.file: result.source}))
            print(f"{result.file}: invalid mission, not verified")
        return EXIT_INFEASIBLE
    mission = result.mission
    home = (mission.world or World()).merged(world).home_or_default
    start = VehicleState(battery=args.battery, heading=home.heading)
    report = verify_mission(mission, profile, world, start)
    if args.format == "json":
        from tml.verify.report import report_json

        print(report_json(report))
    else:
        from rich.console import Console

        from tml.verify.report import print_report

        console = Console(soft_wrap=True)
        if not console.is_terminal:  # a pipe or a file: wide enough for every column
            console = Console(soft_wrap=True, width=140)
        print_report(report, console)
    return EXIT_FEASIBLE if report.feasible else EXIT_INFEASIBLE
