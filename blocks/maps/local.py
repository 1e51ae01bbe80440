"""Offline maps of recent scans, rebuilt often and cheaply (for the room visits).

The room visitor (:mod:`blocks.navigate.rooms`) asks for the offline map
(:mod:`blocks.maps.offline`, no drift correction) of the scans of the last
half minute near a point, about ten times a visit.  Successive windows share
most of their scans, so each part of the map is kept between calls:

* linear features: runs, line tests and merges of the same scans are looked
  up (:class:`blocks.maps.features.FeatureMemo`), with the same result;
* the beams' log-odds: summed exactly on a difference grid, starting from
  the kept sum whose beams differ least from the new ones
  (:class:`blocks.maps.sectors.BeamSums`).

The features, predictions and reading classes are those of
:func:`~blocks.maps.offline.build_offline_map`; the log-odds are the exact
sums of the same beams, where the offline map rounds each addition to
float32 (a difference of about 1e-6 per beam, far below what moves a cell
between free, unknown and occupied), and a cell whose beams cancel out
exactly is left unknown (NaN) instead of 1/2 (unknown too).
"""
from __future__ import annotations

import bisect
from dataclasses import replace

import numpy as np

from .cones import cone_spans
from .features import (FeatureMemo, extract_linear_features, merge_features, predict_ranges,
                       sensor_poses_along)
from .offline import (OfflineMap, OfflineMapParams, beam_codes, classify_readings, cone_reach,
                      finish_map, grid_extent, reading_model)
from .sectors import Beams, BeamSums

__all__ = ["LocalMaps"]


class LocalMaps:
    """The scans of a run as they come, and the offline map of any recent subset of them.

    Parameters
    ----------
    mounts
        (N, 3) sonar mounts on the robot.
    cone_deg, max_range, max_range_margin
        The sonar (as :func:`~blocks.maps.offline.build_offline_map`).
    params
        :class:`~blocks.maps.offline.OfflineMapParams`; drift correction is off.
    keep
        How many past maps' sums to keep for the next ones.

    Examples
    --------
    >>> maps = LocalMaps(np.array([[0.0, 0.0, 0.0]]))
    >>> for k in range(8):  # a robot standing 1 m from a wall
    ...     maps.add(0.1 * k, np.array([0.0, 0.0, 0.0]), np.array([1.0]))
    >>> built = maps.build(maps.window(0.0, (0.0, 0.0), 5.0))
    >>> occupied, free, _ = built.map.classes()
    >>> bool(occupied.any()), bool(free.any())
    (True, True)
    """

    def __init__(self, mounts: np.ndarray, *, cone_deg: float = 30.0, max_range: float = 4.0,
                 max_range_margin: float = 0.05, params: OfflineMapParams | None = None,
                 keep: int = 6) -> None:
        self.mounts = np.asarray(mounts, dtype=np.float64).reshape(-1, 3)
        self.cone_deg, self.max_range = float(cone_deg), float(max_range)
        self.max_range_margin = float(max_range_margin)
        self.params = replace(params or OfflineMapParams(), correct_drift=False)
        self.reach = cone_reach(self.max_range, self.params)
        self._times: list[float] = []
        self._poses = np.empty((0, 3))
        self._ranges = np.empty((0, len(self.mounts)))
        self._count = 0
        self._memo = FeatureMemo()
        self._sums = BeamSums(cone_spans(self.params.resolution, self.cone_deg, self.reach),
                              keep=keep)

    def __len__(self) -> int:
        return self._count

    def add(self, time: float, pose: np.ndarray, ranges: np.ndarray) -> None:
        """Log a scan: the robot's pose (x, y, theta) and the N readings (m)."""
        if self._times and time < self._times[-1]:
            raise ValueError(f"scans must come in time order: {time} after {self._times[-1]}")
        if self._count == len(self._poses):  # grow by doubling
            size = max(64, 2 * self._count)
            grown_poses, grown_ranges = np.empty((size, 3)), np.empty((size, len(self.mounts)))
            grown_poses[:self._count] = self._poses[:self._count]
            grown_ranges[:self._count] = self._ranges[:self._count]
            self._poses, self._ranges = grown_poses, grown_ranges
        self._poses[self._count] = np.asarray(pose, dtype=np.float64)[:3]
        self._ranges[self._count] = np.asarray(ranges, dtype=np.float64)
        self._times.append(float(time))
        self._count += 1

    @property
    def poses(self) -> np.ndarray:
        """(T, 3) the poses logged so far."""
        return self._poses[:self._count]

    def window(self, since: float, near: tuple[float, float], radius: float) -> np.ndarray:
        """The indices of the scans taken from time ``since`` on within ``radius`` of ``near``."""
        lo = bisect.bisect_left(self._times, since)
        poses = self._poses[lo:self._count]
        close = np.hypot(poses[:, 0] - near[0], poses[:, 1] - near[1]) <= radius
        return lo + np.flatnonzero(close)

    def build(self, index: np.ndarray) -> OfflineMap:
        """The offline map of the scans ``index`` (increasing), without drift correction."""
        index = np.asarray(index, dtype=np.int64)
        if index.ndim != 1 or len(index) == 0 or (np.diff(index) <= 0).any() \
                or index[-1] >= self._count:
            raise ValueError("index must name logged scans, in increasing order")
        p = self.params
        poses, ranges = self._poses[index], self._ranges[index]
        echo = ranges < self.max_range - self.max_range_margin
        sensors = sensor_poses_along(poses, self.mounts)  # (T, N, 3)
        found = extract_linear_features(sensors, ranges, echo, self.cone_deg, ids=index,
                                        memo=self._memo)
        features = [f for f in merge_features(found, memo=self._memo)
                    if f.support >= p.min_support]
        flat = sensors.reshape(-1, 3)
        keys = (index[:, None] * len(self.mounts) + np.arange(len(self.mounts))).ravel()
        predicted = predict_ranges(flat, features, self.cone_deg, self.max_range, ids=keys,
                                   memo=self._memo).reshape(ranges.shape)
        cls = classify_readings(ranges, echo, predicted, self.max_range, p.agree_tol)
        free_to, hit_at, weight = reading_model(ranges, echo, cls, predicted, self.max_range, p)
        col, row, degree, free, lo, hi = beam_codes(flat, free_to, hit_at, p.resolution,
                                                    p.arc_thickness)
        beams = Beams(row, col, degree, free, lo, hi,
                      (p.l_free * weight).astype(np.float32).astype(np.float64),
                      (p.l_occ * weight).astype(np.float32).astype(np.float64))
        corner, shape = grid_extent(flat, self.reach, p.resolution)
        log_odds = self._sums(keys, beams, (corner[1], corner[0]), shape)
        m = finish_map(log_odds, log_odds != 0, corner, features, p)
        return OfflineMap(map=m, features=features, reading_class=cls, predicted=predicted,
                          poses=poses)
