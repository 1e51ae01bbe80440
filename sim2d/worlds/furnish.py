"""Furniture, alcoves and objects in a generated floor's rooms.

Furniture stands against a room's back or side wall, clear of the door;
about one room in six loses a far corner to an alcove (an L-shaped room);
objects of the catalogue that belong in a room's kind stand in view of its
door, within 1-2.5 m of it, each with its own scale, lighting and cover
(:func:`sim2d.worlds.looks.object_look`).
"""
from __future__ import annotations

import numpy as np

from .floorplan import Box, Door, FloorPlan, Space, Thing, snap
from .looks import object_look

__all__ = ["OBJECTS_OF_KIND", "furnish"]

#: Place class -> catalogue objects that belong there.
OBJECTS_OF_KIND = {
    "Kitchen": ["CoffeeMachine", "Fridge", "Microwave"], "Administration": ["Printer", "Shredder"],
    "CopyRoom": ["Photocopier", "Printer"], "Library": ["Bookshelf"],
    "Laboratory": ["Microscope", "Workbench"], "MeetingRoom": ["Projector", "Whiteboard"],
    "Classroom": ["Whiteboard", "Projector"], "ServerRoom": ["ServerRack"],
    "Maintenance": ["Toolbox", "Workbench"], "MailRoom": ["Parcel"], "Pharmacy": ["Medicine"],
    "ComputerRoom": ["ServerRack"], "StaffRoom": ["CoffeeMachine"], "BreakRoom": ["Fridge"],
    "Storage": ["Parcel"], "ManagerOffice": ["Bookshelf"],
}


def furnish(plan: FloorPlan, rng: np.random.Generator) -> None:
    """Add alcoves, furniture and objects to the plan's rooms (in place)."""
    used: set[str] = set()
    for room in plan.rooms():
        door = next((d for d in plan.doors if room.name in d.between), None)
        if door is None:
            continue
        x0, y0, x1, y1 = room.bounds()
        if min(x1 - x0, y1 - y0) >= 4.0 and rng.random() < 0.17:
            _alcove(room, door, rng)
        if min(x1 - x0, y1 - y0) >= 3.0 and rng.random() < 0.6:
            _furniture(plan, room, door, rng)
        labels = [lb for lb in OBJECTS_OF_KIND.get(room.kind, []) if lb not in used]
        if labels and not door.closed and rng.random() < 0.8:
            label = labels[int(rng.integers(len(labels)))]
            spot = _in_view_of_door(plan, room, door, rng)
            if spot is not None:
                used.add(label)  # one of each label per floor: "the printer" is one thing
                plan.things.append(Thing(label, *spot, object_look(rng)))


def _inward(room: Space, door: Door) -> tuple[np.ndarray, np.ndarray]:
    """The door's centre and the unit vector from it into the room."""
    x0, y0, x1, y1 = room.bounds()
    cx, cy = door.centre
    dx0, dy0, dx1, dy1 = door.rect
    if dx1 - dx0 > dy1 - dy0:  # a door in a wall along x
        normal = np.array([0.0, 1.0 if (y0 + y1) / 2 > cy else -1.0])
    else:
        normal = np.array([1.0 if (x0 + x1) / 2 > cx else -1.0, 0.0])
    return np.array([cx, cy]), normal


def _alcove(room: Space, door: Door, rng: np.random.Generator) -> None:
    """Cut one of the corners across from the door off the room: the room becomes an L."""
    x0, y0, x1, y1 = room.bounds()
    centre, normal = _inward(room, door)
    far = [c for c in room.polygon if float(np.dot(np.array(c) - centre, normal)) > 0.5]
    corner = far[int(rng.integers(len(far)))]
    cut = {0: snap(rng.uniform(0.3, 0.45) * (x1 - x0)), 1: snap(rng.uniform(0.3, 0.45) * (y1 - y0))}
    pts = list(room.polygon)
    i = pts.index(corner)
    c = np.array(corner)

    def towards(other: tuple[float, float]) -> np.ndarray:
        d = np.array(other) - c
        axis = 0 if abs(d[0]) > abs(d[1]) else 1
        return np.sign(d) * np.eye(2)[axis] * cut[axis]

    a, b = towards(pts[i - 1]), towards(pts[(i + 1) % len(pts)])
    notch = [c + a, c + a + b, c + b]
    room.polygon = pts[:i] + [(round(float(x), 4), round(float(y), 4)) for x, y in notch] + pts[i + 1:]


def _furniture(plan: FloorPlan, room: Space, door: Door, rng: np.random.Generator) -> None:
    """A desk, bench or shelf against the wall opposite the door, clear of the alcove."""
    x0, y0, x1, y1 = room.bounds()
    centre, normal = _inward(room, door)
    depth = snap(rng.uniform(0.5, 0.9))
    if normal[1] != 0:
        length = snap(rng.uniform(0.3, 0.5) * (x1 - x0))
        a = snap(rng.uniform(x0 + 0.3, x1 - 0.3 - length))
        b0, b1 = (y1 - depth, y1) if normal[1] > 0 else (y0, y0 + depth)
        box = Box(a, snap(b0), snap(a + length), snap(b1))
    else:
        length = snap(rng.uniform(0.3, 0.5) * (y1 - y0))
        a = snap(rng.uniform(y0 + 0.3, y1 - 0.3 - length))
        b0, b1 = (x1 - depth, x1) if normal[0] > 0 else (x0, x0 + depth)
        box = Box(snap(b0), a, snap(b1), snap(a + length))
    if _box_inside(room, box):
        plan.boxes.append(box)


def _box_inside(room: Space, box: Box) -> bool:
    from .checks import point_in_polygon
    corners = [(box.x0 + 0.01, box.y0 + 0.01), (box.x1 - 0.01, box.y0 + 0.01),
               (box.x1 - 0.01, box.y1 - 0.01), (box.x0 + 0.01, box.y1 - 0.01)]
    return all(point_in_polygon(x, y, np.asarray(room.polygon)) for x, y in corners)


def _in_view_of_door(plan: FloorPlan, room: Space, door: Door,
                     rng: np.random.Generator) -> tuple[float, float] | None:
    """A point inside the room, 1-2.5 m in from the door and roughly in line with it."""
    from .checks import point_in_polygon
    centre, normal = _inward(room, door)
    side = np.array([-normal[1], normal[0]])
    poly = np.asarray(room.polygon)
    for _ in range(20):
        p = centre + normal * rng.uniform(1.0, 2.5) + side * rng.uniform(-0.6, 0.6)
        probe = [p + 0.45 * np.array(v) for v in ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1))]
        if all(point_in_polygon(q[0], q[1], poly) for q in probe) and not any(
                b.x0 - 0.3 <= p[0] <= b.x1 + 0.3 and b.y0 - 0.3 <= p[1] <= b.y1 + 0.3
                for b in plan.boxes):
            return (round(float(p[0]), 3), round(float(p[1]), 3))
    return None
