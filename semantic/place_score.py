"""Score a place segmentation against a world's ground truth (places and doors).

The true places of a world file (``places:``) are rasterised on the
segmentation's own grid: a cell belongs to a true place if its centre is inside
the polygon (even-odd rule, so the office's slit corridor ring works) and the
world's floor plan is free there. The map's "observed" cells are the cells
that belong to some segmented place (known free space).
"""
from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from blocks.maps.mapio import OccupancyMap, occupancy_map_from_world
from semantic.places import PlaceMap

#: True place kinds one passes through rather than visits: scored as corridors, not rooms.
PASSAGE_KINDS = ("Corridor", "Hall")


def true_map(world: Any) -> OccupancyMap:
    """The world's floor plan as a perfect map, with the outside of the building unknown.

    :func:`blocks.maps.mapio.occupancy_map_from_world` marks every non-wall
    pixel free, including the strip outside the outer walls; a mapper never
    sees that, so here the free cells connected to the image border are NaN.
    """
    from scipy import ndimage

    m = occupancy_map_from_world(world)
    free = m.occupancy < 0.5
    parts, _ = ndimage.label(free)
    edge = np.unique(np.concatenate([parts[0], parts[-1], parts[:, 0], parts[:, -1]]))
    outside = np.isin(parts, edge[edge > 0])
    occ = m.occupancy.copy()
    occ[outside] = np.nan
    return OccupancyMap(occupancy=occ, resolution=m.resolution, origin=m.origin)


def polygon_mask_on_grid(polygon: np.ndarray, shape: tuple[int, int], resolution: float,
                         origin: tuple[float, float, float]) -> np.ndarray:
    """Cells (row 0 = lowest y) whose centres are inside a polygon (even-odd rule).

    Row by row: a cell centre is inside when an odd number of the polygon's
    edges cross its row to its right, so each row needs its crossings, not a
    test of every edge at every cell (a whole-grid test per edge held a
    generated floor's scoring at over 100 MB).
    """
    h, w = shape
    xs = origin[0] + (np.arange(w) + 0.5) * resolution
    ys = origin[1] + (np.arange(h) + 0.5) * resolution
    inside = np.zeros((h, w), dtype=bool)
    pts = np.asarray(polygon, dtype=np.float64)
    x1, y1 = pts[:, 0], pts[:, 1]
    x2, y2 = np.roll(x1, -1), np.roll(y1, -1)
    sloped = y1 != y2
    x1, y1, x2, y2 = x1[sloped], y1[sloped], x2[sloped], y2[sloped]
    if len(x1) == 0:
        return inside
    low, high = min(y1.min(), y2.min()), max(y1.max(), y2.max())
    rows = np.flatnonzero((ys >= low) & (ys <= high))  # rows no edge spans: outside
    for r in rows.tolist():
        py = ys[r]
        crosses = (y1 > py) != (y2 > py)
        if not crosses.any():
            continue
        a1, b1, a2, b2 = x1[crosses], y1[crosses], x2[crosses], y2[crosses]
        x_cross = np.sort(a1 + (py - b1) * (a2 - a1) / (b2 - b1))
        right = len(x_cross) - np.searchsorted(x_cross, xs, side="right")  # crossings > x
        inside[r] = (right & 1).astype(bool)
    return inside


def world_free_on_grid(world: Any, shape: tuple[int, int], resolution: float,
                       origin: tuple[float, float, float]) -> np.ndarray:
    """The world's free cells sampled at the centres of another grid (row 0 = lowest y)."""
    h, w = shape
    xs = origin[0] + (np.arange(w) + 0.5) * resolution
    ys = origin[1] + (np.arange(h) + 0.5) * resolution
    wh, ww = world.occupied.shape
    cols = np.floor((xs - world.origin[0]) / world.resolution).astype(int)
    rows = wh - 1 - np.floor((ys - world.origin[1]) / world.resolution).astype(int)
    okc, okr = (cols >= 0) & (cols < ww), (rows >= 0) & (rows < wh)
    free = np.zeros((h, w), dtype=bool)
    sub = ~world.occupied[np.ix_(rows[okr], cols[okc])]
    free[np.ix_(np.flatnonzero(okr), np.flatnonzero(okc))] = sub
    return free


def score_places(pm: PlaceMap, world: Any, *, names: Mapping[str, str],
                 explored: float = 0.15, one_place_share: float = 0.8,
                 door_tolerance: float = 0.5) -> dict[str, Any]:
    """Compare a named segmentation with the world's true places and doors.

    Parameters
    ----------
    pm
        The segmentation.
    world
        A :class:`sim2d.world.World` with ``places`` and ``doors``.
    names
        Place id -> sign text (e.g. from :func:`semantic.places.place_names`);
        several places may carry one name (their union is scored).
    explored
        A room counts as explored when at least this fraction of it was observed.
    one_place_share
        A room is recovered as ONE place when a single segmented place holds at
        least this share of its observed part (and that place carries its name).
    door_tolerance
        A segmented door matches a true one within this distance (m) if it joins
        the room's place to the place covering most of the other true place.

    Returns
    -------
    dict
        ``rooms``: per true signed room (a true place whose name is a sign
        text): ``name``, ``kind``, ``place`` (ids named after it), ``iou``
        (named places vs the whole true room), ``iou_observed`` (vs its
        observed part), ``coverage``, ``one_place``, ``door_found``,
        ``door_width_error`` (m, estimate - truth), ``door_distance`` (m);
        ``corridors``: per true corridor/hall: ``name``, ``places`` (ids holding
        >= 5 % of its observed part), ``one_place``; and the summary
        ``mean_iou`` (all signed rooms), ``mean_iou_explored``, ``explored_rooms``,
        ``named_rooms``, ``one_place_rooms``, ``doors_found``, ``rooms``;
        ``unsigned``: per true room no sign names with an open door (any room
        when the world lists no doors): ``name``, ``kind``, ``place`` (the
        segmented place holding most of its observed part, or None),
        ``named_as`` (the sign text that place carries, or None), ``iou`` (that
        one place vs the whole true room; 0 when no place holds it or the
        place carries any sign's name: the semantic map has no place of its
        own for it), ``coverage``; with ``unsigned_count``,
        ``unsigned_mean_iou`` and ``unsigned_places`` (how many have an
        unnamed place of their own, IoU at least 0.5); and ``open_count``,
        ``open_mean_iou``: every room with an open door, signed or not
        (issue 20's measure: a signed room's IoU as in ``rooms``).
    """
    shape, res, origin = pm.labels.shape, pm.resolution, pm.origin
    free = world_free_on_grid(world, shape, res, origin)
    observed = pm.labels > 0
    signed = {s.text for s in world.signs}
    masks = {p.name: polygon_mask_on_grid(p.polygon, shape, res, origin) & free
             for p in world.places}
    owner: dict[str, int] = {}  # true place -> the label holding most of its observed part
    for name, mask in masks.items():
        hits = pm.labels[mask & observed]
        owner[name] = int(np.bincount(hits).argmax()) if len(hits) else 0
    rooms = []
    for place in world.places:
        if place.name not in signed:
            continue
        truth = masks[place.name]
        ids = sorted(pid for pid, text in names.items() if text == place.name)
        named = np.isin(pm.labels, [int(pid[1:]) for pid in ids]) if ids else np.zeros(shape, bool)
        seen = truth & observed
        n_true, n_seen = int(truth.sum()), int(seen.sum())
        union = int((named | truth).sum())
        union_seen = int((named | seen).sum())
        inter = int((named & truth).sum())
        k = owner[place.name]
        share = float((pm.labels[seen] == k).sum() / n_seen) if n_seen else 0.0
        row: dict[str, Any] = {
            "name": place.name, "kind": place.kind, "place": ids,
            "iou": inter / union if union else 0.0,
            "iou_observed": int((named & seen).sum()) / union_seen if union_seen else 0.0,
            "coverage": n_seen / n_true if n_true else 0.0,
            "one_place": bool(k and share >= one_place_share and f"P{k}" in ids),
            "door_found": False, "door_width_error": None, "door_distance": None,
        }
        for door in world.doors:
            if place.name not in door.between:
                continue
            other = door.between[1] if door.between[0] == place.name else door.between[0]
            want = {f"P{owner[other]}", *ids} if owner.get(other) else None
            best = None
            for d in pm.doors:
                dist = math.hypot(d.x - door.x, d.y - door.y)
                if dist <= door_tolerance and want and {d.a, d.b} <= want and d.a != d.b \
                        and (best is None or dist < best[0]):
                    best = (dist, d)
            if best is not None:
                row.update(door_found=True, door_distance=round(best[0], 3),
                           door_width_error=round(best[1].width - door.width, 3))
        rooms.append(row)
    corridors = []
    for place in world.places:
        if place.kind not in PASSAGE_KINDS:
            continue
        seen = masks[place.name] & observed
        hits = pm.labels[seen]
        counts = np.bincount(hits) if len(hits) else np.zeros(1, int)
        big = [f"P{k}" for k in np.flatnonzero(counts) if k and counts[k] >= 0.05 * len(hits)]
        corridors.append({"name": place.name, "places": big, "one_place": len(big) == 1,
                          "coverage": float(seen.sum() / max(masks[place.name].sum(), 1))})
    unsigned = _unsigned_rooms(pm, world, masks, observed, owner, names, signed)
    open_ious = [r["iou"] for r in rooms if _has_open_door(world, r["name"])]
    open_ious += [r["iou"] for r in unsigned]
    ious = [r["iou"] for r in rooms]
    exp = [r["iou"] for r in rooms if r["coverage"] >= explored]
    return {
        "rooms": rooms, "corridors": corridors,
        "mean_iou": float(np.mean(ious)) if ious else 0.0,
        "mean_iou_explored": float(np.mean(exp)) if exp else 0.0,
        "mean_iou_observed": float(np.mean([r["iou_observed"] for r in rooms])) if rooms else 0.0,
        "explored_rooms": len(exp), "named_rooms": sum(bool(r["place"]) for r in rooms),
        "one_place_rooms": sum(r["one_place"] for r in rooms),
        "doors_found": sum(r["door_found"] for r in rooms), "room_count": len(rooms),
        "unsigned": unsigned, "unsigned_count": len(unsigned),
        "unsigned_mean_iou": float(np.mean([r["iou"] for r in unsigned])) if unsigned else 0.0,
        "unsigned_places": sum(r["iou"] >= 0.5 for r in unsigned),
        "open_count": len(open_ious),
        "open_mean_iou": float(np.mean(open_ious)) if open_ious else 0.0,
    }


def _has_open_door(world: Any, name: str) -> bool:
    """Whether a true place has a door that is not shut (True when the world lists no doors)."""
    if not world.doors:
        return True
    return any(name in door.between and not door.closed for door in world.doors)


def _unsigned_rooms(pm: PlaceMap, world: Any, masks: Mapping[str, np.ndarray],
                    observed: np.ndarray, owner: Mapping[str, int], names: Mapping[str, str],
                    signed: set[str]) -> list[dict[str, Any]]:
    """Each true room without a sign that a robot could enter, against the place that holds it.

    Why: an unsigned room should become an unnamed place of its own in the
    semantic map; a room a sign does not name is still a room a robot is sent
    to ("go to a room next to the kitchen") and its floor belongs in the map.
    """
    rows = []
    for place in world.places:
        if place.name in signed or place.kind in PASSAGE_KINDS \
                or not _has_open_door(world, place.name):
            continue
        truth = masks[place.name]
        n_true = int(truth.sum())
        k = owner[place.name]
        pid = f"P{k}" if k else None
        named_as = names.get(pid) if pid else None
        iou = 0.0
        if k and named_as is None:
            region = pm.labels == k
            union = int((region | truth).sum())
            iou = int((region & truth).sum()) / union if union else 0.0
        rows.append({"name": place.name, "kind": place.kind, "place": pid, "named_as": named_as,
                     "iou": iou,
                     "coverage": int((truth & observed).sum()) / n_true if n_true else 0.0})
    return rows
