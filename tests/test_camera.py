"""The synthetic PTZ camera: geometry, visibility, occlusion, zoom/pan, degradation."""
from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim2d.camera import (
    CameraError,
    CameraRenderer,
    CameraSpec,
    Walls,
    BLUR_LEVELS,
    _angle_span,
    _Canvas,
    _Lens,
    _Shot,
    _blur_boxes,
    _depth_blur,
    _end_keys,
    _forward_depth,
    _gaussian_blur,
    _inverse_lengths,
    _off_image,
    _project,
    _shared_ends,
    _warp_texture,
    camera_pose,
    cast_rays,
    clamp_ptz,
    focal_length,
    plate_corners,
    project_points,
    render,
    sign_plate_image,
    visible_objects,
    visible_signs,
)
from sim2d.world import SIGN_FONTS, Sign, WorldObject, make_world

SPEC = CameraSpec()
HALF = 0.05  # half the default wall thickness of make_world


def room(x0, y0, x1, y1, signs=(), extra=()):
    """A box room of walls (plus extra walls) with the given signs."""
    walls = [[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0], *extra]
    return make_world(walls, signs=list(signs))


def shot(world, pose, tilt=0.0, zoom=1.0, spec=SPEC, seed=0):
    return render(world, pose, tilt, zoom, spec, np.random.default_rng(seed))


def grey(img):
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.int16)


def look_at_tilt(distance, z=1.2, spec=SPEC):
    """The tilt that centres a point at height z and this forward distance."""
    return math.atan2(z - spec.mount_z, distance)


def plate_mask(world, world_without, pose, tilt=0.0, zoom=1.0):
    """Pixels the plate changes: same seed, so the noise cancels exactly."""
    diff = np.abs(grey(shot(world, pose, tilt, zoom)) - grey(shot(world_without, pose, tilt, zoom)))
    return diff > 25


def extent(mask):
    cols = np.flatnonzero(mask.any(axis=0))
    return 0 if len(cols) == 0 else cols[-1] - cols[0] + 1


FRONT = Sign("ROOM 101", 2.0 - HALF, 0.0, math.pi)  # on the wall 2 m ahead, facing the camera


# ---- a plate in view is drawn where visible_signs says ---------------------------------------
def test_plate_in_view_is_drawn_with_high_contrast():
    with_sign = room(-3, -3, 2, 3, [FRONT])
    without = room(-3, -3, 2, 3)
    tilt = look_at_tilt(2 - HALF)
    seen = visible_signs(with_sign, (0, 0, 0), tilt, 1.0, SPEC)
    assert [s["text"] for s in seen] == ["ROOM 101"]
    s = seen[0]
    assert s["distance"] == pytest.approx(1.95)
    assert s["bearing"] == pytest.approx(0.0, abs=1e-9)
    assert s["viewing_angle"] == pytest.approx(0.0, abs=1e-6)
    assert s["visible_fraction"] == pytest.approx(1.0)
    # pinhole: apparent width = f * w / d
    assert s["apparent_width"] == pytest.approx(focal_length(SPEC, 1) * 0.6 / 1.95, rel=1e-6)
    x0, y0, x1, y1 = s["bbox"]
    assert 0 <= x0 < x1 < SPEC.width and 0 <= y0 < y1 < SPEC.height
    assert abs((x0 + x1) / 2 - (SPEC.width - 1) / 2) < 2  # straight ahead, tilted to centre
    assert abs((y0 + y1) / 2 - (SPEC.height - 1) / 2) < 2

    region = grey(shot(with_sign, (0, 0, 0), tilt))[y0:y1 + 1, x0:x1 + 1]
    assert (region > 195).mean() > 0.3 and (region < 60).mean() > 0.05  # white and black
    empty = grey(shot(without, (0, 0, 0), tilt))[y0:y1 + 1, x0:x1 + 1]
    assert np.percentile(empty, 99) - np.percentile(empty, 1) < 30  # plain wall
    assert not (empty > 195).any() and not (empty < 60).any()


def test_plate_is_not_mirrored():
    world = room(-3, -3, 2, 3, [FRONT])
    tilt = look_at_tilt(2 - HALF)
    s = visible_signs(world, (0, 0, 0), tilt, 1.0, SPEC)[0]
    tl, tr, br, bl = s["corners"]
    assert tl[0] < tr[0] and bl[0] < br[0] and tl[1] < bl[1]  # top-left is top left
    # the drawn plate correlates with its texture, not with the texture's mirror image
    x0, y0, x1, y1 = (round(v) for v in (tl[0], tl[1], br[0], br[1]))
    crop = grey(shot(world, (0, 0, 0), tilt))[y0:y1, x0:x1].astype(np.float32)
    tex = cv2.cvtColor(sign_plate_image("ROOM 101", 600, 200), cv2.COLOR_BGR2GRAY)
    tex = cv2.resize(tex, (crop.shape[1], crop.shape[0]), interpolation=cv2.INTER_AREA)
    tex = tex.astype(np.float32)

    def corr(a, b):
        return float(np.corrcoef(a.ravel(), b.ravel())[0, 1])

    assert corr(crop, tex) > 0.8
    assert corr(crop, tex) > corr(crop, tex[:, ::-1]) + 0.2


def test_plate_corners_follow_the_normal():
    # Looking at a plate whose normal points at -y (viewer looks along +y), its left is -x.
    c = plate_corners(Sign("A", 0.0, 0.0, -math.pi / 2))
    assert c[0, 0] < c[1, 0] and c[3, 0] < c[2, 0]
    assert c[0, 2] > c[3, 2]  # top first


# ---- plates that are not visible are neither reported nor drawn -------------------------------
def assert_hidden(world, world_without, pose, tilt=0.0, zoom=1.0, spec=SPEC):
    assert visible_signs(world, pose, tilt, zoom, spec) == []
    assert np.array_equal(shot(world, pose, tilt, zoom, spec), shot(world_without, pose, tilt,
                                                                   zoom, spec))


def test_plate_behind_the_camera_is_hidden():
    behind = Sign("BACK", -3 + HALF, 0.0, 0.0)  # on the back wall, facing the camera's back
    world, without = room(-3, -3, 2, 3, [behind]), room(-3, -3, 2, 3)
    assert_hidden(world, without, (0, 0, 0))
    # turned round, the camera sees it: the set-up can fail
    assert [s["text"] for s in visible_signs(world, (0, 0, math.pi), 0.2, 1.0, SPEC)] == ["BACK"]


def test_plate_facing_away_is_hidden():
    away = Sign("AWAY", 2.0 + HALF, 0.0, 0.0)  # on the far side of the front wall
    world, without = room(-3, -3, 2, 3, [away]), room(-3, -3, 2, 3)
    assert_hidden(world, without, (0, 0, 0), look_at_tilt(2))


def test_plate_beyond_max_range_is_hidden():
    far = Sign("FAR", 15 - HALF, 0.0, math.pi)
    world, without = room(-1, -2, 15, 2, [far]), room(-1, -2, 15, 2)
    tilt = look_at_tilt(15)
    assert_hidden(world, without, (0, 0, 0), tilt, zoom=3.0)
    longer = CameraSpec(max_range=20.0)
    assert [s["text"] for s in visible_signs(world, (0, 0, 0), tilt, 3.0, longer)] == ["FAR"]


def test_plate_behind_a_wall_is_hidden():
    partition = [[1.0, -1.5, 1.0, 1.5]]
    world = room(-3, -3, 2, 3, [FRONT], extra=partition)
    without = room(-3, -3, 2, 3, extra=partition)
    assert_hidden(world, without, (0, 0, 0), look_at_tilt(2))


def test_plate_partly_behind_a_wall_is_clipped_there():
    # The plate is 3 m ahead; a wall from y=0.1 leftwards, 1.5 m ahead, hides its left part.
    plate = Sign("ROOM 101", 3.0 - HALF, 0.0, math.pi)
    world = room(-3, -3, 3, 3, [plate], extra=[[1.5, 0.1, 1.5, 2.0]])
    open_world = room(-3, -3, 3, 3, [plate])
    tilt = look_at_tilt(3)
    full = visible_signs(open_world, (0, 0, 0), tilt, 1.0, SPEC)[0]
    part = visible_signs(world, (0, 0, 0), tilt, 1.0, SPEC)[0]
    assert full["visible_fraction"] == pytest.approx(1.0)
    # the wall's edge (radius 0.05) reaches y=0.05 at x=1.5, i.e. y~0.1 on the plate
    assert 0.55 < part["visible_fraction"] < 0.8
    assert part["bbox"][0] > full["bbox"][0] + 5  # the left part is gone
    assert part["bbox"][2] == full["bbox"][2]
    # and the image shows only the visible part
    mask = plate_mask(world, room(-3, -3, 3, 3, extra=[[1.5, 0.1, 1.5, 2.0]]), (0, 0, 0), tilt)
    cols = np.flatnonzero(mask.any(axis=0))
    assert cols.min() >= part["bbox"][0] - 2 and cols.max() <= part["bbox"][2] + 2


# ---- zoom and pan ----------------------------------------------------------------------------
def test_zoom_narrows_the_field_of_view():
    y = (3 - HALF) * math.tan(math.radians(20))
    side = Sign("SIDE", 3 - HALF, y, math.pi)  # 20 deg to the left
    world, without = room(-3, -3, 3, 3, [side]), room(-3, -3, 3, 3)
    tilt = look_at_tilt(3)
    seen = visible_signs(world, (0, 0, 0), tilt, 1.0, SPEC)
    assert [s["text"] for s in seen] == ["SIDE"]
    assert seen[0]["bearing"] == pytest.approx(math.radians(20), abs=1e-6)
    assert seen[0]["bbox"][2] < SPEC.width / 2  # on the left of the image
    assert_hidden(world, without, (0, 0, 0), tilt, zoom=4.0)


@pytest.mark.parametrize("zoom", [2.0, 3.0])
def test_zoom_magnifies_the_plate(zoom):
    plate = Sign("ROOM 101", 5 - HALF, 0.0, math.pi)
    world, without = room(-1, -3, 5, 3, [plate]), room(-1, -3, 5, 3)
    tilt = look_at_tilt(5)
    w1 = visible_signs(world, (0, 0, 0), tilt, 1.0, SPEC)[0]["apparent_width"]
    wz = visible_signs(world, (0, 0, 0), tilt, zoom, SPEC)[0]["apparent_width"]
    assert wz / w1 == pytest.approx(zoom, rel=1e-6)
    drawn1 = extent(plate_mask(world, without, (0, 0, 0), tilt, 1.0))
    drawnz = extent(plate_mask(world, without, (0, 0, 0), tilt, zoom))
    assert drawn1 == pytest.approx(w1, abs=3)
    assert drawnz / drawn1 == pytest.approx(zoom, rel=0.1)


def test_pan_brings_a_side_sign_into_view():
    robot = (0.0, 0.0, 0.0)
    bearing = math.radians(60)
    sign = Sign("LEFT", 3 * math.cos(bearing), 3 * math.sin(bearing), bearing + math.pi)
    world = room(-4, -4, 4, 4, [sign], extra=[])
    without = room(-4, -4, 4, 4)
    tilt = look_at_tilt(3)
    assert_hidden(world, without, camera_pose(robot, SPEC, 0.0), tilt)
    cam = camera_pose(robot, SPEC, math.radians(60))
    seen = visible_signs(world, cam, tilt, 1.0, SPEC)
    assert [s["text"] for s in seen] == ["LEFT"]
    # the mount is 0.15 m ahead of the robot, so the camera sees it a little to the left
    expected = math.atan2(sign.y - cam[1], sign.x - cam[0]) - cam[2]
    assert seen[0]["bearing"] == pytest.approx(expected, abs=1e-9)
    assert 0 < seen[0]["bearing"] < math.radians(4)
    x0, _, x1, _ = seen[0]["bbox"]
    centre = (SPEC.width - 1) / 2 - focal_length(SPEC, 1.0) * math.tan(seen[0]["bearing"])
    assert abs((x0 + x1) / 2 - centre) < 3
    mask = plate_mask(world, without, cam, tilt)
    assert mask.sum() > 500


def test_camera_pose_applies_mount_and_pan():
    spec = CameraSpec(mount_x=0.2, mount_y=0.1)
    x, y, yaw = camera_pose((1.0, 2.0, math.pi / 2), spec, pan=0.3)
    assert (x, y, yaw) == pytest.approx((1.0 - 0.1, 2.0 + 0.2, math.pi / 2 + 0.3))


def test_clamp_ptz():
    pan, tilt, zoom = clamp_ptz(SPEC, math.radians(200), math.radians(-45), 25.0)
    assert pan == pytest.approx(math.radians(170))
    assert tilt == pytest.approx(math.radians(-30))
    assert zoom == 10.0
    assert clamp_ptz(SPEC, 0.1, 0.2, 2.0) == (0.1, 0.2, 2.0)


# ---- viewing angle ---------------------------------------------------------------------------
@pytest.mark.parametrize("angle_deg", [45.0, 60.0])
def test_oblique_view_narrows_the_plate(angle_deg):
    plate = Sign("ROOM 101", HALF, 0.0, 0.0)  # on the wall x=0, facing +x
    world = make_world([[0, -6, 0, 6]], signs=[plate])
    without = make_world([[0, -6, 0, 6]])
    tilt = look_at_tilt(3)

    def seen_from(angle):
        cam = (HALF + 3 * math.cos(angle), 3 * math.sin(angle), angle + math.pi)
        return cam, visible_signs(world, cam, tilt, 1.0, SPEC)

    cam0, (head_on,) = seen_from(0.0)
    cam, (oblique,) = seen_from(math.radians(angle_deg))
    assert oblique["viewing_angle"] == pytest.approx(math.radians(angle_deg), abs=1e-6)
    assert oblique["distance"] == pytest.approx(3.0)
    ratio = oblique["apparent_width"] / head_on["apparent_width"]
    assert ratio == pytest.approx(math.cos(math.radians(angle_deg)), rel=0.05)
    drawn = extent(plate_mask(world, without, cam, tilt)) / extent(
        plate_mask(world, without, cam0, tilt))
    assert drawn == pytest.approx(math.cos(math.radians(angle_deg)), rel=0.12)


# ---- noise -----------------------------------------------------------------------------------
def test_same_seed_same_image_different_seed_different_image():
    world = room(-3, -3, 2, 3, [FRONT])
    a, b, c = (shot(world, (0, 0, 0.3), 0.1, seed=s) for s in (7, 7, 8))
    assert a.dtype == np.uint8 and a.shape == (SPEC.height, SPEC.width, 3)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    noise = a.astype(float) - c.astype(float)
    assert 2.5 < noise.std() / math.sqrt(2) < 3.5  # noise_std = 3 grey levels per image
    quiet = CameraSpec(noise_std=0.0)
    assert np.array_equal(shot(world, (0, 0, 0.3), 0.1, spec=quiet, seed=1),
                          shot(world, (0, 0, 0.3), 0.1, spec=quiet, seed=2))


def test_blur_grows_with_distance_and_shrinks_with_zoom():
    """Plate sharpness (Laplacian energy at a common scale): 2 m > 10 m ~ 10 m zoomed 5x."""
    def sharpness(distance, zoom):
        plate = Sign("ROOM 101", distance - HALF, 0.0, math.pi)
        world = room(-1, -3, distance, 3, [plate])
        tilt = look_at_tilt(distance - HALF)
        s = visible_signs(world, (0, 0, 0), tilt, zoom, CameraSpec(noise_std=0.0))[0]
        x0, y0, x1, y1 = s["bbox"]
        img = grey(shot(world, (0, 0, 0), tilt, zoom, spec=CameraSpec(noise_std=0.0)))
        crop = img[y0:y1 + 1, x0:x1 + 1].astype(np.float32)
        crop = cv2.resize(crop, (120, 40), interpolation=cv2.INTER_AREA)  # same scale for all
        return float(np.abs(cv2.Laplacian(crop, cv2.CV_32F)).mean())

    near, far, zoomed = sharpness(2.0, 1.0), sharpness(10.0, 1.0), sharpness(10.0, 5.0)
    assert near > 2 * far
    # 10 m at zoom 5 is as large as 2 m at zoom 1, and should be about as sharp
    assert zoomed == pytest.approx(near, rel=0.25)


# ---- the ray caster --------------------------------------------------------------------------
def test_cast_rays_hits_faces_caps_and_posts():
    segments = np.array([
        [2.0, -1.0, 2.0, 1.0, 0.1],  # a wall 2 m ahead, 0.1 m radius
        [0.0, 3.0, 0.0, 3.0, 0.2],  # a post 3 m to the left
    ])
    angles = np.array([0.0, math.atan2(1.05, 1.9), math.pi / 2, math.pi, -math.pi / 2])
    t, cos = cast_rays((0.0, 0.0), angles, segments)
    assert t[0] == pytest.approx(1.9, abs=1e-5) and cos[0] == pytest.approx(1.0, abs=1e-5)
    # the round cap at (2, 1): the ray passes its centre at a distance d < r
    d = abs(math.sin(angles[1]) * 2.0 - math.cos(angles[1]) * 1.0)
    proj = math.cos(angles[1]) * 2.0 + math.sin(angles[1]) * 1.0
    assert t[1] == pytest.approx(proj - math.sqrt(0.01 - d * d), abs=1e-5)
    assert t[2] == pytest.approx(2.8, abs=1e-5)
    assert math.isinf(t[3]) and math.isinf(t[4]) and cos[3] == 0


def test_cast_rays_closes_convex_corners_of_chained_walls():
    # A square pillar of 0.1 m-radius walls; a ray just past its top-left corner
    # (between the centre line y=0.5 and the surface y=0.6) must still hit it.
    pillar = np.array([[1, -0.5, 1, 0.5, 0.1], [1, 0.5, 2, 0.5, 0.1],
                       [2, 0.5, 2, -0.5, 0.1], [2, -0.5, 1, -0.5, 0.1]])
    target = (0.9, 0.55)
    t, cos = cast_rays((0.0, 0.0), np.array([math.atan2(target[1], target[0])]), pillar)
    assert t[0] == pytest.approx(math.hypot(*target), abs=1e-5)
    assert cos[0] == pytest.approx(0.9 / math.hypot(*target), abs=1e-5)


def _exact_capsule_hit(o, a, angle, seg):
    """Reference: distance along one ray to one capsule (both faces and both caps), scalar."""
    dx, dy = math.cos(angle), math.sin(angle)
    x1, y1, x2, y2, r = seg
    best = math.inf
    ex, ey = x2 - x1, y2 - y1
    length = math.hypot(ex, ey)
    if length > 1e-9:
        nx, ny = -ey / length, ex / length
        for side in (1, -1):
            qx, qy = x1 + side * r * nx - o[0], y1 + side * r * ny - o[1]
            den = dx * ey - dy * ex
            if abs(den) > 1e-12:
                t = (qx * ey - qy * ex) / den
                s = (qx * dy - qy * dx) / den
                if t > 0 and 0 <= s <= 1:
                    best = min(best, t)
    for cx, cy in ((x1, y1), (x2, y2)):
        rx, ry = cx - o[0], cy - o[1]
        proj = dx * rx + dy * ry
        disc = r * r - (rx * rx + ry * ry) + proj * proj
        if disc >= 0 and proj - math.sqrt(disc) > 0:
            best = min(best, proj - math.sqrt(disc))
    return best


coord = st.floats(-8, 8, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(segs=st.lists(st.tuples(coord, coord, coord, coord, st.floats(0.0, 0.3)),
                     min_size=1, max_size=12),
       yaw=st.floats(-math.pi, math.pi), zoom=st.floats(1.0, 10.0))
def test_cast_rays_matches_exact_capsules(segs, yaw, zoom):
    """Free-standing capsules (no shared ends) are hit exactly, culling included."""
    segments = np.array(segs, dtype=np.float64)
    origin = (0.0, 0.0)
    clear = [s for s in segments if _distance_to_capsule(origin, s) > 0.05]
    segments = np.array(clear).reshape(-1, 5)
    ends = np.round(np.concatenate([segments[:, :2], segments[:, 2:4]]) * 1e5)
    if len(np.unique(ends, axis=0)) < len(ends):
        return  # touching ends get square joins, not round caps
    f = focal_length(SPEC, zoom)
    angles = yaw + np.arctan2((SPEC.width - 1) / 2 - np.arange(0, SPEC.width, 7), f)
    t, _ = cast_rays(origin, angles, segments)
    for i, angle in enumerate(angles):
        if any(abs(_ray_to_segment(angle, s) - s[4]) < 1e-4 for s in segments):
            continue  # grazing a capsule's outline: hit or miss is down to rounding
        ref = min((_exact_capsule_hit(origin, None, angle, s) for s in segments), default=math.inf)
        if math.isinf(ref):
            assert math.isinf(t[i])
        else:
            assert t[i] == pytest.approx(ref, abs=2e-4, rel=1e-4)


def _ray_to_segment(angle, seg):
    """Least distance between the ray from the origin at this angle and a segment's centre line."""
    dx, dy = math.cos(angle), math.sin(angle)
    x1, y1, x2, y2, _ = seg
    ex, ey = x2 - x1, y2 - y1
    den = dx * ey - dy * ex
    if abs(den) > 1e-15:
        t = (x1 * ey - y1 * ex) / den
        s = (x1 * dy - y1 * dx) / den
        if t >= 0 and 0 <= s <= 1:
            return 0.0
    ends = [math.hypot(x - max(0.0, x * dx + y * dy) * dx, y - max(0.0, x * dx + y * dy) * dy)
            for x, y in ((x1, y1), (x2, y2))]
    return min(*ends, _distance_to_capsule((0.0, 0.0), (*seg[:4], 0.0)))


def _distance_to_capsule(p, seg):
    x1, y1, x2, y2, r = seg
    ex, ey = x2 - x1, y2 - y1
    l2 = ex * ex + ey * ey
    s = 0.0 if l2 == 0 else min(1.0, max(0.0, ((p[0] - x1) * ex + (p[1] - y1) * ey) / l2))
    return math.hypot(p[0] - x1 - s * ex, p[1] - y1 - s * ey) - r


def test_render_with_no_walls_or_signs():
    empty = make_world([])
    img = shot(empty, (0, 0, 0))
    g = grey(img)
    assert img.shape == (240, 320, 3)
    assert g[:100].mean() > g[140:].mean() + 40  # light ceiling over a dark floor


# ---- the spec --------------------------------------------------------------------------------
def test_spec_from_dict_reads_fields_and_checks_them():
    spec = CameraSpec.from_dict({"width": 640, "height": 480, "hfov_deg": 60, "mount_z": 0.8,
                                 "pan_max_deg": 90})
    assert (spec.width, spec.height, spec.mount_z) == (640, 480, 0.8)
    assert spec.hfov == pytest.approx(math.radians(60))
    assert spec.pan_max_deg == 90 and spec.tilt_max_deg == 30.0
    assert CameraSpec.from_dict({}) == CameraSpec()
    with pytest.raises(CameraError, match="hfov_deg"):
        CameraSpec.from_dict({"hfov": 60})
    with pytest.raises(CameraError, match="whole number"):
        CameraSpec.from_dict({"width": 320.5})
    with pytest.raises(CameraError, match="number"):
        CameraSpec.from_dict({"noise_std": "high"})
    with pytest.raises(CameraError, match="zoom range"):
        CameraSpec.from_dict({"zoom_min": 5, "zoom_max": 2}, file="robot.yaml", line=3)
    with pytest.raises(CameraError, match="mapping"):
        CameraSpec.from_dict([1, 2])


def test_sign_plate_image_has_dark_text_on_a_light_plate():
    img = sign_plate_image("LAB 3", 600, 200)
    assert img.shape == (200, 600, 3) and img.dtype == np.uint8
    g = grey(img)
    assert g[0, 300] < 80 and g[100, 5] < 80  # border
    inner = g[25:175, 25:575]
    assert (inner > 200).mean() > 0.6 and (inner < 80).mean() > 0.05
    rows = np.flatnonzero((inner < 80).any(axis=1))
    height = (rows[-1] - rows[0] + 1) / 200
    assert 0.45 < height <= 0.65  # letters ~0.6 of the plate's height
    cols = np.flatnonzero((inner < 80).any(axis=0)) + 25
    assert abs((cols[0] + cols[-1]) / 2 - 300) < 10  # centred


# ---- plate styles ------------------------------------------------------------------------------
DARK_PLATE = {"plate": (30, 40, 90), "ink": (245, 245, 230)}  # RGB: light letters on navy


def ink_columns(img, plate_grey):
    """Columns holding letters (far from the plate's grey level) inside a 600 x 200 plate's
    10 px border and the 2 px next to it."""
    g = grey(img)[12:-12, 12:-12]
    return np.flatnonzero((np.abs(g - plate_grey) > 80).any(axis=0)) + 12


def test_the_default_style_is_the_explicit_one_and_the_old_look():
    img = sign_plate_image("LAB 3", 600, 200)
    explicit = sign_plate_image("LAB 3", 600, 200, plate=(238, 238, 238), ink=(15, 15, 15),
                                font="duplex", spacing=0.0)
    assert np.array_equal(img, explicit)
    assert img[0, 300].tolist() == [40, 40, 40]  # the dark grey border of old
    assert img[25, 300].tolist() == [238, 238, 238]  # the light plate


def test_a_light_on_dark_plate_has_light_letters_and_border_on_a_dark_plate():
    img = sign_plate_image("LAB 3", 600, 200, **DARK_PLATE)
    assert img[25, 300].tolist() == [90, 40, 30]  # BGR of the plate
    assert img[0, 300].tolist() == [205, 220, 220]  # the ink, 25 levels towards the plate
    inner = grey(img)[25:175, 25:575]
    assert (inner < 80).mean() > 0.6 and (inner > 200).mean() > 0.05  # light on dark
    rows = np.flatnonzero((inner > 200).any(axis=1))
    assert 0.45 < (rows[-1] - rows[0] + 1) / 200 <= 0.65  # letters ~0.6 of the height


def test_a_plate_is_drawn_in_its_own_colours():
    dark = dataclasses.replace(FRONT, **DARK_PLATE)
    world = room(-3, -3, 2, 3, [dark])
    tilt = look_at_tilt(2 - HALF)
    x0, y0, x1, y1 = visible_signs(world, (0, 0, 0), tilt, 1.0, SPEC)[0]["bbox"]
    region = grey(shot(world, (0, 0, 0), tilt))[y0 + 3:y1 - 2, x0 + 3:x1 - 2]
    assert (region < 80).mean() > 0.5 and (region > 180).mean() > 0.05


def test_each_font_draws_a_different_texture_that_stays_on_the_plate():
    textures = {font: sign_plate_image("NURSES STATION", 600, 200, font=font)
                for font in SIGN_FONTS}
    for i, a in enumerate(SIGN_FONTS):
        for b in SIGN_FONTS[i + 1:]:
            assert not np.array_equal(textures[a], textures[b]), (a, b)
    for font, img in textures.items():
        cols = ink_columns(img, 238)
        assert len(cols) > 300, font  # letters across the plate
        assert cols[0] > 12 and cols[-1] < 587, font  # none on or next to the border


def test_letter_spacing_spreads_short_texts_and_fits_long_ones():
    def extent(img):
        cols = ink_columns(img, 238)
        return cols[-1] - cols[0] + 1, cols

    plain, _ = extent(sign_plate_image("LAB 3", 600, 200))
    spaced, _ = extent(sign_plate_image("LAB 3", 600, 200, spacing=0.5))
    assert spaced > 1.3 * plain  # ~0.5 letter heights more in each of 4 gaps
    long_spaced, cols = extent(sign_plate_image("NURSES STATION", 600, 200, spacing=0.5))
    assert cols[0] > 12 and cols[-1] < 587  # fitted inside the border...
    letters = np.flatnonzero((grey(sign_plate_image("NURSES STATION", 600, 200, spacing=0.5))
                              [12:-12, 12:-12] < 100).any(axis=1))
    unspaced = np.flatnonzero((grey(sign_plate_image("NURSES STATION", 600, 200))
                               [12:-12, 12:-12] < 100).any(axis=1))
    assert len(letters) < 0.8 * len(unspaced)  # ... by smaller letters


def test_a_bad_plate_style_is_refused():
    with pytest.raises(ValueError, match="font"):
        sign_plate_image("LAB", font="gothic")
    with pytest.raises(ValueError, match="spacing"):
        sign_plate_image("LAB", spacing=-0.1)


def test_the_reader_reads_light_on_dark_and_simplex_plates_up_close():
    from blocks.signs.read import SignReader
    from semantic.vocabulary import load_vocabulary

    reader = SignReader(load_vocabulary())
    for sign in (Sign("LIBRARY", 2 - HALF, 0.0, math.pi, **DARK_PLATE),
                 Sign("OFFICE 102", 2 - HALF, 0.0, math.pi, font="simplex")):
        world = room(-3, -3, 2, 3, [sign])
        cam, tilt, zoom = (0.8, 0.0, 0.0), look_at_tilt(1.2 - HALF), 1.5  # plate ~60 px high
        truth = visible_signs(world, cam, tilt, zoom, SPEC)[0]
        reading = reader.read(shot(world, cam, tilt, zoom), corners=truth["corners"])
        assert reading.text == sign.text and reading.confidence > 0.75, (sign, reading)


# ---- object scale, light and cover ---------------------------------------------------------------
QUIET = CameraSpec(noise_std=0.0)
PRINTER_TILT = math.atan2(0.55 - SPEC.mount_z, 4.0)  # the printer (1.1 m high) 4 m ahead


def with_objects(*objects):
    world = room(-1, -4, 8, 4)
    world.objects = list(objects)
    return world


def test_an_object_at_scale_two_looks_twice_as_large():
    one = visible_objects(with_objects(WorldObject("Printer", 4.0, 0.0)), (0, 0, 0),
                          PRINTER_TILT, 1.0, SPEC)[0]
    two = visible_objects(with_objects(WorldObject("Printer", 4.0, 0.0, scale=2.0)), (0, 0, 0),
                          PRINTER_TILT, 1.0, SPEC)[0]
    assert two["apparent_width"] == pytest.approx(2 * one["apparent_width"], rel=1e-6)
    assert two["apparent_height"] == pytest.approx(2 * one["apparent_height"], rel=1e-6)
    assert two["corners"][2, 1] == pytest.approx(one["corners"][2, 1])  # both on the floor
    bare = with_objects()
    drawn = [extent(np.abs(grey(shot(w, (0, 0, 0), PRINTER_TILT, spec=QUIET))
                           - grey(shot(bare, (0, 0, 0), PRINTER_TILT, spec=QUIET))) > 10)
             for w in (with_objects(WorldObject("Printer", 4.0, 0.0)),
                       with_objects(WorldObject("Printer", 4.0, 0.0, scale=2.0)))]
    assert drawn[1] == pytest.approx(2 * drawn[0], rel=0.1)


def test_cover_hides_the_lower_half_behind_a_plain_box():
    open_world = with_objects(WorldObject("Printer", 4.0, 0.0))
    covered = with_objects(WorldObject("Printer", 4.0, 0.0, cover=0.5))
    full = visible_objects(open_world, (0, 0, 0), PRINTER_TILT, 1.0, SPEC)[0]
    half = visible_objects(covered, (0, 0, 0), PRINTER_TILT, 1.0, SPEC)[0]
    assert full["visible_fraction"] == pytest.approx(1.0)
    assert half["visible_fraction"] == pytest.approx(0.5, abs=0.02)
    x0, top, x1, bottom = full["bbox"]
    middle = (top + bottom) / 2
    assert half["bbox"][:3] == (x0, top, x1) and abs(half["bbox"][3] - middle) <= 1
    assert half["apparent_height"] == full["apparent_height"]  # the object is no smaller
    a = shot(open_world, (0, 0, 0), PRINTER_TILT, spec=QUIET).astype(int)
    b = shot(covered, (0, 0, 0), PRINTER_TILT, spec=QUIET).astype(int)
    upper = slice(top, round(middle) - 4)
    assert np.array_equal(a[upper], b[upper])  # the picture above the box is untouched
    lower = (slice(round(middle) + 3, bottom - 2), slice(x0 + 3, x1 - 2))
    assert grey(a.astype(np.uint8))[lower].std() > 20  # the picture's lower half...
    assert grey(b.astype(np.uint8))[lower].std() < 2  # ... is behind one plain colour
    assert np.abs(a[lower] - b[lower]).mean() > 20


def test_light_one_half_darkens_the_object_by_half():
    full = with_objects(WorldObject("Printer", 4.0, 0.0))
    dim = with_objects(WorldObject("Printer", 4.0, 0.0, light=0.5))
    x0, y0, x1, y1 = visible_objects(full, (0, 0, 0), PRINTER_TILT, 1.0, SPEC)[0]["bbox"]
    inside = (slice(y0 + 3, y1 - 2), slice(x0 + 3, x1 - 2))
    a = grey(shot(full, (0, 0, 0), PRINTER_TILT, spec=QUIET))[inside].astype(float)
    b = grey(shot(dim, (0, 0, 0), PRINTER_TILT, spec=QUIET))[inside].astype(float)
    bright = a > 60
    assert np.median(b[bright] / a[bright]) == pytest.approx(0.5, abs=0.03)


# ---- building colours ----------------------------------------------------------------------------
def test_world_colours_repaint_the_walls_and_nothing_else():
    plain = room(-1, -4, 8, 4)  # the front wall 8 m ahead: ceiling, wall and floor in view
    blue = room(-1, -4, 8, 4)
    blue.colours = {"wall": (40, 60, 200)}  # RGB
    a, b = (shot(w, (0, 0, 0), spec=QUIET).astype(int) for w in (plain, blue))
    wall = (slice(60, 120), slice(100, 220))
    assert (a[wall][..., 2] > a[wall][..., 0] + 20).all()  # beige: more red than blue
    assert (b[wall][..., 0] > b[wall][..., 2] + 80).all()  # blue (the image is BGR)
    assert np.array_equal(a[:15], b[:15]) and np.array_equal(a[-60:], b[-60:])  # ceiling, floor
    brown = room(-1, -4, 8, 4)
    brown.colours = {"floor": (150, 100, 40)}
    c = shot(brown, (0, 0, 0), spec=QUIET).astype(int)
    assert (c[-60:][..., 2] > c[-60:][..., 0] + 40).all() and np.array_equal(a[wall], c[wall])


# ---- the renderer: many frames, the plain functions' results ------------------------------------
def _same_report(a, b):
    """Ground-truth lists equal to the bit (ndarrays by value and dtype)."""
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert x.keys() == y.keys()
        for key in x:
            if isinstance(x[key], np.ndarray):
                assert x[key].dtype == y[key].dtype and np.array_equal(x[key], y[key])
            else:
                assert type(x[key]) is type(y[key]) and x[key] == y[key]


def _busy_room():
    """Signs on three walls, objects (scaled, dimmed, covered), a post and building colours."""
    world = room(-1, -4, 8, 4, signs=[
        FRONT, Sign("LAB", 8 - HALF, 1.5, math.pi, font="complex", plate=(40, 60, 200)),
        Sign("OFFICE 7", 3.0, 4 - HALF, -math.pi / 2, spacing=0.2),
        Sign("BEHIND", 3.0, -4 + HALF, -math.pi / 2)],  # faces away from the room
        extra=[[5.0, -1.0, 5.0, -1.0]])  # a post
    world.objects = [WorldObject("Printer", 4.0, 0.0), WorldObject("Printer", 6.5, 2.0, scale=1.5),
                     WorldObject("Printer", 6.0, -2.5, light=0.5, cover=0.4)]
    world.colours = {"wall": (200, 190, 170), "floor": (90, 80, 70)}
    return world


@pytest.mark.parametrize("spec", [SPEC, dataclasses.replace(SPEC, noise_std=0.0, width=161,
                                                              height=97, mount_z=0.05)],
                         ids=["default", "quiet-small-low"])
def test_a_renderer_gives_the_plain_functions_results_frame_after_frame(spec):
    """One renderer's frames (its tables kept across tilt and zoom changes and back) are the
    images and ground truth of fresh render, visible_signs and visible_objects calls."""
    world = _busy_room()
    renderer = CameraRenderer(world, spec)
    walk = [((0.0, 0.0, 0.0), 0.0, 1.0), ((0.5, 0.3, 0.2), 0.0, 1.0),
            ((1.0, -0.5, -0.3), 0.2, 1.0), ((1.0, -0.5, 0.6), 0.2, 2.5),
            ((2.0, 1.0, 1.4), -0.4, 1.0), ((2.0, 1.0, -1.2), 0.0, 1.0),
            ((3.0, 0.0, math.pi), 0.1, 1.3), ((3.0, 0.5, math.pi / 2), 0.3, 1.0),
            ((6.0, 1.0, -0.5), 0.6, 6.0)]
    seen = set()
    for i, (pose, tilt, zoom) in enumerate(walk):
        frame = renderer.frame(pose, tilt, zoom, np.random.default_rng(i))
        image = render(world, pose, tilt, zoom, spec, np.random.default_rng(i))
        assert frame.image.dtype == np.uint8 and np.array_equal(frame.image, image)
        _same_report(frame.signs, visible_signs(world, pose, tilt, zoom, spec))
        _same_report(frame.objects, visible_objects(world, pose, tilt, zoom, spec))
        assert np.array_equal(renderer.render(pose, tilt, zoom, np.random.default_rng(i)), image)
        seen |= {s["text"] for s in frame.signs} | {o["index"] for o in frame.objects}
    assert "BEHIND" not in seen
    if spec is SPEC:  # the walk shows every plate that faces the room and every object
        assert {"ROOM 101", "LAB", "OFFICE 7", 0, 1, 2} <= seen


@settings(max_examples=40, deadline=None)
@given(corners=st.lists(st.tuples(coord, coord), min_size=2, max_size=10),
       radius=st.sampled_from([0.0, 0.05, 0.1]), closed=st.booleans(),
       posts=st.lists(st.integers(0, 9), max_size=3),
       origin=st.tuples(coord, coord), yaw=st.floats(-math.pi, math.pi),
       zoom=st.floats(0.3, 10.0))
def test_indexed_walls_cast_as_cast_rays_does(corners, radius, closed, posts, origin, yaw, zoom):
    """Walls indexed once (shared ends found for all segments, counted per cast among the
    ones the wedge keeps) cast bit for bit as cast_rays, for chained walls, posts on their
    corners and wedges from one ray to a full turn."""
    points = np.round(np.array(corners), 2)  # chains share their ends exactly
    chain = np.column_stack([points[:-1], points[1:]])
    if closed:
        chain = np.vstack([chain, np.concatenate([points[-1], points[0]])])
    segments = np.vstack([np.column_stack([chain, np.full(len(chain), radius)]),
                          np.array([[*points[i % len(points)]] * 2 + [0.1]
                                    for i in posts]).reshape(-1, 5)])
    walls = Walls(segments)
    corner = np.arctan2(points[:, 1] - origin[1], points[:, 0] - origin[0])  # where ends differ
    for angles in (np.array([yaw]), yaw + np.arctan2(159.5 - np.arange(320), 360 * zoom),
                   np.linspace(yaw, yaw + 2 * math.pi, 50),
                   *(np.array([a]) for a in np.concatenate([corner - 0.01, corner + 0.01]))):
        want = cast_rays(origin, angles, segments)
        got = walls.cast(origin, angles)
        assert all(g.dtype == w.dtype and np.array_equal(g, w) for g, w in zip(got, want))


def test_opencv_draws_the_same_normals_for_one_channel_as_for_three():
    """The camera noise is drawn as one channel (faster in OpenCV): the values must be those
    a three-channel draw with the same seed, mean and deviation gives, in memory order."""
    three = np.empty((24, 32, 3), np.float32)
    one = np.empty((24, 32 * 3), np.float32)
    for seed in (1, 12345, 2**31 - 2):
        cv2.setRNGSeed(seed)
        cv2.randn(three, (0.0, 0.0, 0.0), (3.0, 3.0, 3.0))
        cv2.setRNGSeed(seed)
        cv2.randn(one, 0.0, 3.0)
        assert np.array_equal(three.reshape(24, -1), one)


@pytest.mark.parametrize("sigma", [0.6, 1.2, math.sqrt(2.0 ** 2 - 0.25) / 2,
                                   math.sqrt(3.0 ** 2 - 0.25) / 2])
def test_the_blur_is_opencvs_gaussian_blur_pixel_for_pixel(sigma):
    """The camera's blurs (full and half resolution) call the separable filter GaussianBlur
    is made of; it must give GaussianBlur's pixels, borders included."""
    image = np.random.default_rng(3).uniform(0, 255, (60, 81, 3)).astype(np.float32)
    want = cv2.GaussianBlur(image, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    assert np.array_equal(_gaussian_blur(image, sigma), want)


def whole_frame_depth_blur(img: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """The depth blur as it was before it was boxed: every level blurred over the whole
    frame and blended over the whole frame (the reference for the boxed one)."""
    f32 = np.float32
    sigma = np.minimum(sigma, f32(BLUR_LEVELS[-1]))
    top = next((k for k, level in enumerate(BLUR_LEVELS) if level >= float(sigma.max())),
               len(BLUR_LEVELS) - 1)
    out, half = img, None
    for k in range(1, top + 1):
        level, lo = BLUR_LEVELS[k], BLUR_LEVELS[k - 1]
        if level >= 1.6:
            if half is None:
                half = cv2.resize(img, (img.shape[1] // 2, img.shape[0] // 2),
                                  interpolation=cv2.INTER_AREA)
            small = _gaussian_blur(half, math.sqrt(level ** 2 - 0.25) / 2)
            blurred = cv2.resize(small, (img.shape[1], img.shape[0]),
                                 interpolation=cv2.INTER_LINEAR)
        else:
            blurred = _gaussian_blur(img, level)
        frac = np.clip((sigma - f32(lo)) * f32(1.0 / (level - lo)), 0, 1)
        out = cv2.blendLinear(out, blurred, f32(1) - frac, frac)
    return out


def sigma_field(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """A camera-like sigma map (px): small near the frame's edges, a far band round a random
    horizon, a far box (a distant wall), and random spikes."""
    rows = np.arange(height, dtype=np.float32)[:, None]
    horizon = rng.uniform(0, height)
    sigma = np.broadcast_to(0.05 + 40 / (1 + np.abs(rows - horizon)) ** 1.5 * rng.uniform(0, 1),
                            (height, width)).astype(np.float32).copy()
    r0, c0 = rng.integers(0, height), rng.integers(0, width)
    sigma[r0:r0 + rng.integers(1, height), c0:c0 + rng.integers(1, width)] = rng.uniform(0, 3.5)
    sigma *= np.float32(rng.choice([0.01, 0.1, 0.3, 0.6, 1.0]))  # frames up to every level
    for _ in range(rng.integers(0, 4)):
        sigma[rng.integers(0, height), rng.integers(0, width)] = rng.uniform(0, 4)
    return sigma


@pytest.mark.parametrize("size", [(240, 320), (64, 96), (60, 81), (61, 64)])
def test_the_boxed_depth_blur_is_the_whole_frame_one_to_the_bit(size):
    """Each blur level runs only on the box of pixels that blend it in (plus its kernel's
    margin): the image must be the whole-frame blur's, bit for bit, wherever the boxes fall
    (at the frame's edges, inside it, one pixel wide), and with frames too odd to box."""
    rng = np.random.default_rng(11)
    height, width = size
    canvas = _Canvas(height, width)
    levels_seen = set()
    for trial in range(60):
        img = rng.uniform(0, 255, (height, width, 3)).astype(np.float32)
        sigma = sigma_field(rng, height, width)
        want = whole_frame_depth_blur(img, sigma)
        boxes, boxed = _blur_boxes(np.minimum(sigma, np.float32(BLUR_LEVELS[-1])))
        levels_seen.add(len(boxes))
        np.copyto(canvas.img, img)
        got = _depth_blur(canvas.img, sigma.copy(), canvas)
        assert np.array_equal(got, want), (trial, boxes)
        assert boxed == (size in [(240, 320), (64, 96)])
    assert levels_seen >= {1, 2, 3, 4}  # every level was blended, boxed or not


def test_blur_boxes_hold_every_pixel_that_blends_each_level():
    """A level's box holds every pixel whose sigma passes the level below, and no row or
    column (before the alignment) without one."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        sigma = np.minimum(sigma_field(rng, 240, 320), np.float32(BLUR_LEVELS[-1]))
        boxes, boxed = _blur_boxes(sigma)
        assert boxed and boxes[0] == (0, 240, 0, 320)
        for k, (r0, r1, c0, c1) in enumerate(boxes[1:], start=2):
            passing = sigma > BLUR_LEVELS[k - 1]
            inside = np.zeros_like(passing)
            inside[r0:r1, c0:c1] = True
            assert not (passing & ~inside).any()
            rows = np.flatnonzero(passing.any(axis=1))
            assert (r0, r1) == (rows[0], rows[-1] + 1)
            assert c0 % 16 == 0 and (c1 % 16 == 0 or c1 == 320)


def test_angle_span_is_the_wrapped_extremes_of_any_rays():
    """The wedge of a cast is the least and greatest ray angle relative to the first,
    wrapped by np.angle(np.exp(1j * a)); for sorted rays only the ends are wrapped, which
    must give the same two floats as wrapping them all, and any other rays wrap them all."""
    rng = np.random.default_rng(7)

    def wrapped_all(angles):
        rel = np.angle(np.exp(1j * (angles - angles[0])))
        return float(rel.min()), float(rel.max())

    for _ in range(3000):
        f = focal_length(SPEC, rng.uniform(1.0, 10.0))
        columns = rng.uniform(-50, 50) + np.arctan2(159.5 - np.arange(320.0), f)
        shuffled = rng.permutation(columns)
        wide = rng.uniform(-7, 7) + np.sort(rng.uniform(0, rng.uniform(0.1, 7), 50))
        for angles in (columns, columns[::-1], shuffled, wide, columns[:1], columns[:2]):
            assert _angle_span(angles) == wrapped_all(angles)


# ---- the renderer's shortcuts: the same numbers as the plain ways -----------------------------
@settings(max_examples=60, deadline=None)
@given(corners=st.lists(st.tuples(coord, coord), min_size=2, max_size=8),
       radius=st.sampled_from([0.0, 0.025, 0.1]), closed=st.booleans(),
       origin=st.tuples(coord, coord), indexed=st.booleans())
def test_walls_with_a_face_each_take_the_short_way_to_the_same_numbers(corners, radius, closed,
                                                                       origin, indexed):
    """Casts over walls that all have a length skip the masks posts need (inverse lengths,
    shared ends, caps): the short way must give the numbers of the long one."""
    points = np.round(np.array(corners), 2)
    chain = np.column_stack([points[:-1], points[1:]])
    if closed:
        chain = np.vstack([chain, np.concatenate([points[-1], points[0]])])
    segments = np.column_stack([chain, np.full(len(chain), radius)])
    walls = Walls(segments, index=indexed)
    rel = walls._rows[:4] - np.array(origin * 2)[:, None]
    length = np.hypot(*(rel[2:4] - rel[0:2]))
    if not length.min() > 1e-9:
        return  # a chain through one point twice: a wall without a face
    inv_len, has_length = _inverse_lengths(length)
    assert has_length is None
    assert np.array_equal(inv_len, np.where(length > 1e-9, 1.0 / length, 0.0))
    short = _shared_ends(rel, walls._rows[4], None, walls._ends, walls._indexed)
    long = _shared_ends(rel, walls._rows[4], np.ones(len(segments), bool), walls._ends,
                        walls._indexed)
    assert all(a.dtype == b.dtype and np.array_equal(a, b) for a, b in zip(short, long))


def test_shared_ends_are_found_among_the_kept_walls_alone():
    """Two walls meeting at a corner share it (no caps there); alone, each has two caps."""
    segments = np.array([[0.0, 0.0, 2.0, 0.0, 0.1], [2.0, 0.0, 2.0, 2.0, 0.1]])
    for indexed in (True, False):
        walls = Walls(segments, index=indexed)
        rel = walls._rows[:4] - np.array([[-1.0], [1.0], [-1.0], [1.0]])
        shared, caps_xy, caps_r = _shared_ends(rel, walls._rows[4], None, walls._ends,
                                               walls._indexed)
        assert shared.tolist() == [[False, True], [True, False]]
        assert caps_xy.T.tolist() == [[1.0, -1.0], [3.0, 1.0]] and caps_r.tolist() == [0.1, 0.1]
        one = _shared_ends(rel[:, :1], walls._rows[4][:1], None, walls._ends[:, :1],
                           walls._indexed)
        assert not one[0].any() and len(one[2]) == 2
    assert len(set(_end_keys(segments).tolist())) == 3


@settings(max_examples=80, deadline=None)
@given(points=st.lists(st.tuples(coord, coord, st.floats(0, 2.5)), min_size=1, max_size=6),
       pose=st.tuples(coord, coord, st.floats(-7, 7)), tilt=st.floats(-0.5, 0.5),
       zoom=st.floats(1.0, 10.0))
def test_a_shot_projects_as_project_points_does(points, pose, tilt, zoom):
    """The views project with the lens's intrinsics, and the centres' depth in plain
    floats: the numbers of project_points, to the bit."""
    pts = np.array(points, dtype=np.float64)
    shot_ = _Shot(pose, tilt, zoom, _Lens.of(SPEC, tilt, zoom), np.zeros(0), np.zeros(0))
    want = project_points(pts, pose, tilt, zoom, SPEC)
    got = _project(pts, shot_, SPEC.mount_z)
    assert all(np.array_equal(g, w) for g, w in zip(got, want))
    for (x, y, _), depth in zip(points, want[2]):
        assert _forward_depth(x, y, pose) == depth


def test_a_quad_is_off_the_image_only_wholly_beside_above_or_below_it():
    u, v = np.array([10.0, 20.0, 20.0, 10.0]), np.array([5.0, 5.0, 30.0, 30.0])
    assert not _off_image(u, v, 320, 240)
    assert _off_image(u - 31, v, 320, 240) and _off_image(u + 311, v, 320, 240)
    assert _off_image(u, v - 31, 320, 240) and _off_image(u, v + 235, 320, 240)
    assert not _off_image(u - 20.4, v, 320, 240) and not _off_image(u, v + 234, 320, 240)


def _warp_texture_by_broadcasting(img, depth, levels, corners, columns, shade, depth_value,
                                  spec):
    """The texture warp as it was, alpha broadcast over the channels (the reference)."""
    corners = corners.astype(np.float64)
    edge = max(np.hypot(*(corners[1] - corners[0])), np.hypot(*(corners[2] - corners[3])))
    tex = levels[0]
    for level in levels:
        if level.shape[1] >= 1.5 * edge:
            tex = level
    th, tw = tex.shape[:2]
    src = np.array([[-0.5, -0.5], [tw - 0.5, -0.5], [tw - 0.5, th - 0.5], [-0.5, th - 0.5]],
                   dtype=np.float32)
    M = cv2.getPerspectiveTransform(src, corners.astype(np.float32))
    x0 = max(0, math.floor(corners[:, 0].min()) - 1)
    x1 = min(spec.width, math.ceil(corners[:, 0].max()) + 2)
    y0 = max(0, math.floor(corners[:, 1].min()) - 1)
    y1 = min(spec.height, math.ceil(corners[:, 1].max()) + 2)
    if x1 <= x0 or y1 <= y0:
        return
    M = np.array([[1, 0, -x0], [0, 1, -y0], [0, 0, 1]], dtype=np.float64) @ M
    size = (x1 - x0, y1 - y0)
    plate = cv2.warpPerspective(tex, M, size, flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0))
    mask = cv2.warpPerspective(np.full((th, tw), 255, np.uint8), M, size,
                               flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                               borderValue=0)
    alpha = mask.astype(np.float32) / 255.0 * columns[None, x0:x1]
    region = img[y0:y1, x0:x1]
    a = alpha[..., None]
    region *= 1.0 - a
    shaded = np.multiply(a, plate)
    shaded *= np.float32(shade)
    region += shaded
    depth[y0:y1, x0:x1] = np.where(alpha > 0.5, np.float32(depth_value), depth[y0:y1, x0:x1])


def test_textures_warp_as_with_alpha_broadcast_over_the_channels():
    """Plates and pictures are blended with alpha spread to three channels first (faster
    loops): the image and depth must be those of alpha broadcast, to the bit."""
    rng = np.random.default_rng(4)
    levels = (rng.integers(0, 256, (200, 600, 3), dtype=np.uint8),
              rng.integers(0, 256, (100, 300, 3), dtype=np.uint8))
    for _ in range(40):
        centre = rng.uniform(-40, 360, 2)
        corners = centre + rng.uniform(-1, 1, (4, 2)) * rng.uniform(2, 150) + \
            np.array([[-60, -20], [60, -20], [60, 20], [-60, 20]]) * rng.uniform(0.05, 2)
        columns = rng.random(SPEC.width) < 0.8
        img = rng.uniform(0, 255, (SPEC.height, SPEC.width, 3)).astype(np.float32)
        depth = rng.uniform(0, 20, (SPEC.height, SPEC.width)).astype(np.float32)
        want_img, want_depth = img.copy(), depth.copy()
        _warp_texture_by_broadcasting(want_img, want_depth, levels, corners, columns, 0.7,
                                      3.5, SPEC)
        _warp_texture(img, depth, levels, corners, columns, 0.7, 3.5, SPEC)
        assert np.array_equal(img, want_img) and np.array_equal(depth, want_depth)
