"""Ring: a corridor loop round a central block, rooms outside it.

The block in the middle holds rooms opening onto the loop, or is a closed
courtyard. One leg is sometimes pinched to 0.9-1.1 m by two piers: a
perimeter follower that turns back there sees a third of the floor.
"""
from __future__ import annotations

import numpy as np

from ..floorplan import Box, FloorPlan, Space, corridor_start, room_row, snap
from ..names import RoomNamer


def draw(plan: FloorPlan, rng: np.random.Generator, namer: RoomNamer) -> None:
    """Fill ``plan`` with a ring floor (in place)."""
    t = plan.wall
    w = snap(rng.uniform(1.4, 3.0))
    a = snap(rng.uniform(16.0, 45.0))
    b = snap(rng.uniform(11.0, 26.0))
    inner = (snap(w + t), snap(w + t), snap(a - w - t), snap(b - w - t))
    ring = [(0.0, b / 2), (0.0, 0.0), (a, 0.0), (a, b), (0.0, b), (0.0, b / 2),
            (w, b / 2), (w, b - w), (a - w, b - w), (a - w, w), (w, w), (w, b / 2)]
    plan.spaces.append(Space("CORRIDOR", "Corridor", ring, role="corridor"))
    legs = {"S": (0.0, 0.0, a, w), "N": (0.0, b - w, a, b), "W": (0.0, 0.0, w, b),
            "E": (a - w, 0.0, a, b)}
    room_row(plan, rng, namer, "CORRIDOR", legs["S"], "S", 0.0, a, snap(rng.uniform(3.0, 7.0)))
    room_row(plan, rng, namer, "CORRIDOR", legs["N"], "N", 0.0, a, snap(rng.uniform(3.0, 7.0)))
    if rng.random() < 0.5:
        room_row(plan, rng, namer, "CORRIDOR", legs["E"], "E", 0.0, b, snap(rng.uniform(3.0, 6.0)))
    core_h = inner[3] - inner[1]
    courtyard = rng.random() < 0.3 or core_h < 2.5
    if not courtyard:  # rooms in the block, back to back, opening onto the south and north legs
        if core_h >= 5.0 + t:
            half = snap((core_h - t) / 2)
            room_row(plan, rng, namer, "CORRIDOR", legs["S"], "N", inner[0], inner[2], half)
            room_row(plan, rng, namer, "CORRIDOR", legs["N"], "S", inner[0], inner[2],
                     snap(core_h - t - half))
        else:
            room_row(plan, rng, namer, "CORRIDOR", legs["S"], "N", inner[0], inner[2], core_h)
    pinch = ""
    if rng.random() < 0.5:
        pinch = _pinch(plan, rng, legs, w)
    plan.doc = (f"A ring corridor ({a:.1f} m x {b:.1f} m, {w:.2f} m wide) round "
                + ("a closed courtyard" if courtyard else "a block of rooms")
                + ", rooms outside" + pinch + ".")
    plan.start = corridor_start(plan, rng, legs[["S", "N", "W", "E"][int(rng.integers(4))]])


def _pinch(plan: FloorPlan, rng: np.random.Generator, legs: dict, width: float) -> str:
    """Two piers narrowing a leg to 0.9-1.1 m, away from doors and signs; a note for the doc."""
    gap = snap(rng.uniform(0.9, 1.1))
    if width < gap + 0.3:
        return ""
    for _ in range(20):
        name = ["S", "N", "W", "E"][int(rng.integers(4))]
        x0, y0, x1, y1 = legs[name]
        along_x = name in ("S", "N")
        lo, hi = (x0, x1) if along_x else (y0, y1)
        u = snap(rng.uniform(lo + width + 2.0, hi - width - 3.0))
        length = snap(rng.uniform(0.3, 1.0))
        if _busy(plan, along_x, u - 1.0, u + length + 1.0):
            continue
        side_a = snap(rng.uniform(0.1, width - gap - 0.1))
        side_b = snap(width - gap - side_a)
        if along_x:
            plan.boxes += [Box(u, y0, u + length, y0 + side_a), Box(u, y1 - side_b, u + length, y1)]
        else:
            plan.boxes += [Box(x0, u, x0 + side_a, u + length), Box(x1 - side_b, u, x1, u + length)]
        return f", its {name} leg pinched to {gap:.2f} m"
    return ""


def _busy(plan: FloorPlan, along_x: bool, lo: float, hi: float) -> bool:
    """Does a door or plate of the loop lie in this stretch of a leg?"""
    for d in plan.doors:
        x0, y0, x1, y1 = d.rect
        a, b = (x0, x1) if along_x else (y0, y1)
        if b > lo and a < hi:
            return True
    return any(lo - 0.5 < (p.x if along_x else p.y) < hi + 0.5 for p in plan.plates)
