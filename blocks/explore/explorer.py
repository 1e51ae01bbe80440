"""Frontier exploration after the perimeter: go where the map ends until it ends nowhere.

Why: the paper's perimeter following sees the walls it follows and what the
sonar reaches from them; on a ring corridor it goes round one side, at a
narrow gap it turns back, and it never crosses a hall.  Once its loop has
closed (or once it brings no new floor for a long stretch, as when it circles
an island), :class:`FrontierExplorer` takes over: it picks the frontier that
is cheapest to reach (``explore_lite``'s rule: distance minus a weight times
the frontier's length), plans there on the robot's own map with the
project's A* and drives with pure pursuit, and picks again whenever the
frontier it was heading for is gone (seen), the robot has arrived, or the
way failed.  It ends with an honest reason:

``explored``
    No frontier the robot can reach is left, even after a look round on the
    spot.  Those out of reach for its footprint are counted in run.json.
``frontiers given up``
    As ``explored``, but frontiers whose ways kept failing, tried again, are
    left: floor the robot knows it has not mapped.
``stuck``
    Too many ways in a row failed without the robot getting anywhere.

A way fails when the sonar guard (:mod:`blocks.navigate.guard`) hears an
obstacle where the robot is about to go that the map did not show, when a
bumper is pressed or the robot stalls (it asks to move and odometry says it
does not: it then undoes its last motion for a moment), or when it makes no
progress along the way.  What stopped it goes on the planning grid, so the
next way goes round it.  A goal that failed ``max_attempts`` times, or
was reached, is not chosen again: a long frontier still there after a goal
near it was reached is approached again where it is farther than
``seen_radius`` from it, or, once nothing else is left, ``end_seen_radius``.
Ways that keep failing in one spot mean the robot is wedged there: it backs
out along its own track.

A way through a doorway (:mod:`blocks.navigate.doorway`) is driven in three
legs: to a point in front of the doorway on its axis, a turn to face along
the axis, and straight through, slowly.

:class:`FrontierExplorer` is a plain state machine fed with poses, sonar
ranges and a map callback: it is tested without the dataflow engine.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from blocks.navigate.collision_monitor import EchoMemory, HeldClock, MonitorParams
from blocks.navigate.doorway import Doorway, doorway_legs, find_doorway
from blocks.navigate.grid import NavGrid, cells_near, inflate, unblock_traversed
from blocks.navigate.guard import SonarGuard
from blocks.navigate.legs import TurnWatch
from blocks.navigate.planner import SNAP_RADIUS, PlanningError, plan
from blocks.navigate.pursuit import PurePursuit, PursuitParams

from .frontiers import FrontierGoal, find_frontiers, frontier_goals, unseen_parts

__all__ = ["ExploreParams", "FrontierExplorer"]

#: The map callback: the robot's map (an OccupancyMap in the frame of the poses), or None.
MapSource = Callable[[], Any]


@dataclass(frozen=True)
class ExploreParams:
    """Tuning of :class:`FrontierExplorer` (SI units).

    Attributes
    ----------
    radius
        Obstacle inflation of the planning grid (the robot's circumscribed radius).
    tight_radius
        A sonar map draws doors narrower than they are (a 0.9 m door some
        0.35 m narrower: each jamb's echoes spread over the cone's width), and
        the grid grown by ``radius`` closes them.  A frontier whose goal on a
        grid grown by this much lies nearer to it, by over half of ``reach``,
        than its goal on the wide grid (beyond a door the wide grid closes)
        gets that goal and its way on that grid; the clearance cost keeps the
        way in the middle of the door, and the doorway passage (``door_*``)
        takes the body through square.  Less than the body's half-width, for
        the map's sake: 0.28 left every 0.9 m door shut.  0: never.
    tight_cost
        Extra cost of each cell of the tight grid that the wide one blocks, so
        a way uses them only where it must (in the door), not to cut round
        the end of a wall closer than the body's corners allow when it turns.
    min_frontier
        Frontiers shorter than this (m) are ignored.
    reach
        A frontier's goal is at most this far (m) from it.
    gain_weight
        Metres of extra travel one metre of frontier is worth.
    goal_distance
        What a goal's distance is: ``straight`` (the straight line from the
        robot) or ``path`` (the shortest way over the planning grid,
        :meth:`~blocks.navigate.grid.NavGrid.travel_distances`; the floor of the
        next room, near through a wall, is far by its door).
    replan_every
        Seconds between looks at the map while driving (is the frontier still there?).
    close_enough
        A way the sonar guard stops within this distance (m) of its goal has arrived.
    stall_window, stall_speed, stall_motion
        Stalled: for ``stall_window`` s every command asked for at least
        ``stall_speed`` (m/s) and odometry moved less than ``stall_motion`` (m).
    escape_turn
        After backing off from a bump while the follower drives, turn this
        much (rad) to the left, away from the followed wall, and hand back.
    follower_bumps, follower_bump_window
        So many bumps or stalls of the follower within the window (s), or one
        within ``forget_radius`` of an earlier one, mean it is caught in a
        cycle: exploration takes over ("follower jammed").
    bump_memory
        Half-side (m) of the square obstacle a bump puts on the planning grid, where
        the body touched it (what the sonar could not hear stays on the map);
        an echo that stops the robot is put there too.  0 remembers nothing.
    nudge_speed, nudge_time
        Too close to something to turn on the spot, the robot first eases
        straight out at this speed, for at most this long (s) a way: away
        from the nearest echo, or with ``ease_by_ends`` by the end of the body
        farther from the echoes around it (backing from a front corner's,
        ahead from a rear corner's or along a wall), else the other way if
        the guard refuses that one.
    monitor
        The settings of the collision monitor
        (:mod:`blocks.navigate.collision_monitor`) that stands between this
        explorer and the wheels, or None if none does.  With one, every motion
        the explorer considers (a way's next command, a back-off, a nudge, a
        turn) is also judged as the monitor will judge it, on the same
        remembered echoes and swept footprint: a motion the monitor would stop
        is blocked here too, so the explorer plans round it instead of asking
        for it until it counts as a stall.  And a bumper that stays pressed is
        one bump, not one a tick: the monitor keeps the robot from pushing on
        into what it touches, and a robot pressed against a wall by its side
        may still drive along it; failing every new way at once would end the
        run ``stuck`` where it is not.  For the same reason, after a back-off,
        a robot that could turn neither way moves straight on along what pins
        it (up to ``unpin_time``): pressed flush against a wall by its side,
        any turn swings a corner into it, and each way planned from there
        would fail at once.  It backs; with ``ease_by_ends`` it goes out by
        the end of the body farther from the echoes, ahead if they are as
        near to either end (the sonars cover the front; a rear corner may
        have none looking past it).
    unpin_time
        See ``monitor``.
    ease_by_ends
        See ``nudge_speed`` and ``monitor`` (off by default until measured on
        the hour-long runs).
    retry_given_up
        When no frontier is left but those given up after failed ways, try
        them again, up to this many rounds: the map and the robot's place
        have changed since, and ending ``explored`` with the rest of the
        floor behind them leaves it unmapped.  0: never.
    held_time
        With a monitor: stopped by it this long (s) while asking to move is
        trouble like a stall (``held``), with the follower driving too.  The
        monitor gets the robot out of a corner by itself after a second, but
        blindly: a follower that turns back into the same wall end is stopped,
        freed and stopped again, touching it each time.  The follower is
        backed off and turned away; held a third time at one place, it is
        taken over.  On the explorer's own ways, a command only the monitor
        would stop (a corner the curve swings onto) is replaced by the
        nearest slow motion it lets through
        (:meth:`~blocks.navigate.collision_monitor.EchoMemory.nearest_clear`),
        without failing the way: a way is failed for a stop the guard
        itself sees, or for no progress.  Boxed in, where the guard has
        refused the first command of ``jam_failures`` ways in a row (an echo
        close ahead and one close behind, a retrace refused too), planning
        again cannot free the robot and each way would fail at once until it
        ends ``stuck``: the next ways creep the same way, the nearest motion
        the monitor lets through, until one gets going.
    door_narrow, door_approach, door_speed
        A way that passes nearer than ``door_narrow`` (m) to walls on both
        sides goes through a doorway (:mod:`blocks.navigate.doorway`): the
        robot drives to a point up to ``door_approach`` (m) in front of it on
        its axis, turns to face along the axis, and drives straight through at
        ``door_speed`` (m/s), its sonar guard's lane no wider than the body
        (the jambs are beside it, not ahead).  0 turns that off.
    door_underfoot
        A way planned while the robot stands in a doorway (within half of
        ``door_approach`` of it) turns square to it on the spot and drives
        straight through, and a doorway's jambs must straddle the way.
        False (the default): a way's first half of ``door_approach`` is not
        looked at for doorways (docs/exploration.md has the measured trade).
    back_off_time, back_off_speed
        After a bump or a stall the robot undoes its last motion this long (s)
        at this speed (m/s), and after an echo blocked its way it backs
        straight off as long, while the sonar guard and the bumpers allow.
    stall_time
        A way with no progress for this long (s) fails.
    max_attempts
        A goal that failed this many times is not tried again.
    forget_radius
        Goals this close (m) to one reached or given up count as the same goal.
    seen_radius
        A goal reached with its frontier still there has looked at the
        frontier within this distance (m); the rest of a longer one is
        approached again (:func:`~blocks.explore.frontiers.unseen_parts`),
        from goals that see it past no wall of the map
        (:func:`~blocks.explore.frontiers.frontier_goals`' ``walls``).
        0 (the default): the whole frontier goes with its reached goal
        (docs/exploration.md has the measured trade).
    end_seen_radius
        ``seen_radius`` from the moment no other frontier is left, before the
        floor counts as explored: a long frontier dropped whole with the goal
        at its middle (a corridor's open end seen along its side) is the
        rest of the floor, and looking along it then costs nothing the
        exploration had to give up.  0: never.
    max_failures, stuck_radius
        This many failed ways in a row, with no goal reached between and all
        within ``stuck_radius`` (m) of where the first of them failed, and
        the robot is stuck: ways that fail here and there while the robot
        covers ground are not a robot that cannot get anywhere.
    hand_backs, hand_back_distance
        Stuck, the robot hands back to the follower for ``hand_back_distance``
        (m) of driving, then plans again from wherever that took it.  The
        follower's rules need no map, and a robot stuck by its map (a doorway
        drawn 0.2 m from where the drifted pose now puts it, a way planned
        through a jamb the sonar then stops it at) is not stuck for them;
        the map meanwhile is drawn again from there.  The ``hand_backs``-th
        time after that (0: the first time) ends the exploration ``stuck``.
    jam_failures, jam_radius, retrace_distance, max_retraces
        So many failed ways in a row within ``jam_radius`` (m) of each other
        are a jam (wedged in a doorway, against a wall end): backing off a
        little and planning again does not free it.  The robot backs out the
        way it came, along its own track, for ``retrace_distance`` (m): it
        fitted there.  At most ``max_retraces`` times between goals reached,
        each counting the ways that failed before it as forgiven.
    stale_distance, stale_gain
        Take over from the follower once it has driven ``stale_distance`` (m)
        while the map gained less than ``stale_gain`` (m^2) of known floor: it
        is going round something it has seen.  0 turns that off.
    trail_time
        Seconds of the robot's track kept passable on the planning grid (all
        of it by default): where it has driven, it fits, and the map was drawn
        from the same poses, so a doorway it came through is open on the map
        even when sonar drew its jambs into it.
    spin_rate
        Turn rate (rad/s) of the look round it takes before it calls a place explored.
    footprint
        Unknown floor within this distance (m) of the robot's track is free: it stood there.
    wall_margin
        Unknown cells this close (m) to a wall make no frontier
        (:func:`~blocks.explore.frontiers.find_frontiers`).
    """

    radius: float = 0.36
    tight_radius: float = 0.2
    tight_cost: float = 20.0
    min_frontier: float = 0.8
    reach: float = 1.0
    gain_weight: float = 1.0
    goal_distance: str = "straight"
    replan_every: float = 2.0
    back_off_time: float = 1.5
    back_off_speed: float = 0.15
    stall_time: float = 12.0
    max_attempts: int = 2
    forget_radius: float = 0.7
    seen_radius: float = 0.0
    end_seen_radius: float = 3.0
    max_failures: int = 8
    stuck_radius: float = 2.0
    hand_backs: int = 3
    hand_back_distance: float = 8.0
    jam_failures: int = 3
    jam_radius: float = 0.5
    retrace_distance: float = 1.5
    max_retraces: int = 3
    stale_distance: float = 40.0
    stale_gain: float = 2.0
    trail_time: float = math.inf
    spin_rate: float = 0.8
    footprint: float = 0.3
    wall_margin: float = 0.0
    close_enough: float = 0.5
    stall_window: float = 1.5
    stall_speed: float = 0.1
    stall_motion: float = 0.03
    escape_turn: float = 0.6
    follower_bumps: int = 3
    follower_bump_window: float = 120.0
    bump_memory: float = 0.12
    nudge_speed: float = 0.1
    nudge_time: float = 2.0
    door_narrow: float = 0.45
    door_approach: float = 0.7
    door_speed: float = 0.2
    door_underfoot: bool = False
    monitor: MonitorParams | None = None
    held_time: float = 0.8
    unpin_time: float = 8.0
    ease_by_ends: bool = False
    retry_given_up: int = 0


@dataclass
class ExploreResult:
    """What the exploration did, for run.json."""

    started: float | None = None
    start_reason: str = ""
    ended: float | None = None
    end_reason: str = ""
    goals_reached: int = 0
    goals_given_up: int = 0
    ways_failed: int = 0
    blocked_ahead: int = 0
    doorways: int = 0
    retraces: int = 0
    hand_backs: int = 0
    bumps: int = 0
    stalls: int = 0
    holds: int = 0
    boxed_in: int = 0
    looks_given_up: int = 0
    frontiers_out_of_reach: int = 0
    frontiers_given_up: int = 0
    frontiers_retried: int = 0
    distance: float = 0.0
    log: list[dict[str, Any]] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        """The counts, rounded, and the log of goals and failures."""
        out = dict(self.__dict__)
        for key in ("started", "ended", "distance"):
            if out[key] is not None:
                out[key] = round(float(out[key]), 2)
        return out


class FrontierExplorer:
    """Takes over from a perimeter follower and explores until no reachable frontier is left.

    Call :meth:`step` every tick: it returns ``None`` while the follower
    should drive, else this tick's ``(v, w)``.

    Parameters
    ----------
    maps
        ``maps()`` gives the robot's current map (an OccupancyMap in the poses' frame) or None.
    guard
        The sonar guard that checks each command against this tick's echoes
        (its ``ahead`` is the stop distance).
    bumpers
        The robot's contact switches, (name, from, to) bearings (rad), in the
        order of the ``bumpers`` fed to :meth:`step`.
    params, pursuit
        See :class:`ExploreParams` and :class:`~blocks.navigate.pursuit.PursuitParams`.
    """

    def __init__(self, maps: MapSource, guard: SonarGuard,
                 params: ExploreParams | None = None,
                 pursuit: PursuitParams | None = None,
                 bumpers: list[tuple[str, float, float]] | None = None) -> None:
        self.maps = maps
        self.guard = guard
        self.bumpers = list(bumpers or [])
        self.p = params or ExploreParams()
        self.pursuit = pursuit or PursuitParams()
        self.result = ExploreResult()
        # follow, plan, drive, align, back_off, unpin, spin, escape, turn_away, ended
        self.phase = "follow"
        self.target: FrontierGoal | None = None
        self._leg: PurePursuit | None = None
        self._pending: list[tuple[str, Any]] = []  # legs after this one: a doorway's
        self._squeeze = False  # this leg goes through a doorway
        self._align_heading = 0.0
        self._narrow_guard = replace(guard, side_margin=0.0)
        self._echoes = None if self.p.monitor is None else EchoMemory(guard, self.p.monitor)
        self._feeds_echoes = True
        self._pressed: set[int] = set()  # bumpers pressed on the last tick
        self._held = HeldClock()  # by the monitor
        self._held_for = 0.0
        self._unpin_until = 0.0
        self._unpin_speed = -self.p.back_off_speed
        self._door_pursuit = replace(self.pursuit, cruise=min(self.p.door_speed,
                                                             self.pursuit.cruise))
        self._occupancy: Any = None  # the map the last goals were chosen on
        self._streak: list[tuple[float, float]] = []  # where the ways failed since a goal
        self._retraces = 0
        self._retrace_pending = False
        self._retrace_until = 0.0
        self._leg_started = self._progress_time = self._next_look = self._back_until = 0.0
        self._best = 0.0
        self._failures = 0
        self._refused = 0  # ways in a row whose first command the guard refused
        self._attempts: list[tuple[tuple[float, float], int]] = []
        self._forgotten: list[tuple[float, float]] = []  # reached or given up
        self._given_up: list[tuple[float, float]] = []
        self._given_up_left = 0
        self._retry_rounds = 0
        self._seen_radius = self.p.seen_radius  # end_seen_radius once the rest is done
        self._looks: list[tuple[float, float]] = []  # where it looked round
        self._spun = self._heading = 0.0
        self._turns = TurnWatch(stall_time=self.p.stall_time)  # a look round that cannot turn
        self._track: list[tuple[float, float, float]] = []  # time, x, y every 0.1 m
        self._samples: list[tuple[float, float]] = []  # (distance driven, known area)
        self._driven = 0.0
        self._last: np.ndarray | None = None
        self._commands: list[tuple[float, float, float, float]] = []  # time, x, y, v asked
        self._command = (0.0, 0.0)  # what this machine asked for last tick
        self._asked = (0.0, 0.0)  # what this machine or the follower asked for last tick
        self._odometry = np.zeros(3)  # the raw odometry pose of this tick
        self._bumps: list[tuple[float, float]] = []  # what the body touched or the guard heard
        self._nudged = 0.0
        self._follower_trouble: list[float] = []
        self._trouble_spots: list[tuple[float, float]] = []
        self._hold_spots: list[tuple[float, float]] = []
        self._escape_until = self._turn_until = 0.0
        self._escape_speed = self._escape_turn = 0.0
        self._after_escape = "plan"
        self._follow_until: float | None = None  # handed back: driven this far, take over

    # ---- the machine ---------------------------------------------------------------------
    def share_echoes(self, echoes: EchoMemory) -> None:
        """Judge motions (with ``params.monitor``) on ``echoes``, the monitor's, fed with
        this tick's scan before each step, rather than on a copy of its own."""
        if self.p.monitor is not None:
            self._echoes, self._feeds_echoes = echoes, False

    @property
    def active(self) -> bool:
        """Whether exploration drives (it has taken over and not ended)."""
        return self.phase not in ("follow", "ended")

    @property
    def ended(self) -> bool:
        """Whether exploration has ended (reason in ``result.end_reason``)."""
        return self.phase == "ended"

    def step(self, time: float, pose: np.ndarray, ranges: np.ndarray, *,
             follower_done: bool = False, hold: bool = False, preempted: bool = False,
             bumpers: np.ndarray | None = None, follower_v: float = 0.0,
             follower_w: float = 0.0, odometry: np.ndarray | None = None,
             monitor_scale: float = 1.0) -> tuple[float, float] | None:
        """This tick's velocities, or None while the follower drives.

        ``hold`` stops the robot (a sign is being read); ``preempted`` says
        another behaviour drives this tick (a room visit), so the way is
        planned again afterwards from wherever the robot then is.
        ``bumpers`` are the contact switches now; ``follower_v`` and
        ``follower_w`` are what the follower asks for (a stall is a command
        odometry does not see).
        ``odometry`` is the raw odometry pose when ``pose`` is corrected
        against the map: a stall is judged on it, as a correction can move
        ``pose`` while the wheels stand still.  ``monitor_scale`` is how much
        of the last tick's command the collision monitor let through (with
        ``params.monitor`` set; 0: it stopped the robot).
        """
        pose = np.asarray(pose, dtype=np.float64)
        self._odometry = pose if odometry is None else np.asarray(odometry, dtype=np.float64)
        if self._echoes is not None and self._feeds_echoes:
            self._echoes.add(time, self._odometry, ranges)
        self._remember(time, pose)
        self._note_monitor(time, monitor_scale)
        command = self._decide(time, pose, ranges, follower_done, hold, preempted, bumpers,
                               follower_v)
        self._command = command if command is not None else (follower_v, 0.0)
        self._asked = command if command is not None else (follower_v, follower_w)
        return command

    def _decide(self, time: float, pose: np.ndarray, ranges: np.ndarray, follower_done: bool,
                hold: bool, preempted: bool, bumpers: np.ndarray | None,
                follower_v: float) -> tuple[float, float] | None:
        if self.phase == "ended":
            return None
        if self.phase in ("escape", "turn_away"):
            return self._escape(time, pose, ranges, bumpers)
        trouble = "" if hold or preempted else self._trouble(time, pose, ranges, bumpers)
        if self.phase == "follow":
            handed_back = self._follow_until is not None
            if trouble:
                return self._follower_trouble_at(time, pose, trouble,
                                                 follower_done and not handed_back)
            if handed_back:
                reason = "handed back" if self._driven >= self._follow_until else ""
            else:
                reason = "loop closed" if follower_done else self._stale(time)
            if not reason:
                return None
            self._take_over(time, reason)
        if preempted:
            self._abandon("plan")
            return 0.0, 0.0
        if hold:
            self._progress_time = time  # a pause is not a stall
            return 0.0, 0.0
        if trouble and self.phase == "retrace":
            return self._start_escape(time, "plan")
        if trouble and self.phase in ("drive", "align"):
            self._failed(time, trouble)  # then planning again, or handed back, or ended
            return self._start_escape(time, self.phase) if self.phase != "ended" else None
        if self.phase == "back_off":
            return self._back_off(time, ranges, bumpers)
        if self.phase == "unpin":
            return self._unpin(time, ranges, bumpers)
        if self.phase == "spin":
            return self._spin(time, pose)
        if self.phase == "align":
            return self._align(time, pose, ranges)
        if self.phase == "plan" and self._retrace_pending:
            self._start_retrace(time, pose)
        if self.phase == "retrace":
            return self._retrace(time, pose, ranges)
        if self.phase == "plan" and not self._plan(time, pose):
            return (0.0, 0.0) if self.phase != "ended" else None
        if self.phase == "align":  # the way starts in a doorway: square to it first
            return self._align(time, pose, ranges)
        return self._drive(time, pose, ranges)

    def _take_over(self, time: float, reason: str) -> None:
        self.phase = "plan"
        if self._follow_until is not None:  # back from a hand-back: started long ago
            self._follow_until = None
            self.result.log.append({"t": round(time, 1), "take over": reason,
                                    "at": [round(float(v), 2) for v in self._last[:2]]})
            return
        self.result.started, self.result.start_reason = time, reason

    # ---- contact and stalls ---------------------------------------------------------------
    def _note_monitor(self, time: float, scale: float) -> None:
        """How long the monitor has held still what was asked (this machine's or the
        follower's command)."""
        v, w = self._asked
        moving = self.p.monitor is not None and (abs(v) >= 1e-6 or abs(w) >= 1e-6)
        self._held_for = self._held.update(time, scale, moving)

    def _trouble(self, time: float, pose: np.ndarray, ranges: np.ndarray,
                 bumpers: np.ndarray | None) -> str:
        """'bumped NAME', 'stalled' or 'held' if the robot is touching something, cannot
        move or is kept from moving, else ''."""
        pressed = [] if bumpers is None else [k for k, on in enumerate(bumpers) if on]
        if self.p.monitor is not None:  # a bumper that stays pressed was one bump
            pressed, self._pressed = [k for k in pressed if k not in self._pressed], set(pressed)
        if pressed:
            for k in pressed:
                self._remember_touch(pose, *self.bumpers[k][1:])
            self.result.bumps += 1
            return "bumped " + "+".join(self.bumpers[k][0] for k in pressed)
        v = self._command[0]
        if self._held_for >= self.p.held_time:
            self._held.reset()
            self.result.holds += 1
            self._remember_blocked(pose, ranges, v)
            return "held"
        odometry = self._odometry
        self._commands.append((time, float(odometry[0]), float(odometry[1]), v))
        while self._commands and self._commands[0][0] < time - self.p.stall_window:
            self._commands.pop(0)
        t0, x0, y0, _ = self._commands[0]
        if (time - t0 >= self.p.stall_window - 1e-9
                and all(abs(c[3]) >= self.p.stall_speed for c in self._commands)
                and math.hypot(odometry[0] - x0, odometry[1] - y0) < self.p.stall_motion):
            self._commands.clear()
            self.result.stalls += 1
            ahead = 1.0 if v > 0 else -1.0
            reach = self.guard.length / 2 + self.p.bump_memory
            self._bumps.append((float(pose[0] + ahead * reach * math.cos(pose[2])),
                                float(pose[1] + ahead * reach * math.sin(pose[2]))))
            return "stalled"
        return ""

    def _remember_touch(self, pose: np.ndarray, start: float, end: float) -> None:
        """Put what a pressed bumper touched on the planning grid: along the body's edge
        across the bumper's whole span (a switch does not say where along it)."""
        half_l, half_w = self.guard.length / 2, self.guard.width / 2
        for bearing in start + np.linspace(0.0, (end - start) % (2 * math.pi), 5):
            c, s = math.cos(bearing), math.sin(bearing)
            edge = min(half_l / abs(c) if abs(c) > 1e-9 else math.inf,
                       half_w / abs(s) if abs(s) > 1e-9 else math.inf)
            reach = edge + self.p.bump_memory / 2
            self._bumps.append((float(pose[0] + reach * math.cos(pose[2] + bearing)),
                                float(pose[1] + reach * math.sin(pose[2] + bearing))))

    def _follower_trouble_at(self, time: float, pose: np.ndarray, why: str,
                             follower_done: bool) -> tuple[float, float]:
        """The follower bumped or stalled: escape and hand back, or take over if it keeps on."""
        here = (float(pose[0]), float(pose[1]))
        if why == "held":  # the monitor kept it from touching: a cycle only the third time here
            again = sum(self._near(here, [spot]) for spot in self._hold_spots) >= 2
            self._hold_spots.append(here)
        else:
            again = self._near(here, self._trouble_spots)  # the same place: a cycle
            self._trouble_spots.append(here)
            self._follower_trouble = [t for t in self._follower_trouble
                                      if t >= time - self.p.follower_bump_window] + [time]
        self.result.log.append({"t": round(time, 1), "follower": why,
                                "at": [round(float(v), 2) for v in pose[:2]]})
        if follower_done or again or len(self._follower_trouble) >= self.p.follower_bumps:
            self._take_over(time, "loop closed" if follower_done else "follower jammed")
            return self._start_escape(time, "plan")
        return self._start_escape(time, "follow")

    def _start_escape(self, time: float, then: str) -> tuple[float, float]:
        """Back off from what the robot touched (forward if it was behind), then ``then``."""
        self._leg, self.target = None, None
        self._pending, self._squeeze = [], False
        # Undo the motion that got it there: back if it was going ahead, and the turn reversed.
        v, w = self._command
        backwards = v >= 0
        self._escape_speed = -self.p.back_off_speed if backwards else self.p.back_off_speed
        self._escape_turn = -float(np.clip(w, -self.p.spin_rate, self.p.spin_rate))
        self._escape_until = time + self.p.back_off_time
        self._turn_until = self._escape_until + (
            self.p.escape_turn / self.p.spin_rate if then == "follow" else 0.0)
        self._after_escape = then
        self.phase = "escape"
        return 0.0, 0.0

    def _escape(self, time: float, pose: np.ndarray, ranges: np.ndarray,
                bumpers: np.ndarray | None) -> tuple[float, float]:
        if self.phase == "escape":
            v = self._escape_speed
            touching = self._touching(bumpers, v)
            if time < self._escape_until and not touching and not self._blocked(
                    ranges, v, self._escape_turn):
                return v, self._escape_turn
            self.phase = "turn_away"
        if time < self._turn_until and not self._blocked(ranges, 0.0, self.p.spin_rate):
            return 0.0, self.p.spin_rate
        self._commands.clear()
        self.phase = self._after_escape
        return 0.0, 0.0

    def _touching(self, bumpers: np.ndarray | None, v: float) -> bool:
        """Whether a bumper facing the way a motion at speed ``v`` goes is pressed."""
        if bumpers is None:
            return False
        for (_, start, end), on in zip(self.bumpers, bumpers):
            mid = start + ((end - start) % (2 * math.pi)) / 2
            if on and math.cos(mid) * v > 0:
                return True
        return False

    def _remember(self, time: float, pose: np.ndarray) -> None:
        if self._last is not None:
            step = float(np.hypot(*(pose[:2] - self._last[:2])))
            self._driven += step
            if self.active:
                self.result.distance += step
        self._last = pose.copy()
        if not self._track or math.hypot(pose[0] - self._track[-1][1],
                                         pose[1] - self._track[-1][2]) >= 0.1:
            self._track.append((time, float(pose[0]), float(pose[1])))

    def _stale(self, time: float) -> str:
        """A reason to take over from a follower that brings no new floor, or ''."""
        if self.p.stale_distance <= 0 or time < self._next_look:
            return ""
        self._next_look = time + self.p.replan_every
        occupancy = self.maps()
        if occupancy is None:
            return ""
        occupied, free, _ = occupancy.classes()
        known = float(np.count_nonzero(occupied | free)) * occupancy.resolution ** 2
        self._samples.append((self._driven, known))
        while len(self._samples) > 1 and \
                self._driven - self._samples[1][0] >= self.p.stale_distance:
            self._samples.pop(0)
        then, before = self._samples[0]
        if self._driven - then >= self.p.stale_distance and known - before < self.p.stale_gain:
            return "no new floor"
        return ""

    # ---- choosing and planning -----------------------------------------------------------
    def _map(self) -> Any:
        """The robot's map with the floor under its track free: it stood there.

        Why: no sonar sees the floor under the robot, so its footprint is an
        unknown hole, which would be a frontier and, grown by the radius,
        would block the robot's own cell.  Only unknown cells are cleared;
        a cell the map holds occupied stays so.
        """
        occupancy = self.maps()
        if occupancy is None or not self._track:
            return occupancy
        track = np.array([(x, y) for _, x, y in self._track])
        under = cells_near(track, self.p.footprint, occupancy.shape, occupancy.resolution,
                           occupancy.origin)
        _, _, unknown = occupancy.classes()
        clear = under & unknown
        touched = self._touched(occupancy)
        if not clear.any() and touched is None:
            return occupancy
        p = np.array(occupancy.occupancy, dtype=np.float64)
        p[clear] = 0.0
        if touched is not None:
            p[touched] = 1.0
        return replace(occupancy, occupancy=p)

    def _touched(self, occupancy: Any) -> np.ndarray | None:
        """Cells within ``bump_memory`` of where the body touched something, or None."""
        if not self._bumps or self.p.bump_memory <= 0:
            return None
        res = occupancy.resolution
        h, w = occupancy.shape
        mask = np.zeros((h, w), dtype=bool)
        k = int(math.ceil(self.p.bump_memory / res))
        for bx, by in self._bumps:
            r = int(math.floor((by - occupancy.origin[1]) / res))
            c = int(math.floor((bx - occupancy.origin[0]) / res))
            mask[max(r - k, 0):max(r + k + 1, 0), max(c - k, 0):max(c + k + 1, 0)] = True
        return mask

    def _grid(self, occupancy: Any, time: float, radius: float) -> NavGrid:
        recent = np.array([(x, y) for t, x, y in self._track if t >= time - self.p.trail_time])
        grid = inflate(occupancy, radius=radius)
        grid = unblock_traversed(grid, recent) if len(recent) else grid
        if radius < self.p.radius:  # the tight grid: its extra cells only where they must be
            grid.cost[~grid.blocked & (grid.clearance < self.p.radius)] += self.p.tight_cost
        return grid

    def _goals(self, time: float, pose: np.ndarray) -> list[tuple[FrontierGoal, NavGrid]]:
        """The goals to choose from, cheapest first, each with the grid to plan it on."""
        occupancy = self._map()
        self._occupancy = occupancy
        if occupancy is None:
            return []
        frontiers = find_frontiers(occupancy, min_length=self.p.min_frontier,
                                   wall_margin=self.p.wall_margin)
        wide = self._grid(occupancy, time, self.p.radius)
        tight = self._grid(occupancy, time, self.p.tight_radius) \
            if self.p.tight_radius > 0 and frontiers else None

        def choose(frontiers: list[Any], walls: np.ndarray | None = None
                   ) -> list[tuple[FrontierGoal, NavGrid]]:
            goals = [(g, wide) for g in frontier_goals(wide, frontiers, pose[:2],
                                                       reach=self.p.reach, walls=walls)]
            if tight is not None and frontiers:
                goals = self._through_tight_doors(tight, pose, frontiers, goals, walls)
            return goals
        goals = choose(frontiers)
        self.result.frontiers_out_of_reach = len(frontiers) - len(goals)
        self._given_up_left = sum(self._near(g.goal, self._given_up) for g, _ in goals)
        # a goal reached with its frontier still there used up the frontier near it; the rest
        # of a long one (a corridor's open end seen along its side) is still to be visited,
        # from where the robot sees it: a frontier drawn outside the building by beams that
        # passed a wall at a grazing angle is never seen from inside, one part or another
        reached = [xy for xy in self._forgotten if not self._near(xy, self._given_up)] \
            if self._seen_radius > 0 else []
        rest = [part for g, _ in goals
                if self._near(g.goal, reached) and not self._near(g.goal, self._given_up)
                for part in unseen_parts(g.frontier, reached, self._seen_radius,
                                         self.p.min_frontier, occupancy.resolution)]
        goals = [(g, grid) for g, grid in goals + (choose(rest, occupancy.classes()[0])
                                                   if rest else [])
                 if not self._near(g.goal, self._forgotten)]
        if self.p.goal_distance == "path" and goals:
            goals = self._by_way(goals, pose)
        return sorted(goals, key=lambda pair: pair[0].distance
                      - self.p.gain_weight * pair[0].frontier.length)

    @staticmethod
    def _by_way(goals: list[tuple[FrontierGoal, NavGrid]], pose: np.ndarray
                ) -> list[tuple[FrontierGoal, NavGrid]]:
        """The goals with their distance the way there over the grid each is planned on,
        not the straight line (one Dijkstra pass per grid: the wide one, and the tight
        one only for the goals behind a door that only it opens)."""
        travel: dict[int, np.ndarray | None] = {}
        out = []
        for g, grid in goals:
            if id(grid) not in travel:
                start = grid.free_cell_at(float(pose[0]), float(pose[1]), SNAP_RADIUS)
                travel[id(grid)] = None if start is None else grid.travel_distances(*start)
            ways = travel[id(grid)]
            r, c = grid.world_to_cell(*g.goal)
            way = float(ways[r, c]) if ways is not None and grid.inside(r, c) else math.inf
            out.append((replace(g, distance=way if math.isfinite(way) else g.distance + 1e3),
                        grid))
        return out

    def _through_tight_doors(self, tight: NavGrid, pose: np.ndarray, frontiers: list[Any],
                             goals: list[tuple[FrontierGoal, NavGrid]],
                             walls: np.ndarray | None) -> list[tuple[FrontierGoal, NavGrid]]:
        """Each frontier's goal on the tight grid where it gets nearer than the wide one's."""
        wide = {id(g.frontier): (g, grid) for g, grid in goals}

        def to_middle(g: FrontierGoal) -> float:
            return math.hypot(g.goal[0] - g.frontier.middle[0], g.goal[1] - g.frontier.middle[1])
        out = []
        for g in frontier_goals(tight, frontiers, pose[:2], reach=self.p.reach, walls=walls):
            known = wide.get(id(g.frontier))
            if known is None or to_middle(g) < to_middle(known[0]) - self.p.reach / 2:
                out.append((g, tight))
            else:
                out.append(known)
        return out

    def _near(self, xy: tuple[float, float], places: list[tuple[float, float]]) -> bool:
        return any(math.hypot(xy[0] - fx, xy[1] - fy) < self.p.forget_radius
                   for fx, fy in places)

    def _plan(self, time: float, pose: np.ndarray) -> bool:
        """Choose a frontier and plan the way there; False if none (ending if none is left)."""
        goals = self._goals(time, pose)
        for goal, grid in goals:
            try:
                way = plan(grid, pose[:2], goal.goal).points
            except PlanningError:
                self._forget(goal.goal)
                continue
            self.target = goal
            self._start_way(way, grid, time)
            self.result.log.append({"t": round(time, 1), "goal": [round(v, 2) for v in goal.goal],
                                    "frontier_m": round(goal.frontier.length, 2)})
            return True
        if not self._looked_here(pose):  # a look round first: the map may just be thin here
            self.phase, self._spun, self._heading = "spin", 0.0, float(pose[2])
            self._looks.append((float(pose[0]), float(pose[1])))
            return False
        if self._given_up_left and self._retry_rounds < self.p.retry_given_up:
            self._retry_given_up(time)
            return False
        if self.p.end_seen_radius > self._seen_radius:
            # the rest is done: long frontiers still there are looked at along their length
            self._seen_radius = self.p.end_seen_radius
            self.result.log.append({"t": round(time, 1), "long frontiers": self._seen_radius})
            return self._plan(time, pose)
        self.result.frontiers_given_up = self._given_up_left
        # frontiers left behind failed ways are floor not mapped: say so, not "explored"
        self._end(time, "frontiers given up" if self._given_up_left else "explored")
        return False

    def _retry_given_up(self, time: float) -> None:
        """Forget that the frontiers given up were given up: they are chosen again."""
        self._retry_rounds += 1
        self.result.frontiers_retried += self._given_up_left
        self.result.log.append({"t": round(time, 1), "retry": self._given_up_left})
        self._forgotten = [g for g in self._forgotten if not self._near(g, self._given_up)]
        self._attempts = [(xy, n) for xy, n in self._attempts if not self._near(xy, self._given_up)]
        self._given_up = []

    def _looked_here(self, pose: np.ndarray) -> bool:
        return self._near((float(pose[0]), float(pose[1])), self._looks)

    def _spin(self, time: float, pose: np.ndarray) -> tuple[float, float]:
        """Turn a whole turn on the spot (measured, not timed), then choose again; a turn
        that gets nowhere for ``stall_time`` counts as done."""
        self._spun += abs(math.remainder(float(pose[2]) - self._heading, 2 * math.pi))
        self._heading = float(pose[2])
        stalled = self._spun < 2 * math.pi and self._turns.stalled(time, self._heading,
                                                                   "look round")
        if stalled:
            self.result.looks_given_up += 1
            self.result.log.append({"t": round(time, 1), "look round": "cannot turn",
                                    "at": [round(float(pose[0]), 2), round(float(pose[1]), 2)]})
        if self._spun >= 2 * math.pi or stalled:
            self.phase = "plan"
            return 0.0, 0.0
        return 0.0, self.p.spin_rate

    def _start_way(self, way: np.ndarray, grid: NavGrid, time: float) -> None:
        """Drive ``way``; through its first doorway in three legs: up to the point in
        front of it, a turn to face along its axis, and straight through."""
        self._pending = []
        door = self._doorway(way, grid)
        if door is None:
            self._start_leg(way, time)
            return
        door_way, before, after = door
        self.result.doorways += 1
        # the rest of the way from where the doorway's leg leaves it
        s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(way, axis=0).T))]
        rest = way[s > door_way.at + float(np.hypot(*(after - np.asarray(door_way.centre))))]
        align = ("align", math.atan2(door_way.axis[1], door_way.axis[0]))
        leg = ("leg", np.vstack([after, rest]) if len(rest) else np.vstack([after, way[-1]]))
        if self.p.door_underfoot and door_way.at < self.p.door_approach / 2:
            # standing in it: line up where it stands, then straight through
            self._pending = [align, ("door", np.vstack([way[0], after])), leg]
            self._next_leg(time)
            return
        try:
            to_door = plan(grid, way[0], before).points
        except PlanningError:
            self._start_leg(way, time)
            return
        self._pending = [align, ("door", np.vstack([before, after])), leg]
        self._start_leg(to_door, time)

    def _doorway(self, way: np.ndarray, grid: NavGrid
                 ) -> tuple[Doorway, np.ndarray, np.ndarray] | None:
        """The way's first doorway and the points in front of and behind it, or None."""
        if self.p.door_narrow <= 0 or self._occupancy is None:
            return None
        occupied, _, _ = self._occupancy.classes()
        underfoot = self.p.door_underfoot
        door = find_doorway(occupied, self._occupancy.resolution, self._occupancy.origin, way,
                            narrow=self.p.door_narrow,
                            skip=0.0 if underfoot else self.p.door_approach / 2,
                            straddle=underfoot)
        if door is None:
            return None
        ends = doorway_legs(grid, door, approach=self.p.door_approach)
        return None if ends is None else (door, ends[0], ends[1])

    def _next_leg(self, time: float) -> bool:
        """Start the way's next leg; False if there is none."""
        if not self._pending:
            return False
        kind, data = self._pending.pop(0)
        if kind == "align":
            self.phase, self._align_heading = "align", float(data)
            self._leg = None
            self._progress_time = time
        else:
            self._start_leg(data, time, squeeze=kind == "door")
        return True

    def _align(self, time: float, pose: np.ndarray, ranges: np.ndarray) -> tuple[float, float]:
        """Turn on the spot to face along the doorway's axis, then drive through it."""
        error = math.remainder(self._align_heading - float(pose[2]), 2 * math.pi)
        w = float(np.clip(2.0 * error, -self.p.spin_rate, self.p.spin_rate))
        if abs(error) < 0.05 or time - self._progress_time > self.p.stall_time \
                or self._blocked(ranges, 0.0, w):
            self._next_leg(time)  # facing it (or as near as the guard lets it turn)
            return 0.0, 0.0
        return 0.0, w

    def _start_leg(self, way: np.ndarray, time: float, squeeze: bool = False) -> None:
        self._nudged = 0.0
        self._squeeze = squeeze
        self._leg = PurePursuit(way, self._door_pursuit if squeeze else self.pursuit)
        self.phase = "drive"
        self._leg_started = self._progress_time = time
        self._next_look = time + self.p.replan_every
        self._best = 0.0

    # ---- driving -------------------------------------------------------------------------
    def _drive(self, time: float, pose: np.ndarray, ranges: np.ndarray) -> tuple[float, float]:
        leg = self._leg
        assert leg is not None and self.target is not None
        v, w, status = leg.step(pose, 0.0)
        if status == "arrived":
            if not self._next_leg(time):
                self._reached(time)
            return 0.0, 0.0
        why = (self._narrow_guard if self._squeeze else self.guard).blocked(ranges, v, w)
        if not why:
            why = self._monitor_stops(v, w)
            if why:
                # only the monitor would stop it (a corner the curve swings onto): creep the
                # nearest way it lets through, as it would itself after a second; keep the way
                creep = self._echoes.nearest_clear(self._odometry, v, w, self.p.monitor)
                if creep is not None:
                    return creep
        touched = None if why else self._touched_in_sweep(pose, v, w)
        if touched is not None and self._nudged < self.p.nudge_time:
            # a wall end the sonar misses, found by touching it, is in the corners' sweep
            nudge = -self.p.nudge_speed if touched[0] > 0 else self.p.nudge_speed
            if not self._blocked(ranges, nudge, 0.0):
                self._nudged += 0.1
                return nudge, 0.0
        if why == "turning":  # too close to something to turn: ease away from it first
            nudge = self._nudge(ranges)
            if nudge is not None and self._nudged < self.p.nudge_time:
                self._nudged += 0.1
                return nudge
        if why:
            if leg.remaining <= self.p.close_enough and not self._pending:
                self._reached(time)  # at the wall the goal is beside
                return 0.0, 0.0
            creep = self._creep_boxed_in(v, w)
            if creep is not None:
                return creep
            if self._best == 0.0 and time - self._leg_started < 0.5:
                self._refused += 1
                if self._refused == self.p.jam_failures and self._echoes is not None:
                    self.result.boxed_in += 1
                    self.result.log.append({"t": round(time, 1), "boxed in": "creeping",
                                            "at": [round(float(x), 2) for x in pose[:2]]})
            self.result.blocked_ahead += 1
            self._remember_blocked(pose, ranges, v)
            self._failed(time, f"blocked {why}")
            if self.phase == "plan":  # room to plan round the echo
                self.phase, self._back_until = "back_off", time + self.p.back_off_time
            return 0.0, 0.0
        if leg.progress > self._best + 0.05 or status == "turning":
            self._best, self._progress_time = max(self._best, leg.progress), time
            if leg.progress > 0.05:
                self._refused = 0  # it got going
        if time - self._progress_time > self.p.stall_time:
            self._failed(time, "no progress")
            return 0.0, 0.0
        if time >= self._next_look:
            self._next_look = time + self.p.replan_every
            if not self._target_still_there(time, pose):
                self._reached(time)
                return 0.0, 0.0
        return float(v), float(w)

    def _creep_boxed_in(self, v: float, w: float) -> tuple[float, float] | None:
        """Boxed in (see ``held_time`` in :class:`ExploreParams`): the slow motion nearest
        to (v, w) that the monitor lets through, or None (not boxed in, or no such motion)."""
        if self._echoes is None or self._refused < self.p.jam_failures:
            return None
        return self._echoes.nearest_clear(self._odometry, v, w, self.p.monitor)

    def _blocked(self, ranges: np.ndarray, v: float, w: float, narrow: bool = False) -> str:
        """Why the motion (v, w) is refused: by the sonar guard on this tick's echoes (its
        lane no wider than the body if ``narrow``), or as the collision monitor downstream
        would stop it (``ahead``, ``behind`` or ``turning``); '' if it may go."""
        return (self._narrow_guard if narrow else self.guard).blocked(ranges, v, w) \
            or self._monitor_stops(v, w)

    def _monitor_stops(self, v: float, w: float) -> str:
        """``ahead``, ``behind`` or ``turning`` if the monitor downstream would stop the
        motion (v, w), else '' (also without a monitor)."""
        if self._echoes is None or not self._echoes.stops(self._odometry, v, w, self.p.monitor):
            return ""
        return "ahead" if v > 1e-3 else "behind" if v < -1e-3 else "turning"

    def _touched_in_sweep(self, pose: np.ndarray, v: float, w: float) -> np.ndarray | None:
        """The nearest remembered touch (robot frame) that a sharp turn (on the spot, or
        on a circle smaller than the corners') would sweep into, or None: the sonar
        guard cannot hear a thin wall end seen edge on, but the bumpers have felt it,
        and turning beside it hits it again."""
        half_l, half_w = self.guard.length / 2, self.guard.width / 2
        sweep = math.hypot(half_l, half_w) + self.guard.turn_margin
        # a turn tighter than the corners' circle swings them out sideways
        if not self._bumps or self.p.bump_memory <= 0 or abs(w) <= 1e-3 \
                or abs(v) >= sweep * abs(w):
            return None
        points = np.array(self._bumps) - pose[:2]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        local = np.column_stack([c * points[:, 0] + s * points[:, 1],
                                 -s * points[:, 0] + c * points[:, 1]])
        reach = np.hypot(local[:, 0], local[:, 1])
        outside = (np.abs(local[:, 0]) > half_l) | (np.abs(local[:, 1]) > half_w)
        inside = np.flatnonzero(outside & (reach <= sweep))
        return None if not len(inside) else local[inside[np.argmin(reach[inside])]]

    def _nudge(self, ranges: np.ndarray) -> tuple[float, float] | None:
        """A slow straight move out of a spot too tight to turn in, if the guard allows it."""
        if self.p.ease_by_ends:
            v = self._easing(ranges)
            return None if v is None else (v, 0.0)
        points = self.guard.echo_points(ranges)  # away from the nearest echo
        if len(points) == 0:
            return None
        nearest = points[int(np.argmin(np.hypot(points[:, 0], points[:, 1])))]
        v = -self.p.nudge_speed if nearest[0] > 0 else self.p.nudge_speed
        return None if self._blocked(ranges, v, 0.0) else (v, 0.0)

    def _easing(self, ranges: np.ndarray) -> float | None:
        """The speed of a slow straight move out of a tight spot: by the end of the body
        farther from the echoes around it (:meth:`SonarGuard.ease_direction`), else the
        other way; None if the guard allows neither."""
        if len(self.guard.echo_points(ranges)) == 0:
            return None
        first = self.guard.ease_direction(ranges) * self.p.nudge_speed
        for v in (first, -first):
            if not self._blocked(ranges, v, 0.0):
                return v
        return None

    def _remember_blocked(self, pose: np.ndarray, ranges: np.ndarray, v: float) -> None:
        """Put the echo that stopped the robot on the planning grid (the map may have missed it).

        The echo nearest the body on the side it was driving to, in the odometry frame.
        """
        points = self.guard.echo_points(ranges)
        ahead = points[points[:, 0] * (1.0 if v >= 0 else -1.0) > 0]
        if len(ahead) == 0:
            return
        px, py = ahead[int(np.argmin(np.hypot(ahead[:, 0], ahead[:, 1])))]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        self._bumps.append((float(pose[0] + c * px - s * py), float(pose[1] + s * px + c * py)))

    def _target_still_there(self, time: float, pose: np.ndarray) -> bool:
        """Whether the frontier the robot is heading for is still on the map."""
        occupancy = self._map()
        if occupancy is None or self.target is None:
            return True
        frontiers = find_frontiers(occupancy, min_length=self.p.min_frontier,
                                   wall_margin=self.p.wall_margin)
        gx, gy = self.target.goal
        return any(np.min(np.hypot(f.points[:, 0] - gx, f.points[:, 1] - gy))
                   <= self.p.reach + 0.3 for f in frontiers)

    def _back_off(self, time: float, ranges: np.ndarray,
                  bumpers: np.ndarray | None) -> tuple[float, float]:
        """Straight back a little, while the guard and the rear bumpers allow, then plan."""
        v = -self.p.back_off_speed
        touching = self._touching(bumpers, v)
        if touching or self._blocked(ranges, v, 0.0):
            self.phase = "plan"
            return 0.0, 0.0
        if time >= self._back_until:
            self.phase = "plan"
            ease = None
            if self.p.monitor is not None and self._pinned(ranges):
                ease = self._easing(ranges) if self.p.ease_by_ends else -self.p.back_off_speed
            if ease is not None:
                self.phase, self._unpin_until = "unpin", time + self.p.unpin_time
                self._unpin_speed = math.copysign(self.p.back_off_speed, ease)
                how = "easing ahead" if ease > 0 else "backing"
                self.result.log.append({"t": round(time, 1), "unpin": f"{how} along the wall",
                                        "at": [round(float(x), 2) for x in self._last[:2]]})
            return 0.0, 0.0
        return v, 0.0

    def _pinned(self, ranges: np.ndarray) -> bool:
        """Whether the robot can turn on the spot neither way."""
        return bool(self._blocked(ranges, 0.0, self.p.spin_rate)
                    and self._blocked(ranges, 0.0, -self.p.spin_rate))

    def _unpin(self, time: float, ranges: np.ndarray,
               bumpers: np.ndarray | None) -> tuple[float, float]:
        """Move straight along what pins the robot until it can turn (or for ``unpin_time``),
        out by the end of the body farther from it (see :meth:`_easing`)."""
        v = self._unpin_speed
        touching = self._touching(bumpers, v)
        if time >= self._unpin_until or touching or self._blocked(ranges, v, 0.0) \
                or not self._pinned(ranges):
            self._progress_time = time
            self.phase = "plan"
            return 0.0, 0.0
        return v, 0.0

    # ---- outcomes ------------------------------------------------------------------------
    def _reached(self, time: float) -> None:
        assert self.target is not None
        self.result.goals_reached += 1
        self._failures = self._retraces = self._refused = 0
        self._streak.clear()
        self._forget(self.target.goal)
        self._abandon("plan")

    def _failed(self, time: float, why: str) -> None:
        assert self.target is not None
        self.result.ways_failed += 1
        self._failures += 1
        goal = self.target.goal
        for k, (xy, count) in enumerate(self._attempts):
            if math.hypot(xy[0] - goal[0], xy[1] - goal[1]) < self.p.forget_radius:
                self._attempts[k] = (xy, count + 1)
                break
        else:
            self._attempts.append((goal, 1))
            count = 0
        if count + 1 >= self.p.max_attempts:
            self.result.goals_given_up += 1
            self._forget(goal)
            self._given_up.append(goal)
        self.result.log.append({"t": round(time, 1), "failed": why,
                                "at": [round(float(v), 2) for v in self._last[:2]]})
        self._abandon("plan")
        here = (float(self._last[0]), float(self._last[1]))
        if self._streak and math.hypot(here[0] - self._streak[0][0],
                                       here[1] - self._streak[0][1]) > self.p.stuck_radius:
            self._failures, self._streak = 1, []  # it got somewhere since: a new count
        self._streak.append(here)
        if self._failures >= self.p.max_failures:
            if self.result.hand_backs < self.p.hand_backs:
                self._hand_back(time)
            else:
                self._end(time, "stuck")
        elif self._jammed():
            self._retrace_pending = True

    def _hand_back(self, time: float) -> None:
        """Stuck here: let the follower drive ``hand_back_distance`` before planning again."""
        self.result.hand_backs += 1
        self.result.log.append({"t": round(time, 1), "hand back": "stuck",
                                "at": [round(float(v), 2) for v in self._last[:2]]})
        # the follower's troubles before count for nothing: it is here to get out of the
        # place they happened (each taken as a cycle, it would be taken over at once)
        self._trouble_spots, self._hold_spots, self._follower_trouble = [], [], []
        self._abandon("follow")
        self._follow_until = self._driven + self.p.hand_back_distance
        self._failures = self._retraces = self._refused = 0
        self._retrace_pending = False
        self._streak.clear()
        self._commands.clear()

    # ---- jams ----------------------------------------------------------------------------
    def _jammed(self) -> bool:
        """The last ``jam_failures`` ways all failed within ``jam_radius`` of one another,
        and a retrace is left."""
        recent = self._streak[-self.p.jam_failures:]
        if self._retraces >= self.p.max_retraces or len(recent) < self.p.jam_failures:
            return False
        xy = np.array(recent)
        return bool(np.all(np.hypot(*(xy - xy.mean(axis=0)).T) <= self.p.jam_radius))

    def _start_retrace(self, time: float, pose: np.ndarray) -> None:
        """Back out along the robot's own track, up to ``retrace_distance`` of it."""
        self._retrace_pending = False
        back = np.array([(x, y) for _, x, y in reversed(self._track)])
        # from where it was before it got wedged: past the track's wriggles in the jam
        away = np.flatnonzero(np.hypot(*(back - pose[:2]).T) > self.p.jam_radius)
        back = back[away[0]:] if len(away) else back[:0]
        steps = np.hypot(*np.diff(back, axis=0).T) if len(back) > 1 else np.zeros(0)
        s = np.r_[0.0, np.cumsum(steps)]
        back = back[:int(np.searchsorted(s, self.p.retrace_distance)) + 1]
        length = float(s[len(back) - 1]) if len(back) else 0.0
        if len(back) < 2 or length < 0.3:
            return
        length += float(np.hypot(*(back[0] - pose[:2])))
        self._retraces += 1
        self.result.retraces += 1
        self._leg = PurePursuit(np.vstack([pose[:2], back]),
                                replace(self._door_pursuit, turn_in_place=math.radians(100.0)))
        self.phase = "retrace"
        self._retrace_until = time + 4.0 * self.p.retrace_distance / self.p.door_speed
        self.result.log.append({"t": round(time, 1), "retrace": round(length, 2),
                                "at": [round(float(v), 2) for v in pose[:2]]})

    def _retrace(self, time: float, pose: np.ndarray, ranges: np.ndarray) -> tuple[float, float]:
        """Drive the track backwards (pursuit of it with the robot's rear as its front)."""
        assert self._leg is not None
        rear = np.array([pose[0], pose[1], pose[2] + math.pi])
        v, w, status = self._leg.step(rear, 0.0)
        v = -v
        if status == "arrived" or time > self._retrace_until \
                or self._blocked(ranges, v, w):
            self._leg = None
            self._failures = 0  # it got out (or as far as the track lets it)
            self._streak.clear()
            self.phase = "plan"
            return 0.0, 0.0
        return float(v), float(w)

    def _forget(self, goal: tuple[float, float]) -> None:
        self._forgotten.append(goal)

    def _abandon(self, phase: str) -> None:
        self._leg, self.target = None, None
        self._pending, self._squeeze = [], False
        if self.phase != "ended":
            self.phase = phase

    def _end(self, time: float, reason: str) -> None:
        self.phase = "ended"
        self._leg, self.target = None, None
        self._pending = []
        self.result.ended, self.result.end_reason = time, reason

    def summary(self, time: float) -> dict[str, Any]:
        """The result for run.json; an exploration still going ran out of time."""
        out = self.result.as_dict()
        if self.phase == "follow" and self.result.started is None:
            out["end_reason"] = "time budget (perimeter)"
        elif self.phase == "follow":  # handed back to the follower
            out["end_reason"], out["ended"] = "time budget", round(time, 2)
        elif self.active:
            out["end_reason"], out["ended"] = "time budget", round(time, 2)
        return out
