"""Room visits: through the door a sign labels, a look around the room, and back.

Why: the perimeter follower keeps to the corridor, so the rooms it passes are
only glimpsed through their doors, and the place segmentation can recover no
more than the fan of each room the sonar saw.  The paper's robot knows a room
once it has read its sign; to *map* the room it has to go in.

A visit, once a sign has been read:

1. **Find the door** on a local map of the recent sonar scans (built by the
   caller in the odometry frame; over half a minute the drift is small).  A
   door is an opening in the sign's wall, within ``half_width`` of the sign,
   with mapped wall on both sides and floor seen behind it
   (:func:`~.doors.find_door`).  Until the robot has passed the door, one jamb is
   not mapped yet and the search is retried every ``retry_distance`` metres
   of travel, up to ``give_up_distance`` from the sign.  A door not found
   then is sought again, up to ``revisits`` times, whenever the robot
   passes within ``revisit_distance`` of the sign later: the explorer comes
   back along most corridors, and a door seen askew or half hidden on one
   pass is often seen square on the next.

   Why a door is missed: a sonar cone 30 degrees wide, passing a door 1.5 m
   off, hears the jambs across most of the opening and draws the wall
   unbroken; 0.8 m off, the cone is half as wide and the opening shows.
   So when a search fails while the robot is still within
   ``drive_by_distance`` of the sign, it **drives by** first: along
   the sign's wall ``drive_by_standoff`` off it, from ``half_width`` plus
   ``drive_by_margin`` on one side of the sign to as far on the other, its
   side sonars square on to the wall, and searches again.  Found, the visit
   goes on from there; not found, the robot goes back to where it was and
   the sign waits for a later pass like any other.

   Why not simply plan to the free space behind the wall: a sonar beam that
   meets a wall at a grazing angle is reflected away, and the echo it hears
   instead comes from farther off, so a sonar map shows free floor through
   walls it has not yet seen square on.  A planner happily drives into them.
   The opening between two mapped jambs is the one way in that is known.
2. **Enter** along the door's axis: A* to a point in front of the door,
   turn to face it and find it again (seen square on, it is drawn truer than
   in passing), then straight through its middle to a point inside, as deep
   as the floor seen through the door allows; **look around** 360 degrees.
3. **Look again**, up to ``looks`` times, from where the most of the room
   is still unseen, now that the looks so far have mapped it
   (:func:`~.doors.next_look`, a next-best-view rule).
4. **Come back**: to the door's axis, face the door and find it again on
   the last scans (odometry drifts during the looks), out through it, A* to
   where the visit began, and face the way the robot was going, so the
   behaviour it interrupted picks up where it left off.

:class:`RoomVisitor` is a plain state machine fed with poses; it gets its
maps from a callback, so it is tested without the dataflow engine.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .collision_monitor import EchoMemory
from .doors import DoorEstimate, SignRef, find_door, next_look
from .grid import NavGrid, inflate, unblock_traversed
from .legs import Leg, TurnWatch, dedupe, turn_rate
from .planner import PlanningError, plan
from .pursuit import PurePursuit, PursuitParams, wrap

__all__ = ["RoomVisitParams", "RoomVisitResult", "RoomVisitor"]


@dataclass(frozen=True)
class RoomVisitParams:
    """Tunables of :class:`RoomVisitor` (SI units).

    Attributes
    ----------
    half_width
        How far (m) along the wall from its sign a door may be.
    approach
        The way in starts this far (m) in front of the wall, on the door's axis.
    depth_min, depth_max
        How deep (m) behind the wall the robot looks around: at least
        ``depth_min`` (else the room is not entered), at most ``depth_max``.
    margin
        Free floor (m) kept between the look-around point and what the map
        shows beyond it (the robot turns in place there).
    looks
        At most this many looks around per room.
    look_again
        A further look must be at least this far (m) from the last one.
    min_gain
        ...and see at least this much unseen floor of the room (m^2); see
        :func:`~.doors.next_look`.
    room_half_width, room_depth
        The box (m) around the door's axis the looks stay in.
    retry_distance
        Metres of travel between two searches for a door not found yet.
    give_up_distance
        A door not found by the time the robot is this far from its sign is
        skipped (closed, or too narrow for the sonar to see through)...
    revisit_distance, revisits
        ...until the robot passes this close (m) to the sign again, when the
        search starts over; at most ``revisits`` times per sign.
    drive_by, drive_by_distance, drive_by_standoff, drive_by_margin
        Whether a search that fails within ``drive_by_distance`` (m) of the sign
        is followed by a close look: a drive along the sign's wall,
        ``drive_by_standoff`` (m) off it, ``half_width + drive_by_margin`` (m) either
        side of the sign.  Once per sign.
    window
        Seconds of scans before a visit that its maps include.
    lead
        The search for a door also includes the scans from this many seconds
        before its sign was read.
    radius
        Obstacle inflation for the A* legs (m); the way through the door is a
        straight line on its axis and needs none.
    leg_timeout, stall_time
        Seconds a leg may take, and may go without progress, before it is
        abandoned and the robot heads back.  A turn on the spot (the look
        round, facing the door, lining up at the end) that gets nowhere for
        ``stall_time`` is given up too (run.json ``turns_given_up``): the look
        counts as taken, the door is gone through as first found.
    held_time
        A leg whose command a collision monitor stops for this long (s) is
        abandoned too (:class:`~blocks.navigate.legs.Leg`); before the door,
        the visit ends ``failed``.  Infinite: no monitor.
    spin_rate
        Turn rate of the look-around (rad/s).
    heading_tolerance
        How close (rad) to a wanted heading a turn on the spot stops.
    refine_radius
        The door found again from in front of it replaces the first estimate
        when it is this close (m): the same opening, better seen.
    exit_window
        On the way out, the door is found again on the scans of the last
        this-many seconds, in the frame odometry has drifted to.
    """

    half_width: float = 2.2
    approach: float = 0.8
    depth_min: float = 1.0
    depth_max: float = 2.2
    margin: float = 0.6
    looks: int = 3
    look_again: float = 1.0
    min_gain: float = 1.5
    room_half_width: float = 3.2
    room_depth: float = 5.5
    retry_distance: float = 0.8
    give_up_distance: float = 5.0
    revisit_distance: float = 2.5
    revisits: int = 2
    drive_by: bool = True
    drive_by_distance: float = 3.0
    drive_by_standoff: float = 0.8
    drive_by_margin: float = 0.4
    window: float = 30.0
    lead: float = 15.0
    radius: float = 0.36
    leg_timeout: float = 60.0
    stall_time: float = 10.0
    held_time: float = math.inf
    spin_rate: float = 1.2
    heading_tolerance: float = 0.05
    refine_radius: float = 0.4
    exit_window: float = 20.0


@dataclass
class RoomVisitResult:
    """What became of one signed room."""

    sign: str
    status: str  # "visited", "not_found", "failed"
    started: float  # s
    finished: float
    looks: list[tuple[float, float]] = field(default_factory=list)  # where it looked around
    attempts: int = 0  # searches for the door
    door_width: float = 0.0  # on the map (m)
    reason: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {"sign": self.sign, "status": self.status, "started": round(self.started, 2),
                "finished": round(self.finished, 2),
                "duration": round(self.finished - self.started, 2),
                "looks": [[round(x, 2), round(y, 2)] for x, y in self.looks],
                "attempts": self.attempts, "door_width": round(self.door_width, 2),
                "reason": self.reason}


@dataclass
class _Pending:
    sign: SignRef
    attempts: int = 0
    last_try: tuple[float, float] | None = None
    first_seen: float = 0.0
    revisits: int = 0  # searches started over on a later pass
    scans_from: float = -math.inf  # a search's maps hold no older scans (a later pass's)
    driven_by: bool = False  # the door was looked for on a drive along its wall
    result: RoomVisitResult | None = None  # while the door is not found


#: A callback giving the local map (an OccupancyMap) of the scans since a time (s) taken
#: near a point (x, y), and the robot positions of those scans; None when there are too few.
MapSource = Callable[[float, "tuple[float, float]"], "tuple[Any, np.ndarray] | None"]


class RoomVisitor:
    """Visits the room behind each new sign, then hands control back.

    Feed it signs with :meth:`add_sign` and call :meth:`step` every tick: it
    returns ``None`` while no visit is under way (the caller's own behaviour
    drives), else the velocities ``(v, w)`` of the visit.

    Parameters
    ----------
    maps
        ``maps(since, near)`` gives the local map of the scans taken since
        time ``since`` near the point ``near`` (a sign, a door), and the
        (N, 2) positions they were taken from (the robot's frame: the poses
        it is fed), or None.
    params
        See :class:`RoomVisitParams`.
    pursuit
        Path-follower tuning for the legs.
    merge_radius
        A sign this close (m) to one already known is the same sign.
    same_text_radius
        ...and so is a sign with the same text this close (m).
    echoes
        The remembered echoes of a collision monitor downstream (fed by the
        caller, in the frame of the poses): a leg's command it would stop is
        replaced by a creep round what stops it (:meth:`~.legs.Leg.step`).
    """

    def __init__(self, maps: MapSource, params: RoomVisitParams | None = None,
                 pursuit: PursuitParams | None = None, merge_radius: float = 1.0,
                 same_text_radius: float = 5.0, echoes: EchoMemory | None = None) -> None:
        self.maps = maps
        self.echoes = echoes
        self.p = params or RoomVisitParams()
        self.pursuit = pursuit or PursuitParams()
        self.merge_radius = merge_radius
        self.same_text_radius = same_text_radius
        self.known: list[SignRef] = []
        self.pending: list[_Pending] = []
        self.dormant: list[_Pending] = []  # door not found: sought again on a later pass
        self.results: list[RoomVisitResult] = []
        self.phase = "idle"  # idle, drive_by, drive_back, enter, face, spin, deeper, return, align
        self.door: DoorEstimate | None = None
        self.grid: NavGrid | None = None  # the last grid planned on (pictures, tests)
        self._leg: Leg | None = None
        self._face_after = False  # at the end of this leg, face the door and find it again
        self._refined = 0  # door estimates refined from in front of the door
        self._facing_out = False
        self._sign: _Pending | None = None
        self._start_pose = np.zeros(3)
        self._started = 0.0
        self._depth = 0.0
        self._looks: list[tuple[float, float]] = []
        self._failure = ""
        self._spun = 0.0
        self._heading = 0.0
        self._turns = TurnWatch(stall_time=self.p.stall_time)  # turns that cannot be made
        self._scale = 1.0
        self._driving_by = False  # the door is sought from in front of the sign
        self._drive_by_far: tuple[np.ndarray, np.ndarray] | None = None  # middle, direction
        self.drive_bys = {"driven": 0, "found": 0, "time_s": 0.0}  # time of those found nothing

    # ---- feeding it ----------------------------------------------------------------------
    def add_sign(self, sign: SignRef, time: float = 0.0) -> bool:
        """Queue the room behind ``sign`` for a visit; False if the sign is already known."""
        # A plate read again is re-estimated, and odometry drifts in between: the same
        # text close by is the same sign too.
        if any(math.hypot(k.x - sign.x, k.y - sign.y)
               < (self.same_text_radius if k.text == sign.text else self.merge_radius)
               for k in self.known):
            return False
        self.known.append(sign)
        self.pending.append(_Pending(sign, first_seen=time))
        return True

    @property
    def visiting(self) -> bool:
        """Whether a visit holds control."""
        return self.phase != "idle"

    # ---- the machine -----------------------------------------------------------------------
    def step(self, time: float, pose: np.ndarray, hold: bool = False,
             scale: float = 1.0) -> tuple[float, float] | None:
        """This tick's velocities, or None when the caller's behaviour should drive.

        ``hold`` pauses a visit (e.g. while another behaviour stops the robot
        to read a sign) and defers starting one; ``scale`` is how much of the
        last tick's command a collision monitor let through.
        """
        pose = np.asarray(pose, dtype=np.float64)
        self._scale = scale
        if self.phase == "idle":
            if hold or not self._try_start(time, pose):
                return None
        if hold:
            if self._leg is not None:  # a pause is not a stall
                self._leg.progress_time = time
            return 0.0, 0.0
        if self.phase == "spin":
            return self._spin(time, pose)
        if self.phase == "face":
            return self._face(time, pose)
        if self.phase == "align":
            return self._align(time, pose)
        return self._follow(time, pose)

    def _grid(self, local_map: Any, positions: np.ndarray) -> NavGrid:
        # Where the robot has been, it fits: the way it came stays open.
        return unblock_traversed(inflate(local_map, radius=self.p.radius), positions)

    def _try_start(self, time: float, pose: np.ndarray) -> bool:
        """Start the visit of the first pending room whose door can be found now."""
        here = (float(pose[0]), float(pose[1]))
        self._revive(time, here)
        for item in list(self.pending):
            sign = item.sign
            if item.attempts and math.hypot(here[0] - sign.x, here[1] - sign.y) \
                    > self.p.give_up_distance:
                self.pending.remove(item)
                item.result = RoomVisitResult(
                    sign.text, "not_found", item.first_seen, time, attempts=item.attempts,
                    reason=f"no open door within {self.p.half_width:g} m of the sign mapped "
                           f"before the robot was {self.p.give_up_distance:g} m from it"
                           + (f" (passes: {item.revisits + 1})" if item.revisits else ""))
                self.results.append(item.result)
                self.dormant.append(item)
                continue
            if item.last_try is not None and math.hypot(
                    here[0] - item.last_try[0], here[1] - item.last_try[1]) < self.p.retry_distance:
                continue
            item.attempts += 1
            item.last_try = here
            built = self._search_map(item, time)
            if built is None:
                continue
            local_map, positions = built
            door = self._enterable_door(local_map, sign)
            if door is None:
                if self._may_drive_by(item, here) and self._start_drive_by(
                        time, pose, item, self._grid(local_map, positions)):
                    return True
                continue
            if self._go_to_door(time, pose, door, self._grid(local_map, positions)):
                self.pending.remove(item)
                self._sign, self._start_pose, self._started = item, pose.copy(), time
                return True
        return False

    def _enterable_door(self, local_map: Any, sign: SignRef) -> DoorEstimate | None:
        """The sign's door on ``local_map`` if floor deep enough to look round is seen behind it."""
        door = find_door(local_map, sign, half_width=self.p.half_width)
        if door is None or door.inside - self.p.margin < self.p.depth_min:
            return None
        return door

    def _search_map(self, item: _Pending, time: float) -> tuple[Any, np.ndarray] | None:
        """The local map to seek a sign's door on, and where its scans were taken.

        The scans since just before the sign was read: they saw its door, even if
        another visit came in between (on a later pass, that pass's only).
        """
        since = max(item.scans_from, min(time - self.p.window, item.first_seen - self.p.lead))
        return self.maps(since, (item.sign.x, item.sign.y))

    def _go_to_door(self, time: float, pose: np.ndarray, door: DoorEstimate,
                    grid: NavGrid) -> bool:
        """Start the way to ``door`` (in front of it, on its axis); False if none."""
        try:
            way = plan(grid, (float(pose[0]), float(pose[1])),
                       door.point(-self.p.approach)).points
        except PlanningError:
            return False
        self.grid, self.door = grid, door
        self._looks, self._failure = [], ""
        self._depth = min(self.p.depth_max, door.inside - self.p.margin)
        # A path that arrives on the door's axis at an angle cuts the corner and
        # meets the door askew, so the robot stops on the axis first (see _face).
        self._begin_leg("enter", way, time, face_after=True)
        return True

    # ---- the drive-by: a close look along the sign's wall ------------------------------------
    def _may_drive_by(self, item: _Pending, here: tuple[float, float]) -> bool:
        """Whether a failed search for this sign's door is followed by a drive-by now."""
        return self.p.drive_by and not item.driven_by and math.hypot(
            here[0] - item.sign.x, here[1] - item.sign.y) <= self.p.drive_by_distance

    def _start_drive_by(self, time: float, pose: np.ndarray, item: _Pending,
                        grid: NavGrid) -> bool:
        """Drive along the sign's wall, close, to look for its door; False if not now."""
        sign = item.sign
        here = (float(pose[0]), float(pose[1]))
        normal = np.array([math.cos(sign.facing), math.sin(sign.facing)])
        along = np.array([-normal[1], normal[0]])
        # the standoff asked for, else the nearest free one (a stray echo near the wall)
        spots = [np.array([sign.x, sign.y]) + d * normal
                 for d in self.p.drive_by_standoff + np.array([0.0, 0.2, -0.2, 0.4, 0.6])
                 if d > 0.3]
        middle = next((spot for spot in spots if grid.is_free(*spot)), None)
        if middle is None:
            return False  # no floor in front of the sign on the map yet
        # the near end first; the far one once there, on the map of what it saw meanwhile
        side = -1.0 if np.dot(np.asarray(here) - middle, along) < 0 else 1.0
        near = self._drive_by_end(grid, middle, side * along)
        try:
            way = plan(grid, here, (float(near[0]), float(near[1]))).points
        except PlanningError:
            return False
        item.driven_by = True
        self.pending.remove(item)
        self.drive_bys["driven"] += 1
        self._sign, self._start_pose, self._started = item, pose.copy(), time
        self._driving_by, self._looks, self._failure, self.grid = True, [], "", grid
        self._drive_by_far = (middle, -side * along)
        self._begin_leg("drive_by", way, time)
        return True

    def _drive_by_end(self, grid: NavGrid, middle: np.ndarray,
                      direction: np.ndarray) -> np.ndarray:
        """The farthest point up to ``half_width + drive_by_margin`` from ``middle`` along
        ``direction`` that a straight drive from ``middle`` reaches (a corridor may end
        before, or a desk stand in the way)."""
        reach = self.p.half_width + self.p.drive_by_margin
        for r in np.arange(reach, 0.0, -0.4):
            end = middle + r * direction
            if grid.segment_free(middle, end):
                return end
        return middle

    def _drive_along(self, time: float, pose: np.ndarray) -> None:
        """At the drive-by's near end: straight along the wall to its far end.

        The far end is found on the map of what the robot saw on its way to the
        near one, as far as a straight drive from the middle reaches; the near
        end lies on the same line, so the whole drive is along free floor.
        """
        assert self._drive_by_far is not None and self._sign is not None
        (middle, direction), self._drive_by_far = self._drive_by_far, None
        built = self._search_map(self._sign, time)
        if built is not None:
            self.grid = self._grid(*built)
        assert self.grid is not None
        end = self._drive_by_end(self.grid, middle, direction)
        self._begin_leg("drive_by", np.vstack([pose[:2], middle, end]), time)

    def _driven_by(self, time: float, pose: np.ndarray) -> None:
        """The close look is over: on into the room by the door it found, or back."""
        item = self._sign
        assert item is not None
        built = self._search_map(item, time)
        if built is not None:
            local_map, positions = built
            door = self._enterable_door(local_map, item.sign)
            if door is not None \
                    and self._go_to_door(time, pose, door, self._grid(local_map, positions)):
                self.drive_bys["found"] += 1
                self._driving_by = False
                return
        # not there (or shut): back to where the robot was; the sign waits for a later pass
        item.last_try = (float(pose[0]), float(pose[1]))
        self.pending.append(item)
        way = np.vstack([pose[:2], self._start_pose[:2]])
        if self.grid is not None:
            try:
                way = plan(self.grid, (float(pose[0]), float(pose[1])),
                           tuple(self._start_pose[:2])).points
            except PlanningError:
                pass
        self._begin_leg("drive_back", way, time)

    def _revive(self, time: float, here: tuple[float, float]) -> None:
        """Seek again the doors of signs passed closer than ``revisit_distance`` once more."""
        for item in list(self.dormant):
            if item.revisits >= self.p.revisits:
                self.dormant.remove(item)
                continue
            if math.hypot(here[0] - item.sign.x, here[1] - item.sign.y) \
                    > self.p.revisit_distance:
                continue
            self.dormant.remove(item)
            if item.result is not None:
                self.results.remove(item.result)
            item.revisits += 1
            item.last_try, item.result = None, None
            item.scans_from = time - self.p.window  # this pass: odometry drifted since the last
            self.pending.append(item)

    def _begin_leg(self, phase: str, path: np.ndarray, time: float,
                   face_after: bool = False) -> None:
        """Follow ``path``; with ``face_after``, face the door at its end (see :meth:`_face`)."""
        self.phase = phase
        self._leg = Leg(PurePursuit(dedupe(path), self.pursuit), time)
        self._face_after = face_after

    def _follow(self, time: float, pose: np.ndarray) -> tuple[float, float]:
        leg = self._leg
        assert leg is not None
        v, w, outcome = leg.step(time, pose, timeout=self.p.leg_timeout,
                                 stall_time=self.p.stall_time, scale=self._scale,
                                 held_time=self.p.held_time, echoes=self.echoes)
        if self.phase in ("drive_by", "drive_back") and outcome:
            if self.phase == "drive_back":
                self.phase = "align"
            elif outcome == "arrived" and self._drive_by_far is not None:
                self._drive_along(time, pose)
            else:  # at the far end, or stopped on the way (it may have seen the door)
                self._drive_by_far = None
                self._driven_by(time, pose)
            return 0.0, 0.0
        if outcome == "held":
            failure = f"{self.phase}: held by the collision monitor"
            if self.phase == "enter" and self._face_after and not self._looks:
                self._failure = failure  # not at the door yet: going on would touch it again
                self._end(time, "failed")
            else:
                self._leg_ended(time, pose, failure)
            return 0.0, 0.0
        if outcome == "arrived":
            if self._face_after:  # on the door's axis: face it, find it again, go through
                self._facing_out = self.phase == "return"
                self.phase = "face"
            else:
                self._leg_ended(time, pose, "")
            return 0.0, 0.0
        if outcome == "timeout":
            self._leg_ended(time, pose, f"{self.phase}: timeout after {self.p.leg_timeout:g} s")
            return 0.0, 0.0
        if outcome:
            self._leg_ended(time, pose, f"{self.phase}: {leg.why}")
            return 0.0, 0.0
        return v, w

    def _face(self, time: float, pose: np.ndarray) -> tuple[float, float]:
        """Turn to face the door from its axis, find it again, then go through it (in or out).

        Why: a door seen in passing, from the corridor, is drawn narrow and
        lopsided by the sonar cones; seen square on from close by, its jambs
        are where the front sonars say; on the way out, odometry has drifted.  The new estimate replaces the old
        one if it is the same opening (within ``refine_radius``) and no
        narrower (sonar only ever narrows a door, so the wider view is truer).
        """
        assert self.door is not None and self._sign is not None
        sign = 1.0 if self._facing_out else -1.0
        heading = math.atan2(sign * self.door.normal[1], sign * self.door.normal[0])
        turn = self._turn_to(heading, pose)
        if turn is not None and not self._turns.stalled(time, float(pose[2]), "face"):
            return 0.0, turn
        # On the way out only the last scans: odometry has drifted during the looks, and
        # the door must be found where it is in the frame the robot drives in now.
        since = time - self.p.exit_window if self._facing_out else self._started - self.p.window
        built = self.maps(since, (self._sign.sign.x, self._sign.sign.y))
        if built is not None:
            door = find_door(built[0], self._sign.sign, half_width=self.p.half_width)
            # Sonar only ever draws a door narrower than it is: the wider view is the truer.
            if door is not None and door.width >= self.door.width - 0.05 and math.hypot(
                    door.wall[0] - self.door.wall[0], door.wall[1] - self.door.wall[1]) \
                    <= self.p.refine_radius:
                self.door = door
                self._refined += 1
        if self._facing_out:
            self._begin_leg("return", np.vstack([pose[:2], self.door.point(0.0),
                                                 self._way_back()]), time)
        else:
            self._begin_leg("enter", np.vstack([pose[:2], self.door.point(0.0),
                                                self.door.point(self._depth)]), time)
        return 0.0, 0.0

    def _leg_ended(self, time: float, pose: np.ndarray, failure: str) -> None:
        """Arrived at the end of a leg (or gave it up): on to the next phase."""
        if failure and not self._failure:
            self._failure = failure
        if self.phase in ("enter", "deeper") and not failure:
            self.phase, self._spun, self._heading = "spin", 0.0, float(pose[2])
            return
        if self.phase == "return":
            if failure:
                self._end(time, "failed")
            else:
                self.phase = "align"
            return
        self._head_back(time, pose)

    def _spin(self, time: float, pose: np.ndarray) -> tuple[float, float]:
        """Turn 360 degrees on the spot (measured, not timed)."""
        self._spun += abs(wrap(float(pose[2]) - self._heading))
        self._heading = float(pose[2])
        remaining = 2 * math.pi - self._spun
        if remaining > 0.02 and not self._turns.stalled(time, float(pose[2]), "spin"):
            return 0.0, min(self.p.spin_rate, max(0.2, 1.5 * remaining))
        self._looks.append((float(pose[0]), float(pose[1])))
        if self._look_again(time, pose):
            return 0.0, 0.0
        self._head_back(time, pose)
        return 0.0, 0.0

    def _look_again(self, time: float, pose: np.ndarray) -> bool:
        """After a look the room is better mapped: go where the next look sees the most."""
        if len(self._looks) >= self.p.looks:
            return False
        if self.door is None:
            return False
        built = self.maps(self._started - self.p.window, self.door.wall)
        if built is None:
            return False
        local_map, positions = built
        self.grid = self._grid(local_map, positions)
        here = (float(pose[0]), float(pose[1]))
        target = next_look(self.grid, local_map.classes()[2], self.door, here,
                           min_distance=self.p.look_again, half_width=self.p.room_half_width,
                           depth_max=self.p.room_depth, min_gain=self.p.min_gain)
        if target is None:
            return False
        try:
            way = plan(self.grid, here, target).points
        except PlanningError:
            return False
        self._begin_leg("deeper", way, time)
        return True

    def _head_back(self, time: float, pose: np.ndarray) -> None:
        """The way back: to the door's axis, face the door, out, A* to where the visit began."""
        assert self.door is not None
        here = np.asarray(pose[:2], dtype=np.float64)
        on_axis = np.array(self.door.point(min(self._depth, self.p.depth_min)))
        inside = [here, on_axis]
        if self.grid is not None and np.hypot(*(here - on_axis)) > 0.3:
            try:
                inside = list(plan(self.grid, here, on_axis).points)
            except PlanningError:
                pass
        # The rest is planned in _face once the door is found again from inside.
        self._begin_leg("return", np.vstack(inside), time, face_after=True)

    def _way_back(self) -> np.ndarray:
        """From in front of the door to where the visit began (A* in the corridor)."""
        assert self.door is not None
        approach = np.array(self.door.point(-self.p.approach))
        start = self._start_pose[:2]
        if self.grid is not None:
            try:
                return plan(self.grid, approach, start).points
            except PlanningError:
                pass
        return np.vstack([approach, start])  # the corridor the robot just drove along

    def _align(self, time: float, pose: np.ndarray) -> tuple[float, float]:
        """Turn on the spot to the heading the visit began with."""
        turn = self._turn_to(float(self._start_pose[2]), pose)
        if turn is None or self._turns.stalled(time, float(pose[2]), "align"):
            if self._driving_by:  # no visit: the behaviour it interrupted goes on
                self._driving_by = False
                self.drive_bys["time_s"] += time - self._started
                self.phase, self._leg, self._sign = "idle", None, None
            else:
                self._end(time, "failed" if self._failure else "visited")
            return 0.0, 0.0
        return 0.0, turn

    def _turn_to(self, heading: float, pose: np.ndarray) -> float | None:
        """Turn rate toward ``heading`` (slowing near it), or None once within tolerance."""
        return turn_rate(heading, float(pose[2]), self.p.spin_rate, self.p.heading_tolerance)

    def _end(self, time: float, status: str) -> None:
        assert self._sign is not None
        self.results.append(RoomVisitResult(
            self._sign.sign.text, status, self._started, time, list(self._looks),
            self._sign.attempts, self.door.width if self.door else 0.0, self._failure))
        self.phase, self._leg, self._sign = "idle", None, None

    def summary(self) -> dict[str, Any]:
        """Counts and each room's result, for run.json."""
        by = {s: sum(r.status == s for r in self.results) for s in ("visited", "not_found",
                                                                      "failed")}
        return {**by, "pending": len(self.pending), "doors_refined": self._refined,
                "turns_given_up": self._turns.given_up,
                "doors_driven_by": self.drive_bys["driven"],
                "doors_found_driving_by": self.drive_bys["found"],
                "drive_by_time_s": round(self.drive_bys["time_s"], 1),
                "time_s": round(sum(r.finished - r.started for r in self.results
                                    if r.status != "not_found"), 1),
                "rooms": [r.as_dict() for r in self.results]}
