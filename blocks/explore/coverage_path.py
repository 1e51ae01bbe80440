"""A coverage path on the true floor plan: the yardstick an exploration's path is measured by.

Why: "the robot drove 400 m" says nothing until it is set beside what seeing
the whole floor takes.  This plans that on the world's own map (so it is for
scoring only, never for a decision the robot makes): the robot's centre may
go where the floor is at least ``robot_radius`` from a wall; viewpoints on a
lattice there each see the floor in clear line of sight within
``sensing_range`` (:func:`~blocks.maps.score.sight_from_cells`); a greedy set
cover (lazy, as gains only shrink) picks viewpoints until ``coverage`` of
the floor any viewpoint sees is seen; the shortest ways between them run on
the drivable floor (Dijkstra on an 8-connected grid, scipy), and their order
is Christofides' tour (networkx) made into a path from the start, improved
by 2-opt.  Both steps are approximations (greedy set cover is within a
factor ln n of the fewest viewpoints), so the path is an upper bound on the
shortest one: a ratio to it below 1 is possible, and means the exploration
was close to the best.
"""
from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from blocks.maps.score import reachable_floor, sight_from_cells

__all__ = ["CoveragePath", "coverage_path"]


@dataclass(frozen=True)
class CoveragePath:
    """A planned coverage path.

    Attributes
    ----------
    viewpoints
        (K, 2) world x, y (m) in visiting order, after the start.
    length
        Length (m) of the way from the start through every viewpoint.
    floor_area
        Reachable floor (m^2): the denominator of ``free_coverage``.
    seen_share
        Share of the reachable floor the viewpoints see.
    """

    viewpoints: np.ndarray
    length: float
    floor_area: float
    seen_share: float


def _grid_graph(mask: np.ndarray, step: float):
    """An 8-connected graph (scipy sparse) over the True cells of ``mask``, and the node of
    each cell (-1 where False)."""
    node = np.full(mask.shape, -1, dtype=np.int64)
    node[mask] = np.arange(int(mask.sum()))
    rows, cols, weights = [], [], []
    h, w = mask.shape
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = node[:h - dy, max(0, -dx):w - max(0, dx)]
        b = node[dy:, max(0, dx):w + min(0, dx)]
        both = (a >= 0) & (b >= 0)
        rows.append(a[both])
        cols.append(b[both])
        weights.append(np.full(int(both.sum()), step * math.hypot(dx, dy)))
    n = int(mask.sum())
    graph = coo_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(n, n)).tocsr()
    return graph, node


def _greedy_cover(views: list[np.ndarray], size: int, target: float) -> list[int]:
    """Indices of views whose union covers ``target`` of the cells any view covers (lazy greedy)."""
    coverable = np.zeros(size, dtype=bool)
    for v in views:
        coverable[v] = True
    goal = target * int(coverable.sum())
    covered = np.zeros(size, dtype=bool)
    heap = [(-len(v), k) for k, v in enumerate(views)]
    heapq.heapify(heap)
    chosen: list[int] = []
    count = 0
    while heap and count < goal:
        neg, k = heapq.heappop(heap)
        gain = int(np.count_nonzero(~covered[views[k]]))
        if gain == 0:
            continue
        if heap and gain < -heap[0][0]:  # stale: its gain shrank; look again later
            heapq.heappush(heap, (-gain, k))
            continue
        chosen.append(k)
        covered[views[k]] = True
        count += gain
    return chosen


def coverage_path(world, sensing_range: float = 2.0, robot_radius: float = 0.36,
                  spacing: float = 0.5, coverage: float = 0.95,
                  graph_step: float = 0.2) -> CoveragePath:
    """Plan a path from the world's start that sees ``coverage`` of its floor.

    Parameters
    ----------
    world
        A world with a floor-plan image (as :func:`~blocks.maps.score.score_map` takes).
    sensing_range
        A viewpoint sees the floor in line of sight this close (m).
    robot_radius
        The robot's centre keeps this far (m) from walls.
    spacing
        Candidate viewpoints lie on a lattice this fine (m).
    coverage
        Share of the floor that any candidate sees that the path must see.
    graph_step
        Cell size (m) of the grid the ways between viewpoints are measured on.

    Returns
    -------
    CoveragePath
    """
    truth, reachable = reachable_floor(world)
    res = float(truth.resolution)
    walls = truth.occupancy > 0.5
    clearance = ndimage.distance_transform_edt(~walls) * res
    drivable = reachable & (clearance >= robot_radius)
    # the robot's own drivable component (the start may sit nearer a wall than the radius)
    sx, sy = world.start[:2]
    six = int((sx - truth.origin[0]) / res)
    siy = int((sy - truth.origin[1]) / res)
    labels, _ = ndimage.label(drivable, structure=np.ones((3, 3), bool))
    near = np.argwhere(labels > 0)
    if len(near) == 0:
        return CoveragePath(np.zeros((0, 2)), 0.0, float(reachable.sum()) * res * res, 0.0)
    nearest = near[np.argmin(np.hypot(near[:, 0] - siy, near[:, 1] - six))]
    drivable = labels == labels[nearest[0], nearest[1]]
    # candidate viewpoints on the lattice, each with the floor cells it sees
    stride = max(1, int(round(spacing / res)))
    lattice = np.zeros_like(drivable)
    lattice[stride // 2::stride, stride // 2::stride] = True
    cand = np.argwhere(drivable & lattice)
    floor_index = np.flatnonzero(reachable.ravel())
    position = np.full(reachable.size, -1, dtype=np.int64)
    position[floor_index] = np.arange(len(floor_index))
    views = []
    for iy, ix in cand:
        seen = sight_from_cells(walls, np.array([iy]), np.array([ix]), sensing_range, res)
        views.append(position[np.flatnonzero(seen.ravel() & reachable.ravel())])
    chosen = _greedy_cover(views, len(floor_index), coverage)
    seen_all = np.zeros(len(floor_index), dtype=bool)
    for k in chosen:
        seen_all[views[k]] = True
    points = cand[chosen]
    # shortest ways on a coarser grid of the drivable floor
    factor = max(1, int(round(graph_step / res)))
    h, w = drivable.shape
    coarse = drivable[:h - h % factor, :w - w % factor].reshape(
        h // factor, factor, w // factor, factor).any(axis=(1, 3))
    graph, node = _grid_graph(coarse, res * factor)
    stops = np.vstack([[nearest[0], nearest[1]], points]) // factor
    stops = np.minimum(stops, np.array(coarse.shape) - 1)
    ids = node[stops[:, 0], stops[:, 1]]
    ok = ids >= 0
    ids, kept = ids[ok], np.flatnonzero(ok)
    dist = dijkstra(graph, directed=False, indices=ids)[:, ids]
    order = _open_tour(dist)
    length = float(sum(dist[a, b] for a, b in zip(order[:-1], order[1:])))
    visit = [kept[k] for k in order[1:]]  # kept[0] is the start
    xy = np.column_stack([truth.origin[0] + (np.vstack([[nearest], points])[visit, 1] + 0.5) * res,
                          truth.origin[1] + (np.vstack([[nearest], points])[visit, 0] + 0.5) * res])
    return CoveragePath(xy, length, float(reachable.sum()) * res * res,
                        float(seen_all.mean()) if len(seen_all) else 0.0)


def _open_tour(dist: np.ndarray) -> list[int]:
    """Node order from node 0 through all the others, ending anywhere.

    Christofides on the nodes plus a dummy joined to node 0 at no cost and to
    every other node at one large cost ``M``: every tour crosses ``M`` once,
    so the shortest tour is the shortest path from node 0 with the dummy
    closing it.  Those edges break the triangle inequality Christofides'
    bound rests on, so the path is then improved by 2-opt moves (reversing a
    stretch, the far end left free) until none shortens it.
    """
    import networkx as nx

    n = len(dist)
    if n <= 2:
        return list(range(n))
    finite = np.where(np.isfinite(dist), dist, 1e9)
    big = float(finite.sum()) + 1.0
    graph = nx.Graph()
    for a in range(n):
        for b in range(a + 1, n):
            graph.add_edge(a, b, weight=float(finite[a, b]))
        graph.add_edge(a, n, weight=0.0 if a == 0 else big)
    cycle = nx.approximation.christofides(graph)[:-1]
    k = cycle.index(n)
    cycle = cycle[k + 1:] + cycle[:k]  # the dummy removed: a path with 0 at one end
    path = cycle if cycle[0] == 0 else cycle[::-1]
    return _two_opt(path, finite)


def _two_opt(path: list[int], dist: np.ndarray) -> list[int]:
    """2-opt on an open path with a fixed first node: reverse ``path[i:j+1]`` while it helps."""
    path = list(path)
    n = len(path)
    improved = True
    while improved:
        improved = False
        for i in range(1, n - 1):
            a, b = path[i - 1], path[i]
            for j in range(i + 1, n):
                c = path[j]
                d = path[j + 1] if j + 1 < n else None
                old = dist[a, b] + (dist[c, d] if d is not None else 0.0)
                new = dist[a, c] + (dist[b, d] if d is not None else 0.0)
                if new < old - 1e-9:
                    path[i:j + 1] = path[i:j + 1][::-1]
                    improved = True
                    a, b = path[i - 1], path[i]
    return path
