"""How generated buildings look to the camera: plates, walls and objects that vary.

The shipped worlds use one 0.6 x 0.2 m white plate with black letters and the
catalogue's own pictures, the very things the detector and recogniser were
tuned on. A generated floor draws each plate's size, colours, contrast,
font, letter spacing and mounting height, the building's wall and floor
colours, and each object's scale, lighting and partial cover, so perception
is measured on what it was not tuned on.
"""
from __future__ import annotations

import numpy as np

from sim2d.world import SIGN_FONTS

__all__ = ["building_colours", "object_look", "plate_look"]


def _rgb(rng: np.random.Generator, lo: int, hi: int, tint: float = 25) -> list[int]:
    base = rng.uniform(lo, hi)
    return [int(np.clip(base + rng.uniform(-tint, tint), 0, 255)) for _ in range(3)]


def plate_look(rng: np.random.Generator, text: str) -> dict:
    """A plate's size (m), mounting height (m), colours (RGB), font and letter spacing.

    Most plates are dark letters on a light plate; about one in three is light
    on dark. Longer texts get wider plates, as a sign maker would make them.
    """
    width = float(np.clip(rng.uniform(0.3, 0.8), 0.1 + 0.04 * len(text), 0.8))
    height = width * rng.uniform(0.25, 0.45)
    if rng.random() < 0.67:
        plate, ink = _rgb(rng, 195, 250), _rgb(rng, 0, 70)
    else:
        plate, ink = _rgb(rng, 20, 95, tint=40), _rgb(rng, 215, 255, tint=10)
    return {"width": round(width, 3), "height": round(height, 3),
            "z": round(float(rng.uniform(1.0, 1.7)), 3), "plate": plate, "ink": ink,
            "font": SIGN_FONTS[int(rng.integers(len(SIGN_FONTS)))],
            "spacing": round(float(rng.uniform(0.0, 0.3)) if rng.random() < 0.5 else 0.0, 3)}


def building_colours(rng: np.random.Generator) -> dict[str, list[int]]:
    """The walls', floor's and skirting's colours (RGB) of one building."""
    return {"wall": _rgb(rng, 140, 235, tint=30), "floor": _rgb(rng, 60, 170, tint=25),
            "skirting": _rgb(rng, 30, 90, tint=15)}


def object_look(rng: np.random.Generator) -> dict:
    """An object's scale, lighting and how much of it stands behind something."""
    look = {"scale": round(float(rng.uniform(0.8, 1.25)), 3),
            "light": round(float(rng.uniform(0.6, 1.3)), 3)}
    if rng.random() < 0.3:
        look["cover"] = round(float(rng.uniform(0.2, 0.5)), 3)
    return look
