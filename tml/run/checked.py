"""The options of a flight that is checked as it flies: one place for ``tml run`` and
``tml serve``.

In flight, each action is checked again against live telemetry before it starts
(:func:`tml.verify.inflight.pre_check`), its time limit is set at the profile's cruise
speed until SET_SPEED changes it (:func:`tml.verify.inflight.cruise`), and moves
follow the planner's paths around the obstacles the verifier planned around
(:func:`tml.verify.inflight.router`).
"""

from __future__ import annotations

from tml.engine import Limits, Options
from tml.run.runner import RunOptions
from tml.verify.inflight import cruise, pre_check, router
from tml.verify.profile import VehicleProfile
from tml.world import World


def checked_options(profile: VehicleProfile, world: World, *, safe_state: str = "rtl",
                    link_lost_limit: float = 10.0, ready_timeout: float = 180.0,
                    safe_state_timeout: float = 120.0, vehicle_fence: bool = True
                    ) -> RunOptions:
    """The runner's options for a flight checked against ``profile`` and ``world``
    (``vehicle_fence`` False: the vehicles keep their own fence, see RunOptions)."""
    engine = Options(world=world, pre_check=pre_check(profile, world),
                     route=router(profile, world),
                     limits=Limits(cruise=cruise(profile)))
    return RunOptions(safe_state=safe_state, link_lost_limit=link_lost_limit,
                      ready_timeout=ready_timeout, safe_state_timeout=safe_state_timeout,
                      vehicle_fence=vehicle_fence, engine=engine)
