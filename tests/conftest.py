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
import re
import stat
from collections.abc import Iterator
from pathlib import Path

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


# -- Every flight log the suite's flights write follows the flight log's schema ----------

FLIGHT_LOG = re.compile(rb'^\{"t":[-0-9.e]+,"kind":"run"')
"""How a flight log the journal writes begins (its first line, compact JSON)."""
TEMPORARY = {"tmp_path", "tmp_path_factory", "tmpdir", "tmpdir_factory"}
"""The fixtures through which a test, or a fixture it uses, writes under the suite's
temporary directories (checked after the tests that use one: walking them after every test
would cost the suite more than its flights' logs)."""
_seen: dict[str, tuple[int, int]] = {}  # path -> (size, mtime) when it was checked


def schema_problems(path: str) -> list[str]:
    """Where the flight log at ``path`` breaks the schema (tml.engine.flightlog)."""
    from tml.engine.flightlog import VERSION, problems
    from tml.run.journal import LogUnreadable, read_log

    try:
        log = read_log(path)
    except LogUnreadable as error:
        return [str(error)]
    if log.version > VERSION:
        return []
    return [f"{path}:{number}: {problem}" for number, line in enumerate(log.lines, 1)
            for problem in problems(line)]


def log_folders(base: Path) -> list[Path]:
    """Where the tests of this process write: its temporary directory, and under pytest-xdist
    what the workers share beside theirs (tests/shared_flights.py), not the other workers'."""
    if not base.name.startswith("popen-gw"):
        return [base]
    return [base, *(p for p in base.parent.iterdir()
                    if p.is_dir() and not p.name.startswith("popen-gw"))]


def new_flight_logs(base: Path) -> list[str]:
    """The flight logs under ``base`` written or changed since the last call."""
    found = []
    for folder, _dirs, files in os.walk(base):
        for name in files:
            path = os.path.join(folder, name)
            try:
                status = os.stat(path)
            except OSError:
                continue
            key = (status.st_size, status.st_mtime_ns)
            if _seen.get(path) == key or not stat.S_ISREG(status.st_mode):
                continue
            _seen[path] = key
            try:
                with open(path, "rb") as stream:
                    head = stream.read(40)
            except OSError:
                continue
            if FLIGHT_LOG.match(head):
                found.append(path)
    return found


@pytest.fixture(autouse=True)
def flight_logs_follow_the_schema(request: pytest.FixtureRequest) -> Iterator[None]:
    """After each test, every flight log written under the suite's temporary directories
    since the last test (by the test, its fixtures, or a ``tml`` process it started) is
    read back and each line checked against the flight log's schema. A log another worker
    is still writing is checked as far as it goes (its last line may be cut) and again
    once it has grown."""
    yield
    if request.node.get_closest_marker("foreign_logs") or \
            not TEMPORARY & set(request.fixturenames):
        return  # a test without pytest's temporary directories writes no log there
    factory: pytest.TempPathFactory = request.getfixturevalue("tmp_path_factory")
    found = [problem for folder in log_folders(factory.getbasetemp())
             for path in new_flight_logs(folder) for problem in schema_problems(path)]
    if found:
        pytest.fail("flight log lines that break the schema:\n" + "\n".join(found[:20]),
                    pytrace=False)
