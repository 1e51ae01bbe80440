"""The processed online map: a crude occupancy map cleaned and traced into wall polylines.

The paper's online map records only where space was seen to be free; walls are
where the free space ends.  Read directly, that map is noisy: free-space edges
are ragged (each sonar cone ends in its own arc), isolated specks of free space
lie outside the rooms, gaps between beams leave unknown holes inside them, and
the free space fringes into narrow slivers where a single beam reached further.
The processed map smooths the free space, finds its edges and follows them
into polylines (OpenCV's border following), which a person or a planner can
use as the building's walls.

Conventions
-----------
Grids follow :mod:`blocks.maps.mapio`: indexed ``[iy, ix]``, row 0 at the
lowest y, ``origin`` the lower-left corner of cell ``[0, 0]``.  OpenCV's pixel
``(x, y)`` is ``(column, row)``, so on these arrays pixel coordinates grow the
same way as world coordinates and no flip is needed: cell ``(col, row)`` has
its centre at ``origin + ((col + 0.5) * res, (row + 0.5) * res)``.

Walls are traced through the centres of the *non-free* cells that touch the
cleaned free space (the cells where the paper puts its borders), so the free
space keeps its extent and the walls sit on the wall surface rather than half
a cell inside the room.  Every wall is oriented with the free space on its
left: the outline of a free region runs counter-clockwise, the outline of an
obstacle inside it clockwise (in the map frame, y up).
"""
from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from blocks.core.atomic import atomic_write_text

from .mapio import OccupancyMap

__all__ = ["ProcessedMap", "polyline_length", "process_occupancy_map", "walls_to_geojson",
           "write_walls_geojson"]

#: Kind of a wall that bounds a free region from outside (a room's walls).
OUTER = "outer"
#: Kind of a wall around a hole in free space (an obstacle or an unseen patch).
INNER = "inner"


@dataclass
class ProcessedMap:
    """The result of :func:`process_occupancy_map`.

    Attributes
    ----------
    map
        On the input's grid (same shape, resolution and origin): cleaned free
        space ``p = 0``, the traced walls drawn one cell thick ``p = 1``,
        ``NaN`` (unknown) elsewhere; default map_server thresholds.
    walls
        Wall polylines in the map frame: each an (K, 2) float array of world
        ``x, y`` vertices in metres; closed outlines repeat their first vertex
        at the end.  A wall may lie up to one cell outside the input's extent
        when free space reaches the edge of the input grid.
    kinds
        One per wall: ``"outer"`` for the outline of a free region, ``"inner"``
        for the outline of a hole (an obstacle) inside one.
    """

    map: OccupancyMap
    walls: list[np.ndarray] = field(default_factory=list)
    kinds: list[str] = field(default_factory=list)

    def to_geojson(self, **kw: Any) -> dict[str, Any]:
        """The walls as GeoJSON (see :func:`walls_to_geojson`), each tagged with its kind."""
        return walls_to_geojson(self.walls, feature_properties=[{"kind": k} for k in self.kinds],
                                **kw)


# ---- geometry ----------------------------------------------------------------------------
def polyline_length(points: np.ndarray | Sequence[Sequence[float]]) -> float:
    """Length of a polyline: the sum of its segments' lengths (metres for world points).

    Parameters
    ----------
    points
        (K, 2) vertices; a closed polyline must repeat its first vertex to
        count its closing segment.  Fewer than two points have length 0.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(p) < 2:
        return 0.0
    return float(np.hypot(*np.diff(p, axis=0).T).sum())


def _signed_area(points: np.ndarray) -> float:
    """Shoelace area of a closed polyline: positive when counter-clockwise (y up)."""
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _disc(radius: int) -> np.ndarray:
    """A disc structuring element of the given radius in cells."""
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


# ---- cleaning ----------------------------------------------------------------------------
def _remove_small(mask: np.ndarray, min_cells: float, connectivity: int,
                  keep_touching_edge: bool = True) -> np.ndarray:
    """``mask`` without its connected components of fewer than ``min_cells`` cells.

    With ``keep_touching_edge`` false, components touching the array's edge go
    too whatever their size (used for holes: background touching the padded
    edge is the outside, never a hole).
    """
    _, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8),
                                                          connectivity=connectivity)
    keep = stats[:, cv2.CC_STAT_AREA] >= min_cells
    keep[0] = False  # label 0 is the background of ``mask``
    if not keep_touching_edge:
        edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
        keep[edge] = True
    return keep[labels] & mask


def _clean_free(free: np.ndarray, barrier: np.ndarray | None, *, open_px: int, gap_px: int,
                min_region_px: float, min_hole_px: float) -> np.ndarray:
    """Smooth a free-space mask (padded: nothing may touch the array's edge).

    1. Closing with a disc of radius ``gap_px // 2`` fills unknown notches and
       cracks up to ``gap_px`` cells wide; a median filter of the same radius
       evens out ragged edges (single-cell bumps and bites).  Both are kept
       that small on purpose: a wall between two rooms is an unknown band in
       the paper's map, and anything that bridges gaps as wide as a wall
       erases it.
    2. Opening with a disc of radius ``open_px`` removes free slivers and
       spurs narrower than the disc (single beams reaching past a doorway,
       speckles); no robot drives through them.
    3. Free regions smaller than ``min_region_px`` are dropped; holes inside
       free space smaller than ``min_hole_px`` become free.
    4. ``barrier`` cells (trusted occupied cells) are never free.
    """
    img = free.astype(np.uint8)
    radius = gap_px // 2
    if radius > 0:
        img = cv2.morphologyEx(img, cv2.MORPH_CLOSE, _disc(radius))
        img = cv2.medianBlur(img * 255, 2 * radius + 1) // 255
        if barrier is not None:
            img[barrier] = 0
    if open_px > 0:
        img = cv2.morphologyEx(img, cv2.MORPH_OPEN, _disc(open_px))
    out = _remove_small(img > 0, min_region_px, connectivity=8)
    # holes are 4-connected, the complement of 8-connected free space
    holes = _remove_small(~out, min_hole_px, connectivity=4, keep_touching_edge=False)
    small_holes = ~out & ~holes
    if barrier is not None:  # a hole with a trusted obstacle in it is no hole to fill
        _, labels = cv2.connectedComponents(small_holes.astype(np.uint8), connectivity=4)
        blocked = np.unique(labels[barrier & small_holes])
        small_holes &= ~np.isin(labels, blocked)
    out |= small_holes
    if barrier is not None:
        out &= ~barrier
    return out


# ---- processing --------------------------------------------------------------------------
def process_occupancy_map(m: OccupancyMap, *, smooth_m: float = 0.15,
                          min_region_m2: float = 0.25, simplify_m: float = 0.05,
                          min_wall_m: float = 0.3, fill_gap_m: float = 0.1,
                          min_hole_m2: float = 0.1, keep_occupied: bool = False) -> ProcessedMap:
    """Smooth a crude occupancy map, detect its free-space edges and trace them into walls.

    Only the free space is used by default: in the paper's map an occupied
    cell is merely an unknown cell next to free space, which carries no
    evidence of its own, and the walls are re-derived from the cleaned free
    space.

    Parameters
    ----------
    m
        The map (any map; free means ``p < m.free_thresh``).  Origin yaw must be 0.
    smooth_m
        Radius (m) of the disc that opens the free space: free slivers and
        spurs narrower than about twice this are removed, and convex corners
        are rounded by a fraction of it.
    min_region_m2
        Free regions smaller than this (m^2) are dropped as speckles.
    simplify_m
        Douglas-Peucker tolerance (m): no wall vertex is dropped if that would
        move the polyline further than this from the traced border.
    min_wall_m
        Walls shorter than this (m) are dropped.
    fill_gap_m
        Unknown cracks and notches in free space up to this wide (m) are
        filled.  Keep it below the thinnest wall (0.2 m in the bundled worlds):
        wider gaps include the walls between rooms.
    min_hole_m2
        Unknown holes inside free space smaller than this (m^2) become free:
        patches the beams happened to miss.  Smaller than ``min_region_m2`` by
        default so that free-standing wall segments (0.2 m thick) of half a
        metre or more survive.
    keep_occupied
        Treat the input's occupied cells as evidence (a probabilistic map):
        cleaning never turns them free and holes containing them are not
        filled.  Leave it off for the paper's map, whose occupied cells ring
        all free space and would stop any smoothing.

    Returns
    -------
    ProcessedMap
        The cleaned map on the input's grid and the wall polylines in metres.

    Raises
    ------
    ValueError
        For a non-positive resolution, a rotated origin or negative parameters.

    Notes
    -----
    Edge detection uses the morphological gradient of the binary free mask
    (non-free cells 8-adjacent to free ones) rather than Canny: on a binary
    image Canny finds the same transitions, but with a one-pixel ambiguity
    about which side of them it marks.  Borders are then followed with
    :func:`cv2.findContours` (Suzuki-Abe) on the free mask grown by those edge
    cells, two-level hierarchy, so each free region yields its outline and
    each hole inside it (an obstacle) its own; islands inside holes are free
    regions again.  Outlines are simplified with :func:`cv2.approxPolyDP`.

    Smoothing rounds corners: with the defaults at 5 cm cells a traced corner
    passes up to about two cells inside the sharp one.
    """
    res = float(m.resolution)
    if not (math.isfinite(res) and res > 0):
        raise ValueError(f"resolution must be > 0, got {m.resolution!r}")
    if len(m.origin) != 3 or m.origin[2] != 0:
        raise ValueError(f"only origin yaw 0 is supported, got {m.origin!r}")
    for name, value in (("smooth_m", smooth_m), ("min_region_m2", min_region_m2),
                        ("simplify_m", simplify_m), ("min_wall_m", min_wall_m),
                        ("fill_gap_m", fill_gap_m), ("min_hole_m2", min_hole_m2)):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be >= 0, got {value!r}")
    occupied, free, _ = m.classes()
    h, w = free.shape
    open_px, gap_px = round(smooth_m / res), round(fill_gap_m / res)
    # Pad so that morphology, edges and contours never meet the array's edge: free space
    # reaching the input's edge still gets a wall one cell beyond it.
    pad = max(open_px, gap_px, 1) + 2
    padded = np.pad(free, pad, constant_values=False)
    barrier = np.pad(occupied, pad, constant_values=False) if keep_occupied else None
    clean = _clean_free(padded, barrier, open_px=open_px, gap_px=gap_px,
                        min_region_px=min_region_m2 / res ** 2,
                        min_hole_px=min_hole_m2 / res ** 2)

    # Edges: non-free cells touching free space; trace the free space grown by them.
    grown = cv2.dilate(clean.astype(np.uint8), np.ones((3, 3), np.uint8))
    contours, hierarchy = cv2.findContours(grown, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    ox, oy = float(m.origin[0]), float(m.origin[1])
    walls: list[np.ndarray] = []
    kinds: list[str] = []
    drawn: list[np.ndarray] = []
    for i, contour in enumerate(contours):
        px = cv2.approxPolyDP(contour, simplify_m / res, closed=True).reshape(-1, 2)
        if len(px) < 2:
            continue
        world = np.column_stack([ox + (px[:, 0] - pad + 0.5) * res,
                                 oy + (px[:, 1] - pad + 0.5) * res])
        world = np.vstack([world, world[:1]])
        if polyline_length(world) < min_wall_m:
            continue
        kind = OUTER if hierarchy[0, i, 3] < 0 else INNER
        area = _signed_area(world)
        if (kind == OUTER) != (area > 0):  # free space on the left
            world = world[::-1].copy()
        walls.append(world)
        kinds.append(kind)
        drawn.append(px.astype(np.int32).reshape(-1, 1, 2))

    canvas = np.zeros_like(grown)
    cv2.polylines(canvas, drawn, isClosed=True, color=1, thickness=1, lineType=cv2.LINE_8)
    p = np.full((h, w), np.nan)
    p[clean[pad:pad + h, pad:pad + w]] = 0.0
    p[canvas[pad:pad + h, pad:pad + w] > 0] = 1.0
    out = OccupancyMap(p, res, (ox, oy, 0.0))
    return ProcessedMap(map=out, walls=walls, kinds=kinds)


# ---- GeoJSON -----------------------------------------------------------------------------
def walls_to_geojson(walls: Sequence[np.ndarray], *,
                     properties: Mapping[str, Any] | None = None,
                     feature_properties: Sequence[Mapping[str, Any]] | None = None,
                     ) -> dict[str, Any]:
    """Wall polylines as a GeoJSON FeatureCollection of LineStrings.

    Coordinates are ``[x, y]`` in metres in the map frame, not longitude and
    latitude, so the collection carries ``"properties": {"frame": "map",
    "units": "m"}`` (a foreign member, which RFC 7946 allows) instead of the
    ``crs`` member, which RFC 7946 removed.

    Parameters
    ----------
    walls
        (K, 2) polylines, K >= 2.
    properties
        Extra properties for the collection (merged over frame and units).
    feature_properties
        One mapping per wall, merged into that feature's properties.

    Returns
    -------
    dict
        Each feature has properties ``length_m`` (metres) and ``closed``
        (first vertex repeated at the end) plus any given ones.
    """
    if feature_properties is not None and len(feature_properties) != len(walls):
        raise ValueError(f"feature_properties has {len(feature_properties)} entries for "
                         f"{len(walls)} walls")
    features = []
    for i, wall in enumerate(walls):
        pts = np.asarray(wall, dtype=np.float64).reshape(-1, 2)
        if len(pts) < 2:
            raise ValueError(f"wall {i} has {len(pts)} vertex; a LineString needs 2")
        props: dict[str, Any] = {"length_m": polyline_length(pts),
                                 "closed": bool(len(pts) > 2 and np.array_equal(pts[0], pts[-1]))}
        if feature_properties is not None:
            props.update(feature_properties[i])
        features.append({"type": "Feature",
                         "geometry": {"type": "LineString", "coordinates": pts.tolist()},
                         "properties": props})
    return {"type": "FeatureCollection",
            "properties": {"frame": "map", "units": "m", **(properties or {})},
            "features": features}


def _round_mm(obj: Any) -> Any:
    """Floats rounded to 1 mm (3 decimals), recursively: millimetres are below any map's
    resolution, and shorter numbers keep the file small and diffs readable."""
    if isinstance(obj, float):
        return round(obj, 3)
    if isinstance(obj, dict):
        return {k: _round_mm(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_round_mm(v) for v in obj]
    return obj


def write_walls_geojson(path: str | Path, walls: Sequence[np.ndarray], **kw: Any) -> Path:
    """Write wall polylines as GeoJSON (atomically; coordinates rounded to 1 mm).

    Parameters
    ----------
    path
        The file to write (conventionally ``.geojson``); folders are created.
    walls
        The polylines, as for :func:`walls_to_geojson`.
    **kw
        Passed to :func:`walls_to_geojson` (``properties``, ``feature_properties``).

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    doc = _round_mm(walls_to_geojson(walls, **kw))
    atomic_write_text(path, json.dumps(doc, indent=1) + "\n")
    return path
