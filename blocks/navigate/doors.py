"""Doors from sonar maps: the opening beside a sign, and where to look into a room next.

Why a module: what a sonar map shows of a door (mapped jambs on both sides,
floor seen behind, narrowed by the cones) is a question of the map alone;
the room visitor (:mod:`blocks.navigate.rooms`) asks it, and so can a test
or a picture, with no robot in the loop.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .grid import NavGrid

__all__ = ["DoorEstimate", "SignRef", "find_door", "free_run", "next_look", "room_box",
           "unseen_nearby"]


@dataclass(frozen=True)
class SignRef:
    """A sign read on a door: its text, position (m) and facing (rad, the way it looks)."""

    text: str
    x: float
    y: float
    facing: float

    @classmethod
    def from_dict(cls, sign: dict[str, Any]) -> SignRef:
        """From a ``signs.correlate`` entry (``facing`` in degrees)."""
        return cls(str(sign["text"]), float(sign["x"]), float(sign["y"]),
                   math.radians(float(sign["facing"])))


@dataclass(frozen=True)
class DoorEstimate:
    """An opening in a wall, as the map shows it.

    Attributes
    ----------
    wall
        (x, y) of the wall's corridor-side surface at the middle of the opening.
    normal
        Unit vector out of the room (the sign's facing).
    width
        Width of the opening on the map (m); sonar draws jambs thick, so
        it is narrower than the true door.
    inside
        Free floor (m) seen straight in from the wall surface.
    """

    wall: tuple[float, float]
    normal: tuple[float, float]
    width: float
    inside: float

    def point(self, depth: float) -> tuple[float, float]:
        """The point ``depth`` metres into the room along the door's axis (negative: out)."""
        return (self.wall[0] - depth * self.normal[0], self.wall[1] - depth * self.normal[1])


def _classes_at(occupancy_map: Any, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(occupied, free) at world points (..., 2); points off the map are neither.

    The map's classes (:meth:`~blocks.maps.mapio.OccupancyMap.classes`) of the
    cells sampled only, not of the whole grid: a door search samples a few
    thousand of its hundreds of thousands of cells.
    """
    res, (ox, oy) = occupancy_map.resolution, occupancy_map.origin[:2]
    rows = np.floor((xy[..., 1] - oy) / res).astype(np.int64)
    cols = np.floor((xy[..., 0] - ox) / res).astype(np.int64)
    h, w = occupancy_map.shape
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    r, c = np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)
    sampled = replace(occupancy_map, occupancy=np.asarray(occupancy_map.occupancy)[r, c])
    occupied, free, _ = sampled.classes()
    return occupied & inside, free & inside


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs of a 1-D mask."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def free_run(occupancy_map: Any, start: tuple[float, float], direction: tuple[float, float],
             *, max_distance: float, step: float | None = None) -> float:
    """How far (m) the map is free from ``start`` along ``direction`` (up to ``max_distance``)."""
    step = step or occupancy_map.resolution / 2
    s = np.arange(0.0, max_distance + step, step)
    xy = np.asarray(start)[None, :] + s[:, None] * np.asarray(direction)[None, :]
    _, free = _classes_at(occupancy_map, xy)
    blocked = np.flatnonzero(~free)
    return float(max_distance if blocked.size == 0 else s[blocked[0]])


def room_box(shape: tuple[int, int], resolution: float, origin: tuple[float, ...],
             door: DoorEstimate, *, half_width: float, depth: float) -> np.ndarray:
    """(H, W) bool: the cells behind the door's wall, up to ``depth`` deep and
    ``half_width`` to either side of the door: where its room can be."""
    h, w = shape
    xs = origin[0] + (np.arange(w) + 0.5) * resolution
    ys = origin[1] + (np.arange(h) + 0.5) * resolution
    dx, dy = xs[None, :] - door.wall[0], ys[:, None] - door.wall[1]
    nx, ny = door.normal
    behind = -(dx * nx + dy * ny)
    lateral = dx * -ny + dy * nx
    return (behind >= 0.0) & (behind <= depth) & (np.abs(lateral) <= half_width)


def unseen_nearby(unknown: np.ndarray, resolution: float, radius: float,
                  block: float = 0.1) -> np.ndarray:
    """(H, W) float: area (m^2) of ``unknown`` cells within ``radius`` of each cell.

    Computed on ``block``-metre cells (a box filter on a disk), so it is cheap
    enough to run after every look.
    """
    import cv2
    f = max(1, int(round(block / resolution)))
    h, w = unknown.shape
    hp, wp = -(-h // f) * f, -(-w // f) * f
    padded = np.zeros((hp, wp), dtype=np.float32)
    padded[:h, :w] = unknown
    coarse = padded.reshape(hp // f, f, wp // f, f).sum(axis=(1, 3)) * resolution ** 2
    k = int(math.ceil(radius / (f * resolution)))
    yy, xx = np.mgrid[-k:k + 1, -k:k + 1]
    disk = ((xx * xx + yy * yy) <= k * k).astype(np.float32)
    area = cv2.filter2D(coarse, -1, disk, borderType=cv2.BORDER_CONSTANT)
    return np.repeat(np.repeat(area, f, axis=0), f, axis=1)[:h, :w]


def next_look(grid: NavGrid, unknown: np.ndarray, door: DoorEstimate,
              here: tuple[float, float], *, min_distance: float = 1.0,
              half_width: float = 3.2, depth_max: float = 5.5, min_clearance: float = 0.5,
              sensing: float = 3.0, min_gain: float = 1.5) -> tuple[float, float] | None:
    """Where to look around next in a room: the reachable spot that sees the most unseen floor.

    A next-best-view rule: candidates are the cells the robot can reach from
    ``here`` inside the room's box (see :func:`room_box`) with
    ``min_clearance`` around them (it turns in place there) and at least
    ``min_distance`` away; each is worth the unknown area of the box within
    ``sensing`` metres (the sonar's useful range).  Occlusion is ignored.

    Parameters
    ----------
    unknown
        (H, W) bool, the local map's unknown cells, on ``grid``'s cells.
    min_gain
        Below this much unseen area (m^2) a look is not worth it.

    Returns
    -------
    (x, y) or None
    """
    cell = grid.free_cell_at(*here, 0.6)
    if cell is None:
        return None
    row, col = cell
    box = room_box(grid.shape, grid.resolution, grid.origin, door, half_width=half_width,
                   depth=depth_max)
    gain = unseen_nearby(unknown & box, grid.resolution, sensing)
    rows, cols = np.nonzero((grid.labels == grid.labels[row, col]) & box
                            & (grid.clearance >= min_clearance))
    if rows.size == 0:
        return None
    xy = grid.cell_to_world(rows, cols)
    distance = np.hypot(xy[:, 0] - here[0], xy[:, 1] - here[1])
    worth = gain[rows, cols]
    ok = (distance >= min_distance) & (worth >= min_gain)
    if not ok.any():
        return None
    # Gain in 0.25 m^2 steps, so near-equal gains tie and the more open cell wins.
    best = np.lexsort((-grid.clearance[rows[ok], cols[ok]], -np.round(worth[ok] / 0.25)))[0]
    return float(xy[ok][best, 0]), float(xy[ok][best, 1])


def find_door(occupancy_map: Any, sign: SignRef, *, half_width: float = 2.2,
              search: float = 3.5, wall_search: float = 0.6, wall_depth: float = 0.25,
              min_width: float = 0.25, max_width: float = 2.0, jamb: float = 0.2,
              seen_behind: float = 0.5) -> DoorEstimate | None:
    """The opening in the sign's wall nearest to the sign, or None.

    Parameters
    ----------
    occupancy_map
        The local map (an :class:`~blocks.maps.mapio.OccupancyMap`).
    sign
        The sign; its wall runs across its facing, the room is behind it.
    half_width
        The opening's middle must be within this distance (m) of the sign
        along the wall (a sign hangs next to its door).
    search
        Length (m) of wall examined on each side of the sign.
    wall_search
        The sign's position is an estimate: the wall's surface is sought
        within this distance (m) in front of and behind it.
    wall_depth
        Thickness (m) of the band behind the surface that counts as the wall.
    min_width, max_width
        Openings narrower than ``min_width`` on the map are gaps between
        readings, wider than ``max_width`` are not doors (m).
    jamb
        Each end of the opening must have mapped wall within this distance (m):
        an opening whose far side was not seen yet is not trusted.
    seen_behind
        Depth (m) behind the wall that must be seen free across most of the
        opening (the robot has looked through it).

    Returns
    -------
    DoorEstimate or None
    """
    res = occupancy_map.resolution
    normal = np.array([math.cos(sign.facing), math.sin(sign.facing)])
    along = np.array([-normal[1], normal[0]])
    u = np.arange(-search, search + res / 2, res / 2)
    d = np.arange(-wall_search, wall_search + wall_depth + seen_behind + res, res / 2)
    # Points at lateral u, depth d behind the sign's position: (len(d), len(u), 2).
    xy = (np.array([sign.x, sign.y])[None, None, :] + u[None, :, None] * along[None, None, :]
          - d[:, None, None] * normal[None, None, :])
    occupied, free = _classes_at(occupancy_map, xy)
    # The wall's surface: the depth whose line holds the most occupied cells.
    surface_rows = np.flatnonzero(np.abs(d) <= wall_search)
    counts = occupied[surface_rows].sum(axis=1)
    if counts.max() * res / 2 < 1.0:  # less than a metre of wall seen
        return None
    k0 = int(surface_rows[int(np.argmax(counts))])
    d0 = float(d[k0])
    band = (d >= d0 - res) & (d <= d0 + wall_depth)
    wall = occupied[band].any(axis=0)
    behind = (d > d0 + wall_depth) & (d <= d0 + wall_depth + seen_behind)
    seen = free[behind].mean(axis=0) >= 0.5
    best: DoorEstimate | None = None
    for a, b in _runs(~wall):
        width = (b - a) * res / 2
        if not (min_width <= width <= max_width):
            continue
        reach = int(round(jamb / (res / 2)))
        left_ok = a > 0 and wall[max(0, a - reach):a].any()
        right_ok = b < len(u) and wall[b:b + reach].any()
        if not (left_ok and right_ok) or seen[a:b].mean() < 0.6:
            continue
        centre = 0.5 * (u[a] + u[b - 1])
        if abs(centre) > half_width:
            continue
        surface = np.array([sign.x, sign.y]) + centre * along - d0 * normal
        inside = free_run(occupancy_map, tuple(surface - (wall_depth + res) * normal),
                          tuple(-normal), max_distance=6.0) + wall_depth + res
        door = DoorEstimate((float(surface[0]), float(surface[1])),
                            (float(normal[0]), float(normal[1])), float(width), float(inside))
        if best is None or abs(centre) < abs(_lateral(best, sign)):
            best = door
    return best


def _lateral(door: DoorEstimate, sign: SignRef) -> float:
    along = (-math.sin(sign.facing), math.cos(sign.facing))
    return (door.wall[0] - sign.x) * along[0] + (door.wall[1] - sign.y) * along[1]
