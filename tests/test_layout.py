"""The layout follows the pipeline: each part of tml imports only from the parts below it.

Read from the sources' import statements (``import`` and ``from ... import``, at any
indentation, so a deferred import counts too).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

# Top to bottom; a part may import from the parts on lower rows (and from itself). Parts on
# one row are siblings that do not import each other.
LAYERS: list[set[str]] = [
    {"tml.__main__"},
    {"tml.commands"},
    {"tml.report", "tml.serve", "tml.simulator"},
    {"tml.run", "tml.plans"},
    {"tml.engine", "tml.mavlink", "tml.verify"},
    {"tml.actions"},
    {"tml.vehicle"},
    {"tml.language"},
    {"tml.geo", "tml.world", "tml.patterns", "tml.signing", "tml.timebase", "tml.terrain"},
    {"tml.errors", "tml.__init__", "tml.__version__"},
]
IMPORT = re.compile(r"^\s*(?:from\s+(tml[\w.]*)\s+import\s+([\w, ()]+)|import\s+(tml[\w.]*))",
                    re.M)


def part(module: str) -> str:
    """The part of the layout a dotted module name belongs to."""
    names = module.split(".")
    return ".".join(names[:2]) if len(names) > 1 else names[0]


def row(name: str) -> int:
    return next(i for i, layer in enumerate(LAYERS) if name in layer)


def imports(path: Path) -> set[str]:
    found = set()
    for from_module, names, plain in IMPORT.findall(path.read_text(encoding="utf-8")):
        if plain:
            found.add(plain)
        elif from_module == "tml":  # from tml import geo, world
            found |= {f"tml.{n.strip(' ()')}" for n in names.split(",") if n.strip(" ()")}
        else:
            found.add(from_module)
    return found


def modules(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


@pytest.mark.parametrize("path", modules("tml"), ids=lambda p: str(p.relative_to(ROOT)))
def test_each_module_imports_only_from_below(path: Path) -> None:
    own = part(".".join(path.relative_to(ROOT).with_suffix("").parts))
    wrong = sorted(m for m in imports(path)
                   if part(m) != own and row(part(m)) <= row(own))
    assert not wrong, f"{own} imports {wrong}, which are not below it"


def test_the_simulator_keeps_its_own_records() -> None:
    # sitl/ plays the vehicle: it shares the world and geodesy with tml, never the ground
    # station's protocol code or records.
    for path in modules("sitl"):
        mavlink = sorted(m for m in imports(path) if m.startswith("tml.mavlink"))
        assert not mavlink, f"{path.relative_to(ROOT)} imports {mavlink}"


SIMULATOR = ROOT / "tml" / "simulator.py"
"""The one module of tml that imports the simulator (sitl): what tml needs of it is one list."""


@pytest.mark.parametrize("path", [p for p in modules("tml") if p != SIMULATOR],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_no_module_of_tml_but_the_simulator_bridge_imports_the_simulator(path: Path) -> None:
    found = re.findall(r"^\s*(?:from|import)\s+(sitl[\w.]*)", path.read_text(encoding="utf-8"),
                       re.M)
    assert not found, f"{path.relative_to(ROOT)} imports {found}: reach it through tml.simulator"
    assert SIMULATOR.is_file()


def test_the_service_does_not_import_the_commands() -> None:
    """tml/serve is below tml/commands: the service gets its vehicles and options from the
    command that starts it, never reaches up into a command module."""
    for path in modules("tml/serve"):
        found = sorted(m for m in imports(path) if m.startswith("tml.commands"))
        assert not found, f"{path.relative_to(ROOT)} imports {found}"


@pytest.mark.parametrize("path", [p for p in modules("tml") if "commands" not in p.parts],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_argparse_stays_in_the_commands(path: Path) -> None:
    """Below tml/commands a flight session gets typed options, never a Namespace."""
    source = path.read_text(encoding="utf-8")
    assert not re.search(r"^\s*(?:import argparse|from argparse import)", source, re.M)
    assert "Namespace" not in re.sub(r"noNamespaceSchemaLocation", "", source)


def test_the_commands_that_fly_share_the_session_not_each_other() -> None:
    """tml serve opens its vehicles as tml run does, through tml.run.session, without
    importing tml run's command module."""
    for name in ("serve", "companion"):
        found = imports(ROOT / "tml" / "commands" / f"{name}.py")
        assert "tml.commands.run" not in found, name
    for name in ("serve", "run", "companion"):
        assert "tml.run.session" in imports(ROOT / "tml" / "commands" / f"{name}.py"), name
