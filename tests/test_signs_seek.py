"""The stop-and-zoom behaviour on a scripted robot: it stops at a good view, zooms, captures,
resumes, and never stalls (lost plates, phantom plates, timeouts)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from blocks.signs.seek import Mode, Observation, SeekParams, SignSeeker, Target
from blocks.signs.types import CameraModel, PlateDetection
from sim2d.camera import CameraSpec, camera_pose, visible_signs
from sim2d.world import Sign, make_world

DT = 0.1
SPEC = CameraSpec()


def corridor_with_sign(sign_x: float = 6.0, left: bool = False) -> object:
    """A 2 m corridor along x; one plate on the right wall (y = 0, facing +y) or on the
    left wall (y = 2, facing -y)."""
    walls = [[-1.0, 0.0, 20.0, 0.0], [-1.0, 2.0, 20.0, 2.0]]
    sign = (Sign(text="LIBRARY", x=sign_x, y=1.95, facing=-math.pi / 2) if left
            else Sign(text="MAIL ROOM", x=sign_x, y=0.05, facing=math.pi / 2))
    return make_world(walls, start=(0.0, 0.7, 0.0), signs=[sign])


def truth_detections(world, pose, head, phantom=None) -> tuple[list[PlateDetection], CameraModel]:
    """Detections as a perfect detector would report them (from sim2d's ground truth)."""
    pan, tilt, zoom = head
    cam = camera_pose(pose, SPEC, pan)
    model = CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt)
    dets = []
    for v in visible_signs(world, cam, tilt, zoom, SPEC):
        corners = np.asarray(v["corners"], dtype=np.float64)
        clipped = bool(corners[:, 0].min() < 0 or corners[:, 0].max() > SPEC.width - 1
                       or corners[:, 1].min() < 0 or corners[:, 1].max() > SPEC.height - 1)
        if v["apparent_height"] < 6:
            continue
        dets.append(PlateDetection(corners=corners, bbox=v["bbox"], bearing=v["bearing"],
                                   range=v["distance"], score=1.0, clipped=clipped))
    if phantom is not None:
        dets.append(phantom)
    return dets, model


def slew(head, cmd, dt=DT):
    turn = math.radians(90.0) * dt
    pan = head[0] + max(-turn, min(turn, cmd[0] - head[0]))
    tilt = head[1] + max(-turn, min(turn, cmd[1] - head[1]))
    zoom = head[2] + max(-0.4, min(0.4, cmd[2] - head[2]))
    return [pan, tilt, zoom]


def drive(world, seconds=20.0, speed=0.7, params=None, detections=truth_detections, **kw):
    """Run the seeker on a robot driving along the corridor; return what happened."""
    seeker = SignSeeker(params or SeekParams(), mount=(SPEC.mount_x, SPEC.mount_y))
    pose = np.array([0.0, 0.7, 0.0])
    head = [0.0, math.radians(5), 1.0]
    v = 0.0
    log = {"captures": [], "stopped": 0.0, "modes": []}
    for k in range(int(seconds / DT)):
        t = k * DT
        fresh = k % 2 == 0  # 5 Hz camera
        dets, model = detections(world, pose, head, **kw) if fresh else ([], None)
        cmd = seeker.step(t, pose, fresh, dets, model, *head)
        log["modes"].append(seeker.mode)
        if cmd.capture is not None:
            view = truth_view(world.signs[0], pose, head[0])
            log["captures"].append({"det": cmd.capture, "zoom": head[2], "view": view,
                                    "time": t, "x": pose[0]})
        target_v = 0.0 if cmd.stop else speed
        v += max(-DT, min(DT, target_v - v))  # 1 m/s^2
        if cmd.stop:
            log["stopped"] += DT
        pose = pose + np.array([v * DT, 0.0, 0.0])
        head = slew(head, (cmd.pan, cmd.tilt, cmd.zoom))
    log["seeker"] = seeker
    return log


def truth_view(sign, pose, pan) -> float:
    cam = camera_pose(pose, SPEC, pan)
    to_cam = math.atan2(cam[1] - sign.y, cam[0] - sign.x)
    return math.degrees(abs((to_cam - sign.facing + math.pi) % (2 * math.pi) - math.pi))


@pytest.mark.parametrize("left, best_view", [(False, 62.0), (True, 45.0)])
def test_stops_at_a_good_view_zooms_captures_and_resumes(left, best_view):
    """Near the right wall the plate, hung above the camera, would leave the top of the
    frame (or fill so much of it that a detector takes it for a wall) before the view gets
    head-on, so the robot stops at the closest view that keeps it in frame; across the
    corridor it stops at the good view."""
    world = corridor_with_sign(left=left)
    log = drive(world)
    seeker = log["seeker"]
    assert len(log["captures"]) == 1, seeker.stats.events
    cap = log["captures"][0]
    assert cap["view"] <= best_view
    assert cap["det"].height_px >= 0.7 * seeker.p.target_height_px  # zoomed in
    assert not cap["det"].clipped
    assert seeker.stats.stops == 1
    assert log["stopped"] <= 3.0  # seconds standing still for one sign
    assert log["modes"][-1] is Mode.EXPLORE  # resumed, and did not stop again


def test_a_plate_far_ahead_is_not_chased_until_near():
    world = corridor_with_sign(sign_x=15.0)
    log = drive(world, seconds=6.0)  # the robot gets to x ~ 4: the plate is > 5 m away
    assert log["seeker"].stats.stops == 0
    assert all(m is Mode.EXPLORE for m in log["modes"])


def test_a_phantom_that_the_zoomed_view_does_not_confirm_is_rejected():
    """A blob that looks like a plate from afar, but is gone once the robot stops."""
    world = corridor_with_sign(sign_x=100.0)  # no real plate in reach
    state = {"stopped_frames": 0}

    def phantom_detector(world, pose, head):
        model = CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, head[2], head[1])
        # a fixed fake plate at (4, 0.05) facing +y, projected by hand, seen only while moving
        fake = corridor_with_sign(sign_x=4.0)
        dets, _ = truth_detections(fake, pose, head)
        if log_modes and log_modes[-1] is Mode.STOP:
            state["stopped_frames"] += 1
            return [], model
        return dets, model

    log_modes: list = []
    seeker = SignSeeker(SeekParams(), mount=(SPEC.mount_x, SPEC.mount_y))
    pose = np.array([0.0, 0.7, 0.0])
    head = [0.0, 0.0, 1.0]
    stopped_for = 0.0
    for k in range(200):
        fresh = k % 2 == 0
        dets, model = phantom_detector(world, pose, head) if fresh else ([], None)
        cmd = seeker.step(k * DT, pose, fresh, dets, model, *head)
        log_modes.append(seeker.mode)
        stopped_for += DT if cmd.stop else 0.0
        if not cmd.stop:
            pose = pose + np.array([0.7 * DT, 0.0, 0.0])
        head = slew(head, (cmd.pan, cmd.tilt, cmd.zoom))
    assert seeker.stats.stops == 1
    assert seeker.stats.rejected == 1
    assert seeker.stats.captures == 0
    assert stopped_for <= 0.2 * seeker.p.lost_frames * 2 + 0.5  # resumes after a few frames
    assert log_modes[-1] is Mode.EXPLORE


def test_a_stop_that_never_settles_times_out():
    """A plate that stays clipped at the image edge can never be captured: the stop ends."""
    world = corridor_with_sign()

    def clipped_detector(world, pose, head):
        dets, model = truth_detections(world, pose, head)
        return [PlateDetection(d.corners, d.bbox, d.bearing, d.range, d.score, clipped=True)
                for d in dets], model

    params = SeekParams(stop_timeout=2.0)
    log = drive(world, seconds=25.0, params=params, detections=clipped_detector)
    seeker = log["seeker"]
    assert seeker.stats.captures == 0
    assert seeker.stats.timeouts >= 1
    assert log["stopped"] <= 2.0 + 0.3
    assert log["modes"][-1] is Mode.EXPLORE


def test_a_target_that_leaves_the_view_is_dropped():
    world = corridor_with_sign()
    frames = {"n": 0}

    def flaky_detector(world, pose, head):
        frames["n"] += 1
        dets, model = truth_detections(world, pose, head)
        return (dets if frames["n"] < 12 else []), model  # the plate vanishes mid-chase

    log = drive(world, seconds=15.0, detections=flaky_detector)
    seeker = log["seeker"]
    assert seeker.stats.lost + seeker.stats.rejected == 1
    assert seeker.stats.captures == 0
    assert log["modes"][-1] is Mode.EXPLORE


@pytest.mark.parametrize("bad", [{"good_view_deg": 0.0, "worst_view_deg": 1.0}])
def test_a_plate_never_seen_well_is_given_up_without_stopping(bad):
    world = corridor_with_sign()
    log = drive(world, params=SeekParams(**bad))
    seeker = log["seeker"]
    assert seeker.stats.stops == 0
    assert seeker.stats.given_up == 1
    assert log["modes"][-1] is Mode.EXPLORE


# ---- plates of unknown size ------------------------------------------------------------------
def corridor_with_plate(scale: float, left: bool, z: float, width: float = 3.0):
    """A corridor ``width`` wide; one plate ``scale`` times the standard size, its centre ``z``
    above the floor, on the followed (right) wall or across the corridor (left)."""
    walls = [[-1.0, 0.0, 30.0, 0.0], [-1.0, width, 30.0, width]]
    w, h = 0.6 * scale, 0.2 * scale
    sign = (Sign(text="X", x=8.0, y=width - 0.05, facing=-math.pi / 2, width=w, height=h, z=z)
            if left else Sign(text="X", x=8.0, y=0.05, facing=math.pi / 2, width=w, height=h,
                              z=z))
    return make_world(walls, start=(0.0, 0.7, 0.0), signs=[sign])


def test_a_plates_size_and_place_follow_from_the_rays_of_two_views():
    """P = camera + k * offset for every view: two views fix P and k; one view leaves k at 1."""
    plate, k = np.array([5.0, 2.0]), 0.6

    def view_from(camera):
        offset = (plate - camera) / k  # where a standard plate along the same ray would be
        return Observation(*(camera + offset), facing=-math.pi / 2, z=1.0, w_pos=4.0,
                           w_facing=10.0, camera=tuple(camera), offset=tuple(offset))

    first = view_from(np.array([0.0, 0.7]))
    target = Target.start(first, 0.0, scale_prior=0.005)
    assert target.scale == pytest.approx(1.0)
    assert (target.x, target.y) == pytest.approx((first.x, first.y))
    for x in (0.75, 1.5, 2.25, 3.0):
        target.absorb(view_from(np.array([x, 0.7])))
    # the prior that holds k to 1 until views disagree leaves a little of itself
    assert target.scale == pytest.approx(k, rel=0.02)
    assert (target.x, target.y) == pytest.approx(tuple(plate), abs=0.1)
    standard = Target.start(first, 0.0)  # standard plates: the views' weighted mean
    standard.absorb(view_from(np.array([3.0, 0.7])))
    assert standard.scale == 1.0 and standard.x > plate[0] + 1.0


@pytest.mark.parametrize("scale", [0.6, 1.0, 1.45])
@pytest.mark.parametrize("left, z", [(False, 1.1), (False, 1.5), (True, 1.3)])
def test_a_plate_of_any_size_is_captured_on_either_wall(scale, left, z):
    """Taken for a standard plate, a small one seems a metre farther (given up as out of
    reach while the robot passes it head-on) and a large one nearer (stopped for too
    early, then lost from the zoomed frame): on one generated office, 10 of 15 plates."""
    world = corridor_with_plate(scale, left, z)
    log = drive(world, params=SeekParams(plate_sizes="any"))
    seeker = log["seeker"]
    assert len(log["captures"]) == 1, seeker.stats.events
    cap = log["captures"][0]
    assert not cap["det"].clipped
    assert cap["view"] <= (45.0 if left else 70.0)
    assert seeker.stats.given_up == seeker.stats.rejected == 0


def test_taken_for_a_standard_plate_a_small_one_is_lost():
    """The case above that fails without the size: the test can fail."""
    log = drive(corridor_with_plate(0.6, True, 1.3), params=SeekParams(plate_sizes="standard"))
    assert len(log["captures"]) == 0
