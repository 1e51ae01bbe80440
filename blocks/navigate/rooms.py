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
   (:func:`find_door`).  Until the robot has passed the door, one jamb is
   not mapped yet and the search is retried every ``retry_distance`` metres
   of travel, up to ``give_up_distance`` from the sign.

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
   (:func:`next_look`, a next-best-view rule).
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
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .grid import NavGrid, inflate, unblock_traversed
from .legs import Leg, dedupe, turn_rate
from .planner import PlanningError, plan
from .pursuit import PurePursuit, PursuitParams, wrap

__all__ = ["DoorEstimate", "RoomVisitParams", "RoomVisitResult", "RoomVisitor", "SignRef",
           "find_door", "free_run", "next_look", "room_box",
           "unseen_nearby"]


@dataclass(frozen=True)
class SignRef:
    """A sign read on a door: its text, position (m) and facing (rad, the way it looks)."""

    text: str
    x: float
    y: float
    facing: float

    @classmethod
    def from_dict(cls, sign: dict[str, Any]) -> SignRef:
        """From a ``signs.correlate`` entry (``facing`` in degrees)."""
        return cls(str(sign["text"]), float(sign["x"]), float(sign["y"]),
                   math.radians(float(sign["facing"])))


@dataclass(frozen=True)
class DoorEstimate:
    """An opening in a wall, as the map shows it.

    Attributes
    ----------
    wall
        (x, y) of the wall's corridor-side surface at the middle of the opening.
    normal
        Unit vector out of the room (the sign's facing).
    width
        Width of the opening on the map (m); sonar draws jambs thick, so
        it is narrower than the true door.
    inside
        Free floor (m) seen straight in from the wall surface.
    """

    wall: tuple[float, float]
    normal: tuple[float, float]
    width: float
    inside: float

    def point(self, depth: float) -> tuple[float, float]:
        """The point ``depth`` metres into the room along the door's axis (negative: out)."""
        return (self.wall[0] - depth * self.normal[0], self.wall[1] - depth * self.normal[1])


def _classes_at(occupancy_map: Any, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(occupied, free) at world points (..., 2); points off the map are neither.

    The map's classes (:meth:`~blocks.maps.mapio.OccupancyMap.classes`) of the
    cells sampled only, not of the whole grid: a door search samples a few
    thousand of its hundreds of thousands of cells.
    """
    res, (ox, oy) = occupancy_map.resolution, occupancy_map.origin[:2]
    rows = np.floor((xy[..., 1] - oy) / res).astype(np.int64)
    cols = np.floor((xy[..., 0] - ox) / res).astype(np.int64)
    h, w = occupancy_map.shape
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    r, c = np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)
    sampled = replace(occupancy_map, occupancy=np.asarray(occupancy_map.occupancy)[r, c])
    occupied, free, _ = sampled.classes()
    return occupied & inside, free & inside


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs of a 1-D mask."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def free_run(occupancy_map: Any, start: tuple[float, float], direction: tuple[float, float],
             *, max_distance: float, step: float | None = None) -> float:
    """How far (m) the map is free from ``start`` along ``direction`` (up to ``max_distance``)."""
    step = step or occupancy_map.resolution / 2
    s = np.arange(0.0, max_distance + step, step)
    xy = np.asarray(start)[None, :] + s[:, None] * np.asarray(direction)[None, :]
    _, free = _classes_at(occupancy_map, xy)
    blocked = np.flatnonzero(~free)
    return float(max_distance if blocked.size == 0 else s[blocked[0]])


def room_box(shape: tuple[int, int], resolution: float, origin: tuple[float, ...],
             door: DoorEstimate, *, half_width: float, depth: float) -> np.ndarray:
    """(H, W) bool: the cells behind the door's wall, up to ``depth`` deep and
    ``half_width`` to either side of the door: where its room can be."""
    h, w = shape
    xs = origin[0] + (np.arange(w) + 0.5) * resolution
    ys = origin[1] + (np.arange(h) + 0.5) * resolution
    dx, dy = xs[None, :] - door.wall[0], ys[:, None] - door.wall[1]
    nx, ny = door.normal
    behind = -(dx * nx + dy * ny)
    lateral = dx * -ny + dy * nx
    return (behind >= 0.0) & (behind <= depth) & (np.abs(lateral) <= half_width)


def unseen_nearby(unknown: np.ndarray, resolution: float, radius: float,
                  block: float = 0.1) -> np.ndarray:
    """(H, W) float: area (m^2) of ``unknown`` cells within ``radius`` of each cell.

    Computed on ``block``-metre cells (a box filter on a disk), so it is cheap
    enough to run after every look.
    """
    import cv2
    f = max(1, int(round(block / resolution)))
    h, w = unknown.shape
    hp, wp = -(-h // f) * f, -(-w // f) * f
    padded = np.zeros((hp, wp), dtype=np.float32)
    padded[:h, :w] = unknown
    coarse = padded.reshape(hp // f, f, wp // f, f).sum(axis=(1, 3)) * resolution ** 2
    k = int(math.ceil(radius / (f * resolution)))
    yy, xx = np.mgrid[-k:k + 1, -k:k + 1]
    disk = ((xx * xx + yy * yy) <= k * k).astype(np.float32)
    area = cv2.filter2D(coarse, -1, disk, borderType=cv2.BORDER_CONSTANT)
    return np.repeat(np.repeat(area, f, axis=0), f, axis=1)[:h, :w]


def next_look(grid: NavGrid, unknown: np.ndarray, door: DoorEstimate,
              here: tuple[float, float], *, min_distance: float = 1.0,
              half_width: float = 3.2, depth_max: float = 5.5, min_clearance: float = 0.5,
              sensing: float = 3.0, min_gain: float = 1.5) -> tuple[float, float] | None:
    """Where to look around next in a room: the reachable spot that sees the most unseen floor.

    A next-best-view rule: candidates are the cells the robot can reach from
    ``here`` inside the room's box (see :func:`room_box`) with
    ``min_clearance`` around them (it turns in place there) and at least
    ``min_distance`` away; each is worth the unknown area of the box within
    ``sensing`` metres (the sonar's useful range).  Occlusion is ignored.

    Parameters
    ----------
    unknown
        (H, W) bool, the local map's unknown cells, on ``grid``'s cells.
    min_gain
        Below this much unseen area (m^2) a look is not worth it.

    Returns
    -------
    (x, y) or None
    """
    row, col = grid.world_to_cell(*here)
    if not grid.inside(row, col) or grid.blocked[row, col]:
        snapped = grid.nearest_free(row, col, 0.6)
        if snapped is None:
            return None
        row, col = snapped
    box = room_box(grid.shape, grid.resolution, grid.origin, door, half_width=half_width,
                   depth=depth_max)
    gain = unseen_nearby(unknown & box, grid.resolution, sensing)
    rows, cols = np.nonzero((grid.labels == grid.labels[row, col]) & box
                            & (grid.clearance >= min_clearance))
    if rows.size == 0:
        return None
    xy = grid.cell_to_world(rows, cols)
    distance = np.hypot(xy[:, 0] - here[0], xy[:, 1] - here[1])
    worth = gain[rows, cols]
    ok = (distance >= min_distance) & (worth >= min_gain)
    if not ok.any():
        return None
    # Gain in 0.25 m^2 steps, so near-equal gains tie and the more open cell wins.
    best = np.lexsort((-grid.clearance[rows[ok], cols[ok]], -np.round(worth[ok] / 0.25)))[0]
    return float(xy[ok][best, 0]), float(xy[ok][best, 1])


def find_door(occupancy_map: Any, sign: SignRef, *, half_width: float = 2.2,
              search: float = 3.5, wall_search: float = 0.6, wall_depth: float = 0.25,
              min_width: float = 0.25, max_width: float = 2.0, jamb: float = 0.2,
              seen_behind: float = 0.5) -> DoorEstimate | None:
    """The opening in the sign's wall nearest to the sign, or None.

    Parameters
    ----------
    occupancy_map
        The local map (an :class:`~blocks.maps.mapio.OccupancyMap`).
    sign
        The sign; its wall runs across its facing, the room is behind it.
    half_width
        The opening's middle must be within this distance (m) of the sign
        along the wall (a sign hangs next to its door).
    search
        Length (m) of wall examined on each side of the sign.
    wall_search
        The sign's position is an estimate: the wall's surface is sought
        within this distance (m) in front of and behind it.
    wall_depth
        Thickness (m) of the band behind the surface that counts as the wall.
    min_width, max_width
        Openings narrower than ``min_width`` on the map are gaps between
        readings, wider than ``max_width`` are not doors (m).
    jamb
        Each end of the opening must have mapped wall within this distance (m):
        an opening whose far side was not seen yet is not trusted.
    seen_behind
        Depth (m) behind the wall that must be seen free across most of the
        opening (the robot has looked through it).

    Returns
    -------
    DoorEstimate or None
    """
    res = occupancy_map.resolution
    normal = np.array([math.cos(sign.facing), math.sin(sign.facing)])
    along = np.array([-normal[1], normal[0]])
    u = np.arange(-search, search + res / 2, res / 2)
    d = np.arange(-wall_search, wall_search + wall_depth + seen_behind + res, res / 2)
    # Points at lateral u, depth d behind the sign's position: (len(d), len(u), 2).
    xy = (np.array([sign.x, sign.y])[None, None, :] + u[None, :, None] * along[None, None, :]
          - d[:, None, None] * normal[None, None, :])
    occupied, free = _classes_at(occupancy_map, xy)
    # The wall's surface: the depth whose line holds the most occupied cells.
    surface_rows = np.flatnonzero(np.abs(d) <= wall_search)
    counts = occupied[surface_rows].sum(axis=1)
    if counts.max() * res / 2 < 1.0:  # less than a metre of wall seen
        return None
    k0 = int(surface_rows[int(np.argmax(counts))])
    d0 = float(d[k0])
    band = (d >= d0 - res) & (d <= d0 + wall_depth)
    wall = occupied[band].any(axis=0)
    behind = (d > d0 + wall_depth) & (d <= d0 + wall_depth + seen_behind)
    seen = free[behind].mean(axis=0) >= 0.5
    best: DoorEstimate | None = None
    for a, b in _runs(~wall):
        width = (b - a) * res / 2
        if not (min_width <= width <= max_width):
            continue
        reach = int(round(jamb / (res / 2)))
        left_ok = a > 0 and wall[max(0, a - reach):a].any()
        right_ok = b < len(u) and wall[b:b + reach].any()
        if not (left_ok and right_ok) or seen[a:b].mean() < 0.6:
            continue
        centre = 0.5 * (u[a] + u[b - 1])
        if abs(centre) > half_width:
            continue
        surface = np.array([sign.x, sign.y]) + centre * along - d0 * normal
        inside = free_run(occupancy_map, tuple(surface - (wall_depth + res) * normal),
                          tuple(-normal), max_distance=6.0) + wall_depth + res
        door = DoorEstimate((float(surface[0]), float(surface[1])),
                            (float(normal[0]), float(normal[1])), float(width), float(inside))
        if best is None or abs(centre) < abs(_lateral(best, sign)):
            best = door
    return best


def _lateral(door: DoorEstimate, sign: SignRef) -> float:
    along = (-math.sin(sign.facing), math.cos(sign.facing))
    return (door.wall[0] - sign.x) * along[0] + (door.wall[1] - sign.y) * along[1]


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
        :func:`next_look`.
    room_half_width, room_depth
        The box (m) around the door's axis the looks stay in.
    retry_distance
        Metres of travel between two searches for a door not found yet.
    give_up_distance
        A door not found by the time the robot is this far from its sign is
        skipped (closed, or too narrow for the sonar to see through).
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
        abandoned and the robot heads back.
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
    """

    def __init__(self, maps: MapSource, params: RoomVisitParams | None = None,
                 pursuit: PursuitParams | None = None, merge_radius: float = 1.0,
                 same_text_radius: float = 5.0) -> None:
        self.maps = maps
        self.p = params or RoomVisitParams()
        self.pursuit = pursuit or PursuitParams()
        self.merge_radius = merge_radius
        self.same_text_radius = same_text_radius
        self.known: list[SignRef] = []
        self.pending: list[_Pending] = []
        self.results: list[RoomVisitResult] = []
        self.phase = "idle"  # idle, enter, face, spin, deeper, return, align
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
        self._scale = 1.0

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
        for item in list(self.pending):
            sign = item.sign
            if item.attempts and math.hypot(here[0] - sign.x, here[1] - sign.y) \
                    > self.p.give_up_distance:
                self.pending.remove(item)
                self.results.append(RoomVisitResult(
                    sign.text, "not_found", item.first_seen, time, attempts=item.attempts,
                    reason=f"no open door within {self.p.half_width:g} m of the sign mapped "
                           f"before the robot was {self.p.give_up_distance:g} m from it"))
                continue
            if item.last_try is not None and math.hypot(
                    here[0] - item.last_try[0], here[1] - item.last_try[1]) < self.p.retry_distance:
                continue
            item.attempts += 1
            item.last_try = here
            # The scans since just before the sign was read: they saw its door, even
            # if another visit came in between.
            built = self.maps(min(time - self.p.window, item.first_seen - self.p.lead),
                              (sign.x, sign.y))
            if built is None:
                continue
            local_map, positions = built
            door = find_door(local_map, sign, half_width=self.p.half_width)
            if door is None or door.inside - self.p.margin < self.p.depth_min:
                continue
            grid = self._grid(local_map, positions)
            approach = door.point(-self.p.approach)
            try:
                way = plan(grid, here, approach).points
            except PlanningError:
                continue
            self.pending.remove(item)
            self.grid, self.door = grid, door
            self._sign, self._start_pose, self._started = item, pose.copy(), time
            self._looks, self._failure = [], ""
            self._depth = min(self.p.depth_max, door.inside - self.p.margin)
            # A path that arrives on the door's axis at an angle cuts the corner and
            # meets the door askew, so the robot stops on the axis first (see _face).
            self._begin_leg("enter", way, time, face_after=True)
            return True
        return False

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
                                 held_time=self.p.held_time)
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
            self._leg_ended(time, pose, f"{self.phase}: no progress for {self.p.stall_time:g} s")
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
        if turn is not None:
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
        if remaining > 0.02:
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
        if turn is None:
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
                "time_s": round(sum(r.finished - r.started for r in self.results
                                    if r.status != "not_found"), 1),
                "rooms": [r.as_dict() for r in self.results]}
