"""A cheap early reject for the object recogniser: rules out frames that cannot show a catalogue object.

The recogniser (:mod:`semantic.recognise`) spends almost all of its time in
SIFT on the whole frame (a Gaussian pyramid of the frame upsampled twice,
about 4 ms for 320x240 whatever the frame shows) and in matching the frame's
keypoints against the catalogue. Most camera frames show walls, corridors and
door signs and nothing of the catalogue, so this gate looks first, in three
steps of growing cost, and the frame goes to the full recogniser only when all
three pass:

1. **Corners.** FAST corners of the grey frame. A recognition needs
   ``min_inliers`` SIFT keypoints on one object, and a textured object gives
   many more FAST corners than that; fewer than ``corners_per_inlier *
   min_inliers`` corners (20 by default) in the whole frame is no object.
   Blank walls, floors and ceilings stop here (~0.04 ms).
2. **Textured regions.** The frame is cut into ``cell`` px squares; squares
   holding a corner, 8-connected, form regions. An object's keypoints lie in
   one region, so a region needs ``min_inliers`` corners and two squares.
   Door frames and corridor corners (scattered single corners) stop here.
3. **Votes.** SIFT on each region's crop (``margin`` px around it; a crop a
   few percent of the frame costs a fraction of the frame's pyramid; crops
   covering more than ``max_crop_share`` of the frame skip this step), and the
   recogniser's ratio test against all catalogue descriptors, in the
   catalogue's ``dims`` principal components. The full recogniser needs
   ``min_inliers`` ratio-test matches of one label (10); a region whose best
   label gets fewer than ``votes_share * min_inliers`` (4) is no object. Most
   door signs stop here; one seen close and head-on can get as many votes as
   an object and goes on to the recogniser, which finds nothing in it.

What passes goes to the unchanged recogniser on the whole frame, so a frame
that passes gives exactly the recognitions it gave without the gate. The
thresholds are measured on every frame the recogniser examines in the office
and hospital runs: recognised frames have at least 48 corners (gate: 20),
regions of at least 34 corners and 10 squares (10 and 2) and at least 10 votes
in their crop (4); catalogue objects at a quarter of the light or 40 % covered
keep at least 58 corners and 7 votes. See ``benchmarks/object_gate.py``. The
thresholds are measured for SIFT, so the gate serves SIFT only.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import cv2
import numpy as np

from semantic.matching import RatioMatcher

__all__ = ["GateEvidence", "GateParams", "ObjectGate", "Region", "textured_regions"]


@dataclass(frozen=True)
class GateParams:
    """Tuning of :class:`ObjectGate` (measured in ``benchmarks/object_gate.py``).

    Attributes
    ----------
    fast_threshold : int
        FAST's intensity threshold (grey levels); well above the camera noise.
    corners_per_inlier : float
        Fewer FAST corners than this times ``min_inliers`` in the frame is no object.
    cell : int
        Side of the squares that group corners into regions (px).
    min_cells : int
        A region needs this many squares (and ``min_inliers`` corners).
    margin : int
        Crop margin around a region for its SIFT (px).
    max_crop_share : float
        When the crops cover more than this share of the frame, the frame goes
        to the recogniser without votes: their SIFT would cost about as much.
    votes_share : float
        A region needs ``ceil(votes_share * min_inliers)`` ratio-test matches of one label.
    dims : int
        Principal components of the catalogue descriptors the votes are matched in.
    """

    fast_threshold: int = 10
    corners_per_inlier: float = 2.0
    cell: int = 16
    min_cells: int = 2
    margin: int = 16
    max_crop_share: float = 0.5
    votes_share: float = 0.4
    dims: int = 32

    def __post_init__(self) -> None:
        if self.cell < 1 or self.min_cells < 1 or self.fast_threshold < 1:
            raise ValueError("cell, min_cells and fast_threshold must be >= 1")
        if self.margin < 0:
            raise ValueError(f"margin must be >= 0, got {self.margin}")
        if not 0.0 < self.max_crop_share <= 1.0:
            raise ValueError(f"max_crop_share must be in (0, 1], got {self.max_crop_share}")
        if not 0.0 < self.votes_share <= 1.0:
            raise ValueError(f"votes_share must be in (0, 1], got {self.votes_share}")
        if self.corners_per_inlier < 0 or self.dims < 1:
            raise ValueError("corners_per_inlier must be >= 0 and dims >= 1")


class Region(NamedTuple):
    """A textured region of a frame: where corners cluster."""

    box: tuple[int, int, int, int]  # x0, y0, x1, y1 in px (x1, y1 exclusive)
    corners: int  # corners in it
    cells: int  # squares it covers


@dataclass(frozen=True)
class GateEvidence:
    """What the gate measures on a frame (all of it; the gate itself stops at the first no).

    Attributes
    ----------
    corners : int
        FAST corners in the frame.
    regions : list of Region
        All textured regions, most corners first.
    votes : list of int
        For each region that is large enough (``min_inliers`` corners,
        ``min_cells`` squares), the most ratio-test matches one picture gets.
    """

    corners: int
    regions: list[Region]
    votes: list[int]


def textured_regions(points: np.ndarray, shape: tuple[int, int], cell: int) -> list[Region]:
    """The regions where corners cluster: 8-connected ``cell`` px squares that hold a corner.

    Parameters
    ----------
    points : (N, 2) array
        Corner positions (x, y) in px.
    shape : (height, width)
        Image size (px).
    cell : int
        Square side (px).

    Returns
    -------
    list of Region
        Each region's box in px (clipped to the image), corners and squares,
        most corners first (then top-left first).

    Examples
    --------
    Three corners in two touching squares, one far away:

    >>> pts = np.array([[1, 1], [5, 2], [12, 3], [35, 35]])
    >>> [(r.box, r.corners, r.cells) for r in textured_regions(pts, (40, 40), 8)]
    [((0, 0, 16, 8), 3, 2), ((32, 32, 40, 40), 1, 1)]
    """
    if len(points) == 0:
        return []
    h, w = shape
    rows, cols = -(-h // cell), -(-w // cell)
    ij = np.clip(np.asarray(points, dtype=np.int64) // cell, 0, [cols - 1, rows - 1])
    occupied = np.zeros((rows, cols), np.uint8)
    occupied[ij[:, 1], ij[:, 0]] = 1
    n, labels, stats, _ = cv2.connectedComponentsWithStats(occupied, connectivity=8)
    count = np.bincount(labels[ij[:, 1], ij[:, 0]], minlength=n)
    regions = []
    for k in range(1, n):
        x, y, bw, bh, area = (int(v) for v in stats[k])
        box = (x * cell, y * cell, min(w, (x + bw) * cell), min(h, (y + bh) * cell))
        regions.append(Region(box, int(count[k]), area))
    return sorted(regions, key=lambda r: (-r.corners, r.box[1], r.box[0]))


class ObjectGate:
    """Says whether a grey frame could show a catalogue object (see the module's method).

    Parameters
    ----------
    descriptors : (M, 128) float32 array
        The catalogue's SIFT descriptors (all pictures).
    owner : (M,) int array
        Which picture each descriptor belongs to.
    detector : cv2.Feature2D
        The recogniser's SIFT for frames (run here on region crops).
    min_inliers : int
        The recogniser's fewest homography inliers of a recognition.
    ratio : float
        The recogniser's Lowe's ratio.
    params : GateParams, optional

    Attributes
    ----------
    counts : dict
        Frames by outcome since the last :meth:`reset_counts`: ``"few corners"``,
        ``"no textured region"``, ``"few votes"`` (ruled out) and ``"passed"``.
    """

    def __init__(self, descriptors: np.ndarray, owner: np.ndarray, detector: Any,
                 min_inliers: int, ratio: float, params: GateParams | None = None) -> None:
        self.params = p = params or GateParams()
        self._detector = detector
        self._owner = np.asarray(owner)
        self._labels = int(self._owner.max()) + 1 if len(self._owner) else 0
        self.min_inliers = min_inliers
        self.min_corners = max(1, math.ceil(p.corners_per_inlier * min_inliers))
        self.min_votes = max(1, math.ceil(p.votes_share * min_inliers))
        self._fast = cv2.FastFeatureDetector_create(threshold=p.fast_threshold,
                                                    nonmaxSuppression=True)
        self._mean, self._basis = _principal_axes(descriptors, p.dims)
        self._matcher = RatioMatcher(self._project(descriptors), ratio)
        self.counts: dict[str, int] = {}
        self.reset_counts()

    def reset_counts(self) -> None:
        """Start :attr:`counts` again from zero (e.g. for a new run)."""
        self.counts = {"few corners": 0, "no textured region": 0, "few votes": 0, "passed": 0}

    def __call__(self, grey: np.ndarray) -> bool:
        """True when the frame may show an object (run the recogniser), False when it cannot.

        Parameters
        ----------
        grey : (H, W) uint8 array
        """
        verdict = self.verdict(grey)
        self.counts[verdict] += 1
        return verdict == "passed"

    def verdict(self, grey: np.ndarray) -> str:
        """``"passed"``, or why the frame cannot show an object (a key of :attr:`counts`)."""
        points = self._corners(grey)
        if len(points) < self.min_corners:
            return "few corners"
        regions = self._large(textured_regions(points, grey.shape[:2], self.params.cell))
        if not regions:
            return "no textured region"
        crops = [self._crop(grey.shape[:2], r.box) for r in regions]
        if sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in crops) > (
                self.params.max_crop_share * grey.shape[0] * grey.shape[1]):
            return "passed"
        if any(self.votes(grey, r.box) >= self.min_votes for r in regions):
            return "passed"
        return "few votes"

    def evidence(self, grey: np.ndarray) -> GateEvidence:
        """Everything the gate measures on a frame, without stopping early (for tuning)."""
        points = self._corners(grey)
        regions = textured_regions(points, grey.shape[:2], self.params.cell)
        return GateEvidence(len(points), regions,
                            [self.votes(grey, r.box) for r in self._large(regions)])

    def _corners(self, grey: np.ndarray) -> np.ndarray:
        corners = self._fast.detect(grey)
        return np.asarray(cv2.KeyPoint_convert(corners), dtype=np.float32).reshape(-1, 2)

    def _large(self, regions: list[Region]) -> list[Region]:
        return [r for r in regions
                if r.corners >= self.min_inliers and r.cells >= self.params.min_cells]

    def votes(self, grey: np.ndarray, box: tuple[int, int, int, int]) -> int:
        """The most ratio-test matches one catalogue picture gets from a region's crop.

        Parameters
        ----------
        grey : (H, W) uint8 array
        box : (x0, y0, x1, y1)
            The region (px); the crop adds ``params.margin`` around it.
        """
        x0, y0, x1, y1 = self._crop(grey.shape[:2], box)
        _, desc = self._detector.detectAndCompute(grey[y0:y1, x0:x1], None)
        if desc is None or self._labels == 0:
            return 0
        _, train = self._matcher(self._project(desc))
        if len(train) == 0:
            return 0
        return int(np.bincount(self._owner[train], minlength=self._labels).max())

    def _crop(self, shape: tuple[int, int], box: tuple[int, int, int, int]) -> tuple[int, ...]:
        """A region's box grown by the margin, clipped to the image."""
        m, (h, w) = self.params.margin, shape
        return max(0, box[0] - m), max(0, box[1] - m), min(w, box[2] + m), min(h, box[3] + m)

    def _project(self, descriptors: np.ndarray) -> np.ndarray:
        # cv2.gemm, not numpy's BLAS, which runs on all cores and stalls on a busy machine
        return cv2.gemm(descriptors - self._mean, self._basis, 1.0, None, 0.0)


def _principal_axes(descriptors: np.ndarray, dims: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean (D,) and the first ``dims`` principal axes (D, dims) of descriptors, float32."""
    x = np.asarray(descriptors, dtype=np.float64)
    mean = x.mean(axis=0)
    _, _, vt = np.linalg.svd(x - mean, full_matrices=False)
    dims = min(dims, vt.shape[0])
    return mean.astype(np.float32), np.ascontiguousarray(vt[:dims].T, dtype=np.float32)
