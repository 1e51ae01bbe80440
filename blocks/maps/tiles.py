"""A tiled occupancy grid: an unbounded map stored as square tiles allocated on demand.

A robot does not know how big the building is before it has explored it, and a
dense array sized for the worst case wastes memory on cells nobody will ever
see.  Following the tiled occupancy grids used in time-of-flight mapping, the
map is split into ``tile_size x tile_size`` tiles that are created the first
time an update touches them; everything else reads as ``fill``.  Consumers that
want a plain array get one through :meth:`TiledGrid.window` or
:meth:`TiledGrid.to_dense`.

Conventions
-----------
Cell ``(ix, iy)`` covers ``x in [ix*res, (ix+1)*res)`` and
``y in [iy*res, (iy+1)*res)`` of the map frame (x right, y up).  Arrays are
indexed ``[iy, ix]`` with ``iy`` growing upward, so row 0 is the lowest ``y``.
Tile ``(tx, ty)`` holds cells ``ix // tile_size == tx`` and
``iy // tile_size == ty`` (floor division, so negative cells work).
"""
from __future__ import annotations

import math
import operator
from collections.abc import Callable, Iterator

import numpy as np

__all__ = ["TiledGrid"]

Op = Callable[[np.ndarray, np.ndarray], None]


def _as_int(value: object, name: str) -> int:
    """Accept Python and numpy integers, reject floats and bools with a clear message."""
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    try:
        return operator.index(value)  # type: ignore[arg-type]
    except TypeError:
        raise ValueError(f"{name} must be an integer, got {value!r}") from None


def _span(lo: int, hi: int, size: int) -> range:
    """Tile indices overlapping cells ``[lo, hi)`` (``hi > lo``)."""
    return range(lo // size, (hi - 1) // size + 1)


class TiledGrid:
    """An unbounded 2-D grid of ``resolution``-metre cells stored as lazily allocated tiles.

    Cells of ``resolution`` metres; cell ``(ix, iy)`` covers
    ``x in [ix*res, (ix+1)*res)``, ``y in [iy*res, (iy+1)*res)`` of the map frame
    (x right, y up).  Arrays are indexed ``[iy, ix]`` with ``iy`` growing upward
    (row 0 = lowest y).

    Parameters
    ----------
    resolution
        Cell edge in metres; finite and positive.
    dtype
        Element type of every tile (numeric or bool).
    fill
        Value of cells never written; it must be exactly representable in an
        integer/bool ``dtype`` (NaN is fine for float grids), otherwise reads of
        unknown cells would silently disagree with what the caller asked for.
    tile_size
        Tile edge in cells.  Large tiles waste memory at the frontier, small
        ones cost Python overhead per update; 64 suits ~160-cell patches.
    """

    def __init__(
        self,
        resolution: float,
        dtype: np.dtype | type = np.uint8,
        fill: float | int = 0,
        tile_size: int = 64,
    ) -> None:
        try:
            res = float(resolution)
        except (TypeError, ValueError):
            raise ValueError(f"resolution must be a number, got {resolution!r}") from None
        if not (math.isfinite(res) and res > 0):
            raise ValueError(f"resolution must be finite and > 0 metres, got {resolution!r}")
        size = _as_int(tile_size, "tile_size")
        if size < 1:
            raise ValueError(f"tile_size must be >= 1 cell, got {tile_size!r}")
        try:
            dt = np.dtype(dtype)
        except TypeError as exc:
            raise ValueError(f"dtype {dtype!r} is not a numpy dtype: {exc}") from None
        if dt.kind not in "biufc":
            raise ValueError(f"dtype must be numeric or bool, got {dt}")
        self.resolution: float = res
        self.dtype: np.dtype = dt
        self.fill = self._check_fill(fill, dt)
        self.tile_size: int = size
        self._tiles: dict[tuple[int, int], np.ndarray] = {}

    @staticmethod
    def _check_fill(fill: float | int, dtype: np.dtype) -> np.generic:
        """Return ``fill`` as a ``dtype`` scalar, refusing lossy conversions (NaN, 0.5 or 300 into uint8)."""
        try:
            with np.errstate(invalid="raise", over="raise"):
                value = np.asarray(fill).astype(dtype)[()]
        except (TypeError, ValueError, OverflowError, FloatingPointError):
            raise ValueError(f"fill {fill!r} cannot be stored in dtype {dtype}") from None
        if dtype.kind in "fc":
            return value  # rounding (0.1 -> float32) is expected; overflow was caught above
        if value != fill:
            raise ValueError(f"fill {fill!r} is not exactly representable in dtype {dtype} (got {value!r})")
        return value

    # ------------------------------------------------------------------ geometry

    def cell_of(
        self, x: float | np.ndarray, y: float | np.ndarray
    ) -> tuple[int | np.ndarray, int | np.ndarray]:
        """Cell indices ``(floor(x / res), floor(y / res))`` of map-frame points.

        Each coordinate is converted on its own: a scalar gives a Python ``int``,
        an array gives an ``int64`` array of the same shape.  Floor (not
        truncation) keeps cells uniform across zero, so ``x = -0.01`` lands in
        cell ``-1``, not ``0``.
        """
        return self._axis_cell(x, "x"), self._axis_cell(y, "y")

    def _axis_cell(self, v: float | np.ndarray, name: str) -> int | np.ndarray:
        if np.ndim(v) == 0:
            f = float(v)  # type: ignore[arg-type]
            if not math.isfinite(f):
                raise ValueError(f"{name} must be finite, got {v!r}")
            return math.floor(f / self.resolution)
        a = np.asarray(v, dtype=np.float64)
        if not np.isfinite(a).all():
            raise ValueError(f"{name} contains non-finite values")
        return np.floor(a / self.resolution).astype(np.int64)

    # ------------------------------------------------------------------ writing

    def _new_tile(self) -> np.ndarray:
        return np.full((self.tile_size, self.tile_size), self.fill, dtype=self.dtype)

    def update(
        self,
        ix0: int,
        iy0: int,
        patch: np.ndarray,
        op: Op,
        mask: np.ndarray | None = None,
    ) -> None:
        """Combine ``patch`` into the grid with ``op``; ``patch[0, 0]`` is cell ``(ix0, iy0)``.

        For every tile the patch overlaps, ``op(dest_view, src_view)`` is called
        once with the overlapping tile region and patch region (same shape);
        ``op`` must modify ``dest_view`` in place, e.g.
        ``lambda d, s: np.add(d, s, out=d)``.  Working per tile on views keeps the
        cost at a handful of numpy calls per update instead of per cell.

        Parameters
        ----------
        ix0, iy0
            Cell of ``patch[0, 0]``; may be negative (the map grows every way).
        patch
            2-D array indexed ``[iy, ix]`` like the grid.
        op
            In-place combiner ``op(dest, src) -> None``.  Returning a new array
            (``lambda d, s: d + s``) would silently drop the update, so it is
            rejected with ``ValueError``.
        mask
            Allocation hint with the patch's shape.  A tile that does not exist
            yet is created (filled with ``fill``) only if the overlapping part of
            ``mask`` has a True value; otherwise that part of the update is
            skipped, so the caller promises ``op`` leaves ``fill`` unchanged where
            ``mask`` is False.  Tiles that already exist always receive ``op``
            over the whole overlap.  ``None`` allocates every overlapped tile.
        """
        ix0 = _as_int(ix0, "ix0")
        iy0 = _as_int(iy0, "iy0")
        patch = np.asarray(patch)
        if patch.ndim != 2:
            raise ValueError(f"patch must be 2-D [iy, ix], got shape {patch.shape}")
        if mask is not None:
            mask = np.asarray(mask)
            if mask.shape != patch.shape:
                raise ValueError(f"mask shape {mask.shape} does not match patch shape {patch.shape}")
        if not callable(op):
            raise ValueError(f"op must be callable op(dest, src), got {op!r}")
        h, w = patch.shape
        if h == 0 or w == 0:
            return
        ts = self.tile_size
        tiles = self._tiles
        ix1, iy1 = ix0 + w, iy0 + h
        for ty in _span(iy0, iy1, ts):
            base_y = ty * ts
            y_lo, y_hi = max(iy0, base_y), min(iy1, base_y + ts)
            ps_y = slice(y_lo - iy0, y_hi - iy0)
            ts_y = slice(y_lo - base_y, y_hi - base_y)
            for tx in _span(ix0, ix1, ts):
                base_x = tx * ts
                x_lo, x_hi = max(ix0, base_x), min(ix1, base_x + ts)
                ps_x = slice(x_lo - ix0, x_hi - ix0)
                tile = tiles.get((tx, ty))
                if tile is None:
                    if mask is not None and not mask[ps_y, ps_x].any():
                        continue
                    tile = tiles[(tx, ty)] = self._new_tile()
                dest = tile[ts_y, slice(x_lo - base_x, x_hi - base_x)]
                result = op(dest, patch[ps_y, ps_x])
                if result is not None and result is not dest and not (
                    isinstance(result, np.ndarray) and np.may_share_memory(result, dest)
                ):
                    raise ValueError(
                        "op must modify dest in place and return None or dest "
                        "(e.g. lambda d, s: np.add(d, s, out=d)); it returned a new value"
                    )

    # ------------------------------------------------------------------ reading

    def window(self, ix0: int, iy0: int, height: int, width: int) -> np.ndarray:
        """A ``(height, width)`` copy of the cells starting at ``(ix0, iy0)``; unallocated cells read as ``fill``.

        A copy, not a view, because the window usually straddles several tiles
        and callers must not be able to corrupt the map by writing to it.
        """
        ix0 = _as_int(ix0, "ix0")
        iy0 = _as_int(iy0, "iy0")
        height = _as_int(height, "height")
        width = _as_int(width, "width")
        if height < 0 or width < 0:
            raise ValueError(f"window height and width must be >= 0, got {height} x {width}")
        out = np.full((height, width), self.fill, dtype=self.dtype)
        if height == 0 or width == 0 or not self._tiles:
            return out
        ts = self.tile_size
        ix1, iy1 = ix0 + width, iy0 + height
        txs, tys = _span(ix0, ix1, ts), _span(iy0, iy1, ts)
        # Visit whichever is smaller: the tile slots in the window or the allocated tiles.
        if len(txs) * len(tys) <= len(self._tiles):
            keys = [(tx, ty) for ty in tys for tx in txs if (tx, ty) in self._tiles]
        else:
            keys = [k for k in self._tiles if k[0] in txs and k[1] in tys]
        for tx, ty in keys:
            tile = self._tiles[(tx, ty)]
            bx, by = tx * ts, ty * ts
            x_lo, x_hi = max(ix0, bx), min(ix1, bx + ts)
            y_lo, y_hi = max(iy0, by), min(iy1, by + ts)
            out[y_lo - iy0 : y_hi - iy0, x_lo - ix0 : x_hi - ix0] = tile[
                y_lo - by : y_hi - by, x_lo - bx : x_hi - bx
            ]
        return out

    def bounds(self) -> tuple[int, int, int, int] | None:
        """``(ix_min, iy_min, ix_max_exclusive, iy_max_exclusive)`` of allocated tiles, or ``None`` if empty."""
        if not self._tiles:
            return None
        ts = self.tile_size
        txs = [k[0] for k in self._tiles]
        tys = [k[1] for k in self._tiles]
        return min(txs) * ts, min(tys) * ts, (max(txs) + 1) * ts, (max(tys) + 1) * ts

    def to_dense(self) -> tuple[np.ndarray, tuple[int, int]]:
        """The bounding box of allocated tiles as one array, and the ``(ix, iy)`` of its ``[0, 0]`` cell.

        An empty grid gives a ``(0, 0)`` array and origin ``(0, 0)``.  Meant for
        saving and display; the array can be much larger than :attr:`nbytes`.
        """
        b = self.bounds()
        if b is None:
            return np.full((0, 0), self.fill, dtype=self.dtype), (0, 0)
        ix_min, iy_min, ix_max, iy_max = b
        return self.window(ix_min, iy_min, iy_max - iy_min, ix_max - ix_min), (ix_min, iy_min)

    @property
    def n_tiles(self) -> int:
        """Number of allocated tiles."""
        return len(self._tiles)

    @property
    def nbytes(self) -> int:
        """Bytes held by tile arrays (excludes the small per-tile Python overhead)."""
        return sum(t.nbytes for t in self._tiles.values())

    def tiles(self) -> Iterator[tuple[tuple[int, int], np.ndarray]]:
        """Yield ``((tx, ty), tile)`` for allocated tiles, sorted by ``(tx, ty)``.

        The tiles are the live ``(tile_size, tile_size)`` arrays (no copy, so
        serialisers stay cheap); writing to them writes to the map.  Tile
        ``(tx, ty)``'s ``[0, 0]`` is cell ``(tx * tile_size, ty * tile_size)``.
        """
        for key in sorted(self._tiles):
            yield key, self._tiles[key]

    def __repr__(self) -> str:
        return (
            f"TiledGrid(resolution={self.resolution}, dtype={self.dtype}, fill={self.fill!r}, "
            f"tile_size={self.tile_size}, n_tiles={self.n_tiles})"
        )
