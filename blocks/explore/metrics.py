"""How well a wall follower keeps its distance: statistics of |distance - target|."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class FollowStats:
    """Collects wall distances while a wall is there; summarises the tracking error.

    Samples with no wall within ``wall_within`` metres (door openings, outer
    corners) are counted as "no wall" and left out of the error statistics.
    """

    target: float
    tolerance: float = 0.15
    wall_within: float = 2.0
    errors: list[float] = field(default_factory=list)
    missing: int = 0

    def add(self, distance: float) -> None:
        if not math.isfinite(distance) or distance > self.wall_within:
            self.missing += 1
        else:
            self.errors.append(abs(distance - self.target))

    def summary(self) -> dict[str, float | None]:
        if not self.errors:
            return {"wall_error_mean_m": None, "wall_error_p95_m": None,
                    "fraction_within_tolerance": None, "fraction_with_wall": 0.0}
        errors = np.asarray(self.errors)
        total = len(errors) + self.missing
        return {"wall_error_mean_m": round(float(errors.mean()), 4),
                "wall_error_p95_m": round(float(np.percentile(errors, 95)), 4),
                "fraction_within_tolerance": round(float((errors <= self.tolerance).mean()), 4),
                "fraction_with_wall": round(len(errors) / total, 4)}
