"""Hospital: a long double-loaded corridor broken by one or two wide halls.

The corridor (2.0-3.5 m) runs 30-58 m; each hall (6-10 m long) bulges 2-4 m
beyond it on both sides, rooms open off its far walls, and it may hold an
island counter. Corridor pieces and halls are separate places joined by
openings, as in the shipped hospital.
"""
from __future__ import annotations

import numpy as np

from ..floorplan import Box, Door, FloorPlan, Space, corridor_start, room_row, snap
from ..names import RoomNamer


def draw(plan: FloorPlan, rng: np.random.Generator, namer: RoomNamer) -> None:
    """Fill ``plan`` with a hospital floor (in place)."""
    t = plan.wall
    length = snap(rng.uniform(30.0, 58.0))
    w = snap(rng.uniform(2.0, 3.5))
    south, north = snap(rng.uniform(4.0, 8.0)), snap(rng.uniform(4.0, 8.0))
    halls = 1 if length < 42 or rng.random() < 0.5 else 2
    cuts = np.sort(rng.uniform(0.25, 0.75, halls)) if halls == 1 else np.array(
        [rng.uniform(0.2, 0.35), rng.uniform(0.6, 0.75)])
    pieces, hall_rects = [], []
    x = 0.0
    for i, c in enumerate(cuts):
        hw = snap(rng.uniform(6.0, 10.0))
        h0 = snap(c * length - hw / 2)
        pieces.append((x, 0.0, h0, w))
        ext_s, ext_n = snap(rng.uniform(2.0, 4.0)), snap(rng.uniform(2.0, 4.0))
        hall_rects.append((h0, -ext_s, snap(h0 + hw), snap(w + ext_n)))
        x = snap(h0 + hw)
    pieces.append((x, 0.0, length, w))
    names = [f"CORRIDOR {i + 1}" for i in range(len(pieces))]
    for i, (name, rect) in enumerate(zip(names, pieces)):
        plan.spaces.append(Space.box(name, "Corridor", *rect, role="corridor"))
        u0 = snap(rect[0] + t) if i > 0 else rect[0]  # a wall's width from the halls
        u1 = snap(rect[2] - t) if i < len(pieces) - 1 else rect[2]
        room_row(plan, rng, namer, name, rect, "S", u0, u1, south)
        room_row(plan, rng, namer, name, rect, "N", u0, u1, north)
    for i, rect in enumerate(hall_rects):
        hall = f"HALL {i + 1}"
        plan.spaces.append(Space.box(hall, "Hall", *rect, role="hall"))
        x0, y0, x1, y1 = rect
        for name, piece in ((names[i], pieces[i]), (names[i + 1], pieces[i + 1])):
            face = x0 if piece[2] <= x0 + 1e-9 else x1
            plan.doors.append(Door((face, 0.0, face, w), (name, hall)))
        room_row(plan, rng, namer, hall, rect, "S", x0, x1, snap(rng.uniform(3.0, 6.0)))
        room_row(plan, rng, namer, hall, rect, "N", x0, x1, snap(rng.uniform(3.0, 6.0)))
        if rng.random() < 0.6 and (y1 - y0) > 7.0:
            cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
            plan.boxes.append(Box(snap(cx - 1.4), snap(cy - 0.7), snap(cx + 1.4),
                                  snap(cy + 0.7)))
    plan.doc = (f"A hospital corridor {length:.1f} m x {w:.2f} m broken by {halls} hall"
                f"{'s' if halls > 1 else ''}, rooms on both sides.")
    plan.start = corridor_start(plan, rng, pieces[int(rng.integers(len(pieces)))])
