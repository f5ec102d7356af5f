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
    land or hold), unless fresh telemetry shows it landing or returning already in a mode
    that carries that safe state out (:data:`SHOWN`; a landing copter is not sent back up
    to return); one armed on the ground is disarmed.
    """
    if kind_of(state.vehicle_type) is Kind.GROUND:
        if state.armed or state.flight_unseen:
            return Disarm(state.vehicle_id), "ground vehicle armed: disarm (it stops)"
        return None
    if state.possibly_flying:
        if left_to_itself(state, safe_state):
            return None  # on its way down already (landing, returning): left to it
        request = SAFE_STATES.get(safe_state, ReturnToLaunch)(state.vehicle_id)
        return request, f"vehicle in the air: {request.name}"
    if state.armed:
        return Disarm(state.vehicle_id), "vehicle armed on the ground: disarm"
    return None


def left_to_itself(state: VehicleState, safe_state: str) -> str:
    """Why a vehicle in the air is left to carry on by itself rather than told
    ``safe_state`` (fresh telemetry shows it landing or returning already, in a mode of
    :data:`SHOWN`): a decision like any other, which the caller logs; "" when it is not."""
    if kind_of(state.vehicle_type) is Kind.GROUND or not state.possibly_flying \
            or safe_state == "hold" or not state.current or state.link == "lost" \
            or state.mode not in SHOWN.get(safe_state, SHOWN["rtl"]):
        return ""
    if state.mode in SHOWN["land"]:
        return f"vehicle landing ({state.mode}): left to land by itself"
    return f"vehicle returning ({state.mode}): left to return by itself"


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


# --- an operator's command -------------------------------------------------------------------

OPERATOR_COMMANDS = ("rtl", "land", "hold", "disarm")
"""What an operator may tell a vehicle at any moment (``tml command``, ``POST
/vehicles/{id}/command``)."""

COMMAND_SHOWN: dict[str, frozenset[str]] = {
    "rtl": frozenset({"RTL", "SMART_RTL", "QRTL"}),
    "land": frozenset({"LAND", "QLAND"}),
    "hold": frozenset({"GUIDED", "LOITER", "BRAKE", "HOLD", "POSHOLD", "QLOITER"}),
}
"""The modes in which a vehicle shows an operator's command taken (hold: a multicopter
stopped in GUIDED, a fixed-wing circling in GUIDED, a rover in HOLD)."""


HOLDING_MODES = {"multicopter": "BRAKE", "fixed-wing": "LOITER", "rover": "HOLD",
                 "boat": "LOITER"}
"""The mode that holds by itself, by the vehicle's kind (an operator's ``hold`` of a
vehicle no run flies is this mode, not GUIDED, where nothing would keep its target once
the command has gone): ArduCopter BRAKE (LOITER follows the sticks, and with SITL's
resting throttle a LOITER hold descends), ArduPlane LOITER (circles where it is), Rover
HOLD, a boat LOITER (holds its position)."""


def holding_mode(state: VehicleState) -> str:
    """The mode of :data:`HOLDING_MODES` for the vehicle's kind (``tml command`` and
    ``tml serve`` hold a vehicle no run flies in it)."""
    kind = kind_of(state.vehicle_type)
    if kind is Kind.FIXED_WING:
        return HOLDING_MODES["fixed-wing"]
    if kind is Kind.GROUND:
        return HOLDING_MODES["boat" if state.vehicle_type == "boat" else "rover"]
    return HOLDING_MODES["multicopter"]


class CommandRefusal(ValueError):
    """An operator's command refused before it is sent, saying why (it would be unsafe, or
    the vehicle cannot do it)."""


def operator_request(state: VehicleState, command: str) -> Request | None:
    """The request that carries out an operator's ``command`` (one of
    :data:`OPERATOR_COMMANDS`); None when there is nothing to do (a disarmed vehicle told
    to disarm, one on the ground and disarmed told to return, land or hold: it is safe
    where it is). Raises :class:`CommandRefusal` with the reason when it must not be sent:

    - a vehicle whose link is lost hears nothing;
    - ``disarm`` of a vehicle that may be in the air (flying, saying it is not landed, or
      asked to fly with no reading since) would drop it: land it first. A ground vehicle
      is disarmed wherever it is (it stops);
    - ``land`` of a ground vehicle: it has nowhere to land (hold or disarm stops it);
    - ``rtl``, ``land`` or ``hold`` of an air vehicle armed on the ground: it is not
      flying, disarm it (a copter told to land there would wait for its own disarm).
    """
    if command not in OPERATOR_COMMANDS:
        raise CommandRefusal(f"{command!r} is not a command (commands: "
                             f"{', '.join(OPERATOR_COMMANDS)})")
    if state.link == "lost":
        raise CommandRefusal("the vehicle's link is lost: no heartbeat")
    vid = state.vehicle_id
    ground = kind_of(state.vehicle_type) is Kind.GROUND
    if command == "disarm":
        if not ground and state.possibly_flying:
            where = f" at {state.altitude:.1f} m" if state.position is not None else ""
            raise CommandRefusal(f"the vehicle is flying{where}: disarming would drop it "
                                 "(land it first)")
        return Disarm(vid) if state.armed or state.flight_unseen else None
    if ground:
        if command == "land":
            raise CommandRefusal("a ground vehicle does not land (hold or disarm stops it)")
        if not state.armed:
            return None
        return ReturnToLaunch(vid) if command == "rtl" else Hold(vid)
    if not state.possibly_flying:
        if state.armed:
            raise CommandRefusal(f"the vehicle is on the ground, armed: nothing to "
                                 f"{'return from' if command == 'rtl' else command} "
                                 "(disarm it)")
        return None
    return SAFE_STATES[command](vid)


def operator_command_shown(state: VehicleState, command: str) -> bool:
    """Whether telemetry that arrived after the command (:attr:`VehicleState.current`)
    shows it taken: disarmed for ``disarm`` (on the ground, for an air vehicle), the
    command's mode (:data:`COMMAND_SHOWN`; a fixed-wing lands in AUTO), or on the ground
    and disarmed for the others."""
    if state.link == "lost" or not state.current:
        return False
    if command == "disarm" or not state.armed:
        return not state.armed and (state.landed or kind_of(state.vehicle_type) is Kind.GROUND)
    shown = COMMAND_SHOWN.get(command, frozenset())
    if command == "land" and kind_of(state.vehicle_type) is Kind.FIXED_WING:
        shown = shown | {"AUTO"}
    return state.mode in shown
