"""Where is the plate? Its position and facing from the corners of its image.

A sign plate is a rectangle of known size hanging vertically on a wall. In
the pinhole model of :class:`~blocks.signs.types.CameraModel` (no roll, tilt
as a principal-point shift) a vertical segment of height ``H`` at forward
depth ``x`` projects to a vertical segment ``f * H / x`` pixels tall, whatever
the tilt. So each of the plate's two vertical edges (TL-BL and TR-BR in image
order) gives a point on the floor plan:

``x_i = f * H / h_i``,  ``y_i = x_i * (cx - u_i) / f``

(camera frame: x forward, y left). The plate's centre is their mean and its
outward normal the perpendicular of the line through them that points at the
camera. That is :func:`plate_from_edges`.

The edge heights are only a few tens of pixels at a few metres, so one pixel
of noise moves an edge's depth by several per cent, and the *difference* of the
two depths (which gives the facing) is very noisy. The edges' bearings
(``u_i``) are much better measured, and the plate's width is known too: the
default estimate (:func:`estimate_plate`, ``plate_width`` given) fits the
plate's centre and facing to all four measurements (two bearings, two heights)
by Gauss-Newton with the width held fixed, starting from the closed form.

A plate cut by the image border has one edge that is not its edge. The
quad's side on the border still marks a vertical line *on* the plate (the
image border column), so its height still gives a point on the plate's line:
the whole edge plus that point give the plate's direction, and the centre is
half a plate width from the whole edge along it.

Everything here is pure numpy and knows nothing of sim2d, so the same code
serves a real camera calibrated into a :class:`CameraModel`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .types import PLATE_HEIGHT, PLATE_WIDTH, CameraModel

__all__ = [
    "PlateEstimate",
    "camera_pose_of",
    "compose",
    "estimate_plate",
    "plate_from_edges",
    "plate_in_camera",
    "plate_in_world",
    "relative",
    "wrap",
]

BORDER_MARGIN = 1.0  # px: a quad corner this close to (or beyond) the image border is clipped
MIN_HEIGHT_PX = 2.0  # px: a shorter edge gives no usable depth


def wrap(a: float) -> float:
    """An angle in (-pi, pi]."""
    a = math.remainder(float(a), 2 * math.pi)
    return math.pi if a == -math.pi else a


def compose(pose, rel) -> tuple[float, float, float]:
    """``pose`` (x, y, yaw) followed by ``rel`` (x, y, yaw) in its frame: the world pose of ``rel``."""
    x, y, th = (float(v) for v in pose[:3])
    rx, ry, rth = (float(v) for v in rel[:3])
    c, s = math.cos(th), math.sin(th)
    return x + c * rx - s * ry, y + s * rx + c * ry, wrap(th + rth)


def relative(pose, world) -> tuple[float, float, float]:
    """The inverse of :func:`compose`: ``world`` (x, y, yaw) in the frame of ``pose``."""
    x, y, th = (float(v) for v in pose[:3])
    wx, wy, wth = (float(v) for v in world[:3])
    c, s = math.cos(th), math.sin(th)
    dx, dy = wx - x, wy - y
    return c * dx + s * dy, -s * dx + c * dy, wrap(wth - th)


def camera_pose_of(robot_pose, mount_x: float, mount_y: float,
                   pan: float) -> tuple[float, float, float]:
    """The camera's pose ``(x, y, yaw)`` in the frame ``robot_pose`` is given in.

    The same convention as :func:`sim2d.camera.camera_pose`: the optical
    centre sits on the pan axis at ``(mount_x, mount_y)`` in the robot frame,
    and the camera's yaw is the robot's heading plus the pan (CCW positive).
    Unlike ``compose``, the yaw is not wrapped, exactly as sim2d returns it.
    """
    x, y, theta = (float(v) for v in robot_pose[:3])
    c, s = math.cos(theta), math.sin(theta)
    return (x + c * mount_x - s * mount_y, y + s * mount_x + c * mount_y, theta + float(pan))


@dataclass(frozen=True)
class PlateEstimate:
    """A plate's pose in the camera frame (x forward, y left), with its uncertainty.

    Attributes
    ----------
    x, y : float
        The plate's centre (m).
    facing : float
        Yaw of the plate's outward normal in the camera frame (rad, in (-pi, pi]);
        it points back at the camera, so it is near pi for a plate seen head-on.
    range : float
        Horizontal distance from the camera to the centre (m).
    bearing : float
        Direction of the centre (rad, CCW/left positive).
    viewing_angle : float
        Angle between the normal and the line of sight to the camera (rad; 0 = head-on).
    sigma_xy : float
        Standard deviation of the centre (m, ``sqrt`` of the trace of its
        covariance) for ``sigma_px`` of corner noise; ``nan`` if not computed.
    sigma_facing : float
        Standard deviation of ``facing`` (rad); ``nan`` if not computed.
    method : str
        ``"width"`` (fitted with the known plate width), ``"edges"`` (closed
        form from the two edges) or ``"clipped"`` (one whole edge plus the
        border column).
    """

    x: float
    y: float
    facing: float
    range: float
    bearing: float
    viewing_angle: float
    sigma_xy: float = math.nan
    sigma_facing: float = math.nan
    method: str = "edges"

    def as_tuple(self) -> tuple[float, float, float]:
        return self.x, self.y, self.facing


# ---- measurements ---------------------------------------------------------------------------
def _edges(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean column ``u`` and vertical height ``h`` of the left (TL-BL) and right (TR-BR) edges.

    The height is the vertical extent, not the segment length, so a corner
    jittered sideways does not lengthen the edge.
    """
    c = np.asarray(corners, dtype=np.float64).reshape(4, 2)
    u = np.array([(c[0, 0] + c[3, 0]) / 2, (c[1, 0] + c[2, 0]) / 2])
    h = np.array([c[3, 1] - c[0, 1], c[2, 1] - c[1, 1]])
    return u, h


def _edge_points(u: np.ndarray, h: np.ndarray, camera: CameraModel,
                 plate_height: float) -> np.ndarray:
    """Camera-frame floor-plan points (2, 2) of the two edges (rows: left, right)."""
    x = camera.f * plate_height / h
    y = x * (camera.cx - u) / camera.f
    return np.stack([x, y], axis=1)


def _pose_from_points(left: np.ndarray, right: np.ndarray) -> tuple[float, float, float]:
    """Centre and camera-facing normal yaw of the plate through two edge points.

    With ``t = right - left`` the normal ``(t_y, -t_x)`` always points at the
    camera, because the left edge is the one seen further to the left (the
    cross product of the two rays fixes the sign).
    """
    cx, cy = (left + right) / 2
    t = right - left
    return float(cx), float(cy), wrap(math.atan2(-t[0], t[1]))


def plate_from_edges(u: np.ndarray, h: np.ndarray, camera: CameraModel,
                     plate_height: float = PLATE_HEIGHT) -> tuple[float, float, float] | None:
    """The closed form: centre and normal yaw from the two edges' columns and heights."""
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(h)) and np.all(h >= MIN_HEIGHT_PX)):
        return None
    left, right = _edge_points(u, h, camera, plate_height)
    return _pose_from_points(left, right)


# ---- the fit with the known width ----------------------------------------------------------------
def _model(p: np.ndarray, camera: CameraModel, plate_height: float,
           plate_width: float) -> tuple[np.ndarray, np.ndarray]:
    """Predicted ``[u_L, u_R, h_L, h_R]`` of a plate at centre ``p[:2]`` with normal yaw
    ``p[2]``, and their Jacobian (4, 3) with respect to ``p``.

    Edge by edge on Python floats (the fit calls this a dozen times per
    detection, and two edges are too few for numpy to pay off); each number
    is the same float operation as on the arrays ``sgn = [1, -1]`` would be.
    """
    x, y, phi = (float(v) for v in p)
    f, cx, half = float(camera.f), float(camera.cx), plate_width / 2
    lx, ly = math.sin(phi) * half, -math.cos(phi) * half  # the viewer's left, half a width
    dlx, dly = math.cos(phi) * half, math.sin(phi) * half  # d(lx, ly) / d phi
    fh = f * plate_height
    pred, rows = [0.0] * 4, [None] * 4
    for k, sgn in enumerate((1.0, -1.0)):  # left edge = centre + l, right edge = centre - l
        ex = x + sgn * lx
        ex = 1e-3 if ex < 1e-3 else ex  # keep the model finite if a step goes behind
        ey = y + sgn * ly
        ex2 = ex * ex
        pred[k], pred[2 + k] = cx - f * ey / ex, fh / ex
        du_dex, du_dey, dh_dex = f * ey / ex2, -f / ex, -f * plate_height / ex2
        rows[k] = (du_dex, du_dey, sgn * (du_dex * dlx + du_dey * dly))
        rows[2 + k] = (dh_dex, 0.0, sgn * dh_dex * dlx)
    return np.array(pred), np.array(rows)


def _fit_width(u: np.ndarray, h: np.ndarray, start: tuple[float, float, float],
               camera: CameraModel, plate_height: float, plate_width: float,
               iterations: int = 40) -> tuple[float, float, float] | None:
    """Levenberg-Marquardt fit of (x, y, normal yaw) to the edges with the width fixed.

    The residuals are weighted by their noise for the same noise on every
    corner coordinate: a column mean has 1/sqrt(2) of it, a height sqrt(2).
    """
    meas = np.concatenate([u, h])
    weights = np.array([math.sqrt(2), math.sqrt(2), 1 / math.sqrt(2), 1 / math.sqrt(2)])
    p = np.array(start, dtype=np.float64)

    def residual(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pred, jac = _model(q, camera, plate_height, plate_width)
        return (pred - meas) * weights, jac * weights[:, None]

    r, jac = residual(p)
    cost = float(r @ r)
    lam = 1e-4
    for _ in range(iterations):
        jtj, jtr = jac.T @ jac, jac.T @ r
        improved = False
        step = np.zeros(3)
        for _ in range(10):
            try:
                step = np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-12), -jtr)
            except np.linalg.LinAlgError:
                return None
            q = p + step
            rq, jq = residual(q)
            cq = float(rq @ rq)
            if cq <= cost:
                p, r, jac, cost, improved = q, rq, jq, cq, True
                lam = max(lam / 10, 1e-12)
                break
            lam *= 10
        if not improved or abs(step[0]) + abs(step[1]) < 1e-9 and abs(step[2]) < 1e-9:
            break
    if not np.all(np.isfinite(p)) or p[0] <= 0:
        return None
    # the plate must face the camera (the fit has a mirror solution behind it)
    if math.cos(p[2] - math.atan2(-p[1], -p[0])) <= 0:
        return None
    return float(p[0]), float(p[1]), wrap(p[2])


# ---- clipped quads ---------------------------------------------------------------------------
def _clipped_edges(corners: np.ndarray, camera: CameraModel) -> tuple[bool, bool, bool]:
    """Which of the left and right edges lie on the image's side borders, and whether
    the top or bottom border cuts the plate (then no edge height can be trusted)."""
    c = np.asarray(corners, dtype=np.float64).reshape(4, 2)
    lo_u, hi_u = BORDER_MARGIN, camera.width - 1 - BORDER_MARGIN
    lo_v, hi_v = BORDER_MARGIN, camera.height - 1 - BORDER_MARGIN
    left = bool(c[0, 0] <= lo_u and c[3, 0] <= lo_u)
    right = bool(c[1, 0] >= hi_u and c[2, 0] >= hi_u)
    vertical = bool(np.any(c[:, 1] <= lo_v) or np.any(c[:, 1] >= hi_v))
    return left, right, vertical


def _plate_from_one_edge(u: np.ndarray, h: np.ndarray, whole: int, camera: CameraModel,
                         plate_height: float,
                         plate_width: float) -> tuple[float, float, float] | None:
    """Centre and normal from the whole edge ``whole`` (0 left, 1 right) and the border side."""
    if not (np.all(np.isfinite(u)) and np.all(h >= MIN_HEIGHT_PX)):
        return None
    pts = _edge_points(u, h, camera, plate_height)
    edge, border = pts[whole], pts[1 - whole]
    d = border - edge
    n = float(np.hypot(*d))
    if n < 0.02 * plate_width:  # the border column is on the edge: no direction
        return None
    centre = edge + d / n * (plate_width / 2)
    left, right = (edge, border) if whole == 0 else (border, edge)
    _, _, facing = _pose_from_points(left, right)
    return float(centre[0]), float(centre[1]), facing


# ---- the estimate ------------------------------------------------------------------------------
def _solve(corners: np.ndarray, camera: CameraModel, plate_height: float,
           plate_width: float | None,
           clipped: bool) -> tuple[tuple[float, float, float], str] | None:
    u, h = _edges(corners)
    if clipped:
        left, right, vertical = _clipped_edges(corners, camera)
        if vertical or (left and right):
            return None
        if left or right:
            if plate_width is None:
                return None
            est = _plate_from_one_edge(u, h, 1 if left else 0, camera, plate_height, plate_width)
            return None if est is None else (est, "clipped")
        # flagged but no side on the border: the quad is whole after all
    est = plate_from_edges(u, h, camera, plate_height)
    if est is None:
        return None
    if plate_width is None:
        return est, "edges"
    fit = _fit_width(u, h, est, camera, plate_height, plate_width)
    return (est, "edges") if fit is None else (fit, "width")


def _covariance(c: np.ndarray, est: tuple[float, float, float], method: str,
                camera: CameraModel, plate_height: float, plate_width: float | None,
                clipped: bool) -> np.ndarray | None:
    """Covariance (3, 3) of (x, y, facing) for unit noise on every corner coordinate.

    The width fit's is its Gauss-Newton covariance ``(J^T J)^-1`` (its
    residuals are already scaled to unit corner noise); the closed forms'
    is propagated by central differences over the eight coordinates.
    """
    if method == "width":
        assert plate_width is not None
        weights = np.array([math.sqrt(2), math.sqrt(2), 1 / math.sqrt(2), 1 / math.sqrt(2)])
        _, jac = _model(np.array(est), camera, plate_height, plate_width)
        jac = jac * weights[:, None]
        try:
            return np.linalg.inv(jac.T @ jac)
        except np.linalg.LinAlgError:
            return None
    jac = np.zeros((3, 8))
    delta = 0.25
    for k in range(8):
        out = []
        for sgn in (1, -1):
            cp = c.copy().reshape(-1)
            cp[k] += sgn * delta
            s = _solve(cp.reshape(4, 2), camera, plate_height, plate_width, clipped)
            if s is None or s[1] != method:
                return None
            out.append(np.array(s[0]))
        diff = out[0] - out[1]
        diff[2] = wrap(diff[2])
        jac[:, k] = diff / (2 * delta)
    return jac @ jac.T


def estimate_plate(corners, camera: CameraModel, plate_height: float = PLATE_HEIGHT, *,
                   plate_width: float | None = PLATE_WIDTH, clipped: bool = False,
                   sigma_px: float | None = 1.0) -> PlateEstimate | None:
    """A plate's centre and facing in the camera frame from its image quad.

    Parameters
    ----------
    corners : array (4, 2)
        Pixel corners, top-left, top-right, bottom-right, bottom-left (image order).
    camera : CameraModel
        The frame's intrinsics (at its zoom and tilt).
    plate_height : float
        The plate's real height (m): it sets the scale.
    plate_width : float or None
        The plate's real width (m). Given, the estimate is fitted to both edges
        with the width held fixed (better facing at a distance), and a clipped
        quad can still be placed; ``None`` uses the two edges' closed form only.
    clipped : bool
        The quad touches the image border. A side on the left or right border
        is then taken as the border column, not the plate's edge; a quad cut by
        the top or bottom border, or by both sides, gives ``None``.
    sigma_px : float or None
        Corner noise (px, standard deviation of each coordinate) for the
        uncertainty; ``None`` skips it.

    Returns
    -------
    PlateEstimate or None
        ``None`` when the quad is degenerate (an edge under 2 px, points behind
        the camera) or too clipped to place.
    """
    c = np.asarray(corners, dtype=np.float64).reshape(4, 2)
    if not np.all(np.isfinite(c)):
        return None
    solved = _solve(c, camera, plate_height, plate_width, clipped)
    if solved is None:
        return None
    (x, y, facing), method = solved
    if not x > 0:
        return None
    sigma_xy = sigma_facing = math.nan
    if sigma_px is not None and sigma_px > 0:
        cov = _covariance(c, (x, y, facing), method, camera, plate_height, plate_width, clipped)
        if cov is not None:
            cov = sigma_px ** 2 * cov
            sigma_xy = float(math.sqrt(max(0.0, cov[0, 0] + cov[1, 1])))
            sigma_facing = float(math.sqrt(max(0.0, cov[2, 2])))
    rng = math.hypot(x, y)
    bearing = math.atan2(y, x)
    view = abs(wrap(facing - math.atan2(-y, -x)))
    return PlateEstimate(x=x, y=y, facing=facing, range=rng, bearing=bearing,
                         viewing_angle=view, sigma_xy=sigma_xy, sigma_facing=sigma_facing,
                         method=method)


def plate_in_camera(corners, camera: CameraModel, plate_height: float = PLATE_HEIGHT, *,
                    plate_width: float | None = PLATE_WIDTH,
                    clipped: bool = False) -> tuple[float, float, float] | None:
    """``(x, y, normal_yaw)`` of the plate in the camera frame, or ``None``.

    See :func:`estimate_plate` (this is it without the uncertainty).
    """
    est = estimate_plate(corners, camera, plate_height, plate_width=plate_width,
                         clipped=clipped, sigma_px=None)
    return None if est is None else est.as_tuple()


def plate_in_world(corners, camera: CameraModel, camera_pose_world,
                   plate_height: float = PLATE_HEIGHT, *,
                   plate_width: float | None = PLATE_WIDTH,
                   clipped: bool = False) -> tuple[float, float, float] | None:
    """``(x, y, facing)`` of the plate in the frame of ``camera_pose_world``.

    ``facing`` is the world yaw of the plate's outward normal (rad), the
    convention of :class:`sim2d.world.Sign`.
    """
    est = plate_in_camera(corners, camera, plate_height, plate_width=plate_width,
                          clipped=clipped)
    return None if est is None else compose(camera_pose_world, est)
