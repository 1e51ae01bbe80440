"""The navigation grid: obstacles inflated by the robot's radius, plus a clearance cost.

A planner that treats the robot as a point needs the obstacles grown by the
robot's radius (the configuration space).  Growing them by exactly the
circumscribed radius lets the robot graze walls, so each free cell also costs
more the closer it is to an obstacle: A* then keeps to the middle of 1 m doors
and 2 m corridors, where small tracking errors do no harm.

Conventions are those of :class:`blocks.maps.mapio.OccupancyMap`: cells are
indexed ``[row, col]`` with row 0 at the lowest y, and ``origin`` is the world
position of cell ``[0, 0]``'s lower-left corner.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage

__all__ = ["NavGrid", "cells_near", "inflate", "inflate_occupied", "unblock_traversed"]

#: Radius (m) of the circle around the ATRV-Mini's 0.5 x 0.5 m body (0.354), rounded up.
DEFAULT_RADIUS = 0.36


@dataclass
class NavGrid:
    """A planning grid in the world frame.

    Attributes
    ----------
    blocked
        (H, W) bool: cells the robot's centre must not enter (obstacles grown by
        ``radius``; unknown cells too unless they were allowed at a cost).
    clearance
        (H, W) float: distance (m) from the cell centre to the nearest obstacle's
        surface; 0 inside obstacles.
    cost
        (H, W) float32: cost of entering a cell, >= 1, ``inf`` where blocked.
    resolution
        Cell size (m).
    origin
        World (x, y) of cell ``[0, 0]``'s lower-left corner.
    radius
        The inflation radius used (m).
    safe_clearance
        Clearance (m) beyond which a cell costs nothing extra; the shortcutter
        never trades clearance below this for a shorter path.
    """

    blocked: np.ndarray
    clearance: np.ndarray
    cost: np.ndarray
    resolution: float
    origin: tuple[float, float]
    radius: float = DEFAULT_RADIUS
    safe_clearance: float = 0.9

    def __post_init__(self) -> None:
        # 8-connected components of the free space: lets the planner snap a blocked
        # goal to a free cell it can actually reach, instead of the nearest one behind a wall.
        self.labels, _ = ndimage.label(~self.blocked, structure=np.ones((3, 3), dtype=bool))
        # Clearance with blocked cells at -1, flat: one lookup answers "blocked?" and "how clear?".
        self._free_clearance = np.where(self.blocked, -1.0, self.clearance).ravel()

    def coarse_cost(self, factor: int) -> np.ndarray:
        """The cost grid min-pooled over ``factor`` x ``factor`` blocks (cached).

        Optimistic on purpose: a coarse cell is passable if any of its cells
        is, so a route found on it exists on the fine grid unless a passage is
        narrower than it looks, which the fine search in the route's band then
        finds out (and the planner falls back to a full search).
        """
        cache = self.__dict__.setdefault("_coarse", {})
        if factor not in cache:
            h, w = self.shape
            hp, wp = -(-h // factor) * factor, -(-w // factor) * factor
            padded = np.full((hp, wp), np.inf, dtype=np.float32)
            padded[:h, :w] = self.cost
            cache[factor] = np.ascontiguousarray(
                padded.reshape(hp // factor, factor, wp // factor, factor).min(axis=(1, 3)))
        return cache[factor]

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W): rows (y) and columns (x)."""
        return self.blocked.shape  # type: ignore[return-value]

    # ---- world <-> cell -------------------------------------------------------------------
    def world_to_cell(self, x: float, y: float) -> tuple[int, int]:
        """The (row, col) of the cell holding world point (x, y); may lie outside the grid."""
        return (int(math.floor((y - self.origin[1]) / self.resolution)),
                int(math.floor((x - self.origin[0]) / self.resolution)))

    def cells_of(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows and columns of (N, 2) world points (vectorised :meth:`world_to_cell`)."""
        xy = np.asarray(xy, dtype=np.float64)
        rows = np.floor((xy[..., 1] - self.origin[1]) / self.resolution).astype(np.int64)
        cols = np.floor((xy[..., 0] - self.origin[0]) / self.resolution).astype(np.int64)
        return rows, cols

    def cell_to_world(self, rows: Any, cols: Any) -> np.ndarray:
        """World (x, y) of cell centres: shape (..., 2)."""
        rows, cols = np.asarray(rows, dtype=np.float64), np.asarray(cols, dtype=np.float64)
        return np.stack([self.origin[0] + (cols + 0.5) * self.resolution,
                         self.origin[1] + (rows + 0.5) * self.resolution], axis=-1)

    def inside(self, row: int, col: int) -> bool:
        """Whether (row, col) is on the grid."""
        h, w = self.shape
        return 0 <= row < h and 0 <= col < w

    def is_free(self, x: float, y: float) -> bool:
        """Whether the robot's centre may be at world (x, y)."""
        r, c = self.world_to_cell(x, y)
        return self.inside(r, c) and not self.blocked[r, c]

    def clearance_at(self, x: float, y: float) -> float:
        """Distance (m) from (x, y)'s cell to the nearest obstacle; 0 off the grid."""
        r, c = self.world_to_cell(x, y)
        return float(self.clearance[r, c]) if self.inside(r, c) else 0.0

    # ---- queries the planner and the follower need ----------------------------------------
    def free_cell_at(self, x: float, y: float, max_distance: float) -> tuple[int, int] | None:
        """The cell of world (x, y) if free, else the nearest free cell within
        ``max_distance`` metres (a robot whose map drew a wall into its own cell)."""
        row, col = self.world_to_cell(x, y)
        if self.inside(row, col) and not self.blocked[row, col]:
            return row, col
        return self.nearest_free(row, col, max_distance)

    def nearest_free(self, row: int, col: int, max_distance: float,
                     label: int | None = None) -> tuple[int, int] | None:
        """The free cell nearest to (row, col) within ``max_distance`` metres.

        Parameters
        ----------
        label
            Only cells of this free-space component (see :attr:`labels`) count,
            so a goal near a wall snaps to the side the robot can reach.

        Returns
        -------
        (row, col) or None
            Ties go to the cell with more clearance.
        """
        h, w = self.shape
        k = int(math.ceil(max_distance / self.resolution))
        r0, r1 = max(0, row - k), min(h, row + k + 1)
        c0, c1 = max(0, col - k), min(w, col + k + 1)
        if r0 >= r1 or c0 >= c1:
            return None
        ok = ~self.blocked[r0:r1, c0:c1]
        if label is not None:
            ok &= self.labels[r0:r1, c0:c1] == label
        rr, cc = np.nonzero(ok)
        if rr.size == 0:
            return None
        d2 = (rr + r0 - row) ** 2 + (cc + c0 - col) ** 2
        within = d2 <= k * k
        if not within.any():
            return None
        rr, cc, d2 = rr[within], cc[within], d2[within]
        best = np.lexsort((-self.clearance[rr + r0, cc + c0], d2))[0]
        return int(rr[best] + r0), int(cc[best] + c0)

    def travel_distances(self, row: int, col: int) -> np.ndarray:
        """(H, W) the length (m) of the shortest 8-connected way over free cells from
        (row, col) to each cell; ``inf`` where none is (blocked, or another component).

        Why: what a goal costs the robot is the way there, not the straight line.
        Beside a wall the next room's floor is near as the crow flies and far by
        the door.  One Dijkstra pass (``scipy.sparse.csgraph``) from the robot
        answers for every goal at once, where an A* per goal would not.

        Examples
        --------
        >>> blocked = np.zeros((3, 5), dtype=bool); blocked[:2, 2] = True  # a wall, open at the top
        >>> grid = NavGrid(blocked, np.ones((3, 5)), np.ones((3, 5), np.float32), 1.0, (0.0, 0.0))
        >>> grid.travel_distances(0, 1)[0, 3].round(2)  # round the wall's end: up, over, down
        np.float64(4.83)
        """
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import dijkstra

        h, w = self.shape
        out = np.full((h, w), np.inf)
        if not self.inside(row, col) or self.blocked[row, col]:
            return out
        mine = self.labels == self.labels[row, col]
        index = np.full((h, w), -1, dtype=np.int64)
        rows, cols = np.nonzero(mine)
        index[rows, cols] = np.arange(len(rows))
        heads, tails, lengths = [], [], []
        for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):  # each neighbour pair once
            a = index[max(0, -dr):h - max(0, dr), max(0, -dc):w - max(0, dc)]
            b = index[max(0, dr):h - max(0, -dr), max(0, dc):w - max(0, -dc)]
            both = (a >= 0) & (b >= 0)
            heads.append(a[both])
            tails.append(b[both])
            lengths.append(np.full(int(both.sum()), math.hypot(dr, dc) * self.resolution))
        n = len(rows)
        graph = coo_matrix((np.concatenate(lengths), (np.concatenate(heads),
                                                      np.concatenate(tails))), shape=(n, n))
        out[rows, cols] = dijkstra(graph.tocsr(), directed=False, indices=int(index[row, col]))
        return out

    def segment_clearance(self, p: np.ndarray, q: np.ndarray) -> float:
        """The least clearance (m) along the straight segment p -> q; 0 if it leaves the grid
        or crosses a blocked cell.  Sampled every half cell, so no cell is skipped.

        The planner's shortcutter calls this hundreds of times per plan, so it
        works on flat arrays with as few numpy calls as possible.
        """
        h, w = self.shape
        res = self.resolution
        ox, oy = self.origin
        px, py, qx, qy = float(p[0]), float(p[1]), float(q[0]), float(q[1])
        # The grid is a rectangle, hence convex: both ends inside means the whole segment is.
        for x, y in ((px, py), (qx, qy)):
            if not (ox <= x < ox + w * res and oy <= y < oy + h * res):
                return 0.0
        n = int(math.hypot(qx - px, qy - py) / (0.5 * res)) + 2
        t = np.arange(n) * (1.0 / (n - 1))
        cols = ((px - ox + t * (qx - px)) * (1.0 / res)).astype(np.int64)
        rows = ((py - oy + t * (qy - py)) * (1.0 / res)).astype(np.int64)
        np.minimum(cols, w - 1, out=cols)  # a point on the far edge rounds to the last cell
        np.minimum(rows, h - 1, out=rows)
        least = float(self._free_clearance.take(rows * w + cols).min())
        return max(least, 0.0)

    def segment_free(self, p: np.ndarray, q: np.ndarray) -> bool:
        """Whether the robot's centre can move along p -> q without entering a blocked cell."""
        return self.segment_clearance(p, q) > 0.0


def distance_to_obstacles(free: np.ndarray) -> np.ndarray:
    """``scipy.ndimage.distance_transform_edt(free)`` (float64), about three times sooner.

    Why it is the same: the distance between two cell centres is the square
    root of a whole number of cells squared, and scipy takes the (correctly
    rounded) float64 root of that number.  OpenCV's exact transform
    (Felzenszwalb and Huttenlocher) finds the same number of cells squared and
    returns its float32 root; for numbers below ``2**20`` (grids whose
    diagonal is under 1,024 cells: the squared sums are whole float32 numbers,
    and squaring the root is off by at most ``2**20 * 2**-23`` = 1/8, well
    inside 1/2 even if OpenCV's root is a few ulps off), rounding its square
    and taking the float64 root gives scipy's value.  Larger grids, and grids
    without an obstacle, go to scipy.

    Examples
    --------
    >>> distance_to_obstacles(np.array([[True, True, False], [True, True, True]]))
    array([[2.        , 1.        , 0.        ],
           [2.23606798, 1.41421356, 1.        ]])
    """
    import cv2

    free = np.asarray(free, dtype=bool)
    h, w = free.shape
    if h * h + w * w >= 2 ** 20 or free.all():
        return ndimage.distance_transform_edt(free)
    root = cv2.distanceTransform(free.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    squared = root.astype(np.float64)
    np.multiply(squared, squared, out=squared)
    return np.sqrt(np.rint(squared, out=squared), out=squared)


def inflate_occupied(obstacle: np.ndarray, resolution: float, origin: tuple[float, ...], *,
                     radius: float = DEFAULT_RADIUS, safe_clearance: float = 0.9,
                     clearance_weight: float = 4.0,
                     extra_cost: np.ndarray | None = None) -> NavGrid:
    """A :class:`NavGrid` from a boolean obstacle grid (row 0 = lowest y).

    Parameters
    ----------
    obstacle
        (H, W) bool, True where the robot may not overlap.  The grid's border
        counts as an obstacle too, so nothing is planned off the map.
    radius
        Inflation radius (m): the circumscribed radius of the robot, so it can
        turn in place anywhere it may stand.
    safe_clearance
        Clearance (m) from which cells cost nothing extra (0.9 m puts the
        cheapest line down the middle of a 2 m corridor).
    clearance_weight
        Extra cost of a cell right at ``radius`` from an obstacle; it falls
        quadratically to 0 at ``safe_clearance``.
    extra_cost
        Optional (H, W) non-negative cost added per cell (e.g. for unknown cells).
    """
    obstacle = np.asarray(obstacle, dtype=bool)
    if obstacle.ndim != 2 or obstacle.size == 0:
        raise ValueError(f"the obstacle grid must be a non-empty 2-D array, got {obstacle.shape}")
    if not resolution > 0:
        raise ValueError(f"resolution must be > 0, got {resolution!r}")
    padded = np.pad(~obstacle, 1, constant_values=False)
    # Distance between cell centres, minus half a cell: the distance to the obstacle
    # cell's edge, i.e. to the wall surface as rasterised.
    centre = distance_to_obstacles(padded)[1:-1, 1:-1]
    clearance = np.clip(centre - 0.5, 0.0, None) * resolution
    blocked = obstacle | (clearance < radius)
    span = max(safe_clearance - radius, resolution)
    closeness = np.clip((safe_clearance - clearance) / span, 0.0, 1.0)
    cost = 1.0 + clearance_weight * closeness ** 2
    if extra_cost is not None:
        cost = cost + np.asarray(extra_cost, dtype=np.float64)
    cost = cost.astype(np.float32)
    cost[blocked] = np.inf
    return NavGrid(blocked=blocked, clearance=clearance.astype(np.float32), cost=cost,
                   resolution=float(resolution), origin=(float(origin[0]), float(origin[1])),
                   radius=float(radius), safe_clearance=float(safe_clearance))


def inflate(occupancy_map: Any, *, radius: float = DEFAULT_RADIUS, unknown: str = "blocked",
            unknown_cost: float = 4.0, safe_clearance: float = 0.9,
            clearance_weight: float = 4.0) -> NavGrid:
    """A :class:`NavGrid` from an :class:`~blocks.maps.mapio.OccupancyMap`.

    Parameters
    ----------
    occupancy_map
        The map (its trinary classes are used: occupied, free, unknown).
    unknown
        ``"blocked"`` (default): unknown cells are obstacles, so the robot
        only drives where the map has seen free floor.  ``"cost"``: unknown
        cells may be crossed at ``unknown_cost`` extra per cell, for driving
        into rooms the map has only glimpsed.
    """
    if unknown not in ("blocked", "cost"):
        raise ValueError(f"unknown must be 'blocked' or 'cost', got {unknown!r}")
    occupied, _, unknown_mask = occupancy_map.classes()
    if unknown == "blocked":
        obstacle, extra = occupied | unknown_mask, None
    else:
        obstacle, extra = occupied, np.where(unknown_mask, float(unknown_cost), 0.0)
    return inflate_occupied(obstacle, occupancy_map.resolution, occupancy_map.origin,
                            radius=radius, safe_clearance=safe_clearance,
                            clearance_weight=clearance_weight, extra_cost=extra)


def cells_near(points: np.ndarray, radius: float, shape: tuple[int, int], resolution: float,
               origin: tuple[float, ...]) -> np.ndarray:
    """(H, W) bool: the cells whose offset from the cell of some point is within ``radius``.

    Grid conventions as :class:`NavGrid` (row 0 at the lowest y, ``origin`` the
    lower-left corner of cell [0, 0]); points off the grid mark what of their
    disk lies on it.

    Examples
    --------
    >>> cells_near(np.array([[0.25, 0.25]]), 0.1, (3, 3), 0.1, (0.0, 0.0)).astype(int)
    array([[0, 0, 0],
           [0, 0, 1],
           [0, 1, 1]])
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    k = int(math.ceil(radius / resolution))
    rows = np.floor((points[:, 1] - origin[1]) / resolution).astype(np.int64)
    cols = np.floor((points[:, 0] - origin[0]) / resolution).astype(np.int64)
    h, w = shape
    mask = np.zeros((h, w), dtype=bool)
    for dr in range(-k, k + 1):
        for dc in range(-k, k + 1):
            if (dr * dr + dc * dc) * resolution ** 2 > radius * radius:
                continue
            r, c = rows + dr, cols + dc
            ok = (r >= 0) & (r < h) & (c >= 0) & (c < w)
            mask[r[ok], c[ok]] = True
    return mask


def unblock_traversed(grid: NavGrid, points: np.ndarray, *, width: float | None = None,
                      cost: float | None = None) -> NavGrid:
    """The grid with the cells the robot's centre has been on made passable.

    Why: where the robot has driven, it fits, whatever the map says.  A sonar
    map draws a door's jambs thicker than they are, the more so the more
    readings it holds, so a door the robot came in by can look closed by the
    time it wants to leave; its own track is the proof that it is open.

    Parameters
    ----------
    points
        (N, 2) world positions the robot's centre has been at (sampled
        densely enough that consecutive points are at most ``width`` apart).
    width
        Radius (m) around each point that is unblocked; default 1.5 cells.
    cost
        Cost of entering an unblocked cell that was blocked; default the
        dearest free cell's, so the planner keeps to the track only where the
        map leaves no other way.
    """
    width = 1.5 * grid.resolution if width is None else float(width)
    track = cells_near(points, width, grid.shape, grid.resolution, grid.origin)
    opened = track & grid.blocked
    if not opened.any():
        return grid
    finite = grid.cost[~grid.blocked]
    fill = float(cost) if cost is not None else float(finite.max()) if finite.size else 1.0
    new_cost = grid.cost.copy()
    new_cost[opened] = fill
    return NavGrid(blocked=grid.blocked & ~opened, clearance=grid.clearance, cost=new_cost,
                   resolution=grid.resolution, origin=grid.origin, radius=grid.radius,
                   safe_clearance=grid.safe_clearance)
