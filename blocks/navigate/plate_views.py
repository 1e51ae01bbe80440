"""Plate views: go back for a readable view of a door plate seen only in passing.

Why: a plate on the wall the perimeter follower keeps 0.7 m to its right is
only ever seen at a grazing angle from the follower's path, and a plate hung
high leaves the top of the frame before the view gets better than about 60
degrees; the sign seeker stops at the best view the path offers, or gives the
plate up, and the reader cannot read what it captured.  A person would step
back across the corridor and look at the plate from in front.  So does this:

1. **Choose where to stand** (:func:`view_point`): a cell the robot can reach
   on its own map, in front of the plate (at most ``max_view`` off its normal),
   far enough for the whole plate to fit in the frame at the head's tilt
   limit, near enough to read it, with a clear line of sight to it.  The most
   frontal such cell wins, then the one nearest the robot.
2. **Go there** (A* on a local map of the recent scans, pure pursuit, the
   sonar guard on every command), **face the plate**, and **look**: the sign
   seeker is told to look at the plate again (``look_at``) and does what it
   does for any plate, stops the robot, zooms and captures.  The look ends
   when a sign is known at the plate, or after ``look_time``.
3. **Come back** to where the view began, facing the way the robot was going,
   so the behaviour it interrupted picks up where it left off.

Each plate is looked at once: a plate still unread after its view is not a
plate a better view would read.

:class:`PlateViewer` is a plain state machine fed with poses, sonar ranges and
a map callback, tested without the dataflow engine.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .collision_monitor import EchoMemory
from .grid import NavGrid, inflate, unblock_traversed
from .guard import SonarGuard
from .legs import Leg, TurnWatch, dedupe, turn_rate
from .planner import PlanningError, plan
from .pursuit import PurePursuit, PursuitParams

__all__ = ["PlateViewParams", "PlateViewer", "WantedPlate", "view_point"]


@dataclass(frozen=True)
class WantedPlate:
    """A plate to look at again, in the frame of the poses.

    Attributes
    ----------
    key
        Its name with the seeker, which ``look_at`` gives back.
    x, y
        The plate's centre (m).
    facing
        Its outward normal (rad).
    top
        Height (m) of its top edge above the camera.
    """

    key: int
    x: float
    y: float
    facing: float
    top: float = 0.8

    @classmethod
    def from_dict(cls, plate: dict[str, Any]) -> WantedPlate:
        """From a ``signs.seek`` ``wanted`` entry."""
        return cls(int(plate["key"]), float(plate["x"]), float(plate["y"]),
                   float(plate["facing"]), float(plate.get("top", 0.8)))


def view_point(grid: NavGrid, occupied: np.ndarray, here: tuple[float, float],
               plate: WantedPlate, *, max_view: float = math.radians(35.0),
               min_range: float = 1.0, max_range: float = 3.0, best_range: float = 1.8,
               tilt_limit: float = math.radians(38.0), view_step: float = math.radians(10.0),
               range_step: float = 0.3) -> tuple[float, float] | None:
    """Where to stand to read ``plate``: the most frontal reachable cell at the best range,
    then the nearest to the robot.

    Parameters
    ----------
    grid
        The planning grid (obstacles grown by the robot's radius); its cells
        reachable from ``here`` are the candidates.
    occupied
        (H, W) bool, the map's occupied cells on ``grid``'s cells: the line of
        sight to the plate must not cross them (the plate's own wall aside).
    here
        The robot's position.
    plate
        The plate.
    max_view
        At most this far off the plate's normal (rad).
    min_range, max_range
        Distance (m) from the plate: at least ``min_range``, and far enough
        for its top to be at most ``tilt_limit`` above the camera's horizon
        (the head's tilt limit plus what of the frame's upper half may be
        used); at most ``max_range``, beyond which its letters are too small.
    best_range
        The distance (m) it is best seen from: near enough to zoom in on
        sharply, far enough that the whole plate sits well inside the frame.
    view_step, range_step
        Views within this many radians of each other, and distances within
        this many metres of ``best_range``, count as equally good.

    Returns
    -------
    (x, y) or None
        None when no reachable cell sees the plate well.
    """
    cell = grid.free_cell_at(*here, 0.6)
    if cell is None:
        return None
    row, col = cell
    near = max(min_range, plate.top / math.tan(tilt_limit))
    if near > max_range:
        return None
    rows, cols = np.nonzero(grid.labels == grid.labels[row, col])
    xy = grid.cell_to_world(rows, cols)
    dx, dy = xy[:, 0] - plate.x, xy[:, 1] - plate.y
    distance = np.hypot(dx, dy)
    normal = np.array([math.cos(plate.facing), math.sin(plate.facing)])
    with np.errstate(invalid="ignore", divide="ignore"):
        view = np.arccos(np.clip((dx * normal[0] + dy * normal[1]) / distance, -1.0, 1.0))
    ok = (distance >= near) & (distance <= max_range) & (view <= max_view)
    if not ok.any():
        return None
    rows, cols, xy, view, distance = rows[ok], cols[ok], xy[ok], view[ok], distance[ok]
    travel = np.hypot(xy[:, 0] - here[0], xy[:, 1] - here[1])
    off_best = np.floor(np.abs(distance - max(best_range, near)) / range_step)
    for k in np.lexsort((travel, off_best, np.floor(view / view_step))):
        if _sees(occupied, grid, xy[k], plate):
            return float(xy[k, 0]), float(xy[k, 1])
    return None


def _sees(occupied: np.ndarray, grid: NavGrid, xy: np.ndarray, plate: WantedPlate,
          wall: float = 0.3) -> bool:
    """Whether no occupied cell lies between ``xy`` and the plate (its last ``wall`` m aside:
    the plate hangs on a wall the map draws thick, and its estimate may lie in it)."""
    target = np.array([plate.x, plate.y])
    length = float(np.hypot(*(target - xy)))
    if length <= wall:
        return True
    s = np.arange(0.0, length - wall, grid.resolution / 2)
    points = xy[None, :] + s[:, None] * (target - xy)[None, :] / length
    r, c = grid.cells_of(points)
    h, w = occupied.shape
    inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
    return not occupied[r[inside], c[inside]].any()


@dataclass(frozen=True)
class PlateViewParams:
    """Tunables of :class:`PlateViewer` (SI units, angles in radians).

    Attributes
    ----------
    max_view, min_range, max_range, tilt_limit
        See :func:`view_point`.
    stopped_view
        A robot stopped on its way (an echo ahead, no progress) still looks
        from there if it sees the plate within this angle of its normal.
    give_up_distance
        A plate farther than this (m) from the robot when its view could start
        is not gone back for.
    window, lead
        The local map holds the scans of the last ``window`` seconds, and at
        least those since ``lead`` seconds before the plate was wanted.
    radius
        Obstacle inflation of the legs (m).
    look_time
        Longest look (s) once the robot faces the plate.
    leg_timeout, stall_time
        Seconds a leg may take, and may go without progress, before it ends.
    held_time
        A leg whose command a collision monitor stops for this long (s) ends
        too (:class:`~blocks.navigate.legs.Leg`).  Infinite: no monitor.
    heading_tolerance
        How close (rad) a turn on the spot gets to the heading it wants.
    spin_rate
        Its turn rate (rad/s).
    """

    max_view: float = math.radians(35.0)
    stopped_view: float = math.radians(55.0)
    min_range: float = 1.0
    max_range: float = 3.0
    tilt_limit: float = math.radians(38.0)
    give_up_distance: float = 6.0
    window: float = 30.0
    lead: float = 10.0
    radius: float = 0.36
    look_time: float = 8.0
    leg_timeout: float = 40.0
    stall_time: float = 8.0
    held_time: float = math.inf
    heading_tolerance: float = 0.05
    spin_rate: float = 1.2


@dataclass
class PlateViewResult:
    """What became of one wanted plate."""

    key: int
    status: str  # "read", "unread", "not needed", "no view", "too far", "failed"
    started: float
    finished: float
    at: tuple[float, float] | None = None  # where the robot stood to look
    reason: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {"key": self.key, "status": self.status, "started": round(self.started, 2),
                "duration": round(self.finished - self.started, 2),
                "at": None if self.at is None else [round(v, 2) for v in self.at],
                "reason": self.reason}


#: The local map (an OccupancyMap) of the scans since a time (s) taken near a point (x, y),
#: and the robot positions of those scans; None when there are too few.
MapSource = Callable[[float, "tuple[float, float]"], "tuple[Any, np.ndarray] | None"]


class PlateViewer:
    """Goes back for a readable view of each plate the seeker wants, one at a time.

    Feed it the seeker's wanted plates with :meth:`want` and call :meth:`step`
    every tick: it returns ``None`` while it is not driving, else ``(v, w)``.
    While it looks, :attr:`look_at` is the plate the seeker should look at again.

    Parameters
    ----------
    maps
        ``maps(since, near)``: the local map of the scans taken since ``since``
        near ``near``, and the positions they were taken from, or None.
    guard
        The sonar guard every command is checked against (None: none).
    params, pursuit
        See :class:`PlateViewParams` and :class:`~.pursuit.PursuitParams`.
    read_radius
        A sign known this close (m) to a plate reads it.
    echoes
        A collision monitor's remembered echoes: see :class:`~.rooms.RoomVisitor`.
    """

    def __init__(self, maps: MapSource, guard: SonarGuard | None = None,
                 params: PlateViewParams | None = None, pursuit: PursuitParams | None = None,
                 read_radius: float = 1.2, echoes: EchoMemory | None = None) -> None:
        self.maps = maps
        self.echoes = echoes
        self.guard = guard
        self.p = params or PlateViewParams()
        self.pursuit = pursuit or PursuitParams()
        self.read_radius = read_radius
        self.queue: list[tuple[WantedPlate, float]] = []  # plate, time wanted
        self.results: list[PlateViewResult] = []
        self.phase = "idle"  # idle, go, face, look, back, align
        self.look_at: WantedPlate | None = None
        self._seen_keys: set[int] = set()
        self._plate: WantedPlate | None = None
        self._leg: Leg | None = None
        self._grid: NavGrid | None = None
        self._start = np.zeros(3)
        self._started = self._look_until = 0.0
        self._at: tuple[float, float] | None = None
        self._status = ""
        self._reason = ""
        self._ranges: np.ndarray | None = None
        self._scale = 1.0
        self._turns = TurnWatch(stall_time=self.p.stall_time)  # turns that cannot be made

    @property
    def active(self) -> bool:
        """Whether a view holds control."""
        return self.phase != "idle"

    def want(self, plates: list[WantedPlate], time: float) -> None:
        """Queue the plates not queued before (each is gone back for once)."""
        for plate in plates:
            if plate.key not in self._seen_keys:
                self._seen_keys.add(plate.key)
                self.queue.append((plate, time))

    # ---- the machine -----------------------------------------------------------------------
    def step(self, time: float, pose: np.ndarray, ranges: np.ndarray | None = None, *,
             hold: bool = False, signs: list[tuple[float, float]] = (),
             scale: float = 1.0) -> tuple[float, float] | None:
        """This tick's velocities, or None when the caller's behaviour should drive.

        ``hold`` pauses a view (the seeker stops the robot to capture) and
        defers starting one; ``signs`` are the (x, y) of the signs known now;
        ``scale`` is how much of the last tick's command a collision monitor
        let through.
        """
        pose = np.asarray(pose, dtype=np.float64)
        self._scale = scale
        self._ranges = ranges
        self._drop_read(time, signs)
        if self.phase == "idle":
            if hold or not self._try_start(time, pose):
                return None
        if self.phase == "look":
            return self._look(time, pose, signs, hold)
        if hold:
            if self._leg is not None:
                self._leg.progress_time = time  # a pause is not a stall
            return 0.0, 0.0
        if self.phase == "face":
            return self._face(time, pose)
        if self.phase == "align":
            return self._align(time, pose)
        return self._follow(time, pose)

    def _drop_read(self, time: float, signs: list[tuple[float, float]]) -> None:
        """Queued plates a sign is known at now need no view."""
        for plate, wanted in list(self.queue):
            if self._is_read(plate, signs):
                self.queue.remove((plate, wanted))
                self.results.append(PlateViewResult(plate.key, "not needed", time, time,
                                                    reason="read before its view"))

    def _is_read(self, plate: WantedPlate, signs: list[tuple[float, float]]) -> bool:
        return any(math.hypot(x - plate.x, y - plate.y) <= self.read_radius for x, y in signs)

    def _try_start(self, time: float, pose: np.ndarray) -> bool:
        here = (float(pose[0]), float(pose[1]))
        while self.queue:
            plate, wanted = self.queue.pop(0)
            if math.hypot(plate.x - here[0], plate.y - here[1]) > self.p.give_up_distance:
                self.results.append(PlateViewResult(plate.key, "too far", time, time))
                continue
            built = self.maps(min(time - self.p.window, wanted - self.p.lead),
                              (plate.x, plate.y))
            if built is None:
                self.results.append(PlateViewResult(plate.key, "no view", time, time,
                                                    reason="no map of the plate's wall"))
                continue
            local_map, positions = built
            grid = unblock_traversed(inflate(local_map, radius=self.p.radius), positions)
            occupied = local_map.classes()[0]
            spot = view_point(grid, occupied, here, plate, max_view=self.p.max_view,
                              min_range=self.p.min_range, max_range=self.p.max_range,
                              tilt_limit=self.p.tilt_limit)
            if spot is None:
                self.results.append(PlateViewResult(plate.key, "no view", time, time,
                                                    reason="no reachable spot sees it well"))
                continue
            try:
                way = plan(grid, here, spot).points
            except PlanningError as exc:
                self.results.append(PlateViewResult(plate.key, "no view", time, time,
                                                    reason=str(exc)))
                continue
            self._plate, self._grid, self._at = plate, grid, spot
            self._start, self._started = pose.copy(), time
            self._status, self._reason = "", ""
            self._begin_leg("go", way, time)
            return True
        return False

    def _begin_leg(self, phase: str, way: np.ndarray, time: float) -> None:
        self.phase = phase
        self._leg = Leg(PurePursuit(dedupe(way), self.pursuit), time)

    def _follow(self, time: float, pose: np.ndarray) -> tuple[float, float]:
        assert self._leg is not None
        v, w, outcome = self._leg.step(time, pose, timeout=self.p.leg_timeout,
                                       stall_time=self.p.stall_time, scale=self._scale,
                                       held_time=self.p.held_time, echoes=self.echoes)
        if not outcome and self._blocked(v, w):
            outcome = "blocked"
        if outcome == "arrived":
            self.phase = "face" if self.phase == "go" else "align"
            return 0.0, 0.0
        if outcome:
            self._leg_failed(time, pose, outcome)
            return 0.0, 0.0
        return v, w

    def _leg_failed(self, time: float, pose: np.ndarray, why: str) -> None:
        if self.phase == "go":
            self._reason = f"on the way: {why}"
            if self._worth_a_look(pose):  # nearer and more in front than where it began
                self.phase = "face"
                self._at = (float(pose[0]), float(pose[1]))
            else:
                self._status = "failed"
                self._head_back(time, pose)
        else:
            self._end(time, self._status or "failed", self._reason or f"on the way back: {why}")

    def _worth_a_look(self, pose: np.ndarray) -> bool:
        """Whether the plate is within reading range and in front from ``pose``."""
        assert self._plate is not None
        dx, dy = pose[0] - self._plate.x, pose[1] - self._plate.y
        distance = math.hypot(dx, dy)
        if not self.p.min_range <= distance <= self.p.max_range:
            return False
        cos_view = (dx * math.cos(self._plate.facing) + dy * math.sin(self._plate.facing)) \
            / distance
        return cos_view >= math.cos(self.p.stopped_view)

    def _face(self, time: float, pose: np.ndarray) -> tuple[float, float]:
        """Turn on the spot towards the plate, then look."""
        assert self._plate is not None
        heading = math.atan2(self._plate.y - pose[1], self._plate.x - pose[0])
        w = turn_rate(heading, float(pose[2]), self.p.spin_rate, self.p.heading_tolerance)
        if w is not None and not self._blocked(0.0, w) \
                and not self._turns.stalled(time, float(pose[2]), "face"):
            return 0.0, w
        self.phase, self.look_at = "look", self._plate  # facing it, or as near as it may turn
        self._look_until = time + self.p.look_time
        return 0.0, 0.0

    def _look(self, time: float, pose: np.ndarray, signs: list[tuple[float, float]],
              hold: bool) -> tuple[float, float]:
        """Stand still while the seeker looks; done when a sign is known at the plate."""
        assert self._plate is not None
        if self._is_read(self._plate, signs):
            self._status = "read"
        elif hold:
            self._look_until = max(self._look_until, time + 1.0)  # a capture under way
        elif time >= self._look_until:
            self._status = self._status or "unread"
        if self._status:
            self.look_at = None
            self._head_back(time, pose)
        return 0.0, 0.0

    def _head_back(self, time: float, pose: np.ndarray) -> None:
        here = np.asarray(pose[:2], dtype=np.float64)
        start = self._start[:2]
        if np.hypot(*(here - start)) < 0.05:
            self.phase = "align"
            return
        way = np.vstack([here, start])
        if self._grid is not None:
            try:
                way = plan(self._grid, here, start).points
            except PlanningError:
                pass
        self._begin_leg("back", way, time)

    def _align(self, time: float, pose: np.ndarray) -> tuple[float, float]:
        w = turn_rate(float(self._start[2]), float(pose[2]), self.p.spin_rate,
                      self.p.heading_tolerance)
        if w is None or self._blocked(0.0, w) \
                or self._turns.stalled(time, float(pose[2]), "align"):
            self._end(time, self._status or "unread", self._reason)
            return 0.0, 0.0
        return 0.0, w

    def _blocked(self, v: float, w: float) -> bool:
        """Whether the sonar guard hears something the command (v, w) would drive into."""
        return self.guard is not None and self._ranges is not None \
            and bool(self.guard.blocked(self._ranges, v, w))

    def _end(self, time: float, status: str, reason: str = "") -> None:
        assert self._plate is not None
        self.results.append(PlateViewResult(self._plate.key, status, self._started, time,
                                            self._at, reason))
        self.phase, self._leg, self._plate, self.look_at = "idle", None, None, None

    def summary(self) -> dict[str, Any]:
        """Counts and each plate's outcome, for run.json."""
        statuses = ("read", "unread", "not needed", "no view", "too far", "failed")
        counts = {s.replace(" ", "_"): sum(r.status == s for r in self.results)
                  for s in statuses}
        return {**counts, "pending": len(self.queue), "turns_given_up": self._turns.given_up,
                "time_s": round(sum(r.finished - r.started for r in self.results), 1),
                "plates": [r.as_dict() for r in self.results]}
