"""``python -m sitl``: see :mod:`sitl.cli`."""

import sys

from sitl.cli import main

sys.exit(main())
