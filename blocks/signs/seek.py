"""Stop-and-zoom: the behaviour that turns sign detections into sharp captures.

The paper's textual sign detector "signals the steering and exploration engine
to stop the robot until the sign image is correctly zoomed and acquired".  A
plate first seen far ahead is at a grazing angle, where no reader can read
it, so the behaviour does not stop at once:

``explore``
    The camera looks ahead.  A plate within ``track_range`` that is not a
    sign already captured (or rejected) becomes the target once it has been
    seen on ``confirm_frames`` frames.
``track``
    The robot keeps exploring; the head pans and tilts to keep the target in
    view, and each new detection refines the target's estimated position and
    facing (in the odometry frame).  When the view is as good as it will get
    (the viewing angle is below ``good_view_deg``, or it has started to grow
    again as the robot passes), the behaviour stops the robot.
``stop``
    The robot halts; the head aims at the plate and zooms until it is
    ``target_height_px`` tall.  Once the head has settled and the robot stands
    still, a frame with the whole plate near the centre is captured.
``resume``
    The robot goes on and the head returns to look ahead.

Every wait has a way out, so the robot never stalls for good: a target lost
for ``lost_frames`` frames is dropped; a plate that the zoomed view does not
confirm is rejected as not a sign (and remembered, so it is not chased
again); and a stop is abandoned after ``stop_timeout`` seconds.

The machine is a plain class fed with numbers, detections and poses; it does
not know the dataflow engine.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np

from .geometry import camera_pose_of, estimate_plate, wrap
from .types import PLATE_HEIGHT, PLATE_WIDTH, CameraModel, PlateDetection

__all__ = ["Mode", "SeekParams", "SeekCommand", "SignSeeker", "Target"]


class Mode(str, Enum):
    EXPLORE = "explore"
    TRACK = "track"
    STOP = "stop"


@dataclass(frozen=True)
class SeekParams:
    """Tunables of the stop-and-zoom behaviour (SI units, angles in degrees).

    Attributes
    ----------
    track_range : float
        Plates farther than this (m) are ignored until the robot comes closer.
    confirm_frames : int
        Frames a plate must be seen on before it is tracked (one-off blobs are not).
    good_view_deg : float
        Stop once the camera sees the plate at most this far off its normal.
    worst_view_deg : float
        If the view stops improving, stop anyway when it is at most this oblique;
        beyond it the plate is given up as unreadable from this path.
    max_stop_range : float
        Stop only when the plate is at most this far (m).
    target_height_px : float
        Zoom until the plate is this tall in the image.
    max_fill : float
        ...but never wider than this share of the image.
    centre_tolerance : float
        A capture needs the plate's centre within this share of the image size
        from the image centre.
    settle_deg, settle_zoom : float
        The head has settled when it is this close to its command.
    still_speed : float
        The robot stands still below this speed (m/s).
    lost_frames : int
        Frames without the target before it is dropped (tracking) or
        rejected as not a sign (stopped).
    stop_timeout : float
        Longest stop (s); then the robot resumes whatever happened.
    track_timeout : float
        Longest chase (s) of one target.
    done_radius : float
        Plates within this distance (m) of a captured or rejected one are not chased again.
    gate : float
        A detection is the target if its estimated position is within this (m).
    scan_pan_deg, scan_tilt_deg : float
        Where the head looks while exploring.
    sweep_deg, sweep_period : float
        While exploring the head sweeps ``scan_pan_deg +- sweep_deg`` (a sine of
        this period, s), so plates beside the robot, out of a fixed forward
        view, are seen too.  0 keeps it still.
    pass_margin : float
        A plate less than this (m) ahead of where the robot would stop is being
        passed: stop now if the view is usable; one this far behind is given up.
    candidate_memory : float
        Plates seen while the behaviour is busy with another one are kept this
        long (s) and chased next.
    pan_limit_deg, tilt_min_deg, tilt_max_deg, zoom_max : float
        The head's limits.
    vfov_half_deg : float
        Half the vertical field of view at zoom 1.
    aspect : float
        The frame's width over its height.
    max_frame_share : float
        A plate whose box would cover more of the frame than this at zoom 1
        is too close to find (detectors take such blobs for walls): the robot
        stops before it gets there.
    fit_fraction : float
        A plate fits in view while its top edge is at most this share of the
        half field of view above the centre of the image at full tilt: the
        robot must stop before it is so close that the plate leaves the top.
    decel, latency : float
        The robot's braking (m/s^2) and the delay (s) before a stop acts: the
        behaviour judges the view from where the robot will come to rest.
    plate_sizes : str
        ``standard``: every plate is the paper's 0.6 x 0.2 m, and one image
        places it.  ``any``: a plate's size is unknown, so one image gives
        only the ray to it; the views from along the robot's way fix how far
        (see :class:`Target`).
    scale_prior : float
        With ``any``, how firmly (a share of one view's weight) the size is
        held to the standard until the views disagree with it.
    scale_min, scale_max : float
        The plate sizes (times the standard) a size estimate is kept within.
    cut_bearing_deg : float
        Stopped, a plate cut by the frame's edge within this bearing of the
        target is the target: the head aims at it and zooms out.
    revisit_view_deg : float
        A plate given up, or captured at a view more oblique than this, is
        *wanted*: a behaviour that can drive the robot may bring it in front
        of the plate and ask the seeker to look again (:meth:`SignSeeker.look_again`).
    """

    track_range: float = 5.0
    confirm_frames: int = 2
    good_view_deg: float = 40.0
    worst_view_deg: float = 70.0
    max_stop_range: float = 3.0
    target_height_px: float = 60.0
    max_fill: float = 0.8
    centre_tolerance: float = 0.25
    settle_deg: float = 1.5
    settle_zoom: float = 0.05
    still_speed: float = 0.02
    lost_frames: int = 5
    stop_timeout: float = 5.0
    track_timeout: float = 20.0
    done_radius: float = 1.2
    gate: float = 1.0
    scan_pan_deg: float = 0.0
    scan_tilt_deg: float = 12.0
    sweep_deg: float = 35.0
    sweep_period: float = 3.0
    candidate_memory: float = 6.0
    pass_margin: float = 0.3
    pan_limit_deg: float = 170.0
    tilt_min_deg: float = -30.0
    tilt_max_deg: float = 30.0
    zoom_max: float = 10.0
    vfov_half_deg: float = 18.5
    aspect: float = 4 / 3
    max_frame_share: float = 0.35
    fit_fraction: float = 0.7
    decel: float = 1.0
    latency: float = 0.2
    plate_sizes: str = "standard"
    scale_prior: float = 0.005
    scale_min: float = 0.3
    scale_max: float = 3.0
    cut_bearing_deg: float = 6.0
    revisit_view_deg: float = 55.0

    def __post_init__(self) -> None:
        if self.plate_sizes not in ("standard", "any"):
            raise ValueError(f"plate_sizes is 'standard' or 'any', not {self.plate_sizes!r}")


@dataclass(frozen=True)
class Observation:
    """One detection placed in the odometry frame, with how much to trust it.

    ``(x, y)`` and ``z`` are where a standard plate would be: the camera at
    ``camera`` plus ``offset``.  A plate ``k`` times the standard size is at
    the camera plus ``k * offset`` (and ``k * z`` above the camera): one image
    fixes the ray, not the distance along it.
    """

    x: float
    y: float
    facing: float
    z: float  # height of the plate's centre above the camera (m)
    w_pos: float  # 1 / variance of the position (1/m^2)
    w_facing: float  # 1 / variance of the facing (1/rad^2)
    camera: tuple[float, float] = (0.0, 0.0)
    offset: tuple[float, float] = (0.0, 0.0)


@dataclass
class Target:
    """The plate being chased: its estimate in the odometry frame, and its history.

    Why a size: a plate of unknown size is placed by one image only up to a
    scale along the ray to it (a small plate looks like a standard one
    farther off), and a seeker that takes every plate for a standard one
    stops a metre late or early, or gives up a plate it is passing at a good
    view because it believes it 3 m away.  The rays from two places on the
    robot's way cross at the plate, so with ``scale_prior`` finite the
    estimate is the least-squares plate ``P`` and size ``k`` of
    ``P = camera_i + k * offset_i`` over the views, each weighted by its
    ``w_pos``, with ``k`` held to 1 by ``scale_prior`` times the mean weight
    of a view's ``offset`` (the size is what the views do not settle).  With
    ``scale_prior`` infinite (standard plates) ``k`` is 1 and ``P`` the
    weighted mean of the views.
    """

    x: float
    y: float
    facing: float  # rad: the plate's outward normal
    weight: float  # sum of the position weights
    z: float = 0.6  # height of the plate's centre above the camera (m)
    seen: int = 1
    missed: int = 0
    since: float = 0.0  # time the chase began (s)
    last_seen: float = 0.0
    nx: float = 0.0  # running sum of facing unit vectors (weighted)
    ny: float = 0.0
    scale: float = 1.0  # the plate's size, times the standard plate's
    scale_prior: float = math.inf
    expected_scale: float = 1.0  # what the size is held to until the views settle it
    scale_range: tuple[float, float] = (0.3, 3.0)
    _normal: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)), repr=False)
    _rhs: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)
    _offsets: float = 0.0  # sum of w_pos * |offset|^2
    _z_std: float = 0.0  # sum of w_pos * z of a standard plate

    @classmethod
    def start(cls, obs: Observation, time: float, scale_prior: float = math.inf,
              scale_range: tuple[float, float] = (0.3, 3.0), scale: float = 1.0) -> "Target":
        """A target from its first view; with ``obs.w_pos`` 0, one known already, of size
        ``scale``, which the views to come are held to as they are to 1 otherwise."""
        t = cls(obs.x, obs.y, obs.facing, 0.0, z=obs.z, seen=0, since=time, last_seen=time,
                scale=scale, scale_prior=scale_prior, scale_range=scale_range,
                expected_scale=scale)
        if obs.w_pos > 0:
            t.absorb(obs)
        return t

    def absorb(self, obs: Observation) -> None:
        """Fold in another observation, each weighted by its inverse variance (facings as
        weighted unit vectors): a far, grazing view barely moves a good estimate."""
        w = obs.w_pos
        self.weight += w
        self.nx += obs.w_facing * math.cos(obs.facing)
        self.ny += obs.w_facing * math.sin(obs.facing)
        self.facing = math.atan2(self.ny, self.nx)
        self.seen += 1
        self.missed = 0
        # rows [1 0 -ox] and [0 1 -oy] of P - k * offset = camera
        ox, oy = obs.offset
        cx, cy = obs.camera
        self._normal += w * np.array([[1.0, 0.0, -ox], [0.0, 1.0, -oy],
                                      [-ox, -oy, ox * ox + oy * oy]])
        self._rhs += w * np.array([cx, cy, -(ox * cx + oy * cy)])
        self._offsets += w * (ox * ox + oy * oy)
        self._z_std += w * obs.z
        self._solve(obs)

    def distance_to(self, obs: Observation) -> float:
        """How far (m) ``obs`` is from this plate, taken at this plate's size."""
        return math.hypot(obs.camera[0] + self.scale * obs.offset[0] - self.x,
                          obs.camera[1] + self.scale * obs.offset[1] - self.y)

    def _solve(self, obs: Observation) -> None:
        if not math.isfinite(self.scale_prior):  # standard plates: the weighted mean
            before = self.weight - obs.w_pos
            self.x = (self.x * before + obs.x * obs.w_pos) / self.weight
            self.y = (self.y * before + obs.y * obs.w_pos) / self.weight
            self.z = (self.z * before + obs.z * obs.w_pos) / self.weight
            return
        prior = self.scale_prior * self._offsets / self.seen
        normal = self._normal + np.diag([0.0, 0.0, prior])
        rhs = self._rhs + np.array([0.0, 0.0, prior * self.expected_scale])
        try:
            px, py, k = np.linalg.solve(normal, rhs)
        except np.linalg.LinAlgError:
            return
        lo, hi = self.scale_range
        if not lo <= k <= hi:  # out of range: the nearest size kept, the plate on its rays
            k = min(max(k, lo), hi)
            px, py = (self._rhs[:2] + k * np.array([-self._normal[0, 2], -self._normal[1, 2]])) \
                / self.weight
        self.x, self.y, self.scale = float(px), float(py), float(k)
        self.z = k * self._z_std / self.weight


@dataclass(frozen=True)
class SeekCommand:
    """What the behaviour asks for on this tick."""

    stop: bool
    pan: float  # rad
    tilt: float  # rad
    zoom: float
    capture: PlateDetection | None = None  # set on the tick a capture is taken
    target: Target | None = None
    event: str = ""  # what happened on this tick, for the log ('' if nothing)


@dataclass
class _Stats:
    stops: int = 0
    captures: int = 0
    stopped_time: float = 0.0
    lost: int = 0
    rejected: int = 0
    timeouts: int = 0
    given_up: int = 0
    events: list[tuple[float, str]] = field(default_factory=list)


class SignSeeker:
    """The stop-and-zoom state machine (see the module docstring).

    Parameters
    ----------
    params : SeekParams
    mount : (x, y)
        The camera's pan axis on the robot (m).
    """

    def __init__(self, params: SeekParams | None = None, mount: tuple[float, float] = (0.0, 0.0)):
        self.p = params or SeekParams()
        self.mount = (float(mount[0]), float(mount[1]))
        self.reset()

    def reset(self) -> None:
        self.mode = Mode.EXPLORE
        self.target: Target | None = None
        self.candidates: list[Target] = []
        self.done: list[tuple[float, float]] = []  # captured or rejected plates (odometry frame)
        self.wanted: list[dict[str, float]] = []  # plates worth a better view
        self._looked: list[tuple[float, float]] = []  # plates looked at again
        self._keys = 0
        self.stats = _Stats()
        self._stop_since = 0.0
        self._cmd = self._scan(0.0)
        self._last_pose: np.ndarray | None = None
        self._last_time = 0.0
        self._speed = 0.0
        self._clipped: list[PlateDetection] = []

    # ---- helpers -----------------------------------------------------------------------
    def _scan(self, time: float | None = None) -> tuple[float, float, float]:
        """Where the head looks while exploring at ``time`` (the sweep's phase)."""
        pan = self.p.scan_pan_deg
        if time is not None and self.p.sweep_deg > 0 and self.p.sweep_period > 0:
            pan += self.p.sweep_deg * math.sin(2 * math.pi * time / self.p.sweep_period)
        return math.radians(pan), math.radians(self.p.scan_tilt_deg), 1.0

    def _note_candidates(self, time: float, placed: list, busy_with: Target | None) -> None:
        """Fold this frame's plates (other than the one being chased) into the candidates."""
        for det, obs in placed:
            if det.range > self.p.track_range or self._is_done(obs.x, obs.y):
                continue
            if busy_with is not None and busy_with.distance_to(obs) < self.p.gate:
                continue
            match = next((c for c in self.candidates if c.distance_to(obs) < self.p.gate), None)
            if match is None:
                self.candidates.append(self._new_target(obs, time))
            else:
                match.absorb(obs)
                match.last_seen = time
        self.candidates = [c for c in self.candidates
                           if time - c.last_seen <= self.p.candidate_memory
                           and not self._is_done(c.x, c.y)]

    def _world(self, det: PlateDetection, camera: CameraModel, pose: np.ndarray,
               pan: float) -> Observation | None:
        """A detection's plate in the odometry frame, with its uncertainty."""
        # a plate of unknown size: its facing from the two edges alone (the width fit
        # would bend it to the standard plate's proportions)
        width = PLATE_WIDTH if self.p.plate_sizes == "standard" else None
        est = estimate_plate(det.corners, camera, plate_width=width, clipped=det.clipped,
                             sigma_px=1.0)
        if est is None:
            return None
        z = est.x * (camera.cy - det.centre[1]) / camera.f
        camx, camy, camyaw = camera_pose_of(pose, self.mount[0], self.mount[1], pan)
        c, s = math.cos(camyaw), math.sin(camyaw)
        sig_xy = est.sigma_xy if math.isfinite(est.sigma_xy) else 0.1 * est.range
        sig_f = est.sigma_facing if math.isfinite(est.sigma_facing) else math.radians(30)
        ox, oy = c * est.x - s * est.y, s * est.x + c * est.y
        return Observation(camx + ox, camy + oy, wrap(camyaw + est.facing), z,
                           w_pos=1.0 / (sig_xy ** 2 + 0.02 ** 2),
                           w_facing=1.0 / (sig_f ** 2 + math.radians(2.0) ** 2),
                           camera=(camx, camy), offset=(ox, oy))

    def _new_target(self, obs: Observation, time: float, scale: float = 1.0) -> Target:
        prior = self.p.scale_prior if self.p.plate_sizes == "any" else math.inf
        return Target.start(obs, time, prior, (self.p.scale_min, self.p.scale_max), scale)

    @staticmethod
    def _described(t: Target) -> str:
        """The target's estimate, for the log."""
        return f"plate at ({t.x:.2f}, {t.y:.2f}) facing {math.degrees(t.facing):.0f} deg, " \
               f"size {t.scale:.2f}, {t.seen} views"

    def _want(self, t: Target, why: str) -> None:
        """Put ``t`` on the wanted list, unless it was looked at again already."""
        if any(math.hypot(t.x - x, t.y - y) < self.p.done_radius for x, y in self._looked):
            return
        self.wanted = [w for w in self.wanted
                       if math.hypot(w["x"] - t.x, w["y"] - t.y) >= self.p.done_radius]
        self._keys += 1
        self.wanted.append({"key": self._keys, "x": t.x, "y": t.y, "facing": t.facing,
                            "z": t.z, "scale": t.scale,
                            "top": t.z + t.scale * PLATE_HEIGHT / 2, "why": why})

    def look_again(self, key: int) -> bool:
        """Chase the wanted plate ``key`` afresh: the robot now stands in front of it.

        The plate is forgotten as done and becomes the next target as it was
        last estimated, so the head turns to it at once (a plate hung high
        above a robot standing close is out of the exploring head's view).
        Once per plate; False if ``key`` is not wanted.
        """
        plate = next((w for w in self.wanted if w["key"] == key), None)
        if plate is None:
            return False
        self.wanted.remove(plate)
        x, y = plate["x"], plate["y"]
        self._looked.append((x, y))
        self.done = [(dx, dy) for dx, dy in self.done
                     if math.hypot(x - dx, y - dy) >= self.p.done_radius]
        again = self._new_target(Observation(x, y, plate["facing"], plate["z"], 0.0, 0.0),
                                 self._last_time, scale=plate["scale"])
        again.seen = self.p.confirm_frames
        self.candidates.insert(0, again)
        return True

    def _is_done(self, x: float, y: float) -> bool:
        return any(math.hypot(x - dx, y - dy) < self.p.done_radius for dx, dy in self.done)

    def _view(self, target: Target, pose: np.ndarray, pan: float) -> tuple[float, float, float]:
        """Viewing angle (rad), distance (m) and head bearing (rad, robot frame) of the target."""
        camx, camy, _ = camera_pose_of(pose, self.mount[0], self.mount[1], pan)
        dx, dy = camx - target.x, camy - target.y
        dist = math.hypot(dx, dy)
        view = abs(wrap(math.atan2(dy, dx) - target.facing)) if dist > 1e-9 else 0.0
        # the optical centre sits on the pan axis, so this is also the pan that aims at it
        bearing = wrap(math.atan2(-dy, -dx) - pose[2])
        return view, dist, bearing

    @staticmethod
    def _ahead(pose: np.ndarray, distance: float) -> np.ndarray:
        """The pose ``distance`` further along the robot's heading."""
        return np.array([pose[0] + distance * math.cos(pose[2]),
                         pose[1] + distance * math.sin(pose[2]), pose[2]])

    def _fits(self, target: Target, pose: np.ndarray, pan: float) -> bool:
        """From ``pose``, does the whole plate stay in frame at full tilt?

        The plate's near edge is what leaves the top of the image first when
        the robot comes too close to a plate hung above the camera.
        """
        camx, camy, _ = camera_pose_of(pose, self.mount[0], self.mount[1], pan)
        tx, ty = -math.sin(target.facing), math.cos(target.facing)
        reach = self.p.fit_fraction * math.radians(self.p.vfov_half_deg)
        half_w, half_h = target.scale * PLATE_WIDTH / 2, target.scale * PLATE_HEIGHT / 2
        tops, bottoms, bearings = [], [], []
        for side in (-1.0, 1.0):
            ex = target.x + side * tx * half_w
            ey = target.y + side * ty * half_w
            d = max(math.hypot(ex - camx, ey - camy), 1e-6)
            tops.append(math.atan2(target.z + half_h, d))
            bottoms.append(math.atan2(target.z - half_h, d))
            bearings.append(math.atan2(ey - camy, ex - camx))
        # the whole plate (its near edge towers over its far one) fits in the frame, the
        # head can tilt far enough to frame it, and it is not so big a detector takes it
        # for a wall
        vfov = 2 * math.radians(self.p.vfov_half_deg)
        tall = max(tops) - min(bottoms)
        wide = abs(wrap(bearings[1] - bearings[0]))
        return (tall <= 2 * reach
                and tall * wide <= self.p.max_frame_share * vfov * vfov * self.p.aspect
                and max(tops) <= math.radians(self.p.tilt_max_deg) + reach
                and min(bottoms) >= math.radians(self.p.tilt_min_deg) - reach)

    def _aim(self, target: Target, pose: np.ndarray, pan: float, tilt: float, zoom: float,
             det: PlateDetection | None, camera: CameraModel | None) -> tuple[float, float, float]:
        """Head command that centres the target; with a detection, also the tilt and zoom."""
        _, dist, bearing = self._view(target, pose, pan)
        limit = math.radians(self.p.pan_limit_deg)
        new_pan = max(-limit, min(limit, bearing))
        new_tilt, new_zoom = self._cmd[1], self._cmd[2]
        if det is not None and camera is not None:
            u, v = det.centre
            new_tilt = math.atan((camera.cy - v) / camera.f)
        elif target.weight == 0:  # not seen since it was looked for again: where it was
            new_tilt = math.atan2(target.z, max(dist, 1e-6))
        new_tilt = max(math.radians(self.p.tilt_min_deg),
                       min(math.radians(self.p.tilt_max_deg), new_tilt))
        return new_pan, new_tilt, new_zoom

    def _zoom_for(self, det: PlateDetection, zoom: float, camera: CameraModel) -> float:
        """The zoom that makes the plate ``target_height_px`` tall, no more than keeps it
        whole and centred enough to capture.

        Zooming scales every offset from the image centre: a plate the head cannot
        centre (above its tilt limit, close to a high plate) leaves the frame, or the
        capture's centre tolerance, if zoomed as far as its size asks.
        """
        h, w = max(det.height_px, 1.0), max(det.width_px, 1.0)
        want = zoom * self.p.target_height_px / h
        want = min(want, zoom * self.p.max_fill * camera.width / w)
        corners = np.asarray(det.corners, dtype=np.float64)
        cy = (camera.height - 1) / 2
        reach_u = float(np.max(np.abs(corners[:, 0] - camera.cx)))
        reach_v = float(np.max(np.abs(corners[:, 1] - cy)))
        u, v = det.centre
        limits = [(reach_u, 0.95 * camera.cx), (reach_v, 0.95 * cy),
                  (abs(u - camera.cx), 0.8 * self.p.centre_tolerance * camera.width),
                  (abs(v - cy), 0.8 * self.p.centre_tolerance * camera.height)]
        for reach, room in limits:
            if reach > 1e-6:
                want = min(want, zoom * room / reach)
        return max(1.0, min(self.p.zoom_max, want))

    def _nearest(self, dets: list[tuple[PlateDetection, Observation]],
                 target: Target) -> tuple[PlateDetection, Observation] | None:
        best, best_d = None, self.p.gate
        for det, obs in dets:
            d = target.distance_to(obs)
            if d < best_d:
                best, best_d = (det, obs), d
        return best

    def _event(self, time: float, text: str) -> str:
        self.stats.events.append((round(time, 2), text))
        return text

    # ---- the machine -------------------------------------------------------------------
    def step(self, time: float, pose: np.ndarray, fresh: bool, detections: list[PlateDetection],
             camera: CameraModel | None, pan: float, tilt: float, zoom: float) -> SeekCommand:
        """Advance one tick.

        Parameters
        ----------
        time : float
            Run time (s).
        pose : (3,) array
            The robot's pose (odometry frame).
        fresh : bool
            True when ``detections`` come from a new camera frame.
        detections : list of PlateDetection
            Plates in the newest frame (best first).
        camera : CameraModel or None
            The newest frame's intrinsics.
        pan, tilt, zoom : float
            The head's current state (rad, rad, factor).
        """
        pose = np.asarray(pose, dtype=np.float64)[:3]
        dt = time - self._last_time
        if self._last_pose is not None and dt > 0:
            self._speed = float(np.hypot(*(pose[:2] - self._last_pose[:2]))) / dt
        self._last_pose, self._last_time = pose.copy(), time
        placed: list[tuple[PlateDetection, Observation]] = []
        self._clipped = [d for d in detections if d.clipped] if fresh else []
        if fresh and camera is not None:
            for det in detections:
                est = self._world(det, camera, pose, pan)
                if est is not None:
                    placed.append((det, est))
        if fresh:
            self._note_candidates(time, placed, self.target)
        if self.mode is Mode.STOP:
            self.stats.stopped_time += max(dt, 0.0)
            return self._step_stop(time, pose, fresh, placed, camera, pan, tilt, zoom)
        if self.mode is Mode.TRACK:
            return self._step_track(time, pose, fresh, placed, camera, pan, tilt, zoom)
        return self._step_explore(time, pose, fresh, placed, camera, pan)

    def _resume(self, time: float, why: str, remember: bool) -> SeekCommand:
        if remember and self.target is not None:
            self.done.append((self.target.x, self.target.y))
        self.mode, self.target = Mode.EXPLORE, None
        self._cmd = self._scan(time)
        return SeekCommand(False, *self._cmd, event=self._event(time, why))

    def _step_explore(self, time, pose, fresh, placed, camera, pan) -> SeekCommand:
        self._cmd = self._scan(time)
        ready = [c for c in self.candidates if c.seen >= self.p.confirm_frames]
        if not ready:
            return SeekCommand(False, *self._cmd)
        self.target = min(ready, key=lambda c: math.hypot(c.x - pose[0], c.y - pose[1]))
        self.candidates.remove(self.target)
        self.target.since = time
        self.target.missed = 0
        self.mode = Mode.TRACK
        event = self._event(time, f"track plate at ({self.target.x:.2f}, {self.target.y:.2f})")
        self._cmd = self._aim(self.target, pose, pan, self._cmd[1], 1.0, None, None)
        return SeekCommand(False, *self._cmd, target=self.target, event=event)

    def _follow(self, t: Target, fresh: bool, placed: list
                ) -> tuple[PlateDetection | None, bool]:
        """The target's detection in a fresh frame (folded into its estimate), and whether
        it has now been missing for ``lost_frames`` frames."""
        if not fresh:
            return None, False
        hit = self._nearest(placed, t)
        if hit is None:
            t.missed += 1
            return None, t.missed >= self.p.lost_frames
        det, obs = hit
        t.absorb(obs)  # resets the miss count
        return det, False

    def _step_track(self, time, pose, fresh, placed, camera, pan, tilt, zoom) -> SeekCommand:
        t = self.target
        assert t is not None
        det, gone = self._follow(t, fresh, placed)
        if gone:
            self.stats.lost += 1
            return self._resume(time, "target lost while tracking", remember=False)
        if time - t.since > self.p.track_timeout:
            self.stats.timeouts += 1
            return self._resume(time, "tracking timed out", remember=True)
        view, dist, _ = self._view(t, pose, pan)
        self._cmd = self._aim(t, pose, pan, tilt, zoom, det, camera)
        # judge the view from where the robot would come to rest: now, or a frame later
        brake = self._speed ** 2 / (2 * self.p.decel) + self._speed * self.p.latency
        rest_now = self._ahead(pose, brake)
        rest_later = self._ahead(pose, brake + self._speed * 0.2)
        view_now, dist_now, _ = self._view(t, rest_now, pan)
        # how far ahead of the robot's resting point the plate is, along its heading
        ahead = ((t.x - rest_now[0]) * math.cos(pose[2]) + (t.y - rest_now[1]) * math.sin(pose[2]))
        fits_now, fits_later = self._fits(t, rest_now, pan), self._fits(t, rest_later, pan)
        reason = ""
        if fits_now and dist_now <= self.p.max_stop_range:
            if view_now <= math.radians(self.p.good_view_deg):
                reason = "good view"
            elif not fits_later and view_now <= math.radians(self.p.worst_view_deg):
                reason = "closest view that keeps the plate in frame"
            elif ahead < self.p.pass_margin and view_now <= math.radians(self.p.worst_view_deg):
                reason = "passing the plate"
        if reason:
            self.mode = Mode.STOP
            self._stop_since = time
            t.missed = 0
            self.stats.stops += 1
            return SeekCommand(True, *self._cmd, target=t, event=self._event(
                time, f"stop ({reason}: {math.degrees(view_now):.0f} deg, {dist_now:.2f} m;"
                      f" {self._described(t)})"))
        if (not fits_now and dist_now < dist) or ahead < -self.p.pass_margin:
            self.stats.given_up += 1
            self._want(t, "given up")
            why = "too close to fit the frame" if not fits_now else "passed"
            return self._resume(time, f"plate given up without a readable view ({why}: "
                                      f"{math.degrees(view_now):.0f} deg, {dist_now:.2f} m; "
                                      f"{self._described(t)})", remember=True)
        return SeekCommand(False, *self._cmd, target=t)

    def _step_stop(self, time, pose, fresh, placed, camera, pan, tilt, zoom) -> SeekCommand:
        t = self.target
        assert t is not None
        if time - self._stop_since > self.p.stop_timeout:
            self.stats.timeouts += 1
            return self._resume(time, "stop timed out", remember=True)
        det, gone = self._follow(t, fresh, placed)
        cut = self._cut_off(t, pose, pan) if fresh and det is None else None
        if cut is not None and camera is not None:
            return self._back_out(t, cut, pan, tilt, zoom, camera)
        if gone:
            self.stats.rejected += 1
            return self._resume(time, "zoomed view shows no plate: not a sign", remember=True)
        if det is None:
            return SeekCommand(True, *self._cmd, target=t)
        assert camera is not None
        new_pan, new_tilt, _ = self._aim(t, pose, pan, tilt, zoom, det, camera)
        new_zoom = self._zoom_for(det, zoom, camera)
        settled = (abs(wrap(self._cmd[0] - pan)) <= math.radians(self.p.settle_deg)
                   and abs(self._cmd[1] - tilt) <= math.radians(self.p.settle_deg)
                   and abs(self._cmd[2] - zoom) <= self.p.settle_zoom)
        u, v = det.centre
        # a plate above (or below) the head's tilt range cannot be centred: whole will do
        tilt_stop = min(abs(tilt - math.radians(self.p.tilt_max_deg)),
                        abs(tilt - math.radians(self.p.tilt_min_deg))) <= math.radians(
                            self.p.settle_deg)
        centred = (abs(u - camera.cx) <= self.p.centre_tolerance * camera.width
                   and (tilt_stop or abs(v - (camera.height - 1) / 2)
                        <= self.p.centre_tolerance * camera.height))
        big_enough = det.height_px >= 0.7 * self.p.target_height_px or zoom >= self.p.zoom_max - 0.05
        if settled and self._speed <= self.p.still_speed and centred and not det.clipped and (
                big_enough or abs(new_zoom - zoom) <= self.p.settle_zoom):
            self.stats.captures += 1
            view, _, _ = self._view(t, pose, pan)
            event = self._event(time, f"capture at zoom {zoom:.1f} ({det.height_px:.0f} px tall,"
                                      f" {math.degrees(view):.0f} deg)")
            self.done.append((t.x, t.y))
            self.wanted = [w for w in self.wanted
                           if math.hypot(w["x"] - t.x, w["y"] - t.y) >= self.p.done_radius]
            if view > math.radians(self.p.revisit_view_deg):
                self._want(t, "grazing capture")
            self.mode, self.target = Mode.EXPLORE, None
            self._cmd = self._scan(time)
            return SeekCommand(False, *self._cmd, capture=det, target=t, event=event)
        self._cmd = (new_pan, new_tilt, new_zoom)
        return SeekCommand(True, *self._cmd, target=t)

    def _cut_off(self, t: Target, pose: np.ndarray, pan: float) -> PlateDetection | None:
        """The target cut by the frame's edge in this frame (it cannot be placed then), or None.

        Matched by bearing: close to a large or high plate the zoomed view, or
        even the whole one, can cut it, and a plate that is there is not a
        phantom to reject.
        """
        _, _, bearing = self._view(t, pose, pan)
        for det in self._clipped:
            if abs(wrap(pan + det.bearing - bearing)) <= math.radians(self.p.cut_bearing_deg):
                return det
        return None

    def _back_out(self, t: Target, det: PlateDetection, pan: float, tilt: float, zoom: float,
                  camera: CameraModel) -> SeekCommand:
        """Aim at the middle of a cut-off target and zoom out until it is whole."""
        t.missed = max(0, t.missed - 1)  # seen, only not whole
        corners = np.asarray(det.corners, dtype=np.float64)
        v_mid = 0.5 * (corners[:, 1].min() + corners[:, 1].max())
        tilt = tilt + math.atan((camera.cy - v_mid) / camera.f)
        tilt = max(math.radians(self.p.tilt_min_deg), min(math.radians(self.p.tilt_max_deg), tilt))
        self._cmd = (wrap(pan + det.bearing), tilt, max(1.0, zoom * 0.7))
        return SeekCommand(True, *self._cmd, target=t)

    def summary(self) -> dict[str, Any]:
        """Counts for run.json."""
        s = self.stats
        return {"stops": s.stops, "captures": s.captures, "stopped_time_s": round(s.stopped_time, 2),
                "lost": s.lost, "rejected_not_sign": s.rejected, "timeouts": s.timeouts,
                "given_up_grazing": s.given_up}
