"""Plates of any look: light on dark, tinted, any size, on walls of any colour."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from blocks.signs.detect import detect_plates, match_detections
from blocks.signs.detect_any import (
    AnyLookParams,
    detect_any_plates,
    detect_outlined_plates,
    plate_levels,
)
from blocks.signs.types import CameraModel
from sim2d.camera import CameraSpec, render, visible_signs
from sim2d.world import Sign, load_world, make_world
from sim2d.worlds import world_path

SPEC = CameraSpec()
WALL_X = 6.0
HALF = 0.05

# (plate RGB, ink RGB, wall RGB, width, height, font): looks a generated building hangs
LOOKS = {
    "navy on green": ((25, 35, 90), (240, 240, 225), (120, 150, 100), 0.5, 0.18, "simplex"),
    "tinted light": ((230, 200, 215), (60, 20, 40), (150, 140, 170), 0.4, 0.15, "triplex"),
    "dark green, wide": ((30, 75, 50), (230, 240, 230), (200, 195, 180), 0.8, 0.22, "duplex"),
    "pale on pale": ((225, 230, 215), (20, 30, 20), (205, 215, 200), 0.35, 0.14, "complex"),
}


def room(sign: Sign, wall_rgb=None):
    """A 9 x 14 m box room holding ``sign``, its walls ``wall_rgb`` (sim2d's beige if None)."""
    walls = [[-3.0, -7.0, WALL_X, -7.0], [WALL_X, -7.0, WALL_X, 7.0], [WALL_X, 7.0, -3.0, 7.0],
             [-3.0, 7.0, -3.0, -7.0]]
    world = make_world(walls, signs=[sign])
    return world if wall_rgb is None else dataclasses.replace(world, colours={"wall": wall_rgb})


def plate(look: str, z: float = 1.4) -> Sign:
    colour, ink, _, width, height, font = LOOKS[look]
    return Sign("OFFICE 12", WALL_X - HALF, 0.0, math.pi, width=width, height=height, z=z,
                plate=colour, ink=ink, font=font)


def frame(world, sign: Sign, distance: float, angle_deg: float, zoom: float = 1.0, seed: int = 0):
    """A camera ``distance`` m from the plate, ``angle_deg`` off its normal, aimed at it."""
    a = math.radians(angle_deg)
    x, y = sign.x - distance * math.cos(a), sign.y + distance * math.sin(a)
    cam = (x, y, math.atan2(sign.y - y, sign.x - x))
    tilt = math.atan2(sign.z - SPEC.mount_z, distance)
    img = render(world, cam, tilt, zoom, SPEC, np.random.default_rng(seed))
    model = CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt)
    return img, model, visible_signs(world, cam, tilt, zoom, SPEC)


@pytest.mark.parametrize("look", sorted(LOOKS))
@pytest.mark.parametrize(("distance", "angle", "zoom"), [(1.5, 0, 1.0), (2.5, 35, 1.0),
                                                         (4.0, 20, 2.0)])
def test_plates_of_any_look_are_found_where_they_are(look, distance, angle, zoom):
    sign = plate(look)
    img, model, truth = frame(room(sign, LOOKS[look][2]), sign, distance, angle, zoom)
    dets = detect_any_plates(img, model)
    tp, fp, fn, _ = match_detections(dets, truth)
    assert (tp, fp, fn) == (1, 0, 0), dets
    t, d = truth[0], dets[0]
    assert abs(d.bearing - t["bearing"]) < math.radians(1.0)
    assert np.abs(d.corners - t["corners"]).max() < max(2.0, 0.1 * t["apparent_height"])


def test_the_white_plate_detector_misses_dark_plates_the_outline_finds():
    sign = plate("navy on green")
    img, model, truth = frame(room(sign, LOOKS["navy on green"][2]), sign, 2.0, 20)
    assert detect_plates(img, model) == []
    assert len(detect_outlined_plates(img, model)) == 1


def test_the_standard_plate_gives_the_white_detectors_detections_unchanged():
    """Where the white-plate detector finds the plate, its detection is the one reported."""
    sign = Sign("ROOM 101", WALL_X - HALF, 0.0, math.pi)
    world = room(sign)
    for distance, angle in [(1.2, 0), (2.5, 30), (4.0, 50), (6.0, 10)]:
        img, model, _ = frame(world, sign, distance, angle)
        plain, both = detect_plates(img, model), detect_any_plates(img, model)
        assert len(plain) == 1
        assert [(d.bbox, d.range, d.score) for d in both] == [(d.bbox, d.range, d.score)
                                                             for d in plain]


def test_a_label_below_the_camera_is_no_door_sign():
    """A text-bearing plate at 0.5 m (a label on furniture) is below where door signs hang."""
    low = plate("navy on green", z=0.45)
    img, model, truth = frame(room(low, LOOKS["navy on green"][2]), low, 2.0, 10)
    assert len(truth) == 1
    explain: list = []
    assert detect_outlined_plates(img, model, explain=explain) == []
    assert any(reason == "elevation" for _, reason in explain)
    # and it is the elevation alone that rejects it
    anywhere = AnyLookParams(min_elevation=-math.inf)
    assert len(detect_outlined_plates(img, model, anywhere)) == 1


def test_a_white_label_below_the_camera_is_no_door_sign_either():
    """A parcel's white address label ("TO: LAB") is the white-plate detector's kind of
    plate, but it lies where no door sign hangs; the white detector alone still finds it."""
    low = Sign("TO: LAB", WALL_X - HALF, 0.0, math.pi, width=0.3, height=0.12, z=0.35)
    img, model, truth = frame(room(low), low, 1.6, 10)
    assert len(truth) == 1
    assert len(detect_plates(img, model)) == 1
    assert detect_any_plates(img, model) == []
    high = dataclasses.replace(low, z=1.4)
    img, model, _ = frame(room(high), high, 1.6, 10)
    assert len(detect_any_plates(img, model)) == 1


@pytest.mark.parametrize("name", ["office", "hospital"])
def test_sign_free_views_of_the_worlds_give_no_outlined_plate(name):
    """Bare walls, doorways, corners, floor and ceiling: no plate of any look."""
    world = load_world(world_path(name))
    bare = dataclasses.replace(world, signs=[], objects=[])
    rng = np.random.default_rng(3)
    xmin, ymin, xmax, ymax = bare.bounds()
    found = 0
    for _ in range(40):
        x, y = rng.uniform(xmin, xmax), rng.uniform(ymin, ymax)
        cam = (x, y, rng.uniform(-math.pi, math.pi))
        tilt, zoom = rng.uniform(0.0, 0.4), rng.uniform(1.0, 3.0)
        img = render(bare, cam, tilt, zoom, SPEC, np.random.default_rng(int(rng.integers(1 << 30))))
        found += len(detect_outlined_plates(img, CameraModel.of(SPEC.width, SPEC.height,
                                                                SPEC.hfov, zoom, tilt)))
    assert found == 0


def test_plate_levels_fall_with_the_colour_distance():
    patch = np.array([[[10, 20, 30], [10, 20, 40], [200, 200, 200]]], np.uint8)
    levels = plate_levels(patch, np.array([10, 20, 30]), 2)
    assert levels.tolist() == [[250, 230, 0]]


def test_text_of_one_ink_lies_between_the_body_and_the_ink_and_books_do_not():
    """:func:`ink_spread`: blurred letters mix one ink into the body; a shelf of books is
    many colours."""
    from blocks.signs.detect_any import ink_spread

    body = np.array([40, 60, 90], np.float64)
    quad = (0.0, 60.0, 0.0, 0.0, 20.0, 20.0)  # a 60 x 20 px plate
    feats = {"quad": quad, "body_level": 250.0}
    smooth = np.tile(body.astype(np.uint8), (20, 60, 1))
    letters = np.zeros((20, 60), bool)
    letters[6:14, 10:50:4] = True
    ink = np.array([230, 235, 240], np.uint8)
    one_ink = smooth.copy()
    one_ink[letters] = ink
    one_ink[6:14, 11:51:4] = ((ink.astype(int) + body) / 2).astype(np.uint8)  # blurred halves
    books = smooth.copy()
    rng = np.random.default_rng(0)
    books[letters] = rng.integers(0, 256, (int(letters.sum()), 3), dtype=np.uint8)
    books[6:14, 11:51:4] = rng.integers(0, 256, (8, 10, 3), dtype=np.uint8)

    def spread(frame):
        return ink_spread(frame, plate_levels(frame, body, 2), feats, body)

    assert spread(one_ink) < 0.05
    assert spread(books) > AnyLookParams().max_ink_spread


def framed_room(sign: Sign, wall_rgb):
    """:func:`room` with a 4 cm frame standing out of the wall 1 cm beyond each end of the
    plate (a door's architrave, a pilaster): its edges run past the plate, top to bottom."""
    edge = sign.width / 2 + 0.01
    walls = [[-3.0, -7.0, WALL_X, -7.0], [WALL_X, -7.0, WALL_X, 7.0], [WALL_X, 7.0, -3.0, 7.0],
             [-3.0, 7.0, -3.0, -7.0], [WALL_X, edge, WALL_X - 0.04, edge],
             [WALL_X, -edge, WALL_X - 0.04, -edge]]
    return dataclasses.replace(make_world(walls, signs=[sign]), colours={"wall": wall_rgb})


@pytest.mark.parametrize("look", sorted(LOOKS))
@pytest.mark.parametrize(("distance", "angle"), [(1.5, 0), (2.0, 20), (2.5, 35)])
def test_a_plate_between_the_edges_of_a_frame_is_found_inside_them(look, distance, angle):
    """The plate's outline touches the frame's edges, which reach the image's top and bottom:
    taken whole, the outline is a wall's; the plate is what the edges enclose."""
    sign = dataclasses.replace(plate(look), width=0.4)
    img, model, truth = frame(framed_room(sign, LOOKS[look][2]), sign, distance, angle)
    assert len(truth) == 1
    inside = AnyLookParams(inside_edges=True)
    tp, fp, fn, _ = match_detections(detect_outlined_plates(img, model, inside), truth)
    assert (tp, fp, fn) == (1, 0, 0)
    assert detect_outlined_plates(img, model) == []  # the default, until measured end to end
