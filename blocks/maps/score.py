"""Scoring a map against the world's ground truth.

A map is compared with the floor plan it was built in, in the world frame, by
world coordinates: the map and the world may differ in resolution, origin and
extent.  Every cell is represented by its centre and looked up in the other
grid's cell that contains it (nearest cell).

Definitions
-----------
Ground truth is the world's occupancy grid (``world.occupied``, image order,
flipped here to y-up); every non-wall pixel counts as floor.

reachable free cells
    True free cells 8-connected to the cell of the world's start pose: the
    part of the floor the robot could ever see.  Floor sealed off from the
    start (inside pillars, outside the building) cannot be mapped and is left
    out.
facing wall cells
    True wall cells that are 8-neighbours of reachable free cells: the wall
    surfaces a sensor can hit.  The inside of thick walls is left out.
precision
    Share of the map's occupied cells whose centre lies within ``tolerance``
    of a true wall cell's centre (Euclidean distance transform of the true
    wall mask, in metres).  The distance transform is padded by the tolerance
    around the world's extent, so a map cell outside the world counts as near
    a wall only if it is within ``tolerance`` of a wall cell on the border.
recall
    Share of facing wall cells that have a map occupied cell within
    ``tolerance`` (distance transform of the map's occupied mask, padded the
    same way, sampled at the wall cells' centres).
f1
    Harmonic mean of precision and recall; 0 when both are 0.
free_coverage
    Share of reachable free cells whose centre falls in a map cell marked free.
false_free
    Share of facing wall cells whose centre falls in a map cell marked free:
    walls the map claims one can drive through (the dangerous error).

A share of an empty set is reported as 0.0 (for example the precision of a
map with no occupied cells), so the numbers are always finite JSON numbers.
Cells are classified with map_server's trinary rule (see
:meth:`blocks.maps.mapio.OccupancyMap.classes`).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from blocks.core.errors import SemmapError

from .mapio import OccupancyMap, occupancy_map_from_world

if TYPE_CHECKING:
    from sim2d.world import World

__all__ = ["METRIC_KEYS", "score_map"]

#: The keys of :func:`score_map`'s result, in order (stable: scripts and JSON rely on them).
METRIC_KEYS = ("precision", "recall", "f1", "free_coverage", "false_free",
               "map_occupied_cells", "map_free_cells", "facing_wall_cells",
               "reachable_free_cells", "tolerance_m", "map_resolution_m",
               "world_resolution_m")

_EIGHT = np.ones((3, 3), dtype=bool)


def _cell_index(x: np.ndarray, y: np.ndarray, origin: tuple[float, float, float],
                resolution: float, shape: tuple[int, int]
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row/column of the cell containing each point, and whether it is inside the grid.

    Rows count up from the lowest y.  Outside points get index 0 (mask them out).
    """
    ix = np.floor((np.asarray(x) - origin[0]) / resolution).astype(np.int64)
    iy = np.floor((np.asarray(y) - origin[1]) / resolution).astype(np.int64)
    inside = (ix >= 0) & (ix < shape[1]) & (iy >= 0) & (iy < shape[0])
    return np.where(inside, iy, 0), np.where(inside, ix, 0), inside


def _padded_distance(mask: np.ndarray, resolution: float, origin: tuple[float, float, float],
                     pad_m: float) -> tuple[np.ndarray, tuple[float, float, float]]:
    """Distance (m) from each cell centre to the nearest True cell centre, on a grid padded
    by ``pad_m`` so points just outside the grid still see nearby cells.

    Returns the distance grid and the padded grid's origin.  With no True cell
    every distance is infinite.
    """
    pad = math.ceil(pad_m / resolution) + 1
    padded = np.pad(mask, pad, constant_values=False)
    if not padded.any():
        dist = np.full(padded.shape, np.inf)
    else:
        dist = ndimage.distance_transform_edt(~padded, sampling=resolution)
    return dist, (origin[0] - pad * resolution, origin[1] - pad * resolution, 0.0)


def _share(part: int, whole: int) -> float:
    return float(part) / whole if whole else 0.0


def _centres(mask: np.ndarray, resolution: float,
             origin: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """World coordinates of the centres of a mask's True cells (row 0 = lowest y)."""
    iy, ix = np.nonzero(mask)
    return origin[0] + (ix + 0.5) * resolution, origin[1] + (iy + 0.5) * resolution


def _ground_truth(world: World) -> tuple[OccupancyMap, np.ndarray, np.ndarray]:
    """The world's wall grid (y-up), its reachable free cells and its facing wall cells."""
    truth = occupancy_map_from_world(world)  # checks for an image and yaw 0
    walls = truth.occupancy > 0.5
    sx, sy = world.start[:2]
    iy, ix, inside = _cell_index(np.array([sx]), np.array([sy]), truth.origin,
                                 truth.resolution, walls.shape)
    if not inside[0] or walls[iy[0], ix[0]]:
        raise SemmapError(f"world '{world.name}': the start pose ({sx:.2f}, {sy:.2f}) is not "
                          "on the floor plan's free space", file=world.source or None,
                          field="start", hint="Move the start inside the image, off the walls.")
    labels, _ = ndimage.label(~walls, structure=_EIGHT)
    reachable = labels == labels[iy[0], ix[0]]
    facing = walls & ndimage.binary_dilation(reachable, structure=_EIGHT)
    return truth, reachable, facing


def score_map(m: OccupancyMap, world: World, tolerance: float = 0.25) -> dict[str, float | int]:
    """Compare a map with the world's ground truth (see the module docstring for definitions).

    Parameters
    ----------
    m
        The map, in the world frame (origin yaw 0).
    world
        A world loaded from a floor-plan image (:func:`sim2d.world.load_world`).
    tolerance
        How far (m) a map wall may be from the true wall and still count as
        right: sonar maps smear walls over a few cells, so exact-cell matching
        would punish a good map for its resolution.

    Returns
    -------
    dict
        :data:`METRIC_KEYS` in order: shares in [0, 1], cell counts, and the
        tolerance and both resolutions in metres.

    Raises
    ------
    ValueError
        If ``tolerance`` is negative or not finite.
    SemmapError
        If the map or the world is rotated, the world has no image, or its
        start pose is not on the floor plan.
    """
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
    if m.origin[2] != 0:
        raise SemmapError(f"the map's origin yaw {m.origin[2]} is not supported", field="origin",
                          hint="Only axis-aligned maps (yaw 0) can be scored.")
    truth, reachable, facing = _ground_truth(world)
    walls = truth.occupancy > 0.5
    occupied, free, _ = m.classes()
    res_m, res_w = float(m.resolution), float(truth.resolution)

    # precision: map occupied cell centres -> distance to the nearest true wall
    wall_dist, wall_origin = _padded_distance(walls, res_w, truth.origin, tolerance)
    mx, my = _centres(occupied, res_m, m.origin)
    iy, ix, inside = _cell_index(mx, my, wall_origin, res_w, wall_dist.shape)
    near_wall = inside & (wall_dist[iy, ix] <= tolerance)
    precision = _share(int(near_wall.sum()), int(occupied.sum()))

    # recall and false free: facing wall cell centres -> the map
    fx, fy = _centres(facing, res_w, truth.origin)
    map_dist, map_origin = _padded_distance(occupied, res_m, m.origin, tolerance)
    iy, ix, inside = _cell_index(fx, fy, map_origin, res_m, map_dist.shape)
    recall = _share(int((inside & (map_dist[iy, ix] <= tolerance)).sum()), len(fx))
    iy, ix, inside = _cell_index(fx, fy, m.origin, res_m, free.shape)
    false_free = _share(int((inside & free[iy, ix]).sum()), len(fx))

    # free coverage: reachable free cell centres -> the map
    rx, ry = _centres(reachable, res_w, truth.origin)
    iy, ix, inside = _cell_index(rx, ry, m.origin, res_m, free.shape)
    coverage = _share(int((inside & free[iy, ix]).sum()), len(rx))

    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    result: dict[str, float | int] = {
        "precision": precision,
        "recall": recall,
        "f1": f1,
        "free_coverage": coverage,
        "false_free": false_free,
        "map_occupied_cells": int(occupied.sum()),
        "map_free_cells": int(free.sum()),
        "facing_wall_cells": len(fx),
        "reachable_free_cells": len(rx),
        "tolerance_m": float(tolerance),
        "map_resolution_m": res_m,
        "world_resolution_m": res_w,
    }
    assert tuple(result) == METRIC_KEYS
    return result
