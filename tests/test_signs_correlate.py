"""Sign geometry (plate pose from its image quad) and correlation (merging, outputs, score)."""
from __future__ import annotations

import json
import dataclasses
import math

import cv2
import numpy as np
import pytest

from blocks.maps.mapio import OccupancyMap
from blocks.signs.correlate import (
    Sighting,
    SignMap,
    draw_hybrid_map,
    normalise_text,
    score_signs,
    sighting_from_capture,
    write_signs_json,
)
from blocks.signs.geometry import (
    camera_pose_of,
    compose,
    estimate_plate,
    plate_in_camera,
    plate_in_world,
    relative,
    wrap,
)
from blocks.signs.types import CameraModel, Capture, PlateDetection, Reading
from sim2d.camera import CameraSpec, camera_pose, render, visible_signs
from sim2d.world import Sign, load_world, make_world

SPEC = CameraSpec()
PLATE = Sign("TEST", 2.0, 1.0, math.radians(70))
LONE = make_world([], signs=[PLATE])


def _inside(c: np.ndarray, margin: float = 1.0) -> bool:
    return bool(c[:, 0].min() >= margin and c[:, 0].max() <= SPEC.width - 1 - margin
                and c[:, 1].min() >= margin and c[:, 1].max() <= SPEC.height - 1 - margin)


def _views(n: int, seed: int, max_distance: float = 4.0):
    """``n`` random whole views of PLATE: (robot pose, pan, tilt, zoom, corners, distance)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        d = rng.uniform(0.8, max_distance)
        angle = math.radians(rng.uniform(-65, 65))
        zoom, tilt = rng.uniform(1, 4), math.radians(rng.uniform(0, 25))
        pan = rng.uniform(-1.5, 1.5)
        # put the camera at distance d, angle off the normal; aim it near the plate
        ang = PLATE.facing + angle
        cx, cy = PLATE.x + d * math.cos(ang), PLATE.y + d * math.sin(ang)
        yaw = ang + math.pi + rng.uniform(-0.4, 0.4) * SPEC.hfov / zoom
        theta = yaw - pan
        robot = (cx - math.cos(theta) * SPEC.mount_x, cy - math.sin(theta) * SPEC.mount_x, theta)
        cam = camera_pose(robot, SPEC, pan)
        seen = visible_signs(LONE, cam, tilt, zoom, SPEC)
        if seen and _inside(seen[0]["corners"]):
            out.append((robot, pan, tilt, zoom, seen[0]["corners"], d))
    return out


def _errors(est, sign: Sign) -> tuple[float, float]:
    return (math.hypot(est[0] - sign.x, est[1] - sign.y),
            abs(math.degrees(wrap(est[2] - sign.facing))))


# ---- geometry ----------------------------------------------------------------------------
def test_camera_pose_of_matches_sim2d():
    spec = CameraSpec(mount_x=0.2, mount_y=-0.07)
    for robot, pan in [((0, 0, 0), 0.0), ((1.5, -2.0, 2.5), -0.9), ((3, 4, -3.0), 2.9)]:
        got = camera_pose_of(robot, spec.mount_x, spec.mount_y, pan)
        assert got == pytest.approx(camera_pose(robot, spec, pan), abs=1e-12)


def test_compose_and_relative_are_inverse():
    pose, world = (1.0, -2.0, 2.8), (3.0, 0.5, -2.9)
    assert compose(pose, relative(pose, world)) == pytest.approx(world, abs=1e-12)


@pytest.mark.parametrize("plate_width", [0.6, None], ids=["width-fit", "edges"])
def test_plate_in_world_recovers_sim2d_plates(plate_width):
    """Noise-free corners at many pans, zooms 1-4, tilts 0-25 deg, 0.8-4 m, 0-65 deg off-axis."""
    for robot, pan, tilt, zoom, corners, _ in _views(120, seed=1):
        camera = CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt)
        cam = camera_pose_of(robot, SPEC.mount_x, SPEC.mount_y, pan)
        est = plate_in_world(corners, camera, cam, plate_width=plate_width)
        assert est is not None
        pos, facing = _errors(est, PLATE)
        assert pos < 0.02 and facing < 2.0, (robot, pan, tilt, zoom, est)


def test_plate_in_world_with_one_pixel_noise():
    rng = np.random.default_rng(7)
    pos_err, facing_err = [], []
    for robot, pan, tilt, zoom, corners, d in _views(150, seed=2, max_distance=3.0):
        camera = CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt)
        cam = camera_pose_of(robot, SPEC.mount_x, SPEC.mount_y, pan)
        est = plate_in_world(corners + rng.uniform(-1, 1, (4, 2)), camera, cam)
        assert est is not None
        pos, facing = _errors(est, PLATE)
        pos_err.append(pos)
        facing_err.append(facing)
    assert max(pos_err) < 0.3
    assert np.median(pos_err) < 0.05
    assert np.median(facing_err) < 3.0 and np.percentile(facing_err, 90) < 10.0


def test_plate_facing_points_back_at_the_camera():
    camera = CameraModel.of(320, 240, math.radians(48), 1.0)
    # a plate 2 m ahead, turned so its left edge is nearer: the normal points right-back
    sign = Sign("X", 2.0, 0.0, math.radians(180 - 30))
    seen = visible_signs(make_world([], signs=[sign]), (0.0, 0.0, 0.0), 0.0, 1.0,
                         CameraSpec())
    x, y, facing = plate_in_camera(seen[0]["corners"], camera)
    assert (x, y) == pytest.approx((2.0, 0.0), abs=1e-6)
    assert math.degrees(facing) == pytest.approx(150.0, abs=1e-4)


def _clip_to_image(c: np.ndarray) -> np.ndarray:
    """The quad cut at the image's side borders, as a detector would report it."""
    c = c.copy()
    for a, b in ((0, 1), (3, 2)):  # top and bottom edges
        for lim, out in ((0.0, lambda u: u < 0), (SPEC.width - 1.0, lambda u: u > SPEC.width - 1)):
            for i, j in ((a, b), (b, a)):
                if out(c[i, 0]):
                    t = (lim - c[j, 0]) / (c[i, 0] - c[j, 0])
                    c[i] = c[j] + t * (c[i] - c[j])
    return c


def _model_on_arrays(p, camera, plate_height, plate_width):
    """The width fit's model as array expressions over both edges (sgn = [1, -1])."""
    x, y, phi = (float(v) for v in p)
    f, half = camera.f, plate_width / 2
    lx, ly = math.sin(phi) * half, -math.cos(phi) * half
    dlx, dly = math.cos(phi) * half, math.sin(phi) * half
    sgn = np.array([1.0, -1.0])
    ex = np.maximum(x + sgn * lx, 1e-3)
    ey = y + sgn * ly
    pred = np.concatenate([camera.cx - f * ey / ex, f * plate_height / ex])
    du_dex, du_dey, dh_dex = f * ey / ex ** 2, -f / ex, -f * plate_height / ex ** 2
    jac = np.empty((4, 3))
    jac[:2, 0], jac[:2, 1] = du_dex, du_dey
    jac[:2, 2] = sgn * (du_dex * dlx + du_dey * dly)
    jac[2:, 0], jac[2:, 1] = dh_dex, 0.0
    jac[2:, 2] = sgn * dh_dex * dlx
    return pred, jac


def test_width_fit_model_is_the_array_model_bit_for_bit_and_its_jacobian_is_right():
    from blocks.signs.geometry import _model
    rng = np.random.default_rng(8)
    for k in range(3000):
        camera = CameraModel.of(640, 480, math.radians(60), rng.uniform(1.0, 8.0),
                                rng.uniform(-0.3, 0.3))
        p = np.array([rng.uniform(-0.5, 8.0), rng.uniform(-4.0, 4.0), rng.uniform(-7.0, 7.0)])
        if k % 5 == 0:
            p[0] = rng.choice([0.0, 1e-3, -0.1])  # the clamp at 1 mm in front
        pred, jac = _model(p, camera, 0.2, 0.3)
        want_pred, want_jac = _model_on_arrays(p, camera, 0.2, 0.3)
        assert pred.tobytes() == want_pred.tobytes() and jac.tobytes() == want_jac.tobytes(), p
    camera, p, eps = CameraModel.of(640, 480, math.radians(60), 2.0), np.array([3.0, 0.4, 2.8]), 1e-6
    _, jac = _model(p, camera, 0.2, 0.3)
    for i in range(3):
        dp = np.zeros(3)
        dp[i] = eps
        numeric = (_model(p + dp, camera, 0.2, 0.3)[0] - _model(p - dp, camera, 0.2, 0.3)[0]) / (2 * eps)
        assert np.allclose(jac[:, i], numeric, rtol=1e-5, atol=1e-4), i


def test_clipped_plate_is_placed_from_its_whole_edge():
    camera = CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, 1.5, 0.1)
    sign = Sign("X", 2.5, 0.3, math.radians(160))
    world = make_world([], signs=[sign])
    for yaw in (0.40, -0.16):  # the plate cut by the right, then the left border
        seen = visible_signs(world, (0.0, 0.0, yaw), 0.1, 1.5, SPEC)
        corners = seen[0]["corners"]
        assert corners[:, 0].min() < 0 or corners[:, 0].max() > SPEC.width - 1
        cut = _clip_to_image(corners)
        est = estimate_plate(cut, camera, clipped=True)
        assert est is not None and est.method == "clipped"
        want = relative((0.0, 0.0, yaw), (sign.x, sign.y, sign.facing))
        assert (est.x, est.y) == pytest.approx(want[:2], abs=0.01)
        assert math.degrees(wrap(est.facing - want[2])) == pytest.approx(0, abs=1.0)
        # taken as whole, the cut quad would put the plate elsewhere
        naive = estimate_plate(cut, camera, clipped=False, plate_width=None)
        assert math.hypot(naive.x - want[0], naive.y - want[1]) > 0.1
    # no place for a plate cut at the top, or by both sides, or without its width
    quad = np.array([[100, 0.0], [200, 0.0], [200, 40], [100, 40]])
    assert estimate_plate(quad, camera, clipped=True) is None
    assert estimate_plate(np.array([[0, 50], [319, 50], [319, 90], [0, 90.0]]), camera,
                          clipped=True) is None
    assert estimate_plate(cut, camera, clipped=True, plate_width=None) is None


def test_degenerate_quads_give_none():
    camera = CameraModel.of(320, 240, math.radians(48), 1.0)
    flat = np.array([[100, 50], [150, 50], [150, 50.5], [100, 50.5]])
    assert plate_in_camera(flat, camera) is None
    assert plate_in_camera(np.full((4, 2), np.nan), camera) is None


def test_uncertainty_grows_with_distance():
    sigmas = []
    for d in (1.0, 2.0, 4.0):
        tilt = math.atan2(0.6, d)
        seen = visible_signs(make_world([], signs=[Sign("X", d, 0.0, math.pi)]), (0, 0, 0),
                             tilt, 1.0, SPEC)
        camera = CameraModel.of(320, 240, math.radians(48), 1.0, tilt)
        est = estimate_plate(seen[0]["corners"], camera, sigma_px=1.0)
        sigmas.append(est.sigma_xy)
    assert all(np.isfinite(sigmas)) and sigmas[0] < sigmas[1] < sigmas[2]
    assert 0.001 < sigmas[0] < 0.05 and sigmas[2] < 0.5


# ---- from a capture to the map -------------------------------------------------------------
def test_correlation_places_a_read_sign_within_0_3_m():
    """The issue's acceptance test: a sign seen from a known pose lands within 0.3 m."""
    world = load_world("sim2d/worlds/office.yaml")
    mail = next(s for s in world.signs if s.text == "MAIL ROOM")
    rng = np.random.default_rng(3)
    smap = SignMap()
    views = [((0.9, 5.7, 0.0), 1.5), ((3.9, 5.7, 0.0), 2.0), ((2.2, 6.6, 0.0), 1.5),
             ((2.0, 6.3, -1.0), 1.0)]  # oblique from both sides, head-on, turned
    for tick, (robot, zoom) in enumerate(views):
        robot = np.array(robot)
        ax, ay, _ = camera_pose(robot, SPEC, 0.0)
        pan = math.atan2(mail.y - ay, mail.x - ax) - robot[2]  # aim the head at the plate
        tilt = math.atan2(mail.z - SPEC.mount_z, math.hypot(mail.x - ax, mail.y - ay))
        cam = camera_pose(robot, SPEC, pan)
        seen = [v for v in visible_signs(world, cam, tilt, zoom, SPEC) if v["text"] == "MAIL ROOM"]
        assert seen and _inside(seen[0]["corners"])
        corners = seen[0]["corners"] + rng.uniform(-1, 1, (4, 2))
        det = PlateDetection(corners=corners, bbox=seen[0]["bbox"], bearing=0.0, range=0.0,
                             score=1.0)
        capture = Capture(image=render(world, cam, tilt, zoom, SPEC, rng), detection=det,
                          camera=CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt),
                          robot_pose=robot, pan=pan, tilt=tilt, zoom=zoom, tick=tick,
                          time=tick * 0.1)
        s = sighting_from_capture(capture, Reading("MAIL R00M", "MAIL ROOM", 0.8 + 0.05 * tick),
                                  mount=(SPEC.mount_x, SPEC.mount_y))
        assert math.hypot(s.x - mail.x, s.y - mail.y) < 0.3
        smap.add(s)
    (sign,) = smap.signs()
    assert sign["text"] == "MAIL ROOM" and sign["sightings"] == 4
    assert math.hypot(sign["x"] - mail.x, sign["y"] - mail.y) < 0.3
    assert sign["facing"] == pytest.approx(90.0, abs=10.0)


def _capture_of(world, sign, robot, zoom=1.0, tick=0):
    """A capture of ``sign`` from ``robot`` with the head aimed at it (exact corners)."""
    robot = np.asarray(robot, dtype=np.float64)
    ax, ay, _ = camera_pose(robot, SPEC, 0.0)
    pan = math.atan2(sign.y - ay, sign.x - ax) - robot[2]
    tilt = math.atan2(sign.z - SPEC.mount_z, math.hypot(sign.x - ax, sign.y - ay))
    cam = camera_pose(robot, SPEC, pan)
    (seen,) = [v for v in visible_signs(world, cam, tilt, zoom, SPEC) if v["text"] == sign.text]
    det = PlateDetection(corners=seen["corners"], bbox=seen["bbox"], bearing=0.0, range=0.0,
                         score=1.0)
    return Capture(image=np.zeros((SPEC.height, SPEC.width, 3), np.uint8), detection=det,
                   camera=CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt),
                   robot_pose=robot, pan=pan, tilt=tilt, zoom=zoom, tick=tick, time=tick * 0.1)


def _wall_map(y_wall: float, gap: tuple[float, float] | None = None) -> OccupancyMap:
    """Free floor y < y_wall, a wall 0.1 m thick above it (a door in it at x in ``gap``)."""
    res = 0.025
    h, w = int(6 / res), int(10 / res)
    yc = (np.arange(h) + 0.5) * res
    xc = (np.arange(w) + 0.5) * res
    p = np.zeros((h, w))
    wall = (yc[:, None] >= y_wall) & (yc[:, None] < y_wall + 0.1)
    if gap is not None:
        wall = wall & ~((xc[None, :] > gap[0]) & (xc[None, :] < gap[1]))
    p[wall & np.ones((1, w), bool)] = 1.0
    p[yc > y_wall + 0.1] = np.nan
    return OccupancyMap(p, res, (0.0, 0.0, 0.0))


@pytest.mark.parametrize("size", [0.45, 1.0, 1.8])
def test_a_plate_of_unknown_size_is_placed_where_its_ray_meets_the_wall(size):
    """The image alone places a plate k times the standard size k times too near or far;
    the wall on the robot's map does not care about its size."""
    sign = Sign("LAB 3", 5.0, 3.0, -math.pi / 2, width=0.6 * size, height=0.2 * size, z=1.3)
    world = make_world([[0.0, 3.0, 10.0, 3.0]], signs=[sign])
    smap = SignMap()
    for tick, robot in enumerate(((3.5, 1.2, 0.3), (5.6, 1.5, 1.2))):
        s = sighting_from_capture(_capture_of(world, sign, robot, tick=tick),
                                  Reading("LAB 3", "LAB 3", 0.9),
                                  mount=(SPEC.mount_x, SPEC.mount_y))
        assert math.hypot(s.x - sign.x, s.y - sign.y) == pytest.approx(
            abs(size - 1) / size * math.hypot(*(np.array(robot[:2]) - (sign.x, sign.y))), abs=0.2)
        smap.add(s)
    assert smap.place_on_walls(_wall_map(3.0)) == 2
    (placed,) = smap.signs()
    assert placed["sightings"] == 2
    assert math.hypot(placed["x"] - sign.x, placed["y"] - sign.y) < 0.1  # the band's middle
    assert [s.scale for s in smap.sightings] == pytest.approx([size] * 2, rel=0.06)
    # where the map has no wall within reason (a door the ray passes), the standard size stays
    smap.place_on_walls(_wall_map(3.0, gap=(0.0, 10.0)))
    assert [s.scale for s in smap.sightings] == [1.0, 1.0]


def test_the_size_the_seeker_measured_places_the_plate_until_a_wall_does():
    """A capture carries the size the views on the way measured: the live sign is placed
    with it (room visits look for its door there), and where the map has no wall for it
    at the end, it keeps that size rather than the standard one."""
    size = 0.6
    sign = Sign("LAB 3", 5.0, 3.0, -math.pi / 2, width=0.6 * size, height=0.2 * size, z=1.3)
    world = make_world([[0.0, 3.0, 10.0, 3.0]], signs=[sign])
    capture = _capture_of(world, sign, (3.5, 1.2, 0.3))
    standard = sighting_from_capture(capture, Reading("LAB 3", "LAB 3", 0.9),
                                     mount=(SPEC.mount_x, SPEC.mount_y))
    assert math.hypot(standard.x - sign.x, standard.y - sign.y) > 1.0
    sized = sighting_from_capture(dataclasses.replace(capture, scale=size), Reading("LAB 3", "LAB 3", 0.9),
                                  mount=(SPEC.mount_x, SPEC.mount_y))
    assert math.hypot(sized.x - sign.x, sized.y - sign.y) < 0.1
    smap = SignMap()
    smap.add(sized)
    smap.place_on_walls(_wall_map(3.0, gap=(0.0, 10.0)))  # no wall: the measured size stays
    (placed,) = smap.signs()
    assert math.hypot(placed["x"] - sign.x, placed["y"] - sign.y) < 0.1


def test_first_occupied_measures_along_a_ray():
    m = _wall_map(3.0)  # 0.1 m thick
    assert m.first_occupied(5.0, 1.0, 0.0, 1.0, 4.0) == pytest.approx((2.0, 2.1), abs=0.025)
    assert m.first_occupied(5.0, 1.0, 0.6, 0.8, 4.0) == pytest.approx((2.5, 2.625), abs=0.03)
    assert m.first_occupied(5.0, 1.0, 0.0, 1.0, 1.5) is None  # out of reach
    assert m.first_occupied(5.0, 1.0, 0.0, -1.0, 4.0) is None  # free, then off the map
    assert m.first_occupied(-3.0, 1.0, -1.0, 0.0, 4.0) is None  # starts off the map


# ---- merging -----------------------------------------------------------------------------
def _s(text, x, y, facing_deg=90.0, confidence=0.9, rng=2.0, view=0.0, tick=0, robot=None):
    return Sighting(text=text, raw_text=text.lower(), confidence=confidence, x=x, y=y,
                    facing=math.radians(facing_deg), tick=tick, range=rng,
                    viewing_angle=view, robot_pose=robot)


@pytest.mark.parametrize("late", [False, True])
def test_a_reading_placed_short_of_its_wall_joins_its_plate_and_leaves_it_where_it_is(late):
    """One reading of the plate on the wall at y = 5 was placed 2.2 m out from it, along
    its line of sight (a plate bigger than the standard one, no wall on the map to put it
    on): it says the same text, so it is the same plate, which stays where the other
    three agree, whichever order they come in."""
    smap = SignMap()
    near = [_s("MAIL ROOM", 2.0 + dx, 5.0, 90) for dx in (-0.05, 0.0, 0.05)]
    far = _s("MAIL ROOM", 1.9, 7.2, 100, rng=3.0)
    for s in near + [far] if late else [far] + near:
        smap.add(s)
    (sign,) = smap.signs()
    assert sign["sightings"] == 4
    assert (sign["x"], sign["y"]) == pytest.approx((2.0, 5.0), abs=0.01)
    # a plate saying something else there is another plate
    smap.add(_s("OFFICE 12", 1.9, 7.2, 100))
    assert len(smap.signs()) == 2


def test_every_reading_is_listed_with_the_plate_it_went_to(tmp_path):
    from blocks.signs.correlate import SIGHTING_COLUMNS, write_sightings_csv
    smap = SignMap()
    for s in (_s("MAIL ROOM", 2.0, 5.0), _s("OFFICE 12", 6.0, 5.0),
              _s("MAIL ROOM", 2.1, 5.05, confidence=0.95), _s("LAB", 9.0, 5.0, confidence=0.3)):
        smap.add(s)
    rows = smap.sighting_rows()
    assert [(r["plate"], r["text"], r["published"]) for r in rows] == [
        (0, "MAIL ROOM", True), (1, "OFFICE 12", True), (0, "MAIL ROOM", True), (2, "LAB", False)]
    path = write_sightings_csv(tmp_path / "signs" / "sightings.csv", rows)
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(SIGHTING_COLUMNS) and len(lines) == 5


def test_two_sightings_of_one_plate_merge_keeping_the_better_text():
    smap = SignMap()
    smap.add(_s("LIBRARY", 5.3, 7.0, -90, confidence=0.7))
    smap.add(_s("library", 5.5, 7.1, -80, confidence=0.95))
    (sign,) = smap.signs()
    assert sign["sightings"] == 2 and sign["text"] == "LIBRARY"
    assert sign["raw_text"] == "library" and sign["confidence"] == pytest.approx(0.95)
    assert 5.3 < sign["x"] < 5.5 and sign["facing"] == pytest.approx(-85.0, abs=3.0)


def test_plates_apart_or_back_to_back_stay_apart():
    smap = SignMap()
    smap.add(_s("MAIL ROOM", 2.0, 5.0))
    smap.add(_s("MANAGER", 5.0, 5.0))  # 3 m apart
    smap.add(_s("STORE", 2.0, 5.2, facing_deg=-90))  # the other side of the wall
    smap.add(_s("KITCHEN", 2.6, 5.0))  # 0.6 m away, confidently read differently
    assert len(smap) == 4
    assert [s["text"] for s in smap.signs()] == ["KITCHEN", "MAIL ROOM", "MANAGER", "STORE"]


def test_a_weak_wrong_reading_does_not_replace_a_good_one():
    smap = SignMap()
    smap.add(_s("LIBRARY", 5.35, 7.1, -90, confidence=0.9, rng=3.0))
    smap.add(_s("LAB", 5.4, 7.0, -90, confidence=0.3, rng=1.0))  # nearer, but a poor read
    smap.add(_s("", 5.3, 7.1, -90, confidence=0.0))  # a plate seen but not read
    (sign,) = smap.signs()
    assert sign["text"] == "LIBRARY" and sign["sightings"] == 3
    assert smap.rejected() == []


def test_a_misread_of_a_plate_is_the_same_plate_and_loses_the_vote():
    """Readings of one plate closer than a plate's width are one plate whatever they say
    (run gen:office:5: "OFFICE 182" read once beside eight reads of "OFFICE 102"); the
    text most confident readings agree on names it."""
    smap = SignMap()
    for i in range(3):
        smap.add(_s("OFFICE 102", 10.44 + 0.02 * i, 5.14, confidence=0.98))
    smap.add(_s("OFFICE 182", 10.53, 5.08, confidence=0.52, rng=1.0))
    (sign,) = smap.signs()
    assert sign["text"] == "OFFICE 102" and sign["sightings"] == 4
    assert smap.clusters[0].disputed
    # one confident read each: the more confident names the plate, whichever came first
    for order in ((0.91, 0.99), (0.99, 0.91)):
        smap = SignMap()
        smap.add(_s("MEETING ROOM" if order[0] < 0.95 else "MEETING ROOM 1", 5.11, 5.19,
                    confidence=order[0]))
        smap.add(_s("MEETING ROOM 1" if order[0] < 0.95 else "MEETING ROOM", 5.14, 5.15,
                    confidence=order[1]))
        assert [s["text"] for s in smap.signs()] == ["MEETING ROOM 1"]


def test_two_agreeing_reads_outvote_one_more_confident_misread_in_any_order():
    """The vote sums confidence per text: 0.8 + 0.8 for "OFFICE 102" beats a single 0.9
    "OFFICE 182"; and the plate is one plate whichever reading came first, even when the
    misread led the vote for a while (the later "OFFICE 102" 0.9 m from the first)."""
    reads = [_s("OFFICE 102", 0.0, 5.0, confidence=0.8),
             _s("OFFICE 182", 0.4, 5.0, confidence=0.9),
             _s("OFFICE 102", 0.9, 5.0, confidence=0.8)]
    for order in ((0, 1, 2), (1, 0, 2), (0, 2, 1), (2, 1, 0)):
        smap = SignMap()
        for i in order:
            smap.add(dataclasses.replace(reads[i]))
        assert [(s["text"], s["sightings"]) for s in smap.signs()] == [("OFFICE 102", 3)], order


def test_a_misread_joins_its_own_plate_not_the_neighbour_it_happens_to_be_nearer():
    """Plates "LAB 1" and "LAB 2" 1.1 m apart: a reading of "LAB 2" that landed nearer to
    "LAB 1" joins "LAB 2" (its text agrees, within the text radius), and "LAB 1" stays."""
    smap = SignMap()
    smap.add(_s("LAB 1", 0.0, 5.0))
    smap.add(_s("LAB 2", 1.1, 5.0))
    smap.add(_s("LAB 2", 0.45, 5.0, confidence=0.95))
    assert [(s["text"], s["sightings"]) for s in smap.signs()] == [("LAB 1", 1), ("LAB 2", 2)]


def test_a_plate_read_once_clearly_is_read_whatever_the_vote_says():
    """"LIB" twice at 0.55 outvotes "LAB" at 0.9, and the plate is still read (a reading
    of it clears min_confidence), not dropped for its winner's weaker reads."""
    smap = SignMap()
    smap.add(_s("LAB", 5.0, 7.0, confidence=0.9))
    smap.add(_s("LIB", 5.05, 7.0, confidence=0.55))
    smap.add(_s("LIB", 5.1, 7.0, confidence=0.55))
    assert [s["text"] for s in smap.signs(min_confidence=0.6)] == ["LIB"]
    assert smap.rejected(min_confidence=0.6) == []
    smap.add(_s("", 5.0, 7.0, confidence=0.99))  # seen, not read: never names the plate
    assert [s["text"] for s in smap.signs(min_confidence=0.6)] == ["LIB"]


def test_weak_reads_do_not_outvote_a_clear_one_and_plates_a_width_apart_stay_apart():
    smap = SignMap()
    smap.add(_s("LIBRARY", 5.0, 7.0, confidence=0.9))
    for _ in range(3):
        smap.add(_s("LAB", 5.05, 7.0, confidence=0.45))
    (sign,) = smap.signs(min_confidence=0.4)
    assert sign["text"] == "LIBRARY" and not smap.clusters[0].disputed
    # two confident readings 0.6 m apart: two plates (the merge radius alone would join them)
    smap = SignMap()
    smap.add(_s("LAB 1", 5.0, 7.0))
    smap.add(_s("LAB 2", 5.6, 7.0))
    assert len(smap) == 2
    # with the rule turned off, even readings 5 cm apart stay two plates, as before
    smap = SignMap(same_plate_radius=0.0)
    smap.add(_s("OFFICE 303", 31.13, 16.46))
    smap.add(_s("OFFICE 342", 31.17, 16.44, confidence=0.76))
    assert len(smap) == 2
    smap = SignMap(same_plate_radius=0.0)  # ...even at one spot
    smap.add(_s("OFFICE 303", 31.13, 16.46))
    smap.add(_s("OFFICE 342", 31.13, 16.46, confidence=0.76))
    assert len(smap) == 2
    with pytest.raises(ValueError):
        SignMap(same_plate_radius=-0.1)


def test_ties_go_to_the_nearer_frontal_view_and_position_favours_it():
    smap = SignMap()
    smap.add(_s("ADMIN", 10.0, 5.0, confidence=0.8, rng=4.0, view=math.radians(60)))
    smap.add(_s("ADMIN ", 10.4, 5.0, confidence=0.8, rng=1.0, view=0.0))
    smap.clusters[0].sightings[1].raw_text = "near"
    (sign,) = smap.signs()
    assert sign["raw_text"] == "near"
    assert sign["x"] > 10.35  # the near view weighs ~30x more


def test_signs_and_rejected_split_on_confidence_and_text():
    smap = SignMap()
    smap.add(_s("ADMIN", 1.0, 1.0, confidence=0.9))
    smap.add(_s("STORE", 5.0, 1.0, confidence=0.3))
    smap.add(_s("", 9.0, 1.0, confidence=0.0))
    assert [s["text"] for s in smap.signs()] == ["ADMIN"]
    assert [s["text"] for s in smap.signs(min_confidence=0.2)] == ["ADMIN", "STORE"]
    reasons = [r["reason"] for r in smap.rejected()]
    assert reasons[0].startswith("confidence") and reasons[1] == "no text"


def test_replace_poses_moves_signs_with_the_corrected_path():
    smap = SignMap()
    # odometry drifted by 3.5 m between two passes: the same sign lands in two places
    for tick, robot in ((10, (2.0, 5.7, 0.0)), (900, (5.5, 5.7, 0.0))):
        rel = (0.35, -0.6, -math.pi / 2)  # the plate on the right-hand wall
        x, y, f = compose(robot, rel)
        s = _s("MAIL ROOM", x, y, math.degrees(f), tick=tick, robot=np.array(robot))
        assert s.rel == pytest.approx(rel)
        smap.add(s)
    assert len(smap.signs()) == 2

    def corrected(tick: int, pose: np.ndarray) -> np.ndarray:
        # the late pass really was 3.5 m further back; then rotate the whole frame by 90 deg
        p = pose - ([3.5, 0.0, 0.0] if tick > 100 else 0.0)
        c, s = 0.0, 1.0
        return np.array([c * p[0] - s * p[1], s * p[0] + c * p[1], p[2] + math.pi / 2])

    for _ in range(2):  # each correction starts from the odometry poses
        assert smap.replace_poses(corrected) == 2
        (sign,) = smap.signs()
        assert sign["sightings"] == 2
        # the plate at (2.35, 5.1) facing -90 deg, rotated by +90 deg about the origin
        assert (sign["x"], sign["y"]) == pytest.approx((-5.1, 2.35), abs=1e-6)
        assert sign["facing"] == pytest.approx(0.0, abs=1e-6)
    assert smap.sightings[1].original_pose == pytest.approx([5.5, 5.7, 0.0])


def test_normalise_text():
    assert normalise_text("  mail   room\n") == "MAIL ROOM"
    assert _s("mail  room", 0, 0).text == "MAIL ROOM"


# ---- outputs -------------------------------------------------------------------------------
def test_write_signs_json_is_a_list_and_atomic(tmp_path):
    smap = SignMap()
    smap.add(_s("ADMIN", 14.35, 5.1, 90.0))
    path = tmp_path / "run" / "signs.json"
    path.parent.mkdir()
    path.write_text("old")
    written = write_signs_json(path, smap.signs(), extra={"rejected": smap.rejected()})
    data = json.loads(path.read_text())
    assert isinstance(data, list) and len(data) == 1
    assert set(data[0]) == {"text", "raw_text", "confidence", "x", "y", "facing", "sightings"}
    assert data[0]["facing"] == pytest.approx(90.0) and data[0]["x"] == pytest.approx(14.35)
    assert written == [path, tmp_path / "run" / "signs.meta.json"]
    assert json.loads(written[1].read_text()) == {"rejected": []}
    assert sorted(p.name for p in path.parent.iterdir()) == ["signs.json", "signs.meta.json"]


def test_draw_hybrid_map_writes_a_png(tmp_path):
    occ = np.zeros((100, 160))  # 8 x 5 m at 5 cm, free inside a wall border, some unknown
    occ[[0, -1], :] = occ[:, [0, -1]] = 1.0
    occ[40:60, 100:140] = np.nan
    grid = OccupancyMap(occupancy=occ, resolution=0.05, origin=(-1.0, -0.5, 0.0))
    signs = [{"text": "MAIL ROOM", "x": 2.3, "y": 0.2, "facing": 90.0, "confidence": 0.9},
             {"text": "LIBRARY", "x": 5.0, "y": 4.3, "facing": -90.0, "confidence": 0.8}]
    truth = [Sign("MAIL ROOM", 2.35, 0.1, math.pi / 2), Sign("LIBRARY", 5.1, 4.4, -math.pi / 2)]
    path = draw_hybrid_map(grid, signs, tmp_path / "hybrid.png",
                           trajectory=np.array([[0.0, 1.0], [6.0, 1.0], [6.0, 3.0]]),
                           true_signs=truth, title="test", size_px=800)
    img = cv2.imread(str(path))
    assert img is not None and img.shape[1] == 800 and img.shape[0] > 300
    assert img.std() > 20  # not blank
    b, g, r = (img[..., k].astype(int) for k in range(3))
    assert ((r > 150) & (g < 100) & (b < 100)).sum() > 30  # the red sign markers
    assert list(tmp_path.iterdir()) == [path]
    # no map: signs alone still draw
    alone = draw_hybrid_map(None, signs, tmp_path / "alone.png")
    assert cv2.imread(str(alone)).std() > 5


# ---- scoring -----------------------------------------------------------------------------
TRUE = [Sign("MAIL ROOM", 2.35, 5.1, math.pi / 2), Sign("LIBRARY", 5.35, 7.1, -math.pi / 2),
        Sign("ADMIN", 14.35, 5.1, math.pi / 2)]


def test_score_exact():
    est = [{"text": "mail  room", "x": 2.45, "y": 5.1, "facing": 80.0},
           {"text": "LIBRARY", "x": 5.35, "y": 6.9, "facing": -90.0},
           {"text": "ADMIN", "x": 14.35, "y": 5.1, "facing": 90.0}]
    sc = score_signs(est, TRUE)
    assert (sc["found"], sc["read_exactly"], sc["false_signs"], sc["missed"]) == (3, 3, 0, 0)
    assert sc["position_error_max"] == pytest.approx(0.2)
    assert sc["position_error_mean"] == pytest.approx(0.1)
    assert sc["facing_error_max_deg"] == pytest.approx(10.0)
    assert sc["precision"] == sc["recall"] == 1.0


def test_score_wrong_text_false_position_and_missed():
    est = [{"text": "MAIL ROOM", "x": 2.0, "y": 5.3, "facing": 90.0},
           {"text": "LIBRARIAN", "x": 5.35, "y": 7.0, "facing": -90.0},  # wrong text
           {"text": "ADMIN", "x": 17.0, "y": 5.1, "facing": 90.0}]  # 2.65 m off: false
    sc = score_signs(est, TRUE, tolerance=1.0)
    assert sc["true_signs"] == 3 and sc["found"] == 2 and sc["read_exactly"] == 1
    assert sc["wrong_text"] == 1 and sc["false_positions"] == 1 and sc["false_signs"] == 2
    assert sc["missed"] == 1
    statuses = [(p["true_text"], p["status"]) for p in sc["per_sign"]]
    assert statuses == [("MAIL ROOM", "read"), ("LIBRARY", "wrong_text"), ("ADMIN", "missed"),
                        (None, "false_position")]
    # a looser tolerance finds ADMIN after all
    assert score_signs(est, TRUE, tolerance=3.0)["read_exactly"] == 2


def test_score_pairs_one_to_one_and_takes_dict_truth_in_degrees():
    truth = [{"text": "A", "x": 0.0, "y": 0.0, "facing": 90.0},
             {"text": "B", "x": 0.8, "y": 0.0, "facing": 90.0}]
    est = [{"text": "A", "x": 0.5, "y": 0.0, "facing": 90.0},  # nearer B, but B has its own
           {"text": "B", "x": 1.0, "y": 0.0, "facing": 90.0}]
    sc = score_signs(est, truth)
    assert sc["read_exactly"] == 2 and sc["facing_error_max_deg"] == pytest.approx(0.0)
    empty = score_signs([], truth)
    assert empty["missed"] == 2 and empty["position_error_mean"] is None
