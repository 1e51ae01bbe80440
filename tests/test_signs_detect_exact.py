"""The sign detector's cheaper paths compute exactly what the plain ones do.

The colourless floor by affine rounding is the table's, order statistics from
a histogram are numpy's, the text's pixels counted per column (and none
looked for where nothing is dark) are the plain mask's, and skipping the
features of rejected blobs (no ``explain``) keeps the detections.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from blocks.signs.detect import DetectorParams, detect_plates, grey_floor_image, level_floors
from blocks.signs.detect import (_median, _median_of_counts, _ring_level, _text_pixels,
                                 _upper_quartile, _upper_quartile_of_counts)
from blocks.signs.types import CameraModel
from sim2d.camera import CameraSpec, camera_pose, render
from sim2d.world import load_world
from sim2d.worlds import world_path

SPEC = CameraSpec()


@pytest.mark.parametrize(("max_chroma", "chroma_floor", "affine"), [
    (0.11, 6.0, True),      # the defaults
    (0.0, 0.0, True),
    (0.2, 10.25, True),
    (0.3333, 6.0, False),   # the rounding misses the table somewhere: the table is used
])
def test_the_colourless_floor_image_is_the_table(max_chroma, chroma_floor, affine):
    params = DetectorParams(max_chroma=max_chroma, chroma_floor=chroma_floor)
    assert (params.allowance is not None) == affine
    grey, _ = level_floors(params)
    hi = np.tile(np.arange(256, dtype=np.uint8), 301)[3:3 + 240 * 320].reshape(240, 320)
    assert np.array_equal(grey_floor_image(hi, params), grey[hi])
    assert np.array_equal(grey_floor_image(hi[5:17, 7:300], params), grey[hi[5:17, 7:300]])


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 17, 400, 5001])
def test_order_statistics_from_counts_are_numpys(n):
    rng = np.random.default_rng(n)
    for values in (rng.integers(0, 256, n).astype(np.uint8),
                   rng.integers(150, 160, n).astype(np.uint8)):
        counts = np.bincount(values, minlength=256)
        assert _median_of_counts(counts) == np.median(values) == _median(values)
        assert _upper_quartile_of_counts(counts) == np.percentile(values, 75) \
            == _upper_quartile(values)


def test_the_ring_level_is_the_bands_median_either_way():
    level = np.random.default_rng(1).integers(0, 256, (240, 320)).astype(np.uint8)
    for box in [(100, 100, 8, 6), (40, 0, 200, 90), (0, 30, 320, 150), (300, 200, 20, 40)]:
        x, y, w, h = box
        pad = max(2, round(0.25 * h))
        grown = np.zeros(level.shape, bool)
        grown[max(0, y - pad):y + h + pad, max(0, x - pad):x + w + pad] = True
        grown[y:y + h, x:x + w] = False
        assert _ring_level(level, box) == np.median(level[grown]), box


def same(a, b):
    return len(a) == len(b) and all(
        np.array_equal(p.corners, q.corners) and (p.bbox, p.bearing, p.range, p.score, p.clipped)
        == (q.bbox, q.bearing, q.range, q.score, q.clipped) for p, q in zip(a, b))


def _plain_text_pixels(level, quad, body_level, dark_ratio):
    """:func:`_text_pixels` as a mask of the interior, then of its dark pixels."""
    u0, u1, t0, t1, s0, s1 = quad
    margin = 0.12 * 0.5 * ((s0 - t0) + (s1 - t1))
    a, b = max(math.ceil(u0 + margin), 0), min(math.floor(u1 - margin), level.shape[1] - 1)
    if b - a < 1:
        return 0.0, 0.0, None
    cols = np.arange(a, b + 1)
    frac = (cols - u0) / max(u1 - u0, 1e-9)
    top, bot = t0 + (t1 - t0) * frac, s0 + (s1 - s0) * frac
    r0 = np.maximum(np.ceil(top + 0.2 * (bot - top)), 0).astype(int)
    r1 = np.minimum(np.floor(bot - 0.2 * (bot - top)), level.shape[0] - 1).astype(int)
    ya, yb = int(r0.min()), int(r1.max()) + 1
    if yb <= ya:
        return 0.0, 0.0, None
    rows = np.arange(ya, yb)[:, None]
    inside = (rows >= r0[None, :]) & (rows <= r1[None, :])
    if inside.sum() < 4:
        return 0.0, 0.0, None
    dark = (level[ya:yb, a:b + 1] < math.ceil(dark_ratio * body_level)) & inside
    if dark.sum() == 0:
        return 0.0, 0.0, None
    dcols = np.flatnonzero(dark.any(axis=0))
    return (dark.sum() / inside.sum(), float(dcols[-1] - dcols[0] + 1) / len(cols),
            (ya, yb, a, b + 1, dark))


def test_the_text_pixels_are_the_plain_masks():
    """Slanted quads (rows of the box outside some columns' interior), dark pixels only
    there, one dark pixel, none at all, quads cut by the border, too thin ones."""
    rng = np.random.default_rng(4)
    level = rng.integers(150, 256, (240, 320)).astype(np.uint8)
    level[100:110, 50:90] = 20  # text
    level[60:64, 200:230] = 20  # dark pixels above a slanted quad's interior only
    level[180, 150] = 20  # a single dark pixel
    quads = [(40.5, 100.5, 95.2, 96.0, 115.3, 114.1), (195.5, 240.5, 58.0, 70.0, 80.0, 95.0),
             (-3.5, 60.5, -8.0, -6.0, 30.0, 33.0), (290.5, 330.5, 200.0, 210.0, 250.0, 245.0),
             (10.5, 14.5, 5.0, 5.0, 7.0, 7.0), (120.5, 160.5, 20.0, 22.0, 40.0, 41.0),
             (130.5, 170.5, 170.0, 170.0, 192.0, 192.0)]
    quads += [tuple(rng.uniform(-20, 340, 2).round(1).tolist() + rng.uniform(-20, 260, 4).tolist())
              for _ in range(300)]
    seen = set()
    for quad in quads:
        want, got = _plain_text_pixels(level, quad, 200.0, 0.75), _text_pixels(level, quad, 200.0,
                                                                               0.75)
        assert want[:2] == got[:2], quad
        assert (want[2] is None) == (got[2] is None), quad
        if want[2] is not None:
            assert want[2][:4] == got[2][:4] and np.array_equal(want[2][4], got[2][4]), quad
        seen.add((want[0] > 0, want[2] is None))
    assert seen == {(True, False), (False, True)}
    assert 0 < _text_pixels(level, quads[6], 200.0, 0.75)[0] < 0.01  # the single pixel


def test_skipping_the_features_of_rejected_blobs_keeps_the_detections():
    # the office's plates from 2 m, tilted up so that the ceiling is in view too
    world = load_world(world_path("office"))
    rng = np.random.default_rng(5)
    reasons, found = set(), 0
    for sign in world.signs[:8]:
        for tilt, zoom, pan in [(0.35, 1.0, 0.0), (0.2, 1.5, 0.3), (0.45, 1.0, -0.4)]:
            x = sign.x + 2.0 * math.cos(sign.facing)
            y = sign.y + 2.0 * math.sin(sign.facing)
            cam = camera_pose((x, y, sign.facing + math.pi), SPEC, pan)
            img = render(world, cam, tilt, zoom, SPEC, rng)
            model = CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt)
            explain: list = []
            full = detect_plates(img, model, explain=explain)
            assert same(detect_plates(img, model), full)
            reasons |= {reason for _, reason, _ in explain}
            found += len(full)
    assert found and "text" in reasons and "contrast" in reasons  # (the quick path ran)
