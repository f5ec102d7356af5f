"""Compare two plan files by their format's rules: what an autopilot is sent from them.

A ``.plan``'s complex items count as the simple items they hold; params 5 and 6 are
compared as the integers a MISSION_ITEM_INT carries (1e-7 degrees in a global frame, a
whole number otherwise, null as 0); a null param is NaN. A waypoint file's line 0 is
home when it is in ArduPilot's home form. Home, fence corners and rally points are
compared to 1e-7 degree, the precision a mission item carries; a ``.plan``'s firmware and
vehicle type, speeds and altitude mode as written.
"""

from __future__ import annotations

import math
from pathlib import Path

from tml.plans.qgc import PlanFile, read_plan
from tml.plans.wpl import read_wpl


def read(path: Path) -> PlanFile:
    """The plan file at ``path``, in its format."""
    text = path.read_text(encoding="utf-8")
    return read_plan(text, path.name) if text.lstrip().startswith("{") \
        else read_wpl(text, path.name)


def _same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def _degrees(value: float) -> int:
    return round(value * 1e7)


def differences(source: PlanFile, back: PlanFile) -> list[str]:
    """What differs between a file and its export, item by item; empty when none."""
    found = []
    if len(source.items) != len(back.items):
        found.append(f"{len(source.items)} items, {len(back.items)} back")
    for a, b in zip(source.items, back.items, strict=False):
        fields_a = (a.command, a.frame, a.x, a.y, bool(a.autocontinue))
        fields_b = (b.command, b.frame, b.x, b.y, bool(b.autocontinue))
        params_a = (a.param1, a.param2, a.param3, a.param4, a.z)
        params_b = (b.param1, b.param2, b.param3, b.param4, b.z)
        if fields_a != fields_b or not all(map(_same, params_a, params_b)):
            found.append(f"{source.source(a.seq)}: {fields_a + params_a} back as "
                         f"{fields_b + params_b}")
    if source.home is not None:
        home_a, home_b = source.home, back.home
        if home_b is None or (_degrees(home_a.latitude), _degrees(home_a.longitude)) != (
                _degrees(home_b.latitude), _degrees(home_b.longitude)) \
                or not math.isclose(home_a.altitude, home_b.altitude, abs_tol=1e-6):
            found.append(f"home {home_a} back as {home_b}")
    zones_a = [(z.inclusion, z.radius, [tuple(map(_degrees, p)) for p in z.points])
               for z in source.zones]
    zones_b = [(z.inclusion, z.radius, [tuple(map(_degrees, p)) for p in z.points])
               for z in back.zones]
    if sorted(zones_a, key=repr) != sorted(zones_b, key=repr):
        found.append(f"fence {zones_a} back as {zones_b}")
    if source.settings is not None:
        for name in ("firmware_type", "vehicle_type", "cruise_speed", "hover_speed",
                     "altitude_mode", "ground_station"):
            given = getattr(source.settings, name)
            got = getattr(back.settings, name) if back.settings is not None else None
            if given is not None and given != got:
                found.append(f"{name} {given} back as {got}")
        editors = back.settings.items if back.settings is not None else ()
        if repr(source.settings.items) != repr(editors):  # NaN (null) equal to NaN
            found.append(f"the editor's item fields {source.settings.items} back as {editors}")
    rally_a = [(_degrees(lat), _degrees(lon), alt) for lat, lon, alt in source.rally]
    rally_b = [(_degrees(lat), _degrees(lon), alt) for lat, lon, alt in back.rally]
    if rally_a != rally_b:
        found.append(f"rally points {rally_a} back as {rally_b}")
    return found
