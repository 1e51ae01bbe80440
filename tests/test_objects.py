"""Object catalogue, object rendering in sim2d's camera, and the object recogniser."""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import pytest

from blocks.core.errors import SemmapError
from blocks.signs.types import CameraModel
from semantic.objects import CatalogueError, default_catalogue, load_catalogue
from semantic.objects.make_catalogue import draw
from semantic.matching import RatioMatcher, ratio_matches
from semantic.object_gate import GateParams, textured_regions
from semantic.recognise import (ObjectRecogniser, RecogniserParams, match_sightings,
                                object_world_position)
from sim2d.camera import CameraSpec, camera_pose, render, visible_objects
from sim2d.world import Sign, make_world

SPEC = CameraSpec()
F1 = (SPEC.width / 2) / math.tan(SPEC.hfov / 2)  # focal length at zoom 1
HALL = [[-3, -6, 9, -6], [9, -6, 9, 6], [9, 6, -3, 6], [-3, 6, -3, -6]]


@dataclass(frozen=True)
class Thing:
    """A world object; ``facing`` (rad) fixes its direction instead of facing the camera."""

    label: str
    x: float
    y: float
    facing: float | None = None


def world_with(*objects, walls=HALL):
    world = make_world(walls)
    world.objects = list(objects)
    return world


@pytest.fixture(scope="module")
def recogniser():
    return ObjectRecogniser()


def framing(label: str, distance: float) -> tuple[float, float]:
    """Tilt that centres the object, and zoom that makes its smaller side >= 70 px (at most 4x),
    as a camera head would frame it: smaller objects are not expected to be recognised."""
    e = default_catalogue().entry(label)
    tilt = math.atan2(e.elevation + e.height / 2 - SPEC.mount_z, distance)
    zoom = min(4.0, max(1.0, 70.0 / (F1 * min(e.width, e.height) / distance)))
    return max(-0.5, min(0.5, tilt)), zoom


# ---- the catalogue -------------------------------------------------------------------------------
def test_the_catalogue_has_the_agreed_labels_and_sane_sizes():
    cat = default_catalogue()
    assert len(cat) >= 10
    assert {"Shredder", "Printer", "Microscope", "Projector", "Bookshelf", "CoffeeMachine",
            "Toolbox", "ServerRack"} <= set(cat.labels)
    for e in cat.entries:
        img = cat.image(e.label)
        assert img.shape[2] == 3 and 256 <= max(img.shape[:2]) <= 400
        assert img.shape[1] / img.shape[0] == pytest.approx(e.aspect, rel=0.05)
        assert 0.1 <= e.height <= 2.5 and 0.1 <= e.width <= 2.5


def test_the_generator_reproduces_the_committed_pictures():
    for e in default_catalogue().entries:
        committed = cv2.imread(str(e.image), cv2.IMREAD_COLOR)
        assert committed is not None, e.image
        assert np.array_equal(draw(e), committed), f"{e.image.name} is stale: run " \
            "python -m semantic.objects.make_catalogue"


def test_every_world_object_label_is_in_the_catalogue():
    from sim2d.world import load_world
    from sim2d.worlds import world_path
    labels = set(default_catalogue().labels)
    for name in ("office", "hospital"):
        for obj in getattr(load_world(world_path(name)), "objects", []):
            assert obj.label in labels, (name, obj.label)


@pytest.mark.parametrize("entry, field, line", [
    ("{label: shredder, image: shredder.png, width: 0.4, height: 0.7}", "label", 3),
    ("{label: Shredder, image: shredder.png, width: -1, height: 0.7}", "width", 3),
    ("{label: Shredder, image: missing.png, width: 0.4, height: 0.7}", "image", 3),
    ("{label: Shredder, image: shredder.png, width: 0.4}", "height", 3),
    ("{label: Shredder, image: shredder.png, width: 0.4, height: 0.7, colour: red}", "colour", 3),
])
def test_a_bad_catalogue_entry_names_file_line_and_field(tmp_path, entry, field, line):
    (tmp_path / "shredder.png").write_bytes(cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))[1])
    path = tmp_path / "catalogue.yaml"
    path.write_text(f"version: 1\nobjects:\n  - {entry}\n")
    with pytest.raises(CatalogueError) as err:
        load_catalogue(path)
    assert isinstance(err.value, SemmapError)
    assert err.value.file == str(path) and err.value.line == line and err.value.field == field


def test_a_duplicate_label_is_an_error_on_its_second_line(tmp_path):
    (tmp_path / "a.png").write_bytes(cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))[1])
    path = tmp_path / "catalogue.yaml"
    path.write_text("objects:\n  - {label: Fridge, image: a.png, width: 0.7, height: 1.8}\n"
                    "  - {label: Fridge, image: a.png, width: 0.7, height: 1.8}\n")
    with pytest.raises(CatalogueError) as err:
        load_catalogue(path)
    assert err.value.line == 3 and "twice" in err.value.message


# ---- rendering -----------------------------------------------------------------------------------
def test_an_object_is_drawn_where_visible_objects_says_and_nothing_without_objects():
    empty, world = world_with(), world_with(Thing("Fridge", 3.0, 0.0))
    tilt = math.radians(10)
    assert visible_objects(empty, (0, 0, 0), tilt, 1.0, SPEC) == []
    seen = visible_objects(world, (0, 0, 0), tilt, 1.0, SPEC)
    assert [s["label"] for s in seen] == ["Fridge"]
    assert seen[0]["distance"] == pytest.approx(3.0)
    assert seen[0]["apparent_height"] == pytest.approx(F1 * 1.8 / 3.0, rel=1e-6)
    a = render(world, (0, 0, 0), tilt, 1.0, SPEC, np.random.default_rng(1)).astype(int)
    b = render(empty, (0, 0, 0), tilt, 1.0, SPEC, np.random.default_rng(1)).astype(int)
    changed = np.abs(a - b).max(axis=2) > 20
    x0, y0, x1, y1 = seen[0]["bbox"]
    assert changed[y0:y1 + 1, x0:x1 + 1].mean() > 0.5
    changed[max(0, y0 - 3):y1 + 4, max(0, x0 - 3):x1 + 4] = False
    assert not changed.any()  # nothing drawn outside the object's box


def test_a_wall_hides_an_object_behind_it():
    wall = [[2.0, -3.0, 2.0, 3.0]]
    hidden = world_with(Thing("Printer", 3.5, 0.0), walls=HALL + wall)
    bare = world_with(walls=HALL + wall)
    assert visible_objects(hidden, (0, 0, 0), 0.2, 1.0, SPEC) == []
    a = render(hidden, (0, 0, 0), 0.2, 1.0, SPEC, np.random.default_rng(2))
    b = render(bare, (0, 0, 0), 0.2, 1.0, SPEC, np.random.default_rng(2))
    assert np.array_equal(a, b)
    # half behind a door jamb: only the visible columns are reported
    jamb = [[2.0, -3.0, 2.0, 0.0]]
    half = world_with(Thing("Printer", 3.5, 0.0), walls=HALL + jamb)
    seen = visible_objects(half, (0, 0, 0), 0.2, 1.0, SPEC)
    assert len(seen) == 1 and 0.3 < seen[0]["visible_fraction"] < 0.8


def test_object_free_worlds_render_exactly_as_before():
    """Objects add nothing when absent: same bytes with and without an empty objects list."""
    from sim2d.world import load_world
    from sim2d.worlds import world_path
    world = load_world(world_path("office"))
    bare = load_world(world_path("office"))
    bare.objects = []
    for k, (x, y, th) in enumerate([(27.0, 6.0, math.pi), (4.0, 6.1, 0.0), (1.1, 10.0, 1.5)]):
        cam = camera_pose((x, y, th), SPEC, 0.3 * k)
        a = render(bare, cam, 0.2, 1.5, SPEC, np.random.default_rng(k))
        bare.objects = None  # a world from before objects existed
        b = render(bare, cam, 0.2, 1.5, SPEC, np.random.default_rng(k))
        bare.objects = []
        assert np.array_equal(a, b)
        assert visible_objects(bare, cam, 0.2, 1.5, SPEC) == []
    assert world.objects, "the office world lists objects"


# ---- recognition ---------------------------------------------------------------------------------
VIEWS = [(1.5, 0.0, 0.0), (2.5, 10.0, 0.0), (4.0, -8.0, 0.0),  # distance, bearing, view angle
         (2.0, 5.0, 25.0), (3.0, -5.0, 40.0)]


@pytest.mark.parametrize("label", sorted(default_catalogue().labels))
def test_each_object_is_recognised_with_its_range_and_bearing(recogniser, label):
    for k, (d, bearing_deg, view_deg) in enumerate(VIEWS):
        b = math.radians(bearing_deg)
        x, y = d * math.cos(b), d * math.sin(b)
        facing = None if view_deg == 0 else math.pi + b + math.radians(view_deg)
        world = world_with(Thing(label, x, y, facing))
        tilt, zoom = framing(label, d)
        img = render(world, (0, 0, 0), tilt, zoom, SPEC, np.random.default_rng(k))
        found = recogniser.recognise(img, CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov,
                                                         zoom, tilt))
        where = f"{label} at {d} m, {bearing_deg} deg off-axis, seen {view_deg} deg off its front"
        assert [s.label for s in found] == [label], where
        s = found[0]
        assert s.range == pytest.approx(d, rel=0.2), where
        assert abs(s.bearing - b) < math.radians(2), where
        assert s.inliers >= recogniser.params.min_inliers and 0 < s.score <= 1


def test_no_false_recognitions_on_office_views_without_objects(recogniser):
    from sim2d.world import load_world
    from sim2d.worlds import world_path
    world = load_world(world_path("office"))
    world.objects = []
    rng = np.random.default_rng(7)
    free = np.argwhere(~world.occupied)
    false = []
    n = 0
    while n < 200:
        r, c = free[int(rng.integers(len(free)))]
        x = world.origin[0] + (c + 0.5) * world.resolution
        y = world.origin[1] + (world.occupied.shape[0] - r - 0.5) * world.resolution
        from sim2d.world import distance_to_segments
        if distance_to_segments(np.array([x, y]), world.segments).min() < 0.4:
            continue
        pose = (x, y, rng.uniform(-math.pi, math.pi))
        tilt, zoom = rng.uniform(-0.1, 0.4), rng.uniform(1.0, 3.0)
        img = render(world, pose, tilt, zoom, SPEC, np.random.default_rng(n))
        found = recogniser.recognise(img, CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov,
                                                         zoom, tilt))
        false += [(pose, s.label) for s in found]
        n += 1
    assert false == []


def test_a_recognised_object_is_placed_in_the_world(recogniser):
    robot = (1.0, 2.0, 0.3)
    pan = -0.2
    cam = camera_pose(robot, SPEC, pan)
    target = (cam[0] + 2.5 * math.cos(cam[2] + 0.1), cam[1] + 2.5 * math.sin(cam[2] + 0.1))
    world = world_with(Thing("Bookshelf", *target),
                       walls=[[-4, -4, 8, -4], [8, -4, 8, 8], [8, 8, -4, 8], [-4, 8, -4, -4]])
    img = render(world, cam, 0.3, 1.0, SPEC, np.random.default_rng(3))
    found = recogniser.recognise(img, CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, 1.0, 0.3))
    assert [s.label for s in found] == ["Bookshelf"]
    x, y = object_world_position(found[0], robot, pan, (SPEC.mount_x, SPEC.mount_y))
    assert math.hypot(x - target[0], y - target[1]) < 0.25
    truth = visible_objects(world, cam, 0.3, 1.0, SPEC)
    m = match_sightings(found, truth)
    assert (m.true_positives, m.false_positives, m.false_negatives) == (1, 0, 0)
    assert match_sightings([], truth, min_visible=0.5).false_negatives == 1


def test_the_recognizer_block_places_merges_scores_and_saves(tmp_path):
    from blocks.core.block import RunContext
    from blocks.objects.blocks import Recognizer
    ctx = RunContext(dt=0.1, seed=0, out_dir=tmp_path)
    params = {name: p.default for name, p in Recognizer.params.items()}
    block = Recognizer(params, name="objects", ctx=ctx)
    block.reset()
    robot, pan = np.array([0.0, 0.0, 0.0]), 0.0
    world = world_with(Thing("Shredder", 2.0, 0.2))
    cam = camera_pose(robot, SPEC, pan)
    tilt, zoom = 0.0, 1.0
    model = CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt)
    for tick in range(3):
        ctx.tick = tick
        img = render(world, cam, tilt, zoom, SPEC, np.random.default_rng(tick))
        out = block.step(image=img, camera=model, pose=robot, pan=pan,
                         visible=visible_objects(world, cam, tilt, zoom, SPEC))
        assert [o["label"] for o in out["objects"]] == ["Shredder"]
        o = out["objects"][0]
        assert math.hypot(o["x"] - 2.0, o["y"] - 0.2) < 0.2 and o["tick"] == tick
    block.finish()
    metrics = ctx.metrics["objects"]
    assert metrics["objects"] == 1 and metrics["merged"][0]["count"] == 3
    assert metrics["frames_rejected_early"] == 0  # every frame shows the shredder
    assert (metrics["precision"], metrics["recall"]) == (1.0, 1.0)
    assert len(list((tmp_path / "objects").glob("*.png"))) == 3


# ---- the early reject ----------------------------------------------------------------------------
def grey_of(img):
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)


def object_view(label, k=0):
    """A frame of one catalogue object in the hall, at VIEWS[k], framed as a camera head would."""
    d, bearing_deg, view_deg = VIEWS[k]
    b = math.radians(bearing_deg)
    facing = None if view_deg == 0 else math.pi + b + math.radians(view_deg)
    tilt, zoom = framing(label, d)
    img = render(world_with(Thing(label, d * math.cos(b), d * math.sin(b), facing)), (0, 0, 0),
                 tilt, zoom, SPEC, np.random.default_rng(k))
    return img, CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt)


def same_sightings(a, b):
    return len(a) == len(b) and all(
        x.label == y.label and x.bbox == y.bbox and np.array_equal(x.corners, y.corners)
        and (x.inliers, x.score, x.bearing, x.range) == (y.inliers, y.score, y.bearing, y.range)
        for x, y in zip(a, b))


@pytest.mark.parametrize("label", sorted(default_catalogue().labels))
def test_the_early_reject_lets_every_object_through(recogniser, label):
    for k in (0, 2, 4):  # close and head-on, far, seen 40 deg off its front
        img, _ = object_view(label, k)
        assert recogniser.gate.verdict(grey_of(img)) == "passed", (label, VIEWS[k])


def test_the_early_reject_rules_out_a_blank_wall_at_its_first_step(recogniser):
    gate = recogniser.gate
    gate.reset_counts()
    for k, tilt in enumerate((0.0, 0.3)):
        img = render(world_with(), (6.0, 1.0, 0.2), tilt, 1.0, SPEC, np.random.default_rng(k))
        assert gate.evidence(grey_of(img)).corners < gate.min_corners
        assert recogniser.recognise(img, CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov,
                                                        1.0, tilt)) == []
    assert gate.counts == {"few corners": 2, "no textured region": 0, "few votes": 0,
                           "passed": 0}


def test_the_early_reject_rules_out_a_door_sign_by_its_votes(recogniser):
    """An oblique door sign has corners and a textured region, but its crop matches no picture."""
    gate = recogniser.gate
    world = world_with(walls=HALL)
    world.signs = [Sign("OFFICE 102", 8.95, 0.0, math.pi)]
    img = render(world, (6.0, 0.0, 0.3), math.atan2(1.2 - SPEC.mount_z, 3.0), 1.0, SPEC,
                 np.random.default_rng(0))
    e = gate.evidence(grey_of(img))
    assert e.corners >= gate.min_corners and e.votes, "the sign reaches the votes"
    assert max(e.votes) < gate.min_votes
    assert gate.verdict(grey_of(img)) == "few votes"


def test_recognitions_are_the_same_with_and_without_the_early_reject(recogniser):
    """Objects in the hall, and office views (with its objects) from random free poses."""
    from sim2d.world import distance_to_segments, load_world
    from sim2d.worlds import world_path
    plain = ObjectRecogniser(params=RecogniserParams(early_reject=False))
    frames = [object_view(label, k) for k, label in enumerate(sorted(default_catalogue().labels))
              for k in (k % len(VIEWS),)]
    world = load_world(world_path("office"))
    rng = np.random.default_rng(11)
    free = np.argwhere(~world.occupied)
    while len(frames) < 17 + 40:
        r, c = free[int(rng.integers(len(free)))]
        x = world.origin[0] + (c + 0.5) * world.resolution
        y = world.origin[1] + (world.occupied.shape[0] - r - 0.5) * world.resolution
        if distance_to_segments(np.array([x, y]), world.segments).min() < 0.4:
            continue
        tilt, zoom = rng.uniform(-0.1, 0.4), rng.uniform(1.0, 3.0)
        img = render(world, (x, y, rng.uniform(-math.pi, math.pi)), tilt, zoom, SPEC,
                     np.random.default_rng(len(frames)))
        frames.append((img, CameraModel.of(SPEC.width, SPEC.height, SPEC.hfov, zoom, tilt)))
    found = 0
    for img, model in frames:
        a, b = recogniser.recognise(img, model), plain.recognise(img, model)
        assert same_sightings(a, b)
        found += bool(a)
    assert found >= 15, "the frames include recognitions"


def test_the_early_reject_is_for_sift_only():
    with pytest.raises(ValueError, match="SIFT"):
        RecogniserParams(feature="orb")
    assert ObjectRecogniser(params=RecogniserParams(feature="orb", early_reject=False)).gate is None
    assert ObjectRecogniser(params=RecogniserParams()).gate is not None


@pytest.mark.parametrize("kw, msg", [({"cell": 0}, "cell"), ({"margin": -1}, "margin"),
                                     ({"votes_share": 0.0}, "votes_share"),
                                     ({"votes_share": 1.5}, "votes_share"),
                                     ({"dims": 0}, "dims")])
def test_gate_params_reject(kw, msg):
    with pytest.raises(ValueError, match=msg):
        GateParams(**kw)


def test_textured_regions_join_touching_squares_and_count_corners():
    # 10 px squares on a 30 x 40 image: (0,0),(1,1) touch diagonally; (3,0) is alone;
    # a corner on the last column lands in the last square, its box clipped to the image
    pts = np.array([[2, 2], [5, 5], [15, 12], [35, 3], [39.9, 4]])
    regions = textured_regions(pts, (30, 40), 10)
    assert [(r.box, r.corners, r.cells) for r in regions] == [
        ((0, 0, 20, 20), 3, 2), ((30, 0, 40, 10), 2, 1)]
    assert textured_regions(np.zeros((0, 2)), (30, 40), 10) == []


@pytest.mark.parametrize("dtype, norm", [(np.float32, cv2.NORM_L2),
                                         (np.uint8, cv2.NORM_HAMMING)])
def test_ratio_matches_are_knn_match_s(dtype, norm):
    """Same matches, in the same order, as BFMatcher.knnMatch and the ratio test."""
    rng = np.random.default_rng(5)
    train = rng.integers(0, 200, (60, 16)).astype(dtype)
    train[30:40] = train[0:10]  # two equally good matches: the ratio test must refuse both
    near = train[[3, 12, 35, 50]].copy()
    near[:, 0] = near[:, 0] // 2  # close to one train row (a duplicated one for 3 and 35)
    query = np.vstack([near, rng.integers(0, 200, (40, 16))]).astype(dtype)
    pairs = cv2.BFMatcher(norm).knnMatch(query, train, k=2)
    want = [(p[0].queryIdx, p[0].trainIdx) for p in pairs
            if len(p) == 2 and p[0].distance < 0.8 * p[1].distance]
    q, t = ratio_matches(query, train, 0.8, norm)
    assert list(zip(q.tolist(), t.tolist())) == want
    assert {1, 3} <= set(q.tolist()) and not {0, 2} & set(q.tolist())


@pytest.mark.parametrize("dims", [16, 32, 128])
def test_ratio_matcher_gives_ratio_matches_to_the_bit(dims):
    """Same matches as ratio_matches, also where only the distances' rounding decides.

    Most queries lie 4/9 of the way from one train row to another, where the
    ratio of their distances is 0.8 up to rounding: the product's bounds must
    send those to batchDistance (without them, dozens come out otherwise).
    """
    rng = np.random.default_rng(dims)
    train = rng.normal(0, 50, (300, dims)).astype(np.float32)
    train[:, : dims // 2] = np.round(np.abs(train[:, : dims // 2]))  # SIFT's are integers
    train[200:210] = train[0:10]  # two equally near rows: no match
    a, b = train[rng.integers(0, 300, 1500)], train[rng.integers(0, 300, 1500)]
    edge = (a + np.float32(4 / 9) * (b - a)).astype(np.float32)
    near = train[rng.integers(0, 300, 300)] + rng.normal(0, 5, (300, dims)).astype(np.float32)
    query = np.vstack([edge, near, rng.normal(0, 50, (200, dims))]).astype(np.float32)
    matcher = RatioMatcher(train, 0.8)
    for q in (query, query[:1], query[:0]):
        want, got = ratio_matches(q, train, 0.8), matcher(q)
        assert all(np.array_equal(w, g) and w.dtype == g.dtype for w, g in zip(want, got))
    assert len(ratio_matches(query, train, 0.8)[0]) > 300
    lonely = RatioMatcher(train[:1], 0.8)(query)  # a single row: no second nearest, no match
    assert all(len(x) == 0 for x in lonely)
