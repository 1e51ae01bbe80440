"""Which of a world's signs a run passed close enough to read: the denominator of its score.

A robot that follows the right-hand wall never enters most rooms, so scoring
its signs against every sign of the floor would blame the reader for the
exploration.  A sign counts as *along the path* when, from some pose of the
true path, the plate is within reading range, faces the robot well enough and
is not hidden behind a wall.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["signs_along_path"]


def signs_along_path(world: Any, path: np.ndarray, *, max_range: float = 3.0,
                     max_view_deg: float = 60.0, step: int = 5) -> list[Any]:
    """The world's signs that the path passed within reading range and view.

    Parameters
    ----------
    world : sim2d.world.World
        Walls (``segments``) and ``signs``.
    path : (T, 3) array
        True robot poses (x, y, theta).
    max_range : float
        Farthest reading distance (m) from the robot's centre to the plate.
    max_view_deg : float
        Most oblique usable view: the angle between the plate's normal and the
        line of sight.
    step : int
        Use every ``step``-th pose (the path is dense).

    Returns
    -------
    list of Sign
        In the world's order.
    """
    from sim2d.camera import cast_rays

    points = np.asarray(path, dtype=np.float64).reshape(-1, 3)[::max(1, step), :2]
    if not len(points):
        return []
    cos_max = math.cos(math.radians(max_view_deg))
    out = []
    for sign in world.signs:
        to_robot = points - np.array([sign.x, sign.y])
        dist = np.hypot(to_robot[:, 0], to_robot[:, 1])
        normal = np.array([math.cos(sign.facing), math.sin(sign.facing)])
        with np.errstate(invalid="ignore", divide="ignore"):
            cos_view = (to_robot @ normal) / dist
        near = np.flatnonzero((dist <= max_range) & (dist > 1e-6) & (cos_view >= cos_max))
        for i in near:
            ox, oy = points[i]
            angle = math.atan2(sign.y - oy, sign.x - ox)
            t, _ = cast_rays((ox, oy), np.array([angle]), world.segments)
            if t[0] >= dist[i] - 0.15:  # the plate hangs on the wall the ray meets
                out.append(sign)
                break
    return out
