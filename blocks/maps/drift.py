"""Odometry drift correction from the walls the sonar sees, for the offline map.

Odometry heading error grows with every metre (a degree or two over an office
lap, so half a metre sideways at the far end of a corridor), and a map built
on it bends its walls and doubles them where the robot passes twice.
Offline, the whole run is available, so the trajectory can be corrected
against the walls already mapped, in the spirit of Amigoni, Gasparini and
Gini's map building without odometry (ICRA 2004): line segments of each new
stretch are matched to the segments mapped so far, and the rigid motion that
best aligns them corrects the rest of the trajectory.

Each chunk of scans (about half a metre of travel) gives local line features
(:func:`blocks.maps.features.extract_linear_features`).  A local feature
matches a mapped one that faces the same way, lies within ``max_offset`` of
its line and overlaps or continues it.  A small rotation and shift is then
solved by least squares on the points' distances to their matched lines,
with a weak prior towards no change, so a corridor (all walls parallel)
corrects heading and sideways drift and leaves the unobservable along-wall
drift alone.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .features import (LinearFeature, _mergeable, _refit, extract_linear_features, gap_along,
                       moved, sensor_poses_along)

__all__ = ["DriftCorrection", "DriftCorrector", "correct_odometry", "corrected_run"]


@dataclass(frozen=True)
class DriftCorrection:
    """Parameters of :func:`correct_odometry`.

    Attributes
    ----------
    chunk
        Scans per chunk (at 10 Hz, 10 scans = 1 s, about 0.4 m of travel).
    max_offset
        Largest distance (m) between a local feature and the mapped line it matches.
    max_angle_deg
        Largest angle between matched lines.
    max_gap
        Largest gap (m) along the line between matched features.
    min_length
        Only mapped walls at least this long (m) are trusted: short pieces
        (door jambs, furniture) are too easily matched to the wrong thing.
    prior
        Weight of the "no shift" prior, relative to one matched point.
    heading_prior
        Weight of the "no turn" prior: a chunk's points span too little to
        measure its heading well, so heading changes slowly, from many chunks.
    max_step
        Corrections larger than this (m, or rad for heading) are not trusted.
    robust_scale
        Distance (m) at which a point's pull on the correction is halved.
    rectilinear
        Assume the walls meet at right angles (most buildings): every straight
        wall the chunk sees then measures its heading, even a wall never seen
        before, against the building's axis (estimated from the first long
        walls).  Without it heading is only corrected against walls already
        mapped, and drifts freely while the robot is in a new room.
    axis_length
        Total length (m) of long walls that fixes the building's axis.
    rectilinear_min_length
        Only local walls at least this long (m) measure heading (shorter ones
        are too noisy: about 1.5 degrees at 0.3 m).
    rectilinear_gain
        Fraction of the measured heading error corrected per chunk; averages
        the noise of single walls over several chunks.
    lean_deg, lean_min_length, lean_reference_length
        A mapped wall at least ``lean_min_length`` (m) long that lies at least
        ``lean_deg`` (degrees) off the building's axis, yet within
        ``max_angle_deg`` of it, shows that the building is not rectilinear:
        a wall that leans a few degrees would otherwise be squared up, turning
        the heading with it and bending every wall after it.  From then on
        the correction stops assuming right angles (:func:`correct_odometry`
        starts again without the assumption).  The wall is measured against
        the axis of the other mapped walls at least 1 m long, once there are
        ``lean_reference_length`` (m) of them: the first few metres that fixed
        the axis leave it a degree or two out.  Shorter walls' directions are
        too noisy to tell (sonar walls 1-2 m long sit up to 6 degrees off on
        square floors).
    """

    chunk: int = 10
    max_offset: float = 0.35
    max_angle_deg: float = 8.0
    max_gap: float = 0.6
    min_length: float = 0.0
    prior: float = 5.0
    heading_prior: float = 10.0
    max_step: float = 0.15
    robust_scale: float = 0.05
    rectilinear: bool = True
    axis_length: float = 3.0
    rectilinear_min_length: float = 0.5
    rectilinear_gain: float = 0.3
    lean_deg: float = 2.5
    lean_min_length: float = 4.0
    lean_reference_length: float = 8.0


def _matches(f: LinearFeature, g: LinearFeature, p: DriftCorrection) -> float | None:
    """How far f lies from g's line if f continues g (None if it does not)."""
    if g.length < p.min_length or np.dot(f.normal, g.normal) < math.cos(
            math.radians(p.max_angle_deg)):
        return None
    offset = abs(float(np.dot((f.p0 + f.p1) / 2 - g.p0, g.normal)))
    if offset > p.max_offset or gap_along(g, f) > p.max_gap:
        return None
    return offset


def _solve(points: np.ndarray, normals: np.ndarray, offsets: np.ndarray, pivot: np.ndarray,
           prior: float, heading_prior: float, scale: float, rounds: int = 4) -> np.ndarray:
    """Small rigid motion (dtheta, dx, dy) about ``pivot`` that moves ``points`` onto
    their lines ``normal . x = offset``: linearised least squares with a prior towards
    no motion, reweighted (Cauchy, ``scale`` m) so a wrong match cannot drag it."""
    rel = points - pivot
    lever = normals[:, 0] * -rel[:, 1] + normals[:, 1] * rel[:, 0]
    a = np.column_stack([lever, normals])
    b = offsets - np.einsum("ij,ij->i", normals, points)
    prior_rows = np.diag([heading_prior, prior, prior])
    weights = np.ones(len(b))
    delta = np.zeros(3)
    for _ in range(rounds):
        root = np.sqrt(weights)[:, None]
        delta = np.linalg.lstsq(np.vstack([a * root, prior_rows]),
                                np.concatenate([b * root[:, 0], np.zeros(3)]), rcond=None)[0]
        weights = 1.0 / (1.0 + ((a @ delta - b) / scale) ** 2)
    return delta


def correct_odometry(poses: np.ndarray, ranges: np.ndarray, echo: np.ndarray,
                     mounts: np.ndarray, cone_deg: float = 30.0,
                     params: DriftCorrection | None = None) -> np.ndarray:
    """Odometry poses (T, 3) corrected against the walls mapped before them.

    Parameters
    ----------
    poses
        (T, 3) odometry x, y, theta, one per scan.
    ranges, echo
        (T, N) sonar readings and echo flags.
    mounts
        (N, 3) sensor mounts on the robot.
    cone_deg
        The sonar's cone angle.
    params
        :class:`DriftCorrection`.

    Returns
    -------
    (T, 3) array
        The corrected poses; the first chunk is taken as is (the map frame
        is the start pose's frame).

    See Also
    --------
    DriftCorrector : the same correction, one scan at a time, while the robot drives.
    """
    return corrected_run(poses, ranges, echo, mounts, cone_deg, params)[0]


def corrected_run(poses: np.ndarray, ranges: np.ndarray, echo: np.ndarray,
                  mounts: np.ndarray, cone_deg: float = 30.0,
                  params: DriftCorrection | None = None
                  ) -> tuple[np.ndarray, LinearFeature | None]:
    """:func:`correct_odometry`, and the wall that showed the building is not
    rectilinear (None if none did, or if the correction did not assume it).

    The whole run is at hand, so once a leaning wall shows that right angles
    cannot be assumed, the run is corrected again from its start without them.
    """
    corrector = DriftCorrector(mounts, cone_deg, params)
    poses = np.asarray(poses, dtype=np.float64)
    out = poses.copy()
    chunk = corrector.params.chunk
    for start in range(0, len(poses), chunk):
        part = slice(start, min(start + chunk, len(poses)))
        out[part] = corrector.add_chunk(poses[part], ranges[part], echo[part])
        if corrector.leaning_wall is not None:
            square = replace(corrector.params, rectilinear=False)
            return (corrected_run(poses, ranges, echo, mounts, cone_deg, square)[0],
                    corrector.leaning_wall)
    out[:, 2] = _wrapped(out[:, 2])
    return out, None


def _wrapped(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


class DriftCorrector:
    """:func:`correct_odometry` online: scans go in one at a time, corrected poses come out.

    Why: the offline map corrects the whole run at its end, but the explorer
    plans on a map drawn while it drives, and odometry alone puts a wall it
    passes twice in two places (metres apart after a few hundred metres),
    which closes doors on the plan and opens phantom frontiers.  The
    correction only ever looks back (each chunk is aligned with the walls
    mapped before it), so online, chunk by chunk, it gives the poses it gives
    offline: :meth:`add` returns each scan's pose under the correction known
    so far, and the correction moves once a chunk is complete.

    Parameters
    ----------
    mounts
        (N, 3) sensor mounts on the robot.
    cone_deg
        The sonar's cone angle.
    params
        :class:`DriftCorrection`.
    """

    def __init__(self, mounts: np.ndarray, cone_deg: float = 30.0,
                 params: DriftCorrection | None = None) -> None:
        self.params = params or DriftCorrection()
        self.mounts = np.asarray(mounts, dtype=np.float64)
        self.cone_deg = float(cone_deg)
        self._motion = _RigidMotion()
        self._mapped = _MappedWalls()
        self._axis = _BuildingAxis(self.params) if self.params.rectilinear else None
        self._pending: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._segments: tuple[int, np.ndarray] | None = None
        self.leaning_wall: LinearFeature | None = None
        """The mapped wall that showed the building is not rectilinear (then no
        longer assumed), or None."""

    @property
    def walls(self) -> list[LinearFeature]:
        """The walls mapped so far, in the corrected frame."""
        return list(self._mapped.features)

    def segments(self, min_support: int = 8) -> np.ndarray:
        """(F, 4) end points x0, y0, x1, y1 of the :attr:`walls` with at least
        ``min_support`` echoes (the offline map's rule), kept until a chunk adds walls."""
        if self._segments is None or self._segments[0] != min_support:
            ends = [[*f.p0, *f.p1] for f in self._mapped.features if f.support >= min_support]
            self._segments = (min_support, np.array(ends, dtype=np.float64).reshape(-1, 4))
        return self._segments[1]

    def corrected(self, pose: np.ndarray) -> np.ndarray:
        """Odometry ``pose`` (x, y, theta) under the correction known so far."""
        out = self._motion.applied(np.asarray(pose, dtype=np.float64)[None, :3])[0]
        out[2] = float(_wrapped(out[2]))
        return out

    def add(self, pose: np.ndarray, ranges: np.ndarray, echo: np.ndarray) -> np.ndarray:
        """Feed one scan and its odometry pose; returns the pose corrected.

        The scan waits for its chunk to be complete; the pose of a chunk's
        last scan already has that chunk's correction.
        """
        self._pending.append((np.asarray(pose, dtype=np.float64)[:3],
                              np.asarray(ranges, dtype=np.float64),
                              np.asarray(echo, dtype=bool)))
        if len(self._pending) < self.params.chunk:
            return self.corrected(self._pending[-1][0])
        poses, scans, echoes = (np.array(a) for a in zip(*self._pending))
        self._pending.clear()
        out = self.add_chunk(poses, scans, echoes)[-1]
        out[2] = float(_wrapped(out[2]))
        return out

    def add_chunk(self, poses: np.ndarray, ranges: np.ndarray, echo: np.ndarray) -> np.ndarray:
        """Correct one chunk of scans (poses (C, 3), ranges and echo (C, N)): aligned with
        the walls mapped before it, which then take in its walls.  Headings are not
        wrapped."""
        p = self.params
        out = self._motion.applied(poses)
        local = _local_features(out, ranges, echo, self.mounts, self.cone_deg)
        if self._axis is not None and local:
            turn = self._axis.heading_error(local)
            if turn is not None:
                delta = np.array([-p.rectilinear_gain * turn, 0.0, 0.0])
                out, local = self._move(delta, poses, out, local)
        if self._mapped and local:  # measured after the turn
            delta = _alignment(local, self._mapped, out[:, :2].mean(axis=0), p)
            if delta is not None:
                out, local = self._move(delta, poses, out, local)
        cos_merge = math.cos(math.radians(p.max_angle_deg))
        touched = []
        for f in local:
            for i in self._mapped.near(f, cos_merge, 0.1, ends=True):
                g = self._mapped.features[i]
                if _mergeable(g, f, math.radians(p.max_angle_deg), 0.1, 0.3):
                    self._mapped.replace(i, _refit(np.vstack([g.points, f.points]), g.normal))
                    break
            else:
                i = len(self._mapped.features)
                self._mapped.append(f)
            touched.append(self._mapped.features[i])
        if local:
            self._segments = None
        if self._axis is not None:
            leaning = self._axis.leaning(touched, self._mapped.features)
            if leaning is not None:
                self.leaning_wall, self._axis = leaning, None
        return out

    @property
    def rectilinear(self) -> bool:
        """Whether the correction still assumes the walls meet at right angles."""
        return self._axis is not None

    def _move(self, delta: np.ndarray, poses: np.ndarray, out: np.ndarray,
              local: list[LinearFeature]) -> tuple[np.ndarray, list[LinearFeature]]:
        """Add ``delta`` (turn about the chunk's centre, shift) to the correction: the
        chunk's poses re-placed, and its features, which moved rigidly with it."""
        pivot = out[:, :2].mean(axis=0)
        r_delta = self._motion.compose(delta, pivot)
        return self._motion.applied(poses), [moved(f, r_delta, pivot, delta[1:]) for f in local]


class _RigidMotion:
    """The correction so far: odometry x -> rotation x + shift, heading + turn."""

    def __init__(self) -> None:
        self.rotation = np.eye(2)
        self.shift = np.zeros(2)
        self.turn = 0.0

    def applied(self, poses: np.ndarray) -> np.ndarray:
        out = poses.copy()
        out[:, :2] = poses[:, :2] @ self.rotation.T + self.shift
        out[:, 2] = poses[:, 2] + self.turn
        return out

    def compose(self, delta: np.ndarray, pivot: np.ndarray) -> np.ndarray:
        """Follow with a small turn ``delta[0]`` about ``pivot`` and shift ``delta[1:]``;
        returns the turn's rotation matrix."""
        c, s = math.cos(delta[0]), math.sin(delta[0])
        r_delta = np.array([[c, -s], [s, c]])
        self.rotation = r_delta @ self.rotation
        self.shift = pivot + r_delta @ (self.shift - pivot) + delta[1:]
        self.turn += float(delta[0])
        return r_delta


class _BuildingAxis:
    """The building's wall direction (modulo 90 degrees), from the first long walls seen."""

    def __init__(self, params: DriftCorrection) -> None:
        self.p = params
        self.sum = np.zeros(2)
        self.length = 0.0
        self.angle: float | None = None

    def heading_error(self, local: list[LinearFeature]) -> float | None:
        """Length-weighted mean angle (rad) of the chunk's walls off the axis, if any
        are near it; None until the axis is known."""
        p = self.p
        long = [f for f in local if f.length >= p.rectilinear_min_length]
        if not long:
            return None
        angles = np.array([_direction(f) for f in long])
        lengths = np.array([f.length for f in long])
        if self.angle is None:
            # a quadrupled angle makes the four wall directions one direction
            self.sum += (lengths[:, None] * np.column_stack([np.cos(4 * angles),
                                                              np.sin(4 * angles)])).sum(axis=0)
            self.length += float(lengths.sum())
            if self.length >= p.axis_length:
                self.angle = math.atan2(self.sum[1], self.sum[0]) / 4
            return None
        off = _off_axis(angles, self.angle)
        near = np.abs(off) <= math.radians(p.max_angle_deg)
        if not near.any():
            return None
        return float(np.average(off[near], weights=lengths[near]))

    def leaning(self, walls: list[LinearFeature],
                mapped: list[LinearFeature]) -> LinearFeature | None:
        """The first of ``walls`` (walls just mapped) long enough to measure, near the axis
        yet off it by ``lean_deg`` or more: a wall the building does not square up.

        The axis is measured again for this, from the other ``mapped`` walls at least
        1 m long near it (at least ``lean_reference_length`` of them).
        """
        if self.angle is None:
            return None
        p = self.p
        for f in walls:
            if f.length < p.lean_min_length:
                continue
            off = abs(math.degrees(_off_axis(_direction(f), self.angle)))
            if not p.lean_deg <= off <= p.max_angle_deg:
                continue
            axis = self._refined([g for g in mapped if g is not f])
            if axis is not None and p.lean_deg <= abs(math.degrees(_off_axis(_direction(f),
                                                                               axis))):
                return f
        return None

    def _refined(self, walls: list[LinearFeature]) -> float | None:
        """The axis measured on ``walls`` at least 1 m long within ``max_angle_deg`` of
        it, by their length-weighted median, which the leaning walls cannot drag while the
        square ones are the longer part (None if they are shorter than
        ``lean_reference_length`` together)."""
        long = [g for g in walls if g.length >= 1.0]
        if not long:
            return None
        offs = _off_axis(np.array([_direction(g) for g in long]), self.angle)
        lengths = np.array([g.length for g in long])
        near = np.abs(offs) <= math.radians(self.p.max_angle_deg)
        if lengths[near].sum() < self.p.lean_reference_length:
            return None
        return self.angle + _weighted_median(offs[near], lengths[near])


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    order = np.argsort(values)
    cumulative = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cumulative, cumulative[-1] / 2)])


def _direction(f: LinearFeature) -> float:
    return math.atan2(f.p1[1] - f.p0[1], f.p1[0] - f.p0[0])


def _off_axis(angle: np.ndarray | float, axis: float) -> np.ndarray | float:
    """Angle(s) (rad) off the nearest of the four directions of ``axis``."""
    return (angle - axis + math.pi / 4) % (math.pi / 2) - math.pi / 4


def _local_features(poses: np.ndarray, ranges: np.ndarray, echo: np.ndarray,
                    mounts: np.ndarray, cone_deg: float) -> list[LinearFeature]:
    sensors = sensor_poses_along(poses, mounts)
    return extract_linear_features(sensors, ranges, echo, cone_deg, min_points=5,
                                   min_length=0.2)


class _MappedWalls:
    """The walls mapped so far, in order, with their normals and first ends side by side.

    Most mapped walls face another way than a given feature, or lie far from
    its line; a few products with all of them rule those out, and only the
    rest are tested in full, in their order (so every test gives what it gave
    over all walls).
    """

    SLACK = 1e-9  # a cosine or offset (m) this close to its bound is tested in full

    def __init__(self) -> None:
        self.features: list[LinearFeature] = []
        self._normals = np.empty((16, 2))
        self._starts = np.empty((16, 2))

    def __bool__(self) -> bool:
        return bool(self.features)

    def append(self, f: LinearFeature) -> None:
        n = len(self.features)
        if n == len(self._normals):
            self._normals = np.concatenate([self._normals, np.empty_like(self._normals)])
            self._starts = np.concatenate([self._starts, np.empty_like(self._starts)])
        self.features.append(f)
        self.replace(n, f)

    def replace(self, i: int, f: LinearFeature) -> None:
        self.features[i] = f
        self._normals[i], self._starts[i] = f.normal, f.p0

    def near(self, f: LinearFeature, cos_tol: float, max_offset: float,
             ends: bool = False) -> list[int]:
        """The indices (increasing) of the walls that may face within ``cos_tol`` (cosine)
        of ``f`` with ``f``'s middle (or, with ``ends``, both its ends) within
        ``max_offset`` of their line: every wall the full tests could pass."""
        n = len(self.features)
        normals, starts = self._normals[:n], self._starts[:n]
        close = normals @ f.normal >= cos_tol - self.SLACK

        def offset(point: np.ndarray) -> np.ndarray:
            return np.abs(np.einsum("ij,ij->i", point - starts, normals))
        if ends:
            far = np.maximum(offset(f.p0), offset(f.p1))
        else:
            far = offset((f.p0 + f.p1) / 2)
        close &= far <= max_offset + self.SLACK
        return np.flatnonzero(close).tolist()


def _alignment(local: list[LinearFeature], mapped: _MappedWalls, pivot: np.ndarray,
               p: DriftCorrection) -> np.ndarray | None:
    """The correction that aligns the chunk's features with the mapped ones, if any match."""
    points, normals, offsets = [], [], []
    cos_match = math.cos(math.radians(p.max_angle_deg))
    for f in local:
        best = None
        for i in mapped.near(f, cos_match, p.max_offset):
            g = mapped.features[i]
            offset = _matches(f, g, p)
            if offset is not None and (best is None or offset < best[0]):
                best = (offset, g)
        if best is None:
            continue
        g = best[1]
        points.append(f.points)
        normals.append(np.repeat(g.normal[None, :], len(f.points), axis=0))
        offsets.append(np.full(len(f.points), float(np.dot(g.normal, (g.p0 + g.p1) / 2))))
    if not points:
        return None
    delta = _solve(np.vstack(points), np.vstack(normals), np.concatenate(offsets), pivot, p.prior,
                   p.heading_prior, p.robust_scale)
    if np.any(np.abs(delta) > p.max_step):
        return None
    return delta
