"""The paper's termination rule: stop once back at the start after going round."""
from __future__ import annotations

import math
from dataclasses import dataclass


def _wrap(angle: float) -> float:
    return math.remainder(angle, 2 * math.pi)


@dataclass
class LoopClosure:
    """Tracks a path; ``closed`` once it returns to its start, the same way round, after a lap.

    Why heading and turning as well as position: a robot that turns back in a
    dead end or at a gap too narrow for it passes its start again going the
    other way, after half a turn; a perimeter lap comes back facing the way
    it set off, having turned a whole turn (either sense: round the inside of
    a floor, or round an island).

    Parameters
    ----------
    radius : float
        How close (m) to the start counts as back.
    min_travel : float
        Distance (m) travelled before a return counts, so leaving the start is not a loop.
    min_away : float
        How far (m) the path must have gone from the start at least once.
    max_heading_error : float
        Largest difference (rad) between the heading at the start and on return.
    min_turning : float
        Smallest net turn (rad, either sense) since the start: a lap turns 2 pi.
    """

    radius: float = 1.0
    min_travel: float = 10.0
    min_away: float = 3.0
    max_heading_error: float = math.radians(60.0)
    min_turning: float = 1.5 * math.pi
    start: tuple[float, float] | None = None
    last: tuple[float, float] | None = None
    start_heading: float | None = None
    last_heading: float | None = None
    turned: float = 0.0
    travelled: float = 0.0
    farthest: float = 0.0
    closed_at: float | None = None
    refused: int = 0
    inside: bool = True

    def update(self, x: float, y: float, time: float, theta: float | None = None) -> bool:
        """Add a position (and heading, if known); True from the moment the loop closes.

        Without headings only position and travel are checked (the paper's rule).
        """
        if self.start is None:
            self.start = self.last = (x, y)
            self.start_heading = self.last_heading = theta
        self.travelled += math.hypot(x - self.last[0], y - self.last[1])
        self.last = (x, y)
        if theta is not None and self.last_heading is not None:
            self.turned += _wrap(theta - self.last_heading)
        self.last_heading = theta
        away = math.hypot(x - self.start[0], y - self.start[1])
        back = away <= self.radius
        self.farthest = max(self.farthest, away)
        if (self.closed_at is None and self.travelled >= self.min_travel
                and self.farthest >= self.min_away and back):
            if self._went_round(theta):
                self.closed_at = time
            elif not self.inside:
                self.refused += 1  # a pass by the start that is not a lap, counted on entry
        self.inside = back
        return self.closed_at is not None

    def _went_round(self, theta: float | None) -> bool:
        if theta is None or self.start_heading is None:
            return True
        return (abs(_wrap(theta - self.start_heading)) <= self.max_heading_error
                and abs(self.turned) >= self.min_turning)
