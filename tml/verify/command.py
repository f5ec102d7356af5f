"""``tml verify``: arguments and the command itself."""

from __future__ import annotations

import argparse
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml verify``."""
    parser.add_argument("mission", metavar="FILE")


def run(args: argparse.Namespace) -> int:
    """Run ``tml verify``; return the exit code."""
    print("tml verify: not available yet", file=sys.stderr)
    return 2
