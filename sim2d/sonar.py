"""Sonar model: the nearest echo inside a cone, exactly, for many sensors at once.

A Polaroid sonar reports the distance to the nearest surface inside its beam
(a 30-degree cone for the ATRV-Mini). Sampling the cone with rays misses thin
objects between rays; instead each wall capsule's centre segment is clipped to
the cone's wedge and the nearest point of what remains is taken, which is
exact and vectorises over sensors x segments.

Incidence: where that nearest point is the foot of the perpendicular from the
sensor, the echo comes straight back (incidence 0). Otherwise the wall is
oblique to every ray in the cone, and the incidence is the angle between the
ray to that point and the wall's normal; above ``specular_deg`` the sound
reflects away (specular loss) and the sonar hears nothing.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_EPS = 1e-12


@dataclass(frozen=True)
class SonarSpec:
    """Beam and noise parameters shared by a sonar array."""

    max_range: float = 4.0  # m; calibration found ~4 m (rated 5.5 m)
    min_range: float = 0.1  # m; closer echoes read as this
    cone_deg: float = 30.0  # full cone angle
    noise_std: float = 0.01  # m, Gaussian range noise on echoes
    specular: bool = True  # drop echoes at grazing incidence
    specular_deg: float = 60.0  # incidence above which an echo is lost
    rate_hz: float = 10.0  # readings per second


def nearest_in_cone(ox: np.ndarray, oy: np.ndarray, c: np.ndarray, s: np.ndarray,
                    segments: np.ndarray, half_angle: float) -> tuple[np.ndarray, ...]:
    """Distance from sensors at (``ox``, ``oy``) heading (``c``, ``s``) = (cos, sin) to the
    capsules ``segments[..., :5]`` inside their cones, ``inf`` where none is; element by
    element, broadcasting sensors against capsules (as :func:`cone_ranges` does, (N, 1)
    against (1, S)) or pairing them (all (P,)).

    Returns the distance and what :func:`cone_ranges` goes on with: the clip of each
    segment to the wedge ``t0..t1``, the foot of the perpendicular ``t_foot``, the
    segment's direction ``dx, dy`` in the sensor frame, the nearest point ``cx, cy``
    and the squared length.
    """
    # Segment end points in each sensor's frame: (N, S)
    ax, ay = segments[..., 0] - ox, segments[..., 1] - oy
    bx, by = segments[..., 2] - ox, segments[..., 3] - oy
    px, py = c * ax + s * ay, -s * ax + c * ay
    qx, qy = c * bx + s * by, -s * bx + c * by
    radius = segments[..., 4]
    dx, dy = qx - px, qy - py
    # Capsule surfaces are `radius` closer: widen the wedge test by the radius, so a
    # capsule whose surface pokes into the cone counts.
    sa, ca = math.sin(half_angle), math.cos(half_angle)
    t0 = np.zeros_like(px)
    t1 = np.ones_like(px)
    for nx, ny in ((sa, -ca), (sa, ca)):  # inside the wedge: nx*x + ny*y >= -radius
        f0 = nx * px + ny * py + radius
        df = nx * dx + ny * dy
        with np.errstate(divide="ignore", invalid="ignore"):
            t_cross = -f0 / df
        entering = df > _EPS
        leaving = df < -_EPS
        t0 = np.where(entering, np.maximum(t0, t_cross), t0)
        t1 = np.where(leaving, np.minimum(t1, t_cross), t1)
        parallel_out = (np.abs(df) <= _EPS) & (f0 < 0)
        t1 = np.where(parallel_out, -1.0, t1)
    valid = t0 <= t1
    length2 = dx * dx + dy * dy
    with np.errstate(divide="ignore", invalid="ignore"):
        t_foot = np.where(length2 > _EPS, -(px * dx + py * dy) / length2, 0.0)
    t_near = np.clip(t_foot, t0, t1)
    cx, cy = px + t_near * dx, py + t_near * dy
    dist = np.hypot(cx, cy) - radius
    dist = np.where(valid & (cx > -radius), dist, np.inf)
    return dist, t0, t1, t_foot, dx, dy, cx, cy, length2


def cone_ranges(sensors: np.ndarray, segments: np.ndarray, half_angle: float,
                max_range: float) -> tuple[np.ndarray, np.ndarray]:
    """Nearest surface inside each sensor's cone, and the incidence angle there.

    Parameters
    ----------
    sensors : (..., N, 3) array
        Sensor poses ``x, y, theta`` in the world frame (m, rad).
    segments : (..., S, 5) array
        Wall capsules ``x1, y1, x2, y2, radius``. Leading axes pair stacks of
        sensors with stacks of capsules (one numpy pass for many small
        problems, as the particle filter's sixteen sonars are).
    half_angle : float
        Half the cone angle (rad), below pi/2.
    max_range : float
        Beyond this the result is ``inf``.

    Returns
    -------
    ranges : (..., N) array
        Distance to the nearest capsule surface in the cone, ``inf`` if none
        within ``max_range``.
    incidence : (..., N) array
        Angle (rad) between the ray to that point and the wall normal; 0 when
        the beam meets the wall square on; ``nan`` where there is no echo.
    """
    shape = sensors.shape[:-1]
    if sensors.shape[-2] == 0 or segments.shape[-2] == 0:
        return np.full(shape, np.inf), np.full(shape, np.nan)
    ox, oy, th = sensors[..., 0:1], sensors[..., 1:2], sensors[..., 2:3]
    dist, t0, t1, t_foot, dx, dy, cx, cy, length2 = nearest_in_cone(
        ox, oy, np.cos(th), np.sin(th), segments[..., None, :, :], half_angle)
    width = dist.shape[-1]
    best = np.argmin(dist, axis=-1).ravel() + np.arange(0, dist.size, width)  # flat indices

    def chosen(a: np.ndarray) -> np.ndarray:
        return np.broadcast_to(a, dist.shape).ravel()[best].reshape(shape)
    ranges = chosen(dist)
    # Incidence at the chosen point: 0 at the perpendicular foot, else the angle
    # between the ray and the segment normal.
    foot = chosen(t_foot)
    foot_inside = (foot >= chosen(t0)) & (foot <= chosen(t1))
    ux, uy = chosen(dx), chosen(dy)
    seg_len = np.sqrt(chosen(length2))
    rx, ry = chosen(cx), chosen(cy)
    ray_len = np.hypot(rx, ry)
    with np.errstate(divide="ignore", invalid="ignore"):
        along = np.abs(rx * ux + ry * uy) / (ray_len * seg_len)  # cos(angle ray-wall)
    incidence = np.where(foot_inside | (seg_len < _EPS), 0.0,
                         np.arcsin(np.clip(np.nan_to_num(along), 0.0, 1.0)))
    hit = np.isfinite(ranges) & (ranges <= max_range)
    return np.where(hit, np.maximum(ranges, 0.0), np.inf), np.where(hit, incidence, np.nan)


def cone_ranges_near(sensors: np.ndarray, segments: np.ndarray, half_angle: float,
                     max_range: float, chunk: int = 256) -> np.ndarray:
    """:func:`cone_ranges`' ranges of many sensors, ``chunk`` at a time, each chunk against
    only the capsules that come within ``max_range`` of one of its sensors.

    A capsule farther than ``max_range`` from every sensor of a chunk gives
    none of them a range, and dropping it keeps the others in their order, so
    the ranges are :func:`cone_ranges`' to the bit. Sensors along a path are
    close together in a chunk, which then meets a few dozen of a building's
    hundreds of capsules: faster, and small chunks stay in cache.
    """
    sensors = np.asarray(sensors, dtype=np.float64).reshape(-1, 3)
    out = np.empty(len(sensors))
    for start in range(0, len(sensors), chunk):
        part = sensors[start:start + chunk]
        lo, hi = part[:, :2].min(axis=0), part[:, :2].max(axis=0)
        centre = (lo + hi) / 2
        reach = max_range + float(np.hypot(*(hi - lo))) / 2 + 1e-6
        near = segments_near(segments, float(centre[0]), float(centre[1]), reach)
        out[start:start + chunk], _ = cone_ranges(part, near, half_angle, max_range)
    return out


def sonar_readings(sensors: np.ndarray, segments: np.ndarray, spec: SonarSpec,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """What the sonar array reports: ranges (m) and which are real echoes.

    ``ranges`` is ``max_range`` where there was no echo (nothing in range, or
    the echo was lost to specular reflection); ``echo`` tells them apart, so
    consumers never mistake "no echo" for an obstacle at ``max_range``.
    """
    true_range, incidence = cone_ranges(sensors, segments, math.radians(spec.cone_deg) / 2,
                                        spec.max_range)
    echo = np.isfinite(true_range)
    if spec.specular:
        echo &= ~(incidence > math.radians(spec.specular_deg))
    noisy = true_range + rng.normal(0.0, spec.noise_std, len(true_range)) if spec.noise_std \
        else true_range
    ranges = np.where(echo, np.clip(noisy, spec.min_range, spec.max_range), spec.max_range)
    echo &= ranges < spec.max_range
    return ranges, echo


def sensor_poses(robot_pose: np.ndarray, mounts: np.ndarray) -> np.ndarray:
    """World poses (N, 3) of sensors mounted at ``mounts`` (N, 3) on a robot at ``robot_pose``."""
    x, y, th = robot_pose
    c, s = math.cos(th), math.sin(th)
    wx = x + c * mounts[:, 0] - s * mounts[:, 1]
    wy = y + s * mounts[:, 0] + c * mounts[:, 1]
    return np.column_stack([wx, wy, th + mounts[:, 2]])


def segments_near(segments: np.ndarray, x: float, y: float, reach: float) -> np.ndarray:
    """The capsules whose surface comes within ``reach`` of (x, y): cheap culling."""
    a, d = segments[:, 0:2], segments[:, 2:4] - segments[:, 0:2]
    px, py = x - a[:, 0], y - a[:, 1]
    length2 = d[:, 0] ** 2 + d[:, 1] ** 2
    t = np.clip((px * d[:, 0] + py * d[:, 1]) / np.maximum(length2, _EPS), 0.0, 1.0)
    ex, ey = px - t * d[:, 0], py - t * d[:, 1]
    return segments[ex * ex + ey * ey <= (reach + segments[:, 4]) ** 2]
