"""A probabilistic occupancy map: log-odds updates with an inverse sonar model.

Where the paper's online map only counts "free" votes, this map also collects
evidence for walls, so walls are cells, not the edge of the free space:

* cells inside the cone nearer than the reading become more likely free;
* cells on the arc at the reading become more likely occupied;
* cells beyond the reading are left alone (unknown);
* a max-range reading (no echo) clears free space but marks nothing occupied,
  which removes the paper map's false borders at maximum range.

Log-odds add up (Thrun, Burgard and Fox, *Probabilistic Robotics*, ch. 9) and
are clamped so that a cell can change its mind after a door opens.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .mapio import OccupancyMap
from .tiles import TiledGrid


@dataclass(frozen=True)
class InverseSonarModel:
    """What one sonar reading says about the cells in its cone.

    Parameters
    ----------
    cone_deg
        Full opening angle of the cone (deg).
    max_range
        Readings at or beyond ``max_range - max_range_margin`` are "no echo" (m).
    max_range_margin
        How close to the maximum a reading counts as no echo (m).
    l_free
        Log-odds added to a cell the beam crossed (negative: towards free).
    l_occ
        Log-odds added to a cell on the arc at the reading.
    arc_thickness
        Depth of the occupied arc around the reading (m).
    l_min, l_max
        Clamp of the accumulated log-odds.
    no_echo_reach
        How far (m) a reading without an echo clears; None: the whole range.
        A sonar also hears nothing when its sound glances off a wall
        (specular loss), and then clearing the whole range draws free floor
        through that wall; an explorer planning on the map needs a short reach.
    shared_arc
        Width (m) of arc that one echo's ``l_occ`` covers; None: every cell
        of the arc gets all of it.  The echo came from somewhere on the arc,
        not from all of it, so a wider arc (a farther echo) adds
        ``l_occ * shared_arc / width`` to each of its cells.  Else the arcs a
        door's jambs echo from across a room paint the doorway shut, and the
        few beams that pass through it from close by never open it again.
    occlusion
        Log-odds from which a cell stops a silent reading's clearing; None:
        nothing stops it.  A sonar that hears nothing has either nothing in
        range or had its sound glance off a wall; cleared through a wall the
        map is already sure of, the free floor drawn behind it makes frontiers
        in rooms across a corridor's wall, and an explorer drives at the wall
        to reach them.  Each bearing of the cone clears up to the first such
        cell on it.
    seen_through
        Beams with an echo that must have passed a cell, reaching on at least
        ``through_margin`` beyond it, for the cell, while the map holds it
        free, to count as seen through when it lies on an echo's arc: the echo
        came from the rest of the arc, which gets the evidence the
        seen-through cells would have had (each cell at most ``l_occ``);
        None: every arc cell takes its share.  Silent beams do not count: a
        beam whose sound glanced off a wall crossed it and heard nothing.  Why:
        passing a door a metre off, the diagonal sonars hear its jambs from
        every position, and their arcs, as wide as the cone, lie across the
        opening that the beams through it have already seen free; drawn
        there, they shut the door on the map, and the room behind it, though
        seen, is out of the planner's reach (``benchmarks/doorways.py``
        counts such doors).
    through_margin
        How far (m) a beam must reach on beyond a cell to count as passing
        through it.  A wall's surface cell is crossed by the beams that end
        on the wall, just short of their echo; with no margin it would count
        as seen through, and the wall would be drawn a cell deeper.
    """

    cone_deg: float = 30.0
    max_range: float = 4.0
    max_range_margin: float = 0.05
    l_free: float = -0.4
    l_occ: float = 0.85
    arc_thickness: float = 0.1
    l_min: float = -4.0
    l_max: float = 4.0
    no_echo_reach: float | None = None
    shared_arc: float | None = None
    occlusion: float | None = None
    seen_through: int | None = None
    through_margin: float = 0.3

    def __post_init__(self) -> None:
        if not 0 < self.cone_deg < 180:
            raise ValueError(f"cone_deg must be in (0, 180), got {self.cone_deg}")
        if self.l_free >= 0 or self.l_occ <= 0:
            raise ValueError("l_free must be negative and l_occ positive")
        if self.arc_thickness <= 0 or self.max_range <= 0:
            raise ValueError("arc_thickness and max_range must be positive")
        if self.l_min >= 0 or self.l_max <= 0:
            raise ValueError("l_min must be negative and l_max positive")
        if self.no_echo_reach is not None and self.no_echo_reach < 0:
            raise ValueError(f"no_echo_reach must be >= 0, got {self.no_echo_reach}")
        if self.shared_arc is not None and not self.shared_arc > 0:
            raise ValueError(f"shared_arc must be > 0, got {self.shared_arc}")
        if self.occlusion is not None and not self.occlusion > 0:
            raise ValueError(f"occlusion must be > 0 (log-odds), got {self.occlusion}")
        if self.seen_through is not None and not self.seen_through >= 1:
            raise ValueError(f"seen_through must be >= 1 (beams), got {self.seen_through}")
        if self.through_margin < 0:
            raise ValueError(f"through_margin must be >= 0, got {self.through_margin}")

    def occupied_evidence(self, reading: float) -> float:
        """Log-odds each arc cell of an echo at ``reading`` (m) gets (see ``shared_arc``)."""
        if self.shared_arc is None:
            return self.l_occ
        width = 2.0 * reading * math.tan(math.radians(self.cone_deg) / 2)
        return self.l_occ * min(1.0, self.shared_arc / max(width, 1e-9))

    def beam_update(self, rho: np.ndarray, in_cone: np.ndarray, reading: float) -> np.ndarray:
        """Log-odds change for cells at range ``rho`` (m), ``in_cone`` of a beam reading ``reading``."""
        half_arc = self.arc_thickness / 2
        echo = reading < self.max_range - self.max_range_margin
        reach = min(reading, self.max_range)
        if not echo and self.no_echo_reach is not None:
            reach = min(reach, self.no_echo_reach)
        delta = np.where(in_cone & (rho < reach - (half_arc if echo else 0.0)),
                         np.float32(self.l_free), np.float32(0.0))
        if echo:
            delta[in_cone & (np.abs(rho - reading) <= half_arc)] = self.occupied_evidence(reading)
        return delta


def clear_ranges(sensors: np.ndarray, ranges: np.ndarray, walls: np.ndarray,
                 model: InverseSonarModel) -> np.ndarray:
    """How far each reading without an echo clears, given the walls known so far.

    Why: a sonar hears nothing when nothing is in range, and also when its
    sound glances off a wall (specular loss).  The offline map tells the two
    apart by the walls it found (:func:`~blocks.maps.offline.reading_model`);
    online, the walls the drift correction has mapped do the same: a silent
    beam clears up to the nearest known wall in its cone, or its whole range
    if there is none.  Cleared only a short way, the silent beams straight
    out of a corridor's open end leave the arcs that its walls' ends draw
    across it, and the map shows a wall where the corridor opens.

    Parameters
    ----------
    sensors
        (N, 3) sensor poses in the map frame.
    ranges
        (N,) readings (m).
    walls
        (F, 4) wall segments x0, y0, x1, y1 in the map frame.
    model
        The inverse sonar model (cone, range, arc).

    Returns
    -------
    (N,) array
        The clearing range of each silent reading; NaN for readings with an
        echo (the model draws them as usual).  Pass it to
        :meth:`LogOddsMap.add_scan`.
    """
    from sim2d.sonar import cone_ranges_near

    ranges = np.asarray(ranges, dtype=np.float64)
    clear = np.full(len(ranges), np.nan)
    silent = np.flatnonzero(ranges >= model.max_range - model.max_range_margin)
    if not len(silent):
        return clear
    predicted = np.full(len(silent), np.inf)
    walls = np.asarray(walls, dtype=np.float64).reshape(-1, 4)
    if len(walls):
        capsules = np.column_stack([walls, np.zeros(len(walls))])
        predicted = cone_ranges_near(np.asarray(sensors, dtype=np.float64)[silent], capsules,
                                     math.radians(model.cone_deg) / 2, model.max_range)
    clear[silent] = np.where(np.isfinite(predicted), predicted - model.arc_thickness / 2,
                             model.max_range)
    return clear


#: Log-odds below which map_server calls a cell free (``OccupancyMap.free_thresh``).
FREE_LOG_ODDS = math.log(OccupancyMap.free_thresh / (1.0 - OccupancyMap.free_thresh))


def _add_in_place(dest: np.ndarray, src: np.ndarray) -> None:
    np.add(dest, src, out=dest)


def log_odds_to_probability(log_odds: np.ndarray) -> np.ndarray:
    """p = 1 / (1 + exp(-l)), the occupancy probability of a log-odds value."""
    return 1.0 / (1.0 + np.exp(-log_odds))


class LogOddsMap:
    """A log-odds occupancy map on tiles allocated as the robot explores.

    Like the paper's beam matrices, each beam's geometry is precomputed: for
    every whole degree of heading, the cells of the cone around an apex cell
    carry their range in half cells (or "outside"). A reading then turns into
    log-odds changes with one table lookup, the 16 beams of a step add up in a
    local window, and the window is added to the tiles once. Ranges and
    headings are thereby rounded to 2.5 cm and 1 degree.

    Parameters
    ----------
    model
        The inverse sonar model.
    resolution
        Metres per cell.
    tile_size
        Cells per tile side.
    """

    OUTSIDE = 255  # range code of cells outside the cone

    def __init__(self, model: InverseSonarModel | None = None, resolution: float = 0.05,
                 tile_size: int = 64) -> None:
        self.model = model or InverseSonarModel()
        self.resolution = resolution
        self.tile_size = tile_size
        self.clear()
        self._reach = int(math.ceil((self.model.max_range + self.model.arc_thickness)
                                    / resolution)) + 1
        if 2 * self._reach >= self.OUTSIDE:
            raise ValueError(f"max_range / resolution is too large for the range codes "
                             f"({self.model.max_range} m at {resolution} m per cell)")
        # bearings only where a silent reading may be stopped (they cost a table per degree)
        occludes = self.model.occlusion is not None
        cones = [self._cone(math.radians(k), bearings=occludes) for k in range(360)]
        self._cones = [cone[:3] for cone in cones]
        self._bearings = [cone[3] for cone in cones]
        self._lut = self._lookup_table()
        # clear-only rows: a reading without an echo that clears up to a given range
        ranges = np.arange(256) / 2 * resolution
        self._clear_lut = np.where(ranges[None, :] < ranges[:2 * self._reach + 1, None],
                                   np.float32(self.model.l_free), np.float32(0.0))
        self._clear_lut[:, self.OUTSIDE] = 0.0
        margin = int(math.ceil(2 * self.model.through_margin / resolution))
        self._through_lut = self._passed(self._lut, margin)

    def _passed(self, lut: np.ndarray, margin: int) -> np.ndarray:
        """1 where a beam's row clears on for ``margin`` range codes beyond the cell, else 0."""
        passed = np.zeros(lut.shape, dtype=np.float32)
        if margin < lut.shape[1]:
            passed[:, :lut.shape[1] - margin] = lut[:, margin:] < 0
        passed[:, self.OUTSIDE] = 0.0
        return passed

    def _cone(self, heading: float, bearings: bool = False
              ) -> tuple[int, int, np.ndarray, np.ndarray | None]:
        """Range codes (half cells) of the cells in a cone at ``heading``, cropped to it, and
        with ``bearings`` each one's bearing off the axis (rad; else None)."""
        n = self._reach
        offsets = np.arange(-n, n + 1, dtype=np.float64)
        dx, dy = np.meshgrid(offsets, offsets)
        rho = np.hypot(dx, dy)
        along = dx * math.cos(heading) + dy * math.sin(heading)
        half = math.radians(self.model.cone_deg) / 2
        inside = ((along >= rho * math.cos(half)) & (rho <= n)) | (rho == 0)
        codes = np.where(inside, np.round(rho * 2), self.OUTSIDE).astype(np.uint8)
        rows, cols = np.nonzero(inside)
        r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
        bearing = None
        if bearings:
            across = -dx * math.sin(heading) + dy * math.cos(heading)
            bearing = np.arctan2(across[r0:r1, c0:c1], along[r0:r1, c0:c1]).astype(np.float32)
        return r0 - n, c0 - n, codes[r0:r1, c0:c1].copy(), bearing

    def _occluded(self, heading_index: int, codes: np.ndarray,
                  log_odds: np.ndarray) -> np.ndarray:
        """Cells of a cone at or behind, on their bearing, a cell of at least ``occlusion``.

        ``log_odds`` is the map under the cone's box before this scan.  A cell
        hides the bearings it spans (its width seen from the apex), so a wall
        of cells leaves no gaps between bearings.
        """
        stop = (codes != self.OUTSIDE) & (codes > 0) & (log_odds >= self.model.occlusion)
        if not stop.any():
            return np.zeros(codes.shape, dtype=bool)
        bearing = self._bearings[heading_index]
        stop_bearing, stop_code = bearing[stop], codes[stop].astype(np.int16)
        # half the angle a cell subtends at its range: half its diagonal (0.71 cells) over
        # its range (code / 2 cells)
        stop_half = np.arctan(1.42 / stop_code.astype(np.float32))
        inside = codes != self.OUTSIDE
        cell_bearing, cell_code = bearing[inside], codes[inside].astype(np.int16)
        hidden = ((np.abs(cell_bearing[:, None] - stop_bearing[None, :]) <= stop_half[None, :])
                  & (stop_code[None, :] <= cell_code[:, None])).any(axis=1)
        occluded = np.zeros(codes.shape, dtype=bool)
        occluded[inside] = hidden
        return occluded

    def _lookup_table(self) -> np.ndarray:
        """Log-odds change for (reading code, range code), both in half cells.

        Each row is the model's :meth:`InverseSonarModel.beam_update` for one
        reading, evaluated at every range code.
        """
        res = self.resolution
        ranges = np.arange(256) / 2 * res
        inside = np.ones(256, dtype=bool)
        inside[self.OUTSIDE] = False
        return np.stack([self.model.beam_update(ranges, inside, code / 2 * res)
                         for code in range(2 * self._reach + 1)])

    def clear(self) -> None:
        """Forget every update (the precomputed cone tables are kept)."""
        self.grid = TiledGrid(self.resolution, dtype=np.float32, fill=0.0,
                              tile_size=self.tile_size)
        # beams that passed each cell with through_margin to spare (model.seen_through)
        self.through = TiledGrid(self.resolution, dtype=np.float32, fill=0.0,
                                 tile_size=self.tile_size)
        self.updates = 0

    def _clamped_add(self, dest: np.ndarray, src: np.ndarray) -> None:
        np.add(dest, src, out=dest)
        np.clip(dest, self.model.l_min, self.model.l_max, out=dest)

    def scan_update(self, sensor_poses: np.ndarray, ranges: np.ndarray,
                    clear_to: np.ndarray | None = None) -> tuple[np.ndarray, tuple[int, int]]:
        """Log-odds changes of one scan in a local window, and the window's (ix, iy) corner.

        ``sensor_poses`` is (N, 3): x, y, heading of each sonar in the map frame.
        ``clear_to`` (N,), where finite, is how far a reading without an echo
        clears instead of the model's ``no_echo_reach`` (e.g. up to the nearest
        known wall in its cone, where its sound may have glanced off).  With
        the model's ``seen_through``, the cells each beam with an echo passed
        are counted into :attr:`through` as the scan is drawn (a silent beam
        may have glanced off a wall it crossed).
        """
        res = self.resolution
        ix, iy = self.grid.cell_of(sensor_poses[:, 0], sensor_poses[:, 1])
        ix, iy = np.asarray(ix, dtype=int), np.asarray(iy, dtype=int)
        n = self._reach
        wx0, wy0 = int(ix.min()) - n, int(iy.min()) - n
        window = np.zeros((int(iy.max()) - wy0 + n + 1, int(ix.max()) - wx0 + n + 1),
                          dtype=np.float32)
        top = 2 * n
        no_echo = self.model.max_range - self.model.max_range_margin
        if clear_to is None:
            clear_to = np.full(len(ranges), np.nan)
        silent = np.asarray(ranges) >= no_echo
        before = passed = seen = None
        if ((self.model.occlusion is not None and silent.any())
                or self.model.seen_through is not None):
            before = self.grid.window(wx0, wy0, window.shape[0], window.shape[1])
        if self.model.seen_through is not None:
            passed = np.zeros(window.shape, dtype=np.float32)
            seen = self.through.window(wx0, wy0, window.shape[0], window.shape[1])
        for (cx, cy, heading, reading, clear, quiet) in zip(ix, iy, sensor_poses[:, 2], ranges,
                                                            clear_to, silent):
            k = int(round(math.degrees(heading))) % 360
            dr, dc, codes = self._cones[k]
            if quiet and math.isfinite(clear):
                code = min(int(round(max(float(clear), 0.0) / res * 2)), top)
                row = self._clear_lut[code]
            else:
                code = min(int(round(float(reading) / res * 2)), top)
                row = self._lut[code]
            r0, c0 = cy - wy0 + dr, cx - wx0 + dc
            h, w = codes.shape
            delta = row[codes]
            if quiet and self.model.occlusion is not None:
                delta[self._occluded(k, codes, before[r0:r0 + h, c0:c0 + w])] = 0.0
            if passed is not None and not quiet:
                self._blame_unseen(delta, seen[r0:r0 + h, c0:c0 + w],
                                   before[r0:r0 + h, c0:c0 + w])
                passed[r0:r0 + h, c0:c0 + w] += self._through_lut[code][codes]
            window[r0:r0 + h, c0:c0 + w] += delta
        if passed is not None:
            self.through.update(wx0, wy0, passed, _add_in_place, mask=passed != 0)
        return window, (wx0, wy0)

    def _blame_unseen(self, delta: np.ndarray, passed: np.ndarray, log_odds: np.ndarray
                      ) -> None:
        """An echo's arc evidence taken off the cells already seen through (``passed``: the
        beams through each, at least ``seen_through``, and free on the map by ``log_odds``)
        and given to the rest, in place."""
        arc = delta > 0
        through = arc & (passed >= self.model.seen_through) & (log_odds <= FREE_LOG_ODDS)
        if not through.any():
            return
        kept = arc & ~through
        if kept.any():
            share = float(delta[kept].max())
            delta[kept] *= min(arc.sum() / kept.sum(), self.model.l_occ / share)
        delta[through] = 0.0

    def add_scan(self, sensor_poses: np.ndarray, ranges: np.ndarray,
                 clear_to: np.ndarray | None = None) -> None:
        """One step: every beam of the scan, added to the map in one tile update
        (``clear_to`` as in :meth:`scan_update`)."""
        window, (wx0, wy0) = self.scan_update(np.asarray(sensor_poses, dtype=np.float64),
                                              np.asarray(ranges, dtype=np.float64),
                                              None if clear_to is None
                                              else np.asarray(clear_to, dtype=np.float64))
        self.grid.update(wx0, wy0, window, self._clamped_add, mask=window != 0)
        self.updates += 1

    def probabilities(self) -> tuple[np.ndarray, tuple[int, int]]:
        """Dense occupancy probabilities (rows y up) and the (ix, iy) of element [0, 0]."""
        log_odds, corner = self.grid.to_dense()
        return log_odds_to_probability(log_odds.astype(np.float64)), corner
