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
from .types import CameraModel, PlateDetection

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
    fit_fraction : float
        A plate fits in view while its top edge is at most this share of the
        half field of view above the centre of the image at full tilt: the
        robot must stop before it is so close that the plate leaves the top.
    decel, latency : float
        The robot's braking (m/s^2) and the delay (s) before a stop acts: the
        behaviour judges the view from where the robot will come to rest.
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
    fit_fraction: float = 0.7
    decel: float = 1.0
    latency: float = 0.2


@dataclass(frozen=True)
class Observation:
    """One detection placed in the odometry frame, with how much to trust it."""

    x: float
    y: float
    facing: float
    z: float  # height of the plate's centre above the camera (m)
    w_pos: float  # 1 / variance of the position (1/m^2)
    w_facing: float  # 1 / variance of the facing (1/rad^2)


@dataclass
class Target:
    """The plate being chased: its estimate in the odometry frame, and its history."""

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

    @classmethod
    def start(cls, obs: Observation, time: float) -> "Target":
        return cls(obs.x, obs.y, obs.facing, obs.w_pos, z=obs.z, since=time, last_seen=time,
                   nx=obs.w_facing * math.cos(obs.facing), ny=obs.w_facing * math.sin(obs.facing))

    def absorb(self, obs: Observation) -> None:
        """Fold in another observation, each weighted by its inverse variance (facings as
        weighted unit vectors): a far, grazing view barely moves a good estimate."""
        total = self.weight + obs.w_pos
        self.x = (self.x * self.weight + obs.x * obs.w_pos) / total
        self.y = (self.y * self.weight + obs.y * obs.w_pos) / total
        self.z = (self.z * self.weight + obs.z * obs.w_pos) / total
        self.nx += obs.w_facing * math.cos(obs.facing)
        self.ny += obs.w_facing * math.sin(obs.facing)
        self.facing = math.atan2(self.ny, self.nx)
        self.weight = total
        self.seen += 1
        self.missed = 0


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
        self.stats = _Stats()
        self._stop_since = 0.0
        self._cmd = self._scan(0.0)
        self._last_pose: np.ndarray | None = None
        self._last_time = 0.0
        self._speed = 0.0

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
            if busy_with is not None and math.hypot(busy_with.x - obs.x,
                                                    busy_with.y - obs.y) < self.p.gate:
                continue
            match = next((c for c in self.candidates
                          if math.hypot(c.x - obs.x, c.y - obs.y) < self.p.gate), None)
            if match is None:
                self.candidates.append(Target.start(obs, time))
            else:
                match.absorb(obs)
                match.last_seen = time
        self.candidates = [c for c in self.candidates
                           if time - c.last_seen <= self.p.candidate_memory
                           and not self._is_done(c.x, c.y)]

    def _world(self, det: PlateDetection, camera: CameraModel, pose: np.ndarray,
               pan: float) -> Observation | None:
        """A detection's plate in the odometry frame, with its uncertainty."""
        est = estimate_plate(det.corners, camera, clipped=det.clipped, sigma_px=1.0)
        if est is None:
            return None
        z = est.x * (camera.cy - det.centre[1]) / camera.f
        camx, camy, camyaw = camera_pose_of(pose, self.mount[0], self.mount[1], pan)
        c, s = math.cos(camyaw), math.sin(camyaw)
        sig_xy = est.sigma_xy if math.isfinite(est.sigma_xy) else 0.1 * est.range
        sig_f = est.sigma_facing if math.isfinite(est.sigma_facing) else math.radians(30)
        return Observation(camx + c * est.x - s * est.y, camy + s * est.x + c * est.y,
                           wrap(camyaw + est.facing), z,
                           w_pos=1.0 / (sig_xy ** 2 + 0.02 ** 2),
                           w_facing=1.0 / (sig_f ** 2 + math.radians(2.0) ** 2))

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
        from .types import PLATE_HEIGHT, PLATE_WIDTH
        camx, camy, _ = camera_pose_of(pose, self.mount[0], self.mount[1], pan)
        tx, ty = -math.sin(target.facing), math.cos(target.facing)
        reach = self.p.fit_fraction * math.radians(self.p.vfov_half_deg)
        for side in (-1.0, 1.0):
            ex = target.x + side * tx * PLATE_WIDTH / 2
            ey = target.y + side * ty * PLATE_WIDTH / 2
            d = max(math.hypot(ex - camx, ey - camy), 1e-6)
            if (math.atan2(target.z + PLATE_HEIGHT / 2, d) > math.radians(self.p.tilt_max_deg) + reach
                    or math.atan2(target.z - PLATE_HEIGHT / 2, d)
                    < math.radians(self.p.tilt_min_deg) - reach):
                return False
        return True

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
            new_tilt = max(math.radians(self.p.tilt_min_deg),
                           min(math.radians(self.p.tilt_max_deg), new_tilt))
        return new_pan, new_tilt, new_zoom

    def _zoom_for(self, det: PlateDetection, zoom: float, camera: CameraModel) -> float:
        h, w = max(det.height_px, 1.0), max(det.width_px, 1.0)
        want = zoom * self.p.target_height_px / h
        want = min(want, zoom * self.p.max_fill * camera.width / w)
        return max(1.0, min(self.p.zoom_max, want))

    def _nearest(self, dets: list[tuple[PlateDetection, Observation]],
                 target: Target) -> tuple[PlateDetection, Observation] | None:
        best, best_d = None, self.p.gate
        for det, obs in dets:
            d = math.hypot(obs.x - target.x, obs.y - target.y)
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
            return SeekCommand(True, *self._cmd, target=t,
                               event=self._event(time, f"stop ({reason}: {math.degrees(view_now):.0f}"
                                                       f" deg, {dist_now:.2f} m)"))
        if (not fits_now and dist_now < dist) or ahead < -self.p.pass_margin:
            self.stats.given_up += 1
            return self._resume(time, "plate passed without a readable view; given up",
                                remember=True)
        return SeekCommand(False, *self._cmd, target=t)

    def _step_stop(self, time, pose, fresh, placed, camera, pan, tilt, zoom) -> SeekCommand:
        t = self.target
        assert t is not None
        if time - self._stop_since > self.p.stop_timeout:
            self.stats.timeouts += 1
            return self._resume(time, "stop timed out", remember=True)
        det, gone = self._follow(t, fresh, placed)
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
        centred = (abs(u - camera.cx) <= self.p.centre_tolerance * camera.width
                   and abs(v - (camera.height - 1) / 2) <= self.p.centre_tolerance * camera.height)
        big_enough = det.height_px >= 0.7 * self.p.target_height_px or zoom >= self.p.zoom_max - 0.05
        if settled and self._speed <= self.p.still_speed and centred and not det.clipped and (
                big_enough or abs(new_zoom - zoom) <= self.p.settle_zoom):
            self.stats.captures += 1
            event = self._event(time, f"capture at zoom {zoom:.1f} ({det.height_px:.0f} px tall)")
            self.done.append((t.x, t.y))
            self.mode, self.target = Mode.EXPLORE, None
            self._cmd = self._scan(time)
            return SeekCommand(False, *self._cmd, capture=det, target=t, event=event)
        self._cmd = (new_pan, new_tilt, new_zoom)
        return SeekCommand(True, *self._cmd, target=t)

    def summary(self) -> dict[str, Any]:
        """Counts for run.json."""
        s = self.stats
        return {"stops": s.stops, "captures": s.captures, "stopped_time_s": round(s.stopped_time, 2),
                "lost": s.lost, "rejected_not_sign": s.rejected, "timeouts": s.timeouts,
                "given_up_grazing": s.given_up}
