"""A leg of a way and a turn on the spot: what every go-somewhere behaviour drives.

Why a module: room visits and plate views both follow A* ways with pure
pursuit, give a leg up when it takes too long or stops getting anywhere, and
turn on the spot to a heading; one copy of those rules keeps them alike.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .collision_monitor import EchoMemory, HeldClock
from .pursuit import PurePursuit, wrap

__all__ = ["Leg", "dedupe", "turn_rate"]


@dataclass
class Leg:
    """A way being followed by pure pursuit, with the clock that abandons it."""

    follower: PurePursuit
    started: float
    best: float = 0.0
    progress_time: float = math.nan
    last: tuple[float, float] = (0.0, 0.0)  # the command of the last step
    held: HeldClock = field(default_factory=HeldClock)  # by a collision monitor

    def __post_init__(self) -> None:
        if math.isnan(self.progress_time):
            self.progress_time = self.started

    def step(self, time: float, pose: np.ndarray, *, timeout: float,
             stall_time: float, scale: float = 1.0,
             held_time: float = math.inf,
             echoes: EchoMemory | None = None) -> tuple[float, float, str]:
        """``(v, w, outcome)``: outcome is '' while under way, else 'arrived',
        'timeout' (longer than ``timeout`` s), 'no progress' (none for ``stall_time`` s)
        or 'held' (a collision monitor let none of the leg's command through, ``scale``
        0, for ``held_time`` s: driving on into what stopped it would only touch it
        again once the monitor backs the robot off).

        With ``echoes`` (the monitor's, and ``pose`` in their odometry frame), a
        command the monitor would stop (a corner the way swings onto, a jamb
        met askew) is replaced by the nearest slow motion it lets through
        (:meth:`~blocks.navigate.collision_monitor.EchoMemory.nearest_clear`):
        the robot creeps round it and the way is kept; creeping that gets
        nowhere ends as 'no progress'.
        """
        if self.held.update(time, scale, self.last != (0.0, 0.0)) >= held_time - 1e-9:
            self.last = (0.0, 0.0)
            return 0.0, 0.0, "held"
        v, w, status = self.follower.step(pose, 0.0)
        if status == "arrived":
            return 0.0, 0.0, "arrived"
        if self.follower.progress > self.best + 0.05 or status == "turning":
            self.best, self.progress_time = max(self.best, self.follower.progress), time
        if time - self.started > timeout:
            return 0.0, 0.0, "timeout"
        if time - self.progress_time > stall_time:
            return 0.0, 0.0, "no progress"
        if echoes is not None and echoes.stops(pose, v, w):
            v, w = echoes.nearest_clear(pose, v, w) or (v, w)
        self.last = (float(v), float(w))
        return float(v), float(w), ""


def turn_rate(heading: float, theta: float, rate: float, tolerance: float) -> float | None:
    """Turn rate (rad/s) from ``theta`` toward ``heading``, slowing near it, or None once
    within ``tolerance``."""
    error = wrap(heading - theta)
    if abs(error) <= tolerance:
        return None
    return math.copysign(min(rate, max(0.15, 1.5 * abs(error))), error)


def dedupe(path: np.ndarray) -> np.ndarray:
    """The path without consecutive points closer than 1 cm (the follower needs length)."""
    path = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    keep = [0] + [k for k in range(1, len(path))
                  if np.hypot(*(path[k] - path[k - 1])) > 0.01]
    out = path[keep]
    return out if len(out) >= 2 else np.vstack([out, out[-1] + 1e-3])
