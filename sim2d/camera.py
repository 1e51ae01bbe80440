"""A synthetic pan-tilt-zoom camera: a fast 2.5D raycaster over a :class:`~sim2d.world.World`.

The renderer treats the world as walls of height ``spec.wall_height`` standing
on a flat floor under a flat ceiling. Each image column casts one ray through
all wall capsules at once (numpy, columns x segments); the nearest hit gives
the column's wall depth and shading. Sign plates are textured quads, projected
with the true pinhole model, occluded per column by the walls in front of
them, and warped into the image; so are the world's objects (upright
billboards of their object-catalogue pictures, facing the camera, visual only:
see the objects section below). The image is then degraded with a
range-dependent Gaussian blur and seeded Gaussian noise.

:func:`render`, :func:`visible_signs` and :func:`visible_objects` draw one
frame each. A :class:`CameraRenderer` draws a world frame after frame, as
the camera block does: it keeps what the world and the last tilt and zoom
fix (indexed walls, plate corners, per-column and per-row tables, work
arrays) and casts one set of rays for the image and both ground truths,
with the same results to the bit.

Frames and conventions
----------------------
* World: REP-103, x forward, y left, yaw counter-clockwise (rad), SI units.
* Camera frame: x forward (optical axis), y left, z up; the camera sits
  ``spec.mount_z`` above the floor. Pan is counter-clockwise positive (rad),
  tilt is **positive upwards** (rad), zoom is a focal-length multiplier.
* Image: OpenCV pixel convention, pixel ``(u, v)`` centred at integer
  coordinates, ``u`` to the right, ``v`` down, BGR ``uint8``. The principal
  point is the image centre; tilt shifts it vertically by ``f * tan(tilt)``
  (a small-tilt approximation of a pitching camera).

Projection of a camera-frame point ``(x, y, z)`` (``z`` relative to the camera
height)::

    u = cx - f * y / x
    v = cy - f * z / x,   cx = (W - 1) / 2,  cy = (H - 1) / 2 + f * tan(tilt)
    f = (W / 2) / tan(hfov / 2) * zoom

The renderer does not enforce the pan/tilt/zoom limits; :func:`clamp_ptz`
does, for the blocks that drive the camera.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from typing import Any

import cv2
import numpy as np

from blocks.core.errors import SemmapError

from .noise import NoiseAhead, gaussian_noise
from .world import Sign, World

__all__ = [
    "CameraError",
    "CameraFrame",
    "CameraRenderer",
    "CameraSpec",
    "Walls",
    "camera_pose",
    "cast_rays",
    "clamp_ptz",
    "focal_length",
    "object_corners",
    "plate_corners",
    "project_points",
    "render",
    "sign_plate_image",
    "visible_objects",
    "visible_signs",
]

NEAR = 0.05  # m: points closer than this to the image plane are not projected
OCCLUSION_TOLERANCE = 0.15  # m: a wall this much in front of a plate still lets it show
# (measured along the plate's normal, so a plate on a wall's centre line stays
# visible at grazing angles; along the ray it is capped at this many times that)
OCCLUSION_CAP = 4.0
TEXTURE_WIDTH = 600  # px: width of the plate texture before warping

# Colours (BGR, 0..255 before lighting) and lighting of the scene.
WALL_BGR = np.array([150.0, 178.0, 196.0], dtype=np.float32)  # pale beige
SKIRTING_BGR = np.array([60.0, 66.0, 74.0], dtype=np.float32)  # dark skirting board
FLOOR_BGR = np.array([78.0, 98.0, 118.0], dtype=np.float32)  # grey-brown
CEILING_BGR = np.array([205.0, 205.0, 200.0], dtype=np.float32)  # off-white
SKIRTING_HEIGHT = 0.08  # m
FLOOR_TILE = 0.6  # m: side of the floor's faint checker pattern
BLUR_LEVELS = (0.0, 0.6, 1.2, 2.0, 3.0)  # px: sigmas blended per pixel (the last is the cap)
_PALETTE = np.stack([FLOOR_BGR, CEILING_BGR, WALL_BGR, SKIRTING_BGR])  # by pixel class
_PALETTE_ROWS = {"floor": 0, "ceiling": 1, "wall": 2, "skirting": 3}  # World.colours keys


class CameraError(SemmapError):
    """A camera description is malformed."""


@dataclass(frozen=True)
class CameraSpec:
    """Intrinsics, limits, mount and degradation of the synthetic PTZ camera.

    Attributes
    ----------
    width, height : int
        Image size (px).
    hfov_deg : float
        Horizontal field of view at zoom 1 (deg); it narrows as ``hfov / zoom``
        in focal length, i.e. ``f = (width / 2) / tan(hfov / 2) * zoom``.
    zoom_min, zoom_max : float
        Zoom range (focal length multiplier).
    pan_min_deg, pan_max_deg : float
        Pan limits (deg, counter-clockwise positive).
    tilt_min_deg, tilt_max_deg : float
        Tilt limits (deg, positive up).
    mount_x, mount_y : float
        Position of the pan axis in the robot frame (m).
    mount_z : float
        Height of the optical centre above the floor (m).
    max_range : float
        Sign plates farther than this (m, horizontal) are neither drawn nor reported.
    noise_std : float
        Standard deviation of the additive Gaussian noise (grey levels).
    blur_per_m : float
        Gaussian blur sigma (px) per metre of depth at zoom 1; the sigma at
        depth ``d`` is ``blur_per_m * d / zoom``. With the default 0.15, text
        on a 0.6 x 0.2 m plate is readable to about 4 m at zoom 1, marginal at
        6 m and a smear at 8-10 m, where zoom 2-3 makes it readable again.
    wall_height : float
        Height of the walls (m); the ceiling lies on top of them.
    """

    width: int = 320
    height: int = 240
    hfov_deg: float = 48.0
    zoom_min: float = 1.0
    zoom_max: float = 10.0
    pan_min_deg: float = -170.0
    pan_max_deg: float = 170.0
    tilt_min_deg: float = -30.0
    tilt_max_deg: float = 30.0
    mount_x: float = 0.15
    mount_y: float = 0.0
    mount_z: float = 0.6
    max_range: float = 12.0
    noise_std: float = 3.0
    blur_per_m: float = 0.15
    wall_height: float = 2.5

    def __post_init__(self) -> None:
        problems = []
        if self.width < 2 or self.height < 2:
            problems.append(f"image size {self.width}x{self.height} must be at least 2x2")
        if not 0 < self.hfov_deg < 180:
            problems.append(f"hfov_deg {self.hfov_deg} must be in (0, 180)")
        if not 0 < self.zoom_min <= self.zoom_max:
            problems.append(f"zoom range [{self.zoom_min}, {self.zoom_max}] must be 0 < min <= max")
        if self.pan_min_deg > self.pan_max_deg:
            problems.append(f"pan range [{self.pan_min_deg}, {self.pan_max_deg}] is reversed")
        if not -90 < self.tilt_min_deg <= self.tilt_max_deg < 90:
            problems.append(f"tilt range [{self.tilt_min_deg}, {self.tilt_max_deg}] must lie "
                            "in (-90, 90) and not be reversed")
        if not 0 < self.mount_z < self.wall_height:
            problems.append(f"mount_z {self.mount_z} must be between the floor and the "
                            f"ceiling (wall_height {self.wall_height})")
        for name in ("max_range",):
            if getattr(self, name) <= 0:
                problems.append(f"{name} must be > 0")
        for name in ("noise_std", "blur_per_m"):
            if getattr(self, name) < 0:
                problems.append(f"{name} must be >= 0")
        if problems:
            raise CameraError("bad camera: " + "; ".join(problems))

    @property
    def hfov(self) -> float:
        """Horizontal field of view at zoom 1 (rad)."""
        return math.radians(self.hfov_deg)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, file: Any = None,
                  line: int | None = None) -> CameraSpec:
        """Build a spec from a mapping (the ``camera:`` section of a robot YAML).

        Keys are the field names; angles are in degrees in the keys ending in
        ``_deg``. Missing keys keep their defaults.

        Parameters
        ----------
        d : mapping
            The values, e.g. ``{"hfov_deg": 60, "mount_z": 0.8}``.
        file, line : optional
            Where the mapping came from, for error messages.

        Raises
        ------
        CameraError
            On an unknown key, a value of the wrong type or an out-of-range value.
        """
        if not isinstance(d, Mapping):
            raise CameraError(f"a camera must be a mapping of its parameters, got {d!r}",
                              file=file, line=line)
        known = {f.name: f for f in fields(cls)}
        values: dict[str, Any] = {}
        for key, value in d.items():
            if key not in known:
                import difflib
                close = difflib.get_close_matches(str(key), list(known), n=1)
                raise CameraError(f"unknown camera field {key!r}", file=file, line=line,
                                  field=str(key),
                                  hint=f"Did you mean {close[0]!r}?" if close else
                                  f"Known fields: {', '.join(known)}.")
            is_int = key in ("width", "height")
            ok = (not isinstance(value, bool) and isinstance(value, (int, float))
                  and math.isfinite(value) and (not is_int or float(value).is_integer()))
            if not ok:
                kind = "a whole number of pixels" if is_int else "a number"
                raise CameraError(f"camera field {key!r} must be {kind}, got {value!r}",
                                  file=file, line=line, field=str(key))
            values[key] = int(value) if is_int else float(value)
        try:
            return cls(**values)
        except CameraError as err:
            raise CameraError(err.message, file=file, line=line) from None


# ---- geometry -------------------------------------------------------------------------------
def focal_length(spec: CameraSpec, zoom: float) -> float:
    """Focal length (px) at a zoom: ``(width / 2) / tan(hfov / 2) * zoom``."""
    if not zoom > 0:
        raise ValueError(f"zoom must be > 0, got {zoom!r}")
    return (spec.width / 2) / math.tan(spec.hfov / 2) * zoom


def clamp_ptz(spec: CameraSpec, pan: float, tilt: float, zoom: float) -> tuple[float, float, float]:
    """Clip a pan (rad), tilt (rad) and zoom command to the camera's limits."""
    pan = min(max(pan, math.radians(spec.pan_min_deg)), math.radians(spec.pan_max_deg))
    tilt = min(max(tilt, math.radians(spec.tilt_min_deg)), math.radians(spec.tilt_max_deg))
    zoom = min(max(zoom, spec.zoom_min), spec.zoom_max)
    return pan, tilt, zoom


def camera_pose(robot_pose, spec: CameraSpec, pan: float = 0.0) -> tuple[float, float, float]:
    """World pose ``(x, y, yaw)`` of the camera on a robot.

    Parameters
    ----------
    robot_pose : (x, y, theta)
        The robot's pose in the world (m, m, rad).
    spec : CameraSpec
        Gives the mount position in the robot frame.
    pan : float
        Pan angle (rad, counter-clockwise positive) added to the robot's heading.
    """
    x, y, theta = (float(v) for v in robot_pose)
    c, s = math.cos(theta), math.sin(theta)
    return (x + c * spec.mount_x - s * spec.mount_y,
            y + s * spec.mount_x + c * spec.mount_y,
            theta + pan)


def _intrinsics(spec: CameraSpec, tilt: float, zoom: float) -> tuple[float, float, float]:
    f = focal_length(spec, zoom)
    return f, (spec.width - 1) / 2, (spec.height - 1) / 2 + f * math.tan(tilt)


def project_points(points: np.ndarray, cam_pose, tilt: float, zoom: float,
                   spec: CameraSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project world points ``(N, 3)`` (x, y, z above the floor) into the image.

    Returns
    -------
    u, v : ndarray (N,)
        Pixel coordinates (meaningless where ``depth <= 0``).
    depth : ndarray (N,)
        Forward distance along the optical axis (m); negative behind the camera.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return _projected(p, cam_pose, *_intrinsics(spec, tilt, zoom), spec.mount_z)


def _project(points: np.ndarray, shot: _Shot, mount_z: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`project_points` for a shot: the intrinsics its lens already holds (the same
    numbers, without working them out again)."""
    lens = shot.lens
    return _projected(points, shot.pose, lens.f, lens.cx, lens.cy, mount_z)


def _projected(p: np.ndarray, cam_pose, f: float, cx: float, cy: float, mount_z: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pinhole projection of points ``p`` (N, 3) with these intrinsics: u, v, depth."""
    px, py, yaw = cam_pose
    dx, dy = p[:, 0] - px, p[:, 1] - py
    c, s = math.cos(yaw), math.sin(yaw)
    xc = c * dx + s * dy
    yc = -s * dx + c * dy
    zc = p[:, 2] - mount_z
    safe = np.where(np.abs(xc) > 1e-12, xc, 1e-12)
    return cx - f * yc / safe, cy - f * zc / safe, xc


def _forward_depth(x: float, y: float, pose: tuple[float, float, float]) -> float:
    """The depth :func:`project_points` gives a point at (``x``, ``y``), in plain floats
    (the same IEEE operations, for one point)."""
    px, py, yaw = pose
    return math.cos(yaw) * (x - px) + math.sin(yaw) * (y - py)


def cast_rays(origin, angles: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest wall hit along each ray, all rays against all capsules at once.

    A capsule is modelled by its face towards the origin (the centre segment
    offset by the radius), extended by the radius at ends shared with another
    segment (so convex corners close), plus a round cap at each free end and
    for zero-length segments (posts). When the rays span less than a half
    turn, segments wholly outside their wedge are skipped first.

    Parameters
    ----------
    origin : (x, y)
        Where the rays start (m); assumed outside every capsule.
    angles : ndarray (R,)
        World directions of the rays (rad).
    segments : ndarray (S, 5)
        Capsules x1, y1, x2, y2, radius (m).

    Returns
    -------
    distance : ndarray (R,)
        Distance along the ray to the first surface hit (m), ``inf`` for none.
    incidence : ndarray (R,)
        ``|cos|`` of the angle between the ray and the surface normal at the
        hit (1 = head-on, 0 = grazing); 0 where nothing is hit.

    See Also
    --------
    Walls : the same cast over walls indexed once, for many casts.
    """
    return Walls(segments, index=False).cast(origin, angles)


class Walls:
    """A world's wall capsules, ready for many :func:`cast_rays` casts.

    Indexing finds once which segment ends coincide (the costly part of
    telling shared ends from free ones); each cast then counts, among the
    segments its wedge keeps, how many of them meet at each end. Casts give
    exactly what :func:`cast_rays` gives for the same segments.

    Parameters
    ----------
    segments : ndarray (S, 5)
        Capsules x1, y1, x2, y2, radius (m).
    index : bool
        Index the ends now (for many casts); without, each cast finds the
        shared ends among its own segments.
    """

    def __init__(self, segments: np.ndarray, index: bool = True) -> None:
        self.segments = np.ascontiguousarray(segments, dtype=np.float64).reshape(-1, 5)
        # by coordinate, (5, S): x1, y1, x2, y2 and radius rows, as a cast works on them
        self._rows = np.ascontiguousarray(self.segments.T)
        self._limit = -(self._rows[4] + 1e-4)  # (S,): how far out of a wedge a centre line may be
        # (2, S) int: the ends' keys (a's, b's), or the same id for coinciding ends when indexed
        self._ends = _end_keys(self.segments).reshape(2, -1)
        self._indexed = False
        n_ends = 2 * len(self.segments)
        if index and n_ends:
            keys = self._ends.ravel()
            # _shared_ends gives ends without a face the stand-in keys -1 .. -n_ends;
            # a real key among them would meet one there, so such walls are not indexed
            if not np.any((keys >= -n_ends) & (keys < 0)):
                self._ends = np.unique(keys, return_inverse=True)[1].reshape(2, -1)
                self._indexed = True

    def cast(self, origin, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest wall hit along each ray: ``distance`` and ``incidence`` as :func:`cast_rays`."""
        angles = np.asarray(angles, dtype=np.float64).reshape(-1)
        n_rays = angles.shape[0]
        if len(self.segments) == 0 or n_rays == 0:
            return np.full(n_rays, np.inf), np.zeros(n_rays)
        ox, oy = float(origin[0]), float(origin[1])
        rel = self._rows[:4] - np.array([[ox], [oy], [ox], [oy]])  # the ends from the origin
        radius, ends = self._rows[4], self._ends
        keep = _cull(rel, self._limit, angles)
        if keep is not None:
            keep = np.flatnonzero(keep)
            if len(keep) == 0:
                return np.full(n_rays, np.inf), np.zeros(n_rays)
            rel, radius, ends = rel[:, keep], radius[keep], ends[:, keep]
        return _cast(rel, radius, angles, ends, self._indexed)


def _cast(rel: np.ndarray, radius: np.ndarray, angles: np.ndarray, ends: np.ndarray,
          indexed: bool) -> tuple[np.ndarray, np.ndarray]:
    """The ray-capsule kernel of :func:`cast_rays` on the segments it keeps.

    ``rel`` (4, S) are their ends relative to the origin (x1, y1, x2, y2 rows),
    ``radius`` (S,) their radii, ``ends`` (2, S) their ends' ids from :class:`Walls`
    when ``indexed``, else their keys (:func:`_end_keys`) for finding the shared ends here.
    """
    n_rays = angles.shape[0]
    a = rel[0:2]
    e = rel[2:4] - a  # (2, S): x and y side by side, the same arithmetic in half the calls
    ex, ey = e
    inv_len, has_length = _inverse_lengths(np.hypot(ex, ey))
    normal = e[::-1] * inv_len  # unit normal (left of a -> b): -ey / len, ex / len
    np.negative(normal[0], out=normal[0])
    ax, ay = a
    nx, ny = normal
    # the face towards the origin: the radius along the normal, or against it
    q = a + np.where(ax * nx + ay * ny <= 0, radius, -radius) * normal
    qx, qy = q
    shared, caps_xy, caps_r = _shared_ends(rel, radius, has_length, ends, indexed)
    # (and 10 um more everywhere, so float32 rounding opens no pinholes at joints)
    r_len, margin = radius * inv_len, 1e-5 * inv_len
    s_lo = np.where(shared[0], -r_len, 0.0) - margin
    s_hi = np.where(shared[1], 1.0 + r_len, 1.0) + margin
    if has_length is not None:
        s_lo[~has_length], s_hi[~has_length] = 2.0, -1.0  # no face for posts
    f32 = np.float32
    dx, dy = np.cos(angles).astype(f32)[:, None], np.sin(angles).astype(f32)[:, None]
    (ex32, ey32), (qx32, qy32) = e.astype(f32), q.astype(f32)
    rows = np.arange(n_rays)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # faces: t*d = q + s*e
        denom = dx * ey32
        denom -= dy * ex32  # (R, S)
        inv = np.divide(f32(1.0), denom)
        t_face = (qx * ey - qy * ex).astype(f32) * inv
        s_face = qx32 * dy
        s_face -= qy32 * dx
        s_face *= inv
        ok = t_face > 0
        ok &= s_face >= s_lo.astype(f32)
        ok &= s_face <= s_hi.astype(f32)
        t_face = np.where(ok, t_face, f32(np.inf))
        best = np.argmin(t_face, axis=1)
        t_best = t_face[rows, best]
        # |cos| only where it is needed, as it would be everywhere
        cos_best = np.abs(denom[rows, best]) * inv_len.astype(f32)[best]
        if len(caps_r):
            cx32, cy32 = caps_xy.astype(f32)
            proj = dx * cx32 + dy * cy32  # (R, K): along the ray
            perp = dx * cy32
            perp -= dy * cx32  # across it (no cancellation, unlike |c|^2 - proj^2)
            disc = (caps_r * caps_r).astype(f32) - perp * perp
            root = np.sqrt(np.maximum(disc, f32(0)))
            t_cap = proj - root
            t_cap = np.where((disc >= 0) & (t_cap > 0), t_cap, f32(np.inf))
            best_cap = np.argmin(t_cap, axis=1)
            t_cap_best = t_cap[rows, best_cap]
            on_cap = t_cap_best < t_best  # a tie goes to the face (listed first)
            if on_cap.any():
                cap_r = np.where(caps_r > 0, caps_r, 1.0).astype(f32)
                cos_cap = root[rows, best_cap] / cap_r[best_cap]
                t_best = np.where(on_cap, t_cap_best, t_best)
                cos_best = np.where(on_cap, cos_cap, cos_best)
    distance = t_best.astype(np.float64)
    incidence = np.where(np.isfinite(distance), cos_best, 0.0)
    return distance, np.clip(incidence, 0.0, 1.0)


def _inverse_lengths(length: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """``1 / length`` (0 for segments of no length, posts) and which segments have a length
    (None when all do: walls without posts take the short way, with the same numbers)."""
    if length.min() > 1e-9:
        return 1.0 / length, None
    has_length = length > 1e-9
    return np.where(has_length, 1.0 / np.where(has_length, length, 1.0), 0.0), has_length


def _cull(rel: np.ndarray, limit: np.ndarray, angles: np.ndarray) -> np.ndarray | None:
    """Which capsules (ends ``rel`` relative to the rays' origin, (4, S) rows x1, y1, x2, y2;
    ``limit`` their ``-(radius + 1e-4)``) are not wholly outside the wedge the rays span
    (S,) bool; None (keep all) when the wedge is a half turn or more."""
    lo, hi = _angle_span(angles)
    half = (hi - lo) / 2
    if half >= math.pi / 2 - 1e-3:
        return None
    mid = angles[0] + lo + half
    c, s = math.cos(mid), math.sin(mid)
    sh, ch = math.sin(half), math.cos(half)
    px, py = rel[0::2], rel[1::2]  # (2, S): both ends
    x, y = c * px + s * py, -s * px + c * py  # in the wedge's frame
    xs, yc = x * sh, y * ch
    out_left, out_right = xs - yc < limit, xs + yc < limit  # (2, S): each end
    return ~((out_left[0] & out_left[1]) | (out_right[0] & out_right[1]))


def _angle_span(angles: np.ndarray) -> tuple[float, float]:
    """The least and greatest of ``angles`` relative to the first, each wrapped into
    (-pi, pi] as ``np.angle(np.exp(1j * a))`` wraps it.

    Rays in strictly monotonic order over less than 3 rad (a camera's columns, or one
    ray) have them at their ends, so only the ends are wrapped (the wrap moves an angle
    by a few ulp, far less than the rays' spacing): the same two numbers, for a
    fifth of the work. (``np.angle`` is ``arctan2`` of the parts; a step test on the
    least or greatest step is the test on all of them, NaN included.)
    """
    if len(angles) == 1:
        return 0.0, 0.0  # the wrap of exp(0j)
    rel = angles - angles[0]
    steps = rel[1:] - rel[:-1]
    if abs(rel[-1]) < 3.0 and (steps.max() < -1e-9 or steps.min() > 1e-9):
        z = np.exp(1j * rel[[0, -1]])
        first, last = np.arctan2(z.imag, z.real).tolist()  # first: 0.0, last: not 0
        return min(first, last), max(first, last)
    z = np.exp(1j * rel)
    wrapped = np.arctan2(z.imag, z.real)
    return float(wrapped.min()), float(wrapped.max())


def _end_keys(seg: np.ndarray) -> np.ndarray:
    """Integer keys (2S,) of the segment ends (a's then b's), equal for ends within 10 um."""
    ends = np.concatenate([seg[:, 0:2], seg[:, 2:4]])
    keys = np.round(ends * 1e5).astype(np.int64)
    return keys[:, 0] * 1_000_003 + keys[:, 1]


def _shared_ends(rel: np.ndarray, radius: np.ndarray, has_length: np.ndarray | None,
                 ends: np.ndarray, indexed: bool
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which segment ends touch another segment's end, and the round caps still needed.

    ``rel`` (4, S) are the ends relative to the rays' origin; ``has_length``
    which segments have a face (None: all); ``ends`` (2, S) the ends' ids from
    :class:`Walls` (equal for coinciding ends) when ``indexed``, else their
    keys (:func:`_end_keys`).

    Returns ``shared`` (2, S) bool (a ends, b ends); ``caps_xy`` (2, K), the x
    and y (relative to the origin) of the free ends, a's then b's, then of the
    zero-length segments (posts); and ``caps_r`` (K,), their radii.
    """
    n = rel.shape[1]
    if indexed and has_length is None:  # how many ends (all with a face) share each id
        shared = np.bincount(ends.ravel())[ends] > 1
    else:
        valid = (np.ones(2 * n, bool) if has_length is None
                 else np.concatenate((has_length, has_length)))  # (2S,): a ends, then b ends
        if indexed:  # how many ends with a face share each id
            shared = np.bincount(ends.ravel(), weights=valid)[ends] > 1
        else:
            _, inverse, counts = np.unique(np.where(valid, ends.ravel(), -1 - np.arange(2 * n)),
                                           return_inverse=True, return_counts=True)
            shared = (counts[inverse] > 1).reshape(2, n)
        if has_length is not None:
            shared &= has_length
    round_end = radius > 0
    free = ~shared & round_end  # (2, S)
    if has_length is not None:
        free &= has_length
    caps_xy = rel.reshape(2, 2, n).transpose(1, 0, 2)[:, free]  # (2, K): x, y
    caps_r = np.broadcast_to(radius, (2, n))[free]
    if has_length is not None:
        posts = ~has_length & round_end
        if posts.any():
            caps_xy = np.concatenate((caps_xy, rel[0:2, posts]), axis=1)
            caps_r = np.concatenate((caps_r, radius[posts]))
    return shared, caps_xy, caps_r


# ---- sign plates ---------------------------------------------------------------------------
DEFAULT_PLATE = (238, 238, 238)  # RGB: a sign's plate (sim2d.world.Sign's default)
DEFAULT_INK = (15, 15, 15)  # RGB: its letters
BORDER_SOFTEN = 25  # grey levels: the border is the ink, this much towards the plate's colour


@dataclass(frozen=True)
class _Lettering:
    """How one of :data:`sim2d.world.SIGN_FONTS` is drawn."""

    face: int  # OpenCV Hershey face
    stroke: float  # line thickness (px) per unit of font scale
    slant: float = 0.0  # italic shear: px to the right per px above the text's middle
    stretch: float = 1.0  # the letters' width factor (< 1: condensed)


# OpenCV 5 draws every Hershey face with one sans-serif typeface, in three weights
# (duplex and triplex alike), so complex is slanted and triplex condensed to keep
# the five apart; plain's letters are 15/27 as tall as the others' at a scale, so
# its stroke is too.
_LETTERINGS = {
    "duplex": _Lettering(cv2.FONT_HERSHEY_DUPLEX, 1.6),
    "simplex": _Lettering(cv2.FONT_HERSHEY_SIMPLEX, 1.6),
    "plain": _Lettering(cv2.FONT_HERSHEY_PLAIN, 0.89),
    "complex": _Lettering(cv2.FONT_HERSHEY_COMPLEX, 1.6, slant=0.2),
    "triplex": _Lettering(cv2.FONT_HERSHEY_TRIPLEX, 1.6, stretch=0.8),
}


def sign_plate_image(text: str, width_px: int = TEXTURE_WIDTH, height_px: int = 200, *,
                     plate: tuple[int, int, int] = DEFAULT_PLATE,
                     ink: tuple[int, int, int] = DEFAULT_INK, font: str = "duplex",
                     spacing: float = 0.0) -> np.ndarray:
    """The texture of a sign plate: text centred on a plate with a border in the ink's colour.

    Parameters
    ----------
    text : str
        The sign's text (one line; fitted to the plate, letters at most 60 %
        of the plate height).
    width_px, height_px : int
        Texture size (px).
    plate, ink : (r, g, b) ints 0-255
        Colours of the plate and of the letters (RGB, as in world files). The
        border is the ink moved ``BORDER_SOFTEN`` grey levels towards the
        plate in each channel (dark grey on the default light plate).
    font : str
        One of :data:`sim2d.world.SIGN_FONTS`: OpenCV's Hershey face of that
        name, ``complex`` slanted and ``triplex`` condensed (see ``_LETTERINGS``).
    spacing : float
        Extra space between letters, as a fraction of the letter height
        (>= 0); the spaced text is fitted to the plate like the plain text.

    Returns
    -------
    ndarray (height_px, width_px, 3) uint8, BGR.

    Raises
    ------
    ValueError
        On a texture under 4 x 4 px, an unknown font or a negative spacing.
    """
    w, h = int(width_px), int(height_px)
    if w < 4 or h < 4:
        raise ValueError(f"a plate texture needs at least 4x4 px, got {w}x{h}")
    if font not in _LETTERINGS:
        raise ValueError(f"unknown sign font {font!r}: use one of {', '.join(_LETTERINGS)}")
    if not spacing >= 0:
        raise ValueError(f"letter spacing must be >= 0, got {spacing!r}")
    plate_bgr, ink_bgr = _bgr(plate), _bgr(ink)
    img = np.empty((h, w, 3), dtype=np.uint8)
    img[:] = plate_bgr
    border = max(1, round(0.05 * min(w, h)))
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), _border_colour(plate_bgr, ink_bgr),
                  thickness=border * 2)
    text = " ".join(str(text).split())
    if not text:
        return img
    look = _LETTERINGS[font]
    (tw, th), _ = cv2.getTextSize(text, look.face, 1.0, 1)
    tw_look = (tw + spacing * th * (len(text) - 1)) * look.stretch + look.slant * th
    inner_w, inner_h = w - 8 * border, h - 4 * border
    scale = min(0.6 * h / max(th, 1), inner_w / max(tw_look, 1), inner_h / max(th, 1))
    thickness = max(1, round(scale * look.stroke))
    if font == "duplex" and spacing == 0:  # fitted and drawn as it always was
        (tw, th), _base = cv2.getTextSize(text, look.face, scale, thickness)
        org = ((w - tw) // 2, (h + th) // 2)
        cv2.putText(img, text, org, look.face, scale, ink_bgr, thickness, cv2.LINE_AA)
        return img
    scale, thickness = _fit_drawn(text, look, scale, spacing * th, th, inner_w)
    alpha = _lettering_alpha(text, look, scale, thickness, spacing * th * scale, w, h)
    a = alpha.astype(np.float32)[..., None] / np.float32(255)
    ink_f = np.array(ink_bgr, dtype=np.float32)
    img[:] = np.rint(img * (1 - a) + ink_f * a).astype(np.uint8)
    return img


def _bgr(rgb) -> tuple[int, int, int]:
    """An RGB colour as OpenCV's BGR tuple of ints."""
    r, g, b = (int(c) for c in rgb)
    return b, g, r


def _border_colour(plate_bgr: tuple[int, int, int],
                   ink_bgr: tuple[int, int, int]) -> tuple[int, int, int]:
    """The ink moved ``BORDER_SOFTEN`` grey levels towards the plate in each channel
    (no further than the plate's own level).

    Examples
    --------
    >>> _border_colour((238, 238, 238), (15, 15, 15)), _border_colour((40, 60, 250), (250, 250, 240))
    ((40, 40, 40), (225, 225, 250))
    """
    return tuple(i + min(max(p - i, -BORDER_SOFTEN), BORDER_SOFTEN)
                 for p, i in zip(plate_bgr, ink_bgr))


def _fit_drawn(text: str, look: _Lettering, scale: float, gap: float, text_h: float,
               inner_w: float) -> tuple[float, int]:
    """Shrink a font scale until the drawn line fits ``inner_w`` px; the scale and thickness.

    ``gap`` (the extra space between letters) and ``text_h`` (the slant's
    height) are in px at scale 1. Fitting at scale 1, as the default plate
    does, misses how thick strokes widen the letters (by up to a fifth).
    """
    thickness = max(1, round(scale * look.stroke))
    for _ in range(3):
        drawn = (_line_width(text, look.face, scale, thickness, gap * scale) * look.stretch
                 + look.slant * text_h * scale)
        if drawn <= inner_w:
            break
        scale *= inner_w / drawn
        thickness = max(1, round(scale * look.stroke))
    return scale, thickness


def _line_width(text: str, face: int, scale: float, thickness: int, gap: float) -> float:
    """Width (px) of a line of text drawn with ``gap`` px more between its letters."""
    return cv2.getTextSize(text, face, scale, thickness)[0][0] + gap * (len(text) - 1)


def _lettering_alpha(text: str, look: _Lettering, scale: float, thickness: int, gap: float,
                     width: int, height: int) -> np.ndarray:
    """Coverage (0-255, ``(height, width)`` uint8) of ``text`` centred on a plate, drawn
    letter by letter ``gap`` px apart, then slanted and stretched about its centre.

    A letter's pen position in the unspaced line is the width of the text up
    to and including it less its own width (where ``cv2.putText`` puts it).
    """
    face = look.face
    th = cv2.getTextSize(text, face, scale, thickness)[0][1]
    line_w = round(_line_width(text, face, scale, thickness, gap))
    canvas_w = max(width, line_w + 2 * thickness + 2)  # the unstretched line may be wider
    canvas = np.zeros((height, canvas_w), dtype=np.uint8)
    x0, y = (canvas_w - line_w) // 2, (height + th) // 2
    for i, ch in enumerate(text):
        if ch == " ":
            continue
        pen = (cv2.getTextSize(text[:i + 1], face, scale, thickness)[0][0]
               - cv2.getTextSize(ch, face, scale, thickness)[0][0])
        cv2.putText(canvas, ch, (x0 + pen + round(i * gap), y), face, scale, 255, thickness,
                    cv2.LINE_AA)
    # x' = width/2 + stretch * (x - canvas_w/2) + slant * (middle - y), y' = y
    middle = y - th / 2
    M = np.array([[look.stretch, -look.slant,
                   width / 2 - look.stretch * canvas_w / 2 + look.slant * middle],
                  [0.0, 1.0, 0.0]])
    return cv2.warpAffine(canvas, M, (width, height), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)


@functools.lru_cache(maxsize=64)  # ~0.5 MB each
def _plate_mipmaps(text: str, width_px: int, height_px: int,
                   style: tuple = (DEFAULT_PLATE, DEFAULT_INK, "duplex", 0.0)
                   ) -> tuple[np.ndarray, ...]:
    """The texture and its successive INTER_AREA halvings (for anti-aliased warping).

    ``style`` is ``(plate, ink, font, spacing)`` as :func:`sign_plate_image` takes them.
    """
    plate, ink, font, spacing = style
    base = sign_plate_image(text, width_px, height_px, plate=plate, ink=ink, font=font,
                            spacing=spacing)
    base.setflags(write=False)
    levels = [base]
    while levels[-1].shape[1] > 16 and levels[-1].shape[0] > 8:
        prev = levels[-1]
        half = cv2.resize(prev, (max(1, prev.shape[1] // 2), max(1, prev.shape[0] // 2)),
                          interpolation=cv2.INTER_AREA)
        half.setflags(write=False)
        levels.append(half)
    return tuple(levels)


def plate_corners(sign: Sign) -> np.ndarray:
    """The plate's corners (4, 3), top-left, top-right, bottom-right, bottom-left as seen
    by someone facing it.

    Uses :meth:`Sign.corners` but checks its left/right order against the
    plate's normal (a viewer facing the plate looks along ``-normal``, so
    their left is ``(sin facing, -cos facing)``) and swaps it if needed, so
    the text is never drawn mirrored.
    """
    corners = np.asarray(sign.corners(), dtype=np.float64)
    left = np.array([math.sin(sign.facing), -math.cos(sign.facing)])
    if float((corners[0, :2] - corners[1, :2]) @ left) < 0:
        corners = corners[[1, 0, 3, 2]]
    return corners


def _tolerance_along_ray(cos_incidence):
    """How far (m, along the ray) a wall may stand in front of a plate without hiding it."""
    cos_incidence = np.maximum(cos_incidence, 1e-3)
    return np.minimum(OCCLUSION_TOLERANCE / cos_incidence, OCCLUSION_CAP * OCCLUSION_TOLERANCE)


def _column_angles(spec: CameraSpec, f: float) -> np.ndarray:
    """Ray angle of each image column in the camera frame (rad, CCW +, left is +)."""
    cx = (spec.width - 1) / 2
    return np.arctan2(cx - np.arange(spec.width, dtype=np.float64), f)


@dataclass
class _PlateView:
    index: int
    sign: Sign
    bearing: float
    distance: float
    viewing_angle: float
    corners: np.ndarray  # (4, 2) px, unclipped
    depth: float  # forward depth of the centre (m)
    columns: np.ndarray  # (W,) bool: columns where the plate is in front of the walls
    visible_fraction: float
    bbox: tuple[int, int, int, int]


@dataclass(frozen=True)
class _Plates:
    """A world's sign plates, fixed once: their corners, centres and reach."""

    signs: tuple[Sign, ...]
    corners: tuple[np.ndarray, ...]  # (4, 3) each, as plate_corners gives them
    xy: np.ndarray  # (N, 2) m: the centres
    reach: np.ndarray  # (N,) m: the farthest corner from the centre (horizontally)
    normals: tuple[np.ndarray, ...]  # (2,) each: (cos, sin) of the sign's facing

    @classmethod
    def of(cls, world: World) -> _Plates:
        signs = tuple(world.signs)
        corners = tuple(plate_corners(sign) for sign in signs)
        xy = np.array([[sign.x, sign.y] for sign in signs], dtype=np.float64).reshape(-1, 2)
        reach = np.array([np.hypot(*(c[:, :2] - centre).T).max()
                          for c, centre in zip(corners, xy)], dtype=np.float64)
        normals = tuple(np.array([math.cos(sign.facing), math.sin(sign.facing)])
                        for sign in signs)
        return cls(signs, corners, xy, reach, normals)


def _plate_views(shot: _Shot, plates: _Plates, walls: Walls, spec: CameraSpec,
                 may_show: np.ndarray | None = None) -> list[_PlateView]:
    """Every plate that is at least partly visible, with its projection and occlusion
    (of those ``may_show`` keeps, if given: :func:`_may_show` of the plates)."""
    if may_show is None:
        may_show = _may_show(plates.xy, plates.reach, shot, spec)
    views = []
    for i in np.flatnonzero(may_show).tolist():
        view = _plate_view(i, plates.signs[i], plates.corners[i], shot, walls, spec,
                           plates.normals[i])
        if view is not None:
            views.append(view)
    return views


def _plate_view(i: int, sign: Sign, corners3: np.ndarray, shot: _Shot, walls: Walls,
                spec: CameraSpec, normal: np.ndarray) -> _PlateView | None:
    """Sign ``i``'s plate as the camera sees it (corners ``corners3`` from
    :func:`plate_corners`, ``normal`` the (cos, sin) of its facing); None when none
    of it shows."""
    px, py, yaw = shot.pose
    width, height = spec.width, spec.height
    to_cam = np.array([px - sign.x, py - sign.y])
    distance = float(np.hypot(to_cam[0], to_cam[1]))
    if distance <= 1e-9 or distance > spec.max_range:
        return None
    cos_view = float(normal @ to_cam) / distance
    if cos_view <= 0:
        return None  # seen from behind or edge-on
    u, v, depth = _project(corners3, shot, spec.mount_z)
    if depth.min() < NEAR:  # (as np.any(depth < NEAR), NaN included)
        return None
    if _off_image(u, v, width, height):
        return None
    columns = _columns_in_front(
        shot, u, sign.x, sign.y, sign.facing, width,
        lambda dx, dy: _tolerance_along_ray(np.abs(dx * normal[0] + dy * normal[1])))
    footprint = _footprint(u, v, columns, height)
    if footprint is None:
        return None
    # line of sight to the centre (cast last: the costliest test)
    los_angle = math.atan2(sign.y - py, sign.x - px)
    t_los, _ = walls.cast((px, py), np.array([los_angle]))
    if t_los[0] < distance - _tolerance_along_ray(cos_view):
        return None
    fraction, bbox = footprint
    bearing = _bearing(yaw, sign.x - px, sign.y - py)
    return _PlateView(
        index=i, sign=sign, bearing=bearing, distance=distance,
        viewing_angle=math.acos(min(1.0, cos_view)), corners=np.stack([u, v], axis=1),
        depth=_forward_depth(sign.x, sign.y, shot.pose), columns=columns,
        visible_fraction=float(fraction), bbox=bbox)


def _off_image(u: np.ndarray, v: np.ndarray, width: int, height: int) -> bool:
    """Whether a projected quad (corners ``u``, ``v``) lies wholly beside, above or below
    the image (the four extremes read once, as plain floats)."""
    us, vs = u.tolist(), v.tolist()
    return (max(us) < -0.5 or min(us) > width - 0.5 or max(vs) < -0.5
            or min(vs) > height - 0.5)


def _may_show(xy: np.ndarray, reach: np.ndarray, shot: _Shot, spec: CameraSpec) -> np.ndarray:
    """Which things may show (N,) bool: all but those surely beyond ``spec.max_range``,
    behind the image plane, or left or right of the image.

    A thing lies within ``reach`` (m, horizontally) of its centre ``xy``. The
    test is conservative (by a micrometre), so the exact per-thing checks of
    :func:`_plate_view` and :func:`_object_view` drop what it keeps but would
    drop nothing it drops.
    """
    px, py, yaw = shot.pose
    eps = 1e-6
    dx, dy = xy[:, 0] - px, xy[:, 1] - py
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = c * dx + s * dy, -s * dx + c * dy  # camera frame: forward, left
    t = (spec.width / 2) / shot.lens.f  # |y / x| at the image's side edges
    side = reach * math.hypot(1.0, t) + eps
    return ((np.hypot(dx, dy) <= spec.max_range + eps) & (x + reach >= NEAR - eps)
            & (y - t * x <= side) & (y + t * x >= -side))


def _columns_in_front(shot: _Shot, u: np.ndarray, x: float, y: float, facing: float,
                      width: int, tolerance: Callable[[np.ndarray, np.ndarray], Any]
                      ) -> np.ndarray:
    """The image columns (bool, ``width``) in which an upright flat picture at (``x``, ``y``)
    facing ``facing`` (rad), whose corners project to columns ``u``, is not behind a wall.

    Each column's ray meets the picture's line at some distance; the column
    shows it unless the column's first wall is nearer by more than
    ``tolerance(dx, dy)`` (m, given the rays' directions). A picture narrower
    than a column takes the nearest one.
    """
    px, py, yaw = shot.pose
    tx, ty = math.sin(facing), -math.cos(facing)
    lo = max(0, math.ceil(u.min() - 0.5))
    hi = min(width - 1, math.floor(u.max() + 0.5))
    columns = np.zeros(width, dtype=bool)
    if hi < lo:
        lo = hi = round(float(u.mean()))
    if 0 <= lo <= hi < width:
        a = yaw + shot.lens.angles[lo:hi + 1]
        dx, dy = np.cos(a), np.sin(a)
        sx, sy = x - px, y - py
        with np.errstate(divide="ignore", invalid="ignore"):
            t_picture = (sx * ty - sy * tx) / (dx * ty - dy * tx)
        columns[lo:hi + 1] = ~(shot.wall_t[lo:hi + 1] < t_picture - tolerance(dx, dy))
    return columns


def _footprint(u: np.ndarray, v: np.ndarray, columns: np.ndarray,
               height: int) -> tuple[float, tuple[int, int, int, int]] | None:
    """How much of a projected quad shows (unoccluded columns x rows in the image) and the
    pixel box of what shows; None when nothing does. Plates and objects share it, so the
    ground truth of both is judged alike."""
    span = max(float(u.max() - u.min()), 1.0)
    rows_in = max(0.0, min(v.max(), height - 0.5) - max(v.min(), -0.5))
    fraction = min(1.0, columns.sum() / span) * min(1.0, rows_in / max(v.max() - v.min(), 1.0))
    if fraction <= 0:
        return None
    visible_cols = np.flatnonzero(columns)
    bbox = (int(visible_cols.min()), int(max(0, math.floor(v.min() + 0.5))),
            int(visible_cols.max()), int(min(height - 1, math.floor(v.max() + 0.5))))
    return fraction, bbox


def _bearing(yaw: float, dx: float, dy: float) -> float:
    """The bearing (rad, CCW from the optical axis) of a world offset seen at ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    return math.atan2(-s * dx + c * dy, c * dx + s * dy)


def visible_signs(world: World, cam_pose, tilt: float, zoom: float,
                  spec: CameraSpec) -> list[dict[str, Any]]:
    """Ground truth: the sign plates the camera sees, as :func:`render` draws them.

    A plate is reported when it faces the camera, its centre is within
    ``spec.max_range`` (horizontal distance) and not behind a wall, none of
    its corners is behind the image plane, and some of it falls inside the
    image in front of the walls (a wall up to 0.15 m in front of the plate,
    along its normal, does not hide it: plates hang on walls).

    Parameters
    ----------
    world : World
    cam_pose : (x, y, yaw)
        Camera pose in the world (see :func:`camera_pose`).
    tilt : float
        Tilt (rad, positive up).
    zoom : float
        Zoom factor.
    spec : CameraSpec

    Returns
    -------
    list of dict, in ``world.signs`` order, with keys

    ``index`` (int)
        Position in ``world.signs``.
    ``text`` (str)
    ``bearing`` (float, rad)
        Direction of the plate's centre in the camera frame, CCW positive (left).
    ``distance`` (float, m)
        Horizontal distance from the camera to the plate's centre.
    ``depth`` (float, m)
        Forward depth of the plate's centre along the optical axis.
    ``viewing_angle`` (float, rad)
        Angle between the plate's normal and the line of sight (0 = head-on).
    ``bbox`` (tuple of int)
        ``(x0, y0, x1, y1)``: inclusive pixel box of the visible part.
    ``apparent_width``, ``apparent_height`` (float, px)
        Horizontal and vertical extent of the whole projected plate (unclipped).
    ``corners`` (ndarray (4, 2), px)
        Projected corners, top-left, top-right, bottom-right, bottom-left as
        seen from the front (unclipped).
    ``visible_fraction`` (float)
        Share of the plate inside the image and not hidden by walls (0..1].
    """
    return CameraRenderer(world, spec).visible_signs(cam_pose, tilt, zoom)


def _sign_reports(views: list[_PlateView]) -> list[dict[str, Any]]:
    """The plates seen, as :func:`visible_signs` reports them."""
    out = []
    for view in views:
        u, v = view.corners[:, 0], view.corners[:, 1]
        out.append({
            "index": view.index, "text": view.sign.text, "bearing": view.bearing,
            "distance": view.distance, "depth": view.depth,
            "viewing_angle": view.viewing_angle, "bbox": view.bbox,
            "apparent_width": float(u.max() - u.min()),
            "apparent_height": float(v.max() - v.min()),
            "corners": view.corners.copy(), "visible_fraction": view.visible_fraction,
        })
    return out


# ---- objects ----------------------------------------------------------------------------------
# World objects (``world.objects``: label, x, y) are drawn as upright billboards:
# the catalogue picture of their label (semantic/objects), at the catalogue's
# physical width x height, standing ``elevation`` above the floor (0: on it),
# centred on (x, y) and turned to face the camera (a sprite: the picture is
# perpendicular to the line of sight from the camera to the object). An object
# with a ``facing`` attribute that is not None (rad, like Sign.facing) faces
# that fixed direction instead and is not drawn from behind. Objects are
# visual only: they have no walls, so the sonar and the robot's physics do not
# see them; walls in front of them hide them column by column, as for plates.
# An object's optional ``scale`` multiplies the catalogue's width and height
# (not its elevation), ``light`` its brightness, and ``cover`` (0..0.8) puts a
# plain box of the billboard's width on the floor just in front of it, up to
# that fraction of the object's height: the box hides the picture's lower
# part, and the ground truth counts only the part above the box.
OBJECT_TOLERANCE = 0.02  # m (along the ray): a wall this close in front of a billboard still lets it show
COVER_BGR = (105, 115, 125)  # a covering box's colour before lighting: a grey-brown desk front
# (as large as a texture need be to keep its half-texel edges under a pixel)
_COVER_LEVELS = (np.full((256, 256, 3), COVER_BGR, dtype=np.uint8),)
_COVER_LEVELS[0].setflags(write=False)


@dataclass
class _ObjectView:
    index: int
    label: str
    bearing: float
    distance: float
    viewing_angle: float
    corners: np.ndarray  # (4, 2) px, unclipped: TL, TR, BR, BL as seen from the front
    depth: float  # forward depth of the centre (m)
    columns: np.ndarray  # (W,) bool: columns where the object is in front of the walls
    visible_fraction: float
    bbox: tuple[int, int, int, int] | None  # None: only the covering box shows
    image: Any  # path of the catalogue picture (the texture cache key)
    light: float = 1.0  # brightness factor
    box: np.ndarray | None = None  # (4, 2) px: the covering box's corners, if any


def _world_objects(world: World) -> list:
    """The world's objects; worlds from before objects existed have none."""
    return list(getattr(world, "objects", None) or [])


def _catalogue(catalogue: Any = None) -> Any:
    if catalogue is not None:
        return catalogue
    from semantic.objects import default_catalogue
    return default_catalogue()


def object_corners(x: float, y: float, facing: float, width: float, height: float,
                   elevation: float = 0.0) -> np.ndarray:
    """A billboard's corners (4, 3): top-left, top-right, bottom-right, bottom-left as seen
    by someone facing it (``facing`` is its outward normal, rad)."""
    tx, ty = -math.sin(facing), math.cos(facing)  # the front viewer's right
    hw = width / 2
    top, bottom = elevation + height, elevation
    return np.array([[x - tx * hw, y - ty * hw, top], [x + tx * hw, y + ty * hw, top],
                     [x + tx * hw, y + ty * hw, bottom], [x - tx * hw, y - ty * hw, bottom]])


@dataclass(frozen=True)
class _Objects:
    """A world's objects, fixed once: their catalogue entries, centres and reach."""

    objects: tuple[Any, ...]
    entries: tuple[Any, ...]  # catalogue entries of their labels
    xy: np.ndarray  # (N, 2) m: the centres
    reach: np.ndarray  # (N,) m: half the billboard's width at its scale

    @classmethod
    def of(cls, world: World, catalogue: Any = None) -> _Objects:
        objects = tuple(_world_objects(world))
        if not objects:
            return cls((), (), np.zeros((0, 2)), np.zeros(0))
        catalogue = _catalogue(catalogue)
        entries = tuple(catalogue.entry(obj.label) for obj in objects)
        xy = np.array([[float(obj.x), float(obj.y)] for obj in objects], dtype=np.float64)
        reach = np.array([entry.width * float(getattr(obj, "scale", 1.0)) / 2
                          for obj, entry in zip(objects, entries)], dtype=np.float64)
        return cls(objects, entries, xy, reach * (1 + 1e-9))


def _object_views(shot: _Shot, objects: _Objects, spec: CameraSpec,
                  may_show: np.ndarray | None = None) -> list[_ObjectView]:
    """Every object that is at least partly visible, with its projection and occlusion
    (of those ``may_show`` keeps, if given: :func:`_may_show` of the objects)."""
    if may_show is None:
        may_show = _may_show(objects.xy, objects.reach, shot, spec)
    views = []
    for i in np.flatnonzero(may_show).tolist():
        view = _object_view(i, objects.objects[i], objects.entries[i], shot, spec)
        if view is not None:
            views.append(view)
    return views


def _object_view(i: int, obj: Any, entry: Any, shot: _Shot,
                 spec: CameraSpec) -> _ObjectView | None:
    """Object ``i`` (its catalogue ``entry``) as the camera sees it; None when none of it shows."""
    px, py, yaw = shot.pose
    width, height = spec.width, spec.height
    ox, oy = float(obj.x), float(obj.y)
    distance = math.hypot(px - ox, py - oy)
    if distance <= 1e-9 or distance > spec.max_range:
        return None
    fixed = getattr(obj, "facing", None)
    facing = math.atan2(py - oy, px - ox) if fixed is None else float(fixed)
    normal = np.array([math.cos(facing), math.sin(facing)])
    cos_view = float(normal @ np.array([px - ox, py - oy])) / distance
    if cos_view <= 0:
        return None  # a fixed-facing object seen from behind or edge-on
    size = float(getattr(obj, "scale", 1.0))
    ow, oh = entry.width * size, entry.height * size
    corners3 = object_corners(ox, oy, facing, ow, oh, entry.elevation)
    u, v, depth = _project(corners3, shot, spec.mount_z)
    if depth.min() < NEAR:  # (as np.any(depth < NEAR), NaN included)
        return None
    if _off_image(u, v, width, height):
        return None
    columns = _columns_in_front(shot, u, ox, oy, facing, width,
                                lambda dx, dy: OBJECT_TOLERANCE)
    footprint = _footprint(u, v, columns, height)
    if footprint is None:
        return None
    fraction, bbox = footprint
    cover, box = float(getattr(obj, "cover", 0.0)), None
    if cover > 0:
        box_top = entry.elevation + cover * oh
        bu, bv, _ = _project(object_corners(ox, oy, facing, ow, box_top), shot, spec.mount_z)
        box = np.stack([bu, bv], axis=1)
        fraction, bbox = _uncovered_footprint(u, v, bv[:2], cover, columns, height)
    bearing = _bearing(yaw, ox - px, oy - py)
    return _ObjectView(
        index=i, label=obj.label, bearing=bearing, distance=distance,
        viewing_angle=math.acos(min(1.0, cos_view)), corners=np.stack([u, v], axis=1),
        depth=_forward_depth(ox, oy, shot.pose), columns=columns,
        visible_fraction=float(fraction),
        bbox=bbox, image=entry.image, light=float(getattr(obj, "light", 1.0)), box=box)


def _uncovered_footprint(u: np.ndarray, v: np.ndarray, v_cover: np.ndarray, cover: float,
                         columns: np.ndarray, height: int
                         ) -> tuple[float, tuple[int, int, int, int] | None]:
    """The visible fraction and pixel box of a billboard whose lower ``cover`` is hidden.

    ``u, v`` are the billboard's projected corners (TL, TR, BR, BL) and
    ``v_cover`` the image rows of the covering box's top corners (TL, TR); the
    visible part is the quad above them, and the fraction is of the whole
    billboard. Returns ``(0.0, None)`` when none of the part above the box shows.
    """
    v_up = np.array([v[0], v[1], v_cover[1], v_cover[0]])
    footprint = _footprint(u, v_up, columns, height)
    if footprint is None:
        return 0.0, None
    fraction, bbox = footprint
    return (1.0 - cover) * fraction, bbox


def visible_objects(world: World, cam_pose, tilt: float, zoom: float, spec: CameraSpec,
                    catalogue: Any = None) -> list[dict[str, Any]]:
    """Ground truth: the world's objects the camera sees, as :func:`render` draws them.

    An object is reported when its centre is within ``spec.max_range``
    (horizontal distance), none of its corners is behind the image plane, and
    some of it falls inside the image in front of the walls and above its
    covering box (an object's ``cover``, see the objects section above).

    Parameters
    ----------
    world : World
        ``world.objects`` (label, x, y) are the objects; a world without the
        attribute has none.
    cam_pose, tilt, zoom, spec
        As for :func:`render`.
    catalogue : semantic.objects.Catalogue, optional
        Pictures and sizes of the labels (default: the packaged catalogue).

    Returns
    -------
    list of dict, in ``world.objects`` order, with keys ``index``, ``label``,
    ``bearing`` (rad, CCW positive from the optical axis), ``distance`` (m,
    horizontal, camera to the object's centre), ``depth`` (m, forward),
    ``viewing_angle`` (rad, 0 for sprites), ``bbox`` (inclusive px box of the
    visible part, above any covering box), ``apparent_width`` and
    ``apparent_height`` (px, unclipped, of the whole object at its ``scale``),
    ``corners`` ((4, 2) px, TL TR BR BL, unclipped) and ``visible_fraction``
    (of the whole object; a cover of 0.5 halves it).
    """
    return CameraRenderer(world, spec, catalogue).visible_objects(cam_pose, tilt, zoom)


def _object_reports(views: list[_ObjectView]) -> list[dict[str, Any]]:
    """The objects seen, as :func:`visible_objects` reports them."""
    out = []
    for view in views:
        if view.bbox is None:  # only its covering box is in view
            continue
        u, v = view.corners[:, 0], view.corners[:, 1]
        out.append({
            "index": view.index, "label": view.label, "bearing": view.bearing,
            "distance": view.distance, "depth": view.depth,
            "viewing_angle": view.viewing_angle, "bbox": view.bbox,
            "apparent_width": float(u.max() - u.min()),
            "apparent_height": float(v.max() - v.min()),
            "corners": view.corners.copy(), "visible_fraction": view.visible_fraction,
        })
    return out


@functools.lru_cache(maxsize=64)
def _object_mipmaps(image_path: Any) -> tuple[np.ndarray, ...]:
    """A catalogue picture and its successive INTER_AREA halvings (for anti-aliased warping)."""
    base = cv2.imread(str(image_path), cv2.IMREAD_COLOR)
    if base is None:
        raise CameraError(f"cannot read the object picture {image_path}")
    base.setflags(write=False)
    levels = [base]
    while levels[-1].shape[1] > 16 and levels[-1].shape[0] > 16:
        prev = levels[-1]
        half = cv2.resize(prev, (max(1, prev.shape[1] // 2), max(1, prev.shape[0] // 2)),
                          interpolation=cv2.INTER_AREA)
        half.setflags(write=False)
        levels.append(half)
    return tuple(levels)


def _draw_object(img: np.ndarray, depth: np.ndarray, view: _ObjectView, spec: CameraSpec) -> None:
    """Warp an object's catalogue picture into ``img`` (in place), hidden behind walls, then
    its covering box, if any, in front of it."""
    shade = float(_light(np.array(view.depth))) * (0.75 + 0.25 * math.cos(view.viewing_angle))
    shade *= view.light
    _warp_texture(img, depth, _object_mipmaps(view.image), view.corners, view.columns, shade,
                  view.depth, spec)
    if view.box is not None:
        _warp_texture(img, depth, _COVER_LEVELS, view.box, view.columns, shade, view.depth, spec)


# ---- rendering -----------------------------------------------------------------------------
def _light(depth: np.ndarray) -> np.ndarray:
    """Fall-off of the scene's brightness with distance (1 at the camera)."""
    return 1.0 / (1.0 + 0.045 * depth)


def render(world: World, cam_pose, tilt: float, zoom: float, spec: CameraSpec,
           rng: np.random.Generator, catalogue: Any = None) -> np.ndarray:
    """Render the camera image.

    Parameters
    ----------
    world : World
        Walls (capsules), sign plates (each in its colours, font and letter
        spacing), objects, and ``colours`` (optional: the building's wall,
        floor, ceiling and skirting colours in place of the defaults).
    cam_pose : (x, y, yaw)
        Camera pose in the world (m, m, rad); see :func:`camera_pose`.
    tilt : float
        Tilt (rad, positive up).
    zoom : float
        Zoom factor (> 0); the horizontal field of view is
        ``2 * atan(tan(hfov / 2) / zoom)``.
    spec : CameraSpec
    rng : numpy.random.Generator or sim2d.noise.NoiseAhead
        Source of the image noise; the image is a deterministic function of
        the scene and the generator's state (the same with a ``NoiseAhead``
        over it, which draws the noise a frame ahead on a thread).
    catalogue : semantic.objects.Catalogue, optional
        Pictures and sizes of the world's objects (default: the packaged
        catalogue; only loaded when the world has objects).

    Returns
    -------
    ndarray (height, width, 3) uint8
        BGR image: floor, walls (shaded by distance and by their angle to the
        ray, with a dark skirting board) and ceiling, sign plates and
        objects (billboards, see ``_object_views``), then a
        depth-dependent Gaussian blur (sigma ``blur_per_m * depth / zoom``)
        and Gaussian noise (``noise_std``).
    """
    return CameraRenderer(world, spec, catalogue).render(cam_pose, tilt, zoom, rng)


@dataclass(frozen=True)
class CameraFrame:
    """One frame of :meth:`CameraRenderer.frame`: the image and the ground truth of it.

    Attributes
    ----------
    image : ndarray (height, width, 3) uint8
        As :func:`render` draws it.
    signs : list of dict
        As :func:`visible_signs` reports them.
    objects : list of dict
        As :func:`visible_objects` reports them.
    """

    image: np.ndarray
    signs: list[dict[str, Any]]
    objects: list[dict[str, Any]]


class CameraRenderer:
    """One camera in one world, frame after frame: :func:`render`, :func:`visible_signs`
    and :func:`visible_objects` sharing what does not change.

    Made once per world, it keeps the walls indexed for ray casting, the
    plates' corners, the objects' catalogue entries and the world's palette;
    it keeps the per-column and per-row tables of the last tilt and zoom; and
    :meth:`frame` casts one set of rays for the image and both ground truths.
    Its results are those of the three functions, bit for bit. The world must
    not change while a renderer draws it, and one renderer draws for one
    thread (it draws into its own work arrays).

    Parameters
    ----------
    world : World
    spec : CameraSpec
    catalogue : semantic.objects.Catalogue, optional
        Pictures and sizes of the world's objects (default: the packaged
        catalogue; only loaded when the world has objects).

    Examples
    --------
    >>> from sim2d.world import make_world
    >>> box = make_world([[0, -2, 4, -2], [4, -2, 4, 2], [4, 2, 0, 2], [0, 2, 0, -2]])
    >>> renderer = CameraRenderer(box, CameraSpec())
    >>> frame = renderer.frame((1.0, 0.0, 0.0), 0.0, 1.0, np.random.default_rng(0))
    >>> frame.image.shape, frame.signs, frame.objects
    ((240, 320, 3), [], [])
    """

    def __init__(self, world: World, spec: CameraSpec, catalogue: Any = None) -> None:
        self.world, self.spec = world, spec
        self._catalogue = catalogue
        self._walls = Walls(world.segments)
        self._plates = _Plates.of(world)
        self._objects: _Objects | None = None  # at the first look (it may load the catalogue)
        self._things: tuple[np.ndarray, np.ndarray] | None = None  # plates' then objects'
        # centres and reach, for _views
        self._palette = _palette(getattr(world, "colours", None))
        self._lens: _Lens | None = None  # of the last tilt and zoom
        self._backdrop: _Backdrop | None = None  # of that lens
        self._canvas: _Canvas | None = None  # at the first image

    def frame(self, cam_pose, tilt: float, zoom: float,
              rng: np.random.Generator | NoiseAhead) -> CameraFrame:
        """The image and the signs and objects in view, from one ray cast (see :func:`render`).

        ``rng`` may be a :class:`sim2d.noise.NoiseAhead` over the generator: the
        same image, with its noise drawn ahead on a thread.
        """
        shot = self._shot(cam_pose, tilt, zoom)
        plates, objects = self._views(shot)
        image = self._image(shot, plates, objects, rng)
        return CameraFrame(image, _sign_reports(plates), _object_reports(objects))

    def render(self, cam_pose, tilt: float, zoom: float,
               rng: np.random.Generator | NoiseAhead) -> np.ndarray:
        """The image alone: :func:`render`."""
        shot = self._shot(cam_pose, tilt, zoom)
        return self._image(shot, *self._views(shot), rng)

    def visible_signs(self, cam_pose, tilt: float, zoom: float) -> list[dict[str, Any]]:
        """The plates in view: :func:`visible_signs`."""
        return _sign_reports(self._plate_views(self._shot(cam_pose, tilt, zoom)))

    def visible_objects(self, cam_pose, tilt: float, zoom: float) -> list[dict[str, Any]]:
        """The objects in view: :func:`visible_objects`."""
        if not _world_objects(self.world):
            return []
        return _object_reports(self._object_views(self._shot(cam_pose, tilt, zoom)))

    def _shot(self, cam_pose, tilt: float, zoom: float) -> _Shot:
        px, py, yaw = (float(v) for v in cam_pose)
        lens = self._lens
        if lens is None or lens.tilt != tilt or lens.zoom != zoom:
            lens = self._lens = _Lens.of(self.spec, tilt, zoom)
            self._backdrop = _Backdrop.of(lens, self._palette, self.spec.width)
        wall_t, incidence = self._walls.cast((px, py), yaw + lens.angles)
        return _Shot((px, py, yaw), tilt, zoom, lens, wall_t, incidence)

    def _plate_views(self, shot: _Shot) -> list[_PlateView]:
        return _plate_views(shot, self._plates, self._walls, self.spec)

    def _views(self, shot: _Shot) -> tuple[list[_PlateView], list[_ObjectView]]:
        """The plates and the objects in view, the candidates of both picked in one
        :func:`_may_show` (the same tests, thing by thing, in half the numpy calls)."""
        if not _world_objects(self.world):
            return self._plate_views(shot), []
        objects = self._loaded_objects()
        may_show = _may_show(*self._things, shot, self.spec)
        n = len(self._plates.signs)
        return (_plate_views(shot, self._plates, self._walls, self.spec, may_show[:n]),
                _object_views(shot, objects, self.spec, may_show[n:]))

    def _loaded_objects(self) -> _Objects:
        """The world's objects (loaded at the first look: it may load the catalogue)."""
        if self._objects is None:
            self._objects = _Objects.of(self.world, self._catalogue)
            self._things = (np.concatenate((self._plates.xy, self._objects.xy)),
                            np.concatenate((self._plates.reach, self._objects.reach)))
        return self._objects

    def _object_views(self, shot: _Shot) -> list[_ObjectView]:
        if not _world_objects(self.world):
            return []
        return _object_views(shot, self._loaded_objects(), self.spec)

    def _image(self, shot: _Shot, plates: list[_PlateView], objects: list[_ObjectView],
               rng: np.random.Generator | NoiseAhead) -> np.ndarray:
        spec, f32 = self.spec, np.float32
        if self._canvas is None:
            self._canvas = _Canvas(spec.height, spec.width)
        canvas = self._canvas
        img, depth = _scene(shot, spec, self._palette, self._backdrop, canvas)
        # sign plates and objects, far to near
        views: list = [*plates, *objects]
        for view in sorted(views, key=lambda vw: -vw.depth):
            if isinstance(view, _ObjectView):
                _draw_object(img, depth, view, spec)
            else:
                _draw_plate(img, depth, view, spec)
        # range-dependent blur (the depths, no longer needed, become the sigmas), then noise
        sigma = np.minimum(depth, canvas.far, out=depth)  # (1e3 m)
        sigma *= f32(spec.blur_per_m)
        sigma /= f32(shot.zoom)
        img = _depth_blur(img, sigma, canvas)
        if spec.noise_std > 0:
            if isinstance(rng, NoiseAhead):
                noise = rng.field(img.shape, spec.noise_std)
            else:
                spare = canvas.spare[0] if img is canvas.spare[1] else canvas.spare[1]
                noise = gaussian_noise(img.shape, spec.noise_std, rng, out=spare)
            # the float32 sum, rounded half to even and saturated, as np.rint and np.clip do
            return cv2.add(img, noise, dtype=cv2.CV_8U)
        return np.clip(np.rint(img, out=img), 0, 255, out=img).astype(np.uint8)


@dataclass(frozen=True)
class _Lens:
    """What a tilt and zoom fix: the intrinsics, the columns' ray angles, and the floor's
    and ceiling's depth and light per image row."""

    tilt: float
    zoom: float
    f: float  # px
    cx: float
    cy: float
    angles: np.ndarray  # (W,) rad: the columns' rays (camera frame, CCW +)
    cos_a: np.ndarray  # (W,) their cosines
    rows: np.ndarray  # (H, 1) float32: the row numbers
    r0: int  # the first floor row (under the horizon)
    floor_d: np.ndarray  # (H - r0, 1) float32 m: the floor's depth per row
    lateral: np.ndarray  # (H - r0, W) float32 m: leftward offset of each floor pixel
    floor_light: np.ndarray  # (H - r0, 2) float32: the floor's shade on even, odd tiles
    r1: int  # the rows above the ceiling's horizon
    ceil_d: np.ndarray  # (r1, 1) float32 m: the ceiling's depth per row
    ceil_shade: np.ndarray  # (r1, 1) float32

    @classmethod
    def of(cls, spec: CameraSpec, tilt: float, zoom: float) -> _Lens:
        W, H = spec.width, spec.height
        f, cx, cy = _intrinsics(spec, tilt, zoom)
        cam_z = spec.mount_z
        angles = _column_angles(spec, f)
        f32 = np.float32
        rows = np.arange(H, dtype=f32)[:, None]  # (H, 1)
        # floor (rows under the horizon): depth per row; the checker tiles scale it by 1 +- ripple
        r0 = min(H, max(0, math.floor(cy) + 1))
        floor_d = (f * cam_z / np.maximum(rows[r0:] - f32(cy), f32(1e-3))).astype(f32)  # (h, 1)
        floor_d = np.minimum(floor_d, f32(1e3))
        lateral = floor_d * ((cx - np.arange(W, dtype=f32)) / f32(f))[None, :]  # (h, W)
        ripple = f32(0.07) * np.exp(-floor_d / f32(4))
        floor_light = np.hstack([_light(floor_d) * (f32(1) + ripple * f32(checker))
                                 for checker in (-1, 1)])
        # ceiling (rows over the horizon)
        r1 = min(H, max(0, math.ceil(cy)))
        ceil_d = (f * (spec.wall_height - cam_z) / np.maximum(f32(cy) - rows[:r1], f32(1e-3)))
        ceil_d = np.minimum(ceil_d.astype(f32), f32(1e3))
        return cls(tilt, zoom, f, cx, cy, angles, np.cos(angles), rows, r0, floor_d, lateral,
                   floor_light, r1, ceil_d, f32(0.95) * _light(ceil_d))


@dataclass(frozen=True)
class _Shot:
    """One camera pose's rays: what the image and the ground truths share."""

    pose: tuple[float, float, float]  # x, y, yaw of the camera (m, m, rad)
    tilt: float
    zoom: float
    lens: _Lens
    wall_t: np.ndarray  # (W,) m: along each column's ray to the first wall (inf: none)
    incidence: np.ndarray  # (W,): |cos| of the ray to the wall's normal there


class _Canvas:
    """Work arrays for images of one size, drawn into frame after frame.

    A fresh image-sized array costs more in page faults (the allocator maps
    and unmaps such blocks) than the arithmetic done on it.
    """

    def __init__(self, height: int, width: int) -> None:
        f32, size = np.float32, (height, width)
        self.depth, self.frac, self.keep = (np.empty(size, f32) for _ in range(3))
        self.img = np.empty((*size, 3), f32)
        # the blurs (each blended in place with the last) and then the noise take turns
        self.spare = (np.empty((*size, 3), f32), np.empty((*size, 3), f32))
        self.half = np.empty((height // 2, width // 2, 3), f32)
        self.small = np.empty((height // 2, width // 2, 3), f32)
        # the depth and sigma caps as whole frames: numpy's float32 minimum is four times
        # as fast against an array as against a scalar (the same values)
        self.far = np.full(size, 1e3, f32)
        self.sigma_cap = np.full(size, BLUR_LEVELS[-1], f32)


@dataclass(frozen=True)
class _Backdrop:
    """The floor's and ceiling's colours and depths for one lens and palette, as whole
    images of the rows they can reach (the floor's on dark and on bright tiles)."""

    floor_dark: np.ndarray  # (H - r0, W, 3) float32 BGR
    floor_bright: np.ndarray  # (H - r0, W, 3)
    floor_depth: np.ndarray  # (H - r0, W) float32 m
    ceiling: np.ndarray  # (r1, W, 3)
    ceiling_depth: np.ndarray  # (r1, W)

    @classmethod
    def of(cls, lens: _Lens, palette: np.ndarray, width: int) -> _Backdrop:
        floor_bgr, ceiling_bgr = palette[0], palette[1]

        def spread(column: np.ndarray) -> np.ndarray:  # (n, ...) -> (n, W, ...), row by row
            return np.ascontiguousarray(np.repeat(column[:, None], width, axis=1))

        return cls(spread(lens.floor_light[:, 0:1] * floor_bgr),
                   spread(lens.floor_light[:, 1:2] * floor_bgr),
                   spread(lens.floor_d[:, 0]), spread(lens.ceil_shade * ceiling_bgr),
                   spread(lens.ceil_d[:, 0]))


def _scene(shot: _Shot, spec: CameraSpec, palette: np.ndarray, backdrop: _Backdrop,
           canvas: _Canvas) -> tuple[np.ndarray, np.ndarray]:
    """The lit walls, floor and ceiling (float32 BGR) and their forward depth (m) per pixel,
    drawn into ``canvas``.

    Walls take a depth per column, shaded by their angle to the ray and by
    distance, with a dark skirting board; the floor a depth per row and a
    faint checker in world coordinates; the ceiling a depth per row. A
    pixel is its class's colour in ``palette`` (floor, ceiling, wall,
    skirting) times its shade; ``backdrop`` has the floor's and ceiling's.
    """
    lens = shot.lens
    H = spec.height
    f, cy = lens.f, lens.cy
    px, py, yaw = shot.pose
    cam_z = spec.mount_z
    wall_d = shot.wall_t * lens.cos_a  # forward depth per column
    hit = np.isfinite(wall_d)
    safe_d = np.where(hit, wall_d, 1.0)
    v_top = np.where(hit, cy - f * (spec.wall_height - cam_z) / safe_d, cy)  # (W,)
    v_bot = np.where(hit, cy + f * cam_z / safe_d, cy)

    # the floor lies under the horizon (rows from r0), the ceiling over it (rows to r1),
    # and so does the skirting board unless the camera is lower than its top
    f32 = np.float32
    rows, r0, r1 = lens.rows, lens.r0, lens.r1
    low = r0 if cam_z >= SKIRTING_HEIGHT else 0
    is_floor = rows[low:] > v_bot.astype(f32)[None, :]  # (H - low, W)
    is_ceiling = rows[:r1] < v_top.astype(f32)[None, :]  # (r1, W)
    v_skirt = np.where(hit, cy + f * (cam_z - SKIRTING_HEIGHT) / safe_d, np.inf).astype(f32)
    is_skirting = (rows[low:] > v_skirt[None, :]) & ~is_floor
    on_floor = is_floor[r0 - low:]  # (H - r0, W)

    # walls: depth per column, shaded by their angle to the ray and by distance;
    # then (later ones win) the skirting board, the floor and the ceiling
    far = np.where(hit, wall_d, 1e3)
    wall_shade = ((0.4 + 0.6 * shot.incidence) * _light(far)).astype(f32)[:, None]  # (W, 1)
    img, depth = canvas.img, canvas.depth
    np.copyto(img, (wall_shade * palette[2])[None])
    depth[:] = far.astype(f32)[None, :]
    if low < H:
        skirting = canvas.spare[0][low:]  # free until the blur
        np.copyto(skirting, (wall_shade * palette[3])[None])
        cv2.copyTo(skirting, is_skirting.view(np.uint8), img[low:])
    if r0 < H:  # a faint checker in world coordinates
        floor_d, lateral = lens.floor_d, lens.lateral
        c, s = math.cos(yaw), math.sin(yaw)
        fx = (f32(px / FLOOR_TILE) + floor_d * f32(c / FLOOR_TILE) - lateral * f32(s / FLOOR_TILE))
        fy = (f32(py / FLOOR_TILE) + floor_d * f32(s / FLOOR_TILE) + lateral * f32(c / FLOOR_TILE))
        # whole tiles (exact in float32 here), odd sums on the bright tiles
        odd = (np.floor(fx).astype(np.int32) + np.floor(fy).astype(np.int32)) & 1
        floor_mask = on_floor.view(np.uint8)
        cv2.copyTo(backdrop.floor_dark, floor_mask, img[r0:])
        cv2.copyTo(backdrop.floor_bright, (on_floor & odd.astype(bool)).view(np.uint8), img[r0:])
        cv2.copyTo(backdrop.floor_depth, floor_mask, depth[r0:])
    if r1 > 0:
        ceiling_mask = is_ceiling.view(np.uint8)
        cv2.copyTo(backdrop.ceiling, ceiling_mask, img[:r1])
        cv2.copyTo(backdrop.ceiling_depth, ceiling_mask, depth[:r1])
    return img, depth


def _palette(colours: Mapping[str, Any] | None) -> np.ndarray:
    """The scene's colours by pixel class (4, 3) BGR: ``_PALETTE`` with a world's overrides.

    ``colours`` maps ``wall``, ``floor``, ``ceiling`` and ``skirting`` to RGB
    0-255 (``World.colours``); unknown keys are ignored, and without any the
    default palette itself is returned.
    """
    if not colours:
        return _PALETTE
    palette = _PALETTE.copy()
    for key, row in _PALETTE_ROWS.items():
        if key in colours:
            palette[row] = _bgr(colours[key])
    return palette


def _draw_plate(img: np.ndarray, depth: np.ndarray, view: _PlateView, spec: CameraSpec) -> None:
    """Warp a plate's texture into ``img`` (in place), hidden where walls are in front."""
    sign = view.sign
    tex_h = max(8, round(TEXTURE_WIDTH * sign.height / sign.width))
    style = (tuple(sign.plate), tuple(sign.ink), sign.font, float(sign.spacing))
    levels = _plate_mipmaps(sign.text, TEXTURE_WIDTH, tex_h, style)
    shade = float(_light(np.array(view.depth))) * (0.75 + 0.25 * math.cos(view.viewing_angle))
    _warp_texture(img, depth, levels, view.corners, view.columns, shade, view.depth, spec)


def _warp_texture(img: np.ndarray, depth: np.ndarray, levels: tuple[np.ndarray, ...],
                  corners: np.ndarray, columns: np.ndarray, shade: float, depth_value: float,
                  spec: CameraSpec) -> None:
    """Warp a mipmapped texture onto an image quad (in place), only in the ``columns`` given.

    ``corners`` (4, 2) px are top-left, top-right, bottom-right, bottom-left;
    the quad's pixels take the forward depth ``depth_value`` in ``depth``
    (for the blur).
    """
    corners = corners.astype(np.float64)
    edge = max(np.hypot(*(corners[1] - corners[0])), np.hypot(*(corners[2] - corners[3])))
    tex = levels[0]
    for level in levels:  # the smallest level still at least 1.5x the apparent size
        if level.shape[1] >= 1.5 * edge:
            tex = level
    th, tw = tex.shape[:2]
    src = np.array([[-0.5, -0.5], [tw - 0.5, -0.5], [tw - 0.5, th - 0.5], [-0.5, th - 0.5]],
                   dtype=np.float32)
    M = cv2.getPerspectiveTransform(src, corners.astype(np.float32))
    # warp only the quad's bounding box (plus a margin) to keep it cheap
    W, H = spec.width, spec.height
    x0 = max(0, math.floor(corners[:, 0].min()) - 1)
    x1 = min(W, math.ceil(corners[:, 0].max()) + 2)
    y0 = max(0, math.floor(corners[:, 1].min()) - 1)
    y1 = min(H, math.ceil(corners[:, 1].max()) + 2)
    if x1 <= x0 or y1 <= y0:
        return
    shift = np.array([[1, 0, -x0], [0, 1, -y0], [0, 0, 1]], dtype=np.float64)
    M = shift @ M
    size = (x1 - x0, y1 - y0)
    plate = cv2.warpPerspective(tex, M, size, flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0))
    mask = cv2.warpPerspective(_opaque(th, tw), M, size, flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    alpha = mask.astype(np.float32) / 255.0 * columns[None, x0:x1]
    region = img[y0:y1, x0:x1]
    # alpha in each channel: numpy's loops run along whole rows, not three values at a time
    a = cv2.merge((alpha, alpha, alpha))
    region *= np.subtract(1.0, a, dtype=np.float32)
    shaded = np.multiply(a, plate, out=a)  # float32, as a * plate.astype(np.float32)
    shaded *= np.float32(shade)
    region += shaded
    depth[y0:y1, x0:x1] = np.where(alpha > 0.5, np.float32(depth_value), depth[y0:y1, x0:x1])


@functools.lru_cache(maxsize=64)
def _opaque(height: int, width: int) -> np.ndarray:
    """A read-only all-255 mask of a texture's size (the coverage :func:`_warp_texture` warps)."""
    mask = np.full((height, width), 255, np.uint8)
    mask.setflags(write=False)
    return mask


def _depth_blur(img: np.ndarray, sigma: np.ndarray, canvas: _Canvas) -> np.ndarray:
    """Blur each pixel with its own sigma (px), interpolating between a few fixed-sigma blurs.

    Sigmas are capped at the last of ``BLUR_LEVELS``; the larger blurs run at
    half resolution (they keep no detail a full-resolution blur would).
    ``sigma`` is capped in place; the result is one of ``canvas.spare`` (or
    ``img`` itself if no pixel needs blurring).

    Each blur is blended in with weight ``frac`` (0 up to the level below,
    1 from its own level), so it is only needed in the box of pixels whose
    sigma passes the level below (:func:`_blur_boxes`): the blur runs on that
    box and its kernel's margin, and the blend on that box. Outside the box
    ``cv2.blendLinear`` with weights 1 and 0 divides by ``1 + 1e-5``, which is
    done there directly, so the image is the same to the bit as blurring the
    whole frame at every level (most frames need the larger blurs only around
    the horizon, a third of the frame or less).
    """
    f32 = np.float32
    sigma = np.minimum(sigma, canvas.sigma_cap, out=sigma)  # BLUR_LEVELS[-1]
    boxes, boxed = _blur_boxes(sigma)
    out = img
    half_box = None  # the part of canvas.half made so far
    for k, box in enumerate(boxes, start=1):
        level, lo = BLUR_LEVELS[k], BLUR_LEVELS[k - 1]
        dst = canvas.spare[k % 2]  # not out, which is the other one (or img)
        r0, r1, c0, c1 = box
        if level >= 1.6:
            if half_box is None:  # the union of what the half-resolution levels need
                half_box = _union([_half_source(b, BLUR_LEVELS[j + 1], img.shape, boxed)
                                   for j, b in enumerate(boxes) if BLUR_LEVELS[j + 1] >= 1.6])
                a0, a1, b0, b1 = half_box
                source = img[2 * a0:2 * a1, 2 * b0:2 * b1] if boxed else img
                cv2.resize(source, (b1 - b0, a1 - a0), dst=canvas.half[a0:a1, b0:b1],
                           interpolation=cv2.INTER_AREA)
            blurred = _half_blur(level, box, canvas, dst, boxed)
        else:
            blurred = _box_blur(img, level, box, dst)
        # piecewise-linear in sigma: pixels past this level take it whole
        frac = canvas.frac[r0:r1, c0:c1]
        if lo:
            np.subtract(sigma[r0:r1, c0:c1], f32(lo), out=frac)
            frac *= f32(1.0 / (level - lo))
        else:  # sigma - 0 is sigma, to the bit
            np.multiply(sigma[r0:r1, c0:c1], f32(1.0 / (level - lo)), out=frac)
        np.clip(frac, 0, 1, out=frac)
        keep = np.subtract(f32(1), frac, out=canvas.keep[r0:r1, c0:c1])
        cv2.blendLinear(out[r0:r1, c0:c1], blurred, keep, frac, dst=blurred)  # in place
        for part in _outside(box, img.shape):  # frac 0: what blendLinear gives there
            np.divide(out[part], _BLEND_DEN, out=dst[part])
        out = dst
    return out


_BLEND_DEN = np.float32(1) + np.float32(1e-5)  # cv2.blendLinear's divisor for weights 1, 0
_BLUR_ALIGN = 16  # px: box columns start and end on multiples of this (see _blur_boxes)


def _blur_boxes(sigma: np.ndarray) -> tuple[list[tuple[int, int, int, int]], bool]:
    """The box ``(r0, r1, c0, c1)`` of pixels each level of ``BLUR_LEVELS`` blends into
    (those whose ``sigma`` passes the level below), up to the first level no sigma passes;
    and whether the frame is boxed at all.

    The columns are widened to multiples of ``_BLUR_ALIGN`` px, so OpenCV
    runs the same vector code on a box as on the whole frame (no scalar tail
    loops where the frame had none); frames whose width is not such a
    multiple, or whose height or width is odd (the half-resolution levels
    scale by exactly 2), blend every level over the whole frame.
    """
    H, W = sigma.shape
    peak = float(sigma.max())
    top = next((k for k, level in enumerate(BLUR_LEVELS) if level >= peak),
               len(BLUR_LEVELS) - 1)
    boxed = W % (2 * _BLUR_ALIGN) == 0 and H % 2 == 0
    boxes = [(0, H, 0, W)] * top  # the first level's box is (nearly) always the whole frame
    if boxed and top > 1:
        # as int32 (twice as fast): the same order as the floats' past any lo > 0
        bits = sigma.view(np.int32)
        row_max = bits.max(axis=1).view(np.float32)
        col_max = bits.max(axis=0).view(np.float32)
        for k in range(2, top + 1):
            lo = BLUR_LEVELS[k - 1]
            rows, cols = np.flatnonzero(row_max > lo), np.flatnonzero(col_max > lo)
            c0 = int(cols[0]) // _BLUR_ALIGN * _BLUR_ALIGN
            c1 = min(W, -(-(int(cols[-1]) + 1) // _BLUR_ALIGN) * _BLUR_ALIGN)
            boxes[k - 1] = (int(rows[0]), int(rows[-1]) + 1, c0, c1)
    return boxes, boxed


def _outside(box: tuple[int, int, int, int], shape: tuple[int, ...]) -> list[tuple[slice, slice]]:
    """The parts of a frame of ``shape`` outside ``box`` (up to four bands), as index pairs."""
    r0, r1, c0, c1 = box
    H, W = shape[:2]
    parts = [(slice(0, r0), slice(0, W)), (slice(r1, H), slice(0, W)),
             (slice(r0, r1), slice(0, c0)), (slice(r0, r1), slice(c1, W))]
    return [part for part in parts if part[0].start < part[0].stop and part[1].start < part[1].stop]


def _grow(box: tuple[int, int, int, int], margin: int, shape: tuple[int, ...],
          align: int = 1) -> tuple[int, int, int, int]:
    """``box`` widened by ``margin`` on each side within ``shape``, its columns to multiples
    of ``align``."""
    r0, r1, c0, c1 = box
    H, W = shape[:2]
    c0 = max(0, c0 - margin) // align * align
    c1 = min(W, -(-(c1 + margin) // align) * align)
    return max(0, r0 - margin), min(H, r1 + margin), c0, c1


def _union(boxes: list[tuple[int, int, int, int]]) -> tuple[int, int, int, int]:
    return (min(b[0] for b in boxes), max(b[1] for b in boxes),
            min(b[2] for b in boxes), max(b[3] for b in boxes))


def _kernel_radius(sigma: float) -> int:
    """Half the size of :func:`_gaussian_blur`'s kernel (px)."""
    return (int(np.rint(8 * sigma + 1)) | 1) // 2


def _box_blur(img: np.ndarray, sigma: float, box: tuple[int, int, int, int],
              dst: np.ndarray) -> np.ndarray:
    """The full-resolution blur of ``img`` inside ``box`` (``dst``'s box, returned), as the
    whole frame's blur has it there: the box and the kernel's margin around it are blurred
    into ``dst`` (the margin's own pixels, reflected at the frame's edges only, are not)."""
    r0, r1, c0, c1 = box
    g0, g1, h0, h1 = _grow(box, _kernel_radius(sigma), img.shape, _BLUR_ALIGN)
    _gaussian_blur(img[g0:g1, h0:h1], sigma, dst[g0:g1, h0:h1])
    return dst[r0:r1, c0:c1]


def _half_source(box: tuple[int, int, int, int], level: float, shape: tuple[int, ...],
                 boxed: bool = True) -> tuple[int, int, int, int]:
    """The half-resolution pixels a half-resolution blur at ``level`` needs for ``box``
    (full resolution): those the upsampling reads, and the kernel's margin round them
    (all of them in a frame that is not boxed)."""
    if not boxed:
        return 0, shape[0] // 2, 0, shape[1] // 2
    up = _half_up(box, shape)
    return _grow(up, _kernel_radius(_half_sigma(level)), (shape[0] // 2, shape[1] // 2),
                 _BLUR_ALIGN)


def _half_up(box: tuple[int, int, int, int], shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """The half-resolution pixels a 2x INTER_LINEAR upsampling reads for ``box``: full
    row ``y`` reads half rows ``y // 2 - 1`` to ``y // 2 + 1`` (so do columns)."""
    r0, r1, c0, c1 = box
    return _grow((r0 // 2, (r1 - 1) // 2 + 1, c0 // 2, (c1 - 1) // 2 + 1), 1,
                 (shape[0] // 2, shape[1] // 2), _BLUR_ALIGN)


def _half_sigma(level: float) -> float:
    """The half-resolution sigma of a blur of ``level`` px (full resolution): the 2x2 box
    average already blurred by ~0.5 px."""
    return math.sqrt(level ** 2 - 0.25) / 2


def _half_blur(level: float, box: tuple[int, int, int, int], canvas: _Canvas,
               dst: np.ndarray, boxed: bool = True) -> np.ndarray:
    """The half-resolution blur at ``level`` inside ``box`` (full resolution: ``dst``'s box,
    returned), from ``canvas.half`` (the frame's 2x2 averages, made where
    :func:`_half_source` says): blurred, then upsampled by INTER_LINEAR into ``dst`` round
    the box, as the whole frame's would be there (the whole frame, in a frame that is not
    boxed)."""
    full = dst.shape
    if not boxed:
        small = _gaussian_blur(canvas.half, _half_sigma(level), canvas.small)
        return cv2.resize(small, (full[1], full[0]), dst=dst, interpolation=cv2.INTER_LINEAR)
    u0, u1, v0, v1 = up = _half_up(box, full)
    g0, g1, h0, h1 = _grow(up, _kernel_radius(_half_sigma(level)), canvas.half.shape,
                           _BLUR_ALIGN)
    small = _gaussian_blur(canvas.half[g0:g1, h0:h1], _half_sigma(level),
                           _work_view(canvas.small, (g1 - g0, h1 - h0, 3)))
    cv2.resize(small[u0 - g0:u1 - g0, v0 - h0:v1 - h0], (2 * (v1 - v0), 2 * (u1 - u0)),
               dst=dst[2 * u0:2 * u1, 2 * v0:2 * v1], interpolation=cv2.INTER_LINEAR)
    r0, r1, c0, c1 = box
    return dst[r0:r1, c0:c1]


def _work_view(buffer: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """A C-contiguous array of ``shape`` over the start of ``buffer`` (no allocation)."""
    return buffer.reshape(-1)[:math.prod(shape)].reshape(shape)


def _gaussian_blur(img: np.ndarray, sigma: float, dst: np.ndarray | None = None) -> np.ndarray:
    """``cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)`` of a float32
    image, pixel for pixel, as the separable filter it is made of (into ``dst`` if given).

    OpenCV sizes a float image's kernel ``cvRound(8 sigma + 1) | 1`` and filters
    with ``getGaussianKernel`` rows and columns; calling ``sepFilter2D`` with that
    kernel skips GaussianBlur's own checks and dispatch (a fifth to a quarter of
    its time on a camera frame).
    """
    size = int(np.rint(8 * sigma + 1)) | 1
    kernel = cv2.getGaussianKernel(size, sigma, cv2.CV_32F)
    return cv2.sepFilter2D(img, -1, kernel, kernel, dst=dst, borderType=cv2.BORDER_REFLECT)
