"""``tml schema``: where the installed XML Schema is, its text, or an XML catalog for editors.

A mission may name its schema by the stable location
:data:`tml.language.schema.SCHEMA_LOCATION` (``urn:tml:schemas:tml.xsd``) instead of a
path into a checkout of this repository; an editor resolves it to the installed file
through the catalog ``tml schema --catalog`` prints (docs/language.md says how to set up
VS Code). Exit codes: 0, or 2 when the output cannot be written.
"""

from __future__ import annotations

import argparse
import sys

from tml.errors import ExitCode

CATALOG_NAMESPACE = "urn:oasis:names:tc:entity:xmlns:xml:catalog"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml schema``."""
    shown = parser.add_mutually_exclusive_group()
    shown.add_argument("--path", action="store_true",
                       help="print the path of the installed schema (the default)")
    shown.add_argument("--print", action="store_true", dest="text",
                       help="print the schema itself")
    shown.add_argument("--catalog", action="store_true",
                       help="print an XML catalog that maps the stable schema locations "
                            "(urn:tml:schemas:...) to the installed files, for editors")
    parser.add_argument("--world", action="store_true",
                        help="the world file's schema (world.xsd) instead of the mission's")


def catalog() -> str:
    """An OASIS XML catalog: each stable location to its installed file, both as a URI and
    as a system identifier (editors look schema locations up as one or the other)."""
    from tml.language.schema import SCHEMA_FILES, schema_path, stable_location

    entries = []
    for name in SCHEMA_FILES:
        target = schema_path(name).resolve().as_uri()
        entries.append(f'  <uri name="{stable_location(name)}" uri="{target}"/>')
        entries.append(f'  <system systemId="{stable_location(name)}" uri="{target}"/>')
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<catalog xmlns="{CATALOG_NAMESPACE}">\n'
            + "\n".join(entries) + "\n</catalog>\n")


def run(args: argparse.Namespace) -> ExitCode:
    """Run ``tml schema``; return the exit code."""
    from tml.language.schema import schema_path

    path = schema_path("world.xsd" if args.world else "tml.xsd")
    if args.catalog:
        sys.stdout.write(catalog())
    elif args.text:
        sys.stdout.write(path.read_text(encoding="utf-8"))
    else:
        print(path)
    return ExitCode.OK
