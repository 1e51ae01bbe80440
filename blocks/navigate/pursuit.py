"""An adaptive pure-pursuit path follower for a skid-steer robot.

Why pure pursuit: it needs only the path and the pose, has one intuitive
knob (the lookahead distance), and degrades gracefully when odometry drifts.
A skid-steer base can also turn on the spot, so when the carrot point lies
far off the heading (> ``turn_in_place``) the follower stops and turns
toward it instead of swinging a wide arc into a wall.

The follower steers toward the point ``lookahead`` metres along the path from
the robot's projection on it, with curvature ``k = 2 sin(alpha) / d`` (alpha:
bearing of that point, d: its distance).  The lookahead grows with speed (a
short one at low speed hugs corners; a long one at speed is smooth), and the
speed falls with curvature, with the bearing error and near the goal, so the
robot arrives slowly enough to stop within ``goal_tolerance``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["PurePursuit", "PursuitParams"]


def wrap(a: float) -> float:
    """An angle in [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


@dataclass
class PursuitParams:
    """Tuning of :class:`PurePursuit` (SI units; defaults suit the ATRV-Mini).

    Attributes
    ----------
    cruise
        Speed on straight legs (m/s).
    max_speed, max_turn_rate
        The robot's limits (m/s, rad/s); outputs never exceed them.
    lookahead, lookahead_min
        Carrot distance (m) at cruise speed and at standstill; it scales
        linearly with speed in between.
    goal_tolerance
        Distance (m) to the goal that counts as arrived.
    turn_in_place
        Bearing error (rad) beyond which the robot stops and turns on the spot;
        it drives again once the error falls below half of it.
    curvature_slowdown
        Speed is divided by ``1 + curvature_slowdown * |k|`` (k in 1/m).
    approach_gain
        Near the goal the speed is at most ``approach_gain * distance`` (1/s).
    min_speed
        Floor of the approach speed (m/s), so the robot does not crawl forever.
    turn_gain
        Turn rate per radian of bearing error when turning in place (1/s).
    """

    cruise: float = 0.4
    max_speed: float = 1.0
    max_turn_rate: float = 1.5
    lookahead: float = 0.6
    lookahead_min: float = 0.3
    goal_tolerance: float = 0.08
    turn_in_place: float = math.radians(60.0)
    curvature_slowdown: float = 0.6
    approach_gain: float = 0.8
    min_speed: float = 0.06
    turn_gain: float = 2.0


class PurePursuit:
    """Follows one path to its end: ``step(pose, dt) -> (v, w, status)``.

    ``status`` is ``"following"`` (driving along), ``"turning"`` (turning on
    the spot toward the path) or ``"arrived"`` (within ``goal_tolerance`` of
    the last point; v = w = 0 from then on).

    Attributes
    ----------
    progress
        Arc length (m) of the robot's projection on the path; never decreases.
    cross_track
        Distance (m) from the robot to the path at the last step.
    """

    def __init__(self, path: np.ndarray, params: PursuitParams | None = None) -> None:
        path = np.asarray(path, dtype=np.float64).reshape(-1, 2)
        if len(path) == 0:
            raise ValueError("the path is empty")
        if len(path) == 1:
            path = np.vstack([path, path])
        keep = np.r_[True, np.hypot(*np.diff(path, axis=0).T) > 1e-9]
        path = path[keep] if keep.sum() >= 2 else path[[0, -1]]
        self.path = path
        self.params = params or PursuitParams()
        seg = np.diff(path, axis=0)
        self._seg = seg
        self._seg_len = np.hypot(seg[:, 0], seg[:, 1])
        self._s = np.r_[0.0, np.cumsum(self._seg_len)]
        self.length = float(self._s[-1])
        self.progress = 0.0
        self.cross_track = 0.0
        self._turning = False
        self._arrived = False
        self._v = 0.0

    @property
    def goal(self) -> np.ndarray:
        return self.path[-1]

    @property
    def remaining(self) -> float:
        """Path length (m) still ahead of the robot's projection."""
        return max(0.0, self.length - self.progress)

    def _project(self, x: float, y: float) -> tuple[float, float]:
        """Arc length of the nearest path point at or after the current progress
        (looking at most a few metres ahead, so a path that folds back on itself
        is not short-circuited), and the distance to it."""
        window = (self._s[1:] >= self.progress - 1e-9) & (self._s[:-1] <= self.progress + 3.0)
        idx = np.nonzero(window)[0]
        if idx.size == 0:
            idx = np.array([len(self._seg) - 1])
        a, d, ln = self.path[idx], self._seg[idx], self._seg_len[idx]
        t = np.where(ln > 0, ((x - a[:, 0]) * d[:, 0] + (y - a[:, 1]) * d[:, 1])
                     / np.maximum(ln, 1e-12) ** 2, 0.0)
        t = np.clip(t, 0.0, 1.0)
        px, py = a[:, 0] + t * d[:, 0], a[:, 1] + t * d[:, 1]
        dist = np.hypot(px - x, py - y)
        k = int(np.argmin(dist))
        s = float(self._s[idx[k]] + t[k] * ln[k])
        return max(s, self.progress), float(dist[k])

    def point_at(self, s: float) -> np.ndarray:
        """The path point at arc length ``s`` (clamped to the path)."""
        s = min(max(s, 0.0), self.length)
        i = int(np.searchsorted(self._s, s, side="right") - 1)
        i = min(i, len(self._seg) - 1)
        ln = self._seg_len[i]
        t = (s - self._s[i]) / ln if ln > 0 else 0.0
        return self.path[i] + t * self._seg[i]

    def step(self, pose: np.ndarray, dt: float) -> tuple[float, float, str]:
        """Velocities for this tick.

        Parameters
        ----------
        pose
            (x, y, theta) in the path's frame.
        dt
            Seconds since the last step (used only to remember the speed).
        """
        p = self.params
        x, y, theta = float(pose[0]), float(pose[1]), float(pose[2])
        if self._arrived:
            return 0.0, 0.0, "arrived"
        self.progress, self.cross_track = self._project(x, y)
        gx, gy = self.goal
        to_goal = math.hypot(gx - x, gy - y)
        if to_goal <= p.goal_tolerance and self.remaining <= p.goal_tolerance + self.cross_track:
            self._arrived = True
            self._v = 0.0
            return 0.0, 0.0, "arrived"
        frac = min(1.0, abs(self._v) / max(p.cruise, 1e-6))
        lookahead = p.lookahead_min + (p.lookahead - p.lookahead_min) * frac
        if self.remaining <= lookahead:
            tx, ty = gx, gy
        else:
            tx, ty = self.point_at(self.progress + lookahead)
        dx, dy = tx - x, ty - y
        dist = math.hypot(dx, dy)
        alpha = wrap(math.atan2(dy, dx) - theta) if dist > 1e-9 else 0.0
        # Turn on the spot when the carrot is far off the heading (with hysteresis).
        if abs(alpha) > p.turn_in_place or (self._turning and abs(alpha) > 0.5 * p.turn_in_place):
            self._turning = True
            self._v = 0.0
            w = math.copysign(min(p.max_turn_rate, p.turn_gain * abs(alpha)), alpha)
            return 0.0, w, "turning"
        self._turning = False
        curvature = 2.0 * math.sin(alpha) / max(dist, 1e-6)
        v = min(p.cruise, p.max_speed) / (1.0 + p.curvature_slowdown * abs(curvature))
        v *= max(0.0, math.cos(alpha))
        v = min(v, max(p.min_speed, p.approach_gain * to_goal))
        w = v * curvature
        if abs(w) > p.max_turn_rate:  # keep the arc, slow down
            v *= p.max_turn_rate / abs(w)
            w = math.copysign(p.max_turn_rate, w)
        self._v = v
        return v, w, "following"
