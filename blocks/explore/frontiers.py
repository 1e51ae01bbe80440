"""Frontiers on an occupancy grid, and the places the robot can reach to look past them.

Why frontiers: a floor is explored when no free cell the robot can reach
borders unknown space (Yamauchi, *A frontier-based approach for autonomous
exploration*, 1997; ``explore_lite`` in ROS).  A frontier is a connected run
of such cells; going to one and looking turns unknown space into known, until
none is left.

The robot cannot stand on a frontier: unknown space is an obstacle to the
planner (a sonar map shows free floor through walls it saw at a grazing
angle, so unknown is never assumed free), and inflation keeps the robot's
centre a radius away from it.  So each frontier gets a *goal*: the cell of the
robot's own free component nearest to the frontier's middle, within ``reach``
of the frontier.  A frontier without one is out of reach for the robot's
footprint (behind a gap too narrow, or seen through a wall).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage

from blocks.navigate.grid import NavGrid

__all__ = ["Frontier", "FrontierGoal", "find_frontiers", "frontier_goals", "frontier_mask",
           "unseen_parts"]

_FOUR = ndimage.generate_binary_structure(2, 1)
_EIGHT = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class Frontier:
    """A connected run of free cells bordering unknown space.

    Attributes
    ----------
    points
        (N, 2) world (x, y) of its cells' centres.
    middle
        (x, y) of the cell nearest to the run's centroid (on the run, unlike
        the centroid of a curved frontier).
    length
        Its size (m): cells times the cell size.
    """

    points: np.ndarray
    middle: tuple[float, float]
    length: float


@dataclass(frozen=True)
class FrontierGoal:
    """Where the robot goes to look past a frontier.

    Attributes
    ----------
    frontier
        The frontier.
    goal
        (x, y) of a free cell of the robot's component within reach of it.
    distance
        Straight-line distance (m) from the robot to ``goal``.
    """

    frontier: Frontier
    goal: tuple[float, float]
    distance: float


def frontier_mask(free: np.ndarray, unknown: np.ndarray) -> np.ndarray:
    """Free cells with an unknown 4-neighbour; the grid's outside counts as unknown.

    Examples
    --------
    >>> free = np.array([[1, 1, 0], [1, 1, 0], [0, 0, 0]], dtype=bool)
    >>> unknown = np.array([[0, 0, 1], [0, 0, 0], [0, 0, 0]], dtype=bool)
    >>> frontier_mask(free, unknown).astype(int)
    array([[1, 1, 0],
           [1, 0, 0],
           [0, 0, 0]])
    """
    free, unknown = np.asarray(free, dtype=bool), np.asarray(unknown, dtype=bool)
    near_unknown = ndimage.binary_dilation(np.pad(unknown, 1, constant_values=True),
                                           structure=_FOUR)[1:-1, 1:-1]
    return free & near_unknown


def find_frontiers(occupancy_map: Any, *, min_length: float = 0.6,
                   wall_margin: float = 0.0) -> list[Frontier]:
    """The frontiers of an :class:`~blocks.maps.mapio.OccupancyMap`, longest first.

    Parameters
    ----------
    occupancy_map
        The robot's map (its map_server classes are used).
    min_length
        Shorter runs (m) are noise (the ragged edge of one sonar cone) and dropped.
    wall_margin
        Unknown cells this close (m) to an occupied cell are part of the wall
        for this purpose: a sonar map's walls have a ragged rim of cells it is
        unsure of, and free floor along it is no way into anything.
    """
    occupied, free, unknown = occupancy_map.classes()
    k = int(math.ceil(wall_margin / float(occupancy_map.resolution)))
    if k > 0 and occupied.any():
        rim = ndimage.binary_dilation(occupied, structure=_EIGHT, iterations=k)
        unknown = unknown & ~rim
    mask = frontier_mask(free, unknown)
    labels, count = ndimage.label(mask, structure=_EIGHT)
    if count == 0:
        return []
    res = float(occupancy_map.resolution)
    ox, oy = float(occupancy_map.origin[0]), float(occupancy_map.origin[1])
    rows, cols = np.nonzero(labels)
    ids = labels[rows, cols] - 1
    order = np.argsort(ids, kind="stable")
    rows, cols, ids = rows[order], cols[order], ids[order]
    starts = np.searchsorted(ids, np.arange(count + 1))
    frontiers = []
    for k in range(count):
        r, c = rows[starts[k]:starts[k + 1]], cols[starts[k]:starts[k + 1]]
        length = len(r) * res
        if length < min_length:
            continue
        points = np.column_stack([ox + (c + 0.5) * res, oy + (r + 0.5) * res])
        frontiers.append(Frontier(points, _middle(points), length))
    frontiers.sort(key=lambda f: -f.length)
    return frontiers


def frontier_goals(grid: NavGrid, frontiers: Sequence[Frontier], start: Sequence[float], *,
                   reach: float = 1.0, snap_radius: float = 0.5,
                   walls: np.ndarray | None = None) -> list[FrontierGoal]:
    """A goal for each frontier the robot can reach, nearest goal first.

    Parameters
    ----------
    grid
        The planning grid of the same map (unknown cells blocked).
    start
        The robot's (x, y); if its cell is blocked (close to a wall), the
        nearest free cell within ``snap_radius`` stands for it.
    reach
        A goal is at most this far (m) from a cell of its frontier: the
        robot's sonar sees well past that.
    walls
        (H, W) bool occupied cells of the map, on the grid's cells: a goal
        must see the frontier cell it is nearest to past none of them.  A
        sonar beam that meets a wall at a grazing angle returns no echo and
        marks free floor beyond it, so a frontier runs along the building's
        outside, a wall's thickness from goals inside; going there shows
        nothing.  None: no such test.
    """
    if not frontiers:
        return []
    r, c = grid.world_to_cell(float(start[0]), float(start[1]))
    if not grid.inside(r, c):
        return []
    if grid.blocked[r, c]:
        cell = grid.nearest_free(r, c, snap_radius)
        if cell is None:
            return []
        r, c = cell
    component = grid.labels == grid.labels[r, c]
    # Every frontier cell drawn on the grid with its frontier's number.
    ids = np.zeros(grid.shape, dtype=np.int32)
    for k, frontier in enumerate(frontiers, start=1):
        fr, fc = grid.cells_of(frontier.points)
        ok = (fr >= 0) & (fr < grid.shape[0]) & (fc >= 0) & (fc < grid.shape[1])
        ids[fr[ok], fc[ok]] = k
    distance, (near_r, near_c) = ndimage.distance_transform_edt(ids == 0, return_indices=True)
    candidate = component & (distance * grid.resolution <= reach)
    cr, cc = np.nonzero(candidate)
    if walls is not None and len(cr):
        seen = _in_sight(np.asarray(walls, dtype=bool), cr, cc, near_r[cr, cc], near_c[cr, cc])
        cr, cc = cr[seen], cc[seen]
    if len(cr) == 0:
        return []
    owner = ids[near_r[cr, cc], near_c[cr, cc]]
    xy = grid.cell_to_world(cr, cc)
    middles = np.array([f.middle for f in frontiers])
    to_middle = np.hypot(*(xy - middles[owner - 1]).T)
    here = grid.cell_to_world(r, c)
    goals = []
    order = np.lexsort((to_middle, owner))
    first = order[np.r_[True, owner[order][1:] != owner[order][:-1]]]
    for i in first:
        goal = (float(xy[i, 0]), float(xy[i, 1]))
        goals.append(FrontierGoal(frontiers[owner[i] - 1], goal,
                                  float(np.hypot(goal[0] - here[0], goal[1] - here[1]))))
    goals.sort(key=lambda g: g.distance)
    return goals


def _in_sight(walls: np.ndarray, r0: np.ndarray, c0: np.ndarray, r1: np.ndarray,
              c1: np.ndarray) -> np.ndarray:
    """Whether the straight line from each cell (r0, c0) to (r1, c1) crosses no wall cell
    (sampled every half cell, a corner clipped diagonally included)."""
    span = float(np.max(np.hypot(r1 - r0, c1 - c0), initial=0.0))
    t = np.linspace(0.0, 1.0, int(math.ceil(2 * span)) + 2)[:, None]
    rows = np.floor(r0 + 0.5 + t * (r1 - r0)).astype(np.int64)
    cols = np.floor(c0 + 0.5 + t * (c1 - c0)).astype(np.int64)
    return ~walls[rows, cols].any(axis=0)


def _middle(points: np.ndarray) -> tuple[float, float]:
    """The point nearest the centroid: on the run, unlike the centroid of a curved one."""
    middle = points[int(np.argmin(np.hypot(*(points - points.mean(axis=0)).T)))]
    return float(middle[0]), float(middle[1])


def unseen_parts(frontier: Frontier, places: Sequence[Sequence[float]], radius: float,
                 min_length: float, resolution: float) -> list[Frontier]:
    """The pieces of ``frontier`` farther than ``radius`` (m) from every one of ``places``.

    Why: a robot that went to a frontier and found it still there has looked
    at it from there; a long frontier (a corridor's open end seen along its
    side) is only looked at near that place, and the rest is still worth a
    visit. Each connected piece at least ``min_length`` (m) long is a
    frontier of its own; ``resolution`` is the map's cell size (m).

    Examples
    --------
    >>> f = Frontier(np.array([[x, 0.0] for x in np.arange(0.05, 9.0, 0.1)]), (4.45, 0.0), 9.0)
    >>> [round(p.length, 1) for p in unseen_parts(f, [(4.5, 0.5)], 2.0, 0.8, 0.1)]
    [2.6, 2.6]
    >>> unseen_parts(f, [(4.5, 0.5)], 6.0, 0.8, 0.1)
    []
    """
    xy = np.asarray(places, dtype=np.float64).reshape(-1, 2)
    points = frontier.points
    if len(xy):
        gap = np.hypot(points[:, None, 0] - xy[None, :, 0],
                       points[:, None, 1] - xy[None, :, 1]).min(axis=1)
        points = points[gap > radius]
    if len(points) * resolution < min_length:
        return []
    cells = np.floor(points / resolution).astype(np.int64)
    lo = cells.min(axis=0)
    raster = np.zeros(tuple(cells.max(axis=0) - lo + 1), dtype=bool)
    raster[tuple((cells - lo).T)] = True
    labels, _ = ndimage.label(raster, structure=_EIGHT)
    piece = labels[tuple((cells - lo).T)]
    parts = []
    for k in np.unique(piece):
        run = points[piece == k]
        if len(run) * resolution < min_length:
            continue
        parts.append(Frontier(run, _middle(run), len(run) * resolution))
    return parts
