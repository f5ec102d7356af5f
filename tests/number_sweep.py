"""Extreme numbers swept over a mission: ``python tests/number_sweep.py MISSION.xml``.

Each numeric site of the mission (an argument's number or point, an environment number, a
repeat count, a time limit, a condition's number), one per kind of site, is replaced in
turn by each extreme value; every variant must be refused by validation or verified
without an exception other than tml's own. Prints one line per variant that broke, and
exits 1 if any did.
"""

from __future__ import annotations

import re
import sys
import tempfile
import traceback
from collections.abc import Iterator
from pathlib import Path

from lxml import etree

from tml.errors import TmlError
from tml.language.parameters import parse_number
from tml.language.validation import validate_file
from tml.verify.motion import PredictedState
from tml.verify.profile import load_profile
from tml.verify.static import verify_mission
from tml.world import World

EXTREMES = ("nan", "inf", "1e309", "-1e300", "1e12", "1e-320", "0", "-5")
WHOLE = ("99999999999999999999999", "0", "-1")
_POINT = re.compile(r"^\(?\s*([^,()]+)\s*,\s*([^,()]+)\s*,\s*([^,()]+)\s*\)?$")


def _sites(root: etree._Element) -> Iterator[tuple[etree._Element, str, str]]:
    """(element, attribute, kind) of each numeric site, the first of each kind only."""
    seen: set[str] = set()
    for element in root.iter():
        if not isinstance(element.tag, str):
            continue
        tag = etree.QName(element).localname
        for attribute, text in element.attrib.items():
            if tag == "argument" and attribute == "value":
                kind = f"argument {element.get('name')}"
            elif tag == "repeat" and attribute == "times":
                kind = "repeat"
            else:
                kind = f"{tag} {attribute}"
            if kind in seen:
                continue
            if parse_number(text) is not None or (
                    (match := _POINT.match(text)) is not None
                    and all(parse_number(g) is not None for g in match.groups())):
                seen.add(kind)
                yield element, attribute, kind


def _variants(text: str, kind: str) -> Iterator[str]:
    if kind == "repeat":
        yield from WHOLE
        return
    match = _POINT.match(text)
    if match is not None and parse_number(text) is None:
        north, east, up = match.groups()
        for value in EXTREMES:
            yield f"({value}, {east}, {up})"
            yield f"({north}, {east}, {value})"
        return
    yield from EXTREMES


def sweep(mission: Path) -> list[str]:
    """What broke, one line per variant, each printed as it is found."""
    broken: list[str] = []
    profile = load_profile("quadcopter")
    tree = etree.parse(str(mission))
    with tempfile.TemporaryDirectory() as folder:
        target = Path(folder) / mission.name
        for element, attribute, kind in list(_sites(tree.getroot())):
            original = element.get(attribute) or ""
            for value in _variants(original, kind):
                element.set(attribute, value)
                tree.write(str(target))
                try:
                    result = validate_file(target)
                    if not result.errors and result.mission is not None:
                        home = (result.mission.world or World()).home_or_default
                        verify_mission(result.mission, profile, None,
                                       PredictedState(battery=100.0, heading=home.heading))
                except TmlError:
                    pass
                except Exception:  # what the sweep looks for: any error not tml's own
                    last = traceback.format_exc().strip().splitlines()[-1]
                    broken.append(f"{mission.name}: {kind} = {value}: {last}")
                    print(broken[-1], flush=True)
            element.set(attribute, original)
    return broken


if __name__ == "__main__":
    found = [line for name in sys.argv[1:] for line in sweep(Path(name))]
    sys.exit(1 if found else 0)
