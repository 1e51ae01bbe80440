"""Linear feature prediction for sonar (O'Sullivan et al., AROB 2004).

A sonar reports the nearest echo anywhere in its 30-degree cone, and loses
echoes from walls met at a grazing angle (specular reflection): the wall is
then simply not there for that reading, and a map that trusts it clears free
space straight through the wall.  Indoors most of what a sonar sees is
straight walls, so the readings can check each other:

1. **Features.**  While the robot drives along a wall, the echoes of one
   sensor line up.  Runs of collinear echoes from one sensor become line
   segments; collinear, overlapping segments of several sensors merge into
   one feature, whose support is the number of echoes behind it.
2. **Prediction.**  Every reading is predicted from the features: the range
   at which its cone would first meet one (exactly, with the simulator's cone
   geometry).  A reading that agrees gains confidence; a reading with no echo
   where a feature predicts a wall is a specular loss, and its free space ends
   at that wall instead of at the maximum range.

The paper's offline map generator (section 6) builds on this; see
:mod:`blocks.maps.offline`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["LinearFeature", "extract_linear_features", "merge_features",
           "predict_ranges", "sensor_poses_along"]


@dataclass(frozen=True)
class LinearFeature:
    """A straight wall piece seen by the sonar.

    Attributes
    ----------
    p0, p1
        End points (m, map frame): the extent over which echoes support it.
    normal
        Unit normal of the line, pointing from the wall towards where the
        sensors were.
    points
        (K, 2) echo points on the wall that support it.
    residual
        RMS distance (m) of the points from the line.
    """

    p0: np.ndarray
    p1: np.ndarray
    normal: np.ndarray
    points: np.ndarray
    residual: float

    @property
    def support(self) -> int:
        """How many echoes back the feature up."""
        return len(self.points)

    @property
    def length(self) -> float:
        return float(np.hypot(*(self.p1 - self.p0)))


def sensor_poses_along(poses: np.ndarray, mounts: np.ndarray) -> np.ndarray:
    """Map-frame poses (T, N, 3) of N sensors mounted at ``mounts`` on robot ``poses`` (T, 3)."""
    poses = np.asarray(poses, dtype=np.float64)
    mounts = np.asarray(mounts, dtype=np.float64)
    c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
    x = poses[:, 0:1] + c * mounts[None, :, 0] - s * mounts[None, :, 1]
    y = poses[:, 1:2] + s * mounts[None, :, 0] + c * mounts[None, :, 1]
    return np.stack([x, y, poses[:, 2:3] + mounts[None, :, 2]], axis=-1)


def _fit_line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid and unit direction of the total-least-squares line through ``points``."""
    centre = points.mean(axis=0)
    d = points - centre
    sxx, syy, sxy = float(d[:, 0] @ d[:, 0]), float(d[:, 1] @ d[:, 1]), float(d[:, 0] @ d[:, 1])
    angle = 0.5 * math.atan2(2 * sxy, sxx - syy)  # major axis of the scatter
    return centre, np.array([math.cos(angle), math.sin(angle)])


def _reflection_points(sensors: np.ndarray, ranges: np.ndarray, normal: np.ndarray,
                       half_cone: float) -> np.ndarray:
    """Where each echo came from, given that the wall's normal is ``normal``.

    The echo comes from the point of the wall nearest the sensor inside the
    cone: straight along ``-normal`` if that direction is inside the cone,
    else along the cone edge nearest to it.  Using the beam axis instead
    would put echoes of oblique walls in front of the wall.
    """
    toward = math.atan2(-normal[1], -normal[0])
    offset = (toward - sensors[:, 2] + np.pi) % (2 * np.pi) - np.pi
    heading = sensors[:, 2] + np.clip(offset, -half_cone, half_cone)
    return sensors[:, :2] + ranges[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])


def _feature_from(points: np.ndarray, sensors: np.ndarray, ranges: np.ndarray,
                  half_cone: float) -> LinearFeature:
    """Fit a feature to one run of echoes (axis points give the direction, then the
    reflection points give the line's offset and extent)."""
    centre, direction = _fit_line(points)
    normal = np.array([-direction[1], direction[0]])
    if np.dot(sensors[:, :2].mean(axis=0) - centre, normal) < 0:
        normal = -normal
    wall = _reflection_points(sensors, ranges, normal, half_cone)
    return _refit(wall, sensors[:, :2].mean(axis=0) - wall.mean(axis=0))


def extract_linear_features(sensors: np.ndarray, ranges: np.ndarray, echo: np.ndarray,
                            cone_deg: float = 30.0, *, line_tol: float = 0.04,
                            max_gap: float = 0.3, min_points: int = 6,
                            min_length: float = 0.3, recent: int = 20) -> list[LinearFeature]:
    """Runs of collinear echoes, sensor by sensor, as line features.

    Parameters
    ----------
    sensors
        (T, N, 3) sensor poses in the map frame, one row per scan.
    ranges, echo
        (T, N) readings (m) and whether each was a real echo.
    cone_deg
        The sonar's full cone angle.
    line_tol
        How far (m) an echo may lie from the line of its run and still extend it.
    max_gap
        Largest distance (m) between consecutive echoes of a run.
    min_points, min_length
        A run needs this many echoes spanning this length (m) to count: short
        runs are corners, door jambs and the robot turning on the spot.
    recent
        A new echo is tested against the line through the run's last
        ``recent`` echoes.

    Returns
    -------
    list of LinearFeature
        One per run, not yet merged across sensors (see :func:`merge_features`).
    """
    half = math.radians(cone_deg) / 2
    axis = sensors[..., :2] + ranges[..., None] * np.stack(
        [np.cos(sensors[..., 2]), np.sin(sensors[..., 2])], axis=-1)
    features: list[LinearFeature] = []
    for j in range(sensors.shape[1]):
        rows = np.flatnonzero(echo[:, j])
        run: list[int] = []

        def close(run: list[int]) -> None:
            if len(run) < min_points:
                return
            pts = axis[run, j]
            if np.hypot(*(pts[-1] - pts[0])) < min_length:
                return
            feature = _feature_from(pts, sensors[run, j], ranges[run, j], half)
            if (feature.length >= min_length and feature.residual <= line_tol
                    and _explains(feature, sensors[run, j], ranges[run, j], cone_deg,
                                  2 * line_tol)):
                features.append(feature)

        for t in rows:
            p = axis[t, j]
            if run and np.hypot(*(p - axis[run[-1], j])) > max_gap:
                close(run)
                run = []
            if len(run) >= 3:  # the recent part only: odometry drift bends long walls
                centre, direction = _fit_line(axis[run[-recent:], j])
                if abs(direction[0] * (p[1] - centre[1]) - direction[1] * (p[0] - centre[0])) > line_tol:
                    close(run)
                    run = run[-1:] if np.hypot(*(p - axis[run[-1], j])) <= max_gap else []
            run.append(int(t))
        close(run)
    return features


def _explains(feature: LinearFeature, sensors: np.ndarray, ranges: np.ndarray,
              cone_deg: float, tol: float, share: float = 0.8) -> bool:
    """Would a sonar read what these sensors read if the feature were the wall?

    Echo points that line up are not always a wall: a sensor closing in on a
    corner or sweeping an end wall also draws a line.  A real wall predicts
    the readings that found it (O'Sullivan's check, applied to the feature
    itself).
    """
    from sim2d.sonar import cone_ranges
    segment = np.array([[*feature.p0, *feature.p1, 0.0]])
    predicted, _ = cone_ranges(sensors, segment, math.radians(cone_deg) / 2, np.inf)
    return float(np.mean(np.abs(predicted - ranges) <= tol)) >= share


def gap_along(a: LinearFeature, b: LinearFeature) -> float:
    """Gap (m) between the two features' extents along ``a``'s line; negative if they overlap."""
    direction = np.array([a.normal[1], -a.normal[0]])
    a0, a1 = sorted((0.0, float(np.dot(a.p1 - a.p0, direction))))
    b0, b1 = sorted((float(np.dot(b.p0 - a.p0, direction)), float(np.dot(b.p1 - a.p0, direction))))
    return max(a0, b0) - min(a1, b1)


def _mergeable(a: LinearFeature, b: LinearFeature, angle_tol: float, offset_tol: float,
               max_gap: float) -> bool:
    if np.dot(a.normal, b.normal) < math.cos(angle_tol):
        return False  # different directions, or the two faces of a thin wall
    if max(abs(np.dot(b.p0 - a.p0, a.normal)), abs(np.dot(b.p1 - a.p0, a.normal))) > offset_tol:
        return False
    return gap_along(a, b) <= max_gap


def moved(f: LinearFeature, rotation: np.ndarray, pivot: np.ndarray,
          shift: np.ndarray) -> LinearFeature:
    """The feature after the rigid motion x -> pivot + rotation (x - pivot) + shift."""
    def move(x: np.ndarray) -> np.ndarray:
        return (x - pivot) @ rotation.T + pivot + shift
    return LinearFeature(p0=move(f.p0), p1=move(f.p1), normal=rotation @ f.normal,
                         points=move(f.points), residual=f.residual)


def _refit(points: np.ndarray, normal_hint: np.ndarray) -> LinearFeature:
    centre, direction = _fit_line(points)
    normal = np.array([-direction[1], direction[0]])
    if np.dot(normal, normal_hint) < 0:
        normal = -normal
    along = (points - centre) @ direction
    across = (points - centre) @ normal
    return LinearFeature(p0=centre + along.min() * direction, p1=centre + along.max() * direction,
                         normal=normal, points=points,
                         residual=float(np.sqrt(np.mean(across ** 2))))


def merge_features(features: list[LinearFeature], *, angle_tol_deg: float = 6.0,
                   offset_tol: float = 0.1, max_gap: float = 0.3) -> list[LinearFeature]:
    """Merge features that are the same wall seen by several sensors or at several times.

    Two features merge when they face the same way within ``angle_tol_deg``,
    one's end points lie within ``offset_tol`` (m) of the other's line, and
    they overlap or leave a gap of at most ``max_gap`` (m) along it.  The
    merged feature is refitted to the union of the echoes, so support adds up.
    Features are merged longest first, which keeps the result deterministic.
    """
    pool = sorted(features, key=lambda f: (-f.support, -f.length))
    angle_tol = math.radians(angle_tol_deg)
    merged = True
    while merged:
        merged = False
        out: list[LinearFeature] = []
        for f in pool:
            for i, g in enumerate(out):
                if _mergeable(g, f, angle_tol, offset_tol, max_gap):
                    out[i] = _refit(np.vstack([g.points, f.points]), g.normal)
                    merged = True
                    break
            else:
                out.append(f)
        pool = sorted(out, key=lambda f: (-f.support, -f.length))
    return pool


def predict_ranges(sensors: np.ndarray, features: list[LinearFeature], cone_deg: float,
                   max_range: float, chunk: int = 4096) -> np.ndarray:
    """The range at which each sensor's cone first meets a feature (``inf`` if none).

    ``sensors`` is (M, 3).  Uses the simulator's exact cone geometry
    (:func:`sim2d.sonar.cone_ranges`), so a prediction is what a sonar would
    read if the features were the only walls.
    """
    from sim2d.sonar import cone_ranges

    sensors = np.asarray(sensors, dtype=np.float64).reshape(-1, 3)
    if not features:
        return np.full(len(sensors), np.inf)
    segments = np.array([[*f.p0, *f.p1, 0.0] for f in features])
    out = np.empty(len(sensors))
    half = math.radians(cone_deg) / 2
    for start in range(0, len(sensors), chunk):
        part = sensors[start:start + chunk]
        out[start:start + chunk], _ = cone_ranges(part, segments, half, max_range)
    return out
