"""A short hop (take off, 20 m over, land) flown by ``tml run --connect ADDRESS`` in its own
process on an ArduCopter SITL vehicle, over whichever link a test set up."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HOP = ('<mission name="Hop">\n'
       '  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="5"/>'
       '</action></task>\n'
       '  <task name="Over"><action name="GO_TO_POINT"><argument name="coordinates" '
       'value="(20, 0, 5)"/></action></task>\n'
       '  <task name="Down"><action name="LAND"/></task>\n</mission>\n')


def fly_hop(folder: Path, address: str, *more: str) -> subprocess.CompletedProcess[str]:
    """``tml run`` of the hop at ``address`` (vehicle clock, quiet, 120 s for the first
    HEARTBEAT), with ``more`` options; the finished process, its output as text."""
    mission = folder / "hop.xml"
    mission.write_text(HOP)
    return subprocess.run([sys.executable, "-m", "tml", "run", str(mission), "--connect",
                           address, "--clock", "vehicle", "-q", "--timeout", "120", *more],
                          capture_output=True, text=True, timeout=500)
