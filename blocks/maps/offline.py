"""The high-resolution offline map (the paper's section 6), from recorded readings and poses.

After exploration every reading is known at once, so each can be judged by
the others before it is drawn (:mod:`blocks.maps.features`):

* linear features (walls) are extracted from runs of collinear echoes;
* every reading is predicted from the features; a reading that agrees with
  them gains confidence, one that contradicts them loses it;
* an echo's termination is darkened (an occupied arc at the reading); a
  reading with no echo darkens nothing;
* a reading with no echo where a feature predicts a wall lost its echo to
  specular reflection: its free space ends at the predicted wall, instead of
  running through it to the maximum range;
* the features themselves are drawn as walls, weighted by their support;
* nothing marks the edge of the explored area: unexplored space stays
  unknown (unbounded), not walled in as on the online map.

Evidence adds up as log-odds (as in :mod:`blocks.maps.logodds`) on a finer
grid than the online map, by default 2.5 cm.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .cones import cone_tables, cone_window
from .drift import DriftCorrection, corrected_run
from .features import (LinearFeature, extract_linear_features, merge_features, predict_ranges,
                       sensor_poses_along)
from .mapio import OccupancyMap

__all__ = ["OfflineMapParams", "OfflineMap", "beam_codes", "build_offline_map",
           "classify_readings", "cone_reach", "finish_map", "grid_extent", "reading_model",
           "READING_CLASSES"]

#: What the feature prediction made of each reading (the codes of :func:`classify_readings`).
READING_CLASSES = ("confirmed", "unexplained", "contradicted", "specular", "open")


@dataclass(frozen=True)
class OfflineMapParams:
    """Tunable parameters of the offline map.

    Attributes
    ----------
    resolution
        Cell size (m) of the offline map.
    agree_tol
        An echo within this distance (m) of its predicted range agrees with the features.
    arc_thickness
        Depth (m) of the darkened termination of an echo.
    l_free, l_occ
        Log-odds per beam for a crossed cell and for a cell on the termination.
    confirmed, unexplained, contradicted
        Confidence weights of echoes that agree with the features, that no
        feature predicts (furniture, corners), and that reach beyond a
        predicted feature (a doorway the feature spans, or a multipath echo).
    open_weight
        Confidence of the free space of a reading with no echo and no feature
        in its cone (open space, or a wall no feature describes).
    feature_logodds
        Log-odds drawn along a feature with ``full_support`` echoes (less
        for fewer).
    min_support
        Features with fewer echoes are ignored.
    clamp
        Log-odds are kept within +-clamp.
    correct_drift
        Correct the odometry against the walls first (:mod:`blocks.maps.drift`).
    rectilinear
        Let that correction assume walls meet at right angles, so every
        straight wall measures heading (:class:`blocks.maps.drift.DriftCorrection`).
    """

    resolution: float = 0.025
    agree_tol: float = 0.1
    arc_thickness: float = 0.05
    l_free: float = -0.4
    l_occ: float = 0.85
    confirmed: float = 1.0
    unexplained: float = 0.5
    contradicted: float = 0.25
    open_weight: float = 1.0
    feature_logodds: float = 3.0
    full_support: int = 30
    min_support: int = 8
    clamp: float = 4.0
    correct_drift: bool = True
    rectilinear: bool = True

    def __post_init__(self) -> None:
        if not 0 < self.resolution <= 1:
            raise ValueError(f"resolution must be in (0, 1] m, got {self.resolution}")
        if self.l_free >= 0 or self.l_occ <= 0:
            raise ValueError("l_free must be negative and l_occ positive")
        for name in ("confirmed", "unexplained", "contradicted", "open_weight"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name} must be a weight in [0, 1]")


@dataclass
class OfflineMap:
    """The offline map and what went into it."""

    map: OccupancyMap
    features: list[LinearFeature]
    reading_class: np.ndarray  # (T, N) index into READING_CLASSES
    predicted: np.ndarray  # (T, N) predicted ranges (m), inf where no feature
    poses: np.ndarray  # (T, 3) the poses the map was drawn from (drift-corrected or not)
    leaning_wall: LinearFeature | None = None  # the wall that showed the floor is not square

    def class_counts(self) -> dict[str, int]:
        return {name: int((self.reading_class == i).sum()) for i, name in
                enumerate(READING_CLASSES)}


def classify_readings(ranges: np.ndarray, echo: np.ndarray, predicted: np.ndarray,
                      max_range: float, agree_tol: float) -> np.ndarray:
    """Sort readings by how the features explain them (indices into :data:`READING_CLASSES`).

    confirmed: an echo within ``agree_tol`` of the prediction; unexplained:
    an echo nearer than predicted (or with nothing predicted); contradicted:
    an echo beyond the predicted wall; specular: no echo, yet a feature in
    range; open: no echo and no feature in range.
    """
    cls = np.where(echo, 1, 4)
    cls = np.where(echo & (np.abs(ranges - predicted) <= agree_tol), 0, cls)
    cls = np.where(echo & (ranges > predicted + agree_tol), 2, cls)
    cls = np.where(~echo & (predicted < max_range), 3, cls)
    return cls.astype(np.int8)


def beam_codes(sensors: np.ndarray, free_to: np.ndarray, hit_at: np.ndarray,
               resolution: float, arc_thickness: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                          np.ndarray]:
    """Where and how far each beam is drawn, in grid cells and half cells.

    Returns
    -------
    col, row
        The apex cell, ``floor(x / resolution)`` and ``floor(y / resolution)``.
    degree
        The heading in whole degrees, 0..359 (the cone table to use).
    free_code
        Cells with a range code (half cells) below it are cleared.
    lo_code, hi_code
        Cells with a code from ``lo_code`` to ``hi_code`` are darkened (the
        echo's arc); ``hi_code`` is -1 for beams that darken nothing
        (``hit_at`` NaN).
    """
    res = resolution
    half_arc = arc_thickness / 2
    col = np.floor(sensors[:, 0] / res).astype(int)
    row = np.floor(sensors[:, 1] / res).astype(int)
    degrees = np.round(np.degrees(sensors[:, 2])).astype(int) % 360
    free_code = np.floor(2 * free_to / res).astype(int)
    hit = np.isfinite(hit_at)
    lo_code = np.where(hit, np.ceil(2 * (np.nan_to_num(hit_at) - half_arc) / res), 0).astype(int)
    hi_code = np.where(hit, np.floor(2 * (np.nan_to_num(hit_at) + half_arc) / res), -1).astype(int)
    return col, row, degrees, free_code, lo_code, hi_code


def _draw_beams(log_odds: np.ndarray, seen: np.ndarray, corner: tuple[int, int],
                sensors: np.ndarray, free_to: np.ndarray, hit_at: np.ndarray,
                w_free: np.ndarray, w_occ: np.ndarray, p: OfflineMapParams,
                cone_deg: float, reach: int) -> None:
    """Add every beam's log-odds to ``log_odds`` in place (rows y up, ``corner`` = (ix, iy)
    of element [0, 0]).  ``hit_at`` is NaN for beams that darken nothing."""
    tables = cone_tables(p.resolution, cone_deg, reach)
    col, row, degrees, free_code, lo_code, hi_code = beam_codes(
        sensors, free_to, hit_at, p.resolution, p.arc_thickness)
    far = np.maximum(free_code, hi_code)
    todo = np.flatnonzero(far > 0)  # beams that clear or darken something
    clear = (p.l_free * w_free[todo]).astype(np.float32)
    darken = (p.l_occ * w_occ[todo]).astype(np.float32)
    # each beam's log-odds by range code, looked up for its cone's cells: a cell gets
    # ``clear`` below ``free``, ``darken`` from ``lo`` to ``hi`` (the arc wins), else 0
    by_code = np.zeros(int(max(t[2].max() for t in tables)) + 1, dtype=np.float32)
    # the loop runs ~10^5 times: its numbers are Python's (no numpy scalars), made a
    # part at a time (as lists, all of them would hold ~40 MB)
    part = 4096
    for first in range(0, len(todo), part):
        at = slice(first, first + part)
        beam = todo[at]
        for k, iy, ix, degree, radius, free, lo, hi in zip(
                range(first, first + len(beam)), (row[beam] - corner[1]).tolist(),
                (col[beam] - corner[0]).tolist(), degrees[beam].tolist(),
                (far[beam] // 2 + 1).tolist(), free_code[beam].tolist(),
                lo_code[beam].tolist(), hi_code[beam].tolist()):
            window = cone_window(tables[degree], iy, ix, radius)
            if window is None:
                continue
            rows, cols, sub = window
            by_code[:max(free, 0)] = clear[k]
            if hi >= lo:  # an echo (beam_codes gives the others hi = -1 < lo)
                by_code[max(lo, 0):hi + 1] = darken[k]
            delta = by_code[sub]
            by_code[:max(free, hi + 1, 0)] = 0
            log_odds[rows, cols] += delta
            seen[rows, cols] |= delta != 0


def _draw_features(log_odds: np.ndarray, seen: np.ndarray, corner: tuple[int, int],
                   features: list[LinearFeature], p: OfflineMapParams) -> None:
    """Draw each feature as a one-cell line of log-odds, stronger with more support."""
    import cv2

    order = sorted(features, key=lambda f: f.support)  # where lines cross, the stronger wins
    first, last = _end_cells(order, corner, p.resolution)
    rows, cols = _feature_window(np.concatenate([first, last]), log_odds.shape)
    evidence = np.zeros((rows.stop - rows.start, cols.stop - cols.start), dtype=np.float32)
    for f, a, b in zip(order, first, last):
        strength = p.feature_logodds * min(1.0, f.support / p.full_support)
        cv2.line(evidence, (int(a[0]) - cols.start, int(a[1]) - rows.start),
                 (int(b[0]) - cols.start, int(b[1]) - rows.start), float(strength), 1,
                 cv2.LINE_8)
    log_odds[rows, cols] += evidence
    seen[rows, cols] |= evidence > 0


def _end_cells(features: list[LinearFeature], corner: tuple[int, int], resolution: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """(F, 2) the cells (x, y) of the features' end points ``p0`` and of their ``p1``, on the
    grid at ``corner``: ``round(p / resolution - corner - 0.5)``, element by element for
    all features at once (the same numbers as feature by feature)."""
    if not features:
        return np.zeros((0, 2), dtype=int), np.zeros((0, 2), dtype=int)
    shift = np.array(corner)
    return tuple(np.round(np.array([getattr(f, end) for f in features]) / resolution
                          - shift - 0.5).astype(int) for end in ("p0", "p1"))


def _feature_window(cells: np.ndarray, shape: tuple[int, int]) -> tuple[slice, slice]:
    """The rows and columns of the grid that hold every line's end ``cells`` ((n, 2) x, y), or the
    whole grid if one lies outside it.  Why: the lines are drawn on that window only (a
    line within its image is drawn the same wherever the image starts), not on a grid-sized
    one added everywhere."""
    whole = (slice(0, shape[0]), slice(0, shape[1]))
    if not len(cells):
        return slice(0, 0), slice(0, 0)
    x0, y0 = cells.min(axis=0)
    x1, y1 = cells.max(axis=0) + 1
    if x0 < 0 or y0 < 0 or x1 > shape[1] or y1 > shape[0]:
        return whole  # cv2 clips the lines to the grid: draw them on it as it is
    return slice(int(y0), int(y1)), slice(int(x0), int(x1))


def build_offline_map(poses: np.ndarray, ranges: np.ndarray, mounts: np.ndarray, *,
                      echo: np.ndarray | None = None, cone_deg: float = 30.0,
                      max_range: float = 4.0, max_range_margin: float = 0.05,
                      params: OfflineMapParams | None = None) -> OfflineMap:
    """The offline map of a recorded exploration.

    Parameters
    ----------
    poses
        (T, 3) robot poses x, y, theta in the map frame (odometry), one per scan.
    ranges
        (T, N) sonar readings (m).
    mounts
        (N, 3) sensor mounts x, y, theta on the robot.
    echo
        (T, N) whether each reading was a real echo; by default a reading
        within ``max_range_margin`` of ``max_range`` is "no echo".
    cone_deg, max_range
        The sonar's cone angle (deg) and maximum range (m).
    params
        :class:`OfflineMapParams`.

    Returns
    -------
    OfflineMap
        The map (cells no beam or feature touched are unknown), the merged
        features, and each reading's class and predicted range.
    """
    p = params or OfflineMapParams()
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    ranges = np.asarray(ranges, dtype=np.float64)
    if ranges.ndim != 2 or len(ranges) != len(poses) or ranges.shape[1] != len(mounts):
        raise ValueError(f"ranges must be (T, {len(mounts)}) with T = {len(poses)} poses, "
                         f"got {ranges.shape}")
    if echo is None:
        echo = ranges < max_range - max_range_margin
    echo = np.asarray(echo, dtype=bool)
    leaning_wall = None
    if p.correct_drift:
        poses, leaning_wall = corrected_run(poses, ranges, echo, mounts, cone_deg,
                                            DriftCorrection(rectilinear=p.rectilinear))
    sensors = sensor_poses_along(poses, mounts)  # (T, N, 3)
    features = [f for f in merge_features(extract_linear_features(sensors, ranges, echo, cone_deg))
                if f.support >= p.min_support]
    flat = sensors.reshape(-1, 3)
    predicted = predict_ranges(flat, features, cone_deg, max_range).reshape(ranges.shape)
    cls = classify_readings(ranges, echo, predicted, max_range, p.agree_tol)

    free_to, hit_at, weight = reading_model(ranges, echo, cls, predicted, max_range, p)
    reach = cone_reach(max_range, p)
    corner, shape = grid_extent(flat, reach, p.resolution)
    log_odds = np.zeros(shape, dtype=np.float32)
    seen = np.zeros(shape, dtype=bool)
    _draw_beams(log_odds, seen, corner, flat, free_to, hit_at, weight, weight, p,
                cone_deg, reach)
    m = finish_map(log_odds, seen, corner, features, p)
    return OfflineMap(map=m, features=features, reading_class=cls, predicted=predicted,
                      poses=poses, leaning_wall=leaning_wall)


def reading_model(ranges: np.ndarray, echo: np.ndarray, cls: np.ndarray, predicted: np.ndarray,
                  max_range: float, p: OfflineMapParams
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per reading (flattened): how far to clear, where (NaN: nowhere) to darken, with
    what confidence (see the module docstring)."""
    r, c = ranges.ravel(), cls.ravel()
    weight = np.array([p.confirmed, p.unexplained, p.contradicted, 1.0, p.open_weight])[c]
    half_arc = p.arc_thickness / 2
    specular = c == 3
    free_to = np.where(specular, predicted.ravel() - half_arc,
                       np.where(echo.ravel(), r - half_arc, np.minimum(r, max_range)))
    hit_at = np.where(echo.ravel(), r, np.nan)
    return free_to, hit_at, weight


def cone_reach(max_range: float, p: OfflineMapParams) -> int:
    """The cone radius (cells) that holds every beam and its arc."""
    return int(math.ceil((max_range + p.arc_thickness) / p.resolution)) + 1


def grid_extent(flat: np.ndarray, reach: int, res: float
                ) -> tuple[tuple[int, int], tuple[int, int]]:
    """The grid that holds every cone of sensors ``flat`` (M, 3): its corner cell
    (ix, iy) and its shape (rows, columns)."""
    x0 = math.floor(flat[:, 0].min() / res) - reach - 2
    y0 = math.floor(flat[:, 1].min() / res) - reach - 2
    x1 = math.floor(flat[:, 0].max() / res) + reach + 3
    y1 = math.floor(flat[:, 1].max() / res) + reach + 3
    return (x0, y0), (y1 - y0, x1 - x0)


def _probability(log_odds: np.ndarray) -> np.ndarray:
    """:func:`~blocks.maps.logodds.log_odds_to_probability` (float64), the same operations in
    place in one new grid instead of a grid-sized temporary for each."""
    p = np.negative(log_odds, dtype=np.float64)
    np.exp(p, out=p)
    p += 1.0
    return np.divide(1.0, p, out=p)


def finish_map(log_odds: np.ndarray, seen: np.ndarray, corner: tuple[int, int],
               features: list[LinearFeature], p: OfflineMapParams) -> OccupancyMap:
    """The map from the beams' log-odds and "seen": the features drawn on, clamped, as
    probabilities (NaN where nothing was seen).  ``log_odds`` and ``seen`` change."""
    _draw_features(log_odds, seen, corner, features, p)
    np.clip(log_odds, -p.clamp, p.clamp, out=log_odds)
    occupancy = _probability(log_odds)
    occupancy[~seen] = np.nan
    res = p.resolution
    return OccupancyMap(occupancy, res, (corner[0] * res, corner[1] * res, 0.0))
