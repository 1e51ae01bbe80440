"""A collision monitor: the last check on every command before it reaches the wheels.

Why: each behaviour (the fuzzy follower, the frontier explorer, a room visit,
a plate view) judges its own motion on what it attends to, and none of them
sees everything: the follower's rules look at sonar groups and miss the front
corner of the body that swings out when it turns round the end of a wall; a
planned way trusts a map off by the odometry's drift.  The monitor asks one
question of whatever command arrives: driving on like this, how soon would
the body cover an echo (:meth:`~blocks.navigate.guard.SonarGuard.collision_time`,
the swept footprint)?  Sooner than ``time_before_collision`` and the command
is scaled down, translation and rotation alike, so that the path stays the
one asked for and the robot arrives no sooner than that: it slows towards an
obstacle and stops short of it.  This is ROS 2 Nav2's collision monitor in
its "approach" mode, with the sonar's echo arcs as the observation source.

A sonar corner seen at a grazing angle echoes on one tick and not the next,
so the echoes of the last ``memory`` seconds are kept, carried into the
robot's present frame by odometry (exact enough over a second).

The monitor steers only to get out of a corner: a behaviour that keeps
asking for a motion the monitor holds back is stalled, and its own stall
handling (back off, turn, plan again) takes over; but where that handling
asks only for motions the monitor also refuses (a turn away from the wall
with something touching the front corner on that side, a back-off with a wall
close behind), the two would hold the robot still for good.  After
``patience`` seconds stopped, the monitor drives for ``recovery_time`` the
motion nearest to the one asked for that it lets through (backing, turning
either way, or both).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from .guard import SonarGuard, felt_walls
from .sonar_triangulation import triangulate_echoes

__all__ = ["CollisionMonitor", "EchoMemory", "HeldClock", "MonitorParams", "carry_points"]


@dataclass(frozen=True)
class MonitorParams:
    """Tuning of :class:`CollisionMonitor` (SI units).

    Attributes
    ----------
    time_before_collision
        A command that would bring the body onto an echo sooner than this
        (s) is scaled so that it would take this long.
    margin
        The body is grown by this much (m) on every side for the check.
    wall_extent
        Each point of an echo's arc also stands for a wall through it across
        the beam, this long (m) either way
        (:func:`~blocks.navigate.guard.wall_hypotheses`): a wall met obliquely
        ahead echoes only at the edge of a diagonal sonar's cone, beside the
        body, and crosses its path beyond.  0 (the default): points alone.
        A property of the memory (what its echoes stand for): a monitor or a
        behaviour checking on a shared memory uses the memory's.
    memory
        Echoes of the last so many seconds count, not only this scan's.
    min_range
        A sonar cannot range closer than this (m): a reading within ``touch``
        of it may be nearer still, so it is taken as touching the body.
    touch
        See ``min_range``.
    patience, recovery_time, recovery_speed, recovery_turn
        Stopped this long (s), the monitor drives for ``recovery_time`` (s)
        the nearest admissible of the motions at most ``recovery_speed``
        (m/s) and ``recovery_turn`` (rad/s).
    step
        The swept footprint is checked every ``step`` seconds of motion.
    triangulate
        Also locate near echoes by how fast their ranges close as the robot
        drives (:func:`~blocks.navigate.sonar_triangulation.triangulate_echoes`),
        comparing each scan with those ``triangulate_lags`` seconds older: a
        wall end met by the body's front corner lies at the inner edge of a
        diagonal sonar's cone, where the arc rule lets it through.
    triangulate_lags, triangulate_range, triangulate_tolerance
        See ``triangulate`` and the function's ``max_range`` and ``tolerance_deg``.
    near_range, near_memory
        Echoes nearer than ``near_range`` (m) are kept ``near_memory`` seconds, not
        ``memory``: the wall a robot drove along is still there when it backs or
        turns into it later, its sonars then reading nothing useful (a side flush
        with a wall reads the least range; a wall end seen edge on, nothing).  A
        near echo's arc is short, so it says where the wall is; odometry drifts
        little in that time.  A later echo from farther along a sonar's cone frees
        the kept points inside it nearer by more than ``carve_tolerance`` (m).
    """

    time_before_collision: float = 0.6
    margin: float = 0.03
    wall_extent: float = 0.0
    memory: float = 1.0
    step: float = 0.05
    min_range: float = 0.1
    touch: float = 0.01
    patience: float = 1.0
    recovery_time: float = 1.0
    recovery_speed: float = 0.15
    recovery_turn: float = 0.6
    triangulate: bool = False
    triangulate_lags: tuple[float, ...] = (0.3, 0.5)
    triangulate_range: float = 1.0
    triangulate_tolerance: float = 10.0
    near_range: float = 0.6
    near_memory: float = 30.0
    carve_tolerance: float = 0.05


def carry_points(points: np.ndarray, then: np.ndarray, now: np.ndarray) -> np.ndarray:
    """Points (..., 2) in the robot frame at pose ``then``, expressed in its frame at ``now``.

    Examples
    --------
    >>> carry_points(np.array([[1.0, 0.0]]), np.zeros(3), np.array([0.5, 0.0, 0.0])).tolist()
    [[0.5, 0.0]]
    """
    c, s = math.cos(then[2]), math.sin(then[2])
    wx = then[0] + c * points[..., 0] - s * points[..., 1]
    wy = then[1] + s * points[..., 0] + c * points[..., 1]
    c, s = math.cos(now[2]), math.sin(now[2])
    dx, dy = wx - now[0], wy - now[1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


def _in_odometry(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Points (..., 2) in the robot frame at odometry ``pose``, in the odometry frame."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.stack([pose[0] + c * points[..., 0] - s * points[..., 1],
                     pose[1] + s * points[..., 0] + c * points[..., 1]], axis=-1)


def _moved(last: np.ndarray | None, pose: np.ndarray) -> bool:
    """Whether the robot has moved from ``last`` enough (2 cm or 0.03 rad) to hear or feel
    anew what it heard or felt there (a robot standing still hears the same echoes)."""
    return last is None or math.hypot(pose[0] - last[0], pose[1] - last[1]) >= 0.02 \
        or abs(math.remainder(pose[2] - last[2], 2 * math.pi)) >= 0.03


class HeldClock:
    """How long a collision monitor has let none of a command that asks to move through.

    The monitor itself (its patience before a recovery), and each behaviour
    that reacts to being held (the explorer, a leg of a room visit), keep one.

    Examples
    --------
    >>> clock = HeldClock()
    >>> clock.update(1.0, 0.0, moving=True), clock.update(1.5, 0.0, moving=True)
    (0.0, 0.5)
    >>> clock.update(1.6, 0.4, moving=True)  # let through again
    0.0
    """

    def __init__(self) -> None:
        self.since: float | None = None

    def update(self, time: float, scale: float, moving: bool) -> float:
        """Seconds held so far, given how much of the command (``scale``) got through."""
        if scale > 0.0 or not moving:
            self.since = None
            return 0.0
        if self.since is None:
            self.since = time
        return time - self.since

    def reset(self) -> None:
        """Start counting afresh (the hold has been answered)."""
        self.since = None


class EchoMemory:
    """The echo arcs of the last ``memory`` seconds, carried into the robot's present frame.

    Why: a sonar corner seen at a grazing angle echoes on one tick and not the
    next, so a check on this tick's echoes alone lets the body through where
    it touched a wall a moment ago.  Odometry is exact enough over a second
    to carry older echoes along.

    Parameters
    ----------
    guard
        The robot's sonar guard (its mounts and echo arcs).
    params
        ``memory`` (s), ``min_range`` and ``touch`` (m) of :class:`MonitorParams`.

    Examples
    --------
    >>> memory = EchoMemory(SonarGuard(np.array([[0.25, 0.0, 0.0]])))
    >>> memory.add(0.0, np.zeros(3), np.array([1.0]))
    >>> memory.arcs(np.array([0.5, 0.0, 0.0]))[0, 1].round(2).tolist()  # 0.5 m nearer now
    [0.75, 0.0]
    """

    def __init__(self, guard: SonarGuard, params: MonitorParams | None = None) -> None:
        self.guard = guard
        self.p = params or MonitorParams()
        # time, odometry pose, echo arcs (and triangulated points), raw ranges
        self._scans: deque[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = deque()
        # near echoes kept longer: (K, S, 2) arcs in the odometry frame, and when heard
        samples = max(guard.arc_samples, 1)
        self._near_arcs = np.zeros((0, samples, 2))
        self._near_times = np.zeros(0)
        self._near_pose: np.ndarray | None = None  # where the last kept were heard
        # walls the bumpers felt (odometry frame), kept as long as near echoes
        self._felt = np.zeros((0, 2))
        self._felt_times = np.zeros(0)
        self._felt_pose: np.ndarray | None = None
        self._felt_spans: list[tuple[float, float]] = []
        self._cached: tuple[float, tuple[float, ...], np.ndarray] | None = None
        self._mounts = np.asarray(guard.mounts, dtype=np.float64).reshape(-1, 3)

    def _echoes(self, raw: np.ndarray) -> np.ndarray:
        """Which readings are echoes that say where something is (not 'no echo', not the
        least range)."""
        return (raw < self.guard.max_range - self.guard.max_range_margin) \
            & (raw > self.p.min_range + self.p.touch)

    def add(self, time: float, pose: np.ndarray, ranges: np.ndarray) -> None:
        """Remember this tick's echoes, heard at odometry ``pose``; forget the old ones."""
        raw = np.asarray(ranges, dtype=np.float64)
        pose = np.array(pose, dtype=np.float64)
        # a reading at the sonar's least range may be nearer still: take it as touching
        arcs = self.guard.echo_arcs(np.where(raw <= self.p.min_range + self.p.touch, 0.0, raw))
        if self.p.triangulate:
            points = self._triangulated(time, pose, raw)
            if len(points):
                samples = max(self.guard.arc_samples, 1)
                arcs = np.concatenate([arcs, np.repeat(points[:, None, :], samples, axis=1)])
        self._scans.append((time, pose, arcs, raw))
        keep = max(self.p.memory, max(self.p.triangulate_lags, default=0.0) + 0.05) \
            if self.p.triangulate else self.p.memory
        while self._scans and self._scans[0][0] < time - keep + 1e-9:
            self._scans.popleft()
        if self.p.near_memory > self.p.memory:
            self._remember_near(time, pose, raw)

    def add_touch(self, time: float, pose: np.ndarray, spans: list[tuple[float, float]],
                  v: float, w: float) -> None:
        """Remember the walls that the bumpers pressed now (their bearing ``spans``, rad) say
        the body touches, the robot moving at (``v``, ``w``) (:func:`~blocks.navigate.guard.
        felt_walls`), at odometry ``pose``; kept ``near_memory`` seconds (at least
        ``memory``), so no behaviour drives on into what no sonar hears."""
        if len(self._felt_times):
            old = self._felt_times < time - max(self.p.near_memory, self.p.memory) + 1e-9
            if old.any():
                self._felt, self._felt_times = self._felt[~old], self._felt_times[~old]
        if not spans or (spans == self._felt_spans and not _moved(self._felt_pose, pose)):
            return  # nothing pressed, or the same switches pressed on where it was: felt
        points = felt_walls(self.guard.length, self.guard.width, spans, v, w)
        if not len(points):
            return
        self._felt_pose, self._felt_spans = np.array(pose, dtype=np.float64), list(spans)
        world = _in_odometry(points, pose)
        self._felt = np.concatenate([self._felt, world])
        self._felt_times = np.concatenate([self._felt_times, np.full(len(world), time)])
        self._cached = None

    def _remember_near(self, time: float, pose: np.ndarray, raw: np.ndarray) -> None:
        """Keep this scan's near echoes (not those at the least range: they are on the
        body, wherever it was) in the odometry frame for ``near_memory`` seconds; a
        robot standing still hears the same ones again, and they are kept once."""
        old = self._near_times < time - self.p.near_memory + 1e-9
        if old.any():
            self._near_arcs, self._near_times = self._near_arcs[~old], self._near_times[~old]
        if len(self._near_times):
            self._carve_near(pose, raw)
        near = (raw < self.p.near_range) & (raw > self.p.min_range + self.p.touch)
        if near.any() and _moved(self._near_pose, pose):
            self._near_pose = pose
            world = _in_odometry(self.guard.echo_arcs(np.where(near, raw, math.inf)), pose)
            self._near_arcs = np.concatenate([self._near_arcs, world])
            self._near_times = np.concatenate([self._near_times, np.full(len(world), time)])

    def _carve_near(self, pose: np.ndarray, raw: np.ndarray) -> None:
        """Forget the kept near arcs' points that this scan's echoes show are free.

        Why: an arc only says the echo is somewhere across the cone.  Beside a
        doorway the jambs' arcs reach across the opening, and kept for
        ``near_memory`` seconds from every pose of an approach they close it.
        A sonar that hears its nearest echo at ``r`` has nothing nearer anywhere
        in its cone, so a kept point inside that cone more than ``carve_tolerance``
        nearer is free.  A reading with no echo says nothing (a wall at grazing
        incidence is silent), nor does one at the least range.  A partly freed
        arc keeps its other points: the echo was there.
        """
        guard = self.guard
        echo = self._echoes(raw)
        if not echo.any():
            return
        m, r = self._mounts[echo], raw[echo] - self.p.carve_tolerance
        arcs = self._near_arcs
        # only arcs within reach of an echo can be freed (most kept ones are behind)
        reach = float(r.max()) + float(np.hypot(*np.abs(m[:, :2]).max(axis=0)))
        centre = arcs[:, arcs.shape[1] // 2]
        within = np.flatnonzero(np.hypot(centre[:, 0] - pose[0], centre[:, 1] - pose[1])
                                < reach + 0.2)
        if not len(within):
            return
        c, s = math.cos(pose[2]), math.sin(pose[2])
        sx = pose[0] + c * m[:, 0] - s * m[:, 1]
        sy = pose[1] + s * m[:, 0] + c * m[:, 1]
        heading = pose[2] + m[:, 2]
        world = arcs[within]
        dx = world[..., 0, None] - sx  # (W, S, N)
        dy = world[..., 1, None] - sy
        off = np.abs(np.remainder(np.arctan2(dy, dx) - heading + math.pi, 2 * math.pi) - math.pi)
        free = ((dx * dx + dy * dy < np.maximum(r, 0.0) ** 2)
                & (off <= math.radians(guard.cone_deg) / 2)).any(axis=-1)  # (W, S)
        if not free.any():
            return
        # a freed point takes the place of one the echo may still be at; a wholly freed
        # arc goes
        first = np.argmax(~free, axis=1)
        arcs[within] = np.where(free[..., None], world[np.arange(len(world)), first][:, None],
                                world)
        gone = within[free.all(axis=1)]
        if len(gone):
            keep = np.ones(len(arcs), dtype=bool)
            keep[gone] = False
            self._near_arcs, self._near_times = arcs[keep], self._near_times[keep]

    def _triangulated(self, time: float, pose: np.ndarray, raw: np.ndarray) -> np.ndarray:
        """Points of this scan's near echoes located against the scans ``triangulate_lags`` ago."""
        guard, mounts = self.guard, self._mounts
        echo = self._echoes(raw)
        found = []
        for lag in self.p.triangulate_lags:
            then = min(self._scans, key=lambda scan: abs(scan[0] - (time - lag)), default=None)
            if then is None or abs(then[0] - (time - lag)) > 0.06:
                continue
            then_raw = then[3]
            then_echo = self._echoes(then_raw)
            found.append(triangulate_echoes(
                mounts, raw, echo, carry_points(mounts[:, :2], then[1], pose), then_raw,
                then_echo, cone_deg=guard.cone_deg, max_range=self.p.triangulate_range,
                tolerance_deg=self.p.triangulate_tolerance))
        return np.concatenate(found) if found else np.zeros((0, 2))

    def arcs(self, pose: np.ndarray) -> np.ndarray:
        """(E, S, 2) the remembered echo arcs in the frame of odometry ``pose``."""
        pose = np.asarray(pose, dtype=np.float64)
        now = self._scans[-1][0] if self._scans else -math.inf
        key = tuple(float(v) for v in pose)
        if self._cached is not None and self._cached[:2] == (now, key):
            return self._cached[2]  # asked again this tick, from the same pose
        arcs = self._arcs(pose)
        self._cached = (now, key, arcs)
        return arcs

    def _arcs(self, pose: np.ndarray) -> np.ndarray:
        """The last ``memory`` seconds' arcs and the older near ones, in ``pose``'s frame."""
        carried = [carry_points(arcs, then, pose) for t, then, arcs, _ in self._scans
                   if len(arcs) and t >= self._scans[-1][0] - self.p.memory + 1e-9]
        if len(self._near_times) and self._scans:
            older = self._near_times < self._scans[-1][0] - self.p.memory + 1e-9
            if older.any():
                carried.append(self._near_in_frame(self._near_arcs[older], pose))
        if len(self._felt):  # each point a wall's: any one reached stops a motion
            samples = max(self.guard.arc_samples, 1)
            carried.append(self._near_in_frame(np.repeat(self._felt[:, None, :], samples, axis=1),
                                               pose))
        if not carried:
            return np.zeros((0, max(self.guard.arc_samples, 1), 2))
        return np.concatenate(carried)

    def _near_in_frame(self, world: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """Odometry-frame arcs in the frame of ``pose``, only those within the reach of a
        monitored motion (the body's corners plus a second at the top speed)."""
        c, s = math.cos(pose[2]), math.sin(pose[2])
        dx, dy = world[..., 0] - pose[0], world[..., 1] - pose[1]
        local = np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)
        reach = math.hypot(self.guard.length, self.guard.width) / 2 + 1.0
        close = (np.abs(local[..., 0]) <= reach).all(axis=1) \
            & (np.abs(local[..., 1]) <= reach).all(axis=1)
        return local[close]

    def collision_time(self, pose: np.ndarray, v: float, w: float,
                       checks: MonitorParams | None = None) -> float:
        """Seconds until the body driving at (v, w) from odometry ``pose`` covers a
        remembered echo, as the monitor sweeps it; inf if not within its horizon.

        ``checks`` gives the horizon, step and margin (``time_before_collision``,
        ``step``, ``margin``): a monitor's own, when it shares this memory; else
        this memory's parameters.
        """
        c = checks or self.p
        return self.guard.collision_time(self.arcs(pose), v, w, c.time_before_collision,
                                         step=c.step, margin=c.margin,
                                         wall_extent=self.p.wall_extent)

    def stops(self, pose: np.ndarray, v: float, w: float,
              checks: MonitorParams | None = None) -> bool:
        """Whether a collision monitor with these echoes would stop the motion (v, w)."""
        return self.collision_time(pose, v, w, checks) <= (checks or self.p).step

    def nearest_clear(self, pose: np.ndarray, v: float, w: float,
                      checks: MonitorParams | None = None) -> tuple[float, float] | None:
        """The slow motion nearest to (v, w) that reaches no echo within the horizon, or None.

        The candidates are backing, standing and creeping ahead at ``recovery_speed``,
        each turning either way or not at ``recovery_turn`` (of ``checks``, as
        :meth:`collision_time`); nearness weighs speeds as shares of those.
        """
        c = checks or self.p
        arcs = self.arcs(pose)
        speed, turn = c.recovery_speed, c.recovery_turn
        options = [(a * speed, b * turn) for a in (-1.0, 0.0, 1.0) for b in (-1.0, 0.0, 1.0)
                   if a or b]
        options.sort(key=lambda o: ((o[0] - v) / speed) ** 2 + ((o[1] - w) / turn) ** 2)
        return next((o for o in options if self.lets_through(arcs, *o, checks=c)), None)

    def lets_through(self, arcs: np.ndarray, v: float, w: float,
                     checks: MonitorParams | None = None) -> bool:
        """Whether (v, w) reaches none of ``arcs`` (this memory's, in the robot's frame)
        within the horizon (of ``checks``, as :meth:`collision_time`)."""
        c = checks or self.p
        return self.guard.collision_time(arcs, v, w, c.time_before_collision,
                                         step=c.step, margin=c.margin,
                                         wall_extent=self.p.wall_extent) == math.inf


class CollisionMonitor:
    """Scales each command so the body reaches no echo sooner than the time allowed.

    Parameters
    ----------
    guard
        The robot's sonar guard: its body, sonar mounts and echo arcs.
    params
        See :class:`MonitorParams`.
    echoes
        An :class:`EchoMemory` that something else feeds every tick, before this
        monitor's step, shared with the behaviours that judge their motions on
        it (one copy, not one each); the monitor then adds no scans itself, and
        the memory's parameters (``memory``, ``near_memory``...) are its, while
        the checks (``time_before_collision``, ``margin``...) are ``params``'.
        None: the monitor keeps its own.

    Examples
    --------
    >>> mounts = np.array([[0.25, 0.0, 0.0]])
    >>> monitor = CollisionMonitor(SonarGuard(mounts))
    >>> v, w = monitor.step(0.0, np.zeros(3), np.array([4.0]), 0.4, 0.0)  # nothing heard
    >>> round(v, 2), monitor.scale
    (0.4, 1.0)
    >>> v, w = monitor.step(0.1, np.zeros(3), np.array([0.15]), 0.4, 0.0)  # 0.15 m ahead
    >>> round(v, 2)
    0.23
    """

    def __init__(self, guard: SonarGuard, params: MonitorParams | None = None,
                 echoes: EchoMemory | None = None) -> None:
        self.guard = guard
        self.p = params or MonitorParams()
        self.echoes = echoes if echoes is not None else EchoMemory(guard, self.p)
        self._feeds = echoes is None
        self.scale = 1.0
        self.limited_ticks = 0
        self.stopped_ticks = 0
        self.recoveries = 0
        self._stopped = HeldClock()
        self._recovery: tuple[float, float] | None = None
        self._recovery_until = 0.0

    def share_echoes(self, echoes: EchoMemory) -> None:
        """Check on ``echoes`` from now on, fed by something else (see ``echoes`` above)."""
        self.echoes, self._feeds = echoes, False

    def arcs(self, pose: np.ndarray) -> np.ndarray:
        """(E, S, 2) the remembered echo arcs in the frame of ``pose``."""
        return self.echoes.arcs(pose)

    def step(self, time: float, pose: np.ndarray, ranges: np.ndarray, v: float,
             w: float) -> tuple[float, float]:
        """This tick's command (v, w) scaled for safety; ``pose`` is odometry.

        The scale applied is left in :attr:`scale` (1: unchanged, 0: stopped).
        """
        pose = np.asarray(pose, dtype=np.float64)
        if self._feeds:
            self.echoes.add(time, pose, ranges)
        arcs = self.echoes.arcs(pose)
        horizon = self.p.time_before_collision
        if self._recovery is not None and time < self._recovery_until:
            if self._clear(arcs, *self._recovery):
                self.scale = 1.0
                return self._recovery
        self._recovery = None
        t = self.guard.collision_time(arcs, v, w, horizon, step=self.p.step, margin=self.p.margin,
                                      wall_extent=self.echoes.p.wall_extent)
        self.scale = 1.0 if t >= horizon else (0.0 if t <= self.p.step else t / horizon)
        if self.scale < 1.0:
            self.limited_ticks += 1
            self.stopped_ticks += self.scale == 0.0
        held = self._stopped.update(time, self.scale, abs(v) >= 1e-6 or abs(w) >= 1e-6)
        if self._stopped.since is None:
            return v * self.scale, w * self.scale
        if held >= self.p.patience - 1e-9:
            self._recovery = self.echoes.nearest_clear(pose, v, w, self.p)
            if self._recovery is not None:
                self.recoveries += 1
                self._recovery_until = time + self.p.recovery_time
                self._stopped.reset()
                return self._recovery
        return 0.0, 0.0

    def _clear(self, arcs: np.ndarray, v: float, w: float) -> bool:
        return self.echoes.lets_through(arcs, v, w, self.p)
