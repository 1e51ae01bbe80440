"""Sonar cones as precomputed cell tables: one per whole degree of heading.

Drawing a 30-degree cone on a grid for every reading is the inner loop of the
offline map and of sonar visibility; with the cone's cells and their ranges
precomputed per degree, a reading becomes a slice and a comparison, as the
paper precomputes its beam matrices.

The same cells also come row by row (:func:`cone_spans`): a cone cut off at a
range is, on every grid row, one run of cells (or a few, where a cone edge
runs along the row), so a reading can be added as a handful of run ends per
row instead of a value per cell (:mod:`blocks.maps.sectors`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["ConeSpans", "cone_extents", "cone_spans", "cone_tables", "cone_window"]


def _offsets(reach: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column and row offsets of a (2 reach + 1)-square around the apex, and their distance."""
    offsets = np.arange(-reach, reach + 1, dtype=np.float64)
    dx, dy = np.meshgrid(offsets, offsets)
    return dx, dy, np.hypot(dx, dy)


def _outside(reach: int) -> int:
    """The code of the cells outside the cone: beyond every reading."""
    return 4 * reach + 8


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
    dx, dy, rho = _offsets(reach)
    codes_all = np.round(rho * 2).astype(np.uint16)
    half = math.radians(cone_deg) / 2
    outside = np.uint16(_outside(reach))
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


def cone_extents(tables: tuple[tuple[int, int, np.ndarray], ...], degrees: np.ndarray,
                 radius: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray],
                                               tuple[np.ndarray, np.ndarray]]:
    """Where :func:`cone_window` would put many readings' windows, without cutting them:
    the rows and the columns (offsets from the apex: the first, and one past the last)
    of the cones of heading ``degrees`` cut to ``radius`` cells, per reading."""
    dr, dc, h, w = (np.array(v)[degrees] for v in zip(*[(t[0], t[1], *t[2].shape)
                                                        for t in tables]))
    return ((dr + np.maximum(0, -radius - dr), dr + np.minimum(h, radius + 1 - dr)),
            (dc + np.maximum(0, -radius - dc), dc + np.minimum(w, radius + 1 - dc)))


@dataclass(frozen=True)
class ConeSpans:
    """The cells of :func:`cone_tables` as runs along grid rows, and the disks that cut them.

    Attributes
    ----------
    first
        (360, 2 reach + 2) int: the runs of heading ``k`` on rows ``dy`` with
        ``y0 <= dy <= y1`` are ``first[k, y0 + reach]`` to
        ``first[k, y1 + reach + 1]`` (exclusive) in the arrays below.
    row, start, stop
        (R,) int: each run's row offset and its columns ``start <= dx < stop``
        (offsets from the apex).
    abs_row
        (R,) int: ``|row|``.
    half_width
        (2 reach + 3, reach + 1) int: ``half_width[t, |dy|]`` is the largest
        ``|dx|`` whose range code is below ``t`` on row ``dy`` (-1: none).
    rows_below
        (2 reach + 3,) int: the largest ``|dy|`` with a code below ``t`` (-1: none).
    limit
        The largest useful code bound: every cell of a cone has a code below it.
    reach
        The cone radius (cells) of the tables.
    reached_from, reached_to
        (360, limit + 1) int: the runs of heading ``k`` on the rows that
        ``{code < t}`` reaches are ``reached_from[k, t]`` to ``reached_to[k, t]``
        (exclusive): the band of rows ``dy`` from the first to the last with a
        cell of the cone below ``t``, narrower than ``|dy| <= rows_below[t]``
        where the cone points along the rows; the runs outside it are cut
        away entirely.
    beyond_from, beyond_to
        (360, limit + 1) int: likewise the runs on the band of rows from the first to
        the last with a cell of the cone at ``t`` or beyond.  A ring
        ``{l <= code < h}`` lies on rows of both bands, of ``h`` in ``reached_*``
        and of ``l`` here: on the others the cones cut at ``l`` and ``h`` have the
        same runs.
    """

    first: np.ndarray
    row: np.ndarray
    start: np.ndarray
    stop: np.ndarray
    abs_row: np.ndarray
    half_width: np.ndarray
    rows_below: np.ndarray
    limit: int
    reach: int
    reached_from: np.ndarray
    reached_to: np.ndarray
    beyond_from: np.ndarray
    beyond_to: np.ndarray

    @property
    def small(self) -> SmallRuns:
        """``row``, ``start``, ``stop``, ``abs_row`` and ``half_width`` as int32."""
        found = self.__dict__.get("_small")
        if found is None:
            found = SmallRuns(*(np.ascontiguousarray(getattr(self, name), dtype=np.int32)
                                for name in ("row", "start", "stop", "abs_row", "half_width")))
            object.__setattr__(self, "_small", found)
        return found


@dataclass(frozen=True)
class SmallRuns:
    """The per-run tables of :class:`ConeSpans` in int32 (offsets of a few hundred cells),
    for the run tables of :func:`blocks.maps.sectors.run_ends` and
    :func:`~blocks.maps.sectors.add_runs`."""

    row: np.ndarray
    start: np.ndarray
    stop: np.ndarray
    abs_row: np.ndarray
    half_width: np.ndarray


@lru_cache(maxsize=4)
def cone_spans(resolution: float, cone_deg: float, reach: int) -> ConeSpans:
    """The cones of :func:`cone_tables` as row runs: ``{code < t}`` of heading ``k`` on row
    ``dy`` is each run of that row cut to ``|dx| <= half_width[t, |dy|]``.

    That holds because a cell's code only grows with ``|dx|`` along a row, which
    is checked here.

    Examples
    --------
    >>> spans = cone_spans(0.1, 30.0, 3)
    >>> k = 0  # heading +x: the apex, then a widening wedge to the right
    >>> lo, hi = spans.first[k, 0 + 3], spans.first[k, 0 + 3 + 1]
    >>> [(int(spans.start[i]), int(spans.stop[i])) for i in range(lo, hi)]
    [(0, 4)]
    >>> int(spans.half_width[3, 0])  # codes 0, 2 (below 3) on the apex row: |dx| <= 1
    1
    """
    tables = cone_tables(resolution, cone_deg, reach)
    outside = _outside(reach)
    first = np.zeros((360, 2 * reach + 2), dtype=np.int64)
    limit = 2 * reach + 2  # codes inside a cone are at most 2 reach
    reached_rows = np.zeros((360, limit + 1, 2), dtype=np.int64)  # dy from, dy to (inclusive)
    beyond_rows = np.zeros((360, limit + 1, 2), dtype=np.int64)
    rows, starts, stops = [], [], []
    count = 0
    for k, (dr, dc, codes) in enumerate(tables):
        t = np.arange(limit + 1)[:, None]
        reached_rows[k] = _row_band(codes.min(axis=1)[None, :] < t, dr)
        greatest = np.where(codes < outside, codes.astype(np.int64), -1).max(axis=1)
        beyond_rows[k] = _row_band(greatest[None, :] >= t, dr)
        inside = np.pad(codes < outside, ((0, 0), (1, 1))).astype(np.int8)
        step = np.diff(inside, axis=1)  # +1 where a run starts, -1 one past its end
        r_on, c_on = np.nonzero(step == 1)  # row by row, left to right
        _, c_off = np.nonzero(step == -1)
        rows.append(r_on + dr)
        starts.append(c_on + dc)
        stops.append(c_off + dc)
        first[k] = count + np.searchsorted(r_on + dr, np.arange(-reach, reach + 2))
        count += len(r_on)
    row, start, stop = np.concatenate(rows), np.concatenate(starts), np.concatenate(stops)
    _, _, rho = _offsets(reach)
    quarter = np.round(rho * 2).astype(np.int64)[reach:, reach:]  # [|dy|, |dx|], as the tables
    if (np.diff(quarter, axis=1) < 0).any():
        raise AssertionError("range codes must not fall along a row")  # never, for hypot
    below = quarter[None, :, :] < np.arange(limit + 1)[:, None, None]
    half_width = below.sum(axis=2) - 1
    rows = np.arange(reach + 1)
    rows_below = np.where(half_width >= 0, rows[None, :], -1).max(axis=1)
    row, start, stop = row.astype(np.int64), start.astype(np.int64), stop.astype(np.int64)
    heading = np.arange(360)[:, None]
    reached_from = first[heading, reach + reached_rows[..., 0]]
    reached_to = first[heading, reach + reached_rows[..., 1] + 1]
    beyond_from = first[heading, reach + beyond_rows[..., 0]]
    beyond_to = first[heading, reach + beyond_rows[..., 1] + 1]
    return ConeSpans(first, row, start, stop, np.abs(row), half_width, rows_below, limit, reach,
                     reached_from, reached_to, beyond_from, beyond_to)


def _row_band(reached: np.ndarray, dr: int) -> np.ndarray:
    """(limit + 1, 2): for each code bound ``t``, the first and last row offset for which
    ``reached`` (limit + 1, rows from offset ``dr`` on) holds; (0, -1) for none.  (A cone on
    a grid is not quite convex: a row between two reached ones may be missed; the band
    holds it all the same, and its runs are then cut away entirely.)"""
    some = reached.any(axis=1)
    lo = np.argmax(reached, axis=1)
    hi = reached.shape[1] - 1 - np.argmax(reached[:, ::-1], axis=1)
    return np.where(some[:, None], np.column_stack([lo + dr, hi + dr]), np.array([0, -1]))
