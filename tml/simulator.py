"""The embedded simulator (the ``sitl`` package) as tml uses it: the one module of tml that
imports ``sitl``.

``sitl`` plays the vehicles: the commands start it (``tml run --sim``, ``tml serve --sim``,
``tml sim``) or run its companion computer against an autopilot (``tml companion``), and
check the simulator's options with its own rules, but reach it only through here, so that
what tml needs of the simulator is one short list. The flight session
(:mod:`tml.run.session`) gets the factories below through its options and never imports
the simulator itself.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING

# The simulator's own checks of its option values, for the commands that pass them on
# (one source of each rule: sitl.cli, which `python -m sitl` uses too).
from sitl.cli import FastBoot, battery_start, count, non_negative, param_setting, positive

if TYPE_CHECKING:
    from tml.run.session import Companion, Simulated, SimulatorOptions
    from tml.timebase import Lockstep
    from tml.world import World

__all__ = ["FastBoot", "battery_start", "count", "non_negative", "open_companion",
           "open_simulator", "param_setting", "parse_frames", "positive", "simulator_main"]


def parse_frames(text: str) -> list[str]:
    """The frames of ``--sim-frame`` (copter, plane, rover), as ``python -m sitl --frame``
    reads them; raises ValueError. (sitl.frames loads numpy: imported when asked.)"""
    from sitl.frames import parse_frames as parse

    return parse(text)


@contextlib.contextmanager
def open_simulator(options: SimulatorOptions, world: World, key: bytes | None,
                   lockstep: Lockstep | None) -> Iterator[Simulated]:
    """The embedded simulator on loopback, on free ports, running until left (the flight
    session's :data:`~tml.run.session.SimulatorFactory`)."""
    from sitl.server import Simulator

    with Simulator(vehicles=options.vehicles, speedup=options.speedup, tcp_base_port=0,
                   world=world, params=dict(options.params), frames=list(options.frames),
                   signing_key=key, lockstep=lockstep) as sim:
        yield sim


def open_companion(address: str, world: World, system_id: int | None,
                   on_text: Callable[[str], None]) -> Companion:
    """The simulator's companion computer (MAVLink component 191) for the autopilot at
    ``address``, not yet connected (the flight session's
    :data:`~tml.run.session.CompanionFactory`)."""
    from sitl.companion_link import CompanionLink

    return CompanionLink(address, world, system_id=system_id, on_text=on_text)


def simulator_main(argv: Sequence[str], prog: str) -> int:
    """``python -m sitl`` under another name (``tml sim``); its exit code."""
    from sitl.cli import main

    return main(list(argv), prog=prog)
