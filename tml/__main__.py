"""``python -m tml`` is the same as the ``tml`` command."""

from tml.cli import entry_point

entry_point()
