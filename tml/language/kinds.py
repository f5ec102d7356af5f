"""Kinds of vehicle and what each can do: one source for the verifier, the interpreter and
the MAVLink adapter.

A vehicle reports its airframe (:data:`VEHICLE_TYPES`, from the HEARTBEAT
type); tml flies three kinds of them, after ArduPilot's Copter, Plane and Rover:

- **multicopter** (and every other aircraft that hovers: helicopters, VTOLs, airships):
  takes off and lands vertically, hovers, turns in place;
- **fixed-wing**: keeps its airspeed, so it cannot hover or turn in place. It takes off in
  a climb along its heading, flies to a point and circles it (ArduPlane loiters around a
  GUIDED target), and lands along an approach: it glides down :data:`GLIDE_RATIO` metres
  for every metre of height (ArduPlane's landings are about 7 degrees) to a touchdown
  point ahead of it;
- **ground** (rovers and boats): drives on the surface and has no altitude. It arms
  itself for its first move (there is nothing to take off from), stops where it is told
  to hold, and turns only while driving.

:func:`refusal` says why an action is impossible for a kind, before anything is sent:
``tml verify`` reports it against the profile's vehicle type (or a role's type), ``tml
run`` against the connected vehicles before the first task, and the interpreter before
each action against the live vehicle's type. :data:`HANDLING` holds what the action scripts
assume of each kind when they judge that a move has arrived.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from tml.geo import Point
from tml.language.actions import BoundAction
from tml.language.diagnostics import indefinite

MULTICOPTERS = frozenset({"quadcopter", "hexacopter", "octocopter", "tricopter", "coaxial"})
"""The vehicle types a role asking for "multicopter" accepts."""
GROUND_AND_WATER = frozenset({"rover", "boat", "submarine"})
"""The vehicle types that are not aircraft (a "UAV" role accepts all the others)."""
VEHICLE_TYPES = MULTICOPTERS | GROUND_AND_WATER | frozenset(
    {"helicopter", "fixed-wing", "vtol", "airship"})
"""The airframe classes a vehicle reports (:attr:`tml.vehicle.VehicleState.vehicle_type`)."""
VEHICLE_TYPE_CLASSES = frozenset({"multicopter", "uav"})
"""Words a role may ask for that stand for several vehicle types ("UAV" as Dolphin writes it)."""


def vehicle_type_matches(wanted: str, actual: str) -> bool:
    """Whether a vehicle of type ``actual`` is what a role asking for ``wanted`` needs.

    ``wanted`` is a word of :data:`VEHICLE_TYPES` (that type only) or of
    :data:`VEHICLE_TYPE_CLASSES`: "multicopter" (any multirotor) or "UAV", any case (any
    aircraft, not a rover, boat or submarine). An unknown ``actual`` ("") matches nothing.
    """
    if not actual:
        return False
    if wanted == actual:
        return True
    if wanted == "multicopter":
        return actual in MULTICOPTERS
    if wanted.lower() == "uav":
        return actual in VEHICLE_TYPES - GROUND_AND_WATER
    return False


class Kind(StrEnum):
    """How a vehicle moves (see the module docstring)."""

    MULTICOPTER = "multicopter"
    FIXED_WING = "fixed-wing"
    GROUND = "ground"


NOUNS = {Kind.MULTICOPTER: "multicopter", Kind.FIXED_WING: "fixed-wing",
         Kind.GROUND: "ground vehicle"}
"""How a vehicle of each kind is called when its type is not known."""

_KINDS = {"fixed-wing": Kind.FIXED_WING, "rover": Kind.GROUND, "boat": Kind.GROUND}


def kind_of(vehicle_type: str) -> Kind:
    """The kind of a vehicle type (a word of :data:`VEHICLE_TYPES`); an unknown
    or empty type is a multicopter, the vehicle tml flies by default."""
    return _KINDS.get(vehicle_type, Kind.MULTICOPTER)


def role_kinds(wanted: str | None) -> frozenset[Kind]:
    """The kinds of vehicle a role asking for ``wanted`` may be given (all for no type)."""
    if wanted is None:
        return frozenset(Kind)
    if wanted.lower() == "uav":
        return frozenset({Kind.MULTICOPTER, Kind.FIXED_WING})
    if wanted == "multicopter":
        return frozenset({Kind.MULTICOPTER})
    return frozenset({kind_of(wanted)})


@dataclass(frozen=True)
class Handling:
    """What the action scripts assume of a kind of vehicle.

    ``arrival_radius``: metres from a target within which a move is done (0: the
    interpreter's own acceptance radius); ``vertical_tolerance``: metres of altitude error
    allowed (infinite: altitude is not watched); ``loiter_radius``: the circle a fixed-wing
    flies around a point it is sent to (0: the vehicle stops on it).
    """

    kind: Kind
    description: str
    arrival_radius: float = 0.0
    vertical_tolerance: float = 0.0
    loiter_radius: float = 0.0


HANDLING: dict[Kind, Handling] = {
    Kind.MULTICOPTER: Handling(
        Kind.MULTICOPTER, "hovers; takes off and lands vertically; turns in place"),
    # ArduPlane circles a GUIDED target at the commanded radius plus the L1 controller's
    # slack (measured on ArduPlane SITL: 60 m asked, about 80 m flown): a move is done
    # once the plane is on that circle. TECS holds altitude within a metre or two.
    Kind.FIXED_WING: Handling(
        Kind.FIXED_WING, "cannot hover: circles the points it is sent to; takes off in a "
        "climb and lands along an approach; cannot turn in place",
        arrival_radius=100.0, vertical_tolerance=5.0, loiter_radius=60.0),
    # ArduPilot Rover stops within WP_RADIUS (2 m by default, 3 m in its SITL parameters).
    Kind.GROUND: Handling(
        Kind.GROUND, "drives on the ground: no altitude, no take-off or landing; arms "
        "itself for its first move; stops to hold; turns only while driving",
        arrival_radius=3.0, vertical_tolerance=math.inf),
}


# Actions each kind cannot fly at all, with the reason (written as the end of a sentence
# that starts with the vehicle type: "a rover cannot take off ...").
_CANNOT: dict[Kind, dict[str, str]] = {
    Kind.FIXED_WING: {
        "ROTATE_YAW": "cannot turn in place (it turns only by flying a circle)",
        "FLIP": "has no FLIP mode",
        "PICK_UP_ITEM": "cannot hover over an item to pick it up",
    },
    Kind.GROUND: {
        "TAKE_OFF": "cannot take off (it stays on the ground and arms itself for its "
                    "first move)",
        "LAND": "cannot land (it stays on the ground; RETURN_HOME_AND_LAND drives home and "
                "stops, and the end of the mission disarms it)",
        "LANDING_POINT": "cannot land (GO_TO_POINT drives it to the point)",
        "SET_ALTITUDE": "has no altitude to change",
        "ROTATE_YAW": "cannot turn in place (ArduPilot Rover turns only while driving)",
        "FLIP": "has no FLIP mode",
        "PICK_UP_ITEM": "cannot descend on an item to pick it up",
        "ORBIT": "cannot face a point while it circles it (ArduPilot Rover heads along "
                 "its circle, and an ROI only aims a camera mount)",
        "SURVEY_PHOTOS": "has no altitude to photograph an area from (the passes and "
                         "the trigger distance come from the camera's footprint there)",
    },
}


def refusal(bound: BoundAction, kind: Kind, vehicle_type: str = "") -> str | None:
    """Why a vehicle of ``kind`` cannot fly ``bound`` at all ("a rover cannot take off
    ..."), or None when it can.

    ``vehicle_type`` names the vehicle in the reason; without it, the kind does. Only
    what the action asks for is judged here, never the vehicle's state: limits of speed,
    altitude, range or turn radius are the verifier's.
    """
    reason = _CANNOT.get(kind, {}).get(bound.name)
    if reason is None and kind is Kind.GROUND and bound.name == "MOVE" \
            and bound.choice("direction") in ("up", "down") and "distance" in bound.values:
        reason = "cannot move up or down"
    return None if reason is None else f"{indefinite(vehicle_type or NOUNS[kind])} {reason}"


def cannot(kind: Kind) -> tuple[str, ...]:
    """The actions ``kind`` cannot fly at all (for descriptions and documentation)."""
    return tuple(sorted(_CANNOT.get(kind, {})))


# --- fixed-wing landings ----------------------------------------------------------------

GLIDE_RATIO = 8.0
"""Metres flown for each metre of descent on a fixed-wing's final approach (ArduPlane's
SITL landings measured about 7 degrees)."""
MIN_FINAL = 200.0
"""The shortest final approach (m): room to line up and flare."""


def final_length(altitude: float) -> float:
    """The length of a final approach from ``altitude`` metres above the touchdown."""
    return max(GLIDE_RATIO * max(altitude, 0.0), MIN_FINAL)


def landing_approach(here: Point, heading: float, touchdown: Point | None) -> tuple[Point, Point]:
    """Where a fixed-wing starts its final approach, and where it touches down.

    Without a ``touchdown`` the vehicle lands straight ahead: the approach starts where it
    is and it touches down a final's length along ``heading``. With one, the approach
    starts a final's length from the touchdown on the side the vehicle comes from, at its
    present altitude, so that it flies there and glides straight in.
    """
    altitude = here[2]
    length = final_length(altitude - (touchdown[2] if touchdown else 0.0))
    if touchdown is None:
        bearing = math.radians(heading)
        ground = (here[0] + length * math.cos(bearing), here[1] + length * math.sin(bearing),
                  0.0)
        return here, ground
    dn, de = here[0] - touchdown[0], here[1] - touchdown[1]
    away = math.hypot(dn, de)
    if away < 1e-6:  # right over it: come in along the heading
        bearing = math.radians(heading)
        dn, de, away = -math.cos(bearing), -math.sin(bearing), 1.0
    approach = (touchdown[0] + length * dn / away, touchdown[1] + length * de / away, altitude)
    return approach, (touchdown[0], touchdown[1], touchdown[2])
