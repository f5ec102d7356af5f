"""``tml export`` and ``tml import``: a mission as other tools' plans, and back.

Exit codes: 0 written (actions with no mission item are named on standard error, and the
plan is written without them), 1 an invalid mission, a plan file that cannot be read as
one or holds nothing to fly, one that holds what a mission cannot carry exactly (unless
``--allow-loss``) or that makes an invalid mission, 2 usage or I/O error (a missing or
non-UTF-8 file, an unwritable output, a role to choose).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from tml.errors import ExitCode
from tml.language.kinds import Kind
from tml.world import Home

if TYPE_CHECKING:
    from tml.language.model import Mission
    from tml.world import World

FORMATS = {"plan": ".plan", "wpl": ".waypoints", "kml": ".kml", "geojson": ".geojson",
           "fence": ".txt", "rally": ".txt"}
LISTS = ("fence", "rally")
"""The formats that hold a world's fence or rally points only (MAVProxy's ``fence save``
and ``rally save``): exported from a world file or a mission's environment."""
SUFFIXES = {".plan": "plan", ".waypoints": "wpl", ".txt": "wpl", ".kml": "kml",
            ".geojson": "geojson", ".json": "geojson"}


def add_export_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml export``."""
    parser.add_argument("mission", metavar="FILE",
                        help="a mission (or, for fence and rally, a world file)")
    parser.add_argument("--format", choices=tuple(FORMATS),
                        help="plan (QGroundControl), wpl (QGC WPL 110, MAVProxy's wp load), "
                             "kml or geojson (the path, obstacles and geofence for a map), "
                             "fence or rally (the world's fence or rally list, MAVProxy's "
                             "fence load and rally load); default: from the suffix of -o")
    parser.add_argument("-o", "--output", metavar="OUT",
                        help="write here (default: standard output)")
    parser.add_argument("--role", metavar="ROLE",
                        help="in a mission with roles: the role whose tasks to export "
                             "(kml and geojson draw every role without it)")
    parser.add_argument("--kind", choices=[k.value for k in Kind], default=None,
                        help="the kind of vehicle the items are for (default: the role's, "
                             "else multicopter)")
    parser.add_argument("--world", metavar="FILE",
                        help="world file laid over the mission's <environment>")


HOME_ALTITUDE = 0.0
"""The altitude (m AMSL) of an ``--home`` given without one. The fence and rally lists
it places give altitudes above home (a fence item none at all), so it changes none of
them; it is the world's ``<home altitude>``."""


def home_position(text: str) -> Home:
    """``LAT,LON[,ALT]`` (degrees, m AMSL; ALT default :data:`HOME_ALTITUDE`) as a home
    (an argparse type)."""
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (2, 3) or not all(map(math.isfinite, values)):
        raise argparse.ArgumentTypeError(f"expected LAT,LON[,ALT] (e.g. 40.0716,-105.2301), "
                                         f"got {text!r}")
    if not (-90 <= values[0] <= 90 and -180 <= values[1] <= 180):
        raise argparse.ArgumentTypeError(f"latitude or longitude out of range in {text!r}")
    return Home(values[0], values[1], values[2] if len(values) == 3 else HOME_ALTITUDE)


def add_import_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml import``."""
    parser.add_argument("plan", metavar="FILE", help="a .plan or a QGC WPL waypoint file")
    parser.add_argument("-o", "--output", metavar="OUT",
                        help="write the mission here (default: standard output)")
    parser.add_argument("--name", help="the mission's name (default: the file's name)")
    parser.add_argument("--allow-loss", action="store_true",
                        help="write the mission even when the file holds what it cannot "
                             "carry exactly (each such item is named; without this option "
                             "the file is refused)")
    parser.add_argument("--home", metavar="LAT,LON[,ALT]", type=home_position,
                        help="the home to place the file's fence and rally points from when "
                             "the file gives none (a fence or rally list); ALT in m above sea "
                             f"level, default {HOME_ALTITUDE:g}")


def _say(command: str, message: str) -> None:
    print(f"tml {command}: {message}", file=sys.stderr)


def _write(command: str, output: str | None, text: str) -> bool:
    """Write ``text`` to ``output`` (standard output for None); False when it cannot."""
    if output is None:
        sys.stdout.write(text)
        return True
    try:
        Path(output).write_text(text, encoding="utf-8")
    except OSError as error:
        _say(command, f"-o {output}: cannot write: {error.strerror or error}")
        return False
    return True


def export(args: argparse.Namespace) -> ExitCode:
    """Run ``tml export``; return the exit code."""
    from tml.errors import TmlError
    from tml.language.build import load_world
    from tml.language.diagnostics import format_human_all
    from tml.language.validation import validate_file
    from tml.plans.maps import write_geojson, write_kml
    from tml.plans.planned import PlanError, plan_mission, world_left_out
    from tml.plans.qgc import write_plan
    from tml.plans.wpl import write_wpl

    form = args.format or SUFFIXES.get(Path(args.output or "").suffix.lower())
    if form is None:
        _say("export", "--format plan|wpl|kml|geojson|fence|rally is needed"
             + (f" (-o {args.output}: the suffix does not say)" if args.output else ""))
        return ExitCode.USAGE
    try:
        result = validate_file(args.mission, root=None if form in LISTS else "mission")
        extra = load_world(args.world) if args.world else None
    except OSError as error:
        _say("export", f"{error.filename}: {error.strerror or error}")
        return ExitCode.USAGE
    except TmlError as error:
        _say("export", f"--world {args.world}: {error}")
        return ExitCode.USAGE
    if result.errors or (result.mission is None and form not in LISTS):
        for text in format_human_all(result.diagnostics, {result.file: result.source}):
            print(text, file=sys.stderr)
        _say("export", f"{result.file}: invalid mission, not exported")
        return ExitCode.INVALID
    if form in LISTS:  # a world file's result holds no mission
        return _export_list(args, form, result.mission, extra)
    mission = result.mission
    assert mission is not None
    kind = Kind(args.kind) if args.kind else None
    try:
        if form in ("kml", "geojson") and args.role is None and mission.roles:
            plans = [plan_mission(mission, r.name, kind, extra) for r in mission.roles]
        else:
            plans = [plan_mission(mission, args.role, kind, extra)]
    except PlanError as error:
        _say("export", str(error))
        return ExitCode.USAGE
    said: dict[str, None] = {}  # each once, in order, when several roles say the same
    for plan in plans:
        said.update({f"{mission.file}: {skipped}": None for skipped in plan.skipped})
        said.update({f"note: {note}": None for note in plan.notes})
        said.update({f"note: {note}": None for note in world_left_out(plan.world, form)})
    for message in said:
        _say("export", message)
    world = plans[0].world
    if form == "plan":
        text = write_plan(plans[0])
    elif form == "wpl":
        text = write_wpl(plans[0])
    elif form == "kml":
        text = write_kml(plans, world, mission.name)
    else:
        text = write_geojson(plans, world)
    if not _write("export", args.output, text):
        return ExitCode.USAGE
    items = sum(len(p.items) for p in plans)
    skipped = sum(len(p.skipped) for p in plans)
    _say("export", f"{items} mission item(s) written to {args.output or 'standard output'}"
         + (f"; {skipped} action(s) not exported" if skipped else ""))
    return ExitCode.OK


def _export_list(args: argparse.Namespace, form: str, mission: Mission | None,
                 extra: World | None) -> ExitCode:
    """Write the fence or rally list of a world file (``mission`` None) or of a mission's
    environment, ``extra`` laid over it."""
    from tml.language.build import load_world
    from tml.plans.planned import world_left_out
    from tml.plans.wpl import write_fence, write_rally
    from tml.world import World

    if mission is None:
        world = load_world(args.mission).merged(extra)  # validated: it loads
    else:
        world = (mission.world or World()).merged(extra)
    for note in world_left_out(world, form):
        _say("export", f"note: {note}")
    text = write_fence(world) if form == "fence" else write_rally(world)
    if not _write("export", args.output, text):
        return ExitCode.USAGE
    what = f"{len(text.splitlines()) - 1} fence item(s)" if form == "fence" \
        else f"{len(world.rally)} rally point(s)"
    _say("export", f"{what} written to {args.output or 'standard output'}")
    return ExitCode.OK


def import_(args: argparse.Namespace) -> ExitCode:
    """Run ``tml import``; return the exit code."""
    from tml.language.validation import validate_file
    from tml.plans.imported import import_plan
    from tml.plans.qgc import PlanFileError, read_plan
    from tml.plans.wpl import read_wpl

    path = Path(args.plan)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        reason = error.strerror if isinstance(error, OSError) else "not UTF-8 text"
        _say("import", f"{args.plan}: {reason or error}")
        return ExitCode.USAGE
    try:
        plan = read_plan(text, args.plan) if text.lstrip().startswith("{") \
            else read_wpl(text, args.plan)
        if args.home is not None and plan.home is None:
            plan = replace(plan, home=args.home)
        elif args.home is not None:
            _say("import", f"{args.plan}: note: the file's home is kept (--home places a "
                 "file that gives none)")
        imported = import_plan(plan, args.name or path.stem)
    except PlanFileError as error:
        message = str(error)
        _say("import", message if message.startswith(args.plan) else f"{args.plan}: {message}")
        return ExitCode.INVALID
    for warning in imported.warnings:
        _say("import", f"{args.plan}: note: {warning}")
    if imported.losses and not args.allow_loss:
        for loss in imported.losses:
            _say("import", f"{args.plan}: {loss}")
        _say("import", f"{args.plan}: not written: {len(imported.losses)} thing(s) the "
             "mission cannot carry exactly (--allow-loss writes it without them)")
        return ExitCode.INVALID
    # What is written must validate: check it as the file it becomes.
    result = validate_file(args.output or f"{path.stem}.xml", imported.text.encode("utf-8"),
                           root="world" if imported.world else "mission")
    lines = imported.text.splitlines()
    for diagnostic in result.diagnostics:  # said of the source item, not of the XML
        tasks = [line for line in lines[:diagnostic.location.line]
                 if line.lstrip().startswith('<task name="item ')]
        where = tasks[-1].split('"')[1].split(":")[0] if tasks else "the mission"
        what = "" if diagnostic.is_error else "note: "
        _say("import", f"{args.plan}: {what}{where}: {diagnostic.code} {diagnostic.message}")
    if result.errors:
        _say("import", f"{args.plan}: the mission made of it is invalid, not written")
        return ExitCode.INVALID
    if not _write("import", args.output, imported.text):
        return ExitCode.USAGE
    raw = f", {imported.raw} of them as MISSION_ITEM" if imported.raw else ""
    if imported.world:
        rally = f" and {len(plan.rally)} rally point(s)" if plan.rally else ""
        _say("import", f"no mission item: the fence ({len(plan.zones)} zone(s)){rally} written "
             f"as a world file to {args.output or 'standard output'} (give it to tml run, "
             "verify or export with --world)")
    else:
        _say("import", f"{len(plan.items)} mission item(s) as {imported.actions} task(s){raw} "
             f"written to {args.output or 'standard output'}")
    if imported.losses:
        _say("import", f"left out ({len(imported.losses)}, --allow-loss):")
        for loss in imported.losses:
            _say("import", f"  {loss}")
    return ExitCode.OK
