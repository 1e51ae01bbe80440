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

Visible metrics
---------------
A perimeter run never looks into some rooms, so scoring it against the whole
reachable floor mixes "mapped badly" with "never seen".  With a visibility mask
(:func:`visible_from_path`: the true-grid cells a sensor of ``max_range`` on the
path had a clear line of sight to), :func:`score_map` also reports

visible wall cells, visible free cells
    Facing wall cells, and reachable free cells, that are also visible.
recall_visible, free_coverage_visible, false_free_visible
    ``recall``, ``free_coverage`` and ``false_free`` with those denominators.
f1_visible
    Harmonic mean of ``precision`` (unchanged: a wall drawn where the robot
    never looked is still wrong) and ``recall_visible``.

A share of an empty set is reported as 0.0 (for example the precision of a
map with no occupied cells), so the numbers are always finite JSON numbers.
Cells are classified with map_server's trinary rule (see
:meth:`blocks.maps.mapio.OccupancyMap.classes`).
"""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from blocks.core.errors import SemmapError

from .mapio import OccupancyMap, occupancy_map_from_world

if TYPE_CHECKING:
    from sim2d.world import World

__all__ = ["METRIC_KEYS", "VISIBLE_KEYS", "TrajectoryError", "free_floor", "reachable_floor",
           "read_path_csv", "score_map", "sight_from_cells", "visible_from_path"]

#: The keys of :func:`score_map`'s result, in order (stable: scripts and JSON rely on them).
METRIC_KEYS = ("precision", "recall", "f1", "free_coverage", "false_free",
               "map_occupied_cells", "map_free_cells", "facing_wall_cells",
               "reachable_free_cells", "tolerance_m", "map_resolution_m",
               "world_resolution_m")

#: The extra keys :func:`score_map` returns after :data:`METRIC_KEYS` when given a visibility mask.
VISIBLE_KEYS = ("recall_visible", "f1_visible", "free_coverage_visible", "false_free_visible",
                "visible_wall_cells", "visible_free_cells")

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


def _harmonic(a: float, b: float) -> float:
    """F1 of two shares; 0 when both are 0."""
    return 2 * a * b / (a + b) if a + b > 0 else 0.0


def _check_visible(visible: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The visibility mask as a bool array on the truth grid, or ValueError if it is not one."""
    mask = np.asarray(visible)
    if mask.shape != shape:
        raise ValueError(f"visible must be a mask on the world's grid of shape {shape} "
                         f"(rows y up, see visible_from_path), got shape {mask.shape}")
    return mask.astype(bool, copy=False)


def score_map(m: OccupancyMap, world: World, tolerance: float = 0.25,
              visible: np.ndarray | None = None) -> dict[str, float | int]:
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
    visible
        Optional bool mask on the ground-truth grid (the shape of
        ``occupancy_map_from_world(world)``, rows y up), usually from
        :func:`visible_from_path`: restricts recall, coverage and false free
        to what the run could see, so a map is not blamed for rooms the robot
        never looked into.

    Returns
    -------
    dict
        :data:`METRIC_KEYS` in order: shares in [0, 1], cell counts, and the
        tolerance and both resolutions in metres; with ``visible``, followed by
        :data:`VISIBLE_KEYS`.

    Raises
    ------
    ValueError
        If ``tolerance`` is negative or not finite, or ``visible`` does not
        have the ground-truth grid's shape.
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
    seen = None if visible is None else _check_visible(visible, facing.shape)
    walls = truth.occupancy > 0.5
    occupied, free, _ = m.classes()
    res_m, res_w = float(m.resolution), float(truth.resolution)

    # precision: map occupied cell centres -> distance to the nearest true wall
    wall_dist, wall_origin = _padded_distance(walls, res_w, truth.origin, tolerance)
    mx, my = _centres(occupied, res_m, m.origin)
    iy, ix, inside = _cell_index(mx, my, wall_origin, res_w, wall_dist.shape)
    near_wall = inside & (wall_dist[iy, ix] <= tolerance)
    precision = _share(int(near_wall.sum()), int(occupied.sum()))

    # recall and false free, per facing wall cell (in np.nonzero order, like mask[facing])
    fx, fy = _centres(facing, res_w, truth.origin)
    map_dist, map_origin = _padded_distance(occupied, res_m, m.origin, tolerance)
    iy, ix, inside = _cell_index(fx, fy, map_origin, res_m, map_dist.shape)
    wall_found = inside & (map_dist[iy, ix] <= tolerance)
    iy, ix, inside = _cell_index(fx, fy, m.origin, res_m, free.shape)
    wall_free = inside & free[iy, ix]

    # free coverage, per reachable free cell
    floor_free = _floor_free(m, free, truth, reachable)

    recall = _share(int(wall_found.sum()), len(fx))
    result: dict[str, float | int] = {
        "precision": precision,
        "recall": recall,
        "f1": _harmonic(precision, recall),
        "free_coverage": _share(int(floor_free.sum()), len(floor_free)),
        "false_free": _share(int(wall_free.sum()), len(fx)),
        "map_occupied_cells": int(occupied.sum()),
        "map_free_cells": int(free.sum()),
        "facing_wall_cells": len(fx),
        "reachable_free_cells": len(floor_free),
        "tolerance_m": float(tolerance),
        "map_resolution_m": res_m,
        "world_resolution_m": res_w,
    }
    assert tuple(result) == METRIC_KEYS
    if seen is None:
        return result
    seen_walls, seen_floor = seen[facing], seen[reachable]
    n_walls, n_floor = int(seen_walls.sum()), int(seen_floor.sum())
    recall_visible = _share(int((wall_found & seen_walls).sum()), n_walls)
    result.update({
        "recall_visible": recall_visible,
        "f1_visible": _harmonic(precision, recall_visible),
        "free_coverage_visible": _share(int((floor_free & seen_floor).sum()), n_floor),
        "false_free_visible": _share(int((wall_free & seen_walls).sum()), n_walls),
        "visible_wall_cells": n_walls,
        "visible_free_cells": n_floor,
    })
    assert tuple(result) == METRIC_KEYS + VISIBLE_KEYS
    return result


# ---- what a run could see ----------------------------------------------------------------
#: Most poses :func:`visible_from_path` samples: a guard against a typo in ``spacing``.
_MAX_SAMPLES = 1_000_000


def _sample_path(path_xy: np.ndarray, spacing: float) -> np.ndarray:
    """Points every ``spacing`` metres of travel along the polyline, and its last point.

    Sampling by distance, not by pose, keeps the cost proportional to the
    ground covered: a robot standing still for a minute adds nothing, and a
    path given as a few waypoints is still seen from in between.
    """
    travel = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path_xy, axis=0).T))])
    count = math.floor(travel[-1] / spacing) + 1
    if count > _MAX_SAMPLES:
        raise ValueError(f"spacing {spacing} m samples a {travel[-1]:.1f} m path {count} times "
                         f"(at most {_MAX_SAMPLES}); use a larger spacing")
    # travel may repeat (the robot stood still); equal travel means an equal point, so
    # whichever of the repeated points interp picks is right.
    s = np.append(np.arange(count) * spacing, travel[-1])
    return np.column_stack([np.interp(s, travel, path_xy[:, 0]),
                            np.interp(s, travel, path_xy[:, 1])])


def _ray_offsets(max_range: float, resolution: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Integer cell offsets (dx, dy), each (rays, steps), of rays cast from a cell's centre.

    Steps are half a cell long, out to ``max_range``; there are enough rays
    (at least 720) that neighbouring rays are less than a cell apart at full
    range, so no cell within range falls between two rays.  Returns the
    offsets and their reach in cells (the largest |offset|).
    """
    n_rays = max(720, math.ceil(2 * math.pi * max_range / (0.7 * resolution)))
    n_steps = math.floor(max_range / (resolution / 2)) + 1
    angles = np.arange(n_rays) * (2 * math.pi / n_rays)
    dist = np.arange(n_steps) * 0.5  # in cells
    dx = np.floor(0.5 + np.outer(np.cos(angles), dist)).astype(np.int64)
    dy = np.floor(0.5 + np.outer(np.sin(angles), dist)).astype(np.int64)
    reach = int(max(np.abs(dx).max(), np.abs(dy).max()))
    return dx, dy, reach


def _check_path(path_xy: np.ndarray) -> np.ndarray:
    points = np.asarray(path_xy, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2 or len(points) == 0:
        raise ValueError(f"path_xy must be an (N, 2) array of x, y with N >= 1, "
                         f"got shape {points.shape}")
    if not np.isfinite(points).all():
        raise ValueError("path_xy contains non-finite coordinates")
    return points


def visible_from_path(world: World, path_xy: np.ndarray, max_range: float = 4.0,
                      spacing: float = 0.1) -> np.ndarray:
    """Cells of the ground-truth grid a range sensor on the path had a clear line of sight to.

    A run can only be expected to map what it could see, so scores against
    the whole building punish a perimeter run for rooms it never looked
    into; this mask (for :func:`score_map`'s ``visible``) draws that line.
    From every sampled pose, rays go out in all directions on the true wall
    grid: cells up to ``max_range`` are visible until the ray's first wall
    cell, which is visible too (it is the surface a sensor hits); cells
    behind it are not.  The sensor is omnidirectional and ideal (no cone, no
    specular loss): the mask is what the path *could* see, whatever the
    robot's heading.

    Parameters
    ----------
    world
        A world with a floor-plan image (as for :func:`score_map`).
    path_xy
        (N, 2) true positions (m, world frame) in driving order.
    max_range
        Sensor range (m); the sonars' 4 m by default.
    spacing
        Distance of travel (m) between poses sampled along the polyline
        (interpolated between its points); the first and last points are
        always used.

    Returns
    -------
    np.ndarray
        (H, W) bool, on ``occupancy_map_from_world(world)``'s grid: indexed
        ``[iy, ix]``, row 0 at the lowest y.  Rays stop at the grid's edge;
        poses outside the grid see nothing.

    Raises
    ------
    ValueError
        If the path is not (N >= 1, 2) finite points, ``max_range`` or
        ``spacing`` is not a positive finite number, or ``spacing`` would
        sample the path more than a million times.
    SemmapError
        If the world has no image or a rotated origin.

    Notes
    -----
    Rays start at the centre of the pose's cell and step half a cell, so a
    diagonal wall one cell thick can leak where two wall cells touch only
    at a corner; the library's walls are at least two cells thick.
    """
    for name, value in (("max_range", max_range), ("spacing", spacing)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a finite number > 0 metres, got {value!r}")
    points = _sample_path(_check_path(path_xy), float(spacing))
    truth = occupancy_map_from_world(world)
    walls = truth.occupancy > 0.5
    iy, ix, inside = _cell_index(points[:, 0], points[:, 1], truth.origin, truth.resolution,
                                 walls.shape)
    return sight_from_cells(walls, iy[inside], ix[inside], float(max_range),
                            float(truth.resolution))


def sight_from_cells(walls: np.ndarray, iy: np.ndarray, ix: np.ndarray, max_range: float,
                     resolution: float) -> np.ndarray:
    """Cells of the grid ``walls`` in clear line of sight of any of the cells (``iy``, ``ix``).

    The ray casting of :func:`visible_from_path`, from given cells: rays go
    out in all directions up to ``max_range`` (m) and stop at their first
    wall cell, which is seen too.  ``walls`` is indexed ``[iy, ix]``;
    the cells must be inside it.

    Examples
    --------
    >>> walls = np.zeros((5, 9), dtype=bool); walls[:, 4] = True
    >>> seen = sight_from_cells(walls, np.array([2]), np.array([1]), 10.0, 1.0)
    >>> seen[2].astype(int).tolist()  # the wall is seen, what is behind it is not
    [1, 1, 1, 1, 1, 0, 0, 0, 0]
    """
    h, w = walls.shape
    dx, dy, reach = _ray_offsets(float(max_range), float(resolution))
    # Pad with walls so rays stop at the edge and never index out of the grid.
    pad = reach + 1
    blocked = np.pad(walls, pad, constant_values=True).ravel()
    stride = w + 2 * pad
    offsets = (dy * stride + dx).astype(np.intp)
    seen = np.zeros(blocked.shape, dtype=bool)
    steps = np.arange(offsets.shape[1])
    for base in ((np.asarray(iy) + pad) * stride + np.asarray(ix) + pad):
        cells = offsets + base
        hit = blocked[cells]
        first = np.where(hit.any(axis=1), hit.argmax(axis=1), offsets.shape[1] - 1)
        seen[cells[steps <= first[:, None]]] = True
    return seen.reshape(h + 2 * pad, w + 2 * pad)[pad:-pad, pad:-pad].copy()


def _floor_free(m: OccupancyMap, free: np.ndarray, truth: OccupancyMap,
                reachable: np.ndarray) -> np.ndarray:
    """For each reachable cell of the truth grid (``np.nonzero`` order), whether the map
    calls it free."""
    rx, ry = _centres(reachable, float(truth.resolution), truth.origin)
    iy, ix, inside = _cell_index(rx, ry, m.origin, float(m.resolution), free.shape)
    return inside & free[iy, ix]


def free_floor(m: OccupancyMap, world: World) -> tuple[OccupancyMap, np.ndarray, np.ndarray]:
    """Where a map's ``free_coverage`` is won and lost: the world's wall grid, its reachable
    floor, and the part of that floor the map calls free (bool masks on the wall grid).

    ``free_mask.sum() / reachable.sum()`` is :func:`score_map`'s ``free_coverage``.
    """
    truth, reachable, _ = _ground_truth(world)
    _, free, _ = m.classes()
    free_mask = np.zeros_like(reachable, dtype=bool)
    free_mask[reachable] = _floor_free(m, free, truth, reachable)
    return truth, reachable, free_mask


def reachable_floor(world: World) -> tuple[OccupancyMap, np.ndarray]:
    """The world's wall grid (y-up, as :func:`score_map` scores on) and its reachable free
    cells: the floor 8-connected to the start, the denominator of ``free_coverage``."""
    truth, reachable, _ = _ground_truth(world)
    return truth, reachable


# ---- trajectory files --------------------------------------------------------------------
class TrajectoryError(SemmapError):
    """A trajectory.csv is missing or malformed (a user error: reported without a traceback)."""


def _coordinate(row: dict[str, str], key: str, file: Path, line: int) -> float:
    text = row.get(key)
    try:
        value = float(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value):
        shown = "nothing" if text is None or not text.strip() else repr(text)
        raise TrajectoryError(f"column '{key}' holds {shown}, not a finite number (m)",
                              file=file, line=line, field=key,
                              hint="Use the trajectory.csv a 'semmap run' wrote.")
    return value


def read_path_csv(path: str | Path, robot: str | None = None,
                  columns: tuple[str, ...] = ("x", "y")) -> np.ndarray:
    """The true positions (or poses) of one robot from a run's trajectory.csv, in file order.

    The true pose, not the odometry: visibility is about where the robot
    really was.  The file is what the ``sim2d.world`` block writes (columns
    ``tick, time, robot, x, y, theta, odom_x, ...``); only ``x`` and ``y`` are
    required, plus ``robot`` to choose among several robots.

    Parameters
    ----------
    path
        The CSV file.
    robot
        Which robot's rows to read; ``None`` takes the robot of the first row.
    columns
        The columns to read: ``("x", "y")``, or ``("x", "y", "theta")`` for poses.

    Returns
    -------
    np.ndarray
        (N, len(columns)) float64, N >= 1, in metres (and radians) in the world frame.

    Raises
    ------
    TrajectoryError
        If the file is missing or unreadable, lacks the ``x``/``y`` (or
        ``robot``) columns, has a non-numeric coordinate, has no rows, or has
        no row for ``robot``.
    """
    file = Path(path)
    hint = "Pass the trajectory.csv written by 'semmap run' (columns tick,time,robot,x,y,...)."
    try:
        text = file.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise TrajectoryError("trajectory file not found", file=file, hint=hint) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TrajectoryError(f"cannot read the trajectory file ({exc})", file=file,
                              hint=hint) from None
    reader = csv.DictReader(text.splitlines())
    header_columns = reader.fieldnames or []
    needed = list(columns) + (["robot"] if robot is not None else [])
    missing = [c for c in needed if c not in header_columns]
    if missing:
        header = ",".join(header_columns)
        raise TrajectoryError(f"the header line {header!r} has no column "
                              f"{' or '.join(repr(c) for c in missing)}" if header_columns
                              else "the file is empty", file=file, line=1,
                              field=missing[0], hint=hint)
    points, robots = [], []
    for row in reader:
        name = row.get("robot")
        if name not in robots:
            robots.append(name)
        if robot is None:
            robot = name
        if name == robot:
            points.append(tuple(_coordinate(row, c, file, reader.line_num) for c in columns))
    if not robots:
        raise TrajectoryError("the trajectory has a header but no rows", file=file, hint=hint)
    if not points:
        raise TrajectoryError(f"no rows for robot {robot!r}; the file has "
                              f"{', '.join(repr(r) for r in robots)}", file=file, field="robot",
                              hint="Choose one of those with --robot.")
    return np.array(points, dtype=np.float64)
