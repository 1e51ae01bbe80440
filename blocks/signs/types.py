"""The records passed between the sign detector, the stop-and-zoom behaviour, the reader
and the correlation: plain dataclasses, so each stage can be tested on its own."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

PLATE_HEIGHT = 0.2  # m: the height of a standard door-sign plate (sim2d's default)
PLATE_WIDTH = 0.6  # m


@dataclass(frozen=True)
class CameraModel:
    """Pinhole intrinsics of one frame, as sim2d's camera renders it.

    ``u = cx - f * y / x`` and ``v = cy - f * z / x`` for a camera-frame point
    ``(x forward, y left, z up)``; ``cy`` already includes the tilt shift
    ``f * tan(tilt)``.
    """

    f: float  # px, focal length at the frame's zoom
    cx: float  # px
    cy: float  # px
    width: int
    height: int

    @classmethod
    def of(cls, width: int, height: int, hfov_rad: float, zoom: float,
           tilt: float = 0.0) -> "CameraModel":
        """The model of a ``width x height`` camera with ``hfov_rad`` at zoom 1."""
        f = (width / 2) / np.tan(hfov_rad / 2) * zoom
        return cls(f=float(f), cx=(width - 1) / 2, cy=(height - 1) / 2 + float(f * np.tan(tilt)),
                   width=int(width), height=int(height))


@dataclass(frozen=True)
class PlateDetection:
    """One sign plate found in a camera frame.

    Attributes
    ----------
    corners : ndarray (4, 2)
        Pixel corners of the plate's quadrilateral, image order: top-left,
        top-right, bottom-right, bottom-left (u right, v down).
    bbox : (x0, y0, x1, y1)
        Inclusive pixel box of the detected region.
    bearing : float
        Direction of the plate's centre from the optical axis (rad, CCW/left positive).
    range : float
        Estimated horizontal distance from the camera to the plate's centre (m), from
        the apparent height of the plate's vertical edges and the known plate height.
    score : float
        Plate-likeness in [0, 1] (contrast, rectangularity, text-like content).
    clipped : bool
        True when the plate touches the image border (its size is then uncertain).
    """

    corners: np.ndarray
    bbox: tuple[int, int, int, int]
    bearing: float
    range: float
    score: float
    clipped: bool = False

    @property
    def centre(self) -> tuple[float, float]:
        c = np.asarray(self.corners, dtype=np.float64).mean(axis=0)
        return float(c[0]), float(c[1])

    @property
    def height_px(self) -> float:
        """Mean apparent height of the left and right edges (px)."""
        c = np.asarray(self.corners, dtype=np.float64)
        return float((np.hypot(*(c[3] - c[0])) + np.hypot(*(c[2] - c[1]))) / 2)

    @property
    def width_px(self) -> float:
        c = np.asarray(self.corners, dtype=np.float64)
        return float((np.hypot(*(c[1] - c[0])) + np.hypot(*(c[2] - c[3]))) / 2)


@dataclass(frozen=True)
class Capture:
    """A zoomed frame of one plate, taken while the robot stood still.

    ``robot_pose`` is the robot's belief (odometry) when the frame was taken;
    ``pan`` and ``tilt`` are the camera head's, and ``camera`` its intrinsics.
    ``scale`` is the plate's size relative to the standard plate, as the
    views on the way to it measured it (1 when it is taken to be standard).
    """

    image: np.ndarray
    detection: PlateDetection
    camera: CameraModel
    robot_pose: np.ndarray  # (3,) x, y, theta (odometry frame)
    pan: float
    tilt: float
    zoom: float
    tick: int
    time: float
    scale: float = 1.0


@dataclass(frozen=True)
class Reading:
    """What the reader made of a capture.

    ``raw_text`` is the OCR output as read; ``text`` is the normalised,
    vocabulary-matched text ('' when nothing matched); ``confidence`` in [0, 1]
    combines the OCR score and the vocabulary match.
    """

    raw_text: str
    text: str
    confidence: float
    ocr_score: float = 0.0
    match_score: float = 0.0
    extra: dict = field(default_factory=dict)
