"""The world's obstacles as the vehicle meets them: contact and distance.

Each obstacle (a vertical cylinder or a prism) becomes a ground shape with a bottom and a
top; a position is in contact with it when it lies between bottom and top (widened by the
margin) and within the margin of the shape. Distances are horizontal, in metres.
"""

from __future__ import annotations

from typing import Any

from shapely.geometry import Point, Polygon

from tml.world import Cylinder, World

Vector = tuple[float, float, float]


def _footprint(obstacle: Any) -> tuple[str, Any, float, float]:
    """(name, ground shape, bottom, top) of a world obstacle."""
    if isinstance(obstacle, Cylinder):
        shape = Point(obstacle.north, obstacle.east).buffer(obstacle.radius)
    else:
        shape = Polygon(obstacle.polygon)
    return obstacle.name, shape, obstacle.bottom, obstacle.top


class Obstacles:
    """The obstacles of ``world``."""

    def __init__(self, world: World) -> None:
        self._shapes = [_footprint(obstacle) for obstacle in world.obstacles]
        # Whether there are any: without, nothing is ever touched (the common case,
        # asked every control step).
        self.present = bool(self._shapes)

    def touching(self, position: Vector, margin: float = 0.0) -> str | None:
        """The name of an obstacle within ``margin`` metres of ``position``, or None."""
        if not self._shapes:
            return None  # the common case, checked every control step: skip the geometry
        point = Point(position[:2])
        for name, shape, bottom, top in self._shapes:
            if bottom - margin <= position[2] <= top + margin and shape.distance(point) <= margin:
                return name
        return None

    def nearest(self, position: Vector, margin: float = 0.0) -> float | None:
        """Horizontal distance to the nearest obstacle at this height (None: none there)."""
        if not self._shapes:
            return None
        point = Point(position[:2])
        distances = [shape.distance(point) for _, shape, bottom, top in self._shapes
                     if bottom - margin <= position[2] <= top + margin]
        return min(distances) if distances else None
