"""``python -m tml`` is the same as the ``tml`` command."""

from tml.commands.cli import entry_point

entry_point()
