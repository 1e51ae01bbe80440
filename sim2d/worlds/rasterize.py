"""A floor plan as a world: turned, placed and drawn into a map_server image.

The plan's spaces and open doors are painted free; every pixel within one wall
thickness of them becomes wall (a disc-shaped dilation, so walls at any angle
are equally thick); furniture is painted in. Everything is turned by the
plan's ``rotation`` about the building's centre and shifted so the image's
lower-left corner is the world origin with a margin all round.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from .floorplan import FloorPlan

__all__ = ["Drawn", "Placement", "draw_plan", "polygon_pixels"]

RESOLUTION = 0.05  # m per pixel
FREE, WALL = 254, 0
MARGIN = 1.0  # m of free space around the building in the image


@dataclass(frozen=True)
class Placement:
    """Building frame -> world frame: turn by ``rotation`` about ``centre``, then shift."""

    rotation: float
    centre: tuple[float, float]
    shift: tuple[float, float]

    def point(self, x: float, y: float) -> tuple[float, float]:
        c, s = math.cos(self.rotation), math.sin(self.rotation)
        dx, dy = x - self.centre[0], y - self.centre[1]
        return (round(c * dx - s * dy + self.shift[0], 4), round(s * dx + c * dy + self.shift[1], 4))

    def points(self, pts: list[tuple[float, float]]) -> list[tuple[float, float]]:
        return [self.point(x, y) for x, y in pts]


@dataclass
class Drawn:
    """A plan drawn: the image (row 0 at the top), and the placement used."""

    image: np.ndarray
    placement: Placement
    size: tuple[float, float]  # world extent of the image (m)


def placement_of(plan: FloorPlan) -> tuple[Placement, tuple[int, int]]:
    """Where the plan goes in the world, and the image size (W, H) in pixels."""
    x0, y0, x1, y1 = plan.bounds()
    pad = plan.wall + 0.1
    corners = [(x0 - pad, y0 - pad), (x1 + pad, y0 - pad), (x1 + pad, y1 + pad),
               (x0 - pad, y1 + pad)]
    centre = (round((x0 + x1) / 2 / RESOLUTION) * RESOLUTION,
              round((y0 + y1) / 2 / RESOLUTION) * RESOLUTION)
    turned = Placement(plan.rotation, centre, (0.0, 0.0)).points(corners)
    tx, ty = zip(*turned)
    # a shift on the pixel grid keeps an unturned plan's coordinates on pixel edges
    sx = math.ceil((MARGIN - min(tx)) / RESOLUTION) * RESOLUTION
    sy = math.ceil((MARGIN - min(ty)) / RESOLUTION) * RESOLUTION
    width = math.ceil((max(tx) + sx + MARGIN) / RESOLUTION)
    height = math.ceil((max(ty) + sy + MARGIN) / RESOLUTION)
    return Placement(plan.rotation, centre, (round(sx, 4), round(sy, 4))), (width, height)


def polygon_pixels(mask: np.ndarray, polygon: list[tuple[float, float]],
                   value: bool = True) -> None:
    """Set the pixels whose centres lie inside a polygon (even-odd rule), in place.

    Parameters
    ----------
    mask : (H, W) bool array
        Row 0 at the top; pixel (r, c) has its centre at
        ((c + 0.5) * RESOLUTION, (H - r - 0.5) * RESOLUTION).
    polygon : list of (x, y)
        Corners in metres, world frame, in order.
    value : bool
        What to set.

    Examples
    --------
    >>> m = np.zeros((4, 4), bool)
    >>> polygon_pixels(m, [(0.0, 0.0), (0.1, 0.0), (0.1, 0.1), (0.0, 0.1)])
    >>> int(m.sum())
    4
    """
    h, w = mask.shape
    pts = np.asarray(polygon, dtype=np.float64)
    c0 = max(0, int(math.floor(pts[:, 0].min() / RESOLUTION)) - 1)
    c1 = min(w, int(math.ceil(pts[:, 0].max() / RESOLUTION)) + 1)
    r0 = max(0, h - int(math.ceil(pts[:, 1].max() / RESOLUTION)) - 1)
    r1 = min(h, h - int(math.floor(pts[:, 1].min() / RESOLUTION)) + 1)
    if c1 <= c0 or r1 <= r0:
        return
    px = (np.arange(c0, c1) + 0.5) * RESOLUTION
    py = (h - np.arange(r0, r1) - 0.5) * RESOLUTION
    px, py = np.meshgrid(px, py)
    inside = np.zeros(px.shape, dtype=bool)
    for (xa, ya), (xb, yb) in zip(pts, np.roll(pts, -1, axis=0)):
        if ya == yb:
            continue
        crosses = (ya > py) != (yb > py)
        x_cross = xa + (py - ya) * (xb - xa) / (yb - ya)
        inside ^= crosses & (px < x_cross)
    region = mask[r0:r1, c0:c1]
    region[inside] = value


def _rect(x0: float, y0: float, x1: float, y1: float) -> list[tuple[float, float]]:
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def draw_plan(plan: FloorPlan) -> Drawn:
    """Draw a plan's walls, openings and furniture into a map_server image.

    Returns
    -------
    Drawn
        ``image`` is uint8, FREE (254) or WALL (0), row 0 at the top; its lower-left
        corner is the world origin (0, 0).
    """
    placement, (width, height) = placement_of(plan)
    free = np.zeros((height, width), dtype=bool)
    for space in plan.spaces:
        polygon_pixels(free, placement.points(space.polygon))
    for door in plan.doors:
        if not door.closed:
            x0, y0, x1, y1 = door.rect
            grow_x, grow_y = (0.05, 0.0) if (x1 - x0) < (y1 - y0) else (0.0, 0.05)
            polygon_pixels(free, placement.points(_rect(x0 - grow_x, y0 - grow_y, x1 + grow_x,
                                                        y1 + grow_y)))
    radius = max(1, round(plan.wall / RESOLUTION))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    grown = cv2.dilate(free.astype(np.uint8), disc) > 0
    solid = grown & ~free
    for box in plan.boxes:
        polygon_pixels(solid, placement.points(_rect(box.x0, box.y0, box.x1, box.y1)))
    image = np.where(solid, WALL, FREE).astype(np.uint8)
    return Drawn(image=image, placement=placement,
                 size=(width * RESOLUTION, height * RESOLUTION))


def world_document(plan: FloorPlan, drawn: Drawn, name: str, image_file: str,
                   extra: dict[str, Any]) -> dict[str, Any]:
    """The world file's contents (map_server keys first, then the ground truth)."""
    pl = drawn.placement
    turn = math.degrees(plan.rotation)

    def xy(x: float, y: float) -> list[float]:
        return list(pl.point(x, y))

    sx, sy, st = plan.start
    start = [*xy(sx, sy), round(math.remainder(st + plan.rotation, 2 * math.pi), 4)]
    doc: dict[str, Any] = {
        "name": name, "doc": plan.doc, "image": image_file, "resolution": RESOLUTION,
        "origin": [0.0, 0.0, 0.0], "negate": 0, "occupied_thresh": 0.65,
        "free_thresh": 0.196, "mode": "trinary", "start": start,
    }
    doc.update(extra)
    doc["signs"] = [{"text": p.text, "x": xy(p.x, p.y)[0], "y": xy(p.x, p.y)[1],
                     "facing": round(math.remainder(p.facing + turn, 360.0), 3), **p.look}
                    for p in plan.plates]
    doc["places"] = [{"name": s.name, "kind": s.kind,
                      "polygon": [list(pl.point(x, y)) for x, y in s.polygon]}
                     for s in plan.spaces]
    doc["doors"] = [{"x": xy(*d.centre)[0], "y": xy(*d.centre)[1], "width": round(d.width, 4),
                     "between": list(d.between), **({"closed": True} if d.closed else {})}
                    for d in plan.doors]
    if plan.things:
        doc["objects"] = [{"label": t.label, "x": xy(t.x, t.y)[0], "y": xy(t.x, t.y)[1],
                           **t.look} for t in plan.things]
    return doc
