"""``tml run``: arguments and the command itself."""

from __future__ import annotations

import argparse
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml run``."""
    parser.add_argument("mission", metavar="FILE")


def run(args: argparse.Namespace) -> int:
    """Run ``tml run``; return the exit code."""
    print("tml run: not available yet", file=sys.stderr)
    return 2
