"""The textual sign detector: finds rendered plates, measures them, ignores everything else."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from blocks.signs.detect import (
    DetectorParams,
    detect_plates,
    is_detectable,
    match_detections,
)
from blocks.signs.types import PLATE_HEIGHT, CameraModel, PlateDetection
from sim2d.camera import (
    CameraSpec,
    camera_pose,
    render,
    sign_plate_image,
    visible_signs,
)
from sim2d.world import Sign, load_world, make_world
from sim2d.worlds import world_path

SPEC = CameraSpec()
HALF = 0.05  # half the default wall thickness of make_world
WALL_X = 6.0  # the plate's wall in the test room
BEIGE = (150, 178, 196)  # sim2d's wall colour (BGR)


def room(signs=(), extra=()):
    """A 9 x 14 m box room, its east wall at x = WALL_X."""
    x0, y0, x1, y1 = -3.0, -7.0, WALL_X, 7.0
    walls = [[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0], *extra]
    return make_world(walls, signs=list(signs))


PLATE = Sign("ROOM 101", WALL_X - HALF, 0.0, math.pi)  # on the east wall, facing west


def model(tilt: float, zoom: float) -> CameraModel:
    return CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt)


def view(world, cam, tilt, zoom, seed=0):
    """The frame, the detections and the ground truth of one camera view."""
    img = render(world, cam, tilt, zoom, SPEC, np.random.default_rng(seed))
    return img, detect_plates(img, model(tilt, zoom)), visible_signs(world, cam, tilt, zoom, SPEC)


def camera_facing_plate(distance, angle_deg, off_axis_deg=0.0):
    """A camera ``distance`` m from the plate, ``angle_deg`` off its normal, the plate
    ``off_axis_deg`` to the left of the optical axis."""
    a = math.radians(angle_deg)
    x, y = PLATE.x - distance * math.cos(a), PLATE.y + distance * math.sin(a)
    to_plate = math.atan2(PLATE.y - y, PLATE.x - x)
    return (x, y, to_plate - math.radians(off_axis_deg))


def tilt_to_plate(distance):
    """The tilt that puts the plate's centre (0.6 m above the camera) mid-frame."""
    return math.atan2(PLATE.z - SPEC.mount_z, distance)


# ---- a rendered plate is found, and measured ------------------------------------------------
@pytest.mark.parametrize(("distance", "angle", "zoom", "off_axis", "tilt_shift"), [
    (1.2, 0, 1.0, 5, 0.0),      # close, head-on: 115 px wide
    (2.5, 30, 1.0, -10, 0.05),  # oblique, off to the right
    (4.0, 50, 2.0, 3, -0.03),
    (3.0, 65, 1.0, 8, 0.0),     # grazing: 0.6 m foreshortened to 0.25 m
    (5.0, 20, 1.0, 0, 0.0),     # far: 14 px tall
    (9.0, 10, 3.0, -2, 0.02),   # far, zoomed in
])
def test_a_rendered_plate_is_found_where_it_is(distance, angle, zoom, off_axis, tilt_shift):
    world = room([PLATE])
    cam = camera_facing_plate(distance, angle, off_axis)
    tilt = tilt_to_plate(distance * math.cos(math.radians(off_axis))) + tilt_shift
    _, dets, truth = view(world, cam, tilt, zoom)
    assert len(truth) == 1 and truth[0]["visible_fraction"] == pytest.approx(1.0)
    t = truth[0]
    assert len(dets) == 1, dets
    d = dets[0]
    assert not d.clipped
    assert 0.0 < d.score <= 1.0
    assert abs(d.bearing - t["bearing"]) < math.radians(1.0)
    assert d.range == pytest.approx(t["distance"], rel=0.12)
    tolerance = max(1.5, 0.1 * t["apparent_height"])
    assert np.abs(d.corners - t["corners"]).max() < tolerance
    # the box covers the plate's visible box
    x0, y0, x1, y1 = t["bbox"]
    assert d.bbox[0] <= x0 + 2 and d.bbox[2] >= x1 - 2
    assert d.bbox[1] <= y0 + 2 and d.bbox[3] >= y1 - 2


def test_corners_are_in_image_order():
    world = room([PLATE])
    cam = camera_facing_plate(2.0, 40, 0)
    _, dets, _ = view(world, cam, tilt_to_plate(2.0), 1.0)
    tl, tr, br, bl = dets[0].corners
    assert tl[0] < tr[0] and bl[0] < br[0]  # left before right
    assert tl[1] < bl[1] and tr[1] < br[1]  # top above bottom
    assert tl[0] == pytest.approx(bl[0]) and tr[0] == pytest.approx(br[0])  # vertical sides


def test_range_follows_the_plate_height():
    """The range scales with the plate height the caller gives (pinhole)."""
    world = room([PLATE])
    cam = camera_facing_plate(3.0, 0, 0)
    img, dets, _ = view(world, cam, tilt_to_plate(3.0), 1.0)
    double = detect_plates(img, model(tilt_to_plate(3.0), 1.0), plate_height=2 * PLATE_HEIGHT)
    assert dets[0].range == pytest.approx(3.0, rel=0.08)
    assert double[0].range == pytest.approx(2 * dets[0].range, rel=1e-6)


@pytest.mark.parametrize(("off_axis", "tilt_shift", "side"), [
    (20, 0.0, 0),     # the plate's left part is out of view: its right edge is whole
    (0, -0.26, 1),    # tilted down: its top is cut off, both sides are in view
])
def test_a_plate_cut_by_the_image_border_is_clipped_but_ranged(off_axis, tilt_shift, side):
    world = room([PLATE])
    cam = camera_facing_plate(1.5 if side else 2.0, 30 if side else 20, off_axis)
    tilt = tilt_to_plate(1.5 if side else 2.0) + tilt_shift
    _, dets, truth = view(world, cam, tilt, 1.0)
    t = truth[0]
    assert 0.65 < t["visible_fraction"] < 0.75 and t["bbox"][side] == 0  # cut at left / top
    assert len(dets) == 1 and dets[0].clipped
    d = dets[0]
    # the centre comes from the plate's direction and width or its whole edge
    assert d.range == pytest.approx(t["distance"], rel=0.06)
    assert abs(d.bearing - t["bearing"]) < math.radians(1.0)


def test_the_same_view_without_the_plate_has_no_detection():
    cam = camera_facing_plate(2.5, 30, 0)
    tilt = tilt_to_plate(2.5)
    assert len(view(room([PLATE]), cam, tilt, 1.0)[1]) == 1
    assert view(room(), cam, tilt, 1.0)[1] == []


# ---- no detections without plates -----------------------------------------------------------
SIGN_FREE_VIEWS = [
    # world, robot pose, pan, tilt, zoom
    ("office", (3.5, 5.8, -math.pi / 2), 0.0, 0.15, 1.0),   # a door opening into a room
    ("office", (3.5, 5.8, -math.pi / 2), 0.0, 0.35, 2.0),   # ... tilted up: ceiling beyond it
    ("office", (1.0, 5.8, 0.0), math.pi / 2, 0.0, 1.0),     # a bare corridor wall, close
    ("office", (1.0, 5.8, 0.0), math.pi, 0.2, 1.0),         # the corridor's corner
    ("office", (1.0, 8.0, math.pi / 2), 0.0, 0.25, 1.0),    # along a corridor: ceiling, floor
    ("office", (12.0, 6.0, 0.0), -math.pi / 2, 0.4, 1.0),   # door frames, tilted to the ceiling
    ("hospital", (3.6, 6.8, -math.pi / 2), 0.0, 0.1, 1.0),  # a ward's door opening
    ("hospital", (20.0, 7.3, 0.0), math.radians(40), 0.2, 1.5),  # the nurses' island
    ("hospital", (20.0, 12.5, -math.pi / 2), 0.0, 0.3, 1.0),     # the hall
]


@pytest.mark.parametrize("name", ["office", "hospital"])
def test_sign_free_views_of_the_worlds_give_no_detection(name):
    world = load_world(world_path(name))
    for world_name, pose, pan, tilt, zoom in SIGN_FREE_VIEWS:
        if world_name != name:
            continue
        cam = camera_pose(pose, SPEC, pan)
        _, dets, truth = view(world, cam, tilt, zoom)
        assert truth == [], (pose, pan)  # the view really is free of signs
        assert dets == [], (pose, pan, [d.bbox for d in dets])


def test_a_world_without_signs_gives_no_detection():
    # an L-shaped corridor with a door opening and a dead end, seen from many poses
    walls = [[0, 0, 10, 0], [0, 2, 4, 2], [5, 2, 8, 2], [8, 2, 8, 8], [10, 0, 10, 8],
             [4, 2, 4, 4], [5, 2, 5, 4], [4, 4, 5, 4], [8, 8, 10, 8], [0, 0, 0, 2]]
    world = make_world(walls)
    rng = np.random.default_rng(3)
    for pose in [(1.0, 1.0, 0.0), (4.5, 1.0, math.pi / 2), (9.0, 1.0, math.pi / 2),
                 (9.0, 6.0, -math.pi / 2), (9.0, 7.5, 0.0)]:
        for pan in (-1.2, 0.0, 1.2):
            tilt, zoom = rng.uniform(0, 0.45), rng.uniform(1, 3)
            cam = camera_pose(pose, SPEC, pan)
            img = render(world, cam, tilt, zoom, SPEC, rng)
            assert detect_plates(img, model(tilt, zoom)) == [], (pose, pan)


# ---- synthetic images -------------------------------------------------------------------------
def canvas(width=320, height=240, shade=1.0):
    img = np.empty((height, width, 3), np.uint8)
    img[:] = np.round(np.array(BEIGE) * shade)
    noise = np.random.default_rng(0).normal(0, 3, img.shape)
    return np.clip(img + noise, 0, 255).astype(np.uint8)


def test_a_pasted_plate_texture_is_a_plate():
    img = canvas()
    plate = cv2.resize(sign_plate_image("LIBRARY"), (120, 40), interpolation=cv2.INTER_AREA)
    img[100:140, 100:220] = plate
    cam = model(0.0, 1.0)
    dets = detect_plates(img, cam)
    assert len(dets) == 1
    d = dets[0]
    expected = np.array([[99.5, 99.5], [219.5, 99.5], [219.5, 139.5], [99.5, 139.5]])
    assert np.abs(d.corners - expected).max() < 1.5
    assert d.range == pytest.approx(math.hypot(cam.f * PLATE_HEIGHT / 40,
                                               PLATE_HEIGHT * (cam.cx - 159.5) / 40), rel=0.06)
    assert abs(d.bearing - math.atan2(cam.cx - 159.5, cam.f)) < math.radians(0.5)


@pytest.mark.parametrize("rim", [0, 3])
def test_a_blank_bright_rectangle_is_not_a_plate(rim):
    """A window or ceiling light: bright, colourless, rectangular, 3:1, but no text."""
    img = canvas()
    cv2.rectangle(img, (100, 100), (219, 139), (238, 238, 238), thickness=-1)
    if rim:
        cv2.rectangle(img, (100, 100), (219, 139), (40, 40, 40), thickness=rim)
    assert detect_plates(img, model(0.0, 1.0)) == []
    # the same rectangle with text is one: the test can fail
    cv2.putText(img, "LAB", (135, 130), cv2.FONT_HERSHEY_DUPLEX, 0.9, (15, 15, 15), 2)
    assert len(detect_plates(img, model(0.0, 1.0))) == 1


def test_a_coloured_plate_is_not_a_plate():
    """Text on a yellow board: the body must be colourless."""
    img = canvas(shade=0.5)  # a dim wall, so the board stands out
    plate = sign_plate_image("LIBRARY", 120, 40).astype(np.float32)
    tint = np.array([0.55, 0.8, 1.0], np.float32)  # keep red, drop blue
    img[100:140, 100:220] = (plate * tint).astype(np.uint8)
    assert detect_plates(img, model(0.0, 1.0)) == []
    # it is the colour (of the board and of the letters' edges) that rejects it
    lenient = DetectorParams(max_chroma=0.5, max_text_chroma=0.5)
    assert len(detect_plates(img, model(0.0, 1.0), lenient)) == 1


def test_a_tall_text_panel_is_not_a_plate():
    """A 1:1 notice with text is not a 3:1 door sign."""
    img = canvas()
    panel = cv2.resize(sign_plate_image("NO", 200, 200), (60, 60), interpolation=cv2.INTER_AREA)
    img[90:150, 130:190] = panel
    assert detect_plates(img, model(0.0, 1.0)) == []
    wide = cv2.resize(sign_plate_image("NO"), (180, 60), interpolation=cv2.INTER_AREA)
    img[90:150, 70:250] = wide
    assert len(detect_plates(img, model(0.0, 1.0))) == 1


def test_bad_input_is_refused():
    with pytest.raises(ValueError):
        detect_plates(np.zeros((240, 320), np.uint8), model(0.0, 1.0))
    with pytest.raises(ValueError):
        detect_plates(np.zeros((120, 160, 3), np.uint8), model(0.0, 1.0))


def test_params_are_honoured():
    img = canvas()
    img[100:140, 100:220] = cv2.resize(sign_plate_image("LIBRARY"), (120, 40),
                                       interpolation=cv2.INTER_AREA)
    assert len(detect_plates(img, model(0.0, 1.0))) == 1
    assert detect_plates(img, model(0.0, 1.0), DetectorParams(min_height=50)) == []


# ---- matching to the ground truth -----------------------------------------------------------
def truth_plate(bbox, height=20.0, visible=1.0, angle=0.0):
    return {"bbox": bbox, "apparent_height": height, "visible_fraction": visible,
            "viewing_angle": angle}


def det(bbox, score=0.9):
    x0, y0, x1, y1 = bbox
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)
    return PlateDetection(corners=corners, bbox=bbox, bearing=0.0, range=1.0, score=score)


def test_matching_counts_true_and_false_positives_and_misses():
    truth = [truth_plate((10, 10, 70, 30)), truth_plate((200, 50, 260, 70)),
             truth_plate((100, 100, 103, 104), height=4.0)]  # too small to expect
    dets = [det((11, 11, 69, 29)), det((150, 150, 200, 170)), det((100, 100, 103, 104))]
    tp, fp, fn, matches = match_detections(dets, truth)
    assert (tp, fp, fn) == (1, 1, 1)  # the small plate's detection is neither
    assert matches == [(0, 0)]


def test_matching_counts_a_second_detection_of_a_plate_as_false():
    truth = [truth_plate((10, 10, 70, 30))]
    dets = [det((10, 10, 40, 30), score=0.5), det((10, 10, 70, 30), score=0.9)]
    tp, fp, fn, matches = match_detections(dets, truth)
    assert (tp, fp, fn) == (1, 1, 0)
    assert matches == [(1, 0)]  # the better one


def test_detectable_means_tall_enough_and_visible_enough():
    assert is_detectable(truth_plate((0, 0, 9, 9), height=6.0, visible=0.6))
    assert not is_detectable(truth_plate((0, 0, 9, 9), height=5.9))
    assert not is_detectable(truth_plate((0, 0, 9, 9), visible=0.5))
    oblique = truth_plate((0, 0, 9, 9), angle=math.radians(80))
    assert is_detectable(oblique)
    assert not is_detectable(oblique, max_viewing_angle=math.radians(70))
