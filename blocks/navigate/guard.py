"""A sonar guard: would this motion run into something the sonars hear?

Why: a path planned on a sonar map trusts the map, and the map misses what
the sonar never heard square on (a door jamb seen at a grazing angle, the
corner of a wall block) and is off by the odometry's drift.  The sonars of
this very tick are the last word.  Each echo is put in the robot's frame as
an arc across its cone (a sonar cone does not say where across its width the
echo came from), and a motion is refused if a whole arc lies where the body
is about to go: then the echo is there whichever part of the cone it came
from.  An arc only partly there is most often a door jamb at the edge of a
cone while the robot passes through the door's middle; what such an arc
misses, the bumpers catch.  The zones:

* driving ahead: the strip ``ahead`` metres deep in front of the body, as
  wide as the body plus ``side_margin``;
* backing: the same strip behind it;
* turning on the spot: the ring between the body and the circle its
  corners sweep, plus ``turn_margin``.

A reading without an echo says nothing: such beams are left out.

:meth:`SonarGuard.collision_time` asks the same question of a whole motion
rather than of a zone: how soon would the body, driving on at (v, w), cover
an echo's arc?  That is the swept footprint a curving motion needs, where the
straight strip misses the front corner that swings out in a turn.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["SonarGuard", "felt_walls", "swept_poses", "wall_hypotheses"]


def wall_hypotheses(arcs: np.ndarray, extent: float, points: int = 5) -> np.ndarray:
    """(E, S, P, 2) for each arc point, a wall through it tangent to the arc, ``extent`` (m)
    either way.

    Why: a sonar hears a flat wall where its beam meets it square on, so an echo
    at a point of the arc means a wall through that point across the beam,
    which is the arc's own tangent there.  A wall met obliquely ahead echoes
    only in a diagonal sonar, at its cone's edge beside the body, and the
    point itself lies just outside the swept footprint while the wall
    through it crosses the body's path.  The tangent is taken from the arc's
    neighbouring points, so arcs carried into another frame keep it; an arc
    shrunk to one point (a touching echo, a triangulated point) stays a point.

    Examples
    --------
    >>> arc = np.array([[[1.0, -0.1], [1.0, 0.0], [1.0, 0.1]]])  # an echo square ahead
    >>> wall_hypotheses(arc, 0.2, points=3)[0, 1].round(2).tolist()
    [[1.0, -0.2], [1.0, 0.0], [1.0, 0.2]]
    """
    arcs = np.asarray(arcs, dtype=np.float64)
    if extent <= 0.0 or arcs.shape[1] < 2:
        return arcs[:, :, None, :]
    ahead = np.concatenate([arcs[:, 1:], arcs[:, -1:]], axis=1)
    behind = np.concatenate([arcs[:, :1], arcs[:, :-1]], axis=1)
    tangent = ahead - behind
    length = np.hypot(tangent[..., 0], tangent[..., 1])[..., None]
    tangent = np.divide(tangent, length, out=np.zeros_like(tangent), where=length > 1e-9)
    offsets = np.linspace(-extent, extent, points)
    return arcs[:, :, None, :] + offsets[None, None, :, None] * tangent[:, :, None, :]


def felt_walls(length: float, width: float, spans: list[tuple[float, float]], v: float,
               w: float, extent: float = 0.3, spacing: float = 0.05, offset: float = 0.005,
               normals: int = 19) -> np.ndarray:
    """(P, 2) robot-frame points of the walls that pressed bumpers say the body touches.

    Why: a contact switch is what a robot has where no sonar looks (past a rear
    corner, along a side flush with a wall); once pressed, the motion that
    pressed it must not go on, and the motions away from it must stay free.  A
    switch says only that the touched surface's normal (from the body to what it
    touches) lies within its span of bearings.  A flat surface touches a box at
    the corner that reaches farthest along that normal, and the touching corner
    was moving into it: of the corners so consistent with the motion (of the
    last moments), the one that drove in hardest is taken, with the mean of its
    consistent normals (a left switch pressed while backing: the rear-left
    corner, the wall behind and to the left).  The wall is the line through that
    corner square to the normal, ``offset`` (m) clear of it and ``extent`` (m)
    either way, sampled every ``spacing``.  With no motion into anything (the
    robot stood still) it is the switch's face, square to the span's middle.
    Points inside the body are dropped (a wall cannot be there).

    Parameters
    ----------
    length, width
        The body (m), centred on the robot's origin.
    spans
        (start, end) bearings (rad, robot frame, counter-clockwise) of each
        pressed switch.
    v, w
        The motion when they were pressed (m/s, rad/s).

    Examples
    --------
    >>> left = [(math.radians(45), math.radians(135))]
    >>> walls = felt_walls(0.5, 0.5, left, -0.15, 0.0)  # pressed while backing
    >>> bool(walls[:, 0].mean() < -0.2)  # by the rear-left corner: behind it
    True
    >>> round(float(np.hypot(*(walls - [-0.25, 0.25]).T).min()), 3)  # just clear of it
    0.005
    """
    half_l, half_w = length / 2, width / 2
    corners = np.array([[half_l, half_w], [half_l, -half_w], [-half_l, -half_w],
                        [-half_l, half_w]])
    along = np.arange(-extent, extent + 1e-9, spacing)
    out = []
    for start, end in spans:
        size = (end - start) % (2 * math.pi)
        bearings = start + np.linspace(0.0, size, normals)
        n = np.column_stack([np.cos(bearings), np.sin(bearings)])
        reach = n @ corners.T  # (normals, 4): how far each corner reaches along each normal
        support = reach >= reach.max(axis=1, keepdims=True) - 1e-9
        velocity = np.column_stack([v - w * corners[:, 1], w * corners[:, 0]])  # (4, 2)
        into = np.where(support, n @ velocity.T, -np.inf)  # (normals, 4)
        if into.max() > 1e-9:
            k = int(np.argmax(into.max(axis=0)))  # the corner that drove in hardest
            mean = n[into[:, k] > 1e-9].sum(axis=0)
            normal = mean / np.hypot(*mean)
            centre = corners[k]
        else:  # no motion into it: the switch's face
            middle = start + size / 2
            normal = np.array([math.cos(middle), math.sin(middle)])
            centre = corners[support[normals // 2]].mean(axis=0)
        tangent = np.array([-normal[1], normal[0]])
        out.append(centre + offset * normal + along[:, None] * tangent)
    if not out:
        return np.zeros((0, 2))
    points = np.concatenate(out)
    outside = (np.abs(points[:, 0]) > half_l) | (np.abs(points[:, 1]) > half_w)
    return points[outside]


def swept_poses(v: float, w: float, times: np.ndarray) -> np.ndarray:
    """(T, 3) poses x, y, theta after ``times`` (s) of driving at (v, w) from the origin.

    Examples
    --------
    >>> swept_poses(0.5, 0.0, np.array([2.0])).round(3).tolist()
    [[1.0, 0.0, 0.0]]
    >>> swept_poses(0.0, 1.0, np.array([math.pi / 2])).round(3).tolist()
    [[0.0, 0.0, 1.571]]
    """
    times = np.asarray(times, dtype=np.float64)
    theta = w * times
    if abs(w) < 1e-9:
        return np.column_stack([v * times, np.zeros_like(times), theta])
    radius = v / w
    return np.column_stack([radius * np.sin(theta), radius * (1.0 - np.cos(theta)), theta])


@dataclass(frozen=True)
class SonarGuard:
    """Checks motions against this tick's sonar echoes.

    Parameters
    ----------
    mounts
        (N, 3) sonar x, y (m) and heading (rad) in the robot frame.
    length, width
        The body (m), centred on the robot's origin.
    cone_deg
        Full opening of a sonar cone; each echo becomes points across it.
    max_range, max_range_margin
        Readings at or beyond ``max_range - max_range_margin`` are no echo.
    ahead
        Depth (m) of the strip in front of (or behind) the body that must be clear.
    side_margin
        The strip is this much (m) wider than the body on each side.
    turn_margin
        Clearance (m) beyond the corners' circle a turn on the spot needs.
    arc_samples
        Points per echo across the cone (odd: the axis is one of them).
    """

    mounts: np.ndarray
    length: float = 0.5
    width: float = 0.5
    cone_deg: float = 30.0
    max_range: float = 4.0
    max_range_margin: float = 0.05
    ahead: float = 0.3
    side_margin: float = 0.05
    turn_margin: float = 0.03
    arc_samples: int = 3

    @classmethod
    def for_robot(cls, spec, **tuning) -> "SonarGuard":
        """The guard of a robot file (:func:`sim2d.robot.load_robot`): its body, sonar mounts,
        cone and range; ``tuning`` sets the other fields."""
        return cls(np.asarray(spec.sonar_mounts, dtype=np.float64), length=spec.length,
                   width=spec.width, cone_deg=spec.sonar.cone_deg,
                   max_range=spec.sonar.max_range, **tuning)

    def echo_points(self, ranges: np.ndarray) -> np.ndarray:
        """(M, 2) robot-frame points of this scan's echoes, each spread across its cone."""
        mounts = np.asarray(self.mounts, dtype=np.float64).reshape(-1, 3)
        ranges = np.asarray(ranges, dtype=np.float64)
        echo = ranges < self.max_range - self.max_range_margin
        half = math.radians(self.cone_deg) / 2
        spread = np.linspace(-half, half, self.arc_samples) if self.arc_samples > 1 \
            else np.zeros(1)
        m, r = mounts[echo], ranges[echo]
        angles = m[:, 2:3] + spread[None, :]
        x = m[:, 0:1] + r[:, None] * np.cos(angles)
        y = m[:, 1:2] + r[:, None] * np.sin(angles)
        return np.column_stack([x.ravel(), y.ravel()])

    def echo_arcs(self, ranges: np.ndarray) -> np.ndarray:
        """(E, S, 2) the arc points of each echo (S = ``arc_samples``), robot frame."""
        return self.echo_points(ranges).reshape(-1, max(self.arc_samples, 1), 2)

    def collision_time(self, arcs: np.ndarray, v: float, w: float, horizon: float,
                       step: float = 0.05, margin: float = 0.03,
                       wall_extent: float = 0.0) -> float:
        """Seconds until the body, driving at (v, w), covers a whole echo arc; inf if not
        within ``horizon``.

        Parameters
        ----------
        arcs
            (E, S, 2) echo arcs in the robot's frame (:meth:`echo_arcs`, or older
            scans' arcs carried into this frame).
        v, w
            The motion (m/s, rad/s), held for the whole horizon.
        horizon, step
            How far ahead (s) the body is swept, and how finely.
        margin
            The body is grown by this much (m) on every side.
        wall_extent
            Each point of an arc stands for a wall through it, tangent to the
            arc, this long (m) either way (see :func:`wall_hypotheses`); 0: the
            point alone.

        Examples
        --------
        >>> guard = SonarGuard(np.array([[0.25, 0.0, 0.0]]))
        >>> arcs = guard.echo_arcs(np.array([0.5]))  # an echo 0.5 m ahead of the front
        >>> round(guard.collision_time(arcs, 0.5, 0.0, horizon=2.0), 2)
        0.95
        >>> guard.collision_time(arcs, -0.5, 0.0, horizon=2.0)
        inf
        """
        arcs = np.asarray(arcs, dtype=np.float64).reshape(-1, max(self.arc_samples, 1), 2)
        if len(arcs) == 0 or (abs(v) < 1e-9 and abs(w) < 1e-9) or horizon <= 0:
            return math.inf
        times = np.arange(0, int(math.ceil(horizon / step - 1e-9)) + 1) * step
        poses = swept_poses(v, w, times)
        walls = wall_hypotheses(arcs, wall_extent)  # (E, S, P, 2)
        dx = walls[None, ..., 0] - poses[:, 0, None, None, None]
        dy = walls[None, ..., 1] - poses[:, 1, None, None, None]
        c, s = np.cos(poses[:, 2])[:, None, None, None], np.sin(poses[:, 2])[:, None, None, None]
        # signed distance of each point from the body (negative inside); a wall is as near as
        # its nearest point, an arc as far as its farthest wall (the echo is on one of them)
        qx = np.abs(c * dx + s * dy) - self.length / 2
        qy = np.abs(-s * dx + c * dy) - self.width / 2
        gap = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0)) + np.minimum(
            np.maximum(qx, qy), 0.0)
        # (T, E); with points alone the walls' axis has one point: a view, no reduction
        arc_gap = (gap.min(axis=3) if gap.shape[3] > 1 else gap[..., 0]).max(axis=2)
        # a hit: within the margin and closer than now (moving along or away from an echo
        # already within the margin is no collision)
        hit = ((arc_gap[1:] <= margin) & (arc_gap[1:] < arc_gap[0] - 1e-4)).any(axis=1)
        return float(times[1:][np.argmax(hit)]) if hit.any() else math.inf

    def ease_direction(self, ranges: np.ndarray, reach: float = 0.05, tie: float = 0.05) -> int:
        """+1 to ease out of a tight spot ahead, -1 backing: by the end of the body farther
        from the echoes around it.

        Why: a robot too close to something to turn must first move straight, and which
        way matters.  Pressed askew against a wall by one front corner, backing frees
        that corner; by a rear corner, going ahead does.  Flush along a wall (the echoes
        as near to either end) it goes ahead: the sonars cover the front, while a rear
        corner may have no sonar looking past it.

        The echoes counted are those a turn on the spot would sweep into, and those
        up to ``reach`` (m) beyond (so the corners' own sonars count as much as the
        side's, however many there are), or the nearest echo if none is that close.
        An end's distance is along the body's axis, from its nearest echo; within
        ``tie`` (m) the ends count as equal.

        Examples
        --------
        >>> guard = SonarGuard(np.array([[0.2, -0.25, -1.2], [-0.2, -0.25, -1.9]]))
        >>> guard.ease_direction(np.array([0.05, 4.0]))  # by the front-right corner
        -1
        >>> guard.ease_direction(np.array([4.0, 0.05]))  # by the rear-right corner
        1
        >>> guard.ease_direction(np.array([0.05, 0.05]))  # flush along the right side
        1
        """
        points = self.echo_points(ranges)
        if len(points) == 0:
            return 1
        x, y = points[:, 0], points[:, 1]
        half_l, half_w = self.length / 2, self.width / 2
        sweep = math.hypot(half_l, half_w) + self.turn_margin
        near = ((np.abs(x) > half_l) | (np.abs(y) > half_w)) & (np.hypot(x, y) <= sweep + reach)
        if not near.any():
            near = np.hypot(x, y) == np.hypot(x, y).min()
        front_gap = float(np.min(half_l - x[near]))
        rear_gap = float(np.min(x[near] + half_l))
        return -1 if rear_gap > front_gap + tie else 1

    def blocked(self, ranges: np.ndarray, v: float, w: float) -> str:
        """Why the command (v, w) would hit an echo: 'ahead', 'behind', 'turning', or ''.

        Examples
        --------
        >>> guard = SonarGuard(np.array([[0.25, 0.0, 0.0], [-0.25, 0.0, math.pi]]))
        >>> guard.blocked(np.array([0.2, 4.0]), 0.3, 0.0)
        'ahead'
        >>> guard.blocked(np.array([0.2, 4.0]), -0.2, 0.0)
        ''
        >>> guard.blocked(np.array([4.0, 4.0]), 0.3, 0.0)
        ''
        """
        arcs = self.echo_arcs(ranges)
        if len(arcs) == 0:
            return ""
        x, y = arcs[..., 0], arcs[..., 1]
        half_l, half_w = self.length / 2, self.width / 2
        in_lane = np.abs(y) <= half_w + self.side_margin
        if v > 1e-3 and np.any(np.all(in_lane & (x >= half_l - 0.05)
                                      & (x <= half_l + self.ahead), axis=1)):
            return "ahead"
        if v < -1e-3 and np.any(np.all(in_lane & (x <= -half_l + 0.05)
                                       & (x >= -half_l - self.ahead), axis=1)):
            return "behind"
        if abs(w) > 1e-3 and abs(v) < 0.05:
            sweep = math.hypot(half_l, half_w) + self.turn_margin
            outside = (np.abs(x) > half_l) | (np.abs(y) > half_w)
            if np.any(np.all(outside & (np.hypot(x, y) <= sweep), axis=1)):
                return "turning"
        return ""
