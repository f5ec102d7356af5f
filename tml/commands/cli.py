"""The ``tml`` command: ``tml validate``, ``tml sim`` ...; ``main(argv)`` returns the exit code.

Exit codes of ``tml validate``: 0 every file valid, 1 some file invalid, 2 usage or I/O error.
A usage error of any command (an unknown option, a bad value) is said in one line and exits 2.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from tml import __version__
from tml.commands.signals import Stopped, StopSignals
from tml.errors import ExitCode

if TYPE_CHECKING:
    from tml.language.validation import ValidationResult

# Files per worker task when validating many files on several cores; below twice this
# many files, forking workers costs more than it saves.
PARALLEL_BATCH = 50


def _mission_files(paths: Sequence[str]) -> tuple[list[tuple[Path, bool]], list[str]]:
    """Files named, and the .xml files under directories named (those marked True: found,
    not named); plus problems found.

    A symbolic link under a directory that leads out of it is refused unread: validating a
    tree must not print a line of a file elsewhere (a link to /etc/passwd). A named path
    that is not a regular file is handed on, for the reader to refuse with its reason.
    """
    files: list[tuple[Path, bool]] = []
    problems: list[str] = []
    for name in paths:
        path = Path(name)
        if path.is_dir():
            tree = path.resolve()
            found = []
            for candidate in sorted(path.rglob("*.xml")):
                if not candidate.resolve().is_relative_to(tree):
                    problems.append(f"{candidate}: a symbolic link leading out of {name}; "
                                    "not read")
                elif candidate.is_file():
                    found.append(candidate)
            if not found:
                problems.append(f"{name}: no .xml files in this directory")
            files.extend((p, True) for p in found)
        elif path.exists():
            files.append((path, False))
        else:
            problems.append(f"{name}: no such file or directory")
    return files, problems


def _validate_for_report(path: Path, found: bool = False) -> ValidationResult | str:
    """Validate one file for printing: its diagnostics, or the text of an I/O error. A
    file named is a mission; a file ``found`` under a directory is a mission or a world
    file, as its root element says (a world kept beside the missions is checked as one)."""
    from tml.language.validation import ValidationResult, validate_file

    try:  # a file found is read once: its root element, parsed, says which it is
        result = validate_file(path, root=None if found else "mission")
    except OSError as exc:
        return f"{path}: {exc.strerror or exc}"
    # The model stays in the worker; quoting source lines needs the text only on problems.
    return ValidationResult(result.file, None, result.diagnostics,
                            result.source if result.diagnostics else "")


def _validate_all(files: list[tuple[Path, bool]]) -> list[ValidationResult | str]:
    """Validate files in order, on every core when there are many."""
    workers = min(os.cpu_count() or 1, len(files) // PARALLEL_BATCH)
    if workers < 2:
        return [_validate_for_report(path, found) for path, found in files]
    from concurrent.futures import ProcessPoolExecutor

    # The first file here, before the workers start: forked, they inherit the modules it
    # imported and the schema it compiled instead of each loading them again.
    first = _validate_for_report(*files[0])
    rest = files[1:]
    with ProcessPoolExecutor(workers) as pool:
        return [first, *pool.map(_validate_for_report, [p for p, _ in rest],
                                 [f for _, f in rest], chunksize=PARALLEL_BATCH)]


def cmd_validate(args: argparse.Namespace) -> ExitCode:
    """Validate mission files and print every problem."""
    from tml.language.diagnostics import format_github, format_human_all, format_json

    files, problems = _mission_files(args.paths)
    if args.tml_only:  # a hook handed every XML file: the others are not ours
        from tml.language.xml import root_name

        files = [(f, True) for f, _ in files if root_name(f) in ("mission", "world", None)]
    for problem in problems:
        print(f"tml validate: {problem}", file=sys.stderr)
    results = []
    io_error = bool(problems)
    for outcome in _validate_all(files):
        if isinstance(outcome, str):
            print(f"tml validate: {outcome}", file=sys.stderr)
            io_error = True
        else:
            results.append(outcome)
    invalid = [r for r in results if not r.valid(args.strict)]
    if args.format == "json":
        print(format_json((r.file, r.valid(args.strict), r.diagnostics) for r in results))
    elif args.format == "github":
        for result in results:
            for diagnostic in result.diagnostics:
                print(format_github(diagnostic))
    else:
        sources = {r.file: r.source for r in results}
        for result in results:
            for text in format_human_all(result.diagnostics, sources):
                print(text)
        if not args.quiet:
            errors = sum(len(r.errors) for r in results)
            warnings = sum(len(r.diagnostics) - len(r.errors) for r in results)
            print(f"{len(results)} file(s) checked: {len(results) - len(invalid)} valid, "
                  f"{len(invalid)} invalid ({errors} error(s), {warnings} warning(s))")
    if io_error:
        return ExitCode.USAGE
    return ExitCode.INVALID if invalid else ExitCode.OK


def cmd_verify(args: argparse.Namespace) -> ExitCode:
    """Check a mission's physical feasibility (see :mod:`tml.commands.verify`)."""
    from tml.commands.verify import run

    return run(args)


def cmd_run(args: argparse.Namespace) -> ExitCode:
    """Fly a mission (see :mod:`tml.commands.run`)."""
    from tml.commands.run import run

    return run(args)


def cmd_companion(args: argparse.Namespace) -> ExitCode:
    """Run the simulated companion computer (see :mod:`tml.commands.companion`)."""
    from tml.commands.companion import run

    return run(args)


def cmd_export(args: argparse.Namespace) -> ExitCode:
    """Write a mission as a plan or a map (see :mod:`tml.commands.plans`)."""
    from tml.commands.plans import export

    return export(args)


def cmd_import(args: argparse.Namespace) -> ExitCode:
    """Make a plan file into a mission (see :mod:`tml.commands.plans`)."""
    from tml.commands.plans import import_

    return import_(args)


def cmd_report(args: argparse.Namespace) -> ExitCode:
    """Draw a flight log (see :mod:`tml.commands.report`)."""
    from tml.commands.report import run

    return run(args)


def cmd_serve(args: argparse.Namespace) -> ExitCode:
    """Serve the HTTP API and the page (see :mod:`tml.commands.serve`)."""
    from tml.commands.serve import run

    return run(args)


def cmd_command(args: argparse.Namespace) -> ExitCode:
    """Tell a vehicle to return, land, hold or disarm (see :mod:`tml.commands.command`)."""
    from tml.commands.command import run

    return run(args)


def cmd_schema(args: argparse.Namespace) -> ExitCode:
    """Show the installed schema (see :mod:`tml.commands.schema`)."""
    from tml.commands.schema import run

    return run(args)


def cmd_completion(args: argparse.Namespace) -> ExitCode:
    """Print the shell's completion script for tml (argcomplete's)."""
    from argcomplete.shell_integration import shellcode

    sys.stdout.write(shellcode(["tml"], shell=args.shell))
    return ExitCode.OK


def cmd_sim(argv: Sequence[str]) -> int:
    """Run the embedded simulator (same options as ``python -m sitl``)."""
    from tml.simulator import simulator_main

    return simulator_main(argv, prog="tml sim")


class Parser(argparse.ArgumentParser):
    """An argument parser whose usage error is one line, the one that says what is wrong
    and where the help is (argparse's usage synopsis before it ran to a dozen lines)."""

    def error(self, message: str) -> NoReturn:
        self.exit(ExitCode.USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def _get_formatter(self) -> argparse.HelpFormatter:
        # argparse makes one for every option added, and sizes it with shutil, whose import
        # (zlib, bz2, lzma) was a thirtieth of the start-up of `tml validate FILE`.
        make: Callable[..., argparse.HelpFormatter] = self.formatter_class
        return make(prog=self.prog, width=_terminal_columns() - 2)


def _terminal_columns() -> int:
    """``shutil.get_terminal_size().columns`` (what argparse asks), without shutil."""
    try:
        columns = int(os.environ["COLUMNS"])
    except (KeyError, ValueError):
        columns = 0
    if columns > 0:
        return columns
    try:
        return os.get_terminal_size(sys.__stdout__.fileno()).columns or 80  # type: ignore[union-attr]
    except (AttributeError, ValueError, OSError):  # no stdout (None), or not a terminal
        return 80


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser of the ``tml`` command; with ``command`` (``"validate"``), the
    other commands are listed without their options, whose modules are then not imported:
    a hook that validates a file or two pays for what validation needs only."""

    def wanted(name: str) -> bool:
        return command is None or command == name

    parser = Parser(
        prog="tml", description="Validate, verify and fly TML mission files on MAVLink drones.")
    parser.add_argument("--version", action="version", version=f"tml {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    validate = commands.add_parser(
        "validate", help="check mission files against the schema and the language rules",
        description="Check mission files (and every .xml file under directories: missions, "
                    "and world files by their root element) against the XML Schema and the "
                    "language's semantic rules. "
                    "Exit 0 when all are valid, 1 when some are invalid, 2 on usage or I/O "
                    "errors.")
    validate.add_argument("paths", nargs="+", metavar="FILE|DIR")
    validate.add_argument("--format", choices=("human", "json", "github"), default="human",
                          help="output format (github: workflow annotations)")
    validate.add_argument("--strict", action="store_true",
                          help="treat warnings as errors (exit 1)")
    validate.add_argument("-q", "--quiet", action="store_true",
                          help="print problems only, no summary line")
    validate.add_argument("--tml-only", action="store_true",
                          help="pass over files whose root element is neither <mission> nor "
                               "<world> (a pom.xml, an SVG) and check worlds as world files, "
                               "for hooks that hand every .xml file over")
    validate.set_defaults(handler=cmd_validate)

    verify = commands.add_parser(
        "verify", help="check a mission's physical feasibility before flight",
        description="Predict position, time and battery after every action of a mission "
                    "and check them against a vehicle profile and a world. Exit 0 when "
                    "feasible, 1 when a constraint fails or the mission is invalid, 2 on "
                    "usage or I/O errors.")
    if wanted("verify"):
        from tml.commands.verify import add_arguments

        add_arguments(verify)
    verify.set_defaults(handler=cmd_verify)

    run = commands.add_parser(
        "run", help="fly a mission on the embedded simulator or a MAVLink vehicle",
        description="Validate, verify and fly a mission. Exit 0 completed, 1 invalid or "
                    "infeasible mission, 2 usage error (a bad option or value, a missing "
                    "file, a malformed address, a log that cannot be written), 3 mission "
                    "aborted, 4 vehicle or link failure.")
    if wanted("run"):
        from tml.commands.run import add_arguments as add_run_arguments

        add_run_arguments(run)
    run.set_defaults(handler=cmd_run)

    companion = commands.add_parser(
        "companion", help="attach the simulated companion computer to an autopilot",
        description="Run the simulator's companion computer (MAVLink component 191: "
                    "recognition skills switched by PARAM_SET, detections as "
                    "NAMED_VALUE_INT and DEBUG_VECT) as a component of the vehicle at "
                    "ADDRESS, e.g. ArduPilot's SERIAL1, until SIGINT or SIGTERM. Exit 0 "
                    "when stopped, 2 on bad arguments or world file, 4 when no autopilot "
                    "is heard.")
    if wanted("companion"):
        from tml.commands.companion import add_arguments as add_companion_arguments

        add_companion_arguments(companion)
    companion.set_defaults(handler=cmd_companion)

    command_parser = commands.add_parser(
        "command", help="tell a vehicle to return, land, hold or disarm, now",
        description="Tell the vehicle at ADDRESS to return to launch, land, hold where it "
                    "is or disarm, and confirm it from telemetry that arrived after the "
                    "command. Exit 0 done (or nothing to do), 2 usage error or a command "
                    "refused as unsafe (disarm in the air, land a ground vehicle), 4 no "
                    "vehicle, refused by the vehicle or not shown within --timeout. See "
                    "docs/command.md.")
    if wanted("command"):
        from tml.commands.command import add_arguments as add_command_arguments

        add_command_arguments(command_parser)
    command_parser.set_defaults(handler=cmd_command)

    export = commands.add_parser(
        "export", help="write a mission as a QGroundControl plan, a waypoint file or a map",
        description="Write what a mission would fly as mission items: a QGroundControl "
                    ".plan (with the geofence and obstacles), a QGC WPL 110 waypoint file "
                    "(MAVProxy's wp load), or KML / GeoJSON of the path, obstacles and "
                    "geofence. Actions with no mission item are named on standard error. "
                    "Exit 0 written, 1 invalid mission, 2 usage or I/O error.")
    if wanted("export"):
        from tml.commands.plans import add_export_arguments

        add_export_arguments(export)
    export.set_defaults(handler=cmd_export)

    imports = commands.add_parser(
        "import", help="make a QGroundControl plan or a waypoint file into a mission",
        description="Turn a QGroundControl .plan or a QGC WPL waypoint file (MAVProxy, "
                    "Mission Planner) into a TML mission: a task per item in a task flown "
                    "as an autopilot mission (dispatch=\"mission\"), home and geofence in "
                    "its <environment>. Exit 0 written (a mission, or a world file when the "
                    "file holds only a fence or rally points), 1 a file that is not a plan or "
                    "waypoint file, holds nothing to fly, holds what a mission cannot carry "
                    "exactly (without --allow-loss) or makes an invalid mission, 2 usage or "
                    "I/O error (a file that cannot be read or is not UTF-8 text, an output "
                    "that cannot be written).")
    if wanted("import"):
        from tml.commands.plans import add_import_arguments

        add_import_arguments(imports)
    imports.set_defaults(handler=cmd_import)

    report = commands.add_parser(
        "report", help="draw a flight log: planned path and track, altitude, battery, tasks",
        description="Make a flight log (tml run --log) into a report: a PNG of the planned "
                    "path against the flown track, altitude and battery over time and the "
                    "tasks on a timeline with the events; an HTML page with that picture and "
                    "tables of the tasks, events and autopilot messages; or the flown tracks "
                    "as GPX or KML. Exit 0 written, 1 not a flight log, 2 usage or I/O "
                    "error.")
    if wanted("report"):
        from tml.commands.report import add_arguments as add_report_arguments

        add_report_arguments(report)
    report.set_defaults(handler=cmd_report)

    schema = commands.add_parser(
        "schema", help="where the installed XML Schema is, its text, or an editor catalog",
        description="Print the path of the installed mission schema (tml.xsd), its text, "
                    "or an XML catalog mapping the stable schema location "
                    "urn:tml:schemas:tml.xsd to it, for XML editors. Exit 0.")
    if wanted("schema"):
        from tml.commands.schema import add_arguments as add_schema_arguments

        add_schema_arguments(schema)
    schema.set_defaults(handler=cmd_schema)

    completion = commands.add_parser(
        "completion", help="print the shell completion script (bash, zsh)",
        description="Print the completion script of tml for a shell: commands, options "
                    "and their choices complete on TAB. For bash, add "
                    "'eval \"$(tml completion bash)\"' to ~/.bashrc; for zsh, "
                    "'eval \"$(tml completion zsh)\"' to ~/.zshrc. Exit 0.")
    completion.add_argument("shell", choices=("bash", "zsh"))
    completion.set_defaults(handler=cmd_completion)

    serve = commands.add_parser(
        "serve", help="serve missions, runs and vehicles over HTTP, with a live web page",
        description="Keep the vehicle links open, fly missions on them and serve an HTTP "
                    "API (OpenAPI at /openapi.json) and a live web page at /, until SIGINT "
                    "or SIGTERM (every flying vehicle is sent to its safe state first). "
                    "Exit 0 when stopped, 2 on bad arguments, 4 when the vehicles cannot "
                    "be reached. See docs/serve.md.")
    if wanted("serve"):
        from tml.commands.serve import add_arguments as add_serve_arguments

        add_serve_arguments(serve)
    serve.set_defaults(handler=cmd_serve)

    sim = commands.add_parser(
        "sim", help="run the embedded MAVLink vehicle simulator", add_help=False,
        description="Run the embedded simulator; see `tml sim --help`.")
    sim.add_argument("sim_args", nargs=argparse.REMAINDER)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``tml`` command with ``argv``; return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["sim"]:  # the simulator parses its own options, --help included
        return cmd_sim(argv[1:])
    if "_ARGCOMPLETE" in os.environ:  # the shell asks for completions: answer and exit
        import argcomplete

        argcomplete.autocomplete(build_parser())
    # A command named first needs its own options only (``tml --help`` lists them all).
    parser = build_parser(argv[0] if argv and not argv[0].startswith("-") else None)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse exits 2 on usage errors, 0 on --help
        return int(exc.code or 0)
    return int(args.handler(args))


def entry_point() -> None:
    """Console-script entry point."""
    # Until a command takes the stop signals over, Ctrl-C raises where tml is, and again
    # should a library swallow it (tml.commands.signals.StopSignals). Imported with this
    # module, so that no Ctrl-C comes between the two.
    stops = StopSignals()
    try:
        with stops:
            code = main()
        sys.stdout.flush()
    except BrokenPipeError:
        # The reader (``| head``) went away: stop quietly, as command-line tools do.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        code = ExitCode.INVALID
    except KeyboardInterrupt as stop:
        # Ctrl-C before a command took the stop signals over (while it starts: imports,
        # reading files), or in a command that keeps Python's own: one line, no traceback.
        name = stop.signal_name if isinstance(stop, Stopped) else "SIGINT"
        print(f"tml: interrupted ({name})", file=sys.stderr)
        code = ExitCode.ABORTED
    except Exception:
        # An interrupt that landed inside a library's import or set-up can come out as
        # another error (an ImportError of a module half loaded): it was the interrupt.
        if stops.received is None:
            raise
        print(f"tml: interrupted ({stops.received})", file=sys.stderr)
        code = ExitCode.ABORTED
    sys.exit(code)
