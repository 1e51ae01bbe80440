"""The textual sign detector: find door-sign plates in a camera frame, cheaply.

A door sign is a light, colourless (grey-white) plate with a dark rim and dark
text, hung flat on a wall. The detector runs on every camera tick, so it
uses a handful of whole-frame OpenCV operations (about 0.5 ms on a 320x240
frame) and then looks only at the few candidate blobs:

1. *Plate body mask.* Box-smooth the frame (3x3, to tame the sensor noise),
   then keep pixels that are colourless (``max - min`` of B, G, R small
   relative to ``max``) and bright (``min`` channel high). Painted walls,
   floors and skirting boards are coloured at every brightness, so they drop
   out; what is left is the plates, and the off-white ceiling.
2. *Candidates.* Connected components of that mask, pruned by size. Large
   letters can cut a small plate's body into an upper and a lower strip:
   pieces spanning the same columns, one just above the other, are joined.
3. *Quadrilateral.* The camera has no roll (a pan-tilt head on a level
   robot), so a plate's vertical edges stay vertical in the image. Each blob
   becomes a quad with vertical sides at its left and right extent and
   straight top and bottom edges, fitted (least squares, trimming outliers)
   to the blob's per-column top and bottom rows; it is then grown by the
   plate's dark rim, which the bright mask leaves out. Where the image border
   cuts a plate, only the columns where wall shows beyond the body's edge
   give that edge (letters may reach the border).
4. *Plate-likeness.* A blob is a plate only if (a) it fills its quad (it is
   a quadrilateral, not a ceiling wedge), (b) its top and bottom edges are
   straight, (c) a ring round it is darker, but not black (a wall, not the
   letter around a letter's white counter), (d) it holds text: a moderate
   share of clearly darker, colourless pixels in its interior, spread across
   its width, and (e) its shape is a plate's: the two vertical edges,
   back-projected with the known plate height, give a metric width of about
   three plate heights and put the plate's centre at the same height (its
   top and bottom edges meet on the horizon). A blank bright rectangle (a
   window, a ceiling light, the ceiling seen through a door) fails (d); the
   ceiling fails (a), (c), (d) (walls seen through it are coloured) or (e).
   Detections lying inside a larger one (pieces of it) are dropped.

Geometry (pinhole, see :class:`~blocks.signs.types.CameraModel`): a vertical
edge of apparent height ``h`` px at column ``u`` lies at depth
``x = f * H / h`` and lateral offset ``y = x * (cx - u) / f``; the plate's
centre is the mean of its two edge points, ``range = hypot(x, y)``, and the
bearing is that of the quad's centre (the crossing of its diagonals, which
perspective keeps at the plate's centre), ``atan2(cx - u_c, f)``. Plates cut
by the image border are marked ``clipped``; their centre is found from the
edge or the sides still whole (see :func:`_geometry`).

On sim2d's office and hospital worlds (``benchmarks/sign_detector.py``) the
detector finds 99.5 % of the plates at least 12 px tall seen within 70 deg of
head-on and 90 % of all plates at least 6 px tall, with no false positive in
25,000 sampled views; ranges of whole plates are within 8 % (95th
percentile), bearings within 0.1 deg, corners within about a pixel.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from .types import PLATE_HEIGHT, PLATE_WIDTH, CameraModel, PlateDetection

__all__ = ["DetectorParams", "above", "body_mask", "box_iou", "components", "detect_plates",
           "detection_of", "drop_nested", "level_floors", "is_detectable", "match_detections",
           "measure_blob", "reject_blob", "smoothed_extremes"]


@dataclass(frozen=True)
class DetectorParams:
    """Tunables of :func:`detect_plates`.

    Attributes
    ----------
    min_level : int
        Darkest ``min(B, G, R)`` (0..255) a plate body may have. Plates are
        light (about 238 head-on near the lamp, ~130 at 12 m and 70 deg);
        the wall's blue channel stays well below the plate's at any distance.
    max_chroma : float
        Largest ``(max - min) / max`` of a plate-body pixel. The sim's walls
        have ~0.23, the floor ~0.34, the plates 0 (plus noise).
    chroma_floor : float
        Grey levels of ``max - min`` always allowed (noise on dim plates).
    min_area : int
        Smallest blob (px) considered; smaller blobs cannot show text anyway.
    min_height : float
        Smallest apparent height (px) of the plate's taller vertical edge.
    min_width : float
        Smallest apparent width (px) of the plate.
    min_fill : float
        Share of the fitted quad the blob (its column spans) must cover.
    max_edge_residual : float
        Largest RMS residual (px, plus 4 % of the height) of the top and
        bottom edges around their fitted lines.
    min_contrast : float
        The ring around the plate must be at least this much darker than the
        plate body (fraction of the body's level).
    max_contrast : float
        ... and at most this much: a plate hangs on a wall, not on black. The
        white counters inside big letters ("O", "R") are bright, rectangular
        and ringed by black; this rejects them.
    min_text_fill, max_text_fill : float
        Bounds on the share of the plate's interior that is clearly darker
        than its body (text). A blank plate has ~0.
    min_text_span : float
        The dark pixels must span at least this share of the interior's width.
    text_dark_ratio : float
        A pixel is "dark" (text) when its level is below this fraction of the
        body's level.
    max_text_chroma : float
        Largest median chroma (``max - min``) of the dark interior pixels, as
        a share of the body's level: text is black; a coloured wall between
        two bright pieces is not text.
    min_aspect, max_aspect : float
        Bounds on the reconstructed metric width / height of a whole
        (unclipped) plate; the standard plate is 3:1, and one 60 % hidden
        behind a wall's edge looks 1.8:1.
    height_error, height_error_share : float
        The error (px, plus a share of the height) allowed on each vertical
        edge's height when checking the aspect (see :func:`_aspect_range`).
    max_height_ratio : float
        Largest ratio of the two vertical edges' heights (perspective).
    max_z_mismatch : float
        Largest difference (in plate heights) between the heights of the
        plate's centre above the camera computed from each vertical edge:
        a vertical rectangle's top and bottom edges meet at the horizon.
    rim_height, rim_width : float
        How far the plate's outer edges lie beyond the bright body's: the
        dark rim (5 % of the plate's height, 1/60 of its width) plus the
        threshold's place in the blurred edge, as shares of each vertical
        edge's height (top and bottom) and of the body's width (sides).
        Calibrated on sim2d frames (``benchmarks/sign_detector.py``).
    edge_offset : float
        Added to every side's growth (px): the 3x3 smoothing spreads the
        bright mask about 1 px past the body.

    Raises
    ------
    ValueError
        If ``max_chroma`` or ``chroma_floor`` is negative (no pixel would be
        colourless) or ``min_level`` is not a level (0..255).
    """

    min_level: int = 90
    max_chroma: float = 0.11
    chroma_floor: float = 6.0
    min_area: int = 24
    min_height: float = 5.0
    min_width: float = 5.0
    min_fill: float = 0.82
    max_edge_residual: float = 1.0
    min_contrast: float = 0.2
    max_contrast: float = 0.8
    min_text_fill: float = 0.12
    max_text_fill: float = 0.85
    min_text_span: float = 0.3
    text_dark_ratio: float = 0.75
    min_aspect: float = 1.5
    max_aspect: float = 4.8
    max_text_chroma: float = 0.05
    height_error: float = 0.75
    height_error_share: float = 0.03
    max_height_ratio: float = 3.0
    max_z_mismatch: float = 0.8
    rim_height: float = 0.067
    rim_width: float = 0.021
    edge_offset: float = -0.85

    def __post_init__(self) -> None:
        if not (self.max_chroma >= 0 and self.chroma_floor >= 0):
            raise ValueError(f"max_chroma and chroma_floor must be >= 0, got {self.max_chroma} "
                             f"and {self.chroma_floor}")
        if not 0 <= self.min_level <= 255:
            raise ValueError(f"min_level must be in 0..255, got {self.min_level}")

    @cached_property
    def floors(self) -> tuple[np.ndarray, np.ndarray]:
        """:func:`level_floors` of these parameters, made once (the detector's per-frame tables)."""
        return level_floors(self)

    @cached_property
    def allowance(self) -> tuple[float, float] | None:
        """:func:`grey_floor_image`'s affine rounding for these parameters (None: use the table)."""
        return _allowance_affine(self.max_chroma, self.chroma_floor, self.floors[0])


DEFAULT_PARAMS = DetectorParams()


def body_mask(image: np.ndarray, params: DetectorParams = DEFAULT_PARAMS
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Masks and levels of the 3x3 box-smoothed frame.

    Returns the plate-body mask (colourless and bright, uint8 0/1), the
    colourless mask (bool), the ``min`` channel and the chroma ``max - min``.
    The ``min`` channel is what the later checks measure levels on: it is the
    one in which a white plate stands out most from a warm-coloured wall.
    """
    hi, lo = smoothed_extremes(image)
    grey_floor, body_floor = level_floors(params)
    return (_at_least(lo, hi, body_floor).view(np.uint8), _at_least(lo, hi, grey_floor), lo,
            cv2.subtract(hi, lo))


def smoothed_extremes(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``max`` and ``min`` of B, G, R of the 3x3 box-smoothed frame ((H, W) uint8 each)."""
    b, g, r = cv2.split(cv2.blur(image, (3, 3)))
    return cv2.max(cv2.max(b, g), r), cv2.min(cv2.min(b, g), r)


def level_floors(params: DetectorParams = DEFAULT_PARAMS) -> tuple[np.ndarray, np.ndarray]:
    """The darkest ``min`` level of a colourless pixel and of a plate-body pixel, per ``max`` level.

    A pixel is colourless when its chroma ``max - min`` is at most ``limit =
    max_chroma * max + chroma_floor`` (computed in float32); levels being
    integers, that is ``min >= max - floor(limit)``. A plate-body pixel is
    also bright, ``min >= min_level``. Either mask is then one table lookup
    and one comparison per pixel (:func:`_at_least`), with no float image;
    :func:`detect_plates` makes the grey floor image by an affine rounding that
    reproduces the table (:func:`grey_floor_image`), cheaper than the lookup.

    Returns
    -------
    grey_floor, body_floor : (256,) uint8 arrays
        Indexed by the ``max`` level.

    Examples
    --------
    >>> grey, body = level_floors()
    >>> grey[[0, 100, 255]].tolist(), body[[0, 100, 255]].tolist()
    ([0, 83, 221], [90, 90, 221])
    """
    levels = np.arange(256, dtype=np.uint8).astype(np.float32)
    limit = levels * np.float32(params.max_chroma) + np.float32(params.chroma_floor)
    grey = np.maximum(np.arange(256) - np.minimum(np.floor(limit), 255).astype(int), 0)
    return grey.astype(np.uint8), np.maximum(grey, params.min_level).astype(np.uint8)


def _allowance_affine(max_chroma: float, chroma_floor: float, grey_floor: np.ndarray
                      ) -> tuple[float, float] | None:
    """``(alpha, beta)`` such that ``hi - convertScaleAbs(hi, alpha, beta)`` is ``grey_floor[hi]``.

    The chroma allowance ``floor(max_chroma * max + chroma_floor)`` is one
    rounding of an affine function of the level (``cv2.convertScaleAbs``, a
    vectorised pass), where the table needs a lookup per pixel (``cv2.LUT``,
    several times slower). Rounding to the nearest from just under half a
    level below is the floor unless the affine value falls just short of an
    integer, which depends on the parameters: the candidate is checked on
    every level, at every place in a row of SIMD lanes, against the table,
    and None returned (use the table) if it differs anywhere.
    """
    alpha, beta = float(max_chroma), float(chroma_floor) - 0.5 + 0.005
    levels = np.tile(np.arange(256, dtype=np.uint8), 302)  # 77,312 values
    for shape in ((240, 320), (64, 1001), (7, 13)):
        for offset in (0, 1, 3, 7, 17, 31):
            hi = levels[offset:offset + shape[0] * shape[1]].reshape(shape)
            grey = cv2.subtract(hi, cv2.convertScaleAbs(hi, alpha=alpha, beta=beta))
            if not np.array_equal(grey, grey_floor[hi]):
                return None
    return alpha, beta


def grey_floor_image(hi: np.ndarray, params: DetectorParams = DEFAULT_PARAMS) -> np.ndarray:
    """``level_floors(params)[0][hi]``: per pixel, the darkest ``min`` level of a colourless pixel.

    Computed by :attr:`DetectorParams.allowance`'s affine rounding where it
    reproduces the table exactly (the default parameters), else by the table.

    Examples
    --------
    >>> grey_floor_image(np.array([[0, 100, 255]], np.uint8)).tolist()
    [[0, 83, 221]]
    """
    if params.allowance is None:
        return cv2.LUT(hi, params.floors[0])
    alpha, beta = params.allowance
    return cv2.subtract(hi, cv2.convertScaleAbs(hi, alpha=alpha, beta=beta))


def _at_least(lo: np.ndarray, hi: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """Bool mask: ``lo >= floor[hi]`` per pixel."""
    return lo >= cv2.LUT(hi, floor)


def detect_plates(image: np.ndarray, camera: CameraModel,
                  params: DetectorParams = DEFAULT_PARAMS,
                  plate_height: float = PLATE_HEIGHT,
                  explain: list | None = None) -> list[PlateDetection]:
    """Find the sign plates in a BGR frame.

    Parameters
    ----------
    image : ndarray (H, W, 3) uint8
        BGR camera frame.
    camera : CameraModel
        The frame's intrinsics (focal length at its zoom, principal point
        including the tilt shift).
    params : DetectorParams
    plate_height : float
        Physical plate height (m), for the range.
    explain : list, optional
        When given, each rejected candidate blob is appended to it as
        ``(bbox, reason, features)`` (for tuning; blobs pruned by size alone
        are not).

    Returns
    -------
    list of PlateDetection, best score first.
    """
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected a BGR uint8 image (H, W, 3), got {image.dtype} "
                         f"{image.shape}")
    if image.shape[:2] != (camera.height, camera.width):
        raise ValueError(f"the image is {image.shape[1]}x{image.shape[0]} but the camera "
                         f"model is {camera.width}x{camera.height}")
    # the body mask (as body_mask), and the rest of it only where a candidate needs it
    hi, level = smoothed_extremes(image)
    grey_floor = grey_floor_image(hi, params)  # (the body floor is this or min_level)
    mask = (level >= cv2.max(grey_floor, params.min_level)).view(np.uint8)
    if cv2.countNonZero(mask) < params.min_area:
        return []  # no candidate can be big enough (most frames: walls, floor, no ceiling)
    labels, stats = components(mask)
    blobs = _blobs(stats, params)
    H = image.shape[0]
    grey_sums = None
    if any(y == 0 or y + h == H for (_, y, _, h), _ in blobs):  # (only these look at it)
        grey_sums = cv2.integral((level >= grey_floor).view(np.uint8))
    out = []
    for box, ks in blobs:
        feats = measure_blob(labels, ks, box, level, hi, grey_sums, camera, plate_height, params,
                         explain is None)
        reason = feats if isinstance(feats, str) else reject_blob(feats, params)
        if reason is None:
            out.append(detection_of(feats, params))
        elif explain is not None:
            x, y, w, h = box
            explain.append(((x, y, x + w - 1, y + h - 1), reason,
                            None if isinstance(feats, str) else feats))
    out = drop_nested(out)
    out.sort(key=lambda d: -d.score)
    return out


def components(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """8-connected components of a 0/1 mask, with their boxes and areas.

    The same labels and statistics as ``cv2.connectedComponentsWithStats(mask,
    connectivity=8)``, about five times cheaper: OpenCV's statistics pass costs
    ten times its labelling, so the boxes and areas are gathered here from the
    mask's horizontal runs (a few hundred per frame) instead of its pixels.

    Parameters
    ----------
    mask : (H, W) uint8 array
        0 or 1.

    Returns
    -------
    labels : (H, W) uint16 array (int32 if the frame may hold 65,535 components)
        0 for the background, 1.. for the components.
    stats : (N, 5) int64 array
        Per label: left, top, width, height and area (OpenCV's ``CC_STAT_*``
        order); row 0 (the background) is all zeros.

    Examples
    --------
    >>> m = np.array([[1, 1, 0, 0], [0, 0, 0, 1], [0, 0, 1, 1]], np.uint8)
    >>> components(m)[1].tolist()
    [[0, 0, 0, 0, 0], [0, 0, 2, 1, 2], [2, 1, 2, 2, 3]]
    """
    H, W = mask.shape
    # 8-connected components are at most one per 2x2 block: 16-bit labels (half the
    # memory to compare a blob's box against) whenever they fit
    ltype = cv2.CV_16U if ((H + 1) // 2) * ((W + 1) // 2) < 65535 else cv2.CV_32S
    n, labels = cv2.connectedComponents(mask, connectivity=8, ltype=ltype)
    padded = cv2.copyMakeBorder(mask, 0, 0, 1, 1, cv2.BORDER_CONSTANT, value=0)
    # the value changes at a run's first pixel and just past its last: in each
    # row (padded with zeros) and so in the whole frame, starts and ends alternate
    steps = np.flatnonzero(cv2.bitwise_xor(padded[:, 1:], padded[:, :-1]).view(bool))
    starts, ends = steps[0::2], steps[1::2]
    rows = starts // (W + 1)
    x0 = starts - rows * (W + 1)
    x1 = ends - rows * (W + 1)
    label = labels[rows, x0]
    left = np.full(n, W, np.int64)
    np.minimum.at(left, label, x0)
    right = np.zeros(n, np.int64)
    np.maximum.at(right, label, x1)
    top = np.full(n, H, np.int64)
    np.minimum.at(top, label, rows)
    bottom = np.full(n, -1, np.int64)
    np.maximum.at(bottom, label, rows)
    stats = np.column_stack([left, top, right - left, bottom + 1 - top,
                             np.bincount(label, weights=x1 - x0, minlength=n).astype(np.int64)])
    stats[0] = 0
    return labels, stats


def drop_nested(dets: list[PlateDetection]) -> list[PlateDetection]:
    """Drop detections lying mostly (60 %) inside a larger one's box.

    A plate holds no plate: what passes inside one is a piece of it (a
    letter's counter, a strip of a plate cut by the image border).
    """
    def area(b: tuple[int, int, int, int]) -> int:
        return (b[2] - b[0] + 1) * (b[3] - b[1] + 1)

    kept: list[PlateDetection] = []
    for det in sorted(dets, key=lambda d: -area(d.bbox)):
        b = det.bbox
        nested = False
        for big in kept:
            g = big.bbox
            ix = min(b[2], g[2]) - max(b[0], g[0]) + 1
            iy = min(b[3], g[3]) - max(b[1], g[1]) + 1
            if ix > 0 and iy > 0 and ix * iy >= 0.6 * area(b):
                nested = True
                break
        if not nested:
            kept.append(det)
    return kept


def _blobs(stats: np.ndarray, params: DetectorParams
           ) -> list[tuple[tuple[int, int, int, int], tuple[int, ...]]]:
    """Candidate blobs: components big enough, with the pieces of split plates joined.

    Large letters can cut a small plate's body into an upper and a lower
    strip; two pieces spanning nearly the same columns, one just above the
    other, are joined into one candidate (the checks then judge the union).
    """
    width, height, size = stats[:, 2], stats[:, 3], stats[:, 4]
    keep = (size >= 6) & (width >= 3) & (size >= 0.25 * width * height)
    keep[0] = False  # the background
    ks = np.flatnonzero(keep)
    # (label, left, top, width, height, area) of each piece
    pieces = [tuple(p) for p in np.column_stack([ks, stats[ks]]).tolist()]
    parent = {p[0]: p[0] for p in pieces}

    def root(k: int) -> int:
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    small = np.array([p[:5] for p in pieces if p[3] * p[4] <= 4000], dtype=np.int64).reshape(-1, 5)
    if len(small) > 1:
        k, x, y, w, h = (small[:, i] for i in range(5))
        overlap = np.minimum((x + w)[:, None], (x + w)[None, :]) - np.maximum(x[:, None], x[None, :])
        same_columns = overlap >= 0.8 * np.maximum(w[:, None], w[None, :])
        # b (column) just below a (row): starts lower, within 60 % of the taller's
        # height of a's bottom, and ends lower
        below = ((y[None, :] > y[:, None])
                 & (y[None, :] - (y + h)[:, None] <= 0.6 * np.maximum(h[:, None], h[None, :]))
                 & ((y + h)[None, :] > (y + h)[:, None]))
        for i, j in zip(*np.nonzero(same_columns & below)):
            parent[root(int(k[j]))] = root(int(k[i]))
    groups: dict[int, list[tuple[int, int, int, int, int, int]]] = {}
    for p in pieces:
        groups.setdefault(root(p[0]), []).append(p)
    out = []
    for members in groups.values():
        if len(members) == 1:
            k, x0, y0, w, h, area = members[0]
        else:
            x0 = min(p[1] for p in members)
            y0 = min(p[2] for p in members)
            w = max(p[1] + p[3] for p in members) - x0
            h = max(p[2] + p[4] for p in members) - y0
            area = sum(p[5] for p in members)
        if area < params.min_area or w < params.min_width - 1 or h < params.min_height - 2:
            continue
        out.append(((x0, y0, w, h), tuple(p[0] for p in members)))
    return out


def above(sums: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Per column, how many pixels of a mask lie above a row.

    ``above(sums, r1, c) - above(sums, r0, c)`` counts the mask's pixels in
    column ``c``, rows ``r0 <= r < r1``.

    Parameters
    ----------
    sums : (H + 1, W + 1) int array
        The mask's integral image (``cv2.integral``).
    rows, cols : (N,) int arrays
        ``0 <= rows <= H``, ``0 <= cols < W``.

    Returns
    -------
    (N,) int array

    Examples
    --------
    >>> sums = cv2.integral(np.array([[1, 0], [1, 1], [0, 1]], np.uint8))
    >>> above(sums, np.array([2, 2]), np.array([0, 1])).tolist()
    [2, 1]
    """
    return sums[rows, cols + 1] - sums[rows, cols]


def _wall_beyond(grey_sums: np.ndarray, cols: np.ndarray, rows: np.ndarray, step: int
                 ) -> np.ndarray:
    """Per column: is any coloured pixel between ``rows`` and the border in direction ``step``?

    ``grey_sums`` is the colourless mask's integral image: a run of rows holds
    a coloured pixel when it holds fewer colourless pixels than rows.
    """
    r = rows.astype(int)
    if step > 0:
        H = grey_sums.shape[0] - 1
        return above(grey_sums, np.full_like(r, H), cols) - above(grey_sums, r + 1, cols) < H - 1 - r
    return above(grey_sums, r, cols) < r


def _fit_edge(cols: np.ndarray, v: np.ndarray, free: np.ndarray, border: float,
              inward: float, robust: bool) -> tuple[float, float, float, bool]:
    """Fit one (top or bottom) edge on the columns where it is not the image border.

    With fewer than three such columns (or a quarter of them) the plate is cut
    off there and the edge is the border row itself (and the last value
    returned, whether the edge was seen, False). ``inward`` is +1 for the
    top edge (the plate lies below it), -1 for the bottom. With ``robust``
    (a plate cut by the border, whose letters may reach it) points inside the
    line are trimmed in a few passes: where a letter touches the border the
    body's extreme pixel lies inside the plate, never outside.
    """
    if not _enough(free):
        return float(border), 0.0, 0.0, False
    u, v = cols[free].astype(np.float64), v[free]
    if not robust:
        return (*_fit_line(u, v), True)
    keep = np.ones(len(u), dtype=bool)
    fit = None  # the fit on the points ``keep`` marks, once made
    for i in range(4):
        fit = a, b, rms = _lsq(u[keep], v[keep]) if i else _lsq(u, v)
        r = (v - (a + b * u)) * inward  # > 0: inside the plate
        new = (r <= max(1.0, 1.5 * rms)) & (r >= -max(1.0, 3.0 * rms))
        if np.count_nonzero(new) < max(3, 0.3 * len(u)) or not (new ^ keep).any():
            break
        keep, fit = new, None
    return (*(fit or _lsq(u[keep], v[keep])), True)


def _enough(free: np.ndarray) -> bool:
    """Whether an edge is seen on enough of its columns (``free``) to fit it (:func:`_fit_edge`)."""
    return np.count_nonzero(free) >= max(3, 0.25 * len(free))


def _fit_line(u: np.ndarray, v: np.ndarray) -> tuple[float, float, float]:
    """``v = a + b * u`` by least squares with one pass of outlier removal; (a, b, rms)."""
    a, b, rms = _lsq(u, v)
    keep = np.abs(v - (a + b * u)) <= max(1.0, 2.0 * rms)
    if 2 <= np.count_nonzero(keep) < len(u):
        a, b, rms = _lsq(u[keep], v[keep])
    return a, b, rms


def _lsq(u: np.ndarray, v: np.ndarray) -> tuple[float, float, float]:
    n = len(u)
    if n < 2:
        return float(v.mean()), 0.0, 0.0
    total = np.add.reduce  # (what ndarray.mean and sum compute, without their overhead)
    um, vm = total(u) / n, total(v) / n
    du = u - um
    denom = float(du @ du)
    b = float(du @ (v - vm)) / denom if denom > 0 else 0.0
    a = float(vm - b * um)
    r = v - a - b * u
    return a, b, math.sqrt(float(total(r * r)) / n)


def measure_blob(labels: np.ndarray, ks: tuple[int, ...], box: tuple[int, int, int, int],
             level: np.ndarray, hi: np.ndarray, grey_sums: np.ndarray | None,
             camera: CameraModel, plate_height: float, params: DetectorParams,
             quick: bool = False) -> dict | str:
    """The features of one blob (or why it cannot be measured, or is too small).

    Coordinates in the returned ``quad`` are image pixels: ``u0, u1`` the
    pixel edges left of the first and right of the last column, and the top
    and bottom lines ``v = a + b * u`` at pixel edges above and below.
    ``level`` and ``hi`` are the smoothed frame's ``min`` and ``max`` channels,
    ``grey_sums`` the colourless mask's integral image (used only if the blob
    touches the top or bottom border). The shape
    checks come first, the cheapest first, and the size checks before the levels
    are measured.

    With ``quick`` (the features of a rejected blob are not wanted, only
    whether it is rejected) a blob whose text fails :func:`reject_blob`'s text
    test is rejected ("text") before its ring is measured and its text's
    colour: most bright blobs that get that far (the ceiling) have no text.
    :func:`reject_blob` rejects a blob when any test fails, so testing one of them
    sooner rejects the same blobs (the reason may differ).
    """
    x, y, w, h = box
    H, W = labels.shape
    sub = labels[y:y + h, x:x + w]
    blob = sub == ks[0]
    for k in ks[1:]:
        blob |= sub == k
    has = blob.any(axis=0)
    cols = np.flatnonzero(has)
    top = np.argmax(blob, axis=0).astype(np.float64)
    bottom = (h - 1 - np.argmax(blob[::-1], axis=0)).astype(np.float64)
    # the top and bottom edges, fitted on the inner columns (the ends are blurred)
    # where they are not the image border
    inner = cols[1:-1] if len(cols) > 4 else cols
    free_t = y + top[inner] > 0
    free_b = y + bottom[inner] < H - 1
    cut = y == 0 or y + h == H
    if cut:
        # a plate cut by the border may have letters reaching it: a column's
        # extreme body pixel is the plate's edge only if wall (not colourless
        # letters or rim) shows between it and the border
        # (an edge seen on too few columns for a fit is the border whatever is beyond)
        if _enough(free_t):
            free_t &= _wall_beyond(grey_sums, x + inner, y + top[inner], -1)
        if _enough(free_b):
            free_b &= _wall_beyond(grey_sums, x + inner, y + bottom[inner], 1)
    a_t, b_t, r_t, seen_t = _fit_edge(inner, top[inner], free_t, -y, 1.0, cut)
    a_b, b_b, r_b, seen_b = _fit_edge(inner, bottom[inner], free_b, H - 1 - y, -1.0, cut)
    u0, u1 = float(cols[0]) - 0.5, float(cols[-1]) + 0.5
    t0, t1 = a_t + b_t * u0 - 0.5, a_t + b_t * u1 - 0.5
    s0, s1 = a_b + b_b * u0 + 0.5, a_b + b_b * u1 + 0.5
    hl, hr = s0 - t0, s1 - t1
    if min(hl, hr) <= 1.0:
        return "too small"
    if max(r_t, r_b) > params.max_edge_residual + 0.04 * 0.5 * (hl + hr):
        return "ragged edges"  # (most blobs, the ceiling, fail here)
    # fill: the blob's column spans (letters count as filled) against the quad's
    # (both within the image)
    uc = cols.astype(np.float64)
    lo_line = np.maximum(a_t + b_t * uc - 0.5, -y - 0.5)
    hi_line = np.minimum(a_b + b_b * uc + 0.5, H - 0.5 - y)
    expected = float(np.maximum(hi_line - lo_line, 0.0).sum())
    if not cut:
        span = float((bottom[cols] - top[cols] + 1).sum())
    else:
        # letters may reach the border and end the body's columns early:
        # count the colourless pixels (body, letters, rim) inside the quad instead
        # (rows ra <= r < rb, and per column those between the lines)
        ra = int(max(0, math.floor(float(lo_line.min()) + y + 0.5)))
        rb = int(min(H, math.ceil(float(hi_line.max()) + y + 0.5)))
        r0 = np.minimum(np.maximum(np.ceil(lo_line - 0.5).astype(int) + y, ra), rb)
        r1 = np.minimum(np.maximum(np.floor(hi_line + 0.5).astype(int) + y + 1, r0), rb)
        span = float((above(grey_sums, r1, x + cols) - above(grey_sums, r0, x + cols)).sum())
    fill = span / expected if expected > 0 else 0.0
    if not params.min_fill <= fill <= 1.0 / params.min_fill:
        return "fill"
    clip = (x == 0, x + w == W, y == 0, y + h == H)
    small = _too_small(hl, hr, u1 - u0, clip, params)
    if small:
        return small
    if w * h < _HIST_MIN:
        body_level = _upper_quartile(level[y:y + h, x:x + w][blob])
    else:
        body_level = _upper_quartile_of_counts(_histogram(level[y:y + h, x:x + w],
                                                          blob.view(np.uint8)))
    quad = (x + u0, x + u1, y + t0, y + t1, y + s0, y + s1)
    text = _text_pixels(level, quad, body_level, params.text_dark_ratio)
    text_fill, text_span = text[:2]
    if quick and not _has_text(text_fill, text_span, params):
        return "text"
    text_chroma = _text_colour(level, hi, text)
    ring_level = _ring_level(level, box)
    return {
        "box": box, "quad": quad, "slopes": (b_t, b_b), "heights": (hl, hr),
        "residual": max(r_t, r_b), "fill": fill, "body_level": body_level,
        "ring_level": ring_level, "text_fill": text_fill, "text_span": text_span,
        "text_chroma": text_chroma,
        "clip": clip, "seen": (seen_t, seen_b),
        "camera": camera, "plate_height": plate_height, "shape": (H, W),
    }


def _too_small(hl: float, hr: float, width: float, clip: tuple[bool, bool, bool, bool],
               params: DetectorParams) -> str | None:
    """"too small" if a blob's quad (edge heights, width, image borders it touches) is."""
    if max(hl, hr) < params.min_height or width < params.min_width:
        return "too small"
    clip_l, clip_r, clip_t, clip_b = clip
    if (clip_t or clip_b) and ((not clip_l and hl < params.min_height)
                               or (not clip_r and hr < params.min_height)):
        # cut by the top or bottom border, its shape is checked only through its
        # sides in view: each must be a real edge (a wedge of ceiling in an
        # image corner has a side of a pixel or two)
        return "too small"
    return None


def reject_blob(f: dict, params: DetectorParams) -> str | None:
    """Why the blob with features ``f`` (big enough) is not a plate (None if it is one)."""
    hl, hr = f["heights"]
    ring = f["ring_level"]
    if ring is None or not (1.0 - params.max_contrast <= ring / f["body_level"]
                            <= 1.0 - params.min_contrast):
        return "contrast"
    if not _has_text(f["text_fill"], f["text_span"], params):
        return "text"
    if f["text_chroma"] > params.max_text_chroma * f["body_level"]:
        return "text colour"
    cut = f["clip"][2] or f["clip"][3]
    if not cut and max(hl, hr) / min(hl, hr) > params.max_height_ratio:
        return "height ratio"
    corners = _outer_corners(f, params)
    geom = _geometry(corners, f["camera"], f["plate_height"], f["clip"], f["seen"])
    f["corners"], f["geometry"] = corners, geom
    if geom is None:
        return "geometry"
    _, _, _, z_mismatch = geom
    lo, hi = _aspect_range(corners, f["camera"], f["plate_height"], params)
    if not any(f["clip"]):
        if hi < params.min_aspect or lo > params.max_aspect:
            return "aspect"
        if z_mismatch > params.max_z_mismatch:
            return "horizon"
    elif not cut and lo > params.max_aspect:
        return "aspect"  # cut at a side: the heights are whole, the width only shorter
    return None


def _has_text(text_fill: float, text_span: float, params: DetectorParams) -> bool:
    """Whether a blob's dark share and its width share are a plate's text's."""
    return (params.min_text_fill <= text_fill <= params.max_text_fill
            and text_span >= params.min_text_span)


def _aspect_range(corners: np.ndarray, camera: CameraModel, plate_height: float,
                  params: DetectorParams) -> tuple[float, float]:
    """Smallest and largest metric width / height of a quad within the height errors.

    The width comes from the depth difference of the two vertical edges,
    which is ill-conditioned for far plates seen nearly head-on (a pixel on
    a 17 px edge is 0.6 m at 10 m): each edge height is varied by
    ``height_error`` px plus ``height_error_share`` of it, both ways.
    """
    f, cx = camera.f, camera.cx
    hl = corners[3, 1] - corners[0, 1]
    hr = corners[2, 1] - corners[1, 1]
    al, ar = (cx - corners[0, 0]) / f, (cx - corners[1, 0]) / f
    dl = params.height_error + params.height_error_share * hl
    dr = params.height_error + params.height_error_share * hr
    cases = [(hl, hr), (hl - dl, hr + dr), (hl + dl, hr - dr), (hl - dl, hr - dr),
             (hl + dl, hr + dr)]
    if max(hl - dl, hr - dr) <= min(hl + dl, hr + dr):  # equal heights possible
        h = 0.5 * (max(hl - dl, hr - dr) + min(hl + dl, hr + dr))
        cases.append((h, h))
    values = []
    for a, b in cases:
        if a <= 0 or b <= 0:
            continue
        xl, xr = f * plate_height / a, f * plate_height / b
        values.append(math.hypot(xr - xl, xr * ar - xl * al) / plate_height)
    if not values:
        return 0.0, math.inf
    return min(values), max(values)


def _outer_corners(f: dict, params: DetectorParams) -> np.ndarray:
    """The plate's outer quad: the body quad grown by the dark rim, less the mask's spread.

    Each vertical edge's ends move out by ``rim_height`` of its own height
    and every side by ``rim_width`` of the body's width (perspective shrinks
    the rim with the plate), each plus ``edge_offset`` px.
    """
    u0, u1, t0, t1, s0, s1 = f["quad"]
    hl, hr = f["heights"]
    e = params.edge_offset
    side = params.rim_width * (u1 - u0) + e
    ul, ur = u0 - side, u1 + side
    bt = (t1 - t0) / (u1 - u0)
    bb = (s1 - s0) / (u1 - u0)
    gl, gr = params.rim_height * hl + e, params.rim_height * hr + e
    tl = (ul, t0 - bt * side - gl)
    tr = (ur, t1 + bt * side - gr)
    br = (ur, s1 + bb * side + gr)
    bl = (ul, s0 - bb * side + gl)
    return np.array([tl, tr, br, bl], dtype=np.float64)


def detection_of(f: dict, params: DetectorParams) -> PlateDetection:
    """The detection of a blob :func:`reject_blob` passed (its features ``f``)."""
    corners = f["corners"]
    bearing, rng, aspect, _ = f["geometry"]
    H, W = f["shape"]
    clipped = bool(any(f["clip"]))
    contrast = 1.0 - f["ring_level"] / f["body_level"]
    score = _score(f["fill"], contrast, f["text_fill"], aspect if not clipped else 3.0, clipped)
    x0 = int(max(0, math.floor(corners[:, 0].min() + 0.5)))
    x1 = int(min(W - 1, math.floor(corners[:, 0].max() + 0.5)))
    y0 = int(max(0, math.floor(corners[:, 1].min() + 0.5)))
    y1 = int(min(H - 1, math.floor(corners[:, 1].max() + 0.5)))
    return PlateDetection(corners=corners, bbox=(x0, y0, x1, y1), bearing=bearing, range=rng,
                          score=score, clipped=clipped)


def _ring_level(level: np.ndarray, box: tuple[int, int, int, int]) -> float | None:
    """Median level of a band around the blob's box (a quarter of its height wide).

    The band is the grown box less the box (which holds the whole blob): the
    rows above and below it, and the rest of the rows beside it.
    """
    x, y, w, h = box
    H, W = level.shape
    pad = max(2, round(0.25 * h))
    xa, xb = max(0, x - pad), min(W, x + w + pad)
    ya, yb = max(0, y - pad), min(H, y + h + pad)
    parts = [level[ya:y, xa:xb], level[y + h:yb, xa:xb], level[y:y + h, xa:x],
             level[y:y + h, x + w:xb]]
    n = sum(p.size for p in parts)
    if n < 4:
        return None
    if n < _HIST_MIN:
        return _median(np.concatenate([p.ravel() for p in parts]))
    counts = np.zeros(256, np.int64)
    for p in parts:
        if p.size:
            counts += _histogram(p)
    return _median_of_counts(counts)


# From this many values on, order statistics of levels come from their histogram
# (cv2.calcHist, linear and ~10x cheaper than np.partition on the ceiling's
# thousands of pixels); below it np.partition is cheaper. Both are exact.
_HIST_MIN = 1500


def _histogram(values: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Counts (256, int64) of the uint8 levels of a 2-D array (where the uint8 ``mask`` is set)."""
    return cv2.calcHist([values], [0], mask, [256], [0, 256]).ravel().astype(np.int64)


def _ranked(counts: np.ndarray, k: int) -> tuple[float, float]:
    """The ``k``-th and ``k + 1``-th smallest of the levels counted in ``counts``.

    As :func:`_order_stats` (the ``k``-th twice if it is the last).

    Examples
    --------
    >>> _ranked(np.bincount(np.array([7, 1, 3, 5]), minlength=256), 1)
    (3.0, 5.0)
    """
    cum = np.cumsum(counts)
    n = int(cum[-1])
    a = int(np.searchsorted(cum, k + 1))  # the first level with more than k values up to it
    b = a if k + 1 >= n else int(np.searchsorted(cum, k + 2))
    return float(a), float(b)


def _median_of_counts(counts: np.ndarray) -> float:
    """:func:`_median` of the levels counted in ``counts``."""
    n = int(counts.sum())
    a, b = _ranked(counts, (n - 1) // 2)
    return a if n % 2 else 0.5 * (a + b)


def _upper_quartile_of_counts(counts: np.ndarray) -> float:
    """:func:`_upper_quartile` of the levels counted in ``counts``."""
    rank = 3 * (int(counts.sum()) - 1)
    a, b = _ranked(counts, rank // 4)
    return a + (b - a) * (rank % 4 / 4)


def _order_stats(values: np.ndarray, k: int) -> tuple[float, float]:
    """The ``k``-th and ``k + 1``-th smallest of ``values`` (0-based; the last twice at the end)."""
    n = values.size
    if k + 1 >= n:
        return (float(np.partition(values, k)[k]),) * 2
    part = np.partition(values, (k, k + 1))
    return float(part[k]), float(part[k + 1])


def _median(values: np.ndarray) -> float:
    """``np.median`` of integer ``values`` (exactly), by one partial sort.

    Examples
    --------
    >>> _median(np.array([7, 1, 3, 5], np.uint8)), _median(np.array([9, 1, 4], np.uint8))
    (4.0, 4.0)
    """
    n = values.size
    a, b = _order_stats(values, (n - 1) // 2)
    return a if n % 2 else 0.5 * (a + b)


def _upper_quartile(values: np.ndarray) -> float:
    """``np.percentile(values, 75)`` of integer ``values`` (exactly), by one partial sort.

    Numpy interpolates linearly between the order statistics around rank
    ``0.75 (n - 1)``, whose fraction is a multiple of a quarter: for integer
    values every step below is exact, so the result is numpy's to the bit.

    Examples
    --------
    >>> _upper_quartile(np.array([0, 10, 20, 30, 40, 50], np.uint8))
    37.5
    """
    rank = 3 * (values.size - 1)  # four times the rank
    a, b = _order_stats(values, rank // 4)
    return a + (b - a) * (rank % 4 / 4)


def _text_pixels(level: np.ndarray, quad: tuple[float, ...], body_level: float,
                 dark_ratio: float) -> tuple[float, float, tuple | None]:
    """What is inside the plate: dark share, its width share, and where the dark pixels are.

    Looks at the middle 60 % of the quad's height, 12 % of the height in from
    its sides. Returns the share of those pixels darker than ``dark_ratio``
    of the body's level, the share of the width the dark columns span, and
    None if there are no dark pixels, else ``(ya, yb, a, b, dark)``: the
    bool mask ``dark`` of the dark pixels in the rows ``ya:yb`` and columns
    ``a:b`` of ``level`` (the frame's ``min`` channel), for
    :func:`_text_colour`.
    """
    u0, u1, t0, t1, s0, s1 = quad
    hmean = 0.5 * ((s0 - t0) + (s1 - t1))
    margin = 0.12 * hmean
    a, b = math.ceil(u0 + margin), math.floor(u1 - margin)
    H, W = level.shape
    a, b = max(a, 0), min(b, W - 1)
    if b - a < 1:
        return 0.0, 0.0, None
    cols = np.arange(a, b + 1)
    frac = (cols - u0) / max(u1 - u0, 1e-9)
    top = t0 + (t1 - t0) * frac
    bot = s0 + (s1 - s0) * frac
    hh = bot - top
    r0 = np.maximum(np.ceil(top + 0.2 * hh), 0).astype(int)
    r1 = np.minimum(np.floor(bot - 0.2 * hh), H - 1).astype(int)
    ya, yb = int(r0.min()), int(r1.max()) + 1
    if yb <= ya:
        return 0.0, 0.0, None
    n_inside = int(np.maximum(r1 - r0 + 1, 0).sum())  # (rows ya..yb span every column's)
    if n_inside < 4:
        return 0.0, 0.0, None
    patch = level[ya:yb, a:b + 1]
    dark = patch < math.ceil(dark_ratio * body_level)  # (levels are integers)
    if not dark.any():
        return 0.0, 0.0, None  # (often so: nothing dark even between these rows)
    rows = np.arange(ya, yb)[:, None]
    dark &= (rows >= r0[None, :]) & (rows <= r1[None, :])
    n_dark = int(np.count_nonzero(dark))
    if n_dark == 0:
        return 0.0, 0.0, None
    dcols = np.flatnonzero(dark.any(axis=0))
    span = float(dcols[-1] - dcols[0] + 1) / len(cols)
    return n_dark / n_inside, span, (ya, yb, a, b + 1, dark)


def _text_colour(level: np.ndarray, hi: np.ndarray,
                 text: tuple[float, float, tuple | None]) -> float:
    """The median chroma (``max - min``, grey levels) of the dark pixels :func:`_text_pixels` found.

    Text is black; a wall seen through a gap is coloured. ``level`` and ``hi``
    are the frame's ``min`` and ``max`` channels. 0 if there are none.
    """
    if text[2] is None:
        return 0.0
    ya, yb, a, b, dark = text[2]
    patch = level[ya:yb, a:b]
    if dark.size < _HIST_MIN:
        return _median(hi[ya:yb, a:b][dark] - patch[dark])
    return _median_of_counts(_histogram(cv2.subtract(hi[ya:yb, a:b], patch), dark.view(np.uint8)))


def _geometry(corners: np.ndarray, camera: CameraModel, plate_height: float,
              clip: tuple[bool, bool, bool, bool], seen: tuple[bool, bool] = (True, True),
              ) -> tuple[float, float, float, float] | None:
    """Bearing, range, metric aspect and height mismatch of a plate's quad.

    The height mismatch is in plate heights: the height of the plate's centre
    above the camera from the left edge minus that from the right edge (zero
    for a vertical rectangle with level top and bottom edges). ``clip`` says
    which image borders (left, right, top, bottom) the plate touches and
    ``seen`` whether its top and bottom edges were seen (not the border).

    A vertical edge is *whole* when it is not on a clipped side and both its
    ends lie inside the image. With both edges whole, the centre is the mean
    of their back-projected points and the bearing that of the quad's centre
    (the crossing of its diagonals, which perspective keeps at the plate's
    centre). With one, the centre is half a plate width from it along the
    plate (:func:`_centre_from_edge`). With none (a plate cut by the top or
    bottom border) but both sides in view, the centre comes from the sides'
    columns and the plate's width (:func:`_centre_from_sides`).
    """
    f, cx, cy = camera.f, camera.cx, camera.cy
    tl, tr, br, bl = corners
    hl, hr = bl[1] - tl[1], br[1] - tr[1]
    if hl <= 0 or hr <= 0:
        return None
    xl, xr = f * plate_height / hl, f * plate_height / hr
    yl, yr = xl * (cx - tl[0]) / f, xr * (cx - tr[0]) / f
    aspect = math.hypot(xr - xl, yr - yl) / plate_height
    zl = (cy - 0.5 * (tl[1] + bl[1])) / hl
    zr = (cy - 0.5 * (tr[1] + br[1])) / hr
    clip_l, clip_r, _, _ = clip

    def inside(v: float) -> bool:
        return 0.5 <= v <= camera.height - 1.5

    whole_l = not clip_l and inside(tl[1]) and inside(bl[1])
    whole_r = not clip_r and inside(tr[1]) and inside(br[1])
    centre = None
    if whole_l != whole_r:
        centre = _centre_from_edge((xl, yl) if whole_l else (xr, yr), corners, camera,
                                   plate_height, right=whole_r)
    elif not whole_l and not clip_l and not clip_r and (seen[0] or seen[1]):
        centre = _centre_from_sides(corners, camera, plate_height, use_top=seen[0])
    if centre is not None:
        return math.atan2(centre[1], centre[0]), math.hypot(*centre), aspect, abs(zl - zr)
    crossing = _diagonal_crossing(corners)
    return (math.atan2(cx - crossing[0], f), math.hypot(0.5 * (xl + xr), 0.5 * (yl + yr)),
            aspect, abs(zl - zr))


def _plate_direction(corners: np.ndarray, camera: CameraModel, use_top: bool = True
                     ) -> np.ndarray:
    """Unit camera-frame (x, y) direction of the plate's horizontal edges.

    Horizontal lines vanish on the horizon row ``cy``: the direction is the ray
    through the column where the (top or bottom) edge line meets that row.
    """
    tl, tr, br, bl = corners
    a, b = (tl, tr) if use_top else (bl, br)
    slope = (b[1] - a[1]) / max(b[0] - a[0], 1e-9)
    if abs(slope) < 1e-6:  # parallel to the image plane
        return np.array([0.0, 1.0])
    u_vp = a[0] + (camera.cy - a[1]) / slope
    d = np.array([1.0, (camera.cx - u_vp) / camera.f])
    return d / np.hypot(*d)


def _centre_from_edge(edge: tuple[float, float], corners: np.ndarray, camera: CameraModel,
                      plate_height: float, right: bool) -> tuple[float, float]:
    """Camera-frame centre (x, y) of a plate of which only one vertical edge is whole.

    The centre lies half a plate width (three halves of its height, for a 3:1
    plate) from the whole edge along the plate's horizontal direction (from
    the vanishing point of its top and bottom edges, where they meet),
    towards the other edge. ``right`` says the whole edge is the right one.
    """
    tl, tr, br, bl = corners
    f, cx = camera.f, camera.cx
    bt = (tr[1] - tl[1]) / max(tr[0] - tl[0], 1e-9)
    bb = (br[1] - bl[1]) / max(br[0] - bl[0], 1e-9)
    half = 0.5 * PLATE_WIDTH / PLATE_HEIGHT * plate_height
    if abs(bt - bb) > 1e-6:
        u_vp = tl[0] + (bl[1] - tl[1]) / (bt - bb)  # where the two edge lines meet
        d = np.array([1.0, (cx - u_vp) / f])
        d /= np.hypot(*d)
    else:  # parallel edges: the plate is square to the optical axis
        d = np.array([0.0, 1.0])
    # towards the other edge: from the right edge that is leftwards, +y
    if d[1] * (1.0 if right else -1.0) < 0:
        d = -d
    return edge[0] + half * d[0], edge[1] + half * d[1]


def _centre_from_sides(corners: np.ndarray, camera: CameraModel, plate_height: float,
                       use_top: bool) -> tuple[float, float] | None:
    """Camera-frame centre of a plate whose sides are in view but whose heights are cut.

    The rays through the two side columns meet the plate's ends; the plate
    runs along its horizontal direction (:func:`_plate_direction`) and is a
    plate width long, which fixes where along the rays its ends lie.
    """
    f, cx = camera.f, camera.cx
    rl = np.array([1.0, (cx - corners[0, 0]) / f])
    rr = np.array([1.0, (cx - corners[1, 0]) / f])
    d = _plate_direction(corners, camera, use_top)
    width = PLATE_WIDTH / PLATE_HEIGHT * plate_height
    m = np.column_stack([rr, -rl])  # s_r * rr - s_l * rl = width * d
    if abs(np.linalg.det(m)) < 1e-9:
        return None
    for sign in (1.0, -1.0):
        s_r, s_l = np.linalg.solve(m, sign * width * d)
        if s_r > 0 and s_l > 0:
            c = 0.5 * (s_l * rl + s_r * rr)
            return float(c[0]), float(c[1])
    return None


def _diagonal_crossing(c: np.ndarray) -> np.ndarray:
    p, r = c[0], c[2] - c[0]
    q, s = c[1], c[3] - c[1]
    denom = r[0] * s[1] - r[1] * s[0]
    if abs(denom) < 1e-12:
        return c.mean(axis=0)
    t = ((q[0] - p[0]) * s[1] - (q[1] - p[1]) * s[0]) / denom
    return p + t * r


def _score(fill: float, contrast: float, text_fill: float, aspect: float, clipped: bool) -> float:
    """Plate-likeness in [0, 1]: the geometric mean of how well each check is met.

    Each factor is in [0.2, 1] (a detection passed every check); a clipped
    plate, whose shape could be only partly checked, scores 0.8 of that.
    """
    def clip(v: float) -> float:
        return min(1.0, max(0.2, v))

    factors = (clip(1.0 - abs(1.0 - fill) / 0.3), clip(contrast / 0.4),
               clip(min(text_fill / 0.25, (0.95 - text_fill) / 0.25)),
               clip(1.0 - abs(math.log(aspect / 3.0))))
    score = math.prod(factors) ** (1.0 / len(factors))
    return float(score * (0.8 if clipped else 1.0))


# ---- evaluation against sim2d's ground truth ----------------------------------------------
def is_detectable(truth: dict, min_height: float = 6.0, min_visible: float = 0.6,
                  max_viewing_angle: float | None = None) -> bool:
    """Whether a ``sim2d.camera.visible_signs`` plate should be found.

    Plates smaller than ``min_height`` px, mostly hidden or outside the frame
    (``visible_fraction < min_visible``) or, when given, seen more obliquely
    than ``max_viewing_angle`` (rad) are not expected.
    """
    if truth["apparent_height"] < min_height or truth["visible_fraction"] < min_visible:
        return False
    return max_viewing_angle is None or truth["viewing_angle"] <= max_viewing_angle


def match_detections(detections: list[PlateDetection], truth_visible: list[dict],
                     min_height: float = 6.0, min_visible: float = 0.6,
                     max_viewing_angle: float | None = None, margin: float = 2.0,
                     ) -> tuple[int, int, int, list[tuple[int, int]]]:
    """Match detections to the ground truth of ``sim2d.camera.visible_signs``.

    A detection matches a plate when its centre lies in the plate's visible
    box (grown by ``margin`` px) or their boxes overlap by IoU >= 0.3; each
    plate takes at most one detection, best score first. A detection on a
    plate that is not :func:`is_detectable` is neither a true nor a false
    positive, and such a plate missed is no false negative. A second
    detection of a plate already matched counts as a false positive.

    Returns
    -------
    tp, fp, fn : int
    matches : list of (detection index, truth index) pairs
        Indices into ``detections`` and ``truth_visible``.
    """
    order = sorted(range(len(detections)), key=lambda i: -detections[i].score)
    used: set[int] = set()
    tp = fp = 0
    matches: list[tuple[int, int]] = []
    for i in order:
        det = detections[i]
        cu, cv = det.centre
        best, best_iou = None, 0.0
        for j, t in enumerate(truth_visible):
            x0, y0, x1, y1 = t["bbox"]
            inside = x0 - margin <= cu <= x1 + margin and y0 - margin <= cv <= y1 + margin
            iou = box_iou(det.bbox, t["bbox"])
            if (inside or iou >= 0.3) and (best is None or iou > best_iou):
                best, best_iou = j, iou
        if best is None:
            fp += 1
            continue
        ok = is_detectable(truth_visible[best], min_height, min_visible, max_viewing_angle)
        if best in used:
            fp += 1
        elif ok:
            tp += 1
            used.add(best)
            matches.append((i, best))
        else:
            used.add(best)
    fn = sum(1 for j, t in enumerate(truth_visible)
             if j not in used and is_detectable(t, min_height, min_visible, max_viewing_angle))
    return tp, fp, fn, matches


def box_iou(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> float:
    """Intersection over union of two inclusive pixel boxes ``(x0, y0, x1, y1)``."""
    ix = min(a[2], b[2]) - max(a[0], b[0]) + 1
    iy = min(a[3], b[3]) - max(a[1], b[1]) + 1
    if ix <= 0 or iy <= 0:
        return 0.0
    inter = ix * iy
    area = (a[2] - a[0] + 1) * (a[3] - a[1] + 1) + (b[2] - b[0] + 1) * (b[3] - b[1] + 1) - inter
    return inter / area
