"""Hall: an open hall with rooms off it and a corridor leading away to a dead end.

The hall (10-20 m x 8-14 m) may have its corners cut at 45 degrees and a grid
of pillars; rooms open straight off its long walls, and a corridor with
rooms on both sides leaves from its east wall.
"""
from __future__ import annotations

import numpy as np

from ..floorplan import Box, Door, FloorPlan, Space, corridor_start, room_row, snap
from ..names import RoomNamer


def draw(plan: FloorPlan, rng: np.random.Generator, namer: RoomNamer) -> None:
    """Fill ``plan`` with a hall floor (in place)."""
    t = plan.wall
    hx, hy = snap(rng.uniform(10.0, 20.0)), snap(rng.uniform(8.0, 14.0))
    cut = snap(rng.uniform(1.5, 3.0)) if rng.random() < 0.5 else 0.0
    w = snap(rng.uniform(1.4, 3.0))  # the corridor leaving from the east wall
    if hy - 2 * cut - w < 1.2:  # no straight east wall left for it: square corners
        cut = 0.0
    if cut:
        polygon = [(cut, 0.0), (hx - cut, 0.0), (hx, cut), (hx, hy - cut), (hx - cut, hy),
                   (cut, hy), (0.0, hy - cut), (0.0, cut)]
    else:
        polygon = [(0.0, 0.0), (hx, 0.0), (hx, hy), (0.0, hy)]
    plan.spaces.append(Space("HALL", "Hall", polygon, role="hall"))
    hall = (0.0, 0.0, hx, hy)
    lo, hi = snap(cut + t), snap(hx - cut - t) if cut else hx
    lo = lo if cut else 0.0
    room_row(plan, rng, namer, "HALL", hall, "S", lo, hi, snap(rng.uniform(3.5, 7.0)))
    room_row(plan, rng, namer, "HALL", hall, "N", lo, hi, snap(rng.uniform(3.5, 7.0)))
    if rng.random() < 0.6:  # pillars in a grid, 2.5-4 m apart, 1.2 m clear of the walls
        step = rng.uniform(2.5, 4.0)
        for px in np.arange(cut + 2.0, hx - cut - 1.5, step):
            for py in np.arange(2.0, hy - 1.5, step):
                plan.boxes.append(Box(snap(px), snap(py), snap(px + 0.4), snap(py + 0.4)))
    y0 = snap(rng.uniform(cut + 0.5, hy - cut - w - 0.5))
    length = snap(rng.uniform(10.0, 30.0))
    leg = (hx, y0, snap(hx + length), snap(y0 + w))
    plan.spaces.append(Space.box("CORRIDOR", "Corridor", *leg, role="corridor"))
    plan.doors.append(Door((hx, y0, hx, snap(y0 + w)), ("CORRIDOR", "HALL")))
    for side in ("S", "N"):
        room_row(plan, rng, namer, "CORRIDOR", leg, side, snap(hx + t), leg[2],
                 snap(rng.uniform(3.0, 6.0)))
    shape = "cut corners" if cut else "square corners"
    plan.doc = (f"An open hall {hx:.1f} m x {hy:.1f} m ({shape}) with rooms off it and a "
                f"{length:.1f} m corridor to a dead end.")
    open_floor = not cut and not any(b.x1 <= hx for b in plan.boxes)  # no pillars, no cuts
    plan.start = corridor_start(plan, rng, hall if open_floor and rng.random() < 0.5 else leg)
