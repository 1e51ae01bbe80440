"""School: a main corridor with one branch (a T) or two (a comb), each ending in a dead end.

Classrooms are large (5-9 m); branches are separate corridor places joined
to the main one by an opening as wide as the branch.
"""
from __future__ import annotations

import numpy as np

from ..floorplan import Door, FloorPlan, Space, corridor_start, room_row, snap
from ..names import RoomNamer


def draw(plan: FloorPlan, rng: np.random.Generator, namer: RoomNamer) -> None:
    """Fill ``plan`` with a school floor (in place)."""
    t = plan.wall
    length = snap(rng.uniform(20.0, 50.0))
    w = snap(rng.uniform(1.6, 3.5))
    south, north = snap(rng.uniform(4.0, 9.0)), snap(rng.uniform(4.0, 9.0))
    count = 1 if rng.random() < 0.5 else 2
    wb = [snap(rng.uniform(1.4, 3.0)) for _ in range(count)]
    if count == 1:
        xs = [snap(rng.uniform(0.3, 0.7) * length - wb[0] / 2)]
    else:
        xs = [snap(rng.uniform(0.12, 0.3) * length), snap(rng.uniform(0.65, 0.85) * length)]
    main = (0.0, 0.0, length, w)
    plan.spaces.append(Space.box("CORRIDOR 1", "Corridor", *main, role="corridor"))
    room_row(plan, rng, namer, "CORRIDOR 1", main, "S", 0.0, length, south,
             width=(4.0, 9.0), kinds=["Classroom"])
    legs = [main]
    edges = [0.0] + [v for x, b in zip(xs, wb) for v in (snap(x - t), snap(x + b + t))] + [length]
    for u0, u1 in zip(edges[::2], edges[1::2]):  # the north wall between the branches
        if u1 - u0 >= 2.5:
            room_row(plan, rng, namer, "CORRIDOR 1", main, "N", u0, u1, north, width=(4.0, 9.0))
    # rooms between two branches share the space between them
    between = (xs[1] - xs[0] - wb[0] - 3 * t) / 2 if count == 2 else 8.0
    for i, (x, b) in enumerate(zip(xs, wb)):
        name = f"CORRIDOR {i + 2}"
        rise = snap(rng.uniform(8.0, 20.0))
        leg = (x, w, snap(x + b), snap(w + rise))
        plan.spaces.append(Space.box(name, "Corridor", *leg, role="corridor"))
        plan.doors.append(Door((x, w, snap(x + b), w), (name, "CORRIDOR 1")))
        start = snap(w + t + north + t)
        if leg[3] - start >= 2.5:
            for side in ("W", "E"):
                inner = count == 2 and (side == "E") == (i == 0)
                depth = snap(rng.uniform(4.0, 8.0))
                depth = snap(min(depth, between)) if inner else depth
                if depth >= 2.5:
                    room_row(plan, rng, namer, name, leg, side, start, leg[3], depth,
                             width=(3.0, 9.0), kinds=["Classroom"])
        legs.append(leg)
    shape = "a T" if count == 1 else "a comb"
    plan.doc = f"A school: a {length:.1f} m corridor with {shape} of dead-end branches, classrooms."
    plan.start = corridor_start(plan, rng, legs[int(rng.integers(len(legs)))])
