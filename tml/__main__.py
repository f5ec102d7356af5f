"""``python -m tml`` is the same as the ``tml`` command."""

import sys

try:
    from tml.commands.cli import entry_point
except KeyboardInterrupt:  # Ctrl-C while the command's modules load: as entry_point says it
    print("tml: interrupted (SIGINT)", file=sys.stderr)
    sys.exit(3)  # ExitCode.ABORTED, written out: tml.errors may not be loaded yet

entry_point()
