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

The visibility graph is built lazily: obstacles are added as needed, first only those the
straight line crosses, then, while the shortest path found crosses further obstacles, those
are added and the path planned again. Free space only shrinks as obstacles are added, so when the
graph has no path no path exists; when the path found crosses nothing else it is the
shortest one. Every obstacle's nodes, their neighbours on its polygon and the other polygons
that hold any of them are found once, for all obstacles, when the planner is made; a round
only gathers those of its obstacles. Points are complex numbers (north + i east) in the
rounds' arithmetic: a numpy call on an (n, n) array of complex numbers, not on an (n, n, 2)
array, whose last axis of two makes numpy loop in steps of two.

Only edges tangent at both ends are kept (the reduced visibility graph): a shortest path bends
around the polygon of each vertex it turns at, so an edge that cuts into the polygon at one
of its ends is never on it. This leaves a few edges per obstacle instead of one to every
node. The nodes next to a crossing of two overlapping polygons, and shared vertices, keep all
their edges; so do the start and the goal. Over random crowded and overlapping worlds the
path found is as long as over every visible edge (a test holds it to within 1e-6).

The edges of a round are tested for obstacles all at once: a segment nearer a polygon's
centre than a disk the polygon holds meets it; one farther than the disk around it, or with
all the polygon's corners on one side of its line or beyond one of its ends, misses it (each
by more than 1e-6 m); only the rest are asked of shapely, so the answers are shapely's (a
test holds them to it). A* then runs over the visible edges in plain Python with a heap.

Distances to obstacles (:meth:`Planner.clearance_of`, :meth:`Planner.nearest`) measure only
the obstacles an STRtree of their footprints finds near the path, not all of them, all the
pieces of a path at once.
"""

from __future__ import annotations

import contextlib
import heapq
import math
from collections.abc import Sequence
from itertools import pairwise

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

from tml.actions.motion import Point3, Trajectory, straight
from tml.world import Cylinder, Obstacle

__all__ = ["Planner", "Point3", "Trajectory", "straight"]

QUAD_SEGS = 3
MARGIN = 0.01  # m between a test polygon and the graph nodes around it
_COVER = 1.0 / math.cos(math.pi / (4 * QUAD_SEGS))
# m: a segment this much nearer or farther than a polygon's inner or outer disk certainly
# meets or misses it (the distances are computed to about 1e-12 m).
_SURE = 1e-6


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
        self.inflated = shapely.buffer(self.cores, (self.radii + clearance) * _COVER,
                                       quad_segs=QUAD_SEGS)
        self.tree = shapely.STRtree(self.inflated)
        self._core_tree = shapely.STRtree(self.cores)
        self._widest = float(np.max(self.radii)) if len(self.radii) else 0.0
        # A disk around each inflated polygon's centroid that the polygon holds (radius
        # -inf where the centroid is not inside it) and one that holds the polygon.
        # (An empty polygon, of a degenerate prism without clearance, has neither: no
        # segment meets it.)
        centres = shapely.centroid(self.inflated)
        self._centres = np.zeros((len(self.obstacles), 2))
        found, owner = shapely.get_coordinates(centres, return_index=True)
        self._centres[owner] = found
        self._inner = np.full(len(self.obstacles), -math.inf)
        held = np.flatnonzero(shapely.contains(self.inflated, centres))

        def inner(indices: np.ndarray) -> None:
            with np.errstate(divide="raise", invalid="raise"):
                self._inner[indices] = shapely.distance(
                    centres[indices], shapely.boundary(self.inflated[indices]))

        # Where GEOS divides by zero (the outline of a degenerate polygon, its corners
        # closer than a float can tell) the distance is not trusted: no inner disk.
        try:
            inner(held)
        except FloatingPointError:
            for index in held:
                with contextlib.suppress(FloatingPointError):
                    inner(held[held == index])
        corners, owner = shapely.get_coordinates(self.inflated, return_index=True)
        self._outer = np.full(len(self.obstacles), -math.inf)
        np.maximum.at(self._outer, owner,
                      np.hypot(*(corners - self._centres[owner]).T))
        # Each polygon's corners (holes' too), the last repeated to make them as many.
        count = np.bincount(owner, minlength=len(self.obstacles))
        most = int(count.max(initial=0))
        fill = (np.cumsum(count) - count)[:, None] \
            + np.minimum(np.arange(most)[None, :], np.maximum(count - 1, 0)[:, None])
        self._corners = corners[np.minimum(fill, len(corners) - 1)] if len(corners) \
            else np.zeros((len(count), 0, 2))
        # The graph's nodes: each inflated polygon's corners grown by MARGIN (as complex
        # numbers north + i east), obstacle by obstacle, with each one's neighbours on its
        # own polygon, and which nodes lie in which other polygons. (GEOS may raise the
        # invalid flag growing a degenerate polygon, such as one inflated by a clearance of
        # 1e-49 m: no warning for an obstacle that no leg may ever meet.)
        with np.errstate(invalid="ignore"):
            grown = shapely.buffer(self.inflated, MARGIN, join_style="mitre")
        rings, owner = shapely.get_coordinates(shapely.get_exterior_ring(grown),
                                               return_index=True)
        closing = np.ones(len(owner), dtype=bool)  # each ring's first, repeated at its end
        closing[:-1] = owner[1:] != owner[:-1]
        self._ring_nodes = _complex(rings[~closing])
        owner = owner[~closing]
        count = np.bincount(owner, minlength=len(self.obstacles))
        first = np.cumsum(count) - count
        self._rings = [np.arange(start, start + size) for start, size in zip(
            first.tolist(), count.tolist(), strict=True)]
        position = np.arange(len(owner)) - first[owner]
        self._ring_before = first[owner] + (position - 1) % count[owner]
        self._ring_after = first[owner] + (position + 1) % count[owner]
        held, holder = self.tree.query(shapely.points(rings[~closing]),
                                       predicate="intersects")
        self._holds: dict[int, list[int]] = {}
        for node, obstacle in zip(held.tolist(), holder.tolist(), strict=True):
            self._holds.setdefault(obstacle, []).append(node)
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
        path = [a2, b2]
        crossed = self._crossed(path, usable)
        # An end may lie inside an inflated polygon yet keep the clearance (the polygon is
        # a little larger than the true shape): such an obstacle stays, but edges from and
        # to that end are tested against its true shape ("soft"). (An obstacle that holds
        # an end meets the straight line: without a crossing, there is none to look for.)
        soft: set[int] = set()
        if crossed:
            for held in {int(i) for i in self.tree.query(shapely.points(path),
                                                         predicate="intersects")[1]}:
                if min(self._flat_distance(held, a2), self._flat_distance(held, b2)) \
                        >= self.clearance - 1e-9:
                    soft.add(held)
                else:
                    usable[held] = False
            crossed = {i for i in crossed if usable[i]}
        active: set[int] = set()
        while crossed:
            active |= crossed
            found = self._shortest(a2, b2, sorted(active), soft)
            if found is None:
                return None
            path = found
            crossed = self._crossed(path, usable) - active
        return _with_altitudes(path, start, end)

    def _crossed(self, path: list[tuple[float, float]], usable: np.ndarray) -> set[int]:
        """The usable obstacles whose inflated polygon the path meets."""
        return {int(i) for i in self.tree.query(shapely.linestrings(path),
                                                predicate="intersects") if usable[i]}

    def _flat_distance(self, index: int, point: tuple[float, float]) -> float:
        return max(float(shapely.distance(self.cores[index], Point(point)))
                   - float(self.radii[index]), 0.0)

    def _shortest(self, a2: tuple[float, float], b2: tuple[float, float],
                  active: list[int], soft: set[int]) -> list[tuple[float, float]] | None:
        """A* over the visibility graph of the active obstacles (the straight-line distance
        to the goal is the heuristic: it never overestimates, so the first time the goal is
        taken the path is shortest). The edges the tangents leave are tested for obstacles
        all at once, then searched in plain Python: a search expands a dozen nodes, and a
        numpy call per expansion cost more than the search itself."""
        kept = np.concatenate([self._rings[i] for i in active])
        beside = np.zeros(len(kept), dtype=bool)
        inside = [self._holds[i] for i in active if i in self._holds]
        if inside:
            # The nodes inside an active polygon are left out. Where polygons overlap, a
            # path bends where their outlines cross, which is no node: the nodes next to
            # such a crossing (a neighbour inside another polygon) stand in for it, so no
            # edge at them is left out as not tangent.
            covered = np.zeros(len(self._ring_nodes), dtype=bool)
            covered[np.concatenate(inside)] = True
            kept = kept[~covered[kept]]
            beside = covered[self._ring_before[kept]] | covered[self._ring_after[kept]]
        # Coincident nodes (shared vertices, a vertex on an end) would make zero-length
        # edges, degenerate geometry for the distance and intersection tests; a shared
        # vertex belongs to two polygons, so no edge at it is left out either.
        unique, first, counts = _unique_points(self._ring_nodes[kept])
        a, b = complex(*a2), complex(*b2)
        ends = (unique == a) | (unique == b)
        kept = kept[first][~ends]
        shared = np.concatenate([[True, True], ((counts > 1) | beside[first])[~ends]])
        nodes = np.concatenate([[a, b], unique[~ends]])
        # Each node's neighbours on its own polygon, to tell the edges tangent at it.
        before = np.concatenate([[a, b], self._ring_nodes[self._ring_before[kept]]])
        after = np.concatenate([[a, b], self._ring_nodes[self._ring_after[kept]]])
        reach = _tangents(nodes, before, after, shared) if self.reduced else \
            np.ones((len(nodes), len(nodes)), dtype=bool)
        bounds, heads, lengths = self._visible(nodes, reach, np.asarray(active), soft)
        # The search, as the open node of least cost plus distance to the goal (the lowest
        # index of equals) taken each time; a node's cost changes only when strictly lower.
        offset = nodes - nodes[1]
        to_goal = np.hypot(offset.real, offset.imag).tolist()
        cost = [math.inf] * len(nodes)
        cost[0] = 0.0
        previous = [0] * len(nodes)
        done = [False] * len(nodes)
        heap = [(to_goal[0], 0)]
        while heap:
            estimate, node = heapq.heappop(heap)
            if done[node] or estimate > cost[node] + to_goal[node]:
                continue  # taken already, or an estimate since lowered
            if node == 1:
                order = [1]
                while order[-1] != 0:
                    order.append(previous[order[-1]])
                return [(float(nodes[i].real), float(nodes[i].imag)) for i in reversed(order)]
            done[node] = True
            here = cost[node]
            for edge in range(bounds[node], bounds[node + 1]):
                other = heads[edge]
                through = here + lengths[edge]
                if through < cost[other] and not done[other]:
                    cost[other] = through
                    previous[other] = node
                    heapq.heappush(heap, (through + to_goal[other], other))
        return None

    def _visible(self, nodes: np.ndarray, reach: np.ndarray, active: np.ndarray,
                 soft: set[int]) -> tuple[list[int], list[int], list[float]]:
        """The edges that ``reach`` keeps and no active obstacle blocks, by the node they
        leave: node i's go to ``heads[bounds[i]:bounds[i + 1]]``, with those lengths.
        Reach is symmetric but for the start's row and the goal's column, so each pair of
        nodes is tested once; an edge into the start or out of the goal is never
        searched."""
        first, second = np.nonzero(np.triu(reach | reach.T, 1))
        along = nodes[second] - nodes[first]
        lengths = np.hypot(along.real, along.imag)
        # Segments at the start or the goal are flown from the start or to the goal.
        outward = first == 1
        starts = np.where(outward, nodes[second], nodes[first])
        stops = np.where(outward, nodes[first], nodes[second])
        hit, polygon = self._crossings(starts, stops, active)
        blocking = self._blocking(hit, polygon, starts, stops, first <= 1, active, soft)
        clear = np.ones(len(first), dtype=bool)
        clear[hit[blocking]] = False
        first, second, lengths = first[clear], second[clear], lengths[clear]
        forward, backward = reach[first, second], reach[second, first]
        tails = np.concatenate([first[forward], second[backward]])
        heads = np.concatenate([second[forward], first[backward]])
        lengths = np.concatenate([lengths[forward], lengths[backward]])
        order = np.argsort(tails, kind="stable")
        bounds = np.searchsorted(tails[order], np.arange(len(nodes) + 1)).tolist()
        return bounds, heads[order].tolist(), lengths[order].tolist()

    def _crossings(self, start: np.ndarray, stop: np.ndarray, active: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
        """The (segment from ``start`` to ``stop``, active obstacle) pairs whose segment
        meets the obstacle's inflated polygon, as shapely's ``intersects`` says (points are
        complex, north + i east). A segment nearer the polygon's centre than the disk it
        holds meets it, one farther than the disk that holds it misses it, each by more
        than ``_SURE`` (far above the rounding of these distances); only the segments in
        between are asked of shapely."""
        along = stop - start
        squared = along.real ** 2 + along.imag ** 2
        offset = self._centres.view(np.complex128)[active, 0][None, :] - start[:, None]
        share = np.clip(np.divide((offset * along.conj()[:, None]).real, squared[:, None],
                                  out=np.zeros(offset.shape), where=squared[:, None] > 0),
                        0.0, 1.0)
        distance = np.abs(offset - share * along[:, None])
        meets = distance < self._inner[active] - _SURE
        segment, polygon = np.nonzero(~meets & (distance <= self._outer[active] + _SURE))
        if len(segment):
            # A polygon whose corners all lie on one side of the segment's line, or all
            # before its start or all past its end, misses it.
            apart = self._apart(start[segment], along[segment], active[polygon])
            segment, polygon = segment[~apart], polygon[~apart]
        if len(segment):
            asked = shapely.intersects(_segments(start[segment], stop[segment]),
                                       self.inflated[active[polygon]])
            meets[segment[asked], polygon[asked]] = True
        hit, polygon = np.nonzero(meets)
        return hit, polygon

    def _apart(self, start: np.ndarray, along: np.ndarray, obstacles: np.ndarray
               ) -> np.ndarray:
        """For each segment (``start`` + ``along``, complex) and obstacle, whether a line
        through the segment or square to it at an end has every corner of the obstacle's
        inflated polygon on its far side by more than ``_SURE``: then the segment misses
        the polygon."""
        length = np.abs(along)
        usable = length > _SURE  # tinier ones are left to shapely
        # Corners in the segment's frame: real, along it from its start; imaginary, aside.
        turned = (self._corners.view(np.complex128)[obstacles, :, 0] - start[:, None]) \
            * (along / np.where(usable, length, 1.0)).conj()[:, None]
        apart: np.ndarray = usable & (
            (turned.imag.min(axis=1) > _SURE) | (turned.imag.max(axis=1) < -_SURE)
            | (turned.real.max(axis=1) < -_SURE) | (turned.real.min(axis=1) > length + _SURE))
        return apart

    def _blocking(self, hit: np.ndarray, polygon: np.ndarray, starts: np.ndarray,
                  stops: np.ndarray, at_end: np.ndarray, active: np.ndarray,
                  soft: set[int]) -> np.ndarray:
        """Which (segment, polygon) hits block: all, except hits of a soft obstacle's
        polygon by an edge from the start or to the goal that keeps its true clearance."""
        blocking = np.ones(len(hit), dtype=bool)
        if not soft:
            return blocking
        indices = active[polygon]
        check = at_end[hit] & np.isin(indices, list(soft))
        if check.any():
            segments = _segments(starts[hit[check]], stops[hit[check]])
            gap = shapely.distance(self.cores[indices[check]], segments) \
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
        geometries = [Point(a[0], a[1]) if math.dist(a[:2], b[:2]) < 1e-9
                      else LineString([a[:2], b[:2]]) for a, b in pieces]
        distances = self._surface(geometries, [min(a[2], b[2]) for a, b in pieces],
                                  [max(a[2], b[2]) for a, b in pieces])[1]
        return float(np.min(distances))

    def nearest(self, point: Point3) -> tuple[float, str]:
        """Distance from a point to the nearest obstacle's surface, and that obstacle's name
        (of equally near ones, the first)."""
        if not self.obstacles:
            return math.inf, ""
        indices, distances = self._surface([Point(point[0], point[1])], [point[2]],
                                           [point[2]])
        least = float(np.min(distances))
        return least, self.obstacles[int(np.min(indices[distances == least]))].name

    def _surface(self, geometries: list[Point | LineString], low: list[float],
                 high: list[float]) -> tuple[np.ndarray, np.ndarray]:
        """Some obstacles and their surface distances to the geometries, each flown between
        its altitudes ``low`` and ``high``, the nearest to any among them. The obstacles
        nearest over the ground give a bound; only obstacles whose footprint core lies
        within the bound plus the largest radius of a geometry can be nearer, and only
        those are measured, all in one call for all the geometries."""
        shapes = np.empty(len(geometries), dtype=object)
        shapes[:] = geometries
        lows, highs = np.array(low), np.array(high)
        piece, found = self._core_tree.query_nearest(shapes)
        bound = float(np.min(self._distances(found, shapes[piece], lows[piece],
                                             highs[piece])))
        if math.isfinite(bound):
            piece, found = self._core_tree.query(shapes, predicate="dwithin",
                                                 distance=bound + self._widest + 1e-6)
        else:
            piece, found = np.divmod(np.arange(len(shapes) * len(self.obstacles)),
                                     len(self.obstacles))
        return found, self._distances(found, shapes[piece], lows[piece], highs[piece])

    def _distances(self, indices: np.ndarray, geometries: np.ndarray, low: np.ndarray,
                   high: np.ndarray) -> np.ndarray:
        flat = np.maximum(shapely.distance(self.cores[indices], geometries)
                          - self.radii[indices], 0.0)
        gap = np.maximum(np.maximum(self.bottoms[indices] - high, low - self.tops[indices]),
                         0.0)
        distances: np.ndarray = np.hypot(flat, gap)
        return distances


def _complex(points: np.ndarray) -> np.ndarray:
    """Points (rows of north, east) as complex numbers north + i east."""
    values: np.ndarray = np.ascontiguousarray(points, dtype=float).view(np.complex128)[:, 0]
    return values


def _segments(start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """Shapely line strings from ``start`` to ``stop`` (complex)."""
    return np.asarray(shapely.linestrings(
        np.stack([start, stop], axis=1).view(float).reshape(-1, 2, 2)))


def _unique_points(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``np.unique(points, return_index=True, return_counts=True)`` for points (complex):
    the points in order (north, then east), the first index of each, how many of each."""
    order = np.lexsort((points.imag, points.real))
    ordered = points[order]
    repeated = ordered[1:] == ordered[:-1]
    if not repeated.any():
        return ordered, order, np.ones(len(points), dtype=int)
    starts = np.flatnonzero(np.concatenate([[True], ~repeated]))
    return ordered[starts], order[starts], np.diff(np.append(starts, len(points)))


def _tangents(nodes: np.ndarray, before: np.ndarray, after: np.ndarray,
              shared: np.ndarray) -> np.ndarray:
    """Which edges (row: from, column: to) a shortest path may take: a shortest path bends
    only around the polygon of the vertex it bends at, so its edges touch the polygons at
    both ends without cutting in (both neighbours of a vertex on one side of the edge).
    Edges from the start, to the goal and at vertices shared by two polygons are always
    kept (an end may lie inside a polygon it keeps the clearance of: see ``soft``).
    Points are complex (north + i east)."""
    direction = nodes[None, :] - nodes[:, None]  # [i, j]: from node i to node j
    # A neighbour within a few margins of the edge's line counts as on it: nodes stand a
    # margin off the polygons, so an edge may cut that band, and the path over every
    # visible edge does.
    scale = 4 * MARGIN * np.hypot(direction.real, direction.imag) + 1e-9

    def side(offset: np.ndarray) -> np.ndarray:
        product: np.ndarray = direction.real * offset.imag[None, :] \
            - direction.imag * offset.real[None, :]
        return product

    # At the far end j, its neighbours seen along i -> j. At the near end the edge is seen
    # the other way, which turns both signs: tangent at i along i -> j is tangent at i
    # as the far end of j -> i, the transpose, to the bit.
    first, second = side(before - nodes), side(after - nodes)
    far = ~((np.minimum(first, second) < -scale) & (np.maximum(first, second) > scale))
    either = far | shared[None, :]
    reach: np.ndarray = either & either.T
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
