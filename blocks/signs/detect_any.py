"""Door-sign plates of any look: outlined, text-bearing quadrilaterals of any colour.

:func:`~blocks.signs.detect.detect_plates` finds the light, colourless plate
with dark text the shipped worlds hang. Buildings drawn by anyone else hang
plates of every colour, light on dark as often as dark on light, on walls of
every colour. What every plate still has is an *outline*: its edge (and its
border) is a closed line of strong local contrast around a patch holding
text. So this detector works on contrast, not on colour:

1. *Contrast mask.* The 3x3 morphological gradient of the box-smoothed frame
   (largest over B, G, R); a pixel is an edge pixel when it passes
   ``edge_level``. Walls, floor and ceiling are smoothly shaded and drop out.
2. *Filled outlines.* The outer contours of the edge mask, filled: a plate's
   closed outline fills to the whole plate (body, letters, border); a small
   plate is one solid blob of edges already. Wall edges, door frames and
   skirting fill to thin shapes, which the fill test rejects.
3. *The plate's own colour.* Each blob's body colour is guessed (the median
   of its smooth pixels, then its light and its dark share), and the frame
   around the blob is mapped to a *plate level*: bright where the colour is
   the body's, darker with the colour distance from it. In that image any
   plate is a light plate with dark text, so the white-plate detector's
   measures (fitted quad, straight edges, fill, ring, text share and span,
   aspect, horizon) judge it unchanged (:func:`~blocks.signs.detect.measure_blob`).
4. *Where door signs hang.* A door sign hangs above a 0.6 m camera: its
   centre is at least ``min_elevation`` of its own heights above the horizon
   (plates hang at 1.0-1.7 m, pictures and labels on furniture lower). The
   ratio needs no plate size, which is unknown here.

:func:`detect_any_plates` runs both detectors and keeps the white-plate
detector's detections wherever both find a plate, so frames of the standard
plate give the same detections as before; the white detector's plates must
hang where door signs do too (4.), unless the frame's border cuts them: a
parcel's white address label ("TO: LAB") was read as the sign IT LAB.

The range of a detection still assumes the standard plate height (0.2 m):
a plate of another size is placed nearer or farther in proportion. Plates
cut by the image border are left to the white-plate detector.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from . import detect as white
from .types import PLATE_HEIGHT, CameraModel, PlateDetection

__all__ = ["AnyLookParams", "detect_any_plates", "detect_outlined_plates", "ink_spread",
           "plate_levels"]


@dataclass(frozen=True)
class AnyLookParams:
    """Tunables of :func:`detect_outlined_plates`.

    Attributes
    ----------
    edge_level : int
        Smallest 3x3 range (grey levels, any channel, of the 3x3-smoothed
        frame) of an edge pixel. The sensor noise (3 levels) stays below 6.
    level_slope : int
        Plate levels fall this much per grey level of colour distance from the
        body's colour (:func:`plate_levels`).
    min_elevation : float
        Smallest height of the plate's centre above the horizon, in its own
        apparent heights (from each vertical edge).
    min_blob_fill : float
        Smallest share of its bounding box a filled outline must cover before
        it is measured (a plate seen at 70 degrees fills about half).
    max_frame_share : float
        Largest share of the frame a blob's box may cover (walls, floor).
    max_ink_spread : float
        Letters are one ink: blurred, their pixels lie between the body's
        colour and the ink's. The median distance of the text pixels' colours
        from that line, as a share of the ink's distance from the body, is at
        most this (a shelf of books holds many colours, :func:`ink_spread`).
    inside_edges : bool
        Also look for plates inside other edges (:func:`_outlines_within`): a
        plate whose outline touches a door frame's or a wall corner's edges,
        which run on to the image's border.  Off until measured end to end.
    shape : DetectorParams
        The white-plate detector's measures, with the ring allowed any
        darkness (a dark plate on a light wall maps to a black ring), the
        text's colour unchecked (plate levels have none) and no rim to grow
        by: the outline already holds the plate's border, and the gradient
        spreads it by about a pixel.
    """

    edge_level: int = 12
    level_slope: int = 2
    min_elevation: float = 1.0
    min_blob_fill: float = 0.3
    max_frame_share: float = 0.45
    max_ink_spread: float = 0.25
    inside_edges: bool = False
    shape: white.DetectorParams = replace(white.DEFAULT_PARAMS, min_contrast=0.05,
                                          max_contrast=1.0, max_text_chroma=1e9,
                                          rim_height=0.0, rim_width=0.0, edge_offset=-1.0)


DEFAULT_ANY = AnyLookParams()
_BODY_LEVEL = 250  # the plate level of the body's own colour
_KERNEL = np.ones((3, 3), np.uint8)
#: wider than a line of edges (about 3 px, a door frame's two lines about 6): the plate stays
_LINE_KERNELS = (np.ones((1, 9), np.uint8), np.ones((9, 1), np.uint8))
#: px: the least width and height of a plate found inside other edges (smaller, and seen
#: edge on, a far plate is no plate to read yet; a far door's frame encloses boxes that small)
_MIN_ENCLOSED = (24, 14)
_MIN_BODY_PIXELS = 12  # smooth pixels enough to tell an enclosed outline's body colour
_BODY_TOLERANCE = 24  # grey levels (any channel) from the median that are the body's colour
_MIN_BODY_SHARE = 0.6  # of the smooth pixels inside an enclosed plate's outline


def plate_levels(patch: np.ndarray, body: np.ndarray, slope: int) -> np.ndarray:
    """Per pixel of a BGR ``patch``: ``250 - slope * d`` (saturated), ``d`` the largest
    channel difference from the ``body`` colour.

    Examples
    --------
    >>> patch = np.array([[[200, 100, 50], [200, 100, 90]]], np.uint8)
    >>> plate_levels(patch, np.array([200, 100, 50]), 2).tolist()
    [[250, 170]]
    """
    colour = np.asarray(np.round(body), np.uint8).reshape(1, 1, 3)
    diff = cv2.absdiff(patch, np.broadcast_to(colour, patch.shape).copy())
    d = cv2.max(cv2.max(diff[..., 0], diff[..., 1]), diff[..., 2])
    return cv2.subtract(np.full_like(d, _BODY_LEVEL), cv2.multiply(d, np.full_like(d, slope)))


def _edge_mask(smooth: np.ndarray, level: int) -> np.ndarray:
    grad = cv2.morphologyEx(smooth, cv2.MORPH_GRADIENT, _KERNEL)
    b, g, r = cv2.split(grad)
    return (cv2.max(cv2.max(b, g), r) > level).view(np.uint8)


def _body_colours(patch: np.ndarray, inside: np.ndarray, smooth_inside: np.ndarray
                  ) -> list[np.ndarray]:
    """Guesses at a blob's body colour, likeliest first.

    The median of its smooth pixels when there are enough of them (a big
    plate's body); then the colours of its light and of its dark share (a
    small plate is all edges: its body is the larger of the two, light or dark).
    """
    guesses = []
    area = int(np.count_nonzero(inside))
    if np.count_nonzero(smooth_inside) >= max(6, 0.15 * area):
        guesses.append(np.median(patch[smooth_inside], axis=0))
    pixels = patch[inside]
    brightness = pixels.astype(np.int32).sum(axis=1)
    order = np.argsort(brightness, kind="stable")
    for share in (0.85, 0.15):
        pick = brightness[order[int(share * (len(order) - 1))]]
        guesses.append(np.median(pixels[np.abs(brightness - pick) <= 12], axis=0))
    return guesses


def ink_spread(smooth: np.ndarray, levels: np.ndarray, feats: dict, body: np.ndarray) -> float:
    """How far the text pixels' colours stray from the line between the body's and the ink's.

    The text pixels are those of the plate's middle rows darker than 3/4 of
    the body's plate level; the ink is the median colour of the farthest
    third of them from the body. Returns the median distance from the
    body-ink segment over the ink's distance from the body (0 if too few to tell).
    """
    u0, u1, t0, t1, s0, s1 = feats["quad"]
    height = 0.5 * ((s0 - t0) + (s1 - t1))
    a, b = int(np.ceil(u0 + 0.12 * height)), int(np.floor(u1 - 0.12 * height)) + 1
    ya = int(np.ceil(0.5 * (t0 + t1) + 0.2 * height))
    yb = int(np.floor(0.5 * (s0 + s1) - 0.2 * height)) + 1
    if b - a < 2 or yb - ya < 1:
        return 0.0  # (too small to tell; the text test has passed)
    dark = levels[ya:yb, a:b] < np.ceil(0.75 * feats["body_level"])
    colours = smooth[ya:yb, a:b][dark].astype(np.float64)
    if len(colours) < 3:
        return 0.0
    offsets = colours - np.asarray(body, np.float64)
    far = np.linalg.norm(offsets, axis=1)
    ink = np.median(offsets[far >= np.quantile(far, 2 / 3)], axis=0)
    reach = float(np.linalg.norm(ink))
    if reach == 0:
        return 0.0
    along = np.clip(offsets @ ink / reach ** 2, 0.0, 1.0)
    off_line = np.linalg.norm(offsets - along[:, None] * ink, axis=1)
    return float(np.median(off_line) / reach)


def _elevation(corners: np.ndarray, camera: CameraModel) -> float:
    """Height of the plate's centre above the horizon, in its apparent heights (the lower of
    the two vertical edges' values)."""
    hl, hr = corners[3, 1] - corners[0, 1], corners[2, 1] - corners[1, 1]
    zl = (camera.cy - 0.5 * (corners[0, 1] + corners[3, 1])) / hl
    zr = (camera.cy - 0.5 * (corners[1, 1] + corners[2, 1])) / hr
    return float(min(zl, zr))


def detect_outlined_plates(image: np.ndarray, camera: CameraModel,
                           params: AnyLookParams = DEFAULT_ANY,
                           plate_height: float = PLATE_HEIGHT,
                           explain: list | None = None) -> list[PlateDetection]:
    """Plates of any colour and polarity whose outline is whole in a BGR frame.

    Parameters and returns as :func:`~blocks.signs.detect.detect_plates`;
    ``explain`` gets ``(box, reason)`` for each rejected blob.
    """
    smooth = cv2.blur(image, (3, 3))
    edges = _edge_mask(smooth, params.edge_level)
    contours, _ = cv2.findContours(edges, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    H, W = edges.shape
    shape = params.shape
    labels = np.zeros((H, W), np.uint16)  # one blob at a time, cleared after it
    levels = np.zeros((H, W), np.uint8)
    measured = np.zeros((H, W), np.uint8)  # the outlines judged whole (for inside_edges)
    found = []

    def judge(inside: np.ndarray, box: tuple[int, int, int, int]) -> None:
        x, y, w, h = box
        body_pixels = inside.view(bool)
        patch = smooth[y:y + h, x:x + w]
        guesses = _body_colours(patch, body_pixels, body_pixels & (edges[y:y + h, x:x + w] == 0))
        pad = max(4, h)
        xa, xb, ya, yb = max(0, x - pad), min(W, x + w + pad), max(0, y - pad), min(H, y + h + pad)
        labels[y:y + h, x:x + w] = inside
        reason = "no body"
        for body in guesses:
            levels[ya:yb, xa:xb] = plate_levels(smooth[ya:yb, xa:xb], body, params.level_slope)
            feats = white.measure_blob(labels, (1,), box, levels, levels, None, camera,
                                       plate_height, shape, quick=explain is None)
            reason = feats if isinstance(feats, str) else white.reject_blob(feats, shape)
            if reason is None and _elevation(feats["corners"], camera) < params.min_elevation:
                reason = "elevation"
            if reason is None and ink_spread(smooth, levels, feats, body) > params.max_ink_spread:
                reason = "ink colours"
            if reason is None:
                found.append(white.detection_of(feats, shape))
                break
        labels[y:y + h, x:x + w] = 0
        levels[ya:yb, xa:xb] = 0
        if reason is not None and explain is not None:
            explain.append(((x, y, x + w - 1, y + h - 1), reason))

    for contour in contours:
        box = _whole_box(cv2.boundingRect(contour), W, H, shape, params)
        if box is None:
            continue  # too small or too big, or cut by the border (the white detector's)
        inside = _filled(contour, box, shape, params)
        if inside is None:
            continue
        if params.inside_edges:
            x, y, w, h = box
            measured[y:y + h, x:x + w] |= inside
        judge(inside, box)
    if params.inside_edges:
        for inside, box in _outlines_within(edges, measured, shape, params):
            if _one_body(smooth, edges, inside, box):
                judge(inside, box)
    return white.drop_nested(found)


def _whole_box(box: tuple[int, int, int, int], W: int, H: int, shape: white.DetectorParams,
               params: AnyLookParams) -> tuple[int, int, int, int] | None:
    """``box`` if a blob with it may be a plate whole in the frame, else None."""
    x, y, w, h = box
    if (h < shape.min_height or w < shape.min_width or w * h > params.max_frame_share * H * W
            or x == 0 or y == 0 or x + w == W or y + h == H):
        return None
    return box


def _filled(contour: np.ndarray, box: tuple[int, int, int, int], shape: white.DetectorParams,
            params: AnyLookParams) -> np.ndarray | None:
    """The contour filled, in its box; None if it covers too little to be a plate's."""
    x, y, w, h = box
    inside = np.zeros((h, w), np.uint8)
    cv2.drawContours(inside, [contour - (x, y)], -1, 1, thickness=cv2.FILLED)
    area = cv2.countNonZero(inside)
    if area < shape.min_area or area < params.min_blob_fill * w * h:
        return None
    return inside


def _outlines_within(edges: np.ndarray, measured: np.ndarray, shape: white.DetectorParams,
                     params: AnyLookParams):
    """(filled outline, box) of each closed outline that no blob judged holds.

    Why: a plate hung beside a door frame or a wall's corner touches their
    edges, and its outline's outer contour runs on along them to the frame's
    border, where it is taken for a wall.  The plate's outline still closes
    round its body: what the background reaching in from the frame's border
    leaves out is the edges and what they enclose.  Opened by a row and then a
    column of pixels wider than a line of edges, the lines drop out and the
    enclosed plate stays.
    """
    H, W = edges.shape
    count, regions = cv2.connectedComponents(1 - edges, connectivity=4)
    reaches_border = np.zeros(count, np.uint8)
    reaches_border[np.concatenate([regions[0], regions[-1], regions[:, 0], regions[:, -1]])] = 1
    reaches_border[0] = 0  # the edges themselves
    enclosed = 1 - reaches_border[regions]
    for kernel in _LINE_KERNELS:  # lines, single or double, across and up the frame drop out
        enclosed = cv2.morphologyEx(enclosed, cv2.MORPH_OPEN, kernel)
    enclosed[measured > 0] = 0
    contours, _ = cv2.findContours(enclosed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    for contour in contours:
        box = _whole_box(cv2.boundingRect(contour), W, H, shape, params)
        if box is None or box[2] < _MIN_ENCLOSED[0] or box[3] < _MIN_ENCLOSED[1]:
            continue  # (a small plate is one blob of edges, found whole as it is)
        inside = _filled(contour, box, shape, params)
        if inside is not None:
            yield inside, box


def _one_body(smooth: np.ndarray, edges: np.ndarray, inside: np.ndarray,
              box: tuple[int, int, int, int]) -> bool:
    """Whether most smooth pixels inside an enclosed outline are of one colour, a body's.

    Why: edges enclose more than plates.  A shelf's compartment of books is a
    closed box of lines too, filled with spines of many colours; a plate's
    smooth pixels are its body's colour, but for its letters' insides.
    """
    x, y, w, h = box
    smooth_inside = inside.view(bool) & (edges[y:y + h, x:x + w] == 0)
    pixels = smooth[y:y + h, x:x + w][smooth_inside].astype(np.int16)
    if len(pixels) < _MIN_BODY_PIXELS:
        return True  # all edges: a small plate; the measures judge it
    off = np.abs(pixels - np.median(pixels, axis=0)).max(axis=1)
    return float(np.mean(off <= _BODY_TOLERANCE)) >= _MIN_BODY_SHARE


def detect_any_plates(image: np.ndarray, camera: CameraModel,
                      params: white.DetectorParams = white.DEFAULT_PARAMS,
                      any_params: AnyLookParams = DEFAULT_ANY,
                      plate_height: float = PLATE_HEIGHT) -> list[PlateDetection]:
    """Both detectors: the white-plate detector's plates, and the outlined plates of any
    look that overlap none of them (box IoU below 0.3); best score first.

    Plates of any size hang where door signs do: a white plate whole in the frame
    whose centre is less than ``min_elevation`` of its heights above the horizon is
    a label lower down (a parcel's address label, "TO: LAB"), as for outlined plates.
    """
    plates = [p for p in white.detect_plates(image, camera, params, plate_height)
              if p.clipped or _elevation(p.corners, camera) >= any_params.min_elevation]
    more = [d for d in detect_outlined_plates(image, camera, any_params, plate_height)
            if all(white.box_iou(d.bbox, p.bbox) < 0.3 for p in plates)]
    if not more:
        return plates
    out = white.drop_nested(plates + more)
    out.sort(key=lambda d: -d.score)
    return out
