"""Linear feature prediction for sonar (O'Sullivan et al., AROB 2004).

A sonar reports the nearest echo anywhere in its 30-degree cone, and loses
echoes from walls met at a grazing angle (specular reflection): the wall is
then simply not there for that reading, and a map that trusts it clears free
space straight through the wall.  Indoors most of what a sonar sees is
straight walls, so the readings can check each other:

1. **Features.**  While the robot drives along a wall, the echoes of one
   sensor line up.  Runs of collinear echoes from one sensor become line
   segments; collinear, overlapping segments of several sensors merge into
   one feature, whose support is the number of echoes behind it.
2. **Prediction.**  Every reading is predicted from the features: the range
   at which its cone would first meet one (exactly, with the simulator's cone
   geometry).  A reading that agrees gains confidence; a reading with no echo
   where a feature predicts a wall is a specular loss, and its free space ends
   at that wall instead of at the maximum range.

The paper's offline map generator (section 6) builds on this; see
:mod:`blocks.maps.offline`.
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

__all__ = ["FeatureMemo", "LinearFeature", "extract_linear_features", "merge_features",
           "predict_ranges", "sensor_poses_along"]


@dataclass(frozen=True)
class LinearFeature:
    """A straight wall piece seen by the sonar.

    Attributes
    ----------
    p0, p1
        End points (m, map frame): the extent over which echoes support it.
    normal
        Unit normal of the line, pointing from the wall towards where the
        sensors were.
    points
        (K, 2) echo points on the wall that support it.
    residual
        RMS distance (m) of the points from the line.
    """

    p0: np.ndarray
    p1: np.ndarray
    normal: np.ndarray
    points: np.ndarray
    residual: float

    @property
    def support(self) -> int:
        """How many echoes back the feature up."""
        return len(self.points)

    @property
    def length(self) -> float:
        return float(np.hypot(*(self.p1 - self.p0)))


def sensor_poses_along(poses: np.ndarray, mounts: np.ndarray) -> np.ndarray:
    """Map-frame poses (T, N, 3) of N sensors mounted at ``mounts`` on robot ``poses`` (T, 3)."""
    poses = np.asarray(poses, dtype=np.float64)
    mounts = np.asarray(mounts, dtype=np.float64)
    c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
    x = poses[:, 0:1] + c * mounts[None, :, 0] - s * mounts[None, :, 1]
    y = poses[:, 1:2] + s * mounts[None, :, 0] + c * mounts[None, :, 1]
    return np.stack([x, y, poses[:, 2:3] + mounts[None, :, 2]], axis=-1)


def _fit_line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid and unit direction of the total-least-squares line through ``points``."""
    centre, direction, _ = _fit_line_offsets(points)
    return centre, direction


def _mean_rows(points: np.ndarray) -> np.ndarray:
    """``points.mean(axis=0)``, the same sum and division, without ``mean``'s Python layer
    (fitting lines to a few echoes is called tens of thousands of times per run)."""
    return np.add.reduce(points, axis=0) / len(points)


def _fit_line_offsets(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_fit_line`, and the points less the centroid."""
    centre = _mean_rows(points)
    d = points - centre
    sxx, syy, sxy = float(d[:, 0] @ d[:, 0]), float(d[:, 1] @ d[:, 1]), float(d[:, 0] @ d[:, 1])
    angle = 0.5 * math.atan2(2 * sxy, sxx - syy)  # major axis of the scatter
    return centre, np.array([math.cos(angle), math.sin(angle)]), d


def _reflection_points(sensors: np.ndarray, ranges: np.ndarray, normal: np.ndarray,
                       half_cone: float) -> np.ndarray:
    """Where each echo came from, given that the wall's normal is ``normal``.

    The echo comes from the point of the wall nearest the sensor inside the
    cone: straight along ``-normal`` if that direction is inside the cone,
    else along the cone edge nearest to it.  Using the beam axis instead
    would put echoes of oblique walls in front of the wall.
    """
    return _wall_points(sensors, ranges, math.atan2(-normal[1], -normal[0]), half_cone)


def _wall_points(sensors: np.ndarray, ranges: np.ndarray, toward: float | np.ndarray,
                 half_cone: float) -> np.ndarray:
    """:func:`_reflection_points` with the direction ``toward`` the wall (rad; one for all
    echoes or one each): element by element, so echoes of many runs at once give what
    they give run by run."""
    offset = (toward - sensors[:, 2] + np.pi) % (2 * np.pi) - np.pi
    heading = sensors[:, 2] + np.clip(offset, -half_cone, half_cone)
    return sensors[:, :2] + ranges[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])


def _features_from(runs: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                   half_cone: float) -> list[LinearFeature]:
    """A feature fitted to each run (axis points, sensors, ranges): the axis points give
    the direction, the reflection points the offset and extent; the reflection
    points of all their echoes worked out at once (element by element, as run by run);
    the line fits run by run, as their sums go through BLAS dot products whose order
    depends on the arrays."""
    towards, seen = [], []
    for points, sensors, _ in runs:
        centre, direction = _fit_line(points)
        normal = np.array([-direction[1], direction[0]])
        seen_from = _mean_rows(sensors[:, :2])
        if np.dot(seen_from - centre, normal) < 0:
            normal = -normal
        towards.append(math.atan2(-normal[1], -normal[0]))
        seen.append(seen_from)
    if not runs:
        return []
    sizes = [len(points) for points, _, _ in runs]
    wall = _wall_points(np.concatenate([sensors for _, sensors, _ in runs]),
                        np.concatenate([ranges for _, _, ranges in runs]),
                        np.repeat(towards, sizes), half_cone)
    out, at = [], 0
    for n, seen_from in zip(sizes, seen):
        points = wall[at:at + n].copy()  # each run's own array, as one at a time
        out.append(_refit(points, seen_from - _mean_rows(points)))
        at += n
    return out


def extract_linear_features(sensors: np.ndarray, ranges: np.ndarray, echo: np.ndarray,
                            cone_deg: float = 30.0, *, line_tol: float = 0.04,
                            max_gap: float = 0.3, min_points: int = 6,
                            min_length: float = 0.3, recent: int = 20,
                            ids: np.ndarray | None = None,
                            memo: FeatureMemo | None = None) -> list[LinearFeature]:
    """Runs of collinear echoes, sensor by sensor, as line features.

    Parameters
    ----------
    sensors
        (T, N, 3) sensor poses in the map frame, one row per scan.
    ranges, echo
        (T, N) readings (m) and whether each was a real echo.
    cone_deg
        The sonar's full cone angle.
    line_tol
        How far (m) an echo may lie from the line of its run and still extend it.
    max_gap
        Largest distance (m) between consecutive echoes of a run.
    min_points, min_length
        A run needs this many echoes spanning this length (m) to count: short
        runs are corners, door jambs and the robot turning on the spot.
    recent
        A new echo is tested against the line through the run's last
        ``recent`` echoes (at least 3).
    ids, memo
        With a :class:`FeatureMemo`, the work done on the same scans in an
        earlier call is looked up instead of repeated (same result): ``ids``
        (T,) names each scan, and a scan's name must always come with the
        same pose and readings.

    Returns
    -------
    list of LinearFeature
        One per run, not yet merged across sensors (see :func:`merge_features`).
    """
    if memo is not None:
        if ids is None:
            raise ValueError("a memo needs the scans' ids")
        memo.configure("extract", (float(cone_deg), line_tol, max_gap, min_points, min_length,
                                   recent), new_call=True)
        ids = np.ascontiguousarray(ids, dtype=np.int64)
    if recent < 3:
        raise ValueError(f"recent must be at least 3 echoes, got {recent}")
    half = math.radians(cone_deg) / 2
    axis = sensors[..., :2] + ranges[..., None] * np.stack(
        [np.cos(sensors[..., 2]), np.sin(sensors[..., 2])], axis=-1)

    def worth_fitting(runs: list[tuple[int, np.ndarray]]) -> list[bool]:
        """Per run: enough echoes, the first and last far enough apart, for a feature (see
        :func:`_explains`); all runs at once (``hypot`` element by element)."""
        if not runs:
            return []
        sensor = np.array([j for j, _ in runs])
        step = axis[[run[-1] for _, run in runs], sensor] \
            - axis[[run[0] for _, run in runs], sensor]
        return ((np.array([len(run) for _, run in runs]) >= min_points)
                & ~(np.hypot(step[:, 0], step[:, 1]) < min_length)).tolist()

    def straight(feature: LinearFeature) -> bool:
        """A fitted run long and straight enough to be checked against its readings."""
        return feature.length >= min_length and feature.residual <= line_tol

    def breaks_line(j: int, tail: np.ndarray, t: int) -> bool:
        # the recent part only: odometry drift bends long walls
        centre, direction = _fit_line(axis[tail, j])
        p = axis[t, j]
        return bool(abs(direction[0] * (p[1] - centre[1]) - direction[1] * (p[0] - centre[0]))
                    > line_tol)

    def first_break(j: int, rows: np.ndarray, status: np.ndarray, start: int) -> int | None:
        """The first echo after ``start`` (positions in ``rows``) that leaves the line."""
        end = len(rows)
        short = status[start, 3:min(recent, end - start)]  # echo start + L, tail from start
        long = status[start:max(start, end - recent), recent]  # echo k, tail k - recent..k
        for i in np.flatnonzero(np.concatenate([short, long])).tolist():
            k = start + 3 + i if i < len(short) else start + recent + i - len(short)
            if status[k - min(recent, k - start), min(recent, k - start)] == _BREAKS or \
                    breaks_line(j, rows[max(start, k - recent):k], rows[k]):
                return k
        return None

    def segment(j: int, rows: np.ndarray, status: np.ndarray) -> list[np.ndarray]:
        # A run of echoes no farther apart than max_gap: runs within it end where the
        # next echo leaves the line (the last echo then starts the next run).
        runs = []
        start = 0
        while True:
            k = first_break(j, rows, status, start)
            runs.append(rows[start:] if k is None else rows[start:k])
            if k is None:
                return runs
            start = k - 1

    def features_of(runs: list[tuple[int, np.ndarray]]) -> list[LinearFeature | None]:
        """Each run's feature, or None; the readings check of all runs at once."""
        out: list[LinearFeature | None] = [None] * len(runs)
        fits = []  # (index, axis points, sensors, ranges) of the runs to fit
        keys = [None if memo is None else (j, ids[run].tobytes()) for j, run in runs]
        for i, ((j, run), worth, key) in enumerate(zip(runs, worth_fitting(runs), keys)):
            found = None if key is None else memo.get("run", key)
            if found is not None:
                out[i] = found[0]
                continue
            if worth:
                fits.append((i, axis[run, j], sensors[run, j], ranges[run, j]))
            elif key is not None:
                memo.store("run", key, (None,))
        checks = []
        for (i, _, sens, rng), feature in zip(fits, _features_from([f[1:] for f in fits], half)):
            if straight(feature):
                checks.append((i, feature, sens, rng))
            elif memo is not None:
                memo.store("run", keys[i], (None,))
        if checks:
            fine = _explained(checks, cone_deg, 2 * line_tol)
            for (i, feature, _, _), ok in zip(checks, fine):
                out[i] = feature if ok else None
                if memo is not None:
                    memo.store("run", keys[i], (out[i],))
        return out

    # The segments (echoes no farther apart than max_gap) of every sensor, in order; those
    # not kept in the memo are worked out together.
    slots: list = []
    todo: list[tuple[int, int, np.ndarray, tuple | None]] = []
    for j in range(sensors.shape[1]):
        rows = np.flatnonzero(echo[:, j])
        if rows.size == 0:
            continue
        pts = axis[rows, j]
        step = pts[1:] - pts[:-1]
        cuts = [0, *(np.flatnonzero(np.hypot(step[:, 0], step[:, 1]) > max_gap) + 1).tolist(),
                len(rows)]
        names = None if memo is None else ids[rows].tobytes()  # 8 bytes a scan
        for a, b in zip(cuts[:-1], cuts[1:]):
            key = None if names is None else (j, names[8 * a:8 * b])  # ids[part].tobytes()
            found = None if key is None else memo.get("segment", key)
            if found is None:
                todo.append((len(slots), j, rows[a:b], key))
            slots.append(found)
    if todo:
        lengths = np.array([len(part) for _, _, part, _ in todo])
        scan = np.concatenate([part for _, _, part, _ in todo])
        sensor = np.repeat([j for _, j, _, _ in todo], lengths)
        flat = axis[scan, sensor]
        if memo is None:
            status = _line_tests(flat, recent, line_tol)
        else:  # each echo named by its scan and sensor, unique in the segments
            names = ids[scan] * sensors.shape[1] + sensor
            status = memo.line_tests(flat, _echo_windows(names, lengths, recent), line_tol)
        straight_through = _no_line_breaks(status, lengths, recent).tolist()
        at = 0
        runs: list[tuple[int, np.ndarray]] = []
        owner: list[int] = []
        for n, (_, j, part, _) in enumerate(todo):
            for run in ([part] if straight_through[n] else
                        segment(j, part, status[at:at + len(part)])):
                runs.append((j, run))
                owner.append(n)
            at += len(part)
        mine: list[list[LinearFeature]] = [[] for _ in todo]
        for f, n in zip(features_of(runs), owner):
            if f is not None:
                mine[n].append(f)
        for (slot, _, _, key), found in zip(todo, mine):
            slots[slot] = found
            if key is not None:
                memo.store("segment", key, found)
    return [f for found in slots for f in found]


_KEEPS, _BREAKS, _UNSURE = 0, 1, 2


LINE_TEST_ROWS = 512  # starts tested at once: (recent, rows) temporaries of ~80 kB stay in cache


def _line_tests(pts: np.ndarray, recent: int, line_tol: float,
                starts: np.ndarray | None = None) -> np.ndarray:
    """Does echo ``s + L`` leave the line through echoes ``s .. s + L - 1``?

    For every start ``s`` (or those ``starts``) and tail length ``3 <= L <=
    recent``: ``_KEEPS``, ``_BREAKS`` or ``_UNSURE`` (n, recent + 1) int8.  The
    lines are fitted from running sums, which round differently from
    :func:`_fit_line`; a test is only decided here when its distance from
    ``line_tol`` exceeds a bound on both roundings, else it is ``_UNSURE`` and
    the caller fits exactly, so decisions are those of :func:`_fit_line`.  Row
    ``s``, column ``L`` depends on echoes ``s .. s + L`` only.  Starts are
    tested :data:`LINE_TEST_ROWS` at a time (each row's arithmetic is its own):
    temporaries that fit in the cache, and that the allocator hands back
    instead of mapping fresh pages for each (that took two thirds of the time
    with 4096 starts at once).
    """
    n = len(pts)
    starts = np.arange(n) if starts is None else np.asarray(starts, dtype=np.int64)
    status = np.zeros((len(starts), recent + 1), dtype=np.int8)
    if n < 4:
        return status
    for first in range(0, len(starts), LINE_TEST_ROWS):
        part = starts[first:first + LINE_TEST_ROWS]
        status[first:first + len(part)] = _line_test_rows(pts, part, recent, line_tol)
    return status


def _line_test_rows(pts: np.ndarray, starts: np.ndarray, recent: int,
                    line_tol: float) -> np.ndarray:
    """:func:`_line_tests` for the ``starts``.

    Worked out with the tail lengths along the first axis, so that the running
    sums add whole rows (up to :data:`LINE_TEST_ROWS` starts each) instead of running along
    a row of ``recent``; and the line's direction from the scatter with square
    roots (no ``arctan2``, ``cos``, ``sin`` nor ``hypot``, the costs of the
    test): it rounds by a few units in the last place, far inside the bound.
    """
    n = len(pts)
    offsets = np.arange(recent + 1)[:, None]
    idx = np.minimum(starts[None, :] + offsets, n - 1)  # (recent + 1, rows)
    ref = pts[starts]
    ux = pts[idx, 0] - ref[:, 0]  # relative to the tail's first echo
    uy = pts[idx, 1] - ref[:, 1]
    count = offsets[1:].astype(np.float64)  # tails of L = 1..recent echoes
    sums = np.empty((5, recent, len(starts)))
    head_x, head_y = ux[:-1], uy[:-1]
    sums[0], sums[1] = head_x, head_y
    np.multiply(head_x, head_x, out=sums[2])
    np.multiply(head_y, head_y, out=sums[3])
    np.multiply(head_x, head_y, out=sums[4])
    for k in range(1, recent):  # running sums, as cumsum adds them, all five a row at a time
        sums[:, k] += sums[:, k - 1]
    sx, sy, sxx, syy, sxy = sums
    cx, cy = sx / count, sy / count
    vxx, vyy, vxy = sxx - count * cx * cx, syy - count * cy * cy, sxy - count * cx * cy
    ex, ey = ux[1:] - cx, uy[1:] - cy  # the echo tested against each tail
    # The major axis: half the angle of (c, d) = (vxx - vyy, 2 vxy), along (scatter + c, d)
    # or, without cancellation where c < 0, (d, scatter - c).
    c, d = vxx - vyy, 2 * vxy
    scatter = np.sqrt(c * c + d * d)
    ahead = c >= 0
    dx = np.where(ahead, scatter + c, d)
    dy = np.where(ahead, d, scatter - c)
    with np.errstate(divide="ignore", invalid="ignore"):
        cross = np.abs(dx * ey - dy * ex) / np.sqrt(dx * dx + dy * dy)  # NaN: no line
        # Bounds: sums of <= recent squares round by far less than 1e-11 of their size; an
        # error e in the scatter turns the line by at most 2 e / |(c, d)|.
        size = sxx + syy
        turn = np.where(scatter > 0, 2e-11 * size / scatter, np.inf)
        slack = np.sqrt(ex * ex + ey * ey) * turn \
            + 1e-11 * (1.0 + np.abs(ref).sum(axis=1) + np.sqrt(size))
        decided = np.abs(cross - line_tol) > slack  # NaN slack (0 * inf): unsure
    status = np.zeros((len(starts), recent + 1), dtype=np.int8)
    status[:, 1:] = np.where(decided, np.where(cross > line_tol, _BREAKS, _KEEPS), _UNSURE).T
    status[:, :3] = _KEEPS
    status[(starts[None, :] + offsets >= n).T] = _KEEPS  # past the last echo
    return status


def _no_line_breaks(status: np.ndarray, lengths: np.ndarray, recent: int) -> np.ndarray:
    """Per segment (of ``lengths``, one after the other in ``status``): does no echo leave
    the line of the run from its first echo, not even unsure (:func:`_line_tests`'
    entries, as ``first_break`` reads them from the start)?  Then the segment is one run.

    Why: most segments are one straight run; this settles them all at once, where
    ``first_break`` looks at each in Python.

    Examples
    --------
    >>> status = np.zeros((7, 5), dtype=np.int8)
    >>> status[5, 4] = _UNSURE  # echo 5 + 4 is past its segment (5..6): not read
    >>> _no_line_breaks(status, np.array([4, 3]), 4).tolist()
    [True, True]
    >>> status[0, 3] = _BREAKS  # echo 3 leaves the line through echoes 0..2
    >>> _no_line_breaks(status, np.array([4, 3]), 4).tolist()
    [False, True]
    """
    first = np.cumsum(lengths) - lengths
    end = np.repeat(first + lengths, lengths)
    rows = np.arange(len(status))
    # from the segment's first echo, tails of 3..recent - 1 echoes inside the segment
    head = (status[first, 3:recent] != 0) & (
        first[:, None] + np.arange(3, recent)[None, :] < (first + lengths)[:, None])
    # then every echo k, tested against the recent echoes before it: rows k - recent
    tail = (status[:, recent] != 0) & (rows + recent < end)
    broken = head.any(axis=1) | (np.add.reduceat(tail, first) > 0 if len(first) else False)
    return ~broken


def _echo_windows(names: np.ndarray, lengths: np.ndarray, recent: int) -> np.ndarray:
    """(n, recent + 1) the names of echoes ``s .. s + recent`` of each echo ``s``'s segment
    (segments of ``lengths`` one after the other in ``names``), -1 past its end: what
    :func:`_line_tests`' row ``s`` depends on, where it is read.

    Examples
    --------
    >>> _echo_windows(np.array([7, 8, 9, 4]), np.array([3, 1]), 2).tolist()
    [[7, 8, 9], [8, 9, -1], [9, -1, -1], [4, -1, -1]]
    """
    n = len(names)
    end = np.repeat(np.cumsum(lengths), lengths)  # one past each echo's segment
    idx = np.arange(n)[:, None] + np.arange(recent + 1)[None, :]
    return np.where(idx < end[:, None], names[np.minimum(idx, n - 1)], -1)


class FeatureMemo:
    """Work of :func:`extract_linear_features` and :func:`merge_features` kept between calls.

    When the scans of one call recur in the next (a sliding window), most
    runs, line tests and merges are the same; this keeps them, keyed by the
    scans' ids and by the features' identities, and the results are those of
    a call without the memo.  What goes unused for ``max_age`` extractions is
    dropped, so the memo stays the size of a few windows.
    """

    def __init__(self, max_age: int = 4) -> None:
        self.max_age = max_age
        self._configs: dict[str, tuple] = {}
        self._new: dict = {}
        self._old: dict = {}
        self._calls = 0
        self._serials: dict[int, tuple[int, weakref.ref, float]] = {}
        self._next_serial = 0
        self.hits = 0
        self.misses = 0

    def configure(self, name: str, config: tuple, new_call: bool = False) -> None:
        """Forget everything when ``name``'s parameters change; age entries on a new call."""
        if self._configs.get(name) != config:
            self._configs[name] = config
            self._new, self._old = {}, {}
        if new_call:
            self._calls += 1
            if self._calls % self.max_age == 0:  # what was not used since the last turn goes
                self._old, self._new = self._new, {}
                self._serials = {k: e for k, e in self._serials.items() if e[1]() is not None}

    def get(self, kind: str, key: tuple):
        """The value kept under ``key``, or None."""
        found = self._new.get((kind, key))
        if found is None:
            found = self._old.get((kind, key))
            if found is None:
                self.misses += 1
                return None
            self._new[(kind, key)] = found
        self.hits += 1
        return found[0]

    def store(self, kind: str, key: tuple, value) -> None:
        self._new[(kind, key)] = (value,)

    def line_tests(self, pts: np.ndarray, windows: np.ndarray, line_tol: float) -> np.ndarray:
        """:func:`_line_tests` of ``pts``, the rows of the last call's echoes looked up.

        Why: a segment that gained or lost echoes at an end is worked out again,
        but most of its starts see the same echoes as before.  ``windows``
        (:func:`_echo_windows`) names the echoes each row depends on; a row kept
        from the last call is used where its echoes are the same ones (past the
        end of the segment, where the caller does not read, it may differ).
        """
        recent = windows.shape[1] - 1
        names = windows[:, 0]
        status = np.empty((len(pts), recent + 1), dtype=np.int8)
        need = np.arange(len(pts))
        known = self.get("lines", (recent, line_tol))
        if known is not None and len(known[0]):
            known_names, known_windows, known_status = known
            at = np.minimum(np.searchsorted(known_names, names), len(known_names) - 1)
            same = (known_names[at] == names) & (
                (known_windows[at] == windows) | (windows < 0)).all(axis=1)
            status[same] = known_status[at[same]]
            need = np.flatnonzero(~same)
        status[need] = _line_tests(pts, recent, line_tol, need)
        order = np.argsort(names)
        self.store("lines", (recent, line_tol), (names[order], windows[order], status[order]))
        return status

    def lookup(self, kind: str, key: tuple, compute, *args):
        """The value kept under ``key``, else ``compute(*args)`` (then kept)."""
        found = self._new.get((kind, key))
        if found is None:
            found = self._old.get((kind, key))
            if found is None:
                self.misses += 1
                found = (compute(*args),)
            else:
                self.hits += 1
            self._new[(kind, key)] = found
        else:
            self.hits += 1
        return found[0]

    def serial(self, feature: LinearFeature) -> tuple[int, float]:
        """A number naming ``feature`` for as long as it lives, and its length."""
        entry = self._serials.get(id(feature))
        if entry is None or entry[1]() is not feature:
            entry = (self._next_serial, weakref.ref(feature), feature.length)
            self._next_serial += 1
            self._serials[id(feature)] = entry
        return entry[0], entry[2]


def _explained(checks: list[tuple[int, LinearFeature, np.ndarray, np.ndarray]],
               cone_deg: float, tol: float, share: float = 0.8) -> list[bool]:
    """:func:`_explains` for many (index, feature, sensors, ranges) at once (same answers:
    the cone geometry is worked out element by element either way)."""
    from sim2d.sonar import nearest_in_cone
    sizes = np.array([len(c[2]) for c in checks])
    sensors = np.concatenate([c[2] for c in checks])
    ranges = np.concatenate([c[3] for c in checks])
    segments = np.repeat(np.array([[*c[1].p0, *c[1].p1, 0.0] for c in checks]), sizes, axis=0)
    dist = nearest_in_cone(sensors[:, 0], sensors[:, 1], np.cos(sensors[:, 2]),
                           np.sin(sensors[:, 2]), segments, math.radians(cone_deg) / 2)[0]
    predicted = np.where(np.isfinite(dist), np.maximum(dist, 0.0), np.inf)
    agree = np.add.reduceat((np.abs(predicted - ranges) <= tol).astype(np.float64),
                            np.cumsum(sizes) - sizes)
    return [bool(a / n >= share) for a, n in zip(agree.tolist(), sizes.tolist())]


#: How far (m) a segment must lie beyond a sensor's back or a cone edge to be passed over by
#: :func:`_distances_in_cones`: far more than the rounding of coordinates of metres.
_CLEAR_OUT = 1e-9


def _distances_in_cones(ox: np.ndarray, oy: np.ndarray, c: np.ndarray, s: np.ndarray,
                        ends: np.ndarray, which: np.ndarray, half_angle: float) -> np.ndarray:
    """:func:`sim2d.sonar.nearest_in_cone`'s distance for pairs (all (P,)) of sensors at
    (``ox``, ``oy``) heading (``c``, ``s``) = (cos, sin) and segments ``ends[which]``
    (``ends`` (F, 4): x0, y0, x1, y1, of radius 0), working out only the pairs it might
    not find ``inf``.

    Why: most pairs a box test leaves are segments behind the sensor or to one side of
    its cone.  A segment whose two ends lie behind the sensor (along its heading:
    ``x < -_CLEAR_OUT``), or both outside the same edge of its wedge, is ``inf`` there
    too: its nearest point in the wedge lies between the ends, behind; and the wedge
    clip leaves no part of it (``t0 > t1``).  The others are worked out by
    ``nearest_in_cone`` itself, element by element, so the result is the same.  The
    end points are read a coordinate at a time, and the (P, 5) segments that
    ``nearest_in_cone`` takes are built for the pairs kept only.
    """
    from sim2d.sonar import nearest_in_cone
    ax, ay = ends[:, 0][which] - ox, ends[:, 1][which] - oy
    bx, by = ends[:, 2][which] - ox, ends[:, 3][which] - oy
    px, py = c * ax + s * ay, -s * ax + c * ay  # the ends in the sensor's frame
    qx, qy = c * bx + s * by, -s * bx + c * by
    sa, ca = math.sin(half_angle), math.cos(half_angle)
    out = (px < -_CLEAR_OUT) & (qx < -_CLEAR_OUT)
    for nx, ny in ((sa, -ca), (sa, ca)):  # inside the wedge: nx * x + ny * y >= 0
        out |= (nx * px + ny * py < -_CLEAR_OUT) & (nx * qx + ny * qy < -_CLEAR_OUT)
    keep = np.flatnonzero(~out)
    segments = np.zeros((len(keep), 5))
    segments[:, :4] = ends[which[keep]]
    dist = np.full(len(ox), np.inf)
    dist[keep] = nearest_in_cone(ox[keep], oy[keep], c[keep], s[keep], segments,
                                 half_angle)[0]
    return dist


def _explains(feature: LinearFeature, sensors: np.ndarray, ranges: np.ndarray,
              cone_deg: float, tol: float, share: float = 0.8) -> bool:
    """Would a sonar read what these sensors read if the feature were the wall?

    Echo points that line up are not always a wall: a sensor closing in on a
    corner or sweeping an end wall also draws a line.  A real wall predicts
    the readings that found it (O'Sullivan's check, applied to the feature
    itself).
    """
    from sim2d.sonar import cone_ranges
    segment = np.array([[*feature.p0, *feature.p1, 0.0]])
    predicted, _ = cone_ranges(sensors, segment, math.radians(cone_deg) / 2, np.inf)
    return float(np.mean(np.abs(predicted - ranges) <= tol)) >= share


def gap_along(a: LinearFeature, b: LinearFeature) -> float:
    """Gap (m) between the two features' extents along ``a``'s line; negative if they overlap."""
    direction = np.array([a.normal[1], -a.normal[0]])
    a0, a1 = sorted((0.0, float(np.dot(a.p1 - a.p0, direction))))
    b0, b1 = sorted((float(np.dot(b.p0 - a.p0, direction)), float(np.dot(b.p1 - a.p0, direction))))
    return max(a0, b0) - min(a1, b1)


def _mergeable(a: LinearFeature, b: LinearFeature, angle_tol: float, offset_tol: float,
               max_gap: float) -> bool:
    if np.dot(a.normal, b.normal) < math.cos(angle_tol):
        return False  # different directions, or the two faces of a thin wall
    if max(abs(np.dot(b.p0 - a.p0, a.normal)), abs(np.dot(b.p1 - a.p0, a.normal))) > offset_tol:
        return False
    return gap_along(a, b) <= max_gap


_QUICK_SLACK = 1e-9  # m (and cosine): see _mergeable_quick


def _mergeable_quick(a: tuple, b: tuple, cos_tol: float, offset_tol: float,
                     max_gap: float, slack: float = _QUICK_SLACK) -> bool | None:
    """:func:`_mergeable` in plain floats, from (nx, ny, x0, y0, x1, y1, ...) tuples; None
    when a test lands within ``slack`` of its bound, where the two roundings (a few
    units in the last place of metres) could disagree."""
    anx, any_, ax0, ay0, ax1, ay1 = a[:6]
    bnx, bny, bx0, by0, bx1, by1 = b[:6]
    dot = anx * bnx + any_ * bny
    if abs(dot - cos_tol) <= slack:
        return None
    if dot < cos_tol:
        return False
    o0 = abs((bx0 - ax0) * anx + (by0 - ay0) * any_)
    o1 = abs((bx1 - ax0) * anx + (by1 - ay0) * any_)
    if abs(o0 - offset_tol) <= slack or abs(o1 - offset_tol) <= slack:
        return None
    if max(o0, o1) > offset_tol:
        return False
    dx, dy = any_, -anx  # along a's line, as gap_along
    a0, a1 = sorted((0.0, (ax1 - ax0) * dx + (ay1 - ay0) * dy))
    b0, b1 = sorted(((bx0 - ax0) * dx + (by0 - ay0) * dy, (bx1 - ax0) * dx + (by1 - ay0) * dy))
    gap = max(a0, b0) - min(a1, b1)
    if abs(gap - max_gap) <= slack:
        return None
    return gap <= max_gap


def moved(f: LinearFeature, rotation: np.ndarray, pivot: np.ndarray,
          shift: np.ndarray) -> LinearFeature:
    """The feature after the rigid motion x -> pivot + rotation (x - pivot) + shift."""
    def move(x: np.ndarray) -> np.ndarray:
        return (x - pivot) @ rotation.T + pivot + shift
    return LinearFeature(p0=move(f.p0), p1=move(f.p1), normal=rotation @ f.normal,
                         points=move(f.points), residual=f.residual)


def _refit(points: np.ndarray, normal_hint: np.ndarray) -> LinearFeature:
    centre, direction, d = _fit_line_offsets(points)
    normal = np.array([-direction[1], direction[0]])
    if np.dot(normal, normal_hint) < 0:
        normal = -normal
    along = d @ direction
    across = d @ normal
    # np.mean(across ** 2), the same sum and division
    return LinearFeature(p0=centre + along.min() * direction, p1=centre + along.max() * direction,
                         normal=normal, points=points,
                         residual=float(np.sqrt(np.add.reduce(across ** 2) / len(across))))


def merge_features(features: list[LinearFeature], *, angle_tol_deg: float = 6.0,
                   offset_tol: float = 0.1, max_gap: float = 0.3,
                   memo: FeatureMemo | None = None) -> list[LinearFeature]:
    """Merge features that are the same wall seen by several sensors or at several times.

    Two features merge when they face the same way within ``angle_tol_deg``,
    one's end points lie within ``offset_tol`` (m) of the other's line, and
    they overlap or leave a gap of at most ``max_gap`` (m) along it.  The
    merged feature is refitted to the union of the echoes, so support adds up.
    Features are merged longest first, which keeps the result deterministic.
    With a :class:`FeatureMemo`, merges of the same two features made in an
    earlier call are looked up (same result).
    """
    angle_tol = math.radians(angle_tol_deg)
    cos_tol = math.cos(angle_tol)
    if memo is not None:
        memo.configure("merge", (angle_tol_deg, offset_tol, max_gap))

    def numbers(f: LinearFeature) -> tuple:
        """The feature's numbers as floats, carried with it through the passes: (nx, ny,
        x0, y0, x1, y1, length, serial, the feature, support)."""
        serial, length = memo.serial(f) if memo is not None else (-1, f.length)
        return (*f.normal.tolist(), *f.p0.tolist(), *f.p1.tolist(), length, serial, f,
                f.support)

    def order(e: tuple) -> tuple[int, float]:
        return -e[9], -e[6]

    def mergeable(g: tuple, f: tuple) -> bool:
        sure = _mergeable_quick(g, f, cos_tol, offset_tol, max_gap)
        return _mergeable(g[8], f[8], angle_tol, offset_tol, max_gap) if sure is None else sure

    def merged(g: tuple, f: tuple) -> tuple:
        a, b = g[8], f[8]
        if memo is None:
            return numbers(_refit(np.vstack([a.points, b.points]), a.normal))
        return numbers(memo.lookup("merged", (g[7], f[7]),
                                   lambda: _refit(np.vstack([a.points, b.points]), a.normal)))

    pool = sorted((numbers(f) for f in features), key=order)
    merged_any = True
    while merged_any:
        merged_any = False
        out: list[tuple] = []
        facing: list[tuple[float, float]] = []  # each kept feature's normal
        for f in pool:
            fx, fy = f[0], f[1]
            for i, (gx, gy) in enumerate(facing):
                # most pairs face different ways: _mergeable_quick's first test, inline
                if gx * fx + gy * fy - cos_tol < -_QUICK_SLACK:
                    continue
                if mergeable(out[i], f):
                    g = out[i] = merged(out[i], f)
                    facing[i] = g[0], g[1]
                    merged_any = True
                    break
            else:
                out.append(f)
                facing.append((fx, fy))
        pool = sorted(out, key=order)
    return [e[8] for e in pool]


def predict_ranges(sensors: np.ndarray, features: list[LinearFeature], cone_deg: float,
                   max_range: float, chunk: int = 256, *, ids: np.ndarray | None = None,
                   memo: FeatureMemo | None = None) -> np.ndarray:
    """The range at which each sensor's cone first meets a feature (``inf`` if none).

    ``sensors`` is (M, 3).  Uses the simulator's exact cone geometry
    (:func:`sim2d.sonar.cone_ranges`), so a prediction is what a sonar would
    read if the features were the only walls.  With a :class:`FeatureMemo`
    and ``ids`` (M,) naming the sensor poses (increasing), each feature's ranges
    for poses it was met with in the last call are looked up (same result: the
    geometry is worked out element by element, the nearest taken exactly; see
    :func:`_kept_predictions`).
    """
    from sim2d.sonar import cone_ranges_near

    sensors = np.asarray(sensors, dtype=np.float64).reshape(-1, 3)
    if not features:
        return np.full(len(sensors), np.inf)
    half = math.radians(cone_deg) / 2
    if memo is not None:
        if ids is None:
            raise ValueError("a memo needs the sensors' ids")
        ids = np.asarray(ids, dtype=np.int64)
        if len(ids) != len(sensors) or (np.diff(ids) <= 0).any():
            raise ValueError("the sensors' ids must be one each, increasing")
        memo.configure("predict", (float(cone_deg), float(max_range)))
        return _kept_predictions(sensors, features, half, max_range, ids, memo)
    segments = np.array([[*f.p0, *f.p1, 0.0] for f in features])
    return cone_ranges_near(sensors, segments, half, max_range, chunk)


def _box_pairs(ends: np.ndarray, features: np.ndarray, sx: np.ndarray, sy: np.ndarray,
               sensors: np.ndarray | None, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """The pairs (feature, sensor) of ``features`` (indices into ``ends`` (F, 4)) and
    ``sensors`` (indices into ``sx``, ``sy``; None: all) with the sensor within ``reach``
    of the segment's bounding box: those that may see it.  Feature by feature, as
    ``np.nonzero`` goes."""
    x = sx if sensors is None else sx[sensors]
    y = sy if sensors is None else sy[sensors]
    e = ends[features]
    x0, x1 = np.minimum(e[:, 0], e[:, 2]), np.maximum(e[:, 0], e[:, 2])
    y0, y1 = np.minimum(e[:, 1], e[:, 3]), np.maximum(e[:, 1], e[:, 3])
    near = (x[None, :] >= (x0 - reach)[:, None]) & (x[None, :] <= (x1 + reach)[:, None]) \
        & (y[None, :] >= (y0 - reach)[:, None]) & (y[None, :] <= (y1 + reach)[:, None])
    k, i = np.nonzero(near)
    return features[k], (i if sensors is None else sensors[i])


def _kept_predictions(sensors: np.ndarray, features: list[LinearFeature], half: float,
                      max_range: float, ids: np.ndarray, memo: FeatureMemo) -> np.ndarray:
    """:func:`predict_ranges` with a memo: each feature's finite ranges at the sensors
    ``ids`` (increasing) of the last call that met it are looked up, and only the pairs of
    it and the sensors not in that call are worked out.

    Why: a feature's ranges are kept as the ids and ranges of the sensors that see it
    (a few hundred), not a row over every sensor of the call (thousands, most ``inf``);
    the sensors of a kept call are box-tested once per call, not per feature.  The
    nearest range is a minimum, exact in any order, of the same element-by-element
    distances, so the result is that of the call without a memo.
    """
    reach = max_range + 1e-6  # farther than this from a segment's box: cannot see it
    ends = np.array([[*f.p0, *f.p1] for f in features])  # (F, 4)
    out = np.full(len(sensors), np.inf)
    groups: dict[int, tuple[np.ndarray | None, list[int]]] = {-1: (None, [])}
    kept: list[tuple[np.ndarray, np.ndarray]] = []  # per feature: its known finite ranges
    keys = []
    for k, f in enumerate(features):
        key = memo.serial(f)[0]
        keys.append(key)
        known = memo.get("predict", key)
        if known is None:
            groups[-1][1].append(k)
            kept.append((ids[:0], out[:0]))
            continue
        known_ids, seen_ids, seen = known
        if id(known_ids) not in groups:  # the features kept by one call share its ids
            at = np.minimum(np.searchsorted(known_ids, ids), len(known_ids) - 1)
            groups[id(known_ids)] = (np.flatnonzero(known_ids[at] != ids), [])
        groups[id(known_ids)][1].append(k)
        at = np.minimum(np.searchsorted(ids, seen_ids), len(ids) - 1)
        here = ids[at] == seen_ids  # those of the last call's sensors still here
        at = at[here]
        out[at] = np.minimum(out[at], seen[here])  # one sensor each
        kept.append((seen_ids[here], seen[here]))
    pairs = [_box_pairs(ends, np.array(members, dtype=np.int64), sensors[:, 0], sensors[:, 1],
                        cand, reach) for cand, members in groups.values() if members]
    which = np.concatenate([p[0] for p in pairs])
    i = np.concatenate([p[1] for p in pairs])
    # each sensor's heading once (cos and sin are worked out element by element)
    c, s = np.cos(sensors[:, 2]), np.sin(sensors[:, 2])
    dist = _distances_in_cones(sensors[i, 0], sensors[i, 1], c[i], s[i], ends, which, half)
    seen = np.flatnonzero(dist <= max_range)
    which, i, found = which[seen], i[seen], np.maximum(dist[seen], 0.0)
    np.minimum.at(out, i, found)
    order = np.argsort(which, kind="stable")
    bounds = np.concatenate([[0], np.cumsum(np.bincount(which, minlength=len(features)))])
    found_ids, found = ids[i[order]], found[order]
    for k, key in enumerate(keys):
        a, b = bounds[k], bounds[k + 1]
        memo.store("predict", key, (ids, np.concatenate([kept[k][0], found_ids[a:b]]),
                                    np.concatenate([kept[k][1], found[a:b]])))
    return out
