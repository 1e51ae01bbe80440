"""Memory of the tiled probabilistic map on a large floor.

Requirement: the tiled map holds only the tiles it touched, and a 100 m x 100 m
floor at 5 cm per cell stays under 64 MB for the probabilistic map.  A robot
with the ATRV-mini's 16 sonars drives a synthetic trajectory over the square
(its perimeter, then crossings through the interior) with deterministic
readings, some echoes and some "no echo" maximum-range readings.

For scale: the whole square as one dense float32 array is 2000 x 2000 x 4 B
= 16 MB (1024 tiles of 64 x 64 cells), so the 64 MB bound alone would not
catch a map that allocates everything; the tile counts below do.
"""
from __future__ import annotations

import itertools
import math
import tracemalloc

import numpy as np
import pytest

from blocks.maps.logodds import LogOddsMap
from sim2d.robot import load_robot

SIDE = 100.0                 # m, the floor's edge
LIMIT = 64 * 2**20           # bytes
STRIDE = 0.4                 # m between scans: every tile the beams pass still gets hit
PERIMETER = [(1.0, 1.0), (99.0, 1.0), (99.0, 99.0), (1.0, 99.0), (1.0, 1.0)]
CROSSINGS = [(99.0, 99.0), (99.0, 50.0), (1.0, 50.0), (50.0, 1.0), (50.0, 99.0)]


def trajectory(waypoints: list[tuple[float, float]], stride: float = STRIDE) -> np.ndarray:
    """(N, 3) poses x, y, heading every ``stride`` metres along the waypoints, facing ahead."""
    poses = []
    for (x0, y0), (x1, y1) in itertools.pairwise(waypoints):
        n = max(1, math.ceil(math.hypot(x1 - x0, y1 - y0) / stride))
        heading = math.atan2(y1 - y0, x1 - x0)
        poses += [(x0 + k / n * (x1 - x0), y0 + k / n * (y1 - y0), heading) for k in range(n)]
    return np.array(poses)


def sensor_poses(pose: np.ndarray, mounts: np.ndarray) -> np.ndarray:
    """The sonars' poses in the map frame, as LogOddsMapBlock.step computes them."""
    x, y, theta = pose
    c, s = math.cos(theta), math.sin(theta)
    return np.column_stack([x + c * mounts[:, 0] - s * mounts[:, 1],
                            y + s * mounts[:, 0] + c * mounts[:, 1], theta + mounts[:, 2]])


def readings(step: int, max_range: float) -> np.ndarray:
    """Deterministic ranges: a third are "no echo" (max range), the rest echoes 0.4-3.9 m."""
    j = np.arange(16)
    echo = 0.4 + ((step * 7 + j * 5) % 36) * 0.1
    return np.where((step + j) % 3 == 0, max_range, echo)


def drive(m: LogOddsMap, poses: np.ndarray, mounts: np.ndarray) -> np.ndarray:
    """Add one scan per pose; return every sonar position used, (N * 16, 2)."""
    positions = []
    for step, pose in enumerate(poses):
        sensors = sensor_poses(pose, mounts)
        m.add_scan(sensors, readings(step, m.model.max_range))
        positions.append(sensors[:, :2])
    return np.concatenate(positions)


def dense_tiles(m: LogOddsMap) -> int:
    """Tiles a dense grid of the whole square would need."""
    return math.ceil(SIDE / m.resolution / m.tile_size) ** 2


@pytest.fixture(scope="module")
def mounts() -> np.ndarray:
    spec = load_robot("atrv_mini")
    assert len(spec.sonar_mounts) == 16
    return np.asarray(spec.sonar_mounts, dtype=np.float64)


@pytest.fixture(scope="module")
def whole_floor(mounts):
    """The perimeter and the crossings, with tracemalloc running during the updates only."""
    m = LogOddsMap()  # the default model at 0.05 m; cone tables built before tracing
    assert m.resolution == 0.05 and m.model.max_range == 4.0
    poses = trajectory(PERIMETER + CROSSINGS)
    tracemalloc.start()
    try:
        positions = drive(m, poses, mounts)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return m, positions, peak


def tile_distances(m: LogOddsMap, points: np.ndarray) -> np.ndarray:
    """For every allocated tile, the distance (m) from its rectangle to the nearest point."""
    size = m.tile_size * m.resolution
    out = []
    for (tx, ty), _ in m.grid.tiles():
        dx = np.maximum(np.maximum(tx * size - points[:, 0], points[:, 0] - (tx + 1) * size), 0)
        dy = np.maximum(np.maximum(ty * size - points[:, 1], points[:, 1] - (ty + 1) * size), 0)
        out.append(np.hypot(dx, dy).min())
    return np.array(out)


def test_a_perimeter_loop_allocates_only_the_band_it_saw(mounts):
    m = LogOddsMap()
    positions = drive(m, trajectory(PERIMETER), mounts)
    reach = m.model.max_range + m.model.arc_thickness
    assert m.grid.n_tiles < 0.5 * dense_tiles(m)          # 1024 for the whole square
    assert (tile_distances(m, positions) <= reach + m.resolution).all()
    size = m.tile_size * m.resolution
    held = {key for key, _ in m.grid.tiles()}
    assert (int(50.0 // size), int(50.0 // size)) not in held   # the middle is never touched
    # every tile a sonar stood in was allocated (its own cell is in its cone)
    stood = {(int(x // size), int(y // size)) for x, y in positions}
    assert stood <= held


def test_the_whole_floor_stays_under_64_mb(whole_floor):
    m, positions, _ = whole_floor
    tile_bytes = m.tile_size ** 2 * np.dtype(np.float32).itemsize
    assert m.grid.nbytes == m.grid.n_tiles * tile_bytes
    assert m.grid.nbytes < LIMIT, f"{m.grid.nbytes / 2**20:.1f} MB of tiles"
    assert m.grid.n_tiles < dense_tiles(m)
    reach = m.model.max_range + m.model.arc_thickness
    assert (tile_distances(m, positions) <= reach + m.resolution).all()


def test_peak_python_allocation_during_updates_is_under_64_mb(whole_floor):
    m, _, peak = whole_floor
    assert peak < LIMIT, f"peak {peak / 2**20:.1f} MB"
    assert peak >= m.grid.nbytes   # the tracer did see the tiles (numpy reports to tracemalloc)


def test_dense_view_covers_exactly_the_touched_extent(whole_floor):
    m, positions, _ = whole_floor
    dense, (ix0, iy0) = m.grid.to_dense()
    touched_y, touched_x = np.nonzero(dense)
    lo_x, hi_x = ix0 + touched_x.min(), ix0 + touched_x.max() + 1
    lo_y, hi_y = iy0 + touched_y.min(), iy0 + touched_y.max() + 1
    ts = m.tile_size
    # the dense view is the tile-aligned box around the touched cells, no larger
    assert (ix0, iy0) == (lo_x // ts * ts, lo_y // ts * ts)
    assert (ix0 + dense.shape[1], iy0 + dense.shape[0]) == (-(-hi_x // ts) * ts,
                                                             -(-hi_y // ts) * ts)
    # and the touched cells are where the beams could reach
    reach = m.model.max_range + m.model.arc_thickness + m.resolution
    res = m.resolution
    assert lo_x * res >= positions[:, 0].min() - reach
    assert hi_x * res <= positions[:, 0].max() + reach
    assert lo_y * res >= positions[:, 1].min() - reach
    assert hi_y * res <= positions[:, 1].max() + reach
    # the beams crossed the whole square: it spans ~100 m each way
    assert (hi_x - lo_x) * res > SIDE and (hi_y - lo_y) * res > SIDE
