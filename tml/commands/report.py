"""``tml report``: a flight log as a picture, a page, or tracks for a map.

Exit codes: 0 written, 1 a log that cannot be read as a flight log, 2 usage or I/O error (a
missing log, an unwritable output, a format the output's suffix does not say).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tml.errors import ExitCode

FORMATS = ("html", "png", "gpx", "kml")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml report``."""
    parser.add_argument("log", metavar="LOG.jsonl", help="a flight log (tml run --log)")
    parser.add_argument("-o", "--output", metavar="OUT",
                        help="write here (default: the log's name with the format's suffix)")
    parser.add_argument("--format", choices=FORMATS,
                        help="html (the picture and tables of tasks and events), png (the "
                             "picture), gpx or kml (the flown tracks); default: from the "
                             "suffix of -o, else html")


def run(args: argparse.Namespace) -> ExitCode:
    """Run ``tml report``; return the exit code."""
    from tml.report.flight import LogError, read_flight

    suffix = Path(args.output).suffix.lower().lstrip(".") if args.output else ""
    form = args.format or (suffix if suffix in FORMATS else None)
    if form is None:
        if args.output:
            print(f"tml report: -o {args.output}: say --format html|png|gpx|kml (the suffix "
                  "does not)", file=sys.stderr)
            return ExitCode.USAGE
        form = "html"
    output = args.output or str(Path(args.log).with_suffix(f".{form}"))
    try:
        flight = read_flight(args.log)
    except OSError as error:
        print(f"tml report: {args.log}: {error.strerror or error}", file=sys.stderr)
        return ExitCode.USAGE
    except LogError as error:
        print(f"tml report: {error}", file=sys.stderr)
        return ExitCode.INVALID
    data = _render(flight, form)
    try:
        Path(output).write_bytes(data)
    except OSError as error:
        print(f"tml report: -o {output}: cannot write: {error.strerror or error}",
              file=sys.stderr)
        return ExitCode.USAGE
    print(f"tml report: {output} ({form}, {len(flight.vehicles)} vehicle(s), "
          f"{len(flight.tasks)} task span(s), {len(flight.marks)} event(s) and message(s))")
    return ExitCode.OK


def _render(flight: object, form: str) -> bytes:
    from tml.report.flight import Flight

    assert isinstance(flight, Flight)
    if form == "png":
        from tml.report.figures import png

        return png(flight)
    if form == "html":
        from tml.report.pages import page

        return page(flight).encode("utf-8")
    from tml.report.tracks import gpx, kml

    return (gpx(flight) if form == "gpx" else kml(flight)).encode("utf-8")
