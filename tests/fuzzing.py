"""What the fuzzers share: their Hypothesis profiles and the bounds every case runs within.

Two profiles: ``ci`` (the default; a few thousand cases over all fuzzers, within about a
minute on two cores) and ``deep`` (by hand, many more cases and longer bounds)::

    TML_FUZZ=deep .venv/bin/python -m pytest -q tests/test_fuzz_*.py

``TML_FUZZ_EXAMPLES=N`` sets the number of cases of each fuzzer in either profile.
docs/reliability.md says more.
"""

from __future__ import annotations

import contextlib
import os
import resource
import signal
from collections.abc import Iterator

from hypothesis import HealthCheck, settings

_COMMON = {"deadline": None, "database": None,
           "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large,
                                     HealthCheck.filter_too_much]}
settings.register_profile("ci", max_examples=200, derandomize=True, print_blob=True, **_COMMON)
settings.register_profile("deep", max_examples=20_000, derandomize=False, print_blob=True,
                          **_COMMON)

PROFILE = os.environ.get("TML_FUZZ", "ci")
if PROFILE not in ("ci", "deep"):
    raise ValueError(f"TML_FUZZ={PROFILE!r}: the profiles are ci and deep")
CASE_SECONDS = 20.0 if PROFILE == "deep" else 10.0
"""CPU seconds one case may take before it counts as a hang: CPU time, not wall-clock time,
so that a case on a busy machine (waiting for a core, not looping) is never called one."""
MEMORY_MARGIN = 2 << 30
"""Bytes of address space a fuzzer may take beyond what the process had when it started."""


def fuzz_settings(examples: int) -> settings:
    """The profile's settings with ``examples`` cases in ``ci`` (``deep`` keeps its own)."""
    override = os.environ.get("TML_FUZZ_EXAMPLES")
    count = int(override) if override else (
        examples if PROFILE == "ci" else settings.get_profile("deep").max_examples)
    return settings(settings.get_profile(PROFILE), max_examples=count)


class Hang(Exception):
    """A case ran longer than CASE_SECONDS (what a fuzzer reports as a defect)."""


@contextlib.contextmanager
def time_bound(seconds: float = CASE_SECONDS) -> Iterator[None]:
    """Raise :class:`Hang` in the main thread if the block spends more than ``seconds`` of
    the process's CPU time. A case that blocks without spinning is left to pytest-timeout,
    whose wall-clock timer (ITIMER_REAL) this one (ITIMER_PROF) does not touch."""
    def expire(_signum: int, _frame: object) -> None:
        raise Hang(f"still running after {seconds:g} s of CPU time")

    previous = signal.signal(signal.SIGPROF, expire)
    signal.setitimer(signal.ITIMER_PROF, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, previous)


def _address_space() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[0]) * resource.getpagesize()


@contextlib.contextmanager
def memory_bound(margin: int = MEMORY_MARGIN) -> Iterator[None]:
    """Make an allocation beyond ``margin`` more bytes of address space a MemoryError."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = _address_space() + margin
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
