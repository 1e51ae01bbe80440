"""Tests for the tiled occupancy grid (blocks.maps.tiles)."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blocks.maps.tiles import TiledGrid


def add(d: np.ndarray, s: np.ndarray) -> None:
    np.add(d, s, out=d)


def sat3(d: np.ndarray, s: np.ndarray) -> None:
    np.minimum(d + s, 3, out=d)


def ramp(h: int, w: int, dtype=np.int32) -> np.ndarray:
    """A patch whose every cell is distinct, so any misplacement shows."""
    return (np.arange(h * w).reshape(h, w) + 1).astype(dtype)


# ---------------------------------------------------------------- round trips


@pytest.mark.parametrize("ix0, iy0", [(-37, -5), (3, 70), (-100, 64), (0, 0), (-1, -1)])
def test_round_trip_window_and_dense(ix0, iy0):
    g = TiledGrid(0.05, dtype=np.int32, tile_size=16)
    patch = ramp(20, 35)
    g.update(ix0, iy0, patch, add)

    np.testing.assert_array_equal(g.window(ix0, iy0, 20, 35), patch)

    # A larger window shows the patch surrounded by fill.
    win = g.window(ix0 - 3, iy0 - 2, 25, 40)
    expected = np.zeros((25, 40), np.int32)
    expected[2:22, 3:38] = patch
    np.testing.assert_array_equal(win, expected)

    dense, (ox, oy) = g.to_dense()
    assert ox % 16 == 0 and oy % 16 == 0
    assert ox <= ix0 and oy <= iy0
    np.testing.assert_array_equal(dense[iy0 - oy : iy0 - oy + 20, ix0 - ox : ix0 - ox + 35], patch)
    assert dense.sum() == patch.sum()
    bx0, by0, bx1, by1 = g.bounds()
    assert (bx0, by0) == (ox, oy)
    assert dense.shape == (by1 - by0, bx1 - bx0)


def test_row_zero_is_lowest_y():
    g = TiledGrid(1.0, tile_size=4)
    patch = np.array([[1, 0], [0, 2]], np.uint8)  # row 0 = y cell 0, row 1 = y cell 1
    g.update(0, 0, patch, add)
    ix, iy = g.cell_of(1.5, 1.5)
    assert g.window(ix, iy, 1, 1)[0, 0] == 2


def test_window_is_a_copy():
    g = TiledGrid(0.1, tile_size=8)
    g.update(0, 0, np.ones((4, 4), np.uint8), add)
    w = g.window(0, 0, 4, 4)
    w[:] = 99
    assert (g.window(0, 0, 4, 4) == 1).all()


def test_empty_grid():
    g = TiledGrid(0.1)
    dense, origin = g.to_dense()
    assert dense.shape == (0, 0) and origin == (0, 0)
    assert g.bounds() is None
    assert g.n_tiles == 0 and g.nbytes == 0
    assert list(g.tiles()) == []
    assert (g.window(-5, -5, 3, 4) == 0).all() and g.window(0, 0, 3, 4).shape == (3, 4)
    assert g.window(0, 0, 0, 5).shape == (0, 5)


# ---------------------------------------------------------------- allocation


def test_tiles_allocated_only_where_touched():
    g = TiledGrid(0.05, tile_size=10)
    g.update(5, 5, np.ones((3, 3), np.uint8), add)  # inside tile (0, 0)
    assert g.n_tiles == 1
    g.update(-2, 8, np.ones((4, 4), np.uint8), add)  # x -2..1, y 8..11 -> tiles x -1,0 / y 0,1
    assert sorted(k for k, _ in g.tiles()) == [(-1, 0), (-1, 1), (0, 0), (0, 1)]
    assert g.n_tiles == 4
    assert g.nbytes == 4 * 10 * 10
    assert g.bounds() == (-10, 0, 10, 20)
    for (tx, ty), tile in g.tiles():
        assert tile.shape == (10, 10) and tile.dtype == np.uint8


def test_tile_keys_use_floor_division():
    g = TiledGrid(1.0, tile_size=8)
    g.update(-1, -8, np.ones((1, 1), np.uint8), add)
    g.update(-9, 7, np.ones((1, 1), np.uint8), add)
    assert sorted(k for k, _ in g.tiles()) == [(-2, 0), (-1, -1)]
    tiles = dict(g.tiles())
    assert tiles[(-1, -1)][0, 7] == 1  # cell (-1, -8) -> row -8 - (-8) = 0, col -1 - (-8) = 7
    assert tiles[(-2, 0)][7, 7] == 1


def test_mask_controls_allocation():
    g = TiledGrid(0.05, tile_size=4)
    patch = np.zeros((8, 8), np.uint8)
    patch[6, 1] = 5  # only tile (0, 1) has data
    g.update(0, 0, patch, add, mask=patch > 0)
    assert [k for k, _ in g.tiles()] == [(0, 1)]
    assert g.window(1, 6, 1, 1)[0, 0] == 5

    # An all-False mask allocates nothing.
    g.update(100, 100, np.ones((8, 8), np.uint8), add, mask=np.zeros((8, 8), bool))
    assert g.n_tiles == 1

    # Existing tiles still receive op over the whole overlap, whatever the mask says.
    g.update(0, 4, np.ones((4, 4), np.uint8), add, mask=np.zeros((4, 4), bool))
    assert g.n_tiles == 1
    assert g.window(0, 4, 4, 4).sum() == 16 + 5


# ---------------------------------------------------------------- op semantics


def test_saturating_add_lambda_uint8():
    g = TiledGrid(0.05, dtype=np.uint8, tile_size=16)
    op = lambda d, s: np.minimum(d + s, 3, out=d)
    patch = np.ones((10, 10), np.uint8)
    for _ in range(5):
        g.update(-4, -4, patch, op)
    np.testing.assert_array_equal(g.window(-4, -4, 10, 10), np.full((10, 10), 3, np.uint8))
    assert g.window(-5, -5, 1, 1)[0, 0] == 0


def test_op_called_once_per_overlapped_tile_with_matching_views():
    g = TiledGrid(1.0, dtype=np.int64, tile_size=8)
    calls = []

    def op(d, s):
        assert d.shape == s.shape
        calls.append(d.shape)
        np.add(d, s, out=d)

    g.update(-3, 5, ramp(12, 18, np.int64), op)  # x -3..14 -> 3 tiles, y 5..16 -> 3 tiles
    assert len(calls) == 9
    assert sum(h * w for h, w in calls) == 12 * 18
    np.testing.assert_array_equal(g.window(-3, 5, 12, 18), ramp(12, 18, np.int64))


def test_op_returning_new_array_is_rejected():
    g = TiledGrid(1.0, tile_size=4)
    with pytest.raises(ValueError, match="in place"):
        g.update(0, 0, np.ones((2, 2), np.uint8), lambda d, s: d + s)


def test_op_returning_dest_or_none_is_fine():
    g = TiledGrid(1.0, tile_size=4)
    g.update(0, 0, np.ones((2, 2), np.uint8), lambda d, s: d.__iadd__(s))
    g.update(0, 0, np.ones((2, 2), np.uint8), np.copyto)
    assert (g.window(0, 0, 2, 2) == 1).all()


# ---------------------------------------------------------------- cell_of


def test_cell_of_scalars_and_negative():
    g = TiledGrid(0.05)
    assert g.cell_of(0.0, 0.0) == (0, 0)
    assert g.cell_of(-0.01, -0.0499) == (-1, -1)
    assert g.cell_of(-0.051, 0.051) == (-2, 1)
    assert g.cell_of(-1.0 - 1e-9, 1.0 + 1e-9) == (-21, 20)
    ix, iy = g.cell_of(-0.01, 0.01)
    assert type(ix) is int and type(iy) is int


def test_cell_of_arrays():
    g = TiledGrid(0.5)
    ix, iy = g.cell_of(np.array([-1.2, -0.5, -0.1, 0.0, 0.4, 1.7]), np.array([[-3.0, 2.9]]))
    np.testing.assert_array_equal(ix, [-3, -1, -1, 0, 0, 3])
    np.testing.assert_array_equal(iy, [[-6, 5]])
    assert ix.dtype.kind == "i"
    with pytest.raises(ValueError):
        g.cell_of(np.array([np.nan]), 0.0)


# ---------------------------------------------------------------- NaN fill


def test_float32_nan_fill():
    g = TiledGrid(0.05, dtype=np.float32, fill=np.nan, tile_size=8)
    assert math.isnan(g.fill)
    patch = np.arange(12, dtype=np.float32).reshape(3, 4)
    g.update(-2, -1, patch, lambda d, s: np.fmax(d, s, out=d))  # fmax ignores NaN
    win = g.window(-3, -2, 5, 6)
    assert win.dtype == np.float32
    np.testing.assert_array_equal(win[1:4, 1:5], patch)
    assert np.isnan(win[0]).all() and np.isnan(win[:, 0]).all() and np.isnan(win[4]).all()
    dense, (ox, oy) = g.to_dense()
    assert (ox, oy) == (-8, -8) and dense.shape == (16, 16)
    assert np.count_nonzero(~np.isnan(dense)) == 12
    np.testing.assert_array_equal(dense[-1 - oy : 2 - oy, -2 - ox : 2 - ox], patch)
    empty, _ = TiledGrid(0.1, dtype=np.float32, fill=np.nan).to_dense()
    assert empty.shape == (0, 0)


# ---------------------------------------------------------------- validation


@pytest.mark.parametrize("res", [0, -0.05, float("nan"), float("inf"), "abc"])
def test_bad_resolution(res):
    with pytest.raises(ValueError, match="resolution"):
        TiledGrid(res)


@pytest.mark.parametrize("ts", [0, -4, 2.5, True])
def test_bad_tile_size(ts):
    with pytest.raises(ValueError, match="tile_size"):
        TiledGrid(0.05, tile_size=ts)


@pytest.mark.parametrize("dtype, fill", [(np.uint8, np.nan), (np.uint8, 300), (np.uint8, -1), (np.int16, 0.5)])
def test_fill_not_representable(dtype, fill):
    with pytest.raises(ValueError, match="fill"):
        TiledGrid(0.05, dtype=dtype, fill=fill)


def test_update_argument_errors():
    g = TiledGrid(0.05)
    with pytest.raises(ValueError, match="2-D"):
        g.update(0, 0, np.ones(5, np.uint8), add)
    with pytest.raises(ValueError, match="2-D"):
        g.update(0, 0, np.ones((2, 2, 2), np.uint8), add)
    with pytest.raises(ValueError, match="mask shape"):
        g.update(0, 0, np.ones((3, 4), np.uint8), add, mask=np.ones((4, 3), bool))
    with pytest.raises(ValueError, match="ix0"):
        g.update(0.5, 0, np.ones((3, 4), np.uint8), add)
    with pytest.raises(ValueError, match="height and width"):
        g.window(0, 0, -1, 3)
    assert g.n_tiles == 0


# ---------------------------------------------------------------- memory


def test_perimeter_walk_memory():
    """Walk the perimeter of a 100 m x 100 m floor; only the swept strip may be stored."""
    res, side, step, half = 0.05, 100.0, 0.25, 80
    g = TiledGrid(res, dtype=np.float32, fill=np.nan, tile_size=64)
    patch = np.ones((2 * half, 2 * half), np.float32)
    op = lambda d, s: np.fmax(d, s, out=d)
    corners = [(0.0, 0.0), (side, 0.0), (side, side), (0.0, side), (0.0, 0.0)]
    expected_tiles: set[tuple[int, int]] = set()
    n_updates = 0
    for (xa, ya), (xb, yb) in itertools.pairwise(corners):
        for k in range(round(side / step)):
            t = k * step / side
            ix, iy = g.cell_of(xa + (xb - xa) * t, ya + (yb - ya) * t)
            g.update(ix - half, iy - half, patch, op)
            n_updates += 1
            expected_tiles.update(
                (tx, ty)
                for tx in range((ix - half) // 64, (ix + half - 1) // 64 + 1)
                for ty in range((iy - half) // 64, (iy + half - 1) // 64 + 1)
            )
    assert n_updates == 1600

    full_floor_tiles = math.ceil(side / res / 64) ** 2
    assert g.nbytes < 64 * 2**20
    assert g.n_tiles == len(expected_tiles)
    assert g.n_tiles < 0.5 * full_floor_tiles
    assert g.nbytes == g.n_tiles * 64 * 64 * 4
    # The middle of the floor was never seen.
    assert np.isnan(g.window(1000, 1000, 10, 10)).all()
    assert g.window(0, 1000, 1, 1)[0, 0] == 1.0


# ---------------------------------------------------------------- property test

ORIGIN = 64  # dense-reference cell (0, 0) sits at ORIGIN so negative offsets fit
SPAN = 160

OPS = {
    "add": lambda d, s: np.add(d, s, out=d),
    "max": lambda d, s: np.maximum(d, s, out=d),
}


@st.composite
def updates(draw):
    h = draw(st.integers(1, 14))
    w = draw(st.integers(1, 14))
    ix0 = draw(st.integers(-ORIGIN, SPAN - ORIGIN - w))
    iy0 = draw(st.integers(-ORIGIN, SPAN - ORIGIN - h))
    values = np.array(draw(st.lists(st.integers(0, 9), min_size=h * w, max_size=h * w)), np.int64)
    use_mask = draw(st.booleans())
    return ix0, iy0, values.reshape(h, w), use_mask


@settings(max_examples=150, deadline=None)
@given(
    tile_size=st.integers(1, 9),
    op_name=st.sampled_from(sorted(OPS)),
    ups=st.lists(updates(), min_size=1, max_size=8),
)
def test_matches_dense_reference(tile_size, op_name, ups):
    op = OPS[op_name]
    g = TiledGrid(1.0, dtype=np.int64, fill=0, tile_size=tile_size)
    ref = np.zeros((SPAN, SPAN), np.int64)
    expected_tiles: set[tuple[int, int]] = set()
    for ix0, iy0, patch, use_mask in ups:
        h, w = patch.shape
        mask = patch > 0 if use_mask else None
        g.update(ix0, iy0, patch, op, mask=mask)
        op(ref[iy0 + ORIGIN : iy0 + ORIGIN + h, ix0 + ORIGIN : ix0 + ORIGIN + w], patch)
        for r in range(h):
            for c in range(w):
                if mask is None or mask[r, c]:
                    expected_tiles.add(((ix0 + c) // tile_size, (iy0 + r) // tile_size))

    assert {k for k, _ in g.tiles()} == expected_tiles
    np.testing.assert_array_equal(g.window(-ORIGIN, -ORIGIN, SPAN, SPAN), ref)
    dense, (ox, oy) = g.to_dense()
    if expected_tiles:
        assert dense.shape[0] <= SPAN + 2 * tile_size and dense.shape[1] <= SPAN + 2 * tile_size
        # Put the dense view back into reference coordinates and compare the overlap.
        canvas = np.zeros((SPAN + 4 * tile_size, SPAN + 4 * tile_size), np.int64)
        pad = 2 * tile_size
        canvas[oy + ORIGIN + pad : oy + ORIGIN + pad + dense.shape[0],
               ox + ORIGIN + pad : ox + ORIGIN + pad + dense.shape[1]] = dense
        np.testing.assert_array_equal(canvas[pad : pad + SPAN, pad : pad + SPAN], ref)
        assert canvas.sum() == ref.sum()
    else:
        assert dense.shape == (0, 0)
