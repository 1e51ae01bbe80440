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

__all__ = ["Frontier", "FrontierGoal", "find_frontiers", "frontier_goals", "frontier_mask"]

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
        centroid = points.mean(axis=0)
        middle = points[int(np.argmin(np.hypot(*(points - centroid).T)))]
        frontiers.append(Frontier(points, (float(middle[0]), float(middle[1])), length))
    frontiers.sort(key=lambda f: -f.length)
    return frontiers


def frontier_goals(grid: NavGrid, frontiers: Sequence[Frontier], start: Sequence[float], *,
                   reach: float = 1.0, snap_radius: float = 0.5) -> list[FrontierGoal]:
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
