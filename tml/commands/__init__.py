"""The ``tml`` command line: argument parsing and exit codes, one module per command
(:mod:`~tml.commands.cli` is the entry point)."""
