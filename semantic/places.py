"""Place segmentation: cut an occupancy map into rooms and corridors joined by doors.

Method (one pass, no learning)
------------------------------
1. **Free space.** Known-free cells of the map; pockets of non-free cells smaller
   than ``hole_area`` that lie inside free space (sonar speckle, chair legs) are
   filled so they do not cut a room in two. Unknown cells belong to no place.
2. **Clearance.** The Euclidean distance transform of the free mask gives, for
   each free cell, the distance to the nearest wall *or unknown cell* (m, to the
   cell edge). Unknown counts as an obstacle because a glimpsed room is only
   known to be as wide as the fan the sonar saw through its door.
3. **Seeds.** Connected components of ``clearance > door_width_max / 2 +
   margin``. A door (or any opening narrower than ``door_width_max``) has a
   clearance of half its width at its throat, so it separates seeds; a 2 m
   corridor keeps a continuous seed along its centre.
4. **Growth.** The seeds are grown back over the free space by a priority flood
   on clearance (a watershed on minus the distance transform): cells are
   claimed from the most open to the narrowest, so two floods meet at the
   narrowest point between them, i.e. in the door's throat.
5. **Small regions** (free pockets no seed reached, slivers behind jambs,
   regions below ``min_place_area``) are merged into the neighbour they share
   the longest border with, or dropped if they touch no place.
6. **Doors.** Each connected stretch of border between two places is a door:
   centre = centroid of the border cells, width = twice the largest clearance
   on the border (the widest disc that passes from one place into the other).
7. **Kind hint.** "corridor" for places that are long and narrow (length /
   width >= ``corridor_elongation`` with width = twice the 95th percentile of
   clearance and length = area / width) and open onto >= 3 other places, or -
   when the robot's ``path`` is given - the place holding the largest share of
   it; "room" otherwise.

Before seeding, doorways in walls are cut: per axis, wall runs >= 0.3 m long
are kept and gaps up to ``door_close`` between them closed, so a room seen only
through a fan narrower than its door (no open core of its own) is still its
own region; clutter spikes pointing at a wall do not count. After growth, two
neighbours whose border is not such a doorway and is nearly as wide as the
narrower of them (``narrowing``) are merged: a corridor pinched by sonar clutter
stays one place.

The flood runs on a grid of at least ``work_resolution`` (a coarse cell is free
when most of it is), then the labels are carried back to the map's own cells,
so a 2.5 cm map costs about as much as a 5 cm one.
"""
from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

import numpy as np
from scipy import ndimage

from blocks.maps.mapio import OccupancyMap
from semantic.vocabulary import canonical


@dataclass
class Place:
    """One segmented place.

    Attributes
    ----------
    id
        ``"P1"``, ``"P2"``, ... (the label value in :attr:`PlaceMap.labels` is the number).
    mask
        (H, W) bool on the map's grid, row 0 = lowest y.
    polygon
        (N, 2) outline of the largest part, world metres, counter-clockwise, not closed.
    centroid
        (x, y) of the mask, world metres.
    area
        m^2.
    kind_hint
        ``"corridor"`` or ``"room"``.
    clearance
        Largest clearance inside the place (m): half the widest free span.
    """

    id: str
    mask: np.ndarray
    polygon: np.ndarray
    centroid: tuple[float, float]
    area: float
    kind_hint: str = "room"
    clearance: float = 0.0


@dataclass
class Door:
    """A door or opening between places ``a`` and ``b`` (ids), centre (x, y) and width (m)."""

    id: str
    a: str
    b: str
    x: float
    y: float
    width: float

    def other(self, place_id: str) -> str | None:
        """The place on the other side from ``place_id`` (None if the door does not touch it)."""
        return self.b if place_id == self.a else self.a if place_id == self.b else None


@dataclass
class PlaceMap:
    """The segmentation: a label grid, its places, doors and the place graph.

    Attributes
    ----------
    labels
        (H, W) int32, 0 = no place, k = place ``"Pk"``; row 0 = lowest y (as the map).
    places, doors
        In id order.
    graph
        ``networkx.Graph``: nodes = place ids (attrs polygon, centroid, area,
        kind_hint); one edge per pair of places joined by a door (attrs door =
        the widest door's id, doors = all of them, width, x, y).
    resolution, origin
        The map's grid.
    """

    labels: np.ndarray
    places: list[Place]
    doors: list[Door]
    graph: Any
    resolution: float
    origin: tuple[float, float, float]
    seconds: float = 0.0
    params: dict[str, Any] = field(default_factory=dict)

    def place(self, place_id: str) -> Place:
        """The place with this id (KeyError if none)."""
        for p in self.places:
            if p.id == place_id:
                return p
        raise KeyError(place_id)

    def cell(self, x: float, y: float) -> tuple[int, int] | None:
        """(row, col) of the cell holding world point (x, y), None outside the grid."""
        col = math.floor((x - self.origin[0]) / self.resolution)
        row = math.floor((y - self.origin[1]) / self.resolution)
        h, w = self.labels.shape
        return (row, col) if 0 <= row < h and 0 <= col < w else None

    def place_at(self, x: float, y: float) -> str | None:
        """The id of the place holding world point (x, y), None if it is in no place."""
        rc = self.cell(x, y)
        if rc is None:
            return None
        k = int(self.labels[rc])
        return f"P{k}" if k > 0 else None

    def doors_of(self, place_id: str) -> list[Door]:
        """The doors that touch a place."""
        return [d for d in self.doors if place_id in (d.a, d.b)]


# ---- segmentation ------------------------------------------------------------------------------
def segment_places(m: OccupancyMap, *, door_width_max: float = 1.3, min_place_area: float = 1.0,
                   robot_radius: float | None = None, path: np.ndarray | None = None,
                   margin: float = 0.0, hole_area: float = 0.05, door_width_min: float = 0.3,
                   corridor_elongation: float = 3.0, work_resolution: float = 0.05,
                   simplify: float = 0.05, door_close: float | None = 1.1,
                   narrowing: float = 0.6) -> PlaceMap:
    """Segment an occupancy map into places joined by doors.

    Parameters
    ----------
    m
        The map (row 0 = lowest y, yaw 0).
    door_width_max
        Openings narrower than this (m) separate places; wider ones do not (so
        a corridor opening into a hall through a 2.4 m gap stays one place with it).
    min_place_area
        Regions smaller than this (m^2) are merged into a neighbour.
    robot_radius
        If given, a region with no cell at least this far from every obstacle
        (one the robot cannot enter, such as a sonar sliver behind a jamb) is
        merged into a neighbour or dropped.
    path
        Optional robot path (N, >= 2) x, y: the place holding most of it is the
        corridor.
    margin
        Added to ``door_width_max / 2`` for the seed threshold (m): absorbs
        noise on the door jambs.
    hole_area
        Non-free pockets inside free space smaller than this (m^2) are filled.
    door_width_min
        Borders narrower than this (m) are contacts, not doors; they are not
        reported (their places are still neighbours in the label grid).
    corridor_elongation
        Length / width ratio from which a place with >= 3 neighbours is a corridor.
    work_resolution
        The flood runs on a grid at least this coarse (m); labels are carried
        back to the map's cells.
    simplify
        Polygon simplification tolerance (m).
    door_close
        Gaps up to this wide (m) between wall cells in one row or column are
        doorways: they are cut before seeding, so a room seen only through a
        narrow fan (no open core of its own) still becomes a place. ``None``
        turns this off. Axis-aligned walls only (a 1-2 degree skew is fine).
    narrowing
        Two places whose border is not a doorway and is at least this fraction
        of the narrower place's width are one place pinched by noise (a
        corridor narrowed by sonar clutter) and are merged.

    Returns
    -------
    PlaceMap
    """
    import time

    import networkx as nx

    t0 = time.perf_counter()
    if m.origin[2] != 0:
        raise ValueError("segment_places needs a map with origin yaw 0")
    res = float(m.resolution)
    occupied, free, _ = m.classes()
    free = _fill_holes(free, hole_area / res ** 2)
    factor = max(1, int(round(work_resolution / res))) if work_resolution > res else 1
    wfree, wres = _coarsen(free, factor), res * factor
    wocc = _coarsen(occupied & ~free, factor, share=0.0)
    clearance = ndimage.distance_transform_edt(wfree) * wres - wres / 2
    clearance[~wfree] = 0.0
    # doorways in walls: gaps up to door_close between wall cells in one row or column
    in_door = np.zeros_like(wfree)
    if door_close and door_close > 0:
        import cv2

        # per direction: keep wall runs at least 0.3 m long along it (an opening), then
        # close gaps up to door_close between them; a wall's end facing another wall's
        # end across a gap is a doorway, a clutter spike pointing at a wall is not
        k = max(3, int(round(door_close / wres)) | 1)
        run = max(3, int(round(0.3 / wres)) | 1)
        occ8 = wocc.astype(np.uint8)
        for shape in ((1, 0), (0, 1)):
            line = np.ones((1 + (k - 1) * shape[1], 1 + (k - 1) * shape[0]), np.uint8)
            short = np.ones((1 + (run - 1) * shape[1], 1 + (run - 1) * shape[0]), np.uint8)
            walls = cv2.morphologyEx(occ8, cv2.MORPH_OPEN, short)
            in_door |= cv2.morphologyEx(walls, cv2.MORPH_CLOSE, line).astype(bool)
        in_door &= wfree
    cut = wfree & ~in_door
    seeds, n_seeds = ndimage.label(cut & (clearance > door_width_max / 2 + margin),
                                   structure=np.ones((3, 3)))
    # a region the door cut off that has no open core (a room glimpsed through a narrow
    # fan) is a seed of its own if it is big enough
    parts, n_parts = ndimage.label(cut)
    if n_parts:
        has_seed = np.zeros(n_parts + 1, bool)
        has_seed[np.unique(parts[seeds > 0])] = True
        sizes = np.bincount(parts.ravel(), minlength=n_parts + 1)
        lonely = ~has_seed & (sizes * wres ** 2 >= min_place_area)
        lonely[0] = False
        for j in np.flatnonzero(lonely):
            n_seeds += 1
            seeds[parts == j] = n_seeds
    labels = _flood(seeds.astype(np.int32), clearance, wfree)
    # free pockets no seed reached: their own regions (merged or dropped below)
    orphans, _ = ndimage.label(wfree & (labels == 0))
    labels[orphans > 0] = orphans[orphans > 0] + n_seeds
    labels = _merge_small(labels, clearance, wfree, min_place_area / wres ** 2,
                          None if robot_radius is None else robot_radius)
    labels = _merge_narrowings(labels, clearance, in_door, narrowing)
    # back to the map's own cells
    if factor > 1:
        labels = _refine(labels, free, factor)
        clearance_fine = ndimage.distance_transform_edt(free) * res - res / 2
        clearance_fine[~free] = 0.0
    else:
        clearance_fine = clearance
    labels = _renumber(labels)
    places = _describe_places(labels, clearance_fine, res, m.origin, simplify)
    doors = _find_doors(labels, clearance_fine, res, m.origin, door_width_min)
    _hint_kinds(places, doors, labels, res, m.origin, path, corridor_elongation)
    graph = nx.Graph()
    for p in places:
        graph.add_node(p.id, polygon=p.polygon, centroid=p.centroid, area=p.area,
                       kind_hint=p.kind_hint)
    for d in doors:
        if graph.has_edge(d.a, d.b):
            e = graph.edges[d.a, d.b]
            e["doors"].append(d.id)
            if d.width <= e["width"]:
                continue
        else:
            graph.add_edge(d.a, d.b, doors=[d.id])
        graph.edges[d.a, d.b].update(door=d.id, width=d.width, x=d.x, y=d.y)
    return PlaceMap(labels=labels, places=places, doors=doors, graph=graph, resolution=res,
                    origin=tuple(float(v) for v in m.origin), seconds=time.perf_counter() - t0,
                    params={"door_width_max": door_width_max, "min_place_area": min_place_area,
                            "robot_radius": robot_radius, "margin": margin})


def _fill_holes(free: np.ndarray, max_cells: float) -> np.ndarray:
    """Fill non-free pockets of fewer than ``max_cells`` cells that free space surrounds."""
    if max_cells < 1:
        return free
    pockets, n = ndimage.label(~free)
    if n == 0:
        return free
    sizes = np.bincount(pockets.ravel(), minlength=n + 1)
    border = np.unique(np.concatenate([pockets[0], pockets[-1], pockets[:, 0], pockets[:, -1]]))
    small = sizes < max_cells
    small[0] = False
    small[border] = False
    return free | small[pockets]


def _coarsen(free: np.ndarray, factor: int, share: float = 0.5) -> np.ndarray:
    """A mask on a grid ``factor`` times coarser: a coarse cell is set if more than
    ``share`` of it is (a majority for free space keeps a 1 m door open at any
    alignment of the grids; any share for walls keeps thin walls).
    """
    if factor == 1:
        return free
    h, w = free.shape
    hh, ww = -(-h // factor), -(-w // factor)
    pad = np.zeros((hh * factor, ww * factor), dtype=np.float32)
    pad[:h, :w] = free
    frac = pad.reshape(hh, factor, ww, factor).mean(axis=(1, 3))
    return frac > share


def _refine(labels: np.ndarray, free: np.ndarray, factor: int) -> np.ndarray:
    """Carry coarse labels back to fine cells: each free cell takes the label of the
    nearest labelled coarse cell (so thin free strips the coarse grid lost still join)."""
    h, w = free.shape
    fine = np.repeat(np.repeat(labels, factor, axis=0), factor, axis=1)[:h, :w]
    missing = fine == 0
    if missing.any() and (~missing).any():
        _, (ri, ci) = ndimage.distance_transform_edt(missing, return_indices=True)
        near = fine[ri, ci]
        dist = np.hypot(ri - np.arange(h)[:, None], ci - np.arange(w)[None, :])
        fine = np.where(missing & (dist <= 2 * factor), near, fine)
    fine[~free] = 0
    return fine.astype(np.int32)


def _flood(seeds: np.ndarray, clearance: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Priority flood (watershed on -clearance) from the seeds over the free cells (4-connected)."""
    h, w = seeds.shape
    lab = seeds.ravel().tolist()
    clr = clearance.ravel().tolist()
    fr = free.ravel().tolist()
    heap: list[tuple[float, int, int, int]] = []
    counter = 0
    # start from the seed cells that touch unlabelled free cells
    edge = np.zeros_like(free)
    s = seeds > 0
    grow = free & ~s
    edge[:-1] |= s[:-1] & grow[1:]
    edge[1:] |= s[1:] & grow[:-1]
    edge[:, :-1] |= s[:, :-1] & grow[:, 1:]
    edge[:, 1:] |= s[:, 1:] & grow[:, :-1]
    queued = (seeds.ravel() > 0).tolist()
    for idx in np.flatnonzero(edge.ravel()).tolist():
        heap.append((-clr[idx], counter, idx, lab[idx]))
        counter += 1
    heapq.heapify(heap)
    push, pop = heapq.heappush, heapq.heappop
    # the edge cells are labelled already: expand their neighbours
    while heap:
        _, _, idx, k = pop(heap)
        if lab[idx] == 0:
            lab[idx] = k
        r = idx // w
        c = idx - r * w
        for nb in ((idx - w) if r > 0 else -1, (idx + w) if r < h - 1 else -1,
                   (idx - 1) if c > 0 else -1, (idx + 1) if c < w - 1 else -1):
            if nb >= 0 and not queued[nb] and fr[nb]:
                queued[nb] = True
                counter += 1
                push(heap, (-clr[nb], counter, nb, k))
    return np.asarray(lab, dtype=np.int32).reshape(h, w)


def _adjacency(labels: np.ndarray) -> dict[tuple[int, int], int]:
    """Border length (in cell pairs, 4-neighbours) between every two touching labels."""
    pairs = []
    for a, b in ((labels[:-1], labels[1:]), (labels[:, :-1], labels[:, 1:])):
        sel = (a != b) & (a > 0) & (b > 0)
        lo, hi = np.minimum(a[sel], b[sel]), np.maximum(a[sel], b[sel])
        pairs.append(np.stack([lo, hi], axis=1))
    allp = np.concatenate(pairs) if pairs else np.zeros((0, 2), int)
    if not len(allp):
        return {}
    uniq, counts = np.unique(allp, axis=0, return_counts=True)
    return {(int(a), int(b)): int(c) for (a, b), c in zip(uniq, counts)}


def _merge_small(labels: np.ndarray, clearance: np.ndarray, free: np.ndarray,
                 min_cells: float, robot_radius: float | None) -> np.ndarray:
    """Merge regions below ``min_cells`` (or too narrow for the robot) into the neighbour
    with the longest shared border, smallest first; drop those with no neighbour."""
    labels = labels.copy()
    while True:
        n = int(labels.max())
        if n == 0:
            return labels
        sizes = np.bincount(labels.ravel(), minlength=n + 1)
        widest = ndimage.maximum(clearance, labels, index=np.arange(n + 1))
        widest = np.nan_to_num(np.asarray(widest, dtype=float))
        bad = (sizes > 0) & (sizes < min_cells)
        if robot_radius is not None:
            bad |= (sizes > 0) & (widest < robot_radius)
        bad[0] = False
        if not bad.any():
            return labels
        adj = _adjacency(labels)
        order = sorted(np.flatnonzero(bad).tolist(), key=lambda k: (sizes[k], k))
        changed = False
        merged: set[int] = set()
        for k in order:
            if k in merged:
                continue
            nbrs = [(c, b if a == k else a) for (a, b), c in adj.items() if k in (a, b)
                    and (b if a == k else a) not in merged]
            if nbrs:
                _, target = max(nbrs)
                labels[labels == k] = target
                merged.add(k)
            else:
                labels[labels == k] = 0
            changed = True
            break  # recompute sizes and borders after each merge
        if not changed:
            return labels


def _merge_narrowings(labels: np.ndarray, clearance: np.ndarray, in_door: np.ndarray,
                      ratio: float) -> np.ndarray:
    """Merge neighbours whose border is not a doorway and is nearly as wide as the
    narrower of them (width = twice the 95th percentile of clearance)."""
    if ratio <= 0:
        return labels
    labels = labels.copy()
    near_door = ndimage.binary_dilation(in_door, iterations=2)
    while True:
        n = int(labels.max())
        width = np.zeros(n + 1)
        for k in np.unique(labels[labels > 0]).tolist():
            width[k] = 2 * np.percentile(clearance[labels == k], 95)
        best = None
        for (a, b), cells in _borders(labels).items():
            rr, cc = cells[:, 0], cells[:, 1]
            if near_door[rr, cc].mean() > 0.3:
                continue
            w = 2 * float(clearance[rr, cc].max())
            score = w / max(min(width[a], width[b]), 1e-9)
            if score >= ratio and (best is None or score > best[0]):
                best = (score, a, b)
        if best is None:
            return labels
        _, a, b = best
        labels[labels == b] = a


def _borders(labels: np.ndarray) -> dict[tuple[int, int], np.ndarray]:
    """For each pair of touching labels, the (row, col) cells on either side of their border."""
    out: dict[tuple[int, int], list[np.ndarray]] = {}
    for axis in (0, 1):
        a = labels[:-1] if axis == 0 else labels[:, :-1]
        b = labels[1:] if axis == 0 else labels[:, 1:]
        sel = (a != b) & (a > 0) & (b > 0)
        r, c = np.nonzero(sel)
        r2, c2 = (r + 1, c) if axis == 0 else (r, c + 1)
        la, lb = a[sel], b[sel]
        lo, hi = np.minimum(la, lb), np.maximum(la, lb)
        keys = lo.astype(np.int64) * (int(labels.max()) + 1) + hi
        cells = np.concatenate([np.stack([r, c], 1), np.stack([r2, c2], 1)])
        keys2 = np.concatenate([keys, keys])
        order = np.argsort(keys2, kind="stable")
        keys2, cells = keys2[order], cells[order]
        splits = np.flatnonzero(np.diff(keys2)) + 1
        for key, chunk in zip(keys2[np.r_[0, splits]] if len(keys2) else [],
                              np.split(cells, splits)):
            pair = (int(key // (int(labels.max()) + 1)), int(key % (int(labels.max()) + 1)))
            out.setdefault(pair, []).append(chunk)
    return {k: np.unique(np.concatenate(v), axis=0) for k, v in out.items()}


def _renumber(labels: np.ndarray) -> np.ndarray:
    """Labels 1..K in order of each region's first cell from the top-left... in raster order
    of the region's lowest-row, lowest-column cell, so ids are stable and deterministic."""
    present = np.unique(labels)
    present = present[present > 0]
    if not len(present):
        return labels.astype(np.int32)
    flat = labels.ravel()
    first = np.full(int(labels.max()) + 1, np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(first, flat, np.arange(flat.size))
    order = sorted(present.tolist(), key=lambda k: first[k])
    lut = np.zeros(int(labels.max()) + 1, dtype=np.int32)
    for new, old in enumerate(order, start=1):
        lut[old] = new
    return lut[labels]


def _to_world(rows: np.ndarray, cols: np.ndarray, res: float,
              origin: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    return origin[0] + (cols + 0.5) * res, origin[1] + (rows + 0.5) * res


def mask_polygon(mask: np.ndarray, res: float, origin: tuple[float, float, float],
                 simplify: float = 0.05) -> np.ndarray:
    """The outline of a mask's largest part: (N, 2) world metres, counter-clockwise.

    The contour runs along the outer edges of the border cells (a cell-centre
    contour grown by half a cell), so the polygon's area matches the mask's.
    """
    import cv2

    m8 = np.zeros((mask.shape[0] * 2 + 2, mask.shape[1] * 2 + 2), np.uint8)
    m8[1:-1, 1:-1] = np.repeat(np.repeat(mask, 2, axis=0), 2, axis=1)  # half-cell grid
    contours, _ = cv2.findContours(m8, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return np.zeros((0, 2))
    c = max(contours, key=cv2.contourArea)
    c = cv2.approxPolyDP(c, max(simplify / res * 2, 0.5), True)[:, 0, :].astype(np.float64)
    # half-cell index i (with the 1-pixel pad) -> cell edge coordinate (i - 1 + 0.5) / 2 cells
    x = origin[0] + (c[:, 0] - 0.5) / 2 * res
    y = origin[1] + (c[:, 1] - 0.5) / 2 * res
    poly = np.stack([x, y], axis=1)
    if _signed_area(poly) < 0:
        poly = poly[::-1]
    return poly


def _signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _describe_places(labels: np.ndarray, clearance: np.ndarray, res: float,
                     origin: tuple[float, float, float], simplify: float) -> list[Place]:
    n = int(labels.max())
    places = []
    objs = ndimage.find_objects(labels)
    for k in range(1, n + 1):
        sl = objs[k - 1]
        if sl is None:
            continue
        sub = labels[sl] == k
        rows, cols = np.nonzero(sub)
        rows = rows + sl[0].start
        cols = cols + sl[1].start
        xs, ys = _to_world(rows, cols, res, origin)
        mask = np.zeros(labels.shape, dtype=bool)
        mask[sl] = sub
        off = (origin[0] + sl[1].start * res, origin[1] + sl[0].start * res, 0.0)
        places.append(Place(id=f"P{k}", mask=mask,
                            polygon=mask_polygon(sub, res, off, simplify),
                            centroid=(float(xs.mean()), float(ys.mean())),
                            area=float(len(rows) * res * res),
                            clearance=float(clearance[sl][sub].max())))
    return places


def _find_doors(labels: np.ndarray, clearance: np.ndarray, res: float,
                origin: tuple[float, float, float], min_width: float) -> list[Door]:
    """One door per connected stretch of border between two places."""
    h, w = labels.shape
    border: dict[tuple[int, int], list[np.ndarray]] = {}
    for axis in (0, 1):
        a = labels[:-1] if axis == 0 else labels[:, :-1]
        b = labels[1:] if axis == 0 else labels[:, 1:]
        sel = (a != b) & (a > 0) & (b > 0)
        r, c = np.nonzero(sel)
        r2, c2 = (r + 1, c) if axis == 0 else (r, c + 1)
        la, lb = a[sel], b[sel]
        for lo, hi, ra, ca, rb, cb in zip(np.minimum(la, lb), np.maximum(la, lb), r, c, r2, c2):
            border.setdefault((int(lo), int(hi)), []).append(np.array([[ra, ca], [rb, cb]]))
    doors = []
    for (ka, kb), cells in sorted(border.items()):
        pts = np.unique(np.concatenate(cells), axis=0)
        canvas = np.zeros((h, w), dtype=bool)
        canvas[pts[:, 0], pts[:, 1]] = True
        parts, n = ndimage.label(canvas, structure=np.ones((3, 3)))
        for j in range(1, n + 1):
            rr, cc = np.nonzero(parts == j) if n > 1 else (pts[:, 0], pts[:, 1])
            # clearance is measured between cell centres less half a cell: across an
            # opening of n cells the best cell sees n/2 (n even) or (n+1)/2 cells to
            # a jamb, so 2 * clearance + res/2 is within half a cell of the width
            width = 2.0 * float(clearance[rr, cc].max()) + res / 2
            if width < min_width:
                continue
            xs, ys = _to_world(rr, cc, res, origin)
            doors.append(Door(id="", a=f"P{ka}", b=f"P{kb}", x=float(xs.mean()),
                              y=float(ys.mean()), width=round(width, 3)))
    for i, d in enumerate(doors, start=1):
        d.id = f"D{i}"
    return doors


def _hint_kinds(places: list[Place], doors: list[Door], labels: np.ndarray, res: float,
                origin: tuple[float, float, float], path: np.ndarray | None,
                elongation: float) -> None:
    """Set each place's kind_hint (see the module docstring, step 7)."""
    degree = {p.id: len({d.other(p.id) for d in doors if p.id in (d.a, d.b)}) for p in places}
    for p in places:
        width = 2.0 * max(p.clearance, res)
        long_narrow = p.area / width / width >= elongation
        p.kind_hint = "corridor" if long_narrow and degree[p.id] >= 3 else "room"
    if path is not None and len(path):
        pts = np.asarray(path, dtype=np.float64)[:, :2]
        cols = np.floor((pts[:, 0] - origin[0]) / res).astype(int)
        rows = np.floor((pts[:, 1] - origin[1]) / res).astype(int)
        ok = (rows >= 0) & (rows < labels.shape[0]) & (cols >= 0) & (cols < labels.shape[1])
        hits = labels[rows[ok], cols[ok]]
        hits = hits[hits > 0]
        if len(hits):
            counts = np.bincount(hits)
            best = f"P{int(np.argmax(counts))}"
            for p in places:
                share = counts[int(p.id[1:])] / len(hits) if int(p.id[1:]) < len(counts) else 0
                if p.id == best or share >= 0.2:
                    p.kind_hint = "corridor"


# ---- signs ---------------------------------------------------------------------------------
def attach_signs(pm: PlaceMap, signs: Iterable[Mapping[str, Any]], *, max_door_distance: float = 2.0,
                 max_off_wall: float = 0.6) -> dict[int, str | None]:
    """Which place each door sign names.

    A sign names the room behind *its* door, not the place it hangs in (the
    corridor). For each sign (x, y, facing in degrees = the direction the
    plate faces, into the corridor):

    1. the place in front is the one 0.3-1.0 m along the facing;
    2. candidate doors: within ``max_door_distance`` of the sign, centre within
       ``max_off_wall`` of the wall line through the sign (the line across the
       facing); the nearest wins. The room is the door's side found 0.4-1.2 m
       *behind* the door centre (against the facing, through the opening), or,
       failing that, the side that is not the place in front;
    3. otherwise the place 0.4-1.0 m behind the plate (through the wall), if
       mapped and not the place in front;
    4. otherwise None.

    Step 2 looks behind the door rather than requiring the door to touch the
    place in front, so a corridor split in two near the sign does not matter.

    Two signs with different texts cannot name one place.  When they claim
    the same one, a sign that found its door (step 2) beats one that looked
    through the wall (step 3), then the nearer door wins; the loser names
    nothing.  Why: a room whose door the map lacks can show through the wall
    behind its plate as the room next door (on a drifted map, a metre off),
    and that room's own sign, beside its own door, is the better witness.

    Parameters
    ----------
    pm
        The segmentation.
    signs
        Mappings with ``x``, ``y``, ``facing`` (degrees), e.g. signs.json records.
    max_door_distance, max_off_wall
        Door search limits (m).

    Returns
    -------
    dict
        Sign index -> place id (or None), for every sign.
    """
    signs = list(signs)
    claims: dict[int, tuple[str, int, float]] = {}  # sign -> (place, step, door distance)
    for i, s in enumerate(signs):
        x, y = float(s["x"]), float(s["y"])
        f = math.radians(float(s.get("facing", float("nan"))))
        if not math.isfinite(f):
            continue
        nx_, ny_ = math.cos(f), math.sin(f)
        front = _first_place(pm, x, y, nx_, ny_, (0.3, 0.5, 0.7, 1.0))
        best, best_d = None, float("inf")
        for d in pm.doors:
            dx, dy = d.x - x, d.y - y
            dist = math.hypot(dx, dy)
            if dist > max_door_distance or abs(dx * nx_ + dy * ny_) > max_off_wall:
                continue
            room = _first_place(pm, d.x, d.y, -nx_, -ny_, (0.4, 0.6, 0.8, 1.0, 1.2))
            if room not in (d.a, d.b) or room == front:
                room = d.other(front) if front in (d.a, d.b) else None
            if room is not None and dist < best_d:
                best, best_d = room, dist
        if best is not None:
            claims[i] = (best, 2, best_d)
            continue
        behind = _first_place(pm, x, y, -nx_, -ny_, (0.4, 0.6, 0.8, 1.0))
        if behind is not None and behind != front:
            claims[i] = (behind, 3, float("inf"))
    out: dict[int, str | None] = {i: None for i in range(len(signs))}
    for i, (place, step, dist) in claims.items():
        text = canonical(signs[i].get("text", ""))
        rivals = [(s, d) for j, (p, s, d) in claims.items()
                  if p == place and canonical(signs[j].get("text", "")) != text]
        if all((step, dist) < rival for rival in rivals):
            out[i] = place
    return out


def _first_place(pm: PlaceMap, x: float, y: float, dx: float, dy: float,
                 steps: Iterable[float]) -> str | None:
    for t in steps:
        pid = pm.place_at(x + t * dx, y + t * dy)
        if pid is not None:
            return pid
    return None


def place_names(signs: list[Mapping[str, Any]], attached: Mapping[int, str | None]) -> dict[str, str]:
    """Place id -> sign text from :func:`attach_signs` (first sign wins for a place)."""
    names: dict[str, str] = {}
    for i, pid in sorted(attached.items()):
        if pid is not None and pid not in names:
            names[pid] = str(signs[i]["text"])
    return names
