"""Office: a straight corridor, or an L of two legs, with rooms on both sides.

Rooms 2.5-8 m wide and 3-8 m deep line both walls; the corridor is 1.2-3.5 m
wide and ends in dead ends. An L's second leg turns north at the east end.
"""
from __future__ import annotations

import numpy as np

from ..floorplan import FloorPlan, Space, corridor_start, room_row, snap
from ..names import RoomNamer


def draw(plan: FloorPlan, rng: np.random.Generator, namer: RoomNamer) -> None:
    """Fill ``plan`` with an office floor (in place)."""
    t = plan.wall
    length = snap(rng.uniform(10.0, 50.0))
    width = snap(rng.uniform(1.2, 3.5))
    south, north = snap(rng.uniform(2.5, 8.0)), snap(rng.uniform(2.5, 8.0))
    main = (0.0, 0.0, length, width)
    legs = [main]
    if rng.random() < 0.4:  # an L: a second leg turning north at the east end
        width2 = snap(rng.uniform(1.2, 3.5))
        rise = snap(rng.uniform(8.0, 26.0))
        x0 = snap(length - width2)
        leg2 = (x0, 0.0, length, width + rise)
        polygon = [(0.0, 0.0), (length, 0.0), (length, width + rise), (x0, width + rise),
                   (x0, width), (0.0, width)]
        plan.spaces.append(Space("CORRIDOR", "Corridor", polygon, role="corridor"))
        room_row(plan, rng, namer, "CORRIDOR", main, "S", 0.0, length, south)
        room_row(plan, rng, namer, "CORRIDOR", main, "N", 0.0, snap(x0 - t), north)
        room_row(plan, rng, namer, "CORRIDOR", leg2, "E", 0.0, width + rise,
                 snap(rng.uniform(3.0, 8.0)))
        west_from = snap(width + t + north + t)
        if width + rise - west_from >= 2.5:
            room_row(plan, rng, namer, "CORRIDOR", leg2, "W", west_from, width + rise,
                     snap(rng.uniform(3.0, 8.0)))
        legs.append(leg2)
        plan.doc = (f"An L-shaped office corridor ({length:.1f} m and {rise:.1f} m legs) with "
                    "rooms on both sides.")
    else:
        plan.spaces.append(Space.box("CORRIDOR", "Corridor", *main, role="corridor"))
        room_row(plan, rng, namer, "CORRIDOR", main, "S", 0.0, length, south)
        room_row(plan, rng, namer, "CORRIDOR", main, "N", 0.0, length, north)
        plan.doc = f"A straight office corridor {length:.1f} m x {width:.2f} m, rooms both sides."
    plan.start = corridor_start(plan, rng, legs[int(rng.integers(len(legs)))])
