"""Sonar cones as precomputed cell tables: one per whole degree of heading.

Drawing a 30-degree cone on a grid for every reading is the inner loop of the
offline map and of sonar visibility; with the cone's cells and their ranges
precomputed per degree, a reading becomes a slice and a comparison, as the
paper precomputes its beam matrices.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

__all__ = ["cone_tables", "cone_window"]


@lru_cache(maxsize=4)
def cone_tables(resolution: float, cone_deg: float, reach: int
                 ) -> tuple[tuple[int, int, np.ndarray], ...]:
    """Per whole degree of heading: the cone's cells as ranges in half cells (uint16).

    Parameters
    ----------
    resolution
        Cell size (m); only part of the cache key (the tables are in cells).
    cone_deg
        Full cone angle.
    reach
        Cone radius in cells.

    Returns
    -------
    tuple of (row offset, column offset, codes)
        For heading ``k`` degrees (counter-clockwise from +x, rows y up):
        ``codes[r, c]`` is the range in half cells of the cell at
        ``(apex row + row offset + r, apex column + column offset + c)``;
        cells outside the cone hold a code beyond every reading.
    """
    offsets = np.arange(-reach, reach + 1, dtype=np.float64)
    dx, dy = np.meshgrid(offsets, offsets)
    rho = np.hypot(dx, dy)
    codes_all = np.round(rho * 2).astype(np.uint16)
    half = math.radians(cone_deg) / 2
    outside = np.uint16(4 * reach + 8)
    tables = []
    for k in range(360):
        heading = math.radians(k)
        along = dx * math.cos(heading) + dy * math.sin(heading)
        inside = ((along >= rho * math.cos(half)) & (rho <= reach)) | (rho == 0)
        rows, cols = np.nonzero(inside)
        r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
        codes = np.where(inside, codes_all, outside)[r0:r1, c0:c1].copy()
        tables.append((int(r0) - reach, int(c0) - reach, codes))
    return tuple(tables)


def cone_window(table: tuple[int, int, np.ndarray], row: int, col: int, radius: int
                ) -> tuple[slice, slice, np.ndarray] | None:
    """A cone cropped to ``radius`` cells around its apex at grid cell (``row``, ``col``).

    Returns the grid's row and column slices and the matching part of the
    codes, or None when nothing is left.  A short reading thereby touches
    only the cells it can reach.
    """
    dr, dc, codes = table
    h, w = codes.shape
    r0, r1 = max(0, -radius - dr), min(h, radius + 1 - dr)
    c0, c1 = max(0, -radius - dc), min(w, radius + 1 - dc)
    if r0 >= r1 or c0 >= c1:
        return None
    return (slice(row + dr + r0, row + dr + r1), slice(col + dc + c0, col + dc + c1),
            codes[r0:r1, c0:c1])
