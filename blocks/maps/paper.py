"""The paper's online map (section 5): 2-bit free-space levels built from beam and robot stamps.

Levels (table 1 of the paper) count how many readings said "free":

====  ===========  ======================================
bits  unoccupied   meaning
====  ===========  ======================================
00    0 %          unknown: never updated
01    33 %         one reading passed through the pixel
10    66 %         two readings
11    100 %        three or more (saturated), or the robot stood there
====  ===========  ======================================

A beam is a uniform 30-degree triangle 80 pixels (4 m at 5 cm) long at level
01, stored as a square matrix and clipped by the reading. The robot is a
10 x 10 pixel square at level 11. The local map puts the robot model at
neutral orientation and pivots the 16 clipped beams at their sensor poses;
overlaps superpose. Each step, the local map is rotated by the robot's heading,
shifted to its position, and added to the global map, skipping 00 pixels and
saturating at 11 (section 5.4, steps 3-5).

The map says where space is free; walls are where the free space ends. That is
also why an unclipped beam at maximum range leaves a false border.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from .tiles import TiledGrid

UNKNOWN, ONCE, TWICE, SATURATED = 0, 1, 2, 3
_SATURATED_U8 = np.uint8(SATURATED)  # a numpy scalar: no conversion per ufunc call


def _saturating_add(dest: np.ndarray, src: np.ndarray) -> None:
    """dest = min(dest + src, 11b) in place (uint8 cannot overflow: both are <= 3)."""
    np.add(dest, src, out=dest)
    np.minimum(dest, _SATURATED_U8, out=dest)


@dataclass(frozen=True)
class BeamModel:
    """One sonar beam as the paper draws it: a uniform triangle in a square matrix.

    Parameters
    ----------
    length_px
        Triangle height, pixels (80 px = 4 m at 5 cm).
    cone_deg
        Apex angle of the triangle (the sonar cone), degrees.
    level
        Grey level of the beam (01: one third free).
    """

    length_px: int = 80
    cone_deg: float = 30.0
    level: int = ONCE

    def matrix(self) -> np.ndarray:
        """The beam as a (2L + 1) x (2L + 1) uint8 matrix: apex at the centre, pointing +x.

        Rows are y (up) as in every grid here, columns x.
        """
        return self.rotated(0.0)[0]

    def axial(self) -> np.ndarray:
        """Distance of each matrix pixel from the apex along the beam axis, pixels."""
        return self.rotated(0.0)[1]

    def rotated(self, angle: float) -> tuple[np.ndarray, np.ndarray]:
        """The beam matrix pointing at ``angle`` (rad, CCW from +x) and its axial distances.

        Pixels are in the beam when their centre is inside the triangle; the
        axial distance is what a reading clips.
        """
        n = self.length_px
        offsets = np.arange(-n, n + 1, dtype=np.float64)
        u, v = np.meshgrid(offsets, offsets)  # u: x (columns), v: y (rows)
        c, s = math.cos(angle), math.sin(angle)
        axial = u * c + v * s
        lateral = -u * s + v * c
        half = math.tan(math.radians(self.cone_deg) / 2)
        inside = (axial >= 0) & (axial <= n) & (np.abs(lateral) <= axial * half + 1e-9)
        inside[n, n] = True  # the apex pixel itself
        return (inside * np.uint8(self.level)), axial.astype(np.float32)

    def clipped(self, reading_px: float, angle: float = 0.0) -> np.ndarray:
        """The beam at ``angle`` clipped to a reading of ``reading_px`` pixels."""
        matrix, axial = self.rotated(angle)
        return np.where(axial <= reading_px, matrix, 0).astype(np.uint8)


@dataclass(frozen=True)
class RobotModel:
    """The robot body as a footprint of free pixels (level 11), at every whole degree.

    The paper precomputes 359 rotated robots; here index ``k`` holds the
    footprint turned by ``k`` degrees (0..359), each in a square matrix with
    the robot's centre at the centre pixel.
    """

    size_px: int = 10
    level: int = SATURATED
    rotations: list[np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "rotations", [self._footprint(math.radians(k))
                                               for k in range(360)])

    def _footprint(self, angle: float) -> np.ndarray:
        # Pixels whose centre lies inside the turned square. An even-sized square
        # is centred on the centre pixel's lower-left corner, so it is exactly
        # size_px wide at 0 degrees.
        half = self.size_px / 2
        shift = 0.5 if self.size_px % 2 == 0 else 0.0
        reach = int(math.ceil(half * math.sqrt(2))) + 1
        offsets = np.arange(-reach, reach + 1, dtype=np.float64) + shift
        u, v = np.meshgrid(offsets, offsets)
        c, s = math.cos(angle), math.sin(angle)
        along, across = u * c + v * s, -u * s + v * c
        inside = (np.abs(along) < half - 1e-9) & (np.abs(across) < half - 1e-9)
        return inside * np.uint8(self.level)

    def at(self, theta: float) -> np.ndarray:
        """The precomputed footprint nearest to heading ``theta`` (rad)."""
        return self.rotations[int(round(math.degrees(theta))) % 360]


@dataclass(frozen=True)
class SensorMount:
    """A sonar's pose on the robot: x, y (m) and heading (rad), robot frame."""

    x: float
    y: float
    theta: float


class LocalMapper:
    """Builds the paper's local map: robot model plus 16 clipped beams, robot frame.

    Parameters
    ----------
    mounts
        The sonars' poses on the robot.
    resolution
        Metres per pixel (0.05 in the paper).
    max_range
        Longest beam (m); readings at or beyond it leave the beam unclipped.
    beam, robot
        The beam and robot models.
    """

    def __init__(self, mounts: list[SensorMount], resolution: float = 0.05,
                 max_range: float = 4.0, beam: BeamModel | None = None,
                 robot: RobotModel | None = None) -> None:
        self.resolution = resolution
        self.max_range = max_range
        self.beam = beam or BeamModel(length_px=int(round(max_range / resolution)))
        self.robot = robot or RobotModel()
        reach = max(math.hypot(m.x, m.y) for m in mounts) / resolution if mounts else 0.0
        self.half = int(math.ceil(reach)) + self.beam.length_px + 1
        self.size = 2 * self.half + 1
        # each sensor's beam turned to its mount angle and clipped at every whole-pixel
        # reading, cut to the clipped beam's own bounding box, so a step looks one up
        # and adds only the pixels it covers
        self._stamps = [self._beam_stamps(m) for m in mounts]
        foot = self.robot.at(0.0)
        corner = self.half - len(foot) // 2
        self._foot = _placed(corner, corner, foot)

    def _beam_stamps(self, mount: SensorMount) -> list[tuple[tuple[slice, slice], np.ndarray]]:
        """Where in the local map, and the stamp, of the beam of ``mount`` clipped at 0..L
        pixels."""
        n = self.beam.length_px
        matrix, axial = self.beam.rotated(mount.theta)
        rows, cols = np.nonzero(matrix)  # the whole beam's bounding box first: 5x less work
        r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
        matrix, axial = matrix[r0:r1, c0:c1], axial[r0:r1, c0:c1]
        row0 = self.half + int(round(mount.y / self.resolution)) - n + int(r0)
        col0 = self.half + int(round(mount.x / self.resolution)) - n + int(c0)
        stamps = []
        for k in range(n + 1):
            clipped = np.where(axial <= k + 0.5, matrix, np.uint8(0))
            rows, cols = np.nonzero(clipped)
            if len(rows) == 0:
                stamps.append(_placed(row0, col0, clipped[:0, :0]))
                continue
            r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
            stamps.append(_placed(row0 + int(r0), col0 + int(c0),
                                  np.ascontiguousarray(clipped[r0:r1, c0:c1])))
        return stamps

    def local_map(self, ranges: np.ndarray) -> np.ndarray:
        """The local map (size x size, uint8 levels), robot at the centre facing +x.

        Steps 3a-3e of the paper: start unknown, stamp the robot model at
        neutral orientation, clip each beam by its reading and pivot it at
        its sensor; overlaps superpose up to 11. The stamps are summed first
        and saturated once: min(min(a + b, 11) + c, 11) = min(a + b + c, 11)
        for levels >= 0, and cv2.add saturates at 255 instead of wrapping, so
        one pass replaces a saturation per stamp whatever the number of beams.
        """
        lm = np.zeros((self.size, self.size), dtype=np.uint8)
        n, top, res = self.beam.length_px, self.max_range, self.resolution
        for stamps, reading in zip(self._stamps, np.asarray(ranges).tolist()):
            reading_px = int(round(min(float(reading), top) / res))
            where, stamp = stamps[min(max(reading_px, 0), n)]
            view = lm[where]
            # cv2.add writes into the view (contiguous rows) at two thirds of np.add's cost
            cv2.add(view, stamp, dst=view)
        where, foot = self._foot
        view = lm[where]
        cv2.add(view, foot, dst=view)
        cv2.min(lm, SATURATED, dst=lm)
        return lm


def _placed(row: int, col: int, stamp: np.ndarray) -> tuple[tuple[slice, slice], np.ndarray]:
    """The slices that put ``stamp``'s [0, 0] at (row, col), and the stamp."""
    return (slice(row, row + stamp.shape[0]), slice(col, col + stamp.shape[1])), stamp


def orient_local_map(lm: np.ndarray, theta: float) -> np.ndarray:
    """Step 4a: the local map turned by the robot's heading about its centre pixel.

    Nearest-neighbour resampling keeps the four levels exact; pixels that
    come from outside the local map are 00 (unknown).
    """
    centre = (lm.shape[1] - 1) / 2
    # Rows are y up, so a CCW turn in the world is a CCW turn of the array's (col, row) axes.
    rot = cv2.getRotationMatrix2D((centre, centre), -math.degrees(theta), 1.0)
    return cv2.warpAffine(lm, rot, (lm.shape[1], lm.shape[0]), flags=cv2.INTER_NEAREST,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)


class PaperGlobalMap:
    """The paper's global map: 2-bit levels on tiles that grow with the explored floor.

    The map frame is the world frame (odometry starts at the world's start
    pose), so a map can be scored against the world directly.
    """

    def __init__(self, resolution: float = 0.05, tile_size: int = 64) -> None:
        self.resolution = resolution
        self.tile_size = tile_size
        self.clear()

    def clear(self) -> None:
        """Back to all unknown."""
        self.grid = TiledGrid(self.resolution, dtype=np.uint8, fill=UNKNOWN,
                              tile_size=self.tile_size)
        self.updates = 0

    def add(self, lm: np.ndarray, pose: np.ndarray) -> None:
        """Steps 4-5: rotate the local map by theta, shift it to (x, y), add it.

        Pixels at 00 are skipped (adding 0 changes nothing, and tiles the local
        map does not reach with a known pixel are never allocated); the rest
        are added and saturate at 11. Only the bounding box of the known
        pixels is added: short readings leave most of the local map unknown,
        and every tile it no longer overlaps is a tile less to visit.
        """
        x, y, theta = (float(v) for v in pose[:3])
        oriented = orient_local_map(lm, theta)
        self.updates += 1
        col, row, width, height = cv2.boundingRect(oriented)  # of the non-zero pixels
        if width == 0:
            return
        patch = oriented[row:row + height, col:col + width]
        half = lm.shape[0] // 2
        ix, iy = self.grid.cell_of(x, y)
        self.grid.update(int(ix) - half + col, int(iy) - half + row, patch, _saturating_add,
                         mask=patch != UNKNOWN)

    def levels(self) -> tuple[np.ndarray, tuple[int, int]]:
        """Dense levels (rows y up) and the (ix, iy) cell of element [0, 0]."""
        return self.grid.to_dense()


def free_space_borders(levels: np.ndarray, min_level: int = ONCE) -> np.ndarray:
    """Unknown pixels next to free ones: where the paper's map puts walls.

    Parameters
    ----------
    levels
        2-bit levels (rows y up).
    min_level
        Lowest level that counts as free.

    Returns
    -------
    numpy.ndarray
        Boolean mask of border pixels (8-connected to a free pixel, unknown themselves).
    """
    free = (levels >= min_level).astype(np.uint8)
    grown = cv2.dilate(free, np.ones((3, 3), np.uint8))
    return (grown > 0) & (levels == UNKNOWN)
