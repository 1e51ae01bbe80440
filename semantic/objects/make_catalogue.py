"""Draw the object catalogue's pictures (front faces) in code, deterministically.

Run ``python -m semantic.objects.make_catalogue`` to (re)write the PNGs next to
``catalogue.yaml``; ``--check`` only compares them with what would be drawn.
tests/test_objects.py checks that the committed PNGs match.

Why drawn, not photographed: the project ships no photographs and downloads
nothing, and the recogniser needs pictures that are (1) feature-rich, so ORB /
SIFT find many keypoints even when an object is 50 px tall, and (2)
*different* from each other, so features of one object do not match another.
Each picture therefore combines the object's own shapes (doors, grilles,
shelves, buttons) with printed text (brand and model), a seeded random logo
and a seeded random asset-tag grid; the random parts are drawn from a
generator seeded by the label's CRC-32, so every run draws the same pixels.

The picture's size follows the catalogue's physical size at 400 px along the
longer side (so the aspect ratio is the object's).
"""
from __future__ import annotations

import argparse
import sys
import zlib
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from . import DEFAULT_PATH, CatalogueEntry, load_catalogue

LONG_SIDE = 400  # px along the longer side of every picture
FONT = cv2.FONT_HERSHEY_DUPLEX
BOLD = cv2.FONT_HERSHEY_TRIPLEX
Colour = tuple[int, int, int]


# ---- drawing toolkit (coordinates as fractions of the picture) ---------------------------------
class Canvas:
    """A picture under construction, addressed in fractions of its width and height."""

    def __init__(self, width: int, height: int, background: Colour, rng: np.random.Generator):
        self.img = np.empty((height, width, 3), np.uint8)
        self.img[:] = background
        self.w, self.h = width, height
        self.rng = rng

    def px(self, fx: float, fy: float) -> tuple[int, int]:
        return round(fx * (self.w - 1)), round(fy * (self.h - 1))

    def rect(self, fx0: float, fy0: float, fx1: float, fy1: float, colour: Colour,
             border: Colour | None = None, thickness: int = 2) -> None:
        cv2.rectangle(self.img, self.px(fx0, fy0), self.px(fx1, fy1), colour, -1)
        if border is not None:
            cv2.rectangle(self.img, self.px(fx0, fy0), self.px(fx1, fy1), border, thickness,
                          cv2.LINE_AA)

    def circle(self, fx: float, fy: float, fr: float, colour: Colour, thickness: int = -1) -> None:
        cv2.circle(self.img, self.px(fx, fy), max(1, round(fr * min(self.w, self.h))), colour,
                   thickness, cv2.LINE_AA)

    def line(self, fx0: float, fy0: float, fx1: float, fy1: float, colour: Colour,
             thickness: int = 2) -> None:
        cv2.line(self.img, self.px(fx0, fy0), self.px(fx1, fy1), colour, thickness, cv2.LINE_AA)

    def text(self, s: str, fx0: float, fy0: float, fx1: float, fy1: float, colour: Colour,
             font: int = FONT) -> None:
        """``s`` fitted into the box (centred), as large as it fits."""
        x0, y0 = self.px(fx0, fy0)
        x1, y1 = self.px(fx1, fy1)
        bw, bh = max(1, x1 - x0), max(1, y1 - y0)
        (tw, th), _ = cv2.getTextSize(s, font, 1.0, 1)
        scale = min(bw / max(tw, 1), bh / max(th, 1)) * 0.9
        thick = max(1, round(scale * 1.5))
        (tw, th), _ = cv2.getTextSize(s, font, scale, thick)
        org = (x0 + (bw - tw) // 2, y0 + (bh + th) // 2)
        cv2.putText(self.img, s, org, font, scale, colour, thick, cv2.LINE_AA)

    def grille(self, fx0: float, fy0: float, fx1: float, fy1: float, n: int, colour: Colour,
               vertical: bool = False, thickness: int = 2) -> None:
        for k in range(n):
            t = (k + 0.5) / n
            if vertical:
                x = fx0 + t * (fx1 - fx0)
                self.line(x, fy0, x, fy1, colour, thickness)
            else:
                y = fy0 + t * (fy1 - fy0)
                self.line(fx0, y, fx1, y, colour, thickness)

    def tag(self, fx0: float, fy0: float, fx1: float, fy1: float, cells: int = 7) -> None:
        """A seeded random black-and-white asset tag (QR-like): many distinctive corners."""
        x0, y0 = self.px(fx0, fy0)
        x1, y1 = self.px(fx1, fy1)
        cv2.rectangle(self.img, (x0, y0), (x1, y1), (255, 255, 255), -1)
        bits = self.rng.random((cells, cells)) < 0.5
        bits[0, :] = bits[-1, :] = bits[:, 0] = bits[:, -1] = True  # a solid frame
        cw, ch = (x1 - x0) / (cells + 2), (y1 - y0) / (cells + 2)
        for i in range(cells):
            for j in range(cells):
                if bits[i, j]:
                    a = (round(x0 + (j + 1) * cw), round(y0 + (i + 1) * ch))
                    b = (round(x0 + (j + 2) * cw) - 1, round(y0 + (i + 2) * ch) - 1)
                    cv2.rectangle(self.img, a, b, (0, 0, 0), -1)

    def logo(self, fx: float, fy: float, fr: float) -> None:
        """A seeded random star polygon in a random saturated colour."""
        n = int(self.rng.integers(5, 9))
        r = fr * min(self.w, self.h)
        angles = np.linspace(0, 2 * np.pi, 2 * n, endpoint=False) + self.rng.uniform(0, np.pi)
        radii = np.where(np.arange(2 * n) % 2 == 0, r, r * self.rng.uniform(0.35, 0.6))
        cx, cy = self.px(fx, fy)
        pts = np.stack([cx + radii * np.cos(angles), cy + radii * np.sin(angles)], axis=1)
        colour = tuple(int(c) for c in self.rng.integers(0, 256, 3))
        colour = (colour[0], colour[1] // 2, 255 - colour[2] // 3)
        cv2.fillPoly(self.img, [np.round(pts).astype(np.int32)], colour, cv2.LINE_AA)
        cv2.polylines(self.img, [np.round(pts).astype(np.int32)], True, (20, 20, 20), 2,
                      cv2.LINE_AA)

    def buttons(self, fx0: float, fy0: float, fx1: float, fy1: float, n: int,
                fr: float = 0.03) -> None:
        """A row of round buttons in seeded random colours."""
        for k in range(n):
            colour = tuple(int(c) for c in self.rng.integers(30, 250, 3))
            x = fx0 + (k + 0.5) / n * (fx1 - fx0)
            self.circle(x, (fy0 + fy1) / 2, fr, colour)
            self.circle(x, (fy0 + fy1) / 2, fr, (20, 20, 20), 1)

    def display(self, fx0: float, fy0: float, fx1: float, fy1: float,
                colour: Colour = (90, 230, 120)) -> None:
        """A dark LCD with seeded random digits."""
        self.rect(fx0, fy0, fx1, fy1, (40, 35, 30), (10, 10, 10))
        digits = "".join(str(int(d)) for d in self.rng.integers(0, 10, 4))
        self.text(f"{digits[:2]}:{digits[2:]}", fx0 + 0.02, fy0, fx1 - 0.02, fy1, colour)

    def speckle(self, fx0: float, fy0: float, fx1: float, fy1: float, n: int,
                size: float = 0.02) -> None:
        """Seeded random small rectangles: a texture of corners."""
        for _ in range(n):
            x = self.rng.uniform(fx0, fx1 - size)
            y = self.rng.uniform(fy0, fy1 - size)
            colour = tuple(int(c) for c in self.rng.integers(0, 256, 3))
            sx = size * self.rng.uniform(0.5, 1.5)
            self.rect(x, y, min(fx1, x + sx), min(fy1, y + size * self.rng.uniform(0.5, 1.5)),
                      colour)

    def scribble(self, fx0: float, fy0: float, fx1: float, fy1: float, strokes: int,
                 colour: Colour) -> None:
        """Seeded random pen strokes (a whiteboard's writing)."""
        for _ in range(strokes):
            k = int(self.rng.integers(3, 7))
            xs = self.rng.uniform(fx0, fx1, k)
            ys = np.clip(self.rng.uniform(fy0, fy1) + self.rng.normal(0, 0.02, k), fy0, fy1)
            pts = np.array([self.px(x, y) for x, y in zip(np.sort(xs), ys)], np.int32)
            cv2.polylines(self.img, [pts], False, colour, 2, cv2.LINE_AA)


# ---- the objects ---------------------------------------------------------------------------------
def _shredder(c: Canvas) -> None:
    c.rect(0.02, 0.02, 0.98, 0.30, (60, 60, 60), (20, 20, 20))  # head
    c.rect(0.15, 0.08, 0.85, 0.12, (10, 10, 10))  # paper slot
    c.text("SHREDMASTER", 0.08, 0.14, 0.70, 0.24, (235, 235, 235), BOLD)
    c.buttons(0.72, 0.14, 0.95, 0.26, 2, fr=0.045)
    c.rect(0.04, 0.32, 0.96, 0.97, (120, 100, 80), (30, 30, 30))  # bin
    c.grille(0.12, 0.40, 0.88, 0.62, 7, (60, 50, 40), vertical=True, thickness=4)
    c.logo(0.30, 0.78, 0.14)
    c.tag(0.56, 0.68, 0.90, 0.88)
    c.text("P-4 3000", 0.10, 0.88, 0.60, 0.95, (250, 250, 250))


def _printer(c: Canvas) -> None:
    c.rect(0.02, 0.02, 0.98, 0.25, (225, 225, 220), (40, 40, 40))  # scanner lid
    c.display(0.60, 0.05, 0.94, 0.15)
    c.buttons(0.60, 0.17, 0.94, 0.23, 4, fr=0.03)
    c.text("LASERPRO", 0.06, 0.06, 0.55, 0.14, (120, 40, 20), BOLD)
    c.rect(0.05, 0.27, 0.95, 0.36, (50, 50, 50))  # output tray
    c.rect(0.10, 0.29, 0.90, 0.33, (250, 250, 250))  # paper
    for k in range(3):  # paper drawers
        y = 0.40 + 0.17 * k
        c.rect(0.05, y, 0.95, y + 0.15, (200, 200, 195), (60, 60, 60))
        c.rect(0.35, y + 0.05, 0.65, y + 0.08, (80, 80, 80))
        c.text(f"A{4 - k}", 0.80, y + 0.02, 0.93, y + 0.12, (40, 40, 40))
    c.logo(0.20, 0.47, 0.12)
    c.tag(0.08, 0.75, 0.30, 0.88)
    c.rect(0.02, 0.92, 0.98, 0.98, (40, 40, 40))


def _photocopier(c: Canvas) -> None:
    c.rect(0.02, 0.02, 0.98, 0.20, (230, 232, 236), (40, 40, 40))
    c.rect(0.10, 0.04, 0.50, 0.09, (60, 60, 60))  # document feeder
    c.display(0.55, 0.04, 0.95, 0.17, (250, 200, 90))
    c.text("COPYSTAR", 0.05, 0.10, 0.50, 0.18, (150, 60, 10), BOLD)
    c.rect(0.02, 0.22, 0.98, 0.97, (210, 214, 220), (50, 50, 50))
    c.grille(0.05, 0.25, 0.40, 0.45, 6, (90, 90, 90))
    c.logo(0.70, 0.35, 0.12)
    for k in range(4):
        y = 0.48 + 0.11 * k
        c.rect(0.05, y, 0.95, y + 0.09, (190, 194, 200), (70, 70, 70))
        c.rect(0.40, y + 0.03, 0.60, y + 0.05, (60, 60, 60))
        c.speckle(0.07, y + 0.01, 0.25, y + 0.08, 3, size=0.025)
    c.tag(0.72, 0.26, 0.92, 0.30 + 0.2 * c.w / c.h)
    c.buttons(0.45, 0.25, 0.65, 0.29, 3, fr=0.025)


def _fridge(c: Canvas) -> None:
    c.rect(0.02, 0.01, 0.98, 0.99, (235, 236, 238), (60, 60, 60))
    c.line(0.02, 0.36, 0.98, 0.36, (60, 60, 60), 3)  # freezer door
    c.rect(0.86, 0.08, 0.91, 0.30, (150, 150, 150), (60, 60, 60))  # handles
    c.rect(0.86, 0.42, 0.91, 0.70, (150, 150, 150), (60, 60, 60))
    c.text("FROSTLINE", 0.10, 0.04, 0.80, 0.10, (140, 90, 30), BOLD)
    c.display(0.15, 0.14, 0.55, 0.21, (255, 200, 120))
    c.logo(0.35, 0.29, 0.12)
    c.speckle(0.08, 0.40, 0.80, 0.62, 14, size=0.05)  # magnets and notes
    c.tag(0.12, 0.66, 0.42, 0.66 + 0.30 * c.w / c.h)
    c.text("A+++", 0.50, 0.68, 0.80, 0.74, (30, 140, 30))
    c.grille(0.10, 0.92, 0.90, 0.97, 3, (90, 90, 90))


def _microwave(c: Canvas) -> None:
    c.rect(0.01, 0.02, 0.99, 0.98, (60, 62, 66), (20, 20, 20))
    c.rect(0.04, 0.08, 0.68, 0.92, (25, 25, 25), (150, 150, 150))  # window
    c.grille(0.07, 0.12, 0.65, 0.88, 9, (55, 55, 55), vertical=True, thickness=1)
    c.grille(0.07, 0.12, 0.65, 0.88, 6, (55, 55, 55), thickness=1)
    c.logo(0.36, 0.50, 0.22)
    c.display(0.72, 0.08, 0.96, 0.26, (80, 160, 255))
    c.buttons(0.72, 0.30, 0.96, 0.40, 3, fr=0.05)
    c.buttons(0.72, 0.44, 0.96, 0.54, 3, fr=0.05)
    c.tag(0.74, 0.58, 0.94, 0.90)
    c.text("WAVO", 0.20, 0.80, 0.52, 0.91, (240, 240, 240), BOLD)


def _coffee_machine(c: Canvas) -> None:
    c.rect(0.02, 0.01, 0.98, 0.99, (30, 30, 140), (10, 10, 10))  # red body (BGR)
    c.rect(0.08, 0.05, 0.92, 0.30, (20, 20, 20))
    c.display(0.14, 0.08, 0.60, 0.20, (120, 220, 255))
    c.buttons(0.64, 0.09, 0.88, 0.19, 2, fr=0.05)
    c.text("BARISTA", 0.10, 0.21, 0.90, 0.29, (230, 230, 230), BOLD)
    c.rect(0.20, 0.34, 0.80, 0.72, (45, 45, 45))  # brewing bay
    c.rect(0.42, 0.34, 0.58, 0.42, (160, 160, 160))  # spout
    c.rect(0.36, 0.55, 0.64, 0.72, (240, 240, 240), (40, 40, 40))  # cup
    c.logo(0.50, 0.62, 0.07)
    c.grille(0.15, 0.76, 0.85, 0.84, 4, (160, 160, 160))  # drip tray
    c.tag(0.08, 0.86, 0.30, 0.97)
    c.text("ESPRESSO", 0.33, 0.86, 0.95, 0.96, (230, 230, 230))


def _workbench(c: Canvas) -> None:
    c.rect(0.00, 0.00, 1.00, 0.55, (90, 110, 120))  # pegboard
    for i in range(14):
        for j in range(7):
            c.circle(0.03 + i * 0.07, 0.04 + j * 0.07, 0.006, (40, 50, 60))
    c.speckle(0.05, 0.06, 0.60, 0.48, 16, size=0.04)  # tools on the board
    c.line(0.65, 0.08, 0.65, 0.40, (30, 30, 30), 6)  # hammer
    c.rect(0.61, 0.06, 0.69, 0.12, (60, 60, 60))
    c.line(0.75, 0.08, 0.80, 0.42, (40, 40, 160), 5)  # screwdriver
    c.logo(0.88, 0.25, 0.10)
    c.rect(0.00, 0.55, 1.00, 0.63, (40, 90, 140), (20, 40, 60))  # top
    c.text("WORKSHOP", 0.30, 0.55, 0.70, 0.63, (230, 230, 230), BOLD)
    c.rect(0.03, 0.63, 0.35, 0.98, (60, 70, 90), (20, 20, 20))  # drawers
    for k in range(3):
        c.line(0.03, 0.63 + 0.117 * (k + 1), 0.35, 0.63 + 0.117 * (k + 1), (20, 20, 20), 2)
        c.rect(0.15, 0.68 + 0.117 * k, 0.23, 0.70 + 0.117 * k, (190, 190, 190))
    c.tag(0.40, 0.68, 0.50, 0.84)
    c.rect(0.95, 0.63, 0.98, 0.98, (50, 50, 50))  # leg
    c.text("BENCH 2", 0.55, 0.70, 0.90, 0.80, (40, 40, 40))


def _toolbox(c: Canvas) -> None:
    c.rect(0.02, 0.02, 0.98, 0.22, (30, 30, 30))  # handle bar
    c.rect(0.04, 0.20, 0.96, 0.98, (20, 60, 200), (10, 20, 60))  # red-orange box
    for k in range(3):
        y = 0.26 + 0.24 * k
        c.rect(0.08, y, 0.92, y + 0.20, (30, 80, 220), (10, 30, 90))
        c.rect(0.40, y + 0.07, 0.60, y + 0.12, (200, 200, 200))
    c.text("TOOLKING", 0.10, 0.26, 0.38, 0.46, (240, 240, 240), BOLD)
    c.logo(0.78, 0.36, 0.14)
    c.tag(0.12, 0.52, 0.30, 0.96)
    c.speckle(0.65, 0.52, 0.90, 0.70, 5, size=0.05)
    c.text("HEAVY DUTY", 0.40, 0.78, 0.90, 0.92, (240, 240, 240))


def _microscope(c: Canvas) -> None:
    c.rect(0.00, 0.00, 1.00, 1.00, (200, 190, 170))  # the bench behind it
    c.rect(0.20, 0.85, 0.80, 0.98, (50, 50, 50))  # base
    c.rect(0.55, 0.20, 0.70, 0.86, (70, 70, 70))  # arm
    c.rect(0.30, 0.05, 0.45, 0.40, (40, 40, 40))  # tube
    c.rect(0.32, 0.00, 0.43, 0.06, (20, 20, 20))  # eyepiece
    c.rect(0.18, 0.55, 0.62, 0.60, (30, 30, 30))  # stage
    c.rect(0.25, 0.50, 0.50, 0.55, (230, 230, 230))  # slide
    c.circle(0.75, 0.62, 0.07, (90, 90, 90))  # focus knobs
    c.circle(0.75, 0.62, 0.03, (200, 200, 200))
    c.text("OPTIX", 0.22, 0.87, 0.78, 0.96, (240, 240, 240), BOLD)
    c.logo(0.85, 0.15, 0.10)
    c.tag(0.02, 0.62, 0.18, 0.84)
    c.speckle(0.05, 0.05, 0.25, 0.45, 6, size=0.05)


def _projector(c: Canvas) -> None:
    c.rect(0.05, 0.05, 0.95, 0.35, (220, 220, 225), (40, 40, 40))  # projector
    c.circle(0.30, 0.20, 0.13, (30, 30, 30))  # lens
    c.circle(0.30, 0.20, 0.08, (120, 60, 40))
    c.circle(0.30, 0.20, 0.03, (250, 250, 250))
    c.grille(0.55, 0.09, 0.90, 0.22, 5, (90, 90, 90))
    c.text("BEAMER", 0.55, 0.24, 0.92, 0.33, (120, 30, 30), BOLD)
    c.rect(0.10, 0.38, 0.90, 0.44, (60, 60, 60))  # trolley top
    c.rect(0.15, 0.44, 0.85, 0.92, (140, 140, 150), (40, 40, 40))  # cabinet
    c.logo(0.35, 0.60, 0.16)
    c.tag(0.58, 0.50, 0.82, 0.64)
    c.speckle(0.20, 0.72, 0.80, 0.88, 8, size=0.05)
    c.circle(0.20, 0.95, 0.04, (20, 20, 20))  # wheels
    c.circle(0.80, 0.95, 0.04, (20, 20, 20))


def _whiteboard(c: Canvas) -> None:
    c.rect(0.02, 0.02, 0.98, 0.70, (250, 250, 250), (150, 150, 150), thickness=6)
    c.scribble(0.06, 0.08, 0.60, 0.40, 10, (160, 60, 20))
    c.text("Q3 PLAN", 0.06, 0.08, 0.40, 0.18, (30, 30, 180))
    c.rect(0.65, 0.08, 0.92, 0.30, (250, 250, 250), (30, 120, 30), thickness=3)  # diagram
    c.line(0.65, 0.30, 0.92, 0.08, (30, 120, 30), 3)
    c.circle(0.78, 0.48, 0.08, (180, 40, 40), 3)
    c.scribble(0.06, 0.44, 0.60, 0.64, 6, (40, 40, 40))
    c.speckle(0.60, 0.56, 0.95, 0.66, 4, size=0.04)  # magnets
    c.tag(0.85, 0.54, 0.95, 0.62)
    c.rect(0.02, 0.70, 0.98, 0.73, (120, 120, 120))  # pen tray
    c.text("WRITEWELL", 0.30, 0.74, 0.70, 0.79, (60, 60, 60), BOLD)
    c.rect(0.48, 0.73, 0.52, 0.96, (110, 110, 110))  # stand
    c.line(0.20, 0.97, 0.80, 0.97, (60, 60, 60), 6)
    c.logo(0.15, 0.85, 0.08)


def _bookshelf(c: Canvas) -> None:
    c.rect(0.00, 0.00, 1.00, 1.00, (40, 80, 120))  # wood
    for k in range(5):  # shelves of book spines
        y0, y1 = 0.03 + 0.19 * k, 0.03 + 0.19 * k + 0.16
        c.rect(0.04, y0, 0.96, y1, (30, 50, 70))
        x = 0.05
        while x < 0.93:
            bw = float(c.rng.uniform(0.03, 0.08))
            top = y0 + float(c.rng.uniform(0.0, 0.04))
            colour = tuple(int(v) for v in c.rng.integers(20, 240, 3))
            c.rect(x, top, min(0.95, x + bw), y1, colour, (15, 15, 15), 1)
            if c.rng.random() < 0.5:
                c.rect(x + bw * 0.2, top + 0.03, min(0.95, x + bw * 0.8), top + 0.05,
                       (230, 230, 230))
            x += bw + 0.004
    c.tag(0.80, 0.975 - 0.12 * c.w / c.h, 0.95, 0.985)
    c.text("LIBRARY", 0.05, 0.965, 0.60, 0.995, (220, 220, 220), BOLD)


def _server_rack(c: Canvas) -> None:
    c.rect(0.00, 0.00, 1.00, 1.00, (25, 25, 28))
    c.rect(0.04, 0.005, 0.96, 0.06, (200, 120, 30))  # a blue name plate
    c.text("RACK A3", 0.08, 0.008, 0.92, 0.057, (250, 250, 250), BOLD)
    y = 0.07
    while y < 0.86:  # rack units
        units = int(c.rng.integers(1, 4))
        h = 0.022 * units
        c.rect(0.06, y, 0.94, y + h - 0.004, (55, 55, 60), (90, 90, 95), 1)
        for k in range(int(c.rng.integers(2, 6))):  # status lights
            colour = ((60, 220, 60), (40, 160, 255), (255, 160, 60))[int(c.rng.integers(3))]
            c.circle(0.12 + 0.07 * k, y + h / 2, 0.02, colour)
        if units > 1:
            c.grille(0.50, y + 0.004, 0.90, y + h - 0.008, 3, (20, 20, 20), vertical=True,
                     thickness=1)
        y += h
        if 0.30 < y < 0.40:  # a switch panel with a big logo
            c.rect(0.06, y, 0.94, y + 0.10, (230, 230, 230), (90, 90, 95), 1)
            c.logo(0.30, y + 0.05, 0.32)
            c.display(0.55, y + 0.02, 0.92, y + 0.08, (80, 240, 80))
            y += 0.105
        if 0.60 < y < 0.70:  # a patch panel with an asset tag
            c.rect(0.06, y, 0.94, y + 0.12, (20, 90, 160), (90, 90, 95), 1)
            c.tag(0.12, y + 0.01, 0.88, y + 0.11, cells=5)
            y += 0.125
    c.rect(0.06, 0.87, 0.94, 0.985, (40, 40, 170), (90, 90, 95), 1)  # a red UPS
    c.text("UPS 3kVA", 0.10, 0.88, 0.90, 0.93, (250, 250, 250), BOLD)
    c.buttons(0.15, 0.94, 0.85, 0.98, 3, fr=0.10)


def _fire_extinguisher(c: Canvas) -> None:
    c.rect(0.00, 0.00, 1.00, 1.00, (30, 30, 200))  # red sign panel behind it
    c.rect(0.05, 0.02, 0.95, 0.16, (250, 250, 250))
    c.text("FIRE", 0.08, 0.03, 0.92, 0.15, (20, 20, 190), BOLD)
    c.rect(0.25, 0.24, 0.75, 0.95, (20, 20, 150), (10, 10, 40))  # cylinder
    c.rect(0.38, 0.18, 0.62, 0.25, (30, 30, 30))  # valve
    c.line(0.60, 0.20, 0.90, 0.30, (30, 30, 30), 5)  # hose
    c.line(0.90, 0.30, 0.88, 0.70, (30, 30, 30), 5)
    c.rect(0.30, 0.40, 0.70, 0.70, (240, 240, 240))  # label
    c.text("CO2", 0.32, 0.42, 0.68, 0.52, (20, 20, 20), BOLD)
    c.tag(0.34, 0.54, 0.66, 0.54 + 0.32 * c.w / c.h)
    c.logo(0.50, 0.82, 0.15)


def _laptop(c: Canvas) -> None:
    c.rect(0.05, 0.02, 0.95, 0.80, (50, 50, 55), (20, 20, 20))  # lid
    c.rect(0.09, 0.06, 0.91, 0.74, (120, 70, 30))  # screen: a desktop
    c.speckle(0.11, 0.10, 0.50, 0.62, 10, size=0.06)  # icons
    c.rect(0.52, 0.12, 0.88, 0.50, (245, 245, 245), (40, 40, 40))  # a window
    c.text("REPORT", 0.54, 0.14, 0.86, 0.24, (30, 30, 30))
    c.scribble(0.55, 0.28, 0.86, 0.46, 5, (80, 80, 80))
    c.tag(0.70, 0.54, 0.86, 0.72)
    c.rect(0.09, 0.66, 0.91, 0.74, (60, 60, 60))  # task bar
    c.logo(0.20, 0.70, 0.05)
    c.rect(0.00, 0.80, 1.00, 0.97, (170, 170, 175), (40, 40, 40))  # base
    c.text("NOTEBOOK", 0.30, 0.82, 0.70, 0.95, (40, 40, 40), BOLD)


def _parcel(c: Canvas) -> None:
    c.rect(0.00, 0.00, 1.00, 1.00, (90, 150, 200))  # cardboard
    c.rect(0.44, 0.00, 0.56, 1.00, (60, 110, 160))  # tape
    c.rect(0.06, 0.08, 0.40, 0.50, (250, 250, 250), (40, 40, 40))  # shipping label
    c.text("TO: LAB", 0.08, 0.10, 0.38, 0.20, (20, 20, 20))
    c.grille(0.08, 0.24, 0.38, 0.36, 3, (40, 40, 40), thickness=1)
    for k in range(14):  # a bar code
        x = 0.08 + 0.02 * k
        if c.rng.random() < 0.7:
            c.rect(x, 0.39, x + 0.012, 0.48, (10, 10, 10))
    c.tag(0.62, 0.08, 0.90, 0.45)
    c.text("FRAGILE", 0.05, 0.60, 0.40, 0.75, (20, 20, 180), BOLD)
    c.logo(0.75, 0.72, 0.18)
    c.text("THIS SIDE UP", 0.05, 0.80, 0.40, 0.92, (30, 30, 30))


def _medicine(c: Canvas) -> None:
    c.rect(0.02, 0.02, 0.98, 0.98, (235, 235, 230), (60, 60, 60))  # medicine trolley
    c.rect(0.05, 0.04, 0.95, 0.22, (40, 140, 40))  # green pharmacy band
    c.rect(0.12, 0.06, 0.20, 0.20, (250, 250, 250))  # a cross
    c.rect(0.07, 0.10, 0.25, 0.16, (250, 250, 250))
    c.text("MEDICINE", 0.28, 0.06, 0.93, 0.20, (250, 250, 250), BOLD)
    for k in range(4):  # drawers with coloured labels
        y = 0.26 + 0.15 * k
        c.rect(0.06, y, 0.94, y + 0.13, (215, 215, 210), (80, 80, 80))
        c.speckle(0.09, y + 0.02, 0.45, y + 0.11, 4, size=0.05)
        c.rect(0.60, y + 0.05, 0.85, y + 0.08, (90, 90, 90))
    c.tag(0.62, 0.86, 0.80, 0.86 + 0.18 * c.w / c.h)
    c.logo(0.25, 0.91, 0.10)


DRAWERS: dict[str, Callable[[Canvas], None]] = {
    "Shredder": _shredder, "Printer": _printer, "Photocopier": _photocopier,
    "Fridge": _fridge, "Microwave": _microwave, "CoffeeMachine": _coffee_machine,
    "Workbench": _workbench, "Toolbox": _toolbox, "Microscope": _microscope,
    "Projector": _projector, "Whiteboard": _whiteboard, "Bookshelf": _bookshelf,
    "ServerRack": _server_rack, "FireExtinguisher": _fire_extinguisher, "Laptop": _laptop,
    "Parcel": _parcel, "Medicine": _medicine,
}
BACKGROUND: Colour = (128, 128, 128)


def picture_size(entry: CatalogueEntry) -> tuple[int, int]:
    """``(width, height)`` px of an entry's picture: :data:`LONG_SIDE` along the longer side."""
    scale = LONG_SIDE / max(entry.width, entry.height)
    return max(16, round(entry.width * scale)), max(16, round(entry.height * scale))


def draw(entry: CatalogueEntry) -> np.ndarray:
    """The picture of one catalogue entry (BGR uint8); the same pixels on every call."""
    drawer = DRAWERS.get(entry.label)
    if drawer is None:
        raise KeyError(f"no drawing for {entry.label!r}; add one to DRAWERS in {__file__}")
    w, h = picture_size(entry)
    canvas = Canvas(w, h, BACKGROUND, np.random.default_rng(zlib.crc32(entry.label.encode())))
    drawer(canvas)
    return canvas.img


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--catalogue", type=Path, default=DEFAULT_PATH)
    parser.add_argument("--check", action="store_true",
                        help="compare with the PNGs on disk instead of writing them")
    args = parser.parse_args(argv)
    from blocks.core.atomic import atomic_write_bytes
    catalogue = load_catalogue(args.catalogue, check_images=False)
    stale = []
    for entry in catalogue.entries:
        img = draw(entry)
        if args.check:
            old = cv2.imread(str(entry.image), cv2.IMREAD_COLOR)
            if old is None or old.shape != img.shape or not np.array_equal(old, img):
                stale.append(entry.image.name)
            continue
        ok, png = cv2.imencode(".png", img)
        if not ok:
            raise RuntimeError(f"cannot encode {entry.image.name}")
        atomic_write_bytes(entry.image, png.tobytes())
        print(f"wrote {entry.image}")
    if stale:
        print("out of date: " + ", ".join(stale))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
