"""Go to goals in turn: plan, follow, look around, replan when needed, give up on timeouts.

This is the navigation layer's state machine.  Per goal::

    plan --ok--> follow --arrived--> [spin 360 deg] --> reached --> next goal
      |            |  deviated > max_deviation, path blocked, stalled: replan
      |            '--timeout--> failed --> next goal
      '--PlanningError--> failed --> next goal

It is a plain class driven by ``step(pose, dt)`` so the same code runs in a
test loop against :mod:`sim2d` and inside the ``navigate.goto`` block.
"""
from __future__ import annotations

import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .grid import NavGrid
from .planner import SNAP_RADIUS, PlannedPath, PlanningError, plan
from .pursuit import PurePursuit, PursuitParams, wrap

__all__ = ["Goal", "GoalResult", "Visit", "parse_goals"]


@dataclass
class Goal:
    """A place to go: world (x, y), whether to look around there, an optional name."""

    x: float
    y: float
    spin: bool | None = None  # None: the Visit's default
    name: str = ""


@dataclass
class GoalResult:
    """What happened to one goal."""

    goal: Goal
    status: str  # "reached" or "failed"
    started: float  # s, Visit clock
    finished: float
    position: tuple[float, float]  # where the robot was at the end
    reason: str = ""
    replans: int = 0
    path_length: float = 0.0  # m, of the first plan

    @property
    def duration(self) -> float:
        return self.finished - self.started

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.goal.name, "x": self.goal.x, "y": self.goal.y,
                "status": self.status, "started": round(self.started, 3),
                "finished": round(self.finished, 3), "duration": round(self.duration, 3),
                "position": [round(v, 3) for v in self.position], "reason": self.reason,
                "replans": self.replans, "path_length": round(self.path_length, 3)}


def parse_goals(raw: Any) -> list[Goal]:
    """Goals from a message or parameter: ``[x, y]``, ``[x, y, spin]``, ``{x, y, spin?, name?}``
    or :class:`Goal`, one or a list of them.

    Raises
    ------
    ValueError
        With a sentence naming the bad item.
    """
    if raw is None:
        return []
    if isinstance(raw, (Goal, dict)) or (isinstance(raw, (list, tuple, np.ndarray)) and len(raw)
                                         and isinstance(raw[0], (int, float, np.number))):
        raw = [raw]
    goals = []
    for k, item in enumerate(raw):
        if isinstance(item, Goal):
            goals.append(item)
            continue
        try:
            if isinstance(item, dict):
                unknown = set(item) - {"x", "y", "spin", "name"}
                if unknown:
                    raise ValueError(f"unknown key(s) {sorted(unknown)}")
                spin = item.get("spin")
                goals.append(Goal(float(item["x"]), float(item["y"]),
                                  None if spin is None else bool(spin), str(item.get("name", ""))))
            else:
                values = list(item)
                if len(values) not in (2, 3):
                    raise ValueError("expected [x, y] or [x, y, spin]")
                spin = bool(values[2]) if len(values) == 3 else None
                goals.append(Goal(float(values[0]), float(values[1]), spin))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"goal {k} ({item!r}) is not [x, y], [x, y, spin] or "
                             f"{{x, y, spin, name}}: {exc}") from None
        if not (math.isfinite(goals[-1].x) and math.isfinite(goals[-1].y)):
            raise ValueError(f"goal {k} ({item!r}) is not a finite point")
    return goals


@dataclass
class _Active:
    goal: Goal
    started: float
    path: PlannedPath | None = None
    follower: PurePursuit | None = None
    replans: int = 0
    first_length: float = 0.0
    spun: float = 0.0  # rad turned so far in the look-around
    last_heading: float | None = None
    best_progress: float = 0.0
    progress_time: float = 0.0
    phase: str = "plan"  # plan, follow, spin


@dataclass
class Visit:
    """Drives to each goal in turn.

    Parameters
    ----------
    goals
        Goals (see :func:`parse_goals` for the accepted forms).
    grid
        The planning grid (replace it with :meth:`set_grid` as the map grows).
    params
        Path-follower tuning.
    spin
        Default for goals that do not say: turn 360 degrees on arrival.
    spin_rate
        Turn rate of the look-around (rad/s).
    timeout
        Seconds a goal may take, look-around included, before it is given up.
    max_deviation
        Distance (m) from the path beyond which the robot replans.
    stall_time
        Seconds without progress along the path before a replan.
    max_replans
        Replans per goal before it is given up.
    snap_radius
        How far (m) a blocked goal may be moved to free floor (see :func:`plan`).
    """

    goals: Iterable[Any]
    grid: NavGrid
    params: PursuitParams = field(default_factory=PursuitParams)
    spin: bool = False
    spin_rate: float = 0.8
    timeout: float = 90.0
    max_deviation: float = 0.5
    stall_time: float = 8.0
    max_replans: int = 10
    snap_radius: float = SNAP_RADIUS

    def __post_init__(self) -> None:
        self.queue: list[Goal] = parse_goals(list(self.goals) if not isinstance(
            self.goals, (dict, Goal)) else self.goals)
        self.results: list[GoalResult] = []
        self.time = 0.0
        self.current: _Active | None = None
        self.event: str | None = None  # "reached" / "failed" on the tick it happens
        self.status = "idle"
        self._grid_changed = False

    # ---- feeding it ---------------------------------------------------------------------------
    def add_goals(self, goals: Any) -> None:
        """Queue more goals after the ones waiting."""
        self.queue.extend(parse_goals(goals))

    def replace_goals(self, goals: Any) -> None:
        """Drop the current and waiting goals (unfinished ones are not reported) and take these."""
        self.queue = parse_goals(goals)
        self.current = None

    def set_grid(self, grid: NavGrid) -> None:
        """A new map: the current path is checked against it on the next step."""
        self.grid = grid
        self._grid_changed = True

    # ---- state ------------------------------------------------------------------------------
    @property
    def active(self) -> bool:
        """Whether a goal is being pursued (or waits)."""
        return self.current is not None or bool(self.queue)

    @property
    def done(self) -> bool:
        """Whether every goal given so far has been reached or given up."""
        return not self.active and bool(self.results)

    @property
    def reached(self) -> list[GoalResult]:
        return [r for r in self.results if r.status == "reached"]

    @property
    def failed(self) -> list[GoalResult]:
        return [r for r in self.results if r.status == "failed"]

    @property
    def path(self) -> np.ndarray | None:
        """The path being followed, (N, 2), or None."""
        c = self.current
        return None if c is None or c.path is None else c.path.points

    # ---- the machine ----------------------------------------------------------------------------
    def _finish(self, status: str, pose: np.ndarray, reason: str = "") -> None:
        c = self.current
        assert c is not None
        self.results.append(GoalResult(c.goal, status, c.started, self.time,
                                       (float(pose[0]), float(pose[1])), reason, c.replans,
                                       c.first_length))
        self.event = status
        self.current = None

    def _plan(self, pose: np.ndarray) -> bool:
        c = self.current
        assert c is not None
        try:
            path = plan(self.grid, pose[:2], (c.goal.x, c.goal.y), snap_radius=self.snap_radius)
        except PlanningError as exc:
            self._finish("failed", pose, f"planning: {exc}")
            return False
        if c.path is None:
            c.first_length = path.length
        c.path = path
        c.follower = PurePursuit(path.points, self.params)
        c.best_progress, c.progress_time = 0.0, self.time
        c.phase = "follow"
        return True

    def _replan(self, pose: np.ndarray, why: str) -> bool:
        c = self.current
        assert c is not None
        c.replans += 1
        if c.replans > self.max_replans:
            self._finish("failed", pose, f"gave up after {self.max_replans} replans ({why})")
            return False
        return self._plan(pose)

    def _path_blocked(self) -> bool:
        """Whether the rest of the current path crosses a blocked cell of the grid."""
        c = self.current
        assert c is not None and c.follower is not None and c.path is not None
        f = c.follower
        pts = c.path.points
        here = f.point_at(f.progress)
        ahead = np.r_[here[None, :], pts[np.searchsorted(f._s, f.progress, side="right"):]]
        if len(ahead) < 2:
            return False
        # A robot escaping a wall starts inside the inflation: skip that first stretch then.
        first = 0 if self.grid.is_free(*here) else 1
        return any(not self.grid.segment_free(a, b)
                   for a, b in itertools.pairwise(ahead[first:]))

    def step(self, pose: np.ndarray, dt: float) -> tuple[float, float, str]:
        """Velocities (v, w) and a status for this tick.

        Status: ``"idle"`` (no goals), ``"following"``, ``"turning"``, ``"spinning"``,
        ``"reached"`` / ``"failed"`` (on the tick a goal ends), ``"done"`` (all goals ended).
        :attr:`event` is ``"reached"`` / ``"failed"`` on that tick, else None.
        """
        pose = np.asarray(pose, dtype=np.float64)
        self.time += dt
        self.event = None
        if self.current is None:
            if not self.queue:
                self.status = "done" if self.results else "idle"
                return 0.0, 0.0, self.status
            self.current = _Active(self.queue.pop(0), self.time - dt)
            self._grid_changed = False
        c = self.current
        if self.time - c.started > self.timeout:
            self._finish("failed", pose, f"timeout after {self.timeout:g} s")
            self.status = "failed"
            return 0.0, 0.0, self.status
        if c.phase == "plan" and not self._plan(pose):
            self.status = "failed"
            return 0.0, 0.0, self.status
        if c.phase == "follow":
            v, w, status = self._follow(pose)
            if status != "arrived":
                self.status = status
                return v, w, status
            spin = self.spin if c.goal.spin is None else c.goal.spin
            if not spin:
                self._finish("reached", pose)
                self.status = "reached"
                return 0.0, 0.0, self.status
            c.phase, c.last_heading, c.spun = "spin", float(pose[2]), 0.0
        # Look around: turn until 2 pi has been swept (measured, not timed).
        c.spun += abs(wrap(float(pose[2]) - c.last_heading))
        c.last_heading = float(pose[2])
        remaining = 2 * math.pi - c.spun
        if remaining <= 0.02:
            self._finish("reached", pose)
            self.status = "reached"
            return 0.0, 0.0, self.status
        # Slow down over the last half-radian so the turn ends where it should.
        w = min(self.spin_rate, max(0.2, 1.5 * remaining))
        self.status = "spinning"
        return 0.0, w, self.status

    def _follow(self, pose: np.ndarray) -> tuple[float, float, str]:
        c = self.current
        assert c is not None and c.follower is not None
        if self._grid_changed:
            self._grid_changed = False
            if self._path_blocked() and not self._replan(pose, "path blocked"):
                return 0.0, 0.0, "failed"
        v, w, status = c.follower.step(pose, 0.0)
        if status == "arrived":
            return v, w, status
        f = c.follower
        if f.cross_track > self.max_deviation:
            if not self._replan(pose, f"{f.cross_track:.2f} m off the path"):
                return 0.0, 0.0, "failed"
            return self._follow(pose)
        if f.progress > c.best_progress + 0.05 or status == "turning":
            c.best_progress, c.progress_time = max(c.best_progress, f.progress), self.time
        elif self.time - c.progress_time > self.stall_time:
            if not self._replan(pose, "no progress"):
                return 0.0, 0.0, "failed"
            return self._follow(pose)
        return v, w, status
