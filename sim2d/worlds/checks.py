"""The checks every generated floor must pass: a floor that fails its own check is a bug.

- the whole floor is connected for a 0.5 m robot: every place behind an open
  door is reachable from the start by a disc of 0.25 m radius;
- every sign hangs on a wall face and faces free space;
- every place's polygon matches the image: free inside (but for furniture),
  wall or another place or a door just outside, and no two places overlap;
- the start, the open doors and the objects are in free space, the closed
  doors in walls.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from sim2d.world import World, distance_to_segments, world_is_occupied

from .generate import point_in_polygon
from .rasterize import RESOLUTION, polygon_pixels

__all__ = ["check_generated", "point_in_polygon"]

ROBOT_RADIUS = 0.25  # m: half the 0.5 m robot's width
MAX_FURNITURE = 0.3  # share of a room's interior furniture may take
MAX_LEAK = 0.02  # share of a place's outline that may be neither wall, place nor door


def _place_masks(world: World) -> list[np.ndarray]:
    h, w = world.occupied.shape
    masks = []
    for place in world.places:
        m = np.zeros((h, w), dtype=bool)
        polygon_pixels(m, [(x - world.origin[0], y - world.origin[1]) for x, y in place.polygon])
        masks.append(m)
    return masks


def _cell(world: World, x: float, y: float) -> tuple[int, int]:
    h = world.occupied.shape[0]
    return (h - 1 - int(math.floor((y - world.origin[1]) / world.resolution)),
            int(math.floor((x - world.origin[0]) / world.resolution)))


def _reachable(world: World) -> np.ndarray:
    """Cells a disc of :data:`ROBOT_RADIUS` can reach from the start."""
    free = (~world.occupied).astype(np.uint8)
    clear = cv2.distanceTransform(free, cv2.DIST_L2, 5) * world.resolution > ROBOT_RADIUS
    _, labels = cv2.connectedComponents(clear.astype(np.uint8), connectivity=8)
    r, c = _cell(world, *world.start[:2])
    return labels == labels[r, c] if clear[r, c] else np.zeros_like(clear)


def _door_mask(world: World) -> np.ndarray:
    """Pixels near any door (open or shut): an outline may pass through them."""
    mask = np.zeros(world.occupied.shape, dtype=bool)
    for d in world.doors:
        r, c = _cell(world, d.x, d.y)
        k = int(math.ceil((d.width / 2 + 0.3) / world.resolution))
        mask[max(0, r - k):r + k + 1, max(0, c - k):c + k + 1] = True
    return mask


def check_generated(world: World) -> list[str]:
    """Problems with a generated world; an empty list if there are none.

    Parameters
    ----------
    world : sim2d.world.World
        A loaded world with ``places`` and ``doors`` (its image is the truth).

    Returns
    -------
    list of str
        One sentence per problem.
    """
    problems: list[str] = []
    occ = world.occupied
    masks = _place_masks(world)
    reach = _reachable(world)
    if not reach.any():
        problems.append("the start is not clear for a 0.5 m robot")
    shut = {p for d in world.doors if d.closed for p in d.between}
    open_ = {p for d in world.doors if not d.closed for p in d.between}
    clear = cv2.distanceTransform((~occ).astype(np.uint8), cv2.DIST_L2, 5) * world.resolution
    doors = _door_mask(world)
    union = np.zeros_like(occ)
    for place, mask in zip(world.places, masks):
        if (union & mask).sum() > 4:
            problems.append(f"place {place.name!r} overlaps another place")
        union |= mask
    for place, mask in zip(world.places, masks):
        inside = int(mask.sum())
        if inside == 0:
            problems.append(f"place {place.name!r} covers no pixel")
            continue
        if occ[mask].mean() > MAX_FURNITURE:
            problems.append(f"place {place.name!r} is {occ[mask].mean():.0%} wall inside")
        ring = cv2.dilate(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & ~mask
        leak = ring & ~occ & ~union & ~doors
        if leak.sum() > MAX_LEAK * ring.sum():
            problems.append(f"place {place.name!r}: {leak.sum()} px of its outline are open "
                            "floor, not wall")
        roomy = mask & (clear > ROBOT_RADIUS)
        if place.name in shut and place.name not in open_:
            if (roomy & reach).any():
                problems.append(f"place {place.name!r} is behind a closed door but reachable")
        elif roomy.any() and (roomy & reach).sum() < 0.95 * roomy.sum():
            problems.append(f"place {place.name!r} is not reachable for a 0.5 m robot "
                            f"({(roomy & reach).sum() / roomy.sum():.0%} of it)")
    for sign in world.signs:
        gap = float(distance_to_segments(np.array([sign.x, sign.y]), world.segments).min())
        if not -0.06 <= gap <= 0.06:
            problems.append(f"sign {sign.text!r} is {gap:.3f} m off the wall surface")
        front = (sign.x + 0.5 * math.cos(sign.facing), sign.y + 0.5 * math.sin(sign.facing))
        if world_is_occupied(world, *front, margin=0.3):
            problems.append(f"sign {sign.text!r} does not face free space")
    x, y, _ = world.start
    if world_is_occupied(world, x, y, margin=0.45):
        problems.append("the start is less than 0.45 m from a wall")
    for d in world.doors:
        if d.closed != world_is_occupied(world, d.x, d.y):
            state = "closed door is open" if d.closed else "door is not an opening"
            problems.append(f"the {state} at ({d.x:.2f}, {d.y:.2f}) between {d.between}")
    for obj in world.objects:
        if world_is_occupied(world, obj.x, obj.y) or not any(
                point_in_polygon(obj.x, obj.y, p.polygon) for p in world.places):
            problems.append(f"object {obj.label} at ({obj.x:.2f}, {obj.y:.2f}) is not in a place")
    return problems
