"""Where across its cone an echo came from, from how fast its range closes as the robot moves.

Why: a sonar reading says how far the nearest thing in the cone is, not
where across the cone's width it lies, so a safety check puts the echo on an
arc across the cone and, to let the robot through doors whose jambs echo at
the cones' edges, only acts on an arc that lies wholly in the way.  A wall
end met by the front corner of the body falls through that rule: the corner
is at the inner edge of a diagonal sonar's cone, and the echo's arc reaches
out to the side, clear of the body's path.  Two readings of one sonar taken
from two points of a straight drive tell more (triangulation-based fusion,
Wijk and Christensen 2000).  For a point-like target, the range closes at
``cos(b)`` metres per metre driven, where ``b`` is the target's bearing from
the direction of the drive: an echo whose range closes as fast as the robot
drives lies straight ahead of the sonar, whatever the cone's width; one
beside the path (a door jamb) closes slower and lies to the side.  A flat
face across the path closes at the full rate too, and it is in the way.

:func:`triangulate_echoes` returns those points, for the collision check to
treat as echoes known to within a point instead of an arc.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["triangulate_echoes"]


def triangulate_echoes(mounts: np.ndarray, ranges: np.ndarray, echo: np.ndarray,
                       then_xy: np.ndarray, then_ranges: np.ndarray, then_echo: np.ndarray, *,
                       cone_deg: float, max_range: float = 1.0, min_baseline: float = 0.06,
                       min_rate: float = 0.3, tolerance_deg: float = 10.0) -> np.ndarray:
    """(P, 2) points, robot frame, of echoes located by the rate their ranges closed at.

    Parameters
    ----------
    mounts
        (N, 3) sonar x, y (m) and heading (rad) in the robot's frame now.
    ranges, echo
        (N,) this scan's ranges (m) and whether each is an echo.
    then_xy
        (N, 2) where each sonar was at an earlier scan, in the robot's frame now
        (odometry carries it).
    then_ranges, then_echo
        (N,) that scan's ranges and echoes.
    cone_deg
        Full opening of a sonar cone.
    max_range
        Echoes farther than this (m) now are left out: only near ones matter
        for safety, and over a longer range a wall is not a point.
    min_baseline
        Sonars that moved less than this (m) between the scans are left out:
        the rate is noise.
    min_rate
        Ranges closing slower than this (m per m driven), or opening, are left
        out: the target is abeam or behind, or the two echoes are not one.
    tolerance_deg
        A bearing this far outside the cone is kept: the simulator's and a
        real sonar's cones are not sharp, and a face across the path that
        pokes into the cone's edge closes at the full rate.

    Examples
    --------
    A target 0.5 m straight ahead of a sonar facing 30 degrees to the left,
    heard 0.6 m away before the robot drove 0.1 m towards it:

    >>> mounts = np.array([[0.25, 0.0, math.radians(30.0)]])
    >>> then = np.array([[0.15, 0.0]])
    >>> triangulate_echoes(mounts, np.array([0.5]), np.array([True]), then,
    ...                    np.array([0.6]), np.array([True]), cone_deg=30.0,
    ...                    tolerance_deg=20.0).round(2).tolist()
    [[0.75, 0.0]]
    """
    mounts = np.asarray(mounts, dtype=np.float64).reshape(-1, 3)
    ranges = np.asarray(ranges, dtype=np.float64)
    then_ranges = np.asarray(then_ranges, dtype=np.float64)
    shift = mounts[:, :2] - np.asarray(then_xy, dtype=np.float64).reshape(-1, 2)
    baseline = np.hypot(shift[:, 0], shift[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = (then_ranges - ranges) / baseline
    use = (np.asarray(echo, bool) & np.asarray(then_echo, bool) & (ranges <= max_range)
           & (baseline >= min_baseline) & (rate >= min_rate))
    if not use.any():
        return np.zeros((0, 2))
    k = np.flatnonzero(use)
    alpha = np.arccos(np.minimum(rate[k], 1.0))
    drive = np.arctan2(shift[k, 1], shift[k, 0])
    limit = math.radians(cone_deg / 2 + tolerance_deg)
    points = []
    for sign in (1.0, -1.0):  # left or right of the drive: the cone says which
        bearing = drive + sign * alpha
        inside = np.abs(np.remainder(bearing - mounts[k, 2] + math.pi, 2 * math.pi)
                        - math.pi) <= limit
        # (nearly) straight ahead, both signs give one point: keep it once
        inside &= (sign > 0) | (alpha > 0.01)
        j = k[inside]
        b = bearing[inside]
        points.append(np.column_stack([mounts[j, 0] + ranges[j] * np.cos(b),
                                       mounts[j, 1] + ranges[j] * np.sin(b)]))
    return np.concatenate(points)
