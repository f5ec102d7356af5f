"""Which vehicles may be picked for a role, in which order, and why the others may not."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from tml import geo
from tml.language.diagnostics import indefinite
from tml.language.kinds import vehicle_type_matches
from tml.language.model import Role
from tml.vehicle import VehicleState
from tml.world import Home


@dataclass(frozen=True)
class Candidate:
    """A vehicle as a pick sees it."""

    vehicle_id: int
    state: VehicleState
    payloads: frozenset[str]  # declared for the run, beyond what the state reports
    free_since: float  # -inf: never used
    role: str | None  # the role it is bound to
    lost: str  # why it cannot be used any more ("" when it can)


def candidates(role: Role, vehicles: Iterable[Candidate],
               home: Home | None) -> tuple[list[int], list[tuple[int, str]]]:
    """The vehicles that qualify for ``role``, best first (free the longest, then by id), and
    why each other one does not. ``home`` is the mission's, that regions are drawn from."""
    chosen: list[Candidate] = []
    refused: list[tuple[int, str]] = []
    for vehicle in vehicles:
        why = refusal(role, vehicle, home)
        if why:
            refused.append((vehicle.vehicle_id, why))
        else:
            chosen.append(vehicle)
    chosen.sort(key=lambda v: (v.free_since, v.vehicle_id))
    return [v.vehicle_id for v in chosen], refused


def refusal(role: Role, vehicle: Candidate, home: Home | None) -> str:
    """Why ``vehicle`` cannot be picked for ``role`` ("" when it can)."""
    state = vehicle.state
    if vehicle.lost or state.link == "lost":
        return vehicle.lost or "link lost"
    if vehicle.role is not None:
        return f"busy (role {vehicle.role!r})"
    if role.vehicle_type and not vehicle_type_matches(role.vehicle_type, state.vehicle_type):
        return f"{indefinite(state.vehicle_type or 'vehicle of unknown type')}, not " \
            f"{role.vehicle_type}"
    carried = vehicle.payloads | {c.lower() for c in state.capabilities}
    missing = [p for p in role.payloads if p.lower() not in carried]
    if missing:
        return f"no {', '.join(missing)}"
    if role.region is not None:
        where = mission_frame(state, home)
        if where is None:
            return "position unknown"
        region = role.region
        if region.is_circle:
            inside = math.dist(where, region.points[0]) <= (region.radius or 0.0)
        else:
            import shapely  # here: it loads threading, which the pure engine avoids

            inside = bool(shapely.Polygon(region.points).covers(shapely.Point(where)))
        if not inside:
            return f"outside the region (at {round(where[0])} m N, {round(where[1])} m E)"
    return ""


def mission_frame(state: VehicleState, home: Home | None) -> tuple[float, float] | None:
    """The vehicle's (north, east) from the mission's ``home``: its position is reported from
    its own home, which may be elsewhere."""
    if state.position is None:
        return None
    if home is None or state.home is None:
        return state.position[0], state.position[1]
    own = state.home
    latitude, longitude, altitude = geo.to_global(*state.position, own.latitude,
                                                  own.longitude, own.altitude)
    north, east, _ = geo.to_local(latitude, longitude, altitude, home.latitude,
                                  home.longitude, home.altitude)
    return north, east
