"""The safe state: what a vehicle is told when nobody flies it any more.

One rule for every place that needs it: the end of a mission, a role's release, a lost
vehicle, and the runner when the engine itself cannot be asked.
"""

from __future__ import annotations

from collections.abc import Callable

from tml.language.kinds import Kind, kind_of
from tml.vehicle import Disarm, Hold, Land, Request, ReturnToLaunch, VehicleState

SAFE_STATES: dict[str, Callable[[int], Request]] = {
    "rtl": ReturnToLaunch, "land": Land, "hold": Hold}
"""The safe states a run may choose (``--safe-state``), RTL being the default."""


def safe_state_request(state: VehicleState, safe_state: str) -> tuple[Request, str] | None:
    """What puts a vehicle in the safe state, and why; None when it is safe already.

    A ground vehicle is safe stopped: an armed one is disarmed, wherever it is. Any other
    that is not on the ground -- flying, saying it is not landed even when disarmed (in
    doubt it is taken to be in the air), or asked to fly with no telemetry since
    (:attr:`~tml.vehicle.VehicleState.possibly_flying`) -- is told ``safe_state`` (rtl,
    land or hold); one armed on the ground is disarmed.
    """
    if kind_of(state.vehicle_type) is Kind.GROUND:
        if state.armed or state.flight_unseen:
            return Disarm(state.vehicle_id), "ground vehicle armed: disarm (it stops)"
        return None
    if state.possibly_flying:
        request = SAFE_STATES.get(safe_state, ReturnToLaunch)(state.vehicle_id)
        return request, f"vehicle in the air: {request.name}"
    if state.armed:
        return Disarm(state.vehicle_id), "vehicle armed on the ground: disarm"
    return None


SHOWN: dict[str, frozenset[str]] = {
    "rtl": frozenset({"RTL", "SMART_RTL", "QRTL", "LAND", "QLAND"}),
    "land": frozenset({"LAND", "QLAND"}),
    "hold": frozenset({"GUIDED", "LOITER", "BRAKE", "HOLD", "POSHOLD", "RTL", "SMART_RTL",
                       "QRTL", "LAND", "QLAND"}),
}
"""The modes in which a flying vehicle shows each safe state (an autopilot's own failsafe
landing shows a safe return as well)."""


def safe_state_shown(state: VehicleState, safe_state: str) -> bool:
    """Whether the telemetry shows the vehicle in its safe state: nothing left to ask of it
    (:func:`safe_state_request`), or flying in a mode of :data:`SHOWN` (a fixed-wing lands
    by a landing sequence flown in AUTO). A lost link shows nothing, nor does a picture
    older than the latest request (:attr:`~tml.vehicle.VehicleState.current`)."""
    if state.link == "lost" or not state.current:
        return False
    if safe_state_request(state, safe_state) is None:
        return True
    shown = SHOWN.get(safe_state, SHOWN["rtl"])
    if safe_state == "land" and kind_of(state.vehicle_type) is Kind.FIXED_WING:
        shown = shown | {"AUTO"}
    return state.flying and state.mode in shown
