"""The sign detector's cheaper paths compute exactly what the plain ones do.

The colourless floor by affine rounding is the table's, order statistics from
a histogram are numpy's, and skipping the features of rejected blobs (no
``explain``) keeps the detections.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from blocks.signs.detect import DetectorParams, detect_plates, grey_floor_image, level_floors
from blocks.signs.detect import (_median, _median_of_counts, _ring_level, _upper_quartile,
                                 _upper_quartile_of_counts)
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
