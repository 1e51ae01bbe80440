"""Object recognition: which catalogue objects a camera frame shows, where, and how far away.

Knowledge updating by object recognition (issue 7): an object of a known kind
seen in a room is evidence of what the room is (a shredder in an office, a
microscope in a laboratory). This module finds the objects of the object
catalogue (:mod:`semantic.objects`) in a frame by local features, the classic
recipe for textured, rigid objects:

1. keypoints and descriptors of every catalogue picture, once (SIFT by
   default; ORB and AKAZE are available — SIFT was chosen because objects are
   often only 40-80 px tall, where ORB's 31 px patches find almost nothing;
   see ``benchmarks/object_recogniser.py`` for the cost);
2. per frame: first a cheap early reject (:mod:`semantic.object_gate`: too
   few corners, no textured region, or no region whose crop matches the
   catalogue — most frames show walls and door signs only), then keypoints of
   the frame, a 2-nearest-neighbour match of each against all catalogue
   descriptors at once, and Lowe's ratio test (the best match must be clearly
   better than the second best, from any object);
3. per label: a homography from the picture to the frame by RANSAC over that
   label's matches, then sanity checks — enough inliers, spread over the
   picture, a convex quadrilateral with vertical sides (the camera does not
   roll), an aspect ratio near the object's and sides of similar height
   (moderate perspective) — and at most one sighting per label and image
   region (overlapping sightings of two labels keep the better one);
4. range and bearing from the projected picture corners: each vertical side
   of height ``h`` px is at forward depth ``f * H / h`` for the catalogue
   height ``H``, which places the side on the floor plan; the object's centre
   is the mean of the two sides (as for sign plates, see
   :mod:`blocks.signs.geometry`). The corners come from the homography, so a
   partly hidden or cut-off object still gets a range.

Everything here is plain OpenCV/numpy on a :class:`~blocks.signs.types.CameraModel`,
so the same code serves a real calibrated camera.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from blocks.signs.types import CameraModel
from semantic.matching import RatioMatcher, ratio_matches
from semantic.object_gate import GateParams, ObjectGate

__all__ = [
    "ObjectRecogniser",
    "ObjectSighting",
    "RecogniserParams",
    "object_world_position",
    "range_bearing_from_corners",
]


@dataclass(frozen=True)
class ObjectSighting:
    """One catalogue object found in a frame.

    Attributes
    ----------
    label : str
        Catalogue label (ontology class local name).
    bbox : (x0, y0, x1, y1)
        Inclusive pixel box of the projected picture, clipped to the image.
    corners : ndarray (4, 2)
        The picture's corners in the frame (px, unclipped): top-left, top-right,
        bottom-right, bottom-left.
    inliers : int
        Feature matches consistent with the homography.
    score : float
        Confidence in [0, 1] (grows with the inliers and their share of the matches).
    bearing : float
        Direction of the object's centre from the optical axis (rad, CCW/left positive).
    range : float
        Horizontal distance from the camera to the object's centre (m).
    """

    label: str
    bbox: tuple[int, int, int, int]
    corners: np.ndarray
    inliers: int
    score: float
    bearing: float
    range: float


@dataclass(frozen=True)
class RecogniserParams:
    """Tuning of :class:`ObjectRecogniser` (the defaults are measured by the benchmark).

    Attributes
    ----------
    feature : {"sift", "orb", "akaze"}
        Keypoint detector and descriptor.
    frame_features : int
        Most keypoints kept per frame.
    catalogue_features : int
        Most keypoints kept per catalogue picture.
    ratio : float
        Lowe's ratio: the best match's distance must be under this share of the second's.
    min_inliers : int
        Fewer homography inliers is no sighting.
    ransac_px : float
        RANSAC reprojection threshold (px).
    min_spread : float
        The inliers must span at least this share of the picture's width and height.
    aspect_tolerance : float
        The apparent width/height over the catalogue's must lie within
        ``[1 / (1 + t), 1 + t]`` — wide enough for ~50 deg of perspective.
    max_lean : float
        Most horizontal drift of a vertical side per unit of its height.
    min_height_px : float
        Shorter pictures (px) are not trusted.
    overlap : float
        Sightings whose boxes overlap more than this (intersection over the
        smaller box) are one object: the one with more inliers stays.
    early_reject : bool
        Rule out frames that cannot show an object before SIFT on the whole
        frame (:class:`~semantic.object_gate.ObjectGate`); the frames it lets
        through give the same recognitions as without it. SIFT only.
    gate : GateParams
        Tuning of the early reject.

    Raises
    ------
    ValueError
        When ``early_reject`` is asked for with a feature other than SIFT (its
        thresholds are measured for SIFT).
    """

    feature: str = "sift"
    frame_features: int = 600
    catalogue_features: int = 700
    ratio: float = 0.8
    min_inliers: int = 10
    ransac_px: float = 4.0
    min_spread: float = 0.2
    aspect_tolerance: float = 0.9
    max_lean: float = 0.25
    min_height_px: float = 16.0
    overlap: float = 0.5
    early_reject: bool = True
    gate: GateParams = field(default_factory=GateParams)

    def __post_init__(self) -> None:
        if self.early_reject and self.feature != "sift":
            raise ValueError(f"early_reject is measured for SIFT features only, not "
                             f"{self.feature!r}: give early_reject=False")


@dataclass
class _Model:
    """A catalogue picture's features."""

    label: str
    height_m: float
    aspect: float
    size: tuple[int, int]  # picture width, height (px)
    points: np.ndarray  # (K, 2) keypoint positions in the picture (px)


def _detector(params: RecogniserParams, n: int) -> Any:
    if params.feature == "sift":
        return cv2.SIFT_create(nfeatures=n)
    if params.feature == "orb":
        return cv2.ORB_create(nfeatures=n, scaleFactor=1.2, nlevels=8, edgeThreshold=15,
                              patchSize=15, fastThreshold=10)
    if params.feature == "akaze":
        return cv2.AKAZE_create(threshold=5e-4)
    raise ValueError(f"unknown feature {params.feature!r}: sift, orb or akaze")


class ObjectRecogniser:
    """Finds the catalogue's objects in camera frames.

    Parameters
    ----------
    catalogue : semantic.objects.Catalogue, optional
        The objects to look for (default: the packaged catalogue).
    params : RecogniserParams, optional
    """

    def __init__(self, catalogue: Any = None, params: RecogniserParams | None = None) -> None:
        if catalogue is None:
            from semantic.objects import default_catalogue
            catalogue = default_catalogue()
        self.catalogue = catalogue
        self.params = params or RecogniserParams()
        self._frame_detector = _detector(self.params, self.params.frame_features)
        model_detector = _detector(self.params, self.params.catalogue_features)
        self._models: list[_Model] = []
        descriptors, owners = [], []
        for entry in catalogue.entries:
            grey = cv2.cvtColor(catalogue.image(entry.label), cv2.COLOR_BGR2GRAY)
            kps, desc = model_detector.detectAndCompute(grey, None)
            if desc is None or len(kps) < self.params.min_inliers:
                continue  # a featureless picture can never be recognised
            if self.params.feature == "akaze" and len(kps) > self.params.catalogue_features:
                order = np.argsort([-k.response for k in kps])[:self.params.catalogue_features]
                kps, desc = [kps[i] for i in order], desc[order]
            owners.append(np.full(len(kps), len(self._models), dtype=np.int32))
            descriptors.append(desc)
            self._models.append(_Model(
                label=entry.label, height_m=entry.height, aspect=entry.aspect,
                size=(grey.shape[1], grey.shape[0]),
                points=np.array([k.pt for k in kps], dtype=np.float32)))
        self._descriptors = np.vstack(descriptors) if descriptors else None
        self._owner = np.concatenate(owners) if owners else np.zeros(0, np.int32)
        self._offset = np.concatenate([[0], np.cumsum([len(m.points) for m in self._models])])
        self._norm = cv2.NORM_L2 if self.params.feature == "sift" else cv2.NORM_HAMMING
        self._matcher: RatioMatcher | None = None  # (float descriptors: batchDistance's matches)
        if self._descriptors is not None and self._norm == cv2.NORM_L2:
            self._matcher = RatioMatcher(self._descriptors, self.params.ratio)
        self.gate: ObjectGate | None = None
        if self.params.early_reject and self._descriptors is not None:
            self.gate = ObjectGate(self._descriptors, self._owner, self._frame_detector,
                                   self.params.min_inliers, self.params.ratio, self.params.gate)
        self.rejections: dict[str, int] = {}

    def _reject(self, reason: str) -> None:
        """Count a rejected candidate by reason (for tuning; see :attr:`rejections`)."""
        self.rejections[reason] = self.rejections.get(reason, 0) + 1
        return None

    @property
    def labels(self) -> list[str]:
        """The labels it can recognise (pictures with enough features)."""
        return [m.label for m in self._models]

    def recognise(self, image_bgr: np.ndarray, camera: CameraModel) -> list[ObjectSighting]:
        """The catalogue objects in a frame, best first.

        Parameters
        ----------
        image_bgr : ndarray (H, W, 3) uint8
        camera : CameraModel
            The frame's intrinsics (for range and bearing).
        """
        p = self.params
        if self._descriptors is None:
            return []
        grey = image_bgr if image_bgr.ndim == 2 else cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
        if self.gate is not None and not self.gate(grey):
            return []
        kps, desc = self._frame_detector.detectAndCompute(grey, None)
        if desc is None or len(kps) < p.min_inliers:
            return []
        if self._matcher is not None:
            good_q, train = self._matcher(desc)
        else:
            good_q, train = ratio_matches(desc, self._descriptors, p.ratio, self._norm)
        if len(good_q) < p.min_inliers:
            return []
        frame_pts = cv2.KeyPoint_convert(kps)[good_q]  # (N, 2) float32, as the k.pt
        owner = self._owner[train]
        sightings = []
        for m in np.unique(owner):
            sel = owner == m
            if sel.sum() < p.min_inliers:
                continue
            model = self._models[int(m)]
            s = self._verify(model, model.points[train[sel] - self._offset[m]], frame_pts[sel],
                             camera)
            if s is not None:
                sightings.append(s)
        return _suppress_overlaps(sightings, p.overlap)

    def _verify(self, model: _Model, src: np.ndarray, dst: np.ndarray,
                camera: CameraModel) -> ObjectSighting | None:
        """A homography from the picture to the frame, checked for sense; None if it fails."""
        p = self.params
        H, mask = cv2.findHomography(src, dst, cv2.RANSAC, p.ransac_px, maxIters=2000,
                                     confidence=0.995)
        if H is None or mask is None or not np.all(np.isfinite(H)):
            return self._reject("no homography")
        inl = mask.ravel().astype(bool)
        n_in = int(inl.sum())
        if n_in < p.min_inliers:
            return self._reject("few inliers")
        w, h = model.size
        spread = np.ptp(src[inl], axis=0) / np.array([w, h], dtype=np.float32)
        if spread.min() < p.min_spread:
            return self._reject("clustered")  # the quad would be extrapolated
        box = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]],
                       dtype=np.float64)
        ones = np.hstack([box, np.ones((4, 1))])
        proj = ones @ H.T
        if np.any(proj[:, 2] <= 1e-9):
            return self._reject("behind")  # a corner behind the camera
        corners = proj[:, :2] / proj[:, 2:3]
        why = _implausible(corners, model.aspect, p)
        if why:
            return self._reject(why)
        try:
            rng, bearing = range_bearing_from_corners(corners, model.height_m, camera)
        except ValueError:
            return self._reject("shape")
        x0, y0 = np.floor(corners.min(axis=0)).astype(int)
        x1, y1 = np.ceil(corners.max(axis=0)).astype(int)
        bbox = (int(max(0, x0)), int(max(0, y0)), int(min(camera.width - 1, x1)),
                int(min(camera.height - 1, y1)))
        if bbox[2] <= bbox[0] or bbox[3] <= bbox[1]:
            return self._reject("outside")
        share = n_in / len(src)
        score = float(min(1.0, share + 0.2) * (1.0 - math.exp(-n_in / 12.0)))
        return ObjectSighting(label=model.label, bbox=bbox, corners=corners, inliers=n_in,
                              score=round(score, 4), bearing=bearing, range=rng)


def _implausible(corners: np.ndarray, aspect: float, p: RecogniserParams) -> str:
    """Why the projected picture is not a sensible view of an upright object ('' if it is)."""
    c = corners
    # convex, clockwise in image coordinates (TL, TR, BR, BL), not mirrored
    cross = []
    for i in range(4):
        a, b, d = c[i], c[(i + 1) % 4], c[(i + 2) % 4]
        cross.append((b[0] - a[0]) * (d[1] - b[1]) - (b[1] - a[1]) * (d[0] - b[0]))
    if not all(x > 0 for x in cross):
        return "shape"
    h_left, h_right = c[3, 1] - c[0, 1], c[2, 1] - c[1, 1]
    if min(h_left, h_right) < p.min_height_px:
        return "small"
    if max(h_left, h_right) > 2.0 * min(h_left, h_right):
        return "perspective"  # more than a view within ~60 deg of head-on gives
    if (abs(c[3, 0] - c[0, 0]) > p.max_lean * h_left
            or abs(c[2, 0] - c[1, 0]) > p.max_lean * h_right):
        return "lean"  # the camera does not roll: vertical sides stay vertical
    width = (np.hypot(*(c[1] - c[0])) + np.hypot(*(c[2] - c[3]))) / 2
    ratio = width / ((h_left + h_right) / 2) / aspect
    if not 1.0 / (1.0 + p.aspect_tolerance) <= ratio <= 1.0 + p.aspect_tolerance:
        return "aspect"
    return ""


def _suppress_overlaps(sightings: list[ObjectSighting], overlap: float) -> list[ObjectSighting]:
    """Keep the best of sightings that cover the same region (most inliers first)."""
    kept: list[ObjectSighting] = []
    for s in sorted(sightings, key=lambda s: (-s.inliers, s.label)):
        if all(_overlap(s.bbox, k.bbox) <= overlap for k in kept):
            kept.append(s)
    return kept


def _overlap(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> float:
    """Intersection over the smaller box."""
    iw = min(a[2], b[2]) - max(a[0], b[0]) + 1
    ih = min(a[3], b[3]) - max(a[1], b[1]) + 1
    if iw <= 0 or ih <= 0:
        return 0.0
    area = min((a[2] - a[0] + 1) * (a[3] - a[1] + 1), (b[2] - b[0] + 1) * (b[3] - b[1] + 1))
    return iw * ih / max(area, 1)


def range_bearing_from_corners(corners: np.ndarray, height_m: float,
                               camera: CameraModel) -> tuple[float, float]:
    """Horizontal range (m) and bearing (rad, CCW positive) of an upright rectangle's centre.

    Each vertical side of apparent height ``h`` px is at forward depth
    ``x = f * height_m / h`` and lateral offset ``y = x * (cx - u) / f``; the
    centre is the mean of the two sides' floor-plan points. Tilt does not
    matter: in the camera model it shifts ``cy`` only.

    Raises
    ------
    ValueError
        When a side has no positive height.
    """
    c = np.asarray(corners, dtype=np.float64).reshape(4, 2)
    u = np.array([(c[0, 0] + c[3, 0]) / 2, (c[1, 0] + c[2, 0]) / 2])
    h = np.array([c[3, 1] - c[0, 1], c[2, 1] - c[1, 1]])
    if np.any(h <= 0):
        raise ValueError("a vertical side has no height")
    x = camera.f * height_m / h
    y = x * (camera.cx - u) / camera.f
    cx_, cy_ = float(x.mean()), float(y.mean())
    return math.hypot(cx_, cy_), math.atan2(cy_, cx_)


def object_world_position(sighting: ObjectSighting, robot_pose, pan: float,
                          mount: tuple[float, float] = (0.15, 0.0)) -> tuple[float, float]:
    """Where a sighted object stands, in the frame ``robot_pose`` is given in.

    Parameters
    ----------
    sighting : ObjectSighting
    robot_pose : (x, y, theta)
        The robot's pose when the frame was taken (e.g. odometry).
    pan : float
        The camera head's pan (rad, CCW positive) for that frame.
    mount : (x, y)
        The pan axis in the robot frame (m); the camera's ``mount_x``, ``mount_y``.
    """
    from blocks.signs.geometry import camera_pose_of
    cx, cy, yaw = camera_pose_of(robot_pose, mount[0], mount[1], pan)
    a = yaw + sighting.bearing
    return cx + sighting.range * math.cos(a), cy + sighting.range * math.sin(a)


@dataclass
class MatchResult:
    """Sightings matched against ground truth (``visible_objects``) for one frame."""

    true_positives: int = 0
    false_positives: int = 0
    false_negatives: int = 0
    pairs: list = field(default_factory=list)  # (sighting, truth dict)


def match_sightings(sightings: list[ObjectSighting], truth: list[dict], *,
                    min_height: float = 40.0, min_visible: float = 0.8) -> MatchResult:
    """Score one frame: a sighting is true when its label is a visible object's and its box
    overlaps that object's box; a visible object is *expected* (a miss counts) only when at
    least ``min_height`` px tall and ``min_visible`` visible."""
    result = MatchResult()
    used: set[int] = set()
    for s in sightings:
        hit = None
        for k, t in enumerate(truth):
            if k not in used and t["label"] == s.label and _overlap(s.bbox, t["bbox"]) > 0.3:
                hit = k
                break
        if hit is None:
            result.false_positives += 1
        else:
            used.add(hit)
            result.true_positives += 1
            result.pairs.append((s, truth[hit]))
    for k, t in enumerate(truth):
        if (k not in used and t["apparent_height"] >= min_height
                and t["visible_fraction"] >= min_visible):
            result.false_negatives += 1
    return result
