"""The floor plan a building layout draws: spaces, doors, plates, furniture, in metres.

A layout (``sim2d/worlds/layouts/*.py``) fills a :class:`FloorPlan` in the
*building frame*: every space is the clear interior of a room, corridor or
hall (a rectangle or a polygon), spaces that share a wall are exactly one wall
thickness apart, and a door is an opening through that wall. Walls are not
drawn: :mod:`sim2d.worlds.rasterize` makes every pixel within one wall
thickness of a space a wall, so the plan cannot leave a gap in the building's
shell. The plan is then turned (``rotation``) and written as a world.

:func:`room_row` is the one primitive every layout shares: a row of rooms
along one side of a corridor or hall, each with a door, most with a sign
beside it on the corridor face of the wall.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .looks import plate_look
from .names import RoomNamer

__all__ = ["Box", "Door", "FloorPlan", "Plate", "Space", "Thing", "room_row", "snap"]

GRID = 0.05  # m: every coordinate a layout chooses lies on this grid (the image's pixels)
SIGN_GAP = (0.25, 0.8)  # m: from a door's edge to the near edge of its plate
DOOR_MARGIN = 0.3  # m: from a door's edge to the room's side wall


def snap(value: float) -> float:
    """The nearest multiple of :data:`GRID` (rounded to 4 decimals).

    Examples
    --------
    >>> snap(1.234)
    1.25
    """
    return round(round(value / GRID) * GRID, 4)


@dataclass
class Space:
    """A room, corridor or hall: its name, ontology class and clear interior.

    ``polygon`` lists the corners (m, building frame) in order; ``signed``
    says whether a plate by its door names it.
    """

    name: str
    kind: str
    polygon: list[tuple[float, float]]
    role: str = "room"  # room | corridor | hall
    signed: bool = False

    @classmethod
    def box(cls, name: str, kind: str, x0: float, y0: float, x1: float, y1: float,
            **kw: Any) -> Space:
        x0, x1 = sorted((x0, x1))
        y0, y1 = sorted((y0, y1))
        return cls(name, kind, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)], **kw)

    def bounds(self) -> tuple[float, float, float, float]:
        xs, ys = zip(*self.polygon)
        return min(xs), min(ys), max(xs), max(ys)


@dataclass
class Door:
    """An opening through a wall: ``rect`` spans the wall's thickness, ``width`` is clear."""

    rect: tuple[float, float, float, float]  # x0, y0, x1, y1 (m)
    between: tuple[str, str]
    closed: bool = False

    @property
    def centre(self) -> tuple[float, float]:
        x0, y0, x1, y1 = self.rect
        return (x0 + x1) / 2, (y0 + y1) / 2

    @property
    def width(self) -> float:
        """Clear width: the opening's extent along the wall (walls are thinner than doors)."""
        x0, y0, x1, y1 = self.rect
        return max(x1 - x0, y1 - y0)


@dataclass
class Plate:
    """A sign on a wall face: text, centre (m), facing (deg, into the free space) and look."""

    text: str
    x: float
    y: float
    facing: float
    look: dict[str, Any] = field(default_factory=dict)  # width, height, z, plate, ink, font...


@dataclass
class Box:
    """A solid obstacle inside a space (furniture, a pillar, a counter), m."""

    x0: float
    y0: float
    x1: float
    y1: float


@dataclass
class Thing:
    """A catalogue object standing in a space (camera only: the sonar does not see it)."""

    label: str
    x: float
    y: float
    look: dict[str, Any] = field(default_factory=dict)  # scale, light, cover


@dataclass
class FloorPlan:
    """Everything a layout draws, in the building frame (metres).

    Attributes
    ----------
    kind, seed : str, int
        What drew it.
    wall : float
        Wall thickness (m); spaces sharing a wall are this far apart.
    spaces, doors, plates, boxes, things : lists
        The clear interiors, the openings, the signs, the obstacles, the objects.
    start : (x, y, theta)
        The robot's start pose (m, rad), in the building frame.
    rotation : float
        The building's turn (rad) when written as a world.
    domain : str
        Which vocabulary domain its rooms come from (office, hospital, school).
    doc : str
        One line about the floor.
    """

    kind: str
    seed: int
    wall: float
    domain: str = "office"
    spaces: list[Space] = field(default_factory=list)
    doors: list[Door] = field(default_factory=list)
    plates: list[Plate] = field(default_factory=list)
    boxes: list[Box] = field(default_factory=list)
    things: list[Thing] = field(default_factory=list)
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: float = 0.0
    doc: str = ""

    def space(self, name: str) -> Space:
        return next(s for s in self.spaces if s.name == name)

    def rooms(self) -> list[Space]:
        return [s for s in self.spaces if s.role == "room"]

    def bounds(self) -> tuple[float, float, float, float]:
        pts = np.array([p for s in self.spaces for p in s.polygon])
        return (float(pts[:, 0].min()), float(pts[:, 1].min()), float(pts[:, 0].max()),
                float(pts[:, 1].max()))


# ---- a row of rooms along a corridor ---------------------------------------------------------
# Sides of a corridor's clear rectangle: the wall face's axis and which way the rooms lie.
SIDES = {"N": ("y", +1), "S": ("y", -1), "E": ("x", +1), "W": ("x", -1)}


def _to_xy(side: str, u: float, v: float) -> tuple[float, float]:
    """(along the wall, across it) -> (x, y): u runs along the face, v away from it."""
    axis, _ = SIDES[side]
    return (u, v) if axis == "y" else (v, u)


def _widths(rng: np.random.Generator, length: float, wall: float, lo: float,
            hi: float) -> list[float]:
    """Room widths (m, on the grid) that fill ``length`` with walls between them."""
    widths: list[float] = []
    left = length
    while left > 0:
        if left <= hi:
            w = left
        else:
            w = snap(rng.uniform(lo, min(hi, left - wall - lo)))
        if w < lo:  # the last sliver joins the room before it
            if widths:
                widths[-1] = snap(widths[-1] + wall + w)
            else:
                widths.append(snap(w))
            break
        widths.append(snap(w))
        left = snap(left - w - wall)
    return widths


def room_row(plan: FloorPlan, rng: np.random.Generator, namer: RoomNamer, corridor: str,
             leg: tuple[float, float, float, float], side: str, u0: float, u1: float,
             depth: float, *, closed_p: float = 0.08,
             unsigned_p: float = 0.15, width: tuple[float, float] = (2.5, 8.0),
             kinds: list[str] | None = None) -> list[Space]:
    """Rooms along one side of a rectangular corridor (or hall), each with a door onto it.

    Parameters
    ----------
    plan : FloorPlan
        Gets the rooms, doors and plates (in place).
    rng : numpy.random.Generator
        All choices (widths, door places and widths, sign sides, names).
    namer : RoomNamer
        Names and classes for the rooms.
    corridor : str
        The name of the corridor or hall the doors open onto.
    leg : (x0, y0, x1, y1)
        The part of it (a rectangle, m) whose face the rooms stand on.
    side : {"N", "S", "E", "W"}
        Which face of the corridor the rooms stand on.
    u0, u1 : float
        The row's extent along that face (m, on the grid).
    depth : float
        The rooms' depth away from the corridor (m, on the grid).
    closed_p, unsigned_p : float
        Chance that a room's door is shut, that a room has no sign.
    width : (float, float)
        Room widths along the corridor (m).
    kinds : list of str, optional
        Ask the namer for these classes first, in order.

    Returns
    -------
    list of Space
        The rooms, in order along the face.
    """
    axis, out = SIDES[side]
    t = plan.wall
    cx0, cy0, cx1, cy1 = leg
    face = {"N": cy1, "S": cy0, "E": cx1, "W": cx0}[side]
    lo_u, hi_u = (cx0, cx1) if axis == "y" else (cy0, cy1)
    lo_u, hi_u = max(lo_u, u0), min(hi_u, u1)  # plates hang on this row's wall only
    near, far = face + out * t, face + out * (t + depth)
    facing = {"N": -90.0, "S": 90.0, "E": 180.0, "W": 0.0}[side]
    rooms = []
    a = u0
    wanted = list(kinds or [])
    for w in _widths(rng, u1 - u0, t, *width):
        b = snap(a + w)
        name, kind = namer.next(rng, wanted.pop(0) if wanted else None)
        (x0, y0), (x1, y1) = _to_xy(side, a, near), _to_xy(side, b, far)
        room = Space.box(name, kind, x0, y0, x1, y1)
        dw = snap(rng.uniform(0.8, min(1.4, w - 2 * DOOR_MARGIN)))
        d0 = snap(rng.uniform(a + DOOR_MARGIN, b - DOOR_MARGIN - dw))
        closed = bool(rng.random() < closed_p)
        (dx0, dy0), (dx1, dy1) = _to_xy(side, d0, face), _to_xy(side, d0 + dw, near)
        plan.doors.append(Door((min(dx0, dx1), min(dy0, dy1), max(dx0, dx1), max(dy0, dy1)),
                               (name, corridor), closed))
        if rng.random() >= unsigned_p:
            look = plate_look(rng, name)
            half = look["width"] / 2
            gap = rng.uniform(*SIGN_GAP)
            sides = [-1, 1] if rng.random() < 0.5 else [1, -1]
            for s in sides:  # before the door, else after it
                u = d0 - gap - half if s < 0 else d0 + dw + gap + half
                # on this room's own stretch of wall, clear of the corridor's ends and doors
                end = max(half + 0.1, 0.4)  # a plate's centre stays 0.4 m from a corner
                if (max(lo_u + end, a + half + 0.1) <= u <= min(hi_u - end, b - half - 0.1)
                        and _clear_of_doors(plan, side, face, u, half)):
                    px, py = _to_xy(side, round(u, 4), face)
                    plan.plates.append(Plate(name, px, py, facing, look))
                    room.signed = True
                    break
        if not room.signed:  # no sign on the floor says its name
            room.name = namer.unsigned_name()
            plan.doors[-1].between = (room.name, corridor)
        rooms.append(room)
        plan.spaces.append(room)
        a = snap(b + t)
    return rooms


def _clear_of_doors(plan: FloorPlan, side: str, face: float, u: float, half: float) -> bool:
    """Is a plate centred at ``u`` on this face clear of every door opening in it?"""
    axis, _ = SIDES[side]
    for d in plan.doors:
        x0, y0, x1, y1 = d.rect
        lo, hi, c0, c1 = (x0, x1, y0, y1) if axis == "y" else (y0, y1, x0, x1)
        if c0 - 1e-6 <= face <= c1 + 1e-6 and u + half > lo - 0.1 and u - half < hi + 0.1:
            return False
    return True


def corridor_start(plan: FloorPlan, rng: np.random.Generator,
                   leg: tuple[float, float, float, float],
                   clearance: float = 0.7) -> tuple[float, float, float]:
    """A start pose in a rectangular space: ``clearance`` from one of its long walls, that
    wall on the robot's right, heading along it, away from the ends.

    Parameters
    ----------
    plan : FloorPlan
        Its doors are avoided (the wall on the right is solid beside the start).
    rng : numpy.random.Generator
    leg : (x0, y0, x1, y1)
        A rectangle of clear space (m): a corridor's leg, a hall, a room.
    clearance : float
        Distance from the wall (m); at most half the space's width.
    """
    x0, y0, x1, y1 = leg
    for _ in range(50):
        horizontal = (x1 - x0) >= (y1 - y0) if rng.random() < 0.8 else (x1 - x0) < (y1 - y0)
        across = (y1 - y0) if horizontal else (x1 - x0)
        c = min(clearance, across / 2)
        along_lo, along_hi = ((x0, x1) if horizontal else (y0, y1))
        if along_hi - along_lo < 3.0:
            continue
        u = rng.uniform(along_lo + 1.2, along_hi - 1.2)
        low_wall = rng.random() < 0.5
        if horizontal:  # wall below (heading +x) or above (heading -x)
            pose = (u, y0 + c, 0.0) if low_wall else (u, y1 - c, math.pi)
            wall_pt = (u, y0 - plan.wall / 2) if low_wall else (u, y1 + plan.wall / 2)
        else:  # wall on the east (heading +y) or west (heading -y)
            pose = (x1 - c, u, math.pi / 2) if low_wall else (x0 + c, u, -math.pi / 2)
            wall_pt = (x1 + plan.wall / 2, u) if low_wall else (x0 - plan.wall / 2, u)
        if not any(_near_door(d, wall_pt, 1.2) for d in plan.doors):
            return (snap(pose[0]), snap(pose[1]), pose[2])
    raise ValueError(f"no start pose in {leg}")


def _near_door(door: Door, point: tuple[float, float], margin: float) -> bool:
    x0, y0, x1, y1 = door.rect
    return x0 - margin <= point[0] <= x1 + margin and y0 - margin <= point[1] <= y1 + margin
