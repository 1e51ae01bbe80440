"""Doorways on a planned way: where it squeezes between two walls, and how to go through.

Why: pure pursuit cuts corners, and a way that turns into a door 0.9 m wide
cuts the jamb; a robot that reaches a door at an angle has its front
sonars on a jamb and its guard stops it there.  A person walking through a
door lines up with it first.  So the explorer finds each *doorway* on its
way (a stretch where the way passes closer than ``narrow`` to walls on
both sides), lines up on the doorway's axis in front of it, and drives
straight through.

The axis comes from the map: the nearest wall cell on each side of the
way's narrowest point are the jambs; the axis is square to the line
between them, through its middle.  A sonar map draws both jambs too far into
the opening by about the same amount, so the middle stays where it is even
when the width does not.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from .grid import NavGrid

__all__ = ["Doorway", "find_doorway", "doorway_legs"]


@dataclass(frozen=True)
class Doorway:
    """A narrow place on a way, between two jambs.

    Attributes
    ----------
    centre
        (x, y) halfway between the jambs.
    axis
        Unit (x, y) square to the jambs' line, pointing the way the way goes.
    width
        Distance (m) between the jambs' cells on the map (narrower than the
        door itself on a sonar map).
    at
        Arc length (m) along the way of its narrowest point.
    """

    centre: tuple[float, float]
    axis: tuple[float, float]
    width: float
    at: float


def _resample(way: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``step`` m along the polyline, and their arc lengths."""
    seg = np.diff(way, axis=0)
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    s = np.r_[0.0, np.cumsum(lengths)]
    if s[-1] <= 0:
        return way[:1].copy(), np.zeros(1)
    at = np.arange(0.0, s[-1] + 1e-9, step)
    xy = np.column_stack([np.interp(at, s, way[:, 0]), np.interp(at, s, way[:, 1])])
    return xy, at


def find_doorway(walls: np.ndarray, resolution: float, origin: tuple[float, ...],
                 way: np.ndarray, *, narrow: float = 0.5, skip: float = 0.0,
                 search: float = 1.0, straddle: bool = True) -> Doorway | None:
    """The first doorway on ``way`` (after ``skip`` m of it), or None.

    Parameters
    ----------
    walls
        (H, W) bool wall cells of the map (row 0 at the lowest y).
    way
        (N, 2) the planned way, world (x, y).
    narrow
        A stretch of the way nearer than this (m) to walls on both sides is
        a doorway: nearer than the robot's half-width plus a hand's breadth
        on each side, where pursuit's corner cutting and a slanted approach
        put a jamb under the body.
    skip
        Metres of the way's start to leave out.
    search
        How far (m) from the way a jamb may be.
    straddle
        The jambs must straddle the way (it passes between them): near one
        wall, a way leaving it at a slant has that wall's cells on both
        sides of its line, one side behind and the other ahead, and a room's
        corner beside it looks like a doorway.  False: any wall cells on
        both sides will do (what the explorer asked before it looked for a
        doorway under the robot; it skipped a way's start instead).

    Examples
    --------
    A wall along x = 2 with a gap 0.9 m wide (y from -0.4 to 0.5), crossed
    slantwise from the south-west: the axis is square to the wall all the same.

    >>> walls = np.zeros((40, 40), dtype=bool)
    >>> walls[:, 20] = True
    >>> walls[16:25, 20] = False
    >>> door = find_doorway(walls, 0.1, (0.0, -2.0), np.array([[0.5, -1.0], [3.5, 1.0]]))
    >>> [round(v, 2) + 0.0 for v in door.centre + door.axis], round(door.width, 2)
    ([2.05, 0.05, 1.0, 0.0], 1.0)
    """
    walls = np.asarray(walls, dtype=bool)
    if not walls.any():
        return None
    way = np.asarray(way, dtype=np.float64).reshape(-1, 2)
    if len(way) < 2:
        return None
    xy, at = _resample(way, resolution / 2)
    distance = ndimage.distance_transform_edt(~walls)
    rows = np.floor((xy[:, 1] - origin[1]) / resolution).astype(int)
    cols = np.floor((xy[:, 0] - origin[0]) / resolution).astype(int)
    h, w = walls.shape
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w) & (at >= skip)
    clear = np.full(len(xy), np.inf)
    clear[inside] = distance[rows[inside], cols[inside]] * resolution
    tight = clear < narrow
    k = 0
    while k < len(xy):
        if not tight[k]:
            k += 1
            continue
        end = k
        while end + 1 < len(xy) and tight[end + 1]:
            end += 1
        door = _throat(walls, resolution, origin, xy, at, k, end, search, straddle)
        if door is not None:
            return door
        k = end + 1
    return None


def _throat(walls: np.ndarray, resolution: float, origin: tuple[float, ...], xy: np.ndarray,
            at: np.ndarray, first: int, last: int, search: float,
            straddle: bool = True) -> Doorway | None:
    """The doorway of the way's narrow stretch ``first..last``: at the point where the
    nearest wall cell on its left and the nearest on its right are closest together
    (those are the jambs), if walls flank it on both sides within ``search`` (and, with
    ``straddle``, the way passes between them)."""
    middle = xy[(first + last) // 2]
    k = int(math.ceil((search + np.hypot(*(xy[last] - xy[first])) / 2) / resolution))
    r, c = (int(math.floor((middle[1] - origin[1]) / resolution)),
            int(math.floor((middle[0] - origin[0]) / resolution)))
    r0, c0 = max(r - k, 0), max(c - k, 0)
    wr, wc = np.nonzero(walls[r0:r + k + 1, c0:c + k + 1])
    if len(wr) == 0:
        return None
    cells = np.column_stack([origin[0] + (wc + c0 + 0.5) * resolution,
                             origin[1] + (wr + r0 + 0.5) * resolution])
    best = None
    for i in range(first, last + 1):
        ahead = xy[min(i + 1, len(xy) - 1)] - xy[max(i - 1, 0)]
        if not np.any(ahead):
            continue
        offset = cells - xy[i]
        reach = np.hypot(offset[:, 0], offset[:, 1])
        side = ahead[0] * offset[:, 1] - ahead[1] * offset[:, 0]  # > 0: on the left
        left, right = (side > 0) & (reach <= search), (side < 0) & (reach <= search)
        if not left.any() or not right.any():
            continue
        a = cells[left][int(np.argmin(reach[left]))]
        b = cells[right][int(np.argmin(reach[right]))]
        width = float(np.hypot(*(a - b)))
        if straddle and _off_segment(xy[i], a, b) > 0.25 * width + resolution:
            continue  # both on one wall (behind and ahead along it), not across the way
        if best is None or width < best[0] - 1e-9:
            best = (width, a, b, i, ahead)
    if best is None:
        return None
    width, a, b, i, ahead = best
    jambs = a - b
    axis = np.array([jambs[1], -jambs[0]]) / max(width, 1e-9)  # b -> a turned clockwise
    if axis @ ahead < 0:
        axis = -axis
    centre = (a + b) / 2
    return Doorway((float(centre[0]), float(centre[1])), (float(axis[0]), float(axis[1])),
                   width, float(at[i]))


def _off_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance (m) from ``p`` to the segment ``a``-``b``."""
    ab = b - a
    t = float(np.clip((p - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0))
    return float(np.hypot(*(p - (a + t * ab))))


def doorway_legs(grid: NavGrid, door: Doorway, *, approach: float = 0.7,
                 leave: float = 0.6, least: float = 0.3) -> tuple[np.ndarray, np.ndarray] | None:
    """The points in front of and behind ``door`` on its axis, as far out as
    ``approach`` and ``leave`` (m) where the grid lets the robot stand and the
    straight line between them is free; None if either is nearer than ``least``."""
    centre, axis = np.asarray(door.centre), np.asarray(door.axis)

    def farthest(sign: float, most: float) -> np.ndarray | None:
        for d in np.arange(most, least - 1e-9, -grid.resolution):
            q = centre + sign * d * axis
            if grid.is_free(float(q[0]), float(q[1])) and grid.segment_free(q, centre):
                return q
        return None
    before, after = farthest(-1.0, approach), farthest(1.0, leave)
    if before is None or after is None:
        return None
    return before, after
