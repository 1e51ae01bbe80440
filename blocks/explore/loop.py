"""The paper's termination rule: stop once back at the start after real progress."""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class LoopClosure:
    """Tracks a path; ``closed`` once it returns near its start after enough travel.

    Parameters
    ----------
    radius : float
        How close (m) to the start counts as back.
    min_travel : float
        Distance (m) travelled before a return counts, so leaving the start is not a loop.
    min_away : float
        How far (m) the path must have gone from the start at least once.
    """

    radius: float = 1.0
    min_travel: float = 10.0
    min_away: float = 3.0
    start: tuple[float, float] | None = None
    last: tuple[float, float] | None = None
    travelled: float = 0.0
    farthest: float = 0.0
    closed_at: float | None = None

    def update(self, x: float, y: float, time: float) -> bool:
        """Add a position; True from the moment the loop closes."""
        if self.start is None:
            self.start = self.last = (x, y)
        self.travelled += math.hypot(x - self.last[0], y - self.last[1])
        self.last = (x, y)
        away = math.hypot(x - self.start[0], y - self.start[1])
        self.farthest = max(self.farthest, away)
        if (self.closed_at is None and self.travelled >= self.min_travel
                and self.farthest >= self.min_away and away <= self.radius):
            self.closed_at = time
        return self.closed_at is not None
