"""How the suite spreads over pytest-xdist's workers (``pytest -n auto``, README.md).

Most of the suite's time is spent waiting, not computing: vehicles of the simulator flying
at a few times real time while tml runs in a process of its own, a link cut lasting its
seconds, a service's run being watched. Measured over the whole suite (resource usage of
each test, its processes included), the tests use about a third of a core per second of
their own wall time. So ``-n auto`` starts :data:`WORKERS_PER_CORE` workers per core
instead of one: the waits of one overlap the computing of another. A test's verdict does
not depend on how busy the machine is (the simulator runs in lock-step with tml, or tests
wait for states with generous hang guards), so a busier machine makes them slower, never
different.

Each worker starts with an equal share of the tests and one that runs out takes tests not
yet started from the others (xdist's ``worksteal``), since their lengths range from
milliseconds to a minute: a worker left with a queue of long flights at the end would
otherwise keep the others idle.
"""

from __future__ import annotations

import os

import pytest

WORKERS_PER_CORE = 3
"""Workers ``-n auto`` starts for each core this process may run on."""


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """The number of workers ``-n auto`` starts: :data:`WORKERS_PER_CORE` a core."""
    return WORKERS_PER_CORE * len(os.sched_getaffinity(0))


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config: pytest.Config) -> None:
    """Tests taken by the workers that run out (``--dist worksteal``) with ``-n auto`` when
    no distribution mode is named (xdist's own default would be ``load``). A count of
    workers named (``-n 2``: the interoperability suite, whose cases share ArduPilot SITL
    instances per worker) keeps xdist's default."""
    option = config.option
    if getattr(option, "numprocesses", None) == "auto" and \
            getattr(option, "dist", "no") == "no" and not getattr(option, "distload", False):
        option.dist = "worksteal"
