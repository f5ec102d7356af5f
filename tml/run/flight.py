"""Flying a mission: the one use case of ``tml run``, ``tml serve`` and a cluster's takeover.

Theory of operation
-------------------
A :class:`Flight` is one mission on the vehicles its caller opened (``tml run``: a
:class:`~tml.run.session.Session`) or holds (``tml serve``: the runs' vehicles of its
hangar, a cluster's takeover: the vehicles of the run it continues), flown with typed
:class:`FlightOptions`. Every caller goes the same way:

1. :meth:`Flight.clear` clears the mission for the vehicles before anything is sent
   (:func:`tml.run.clearance.clear`: the verifier's profile, read from the first vehicle
   when none is given; the actions the vehicles cannot do; their GCS failsafe);
2. :meth:`Flight.start` makes the runner with the options checked against the cleared
   profile and the world (:func:`tml.run.checked.checked_options`), its journal, clock
   and wake-up, going on from an interrupted run's progress when given;
3. :meth:`Flight.fly` flies it to its end. The runner's own ends (completion, abort, a
   stop, a take-over, a lost link) pass through its safe-state path; should the runner
   itself raise (a broken vehicle adapter, a journal whose database failed), the error is
   written to the journal when it still takes lines, every vehicle is sent its safe
   state from here, what was sent is said, and the error is raised to the caller, which
   decides how its run ended.

What differs is the callers', given as hooks: what is said (``on_safety``: the command
line prints, the service keeps it with the run), what a change updates (``on_update``:
the live display), how the loop waits (``wake``, ``wait``: a session's flag, a
hangar's), where the journal writes (a file, the service's database) and how the
vehicles were had.
"""

from __future__ import annotations

import contextlib
import threading
import traceback
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from tml.run.checked import checked_options
from tml.run.clearance import ClearanceOptions, Cleared, NotCleared, clear
from tml.run.runner import Outcome, Runner, RunOptions
from tml.timebase import SYSTEM, Flag, Timebase

if TYPE_CHECKING:
    from tml.engine.resume import Progress
    from tml.language.model import Mission
    from tml.run.journal import Journal
    from tml.vehicle import IdSource, Vehicle
    from tml.verify.profile import VehicleProfile
    from tml.world import World


@dataclass(frozen=True)
class FlightOptions:
    """How a mission is cleared and flown (``tml run``'s options, ``tml serve``'s and
    each run's)."""

    safe_state: str = "rtl"
    """What a flying vehicle is told when the run stops early (rtl, land, hold)."""
    link_lost_limit: float = 10.0
    """Seconds of a lost link before the run is aborted."""
    ready_timeout: float = 180.0
    """Seconds for the vehicles to be ready before the first task."""
    safe_state_timeout: float = 120.0
    """Seconds the safe state is commanded again until the vehicle shows it."""
    vehicle_fence: bool = True
    """Put the mission's fence on the vehicles (False: they keep their own)."""
    force: bool = False
    """Fly a mission refused as infeasible or beyond its vehicles anyway."""
    gcs_failsafe: bool = True
    """Read each vehicle's ``FS_GCS_ENABLE`` when clearing (a warning when it does
    nothing)."""
    require_gcs_failsafe: bool = False
    """Refuse a vehicle whose ``FS_GCS_ENABLE`` does nothing."""

    def clearance(self) -> ClearanceOptions:
        """The clearance's options."""
        return ClearanceOptions(force=self.force, gcs_failsafe=self.gcs_failsafe,
                                require_gcs_failsafe=self.require_gcs_failsafe)

    def run_options(self, profile: VehicleProfile, world: World) -> RunOptions:
        """The runner's options for a flight checked against ``profile`` and ``world``."""
        return checked_options(profile, world, safe_state=self.safe_state,
                               link_lost_limit=self.link_lost_limit,
                               ready_timeout=self.ready_timeout,
                               safe_state_timeout=self.safe_state_timeout,
                               vehicle_fence=self.vehicle_fence)


class Flight:
    """A mission cleared for its vehicles and flown to a safe end; see the module
    docstring."""

    def __init__(self, mission: Mission, vehicles: Sequence[Vehicle],
                 options: FlightOptions | None = None, *,
                 on_safety: Callable[[str], None] | None = None) -> None:
        self.mission = mission
        self.vehicles = list(vehicles)
        self.options = options or FlightOptions()
        self.on_safety = on_safety
        self._runner: Runner | None = None

    def clear(self, profile: VehicleProfile | None, extra: World | None = None, *,
              verified: bool = False) -> Cleared | NotCleared:
        """Clear the mission for flight on the vehicles (:func:`tml.run.clearance.clear`
        with the options' clearance; ``verified``: ``profile`` was verified already)."""
        return clear(self.mission, self.vehicles, profile, extra, self.options.clearance(),
                     verified=verified)

    def start(self, profile: VehicleProfile, world: World, journal: Journal, *,
              clock: Callable[[], float], wake: Flag | threading.Event | None = None,
              wait: Callable[[float], None] | None = None, timebase: Timebase = SYSTEM,
              ids: IdSource | None = None, resume: Mapping[int, Progress] | None = None,
              payloads: Mapping[int, Iterable[str]] | None = None,
              on_update: Callable[[Runner], None] | None = None,
              about: Mapping[str, object] | None = None) -> Runner:
        """Make the runner that flies the cleared mission (:meth:`fly` flies it):
        ``profile`` the cleared one, ``world`` the mission's (and ``--world``'s), its
        first log line with ``about``; going on from ``resume`` (an interrupted run's
        progress, its requests numbered on by ``ids``) when given."""
        self._runner = Runner(self.mission, self.vehicles, clock=clock,
                              options=self.options.run_options(profile, world),
                              journal=journal, wake=wake, wait=wait, timebase=timebase,
                              on_safety=self.on_safety, payloads=payloads,
                              on_update=on_update, ids=ids, resume=resume, about=about)
        return self._runner

    @property
    def runner(self) -> Runner:
        """The runner :meth:`start` made."""
        if self._runner is None:
            raise RuntimeError("the flight has not started")
        return self._runner

    def fly(self, describe: Callable[[Exception], str] | None = None) -> Outcome:
        """Fly until every vehicle's mission has ended; how it went. Should the runner
        itself raise, the error is journaled (``describe``: how it is said), every vehicle
        is sent its safe state (:meth:`safe_end`), and the error raised again."""
        runner = self.runner
        try:
            return runner.run()
        except Exception as error:
            reason = describe(error) if describe is not None else \
                f"{type(error).__name__}: {error}"
            with contextlib.suppress(Exception):  # the journal may be what failed
                runner.journal.write(runner.clock(), "error", None, message=reason,
                                     traceback=traceback.format_exc())
            self.safe_end(reason)
            raise

    def safe_end(self, reason: str) -> None:
        """The engine's safe state, sent to every vehicle from here when the runner itself
        failed; what was sent said to ``on_safety``."""
        from tml.engine.safety import safe_state_request

        for vehicle in self.vehicles:
            vid = vehicle.vehicle_id
            try:
                safe = safe_state_request(vehicle.state(), self.options.safe_state)
                if safe is not None:
                    vehicle.submit(safe[0])
                    self._say(f"vehicle {vid}: {safe[0].name} ({reason})")
            except Exception as error:  # one vehicle must not spare the others
                self._say(f"vehicle {vid}: safe state not sent: {error!r}")

    def _say(self, message: str) -> None:
        if self.on_safety is not None:
            self.on_safety(message)
