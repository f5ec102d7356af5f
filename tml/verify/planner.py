"""The trajectory planner: shortest collision-free paths around known obstacles.

Obstacles are vertical extrusions (cylinders and prisms, :mod:`tml.world`), so a leg from
``a`` to ``b`` is planned in the ground plane: an obstacle matters to the leg only when its
altitude band, widened by the clearance, meets the altitudes the leg flies through (a leg
above a building's top plus the clearance flies straight over it). The altitude is then
interpolated along the planned path.

Each obstacle that matters is inflated by the clearance into a polygon that *contains* the
true inflated shape: a shapely buffer with ``quad_segs`` segments per quarter circle puts its
vertices on the circle, so the buffer distance is divided by ``cos(pi / (4 * quad_segs))``
to push every chord out to the clearance. The shortest path among polygons runs through
their vertices (a visibility graph); the vertices used as graph nodes come from the inflated
polygon grown by a further ``MARGIN``, so that a path along a polygon's edge does not touch
the polygon it is tested against.

The visibility graph is built lazily, in two ways. A* finds the edges of a node only when
it expands it. And obstacles are added as needed: first only those the straight line
crosses, then, while the shortest path found crosses further obstacles, those are added
and the path planned again. Free space only shrinks as obstacles are added, so when the
graph has no path no path exists; when the path found crosses nothing else it is the
shortest one.

Only edges tangent at both ends are kept (the reduced visibility graph): a shortest path bends
around the polygon of each vertex it turns at, so an edge that cuts into the polygon at one
of its ends is never on it. This leaves a few edges per obstacle instead of one to every
node. The nodes next to a crossing of two overlapping polygons, and shared vertices, keep all
their edges; so do the start and the goal. Over random crowded and overlapping worlds the
path found is as long as over every visible edge (a test holds it to within 1e-6).

Distances to obstacles (:meth:`Planner.clearance_of`, :meth:`Planner.nearest`) measure only
the obstacles an STRtree of their footprints finds near the path, not all of them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

from tml.world import Cylinder, Obstacle

Point3 = tuple[float, float, float]  # (north, east, up) in metres from home
QUAD_SEGS = 3
MARGIN = 0.01  # m between a test polygon and the graph nodes around it
_COVER = 1.0 / math.cos(math.pi / (4 * QUAD_SEGS))


@dataclass(frozen=True)
class Trajectory:
    """A path of straight segments in the local frame, from its first point to its last."""

    points: tuple[Point3, ...]

    @property
    def length(self) -> float:
        """Length in metres, climbs and descents included (the paper's Length)."""
        return sum(math.dist(a, b) for a, b in pairwise(self.points))

    @property
    def horizontal_length(self) -> float:
        """Length in metres over the ground."""
        return sum(math.hypot(b[0] - a[0], b[1] - a[1])
                   for a, b in pairwise(self.points))


def straight(a: Point3, b: Point3) -> Trajectory:
    """The straight segment from ``a`` to ``b``."""
    return Trajectory((a, b)) if a != b else Trajectory((a,))


class Planner:
    """Plans legs among fixed obstacles with a fixed clearance; caches the legs it plans."""

    def __init__(self, obstacles: Sequence[Obstacle], clearance: float,
                 reduced: bool = True) -> None:
        self.obstacles = tuple(obstacles)
        self.clearance = clearance
        # Only edges tangent at both ends (the reduced visibility graph); False: every
        # visible edge, the graph the reduced one is measured against.
        self.reduced = reduced
        cores: list[Point | Polygon] = []
        radii: list[float] = []
        for obstacle in self.obstacles:
            if isinstance(obstacle, Cylinder):
                cores.append(Point(obstacle.north, obstacle.east))
                radii.append(obstacle.radius)
            else:
                cores.append(Polygon(obstacle.polygon))
                radii.append(0.0)
        # The true footprint is ``core`` grown by ``radius``; distances use it exactly.
        self.cores = np.array(cores, dtype=object)
        self.radii = np.array(radii, dtype=float)
        self.bottoms = np.array([o.bottom for o in self.obstacles], dtype=float)
        self.tops = np.array([o.top for o in self.obstacles], dtype=float)
        self.inflated = np.array(
            [core.buffer((radius + clearance) * _COVER, quad_segs=QUAD_SEGS)
             for core, radius in zip(cores, radii, strict=True)], dtype=object)
        self.tree = shapely.STRtree(self.inflated)
        self._core_tree = shapely.STRtree(self.cores)
        self._widest = float(np.max(self.radii)) if len(self.radii) else 0.0
        self._nodes: dict[int, np.ndarray] = {}
        self._cache: dict[tuple[Point3, Point3], Trajectory | None] = {}

    def band(self, low: float, high: float) -> np.ndarray:
        """Mask of the obstacles whose altitudes, widened by the clearance, meet [low, high]."""
        return (self.bottoms - self.clearance < high) & (self.tops + self.clearance > low)

    def trajectory(self, start: Point3, end: Point3) -> Trajectory | None:
        """The shortest collision-free path from ``start`` to ``end`` (the paper's
        Trajectory), or None when the obstacles close every way.

        Obstacles whose inflated shape holds ``start`` or ``end`` are left out: the
        constraints report a point too close to an obstacle on their own (c1).
        """
        key = (start, end)
        if key not in self._cache:
            self._cache[key] = self._plan(start, end)
        return self._cache[key]

    def _plan(self, start: Point3, end: Point3) -> Trajectory | None:
        a2, b2 = (start[0], start[1]), (end[0], end[1])
        if math.dist(a2, b2) < 1e-9 or not self.obstacles:  # a vertical or empty leg
            return straight(start, end)
        usable = self.band(min(start[2], end[2]), max(start[2], end[2]))
        # An end may lie inside an inflated polygon yet keep the clearance (the polygon is
        # a little larger than the true shape): such an obstacle stays, but edges from and
        # to that end are tested against its true shape ("soft").
        soft: set[int] = set()
        for held in {int(i) for i in self.tree.query([Point(a2), Point(b2)],
                                                     predicate="intersects")[1]}:
            if min(self._flat_distance(held, a2), self._flat_distance(held, b2)) \
                    >= self.clearance - 1e-9:
                soft.add(held)
            else:
                usable[held] = False
        active: set[int] = set()
        path = [a2, b2]
        while True:
            crossed = {int(i) for i in self.tree.query(LineString(path), predicate="intersects")
                       if usable[i]} - active
            if not crossed:
                break
            active |= crossed
            found = self._shortest(a2, b2, sorted(active), soft)
            if found is None:
                return None
            path = found
        return _with_altitudes(path, start, end)

    def _node_points(self, index: int) -> np.ndarray:
        if index not in self._nodes:
            grown = self.inflated[index].buffer(MARGIN, join_style="mitre")
            self._nodes[index] = np.asarray(grown.exterior.coords)[:-1]
        return self._nodes[index]

    def _rings(self, active: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The nodes of the active obstacles, and the indices of each one's neighbours
        before and after it on its own polygon."""
        rings = [self._node_points(i) for i in active]
        lengths = np.array([len(r) for r in rings])
        starts = np.repeat(np.cumsum(lengths) - lengths, lengths)
        sizes = np.repeat(lengths, lengths)
        position = np.arange(len(starts)) - starts
        return (np.concatenate(rings), starts + (position - 1) % sizes,
                starts + (position + 1) % sizes)

    def _flat_distance(self, index: int, point: tuple[float, float]) -> float:
        return max(float(shapely.distance(self.cores[index], Point(point)))
                   - float(self.radii[index]), 0.0)

    def _shortest(self, a2: tuple[float, float], b2: tuple[float, float],
                  active: list[int], soft: set[int]) -> list[tuple[float, float]] | None:
        """A* over the visibility graph of the active obstacles, whose edges are found only
        from the nodes it expands (the straight-line distance to the goal is the heuristic:
        it never overestimates, so the first time the goal is taken the path is shortest)."""
        tree = shapely.STRtree(self.inflated[active])
        # Each node's neighbours on its own polygon, to tell the edges tangent at it.
        candidates, previous_index, next_index = self._rings(active)
        before, after = candidates[previous_index], candidates[next_index]
        inside = tree.query(shapely.points(candidates), predicate="intersects")[0]
        keep = np.ones(len(candidates), dtype=bool)
        keep[inside] = False
        # Where polygons overlap, a path bends where their outlines cross, which is no
        # node: the nodes next to such a crossing (a neighbour inside another polygon)
        # stand in for it, so no edge at them is left out as not tangent.
        beside = ~(keep[previous_index] & keep[next_index])
        # Coincident nodes (shared vertices, a vertex on an end) would make zero-length
        # edges, degenerate geometry for the distance and intersection tests; a shared
        # vertex belongs to two polygons, so no edge at it is left out either.
        unique, first, counts = np.unique(candidates[keep], axis=0, return_index=True,
                                          return_counts=True)
        ends = np.all(unique == a2, axis=1) | np.all(unique == b2, axis=1)
        shared = np.concatenate([[True, True], ((counts > 1) | beside[keep][first])[~ends]])
        nodes = np.vstack([np.array([a2, b2]), unique[~ends]])
        before = np.vstack([np.array([a2, b2]), before[keep][first][~ends]])
        after = np.vstack([np.array([a2, b2]), after[keep][first][~ends]])
        to_goal = np.hypot(*(nodes - nodes[1]).T)
        cost = np.full(len(nodes), math.inf)
        cost[0] = 0.0
        previous = np.zeros(len(nodes), dtype=np.intp)
        open_ = np.ones(len(nodes), dtype=bool)
        reach = _tangents(nodes, before, after, shared) if self.reduced else \
            np.ones((len(nodes), len(nodes)), dtype=bool)
        while True:
            # The open node of least cost plus distance to the goal (the lowest index of
            # equals), as a heap of (estimate, node) would give it.
            node = int(np.argmin(np.where(open_, cost + to_goal, math.inf)))
            if not open_[node] or math.isinf(cost[node]):
                return None
            if node == 1:
                order = [1]
                while order[-1] != 0:
                    order.append(int(previous[order[-1]]))
                return [(float(nodes[i][0]), float(nodes[i][1])) for i in reversed(order)]
            open_[node] = False
            others = np.flatnonzero(open_ & reach[node])
            through = cost[node] + np.hypot(*(nodes[others] - nodes[node]).T)
            # Only an edge that would make a node cheaper is worth testing for obstacles.
            others, through = others[through < cost[others]], through[through < cost[others]]
            segments = shapely.linestrings(np.stack(
                [np.broadcast_to(nodes[node], (len(others), 2)), nodes[others]], axis=1))
            hit, polygon = tree.query(segments, predicate="intersects")
            # An (n, 2, 2) array makes n lines, an array; shapely's annotations cannot tell
            # an array's shape and also allow the single LineString of a 2-D one.
            hit = hit[self._blocking(hit, polygon, node, others,
                                     segments, active, soft)]  # type: ignore[arg-type]
            visible = np.ones(len(others), dtype=bool)
            visible[hit] = False
            cost[others[visible]] = through[visible]
            previous[others[visible]] = node

    def _blocking(self, hit: np.ndarray, polygon: np.ndarray, node: int, others: np.ndarray,
                  segments: np.ndarray, active: list[int], soft: set[int]) -> np.ndarray:
        """Which (segment, polygon) hits block: all, except hits of a soft obstacle's
        polygon by an edge from the start or to the goal that keeps its true clearance."""
        blocking = np.ones(len(hit), dtype=bool)
        if not soft:
            return blocking
        indices = np.asarray(active)[polygon]
        at_end = (node == 0) | (others[hit] == 1)
        check = at_end & np.isin(indices, list(soft))
        if check.any():
            gap = shapely.distance(self.cores[indices[check]], segments[hit[check]]) \
                - self.radii[indices[check]]
            blocking[np.flatnonzero(check)] = gap < self.clearance - 1e-9
        return blocking

    def clearance_of(self, points: Sequence[Point3]) -> float:
        """Smallest distance in metres from a path (or a point) to any obstacle's surface,
        counting the vertical gap to obstacles the path passes over or under; inf without
        obstacles. The paper's DistanceObstacle for a single point."""
        if not self.obstacles:
            return math.inf
        pieces = list(pairwise(points)) or \
                 [(points[0], points[0])]
        best = math.inf
        for a, b in pieces:
            geometry = Point(a[0], a[1]) if math.dist(a[:2], b[:2]) < 1e-9 \
                else LineString([a[:2], b[:2]])
            distances = self._surface(geometry, min(a[2], b[2]), max(a[2], b[2]))[1]
            best = min(best, float(np.min(distances)))
        return best

    def nearest(self, point: Point3) -> tuple[float, str]:
        """Distance from a point to the nearest obstacle's surface, and that obstacle's name."""
        if not self.obstacles:
            return math.inf, ""
        indices, distances = self._surface(Point(point[0], point[1]), point[2], point[2])
        index = int(np.argmin(distances))
        return float(distances[index]), self.obstacles[int(indices[index])].name

    def _surface(self, geometry: Point | LineString, low: float, high: float
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Some obstacles and their surface distances to ``geometry`` flown between
        altitudes ``low`` and ``high``, the nearest among them. The obstacle nearest over
        the ground gives a bound; only obstacles whose footprint core lies within the bound
        plus the largest radius can be nearer, and only those are measured."""
        found = self._core_tree.query_nearest(geometry)
        bound = float(np.min(self._distances(found, geometry, low, high)))
        if math.isfinite(bound):
            found = np.union1d(found, self._core_tree.query(
                geometry, predicate="dwithin", distance=bound + self._widest + 1e-6))
        else:
            found = np.arange(len(self.obstacles))
        return found, self._distances(found, geometry, low, high)

    def _distances(self, indices: np.ndarray, geometry: Point | LineString, low: float,
                   high: float) -> np.ndarray:
        flat = np.maximum(shapely.distance(self.cores[indices], geometry)
                          - self.radii[indices], 0.0)
        gap = np.maximum(np.maximum(self.bottoms[indices] - high, low - self.tops[indices]),
                         0.0)
        distances: np.ndarray = np.hypot(flat, gap)
        return distances


def _tangents(nodes: np.ndarray, before: np.ndarray, after: np.ndarray,
              shared: np.ndarray) -> np.ndarray:
    """Which edges (row: from, column: to) a shortest path may take: a shortest path bends
    only around the polygon of the vertex it bends at, so its edges touch the polygons at
    both ends without cutting in (both neighbours of a vertex on one side of the edge).
    Edges from the start, to the goal and at vertices shared by two polygons are always
    kept (an end may lie inside a polygon it keeps the clearance of: see ``soft``)."""
    direction = nodes[None, :, :] - nodes[:, None, :]  # [i, j]: from node i to node j
    # A neighbour within a few margins of the edge's line counts as on it: nodes stand a
    # margin off the polygons, so an edge may cut that band, and the path over every
    # visible edge does.
    scale = 4 * MARGIN * np.hypot(direction[..., 0], direction[..., 1]) + 1e-9

    def side(offset: np.ndarray) -> np.ndarray:
        product: np.ndarray = direction[..., 0] * offset[..., 1] \
            - direction[..., 1] * offset[..., 0]
        return product

    def one_side(first: np.ndarray, second: np.ndarray) -> np.ndarray:
        mixed: np.ndarray = ((first > scale) & (second < -scale)) \
            | ((first < -scale) & (second > scale))
        return ~mixed

    # At the far end j, its neighbours seen along i -> j; at the near end i, along i -> j.
    far = one_side(side((before - nodes)[None, :, :]), side((after - nodes)[None, :, :]))
    near = one_side(side((before - nodes)[:, None, :]), side((after - nodes)[:, None, :]))
    reach: np.ndarray = (far | shared[None, :]) & (near | shared[:, None])
    reach[0, :] = True
    reach[:, 1] = True
    return reach


def _with_altitudes(path: Sequence[tuple[float, float]], start: Point3,
                    end: Point3) -> Trajectory:
    # The altitude changes evenly with the distance flown over the ground; the ends are
    # kept exactly as given.
    total = sum(math.dist(p, q) for p, q in pairwise(path))
    points: list[Point3] = [start]
    flown = 0.0
    for index in range(1, len(path) - 1):
        flown += math.dist(path[index - 1], path[index])
        up = start[2] + (end[2] - start[2]) * flown / total
        points.append((path[index][0], path[index][1], up))
    points.append(end)
    return Trajectory(tuple(points))
