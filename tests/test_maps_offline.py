"""The offline map's parts without the framework: features, prediction, drift, the map itself."""
from __future__ import annotations

import math

import numpy as np
import pytest

from blocks.maps.drift import DriftCorrection, DriftCorrector, correct_odometry, corrected_run
from blocks.maps.features import (extract_linear_features, merge_features, predict_ranges,
                                  sensor_poses_along)
from blocks.maps.logodds import InverseSonarModel, LogOddsMap
from blocks.maps.offline import (READING_CLASSES, OfflineMapParams, build_offline_map,
                                 classify_readings)
from sim2d.robot import load_robot
from sim2d.sonar import SonarSpec, sonar_readings

SPEC = load_robot("atrv_mini")
MOUNTS = np.asarray(SPEC.sonar_mounts)

# A 12 m x 3 m corridor closed at both ends (wall capsules x1, y1, x2, y2, radius).
CORRIDOR = np.array([
    [0.0, 0.0, 12.0, 0.0, 0.05],
    [0.0, 3.0, 12.0, 3.0, 0.05],
    [0.0, 0.0, 0.0, 3.0, 0.05],
    [12.0, 0.0, 12.0, 3.0, 0.05],
])
WALL_SURFACES = {"south": 0.05, "north": 2.95}


def corridor_run(specular: bool, y: float = 0.8, steps: int = 200, seed: int = 0):
    """Drive east along the corridor 0.75 m from the south wall; poses and sonar readings."""
    rng = np.random.default_rng(seed)
    spec = SonarSpec(specular=specular, noise_std=0.01)
    poses = np.array([[1.0 + 0.045 * k, y, 0.0] for k in range(steps)])
    ranges, echo = [], []
    for pose in poses:
        r, e = sonar_readings(sensor_poses_along(pose[None], MOUNTS)[0], CORRIDOR, spec, rng)
        ranges.append(r)
        echo.append(e)
    return poses, np.array(ranges), np.array(echo)


def test_collinear_echoes_become_one_feature_on_the_wall():
    poses, ranges, echo = corridor_run(specular=True)
    sensors = sensor_poses_along(poses, MOUNTS)
    features = merge_features(extract_linear_features(sensors, ranges, echo))
    long = [f for f in features if f.length > 3.0]
    assert long, [f.length for f in features]
    for f in long:
        # horizontal walls, normal pointing back at the robot, on a true wall surface
        assert abs(f.normal[0]) < 0.05
        y_wall = float((f.p0[1] + f.p1[1]) / 2)
        assert min(abs(y_wall - w) for w in WALL_SURFACES.values()) < 0.03, y_wall
        assert np.sign(f.normal[1]) == np.sign(0.8 - y_wall)
        assert f.residual < 0.03


def test_merging_many_pieces_of_a_wall_keeps_no_intermediate_merges():
    """A long wall seen in 400 pieces merges into one, in memory proportional to its echoes
    (each merge is a new feature holding all the echoes so far: kept, they add up to the
    square of the wall's length, hundreds of MB on a long run)."""
    import tracemalloc

    from blocks.maps.features import _refit
    rng = np.random.default_rng(2)
    pieces = []
    for k in range(400):
        x = 0.05 * k + np.linspace(0.0, 0.06, 60)
        points = np.column_stack([x, 1.0 + rng.normal(0, 0.003, 60)])
        pieces.append(_refit(points, np.array([0.0, -1.0])))
    tracemalloc.start()
    merged = merge_features(pieces)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert len(merged) == 1 and merged[0].support == 400 * 60
    assert peak < 8 * merged[0].points.nbytes, peak  # not 400 copies of the wall


def test_oblique_echoes_are_placed_on_the_wall_not_on_the_beam_axis():
    """A sensor 45 degrees off the wall hears its cone edge; its echoes must land on the wall."""
    diagonal = [j for j, m in enumerate(MOUNTS) if 30 < abs(math.degrees(m[2])) < 60]
    poses, ranges, echo = corridor_run(specular=False)
    sensors = sensor_poses_along(poses, MOUNTS)[:, diagonal]
    features = extract_linear_features(sensors, ranges[:, diagonal], echo[:, diagonal])
    assert features
    for f in features:
        y_wall = float(np.mean(f.points[:, 1]))
        assert min(abs(y_wall - w) for w in WALL_SURFACES.values()) < 0.04, y_wall


def test_prediction_is_the_cone_range_to_the_nearest_feature():
    poses, ranges, echo = corridor_run(specular=False)
    features = merge_features(extract_linear_features(sensor_poses_along(poses, MOUNTS),
                                                      ranges, echo))
    sensors = np.array([[5.0, 1.5, math.pi / 2], [5.0, 1.5, -math.pi / 2], [5.0, 1.5, 0.0]])
    predicted = predict_ranges(sensors, features, 30.0, 4.0)
    assert predicted[0] == pytest.approx(1.45, abs=0.04)
    assert predicted[1] == pytest.approx(1.45, abs=0.04)
    assert predicted[2] == np.inf or predicted[2] > 3.5  # nothing ahead within range
    assert np.all(predict_ranges(sensors, [], 30.0, 4.0) == np.inf)


def test_readings_are_classified_by_the_prediction():
    ranges = np.array([1.0, 0.5, 2.0, 4.0, 4.0, 0.8])
    echo = np.array([True, True, True, False, False, True])
    predicted = np.array([1.05, 1.0, 1.0, 1.5, np.inf, np.inf])
    cls = classify_readings(ranges, echo, predicted, 4.0, 0.1)
    assert [READING_CLASSES[c] for c in cls] == [
        "confirmed", "unexplained", "contradicted", "specular", "open", "unexplained"]


def _false_free_on_walls(m) -> float:
    """Share of true wall-surface cells along the driven stretch that the map marks free."""
    xs = np.arange(2.0, 9.0, 0.025)
    _, free, _ = m.classes()
    hits = total = 0
    for y in (0.0, 3.0):
        ix = np.floor((xs - m.origin[0]) / m.resolution).astype(int)
        iy = int(math.floor((y - m.origin[1]) / m.resolution))
        hits += int(free[iy, ix].sum())
        total += len(xs)
    return hits / total


def test_feature_prediction_stops_specular_losses_clearing_through_walls():
    poses, ranges, echo = corridor_run(specular=True)
    assert (~echo).mean() > 0.15  # the scenario really loses many echoes
    offline = build_offline_map(poses, ranges, MOUNTS, echo=echo,
                                params=OfflineMapParams(correct_drift=False)).map
    # the plain log-odds map of the same readings clears through the walls
    logodds = LogOddsMap(InverseSonarModel(), resolution=0.05)
    for pose, r in zip(poses, ranges):
        logodds.add_scan(sensor_poses_along(pose[None], MOUNTS)[0], r)
    from blocks.maps.mapio import OccupancyMap
    p, (ix, iy) = logodds.probabilities()
    plain = OccupancyMap(p, 0.05, (ix * 0.05, iy * 0.05, 0.0))
    assert _false_free_on_walls(plain) > 0.3
    assert _false_free_on_walls(offline) < 0.05


def test_offline_map_marks_walls_and_leaves_the_unexplored_unknown():
    poses, ranges, echo = corridor_run(specular=True)
    result = build_offline_map(poses, ranges, MOUNTS, echo=echo,
                               params=OfflineMapParams(correct_drift=False))
    m = result.map
    occupied, free, unknown = m.classes()
    xs, ys = m.cell_centres()
    # every occupied cell is near a true wall surface (no walls at maximum range)
    iy, ix = np.nonzero(occupied)
    near = np.zeros(len(iy), dtype=bool)
    for x1, y1, x2, y2, _ in CORRIDOR:
        px, py = xs[ix], ys[iy]
        dx, dy = x2 - x1, y2 - y1
        t = np.clip(((px - x1) * dx + (py - y1) * dy) / (dx * dx + dy * dy), 0, 1)
        near |= np.hypot(px - x1 - t * dx, py - y1 - t * dy) < 0.25
    assert occupied.sum() > 200 and near.mean() > 0.93  # echo arcs curve off oblique walls
    # both long walls are found along the driven stretch
    for y in (0.0, 3.0):
        row = int(math.floor((y - m.origin[1]) / m.resolution))
        band = occupied[row - 4:row + 5, (xs > 2) & (xs < 9)].any(axis=0)
        assert band.mean() > 0.9, y
    # outside the corridor nothing was seen: unknown, not walls (the map is unbounded)
    outside = ys < -0.5
    assert unknown[outside].all()
    assert result.class_counts()["specular"] > 0
    assert sum(result.class_counts().values()) == ranges.size


def test_drift_correction_pulls_a_drifting_odometry_back_onto_the_walls():
    poses, ranges, echo = corridor_run(specular=False, steps=200)
    # odometry with a slow heading drift: 0.02 degrees per step, about 2 degrees at the end
    drift = np.radians(0.02) * np.arange(len(poses))
    odom = poses.copy()
    step = np.diff(poses[:, 0], prepend=poses[0, 0])
    odom[:, 0] = poses[0, 0] + np.cumsum(step * np.cos(drift))
    odom[:, 1] = poses[0, 1] + np.cumsum(step * np.sin(drift))
    odom[:, 2] = drift
    corrected = correct_odometry(odom, ranges, echo, MOUNTS)
    before = np.abs(odom[:, 1] - poses[:, 1])
    after = np.abs(corrected[:, 1] - poses[:, 1])
    assert before[-1] > 0.2
    assert after[-1] < 0.5 * before[-1]
    assert after.mean() < 0.5 * before.mean()


def test_the_online_corrector_gives_the_offline_poses_chunk_by_chunk():
    """Online, a chunk's last scan gets the pose the whole-run correction gives it, and
    the scans before it the pose under the correction known when they arrived (the
    correction only ever looks back), so an explorer's map drawn on them is the
    offline map's frame."""
    truth, odom, ranges, echo = l_corridor_run(0.3, slip_deg=4.0)
    offline = correct_odometry(odom, ranges, echo, MOUNTS)
    corrector = DriftCorrector(MOUNTS)
    chunk = corrector.params.chunk
    online = np.array([corrector.add(odom[i], ranges[i], echo[i]) for i in range(len(odom))])
    ends = np.arange(chunk - 1, len(odom), chunk)
    np.testing.assert_allclose(online[ends], offline[ends], atol=1e-9)
    # in between, within one chunk's step of the offline pose, and far closer than odometry
    gap = np.hypot(*(online[:, :2] - offline[:, :2]).T)
    assert gap.max() < DriftCorrection().max_step * 1.5
    odometry_error = np.hypot(*(odom[-1, :2] - truth[-1, :2]))
    online_error = np.hypot(*(online[-1, :2] - truth[-1, :2]))
    assert online_error < 0.15 * odometry_error, (online_error, odometry_error)
    assert corrector.walls  # the walls it aligned against, in the corrected frame


def _rotated(xy: np.ndarray, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return xy @ np.array([[c, -s], [s, c]]).T


def l_corridor_run(building_angle: float, slip_deg: float, seed: int = 0, lean_deg: float = 0.0):
    """East along a corridor, a turn on the spot, then north up a corridor never seen before,
    in a building turned by ``building_angle``; the turn slips by ``slip_deg`` on the
    odometry, which then integrates the wrong heading.  With ``lean_deg`` the second
    corridor leans that much to the west of north (the building is no longer square).
    True poses, odometry, readings."""
    # the second corridor's east wall is set back 0.6 m, so no wall carries on round the turn
    walls = np.array([[0, 0, 12, 0], [0, 3, 9.5, 3], [0, 0, 0, 3], [12, 0, 12, 3],
                      [12, 3, 12.6, 3], [12.6, 3, 12.6, 15], [9.5, 3, 9.5, 15],
                      [9.5, 15, 12.6, 15]], dtype=float)
    lean, corner = math.radians(lean_deg), np.array([11.05, 1.5])
    walls[5:, :2] = _rotated(walls[5:, :2] - corner, lean) + corner
    walls[5:, 2:] = _rotated(walls[5:, 2:] - corner, lean) + corner
    walls = np.column_stack([_rotated(walls[:, :2], building_angle),
                             _rotated(walls[:, 2:], building_angle), np.full(len(walls), 0.05)])
    east = [[1.0 + 0.045 * k, 1.5, 0.0] for k in range(224)]
    turn = [[11.05, 1.5, (math.pi / 2 + lean) * k / 20] for k in range(1, 21)]
    north = [[11.05 - 0.045 * k * math.sin(lean), 1.5 + 0.045 * k * math.cos(lean),
              math.pi / 2 + lean] for k in range(1, 250)]
    local = np.array(east + turn + north)
    truth = np.column_stack([_rotated(local[:, :2], building_angle),
                             local[:, 2] + building_angle])
    odom = truth.copy()
    slip = np.zeros(len(truth))
    slip[len(east):len(east) + len(turn)] = np.radians(slip_deg) / len(turn)
    odom[:, 2] = truth[:, 2] + np.cumsum(slip)
    steps = np.hypot(*np.diff(truth[:, :2], axis=0).T)
    odom[1:, 0] = truth[0, 0] + np.cumsum(steps * np.cos(odom[1:, 2]))
    odom[1:, 1] = truth[0, 1] + np.cumsum(steps * np.sin(odom[1:, 2]))
    rng = np.random.default_rng(seed)
    spec = SonarSpec(specular=False, noise_std=0.01)
    readings = [sonar_readings(sensor_poses_along(pose[None], MOUNTS)[0], walls, spec, rng)
                for pose in truth]
    return truth, odom, np.array([r for r, _ in readings]), np.array([e for _, e in readings])


@pytest.mark.parametrize("building_angle", [0.0, 0.5])
def test_right_angled_walls_correct_heading_along_walls_never_seen_before(building_angle):
    truth, odom, ranges, echo = l_corridor_run(building_angle, slip_deg=4.0)

    def errors(poses):
        heading = np.degrees(np.abs((poses[:, 2] - truth[:, 2] + np.pi) % (2 * np.pi) - np.pi))
        return heading[-1], np.hypot(*(poses[-1, :2] - truth[-1, :2]))

    plain = correct_odometry(odom, ranges, echo, MOUNTS, params=DriftCorrection(rectilinear=False))
    right = correct_odometry(odom, ranges, echo, MOUNTS, params=DriftCorrection(rectilinear=True))
    odom_heading, odom_position = errors(odom)
    assert odom_heading > 3.9 and odom_position > 0.5  # the slip shows at the end
    plain_heading, _ = errors(plain)
    right_heading, right_position = errors(right)
    assert plain_heading > 1.0  # new walls alone cannot tell the heading
    assert right_heading < 0.5, right_heading
    assert right_position < 0.15 * odom_position, (right_position, odom_position)


def _final_errors(truth: np.ndarray, poses: np.ndarray) -> tuple[float, float]:
    """Heading (degrees) and position (m) errors of the last pose."""
    heading = math.degrees(abs((poses[-1, 2] - truth[-1, 2] + math.pi) % (2 * math.pi) - math.pi))
    return heading, float(np.hypot(*(poses[-1, :2] - truth[-1, :2])))


def test_a_corridor_that_leans_is_not_squared_up():
    """A corridor 5 degrees off square: its long wall shows that right angles cannot be
    assumed, and the run is corrected without them (graphs/mapping.yaml on a skewed room,
    tests/test_maps_graph.py, shows what squaring it up would cost)."""
    truth, odom, ranges, echo = l_corridor_run(0.3, slip_deg=0.0, lean_deg=5.0)
    poses, leaning = corrected_run(odom, ranges, echo, MOUNTS)
    plain = correct_odometry(odom, ranges, echo, MOUNTS, params=DriftCorrection(rectilinear=False))
    assert leaning is not None and leaning.length >= DriftCorrection().lean_min_length
    assert _final_errors(truth, poses)[0] < 0.5
    np.testing.assert_array_equal(poses, plain)  # corrected again without right angles
    online = DriftCorrector(MOUNTS)
    for pose, r, e in zip(odom, ranges, echo):
        online.add(pose, r, e)
    assert not online.rectilinear and online.leaning_wall is not None


def test_a_slipped_turn_is_squared_up_not_taken_for_a_leaning_wall():
    """The same corridor square, and a turn whose odometry slipped 4 degrees: its walls read
    4 degrees off the axis at first, which the correction puts right before they are long."""
    truth, odom, ranges, echo = l_corridor_run(0.3, slip_deg=4.0)
    poses, leaning = corrected_run(odom, ranges, echo, MOUNTS)
    assert leaning is None
    assert _final_errors(truth, poses)[0] < 0.5


def test_sonar_visibility_is_each_cone_drawn_up_to_its_range():
    """The row-run sums give the cells of every cone up to one cell past its true range,
    as drawing the cones one by one does; sensors whose cones leave the floor plan's
    padded grid (on any side) see nothing of it."""
    from blocks.maps.cones import cone_tables, cone_window
    from blocks.maps.mapio import occupancy_map_from_world
    from blocks.maps.visibility import sonar_visible
    from sim2d.sonar import cone_ranges
    from sim2d.world import load_world
    from sim2d.worlds import world_path

    world = load_world(world_path("office"))
    truth = occupancy_map_from_world(world)
    res, (h, w) = float(truth.resolution), truth.occupancy.shape
    rng = np.random.default_rng(8)
    n = 300
    sensors = np.column_stack([truth.origin[0] + rng.uniform(0.6, w * res - 0.6, n),
                               truth.origin[1] + rng.uniform(0.6, h * res - 0.6, n),
                               rng.uniform(-math.pi, math.pi, n)])
    ranges = np.minimum(cone_ranges(sensors, world.segments, math.radians(15), 4.0)[0], 4.0)
    reach = int(math.ceil(4.0 / res)) + 2
    tables, pad = cone_tables(res, 30.0, reach), reach + 1
    expected = np.zeros((h + 2 * pad, w + 2 * pad), bool)
    for (x, y, heading), r in zip(sensors, ranges):
        limit = math.floor(2 * (r / res + 1.0))
        window = cone_window(tables[round(math.degrees(heading)) % 360],
                             math.floor((y - truth.origin[1]) / res) + pad,
                             math.floor((x - truth.origin[0]) / res) + pad, limit // 2 + 1)
        rows, cols, codes = window
        expected[rows, cols] |= codes <= limit
    seen = sonar_visible(world, sensors)
    assert np.array_equal(seen, expected[pad:pad + h, pad:pad + w]) and seen.sum() > 10000
    far = [(truth.origin[0] - 6.0, truth.origin[1] - 6.0),
           (truth.origin[0] + w * res + 6.0, truth.origin[1] + h * res + 6.0)]
    assert not sonar_visible(world, np.array([[x, y, a] for x, y in far
                                              for a in (0.0, 1.6, 3.1, -1.6)])).any()
    x1, y1 = truth.origin[0] + w * res + 0.5, truth.origin[1] + h * res + 0.5
    for away in (0.0, 0.8, 1.6):  # facing away: the cones leave the padded grid
        assert not sonar_visible(world, np.array([[x1, y1, away]])).any()
    assert sonar_visible(world, np.array([[x1, y1, -2.3]])).any()  # facing the floor plan


def _random_feature(rng: np.random.Generator, near: np.ndarray | None = None):
    """A short wall piece anywhere (or, with ``near``, almost along that feature)."""
    if near is None:
        centre, angle = rng.uniform(0, 10, 2), rng.uniform(-np.pi, np.pi)
    else:
        along = np.array([near.normal[1], -near.normal[0]])
        centre = (near.p0 + near.p1) / 2 + along * rng.uniform(-1.5, 1.5) \
            + near.normal * rng.choice([rng.uniform(-0.4, 0.4), 0.1, -0.35, 0.35])
        angle = math.atan2(along[1], along[0]) + rng.choice(
            [rng.normal(0, 0.1), math.radians(8.0), math.radians(6.0), 0.0])
    direction = np.array([math.cos(angle), math.sin(angle)])
    points = centre + np.outer(np.linspace(-0.6, 0.6, 7), direction)
    points += rng.normal(0, 0.005, points.shape)
    from blocks.maps.features import _refit
    return _refit(points, np.array([-direction[1], direction[0]]))


def test_drift_walls_prefilter_keeps_every_wall_the_full_tests_pass():
    """``_MappedWalls.near`` only skips walls that ``_matches`` and ``_mergeable`` reject,
    also for features at the tests' bounds (8 and 6 degrees, 0.1 and 0.35 m off)."""
    from blocks.maps.drift import _matches, _MappedWalls
    from blocks.maps.features import _mergeable
    rng = np.random.default_rng(3)
    p = DriftCorrection()
    walls = _MappedWalls()
    for _ in range(150):
        walls.append(_random_feature(rng))
    cos_tol = math.cos(math.radians(p.max_angle_deg))
    passed = {"match": 0, "merge": 0}
    for k in range(400):
        f = _random_feature(rng, walls.features[k % len(walls.features)])
        match = set(walls.near(f, cos_tol, p.max_offset))
        merge = set(walls.near(f, cos_tol, 0.1, ends=True))
        for i, g in enumerate(walls.features):
            if _matches(f, g, p) is not None:
                assert i in match
                passed["match"] += 1
            if _mergeable(g, f, math.radians(p.max_angle_deg), 0.1, 0.3):
                assert i in merge
                passed["merge"] += 1
        assert len(match) < len(walls.features) // 4  # and it does skip most walls
    assert passed["match"] > 100 and passed["merge"] > 15  # the tests were exercised


def test_beams_drawn_at_once_equal_beams_drawn_one_by_one():
    """``_draw_beams`` gives, to the bit, the float32 sums of adding one reading's cone
    after the other (the offline map's definition)."""
    from blocks.maps.cones import cone_tables, cone_window
    from blocks.maps.offline import _draw_beams, beam_codes, cone_reach, grid_extent
    rng = np.random.default_rng(5)
    p = OfflineMapParams()
    n = 400
    sensors = np.column_stack([rng.uniform(0, 4, n), rng.uniform(0, 3, n),
                               rng.uniform(-np.pi, np.pi, n)])
    free_to = rng.uniform(-0.1, 4.0, n)
    hit_at = np.where(rng.random(n) < 0.6, free_to + 0.02, np.nan)
    w_free, w_occ = rng.choice([1.0, 0.7, 0.25], n), rng.choice([1.0, 0.5], n)
    reach = cone_reach(4.0, p)
    corner, shape = grid_extent(sensors, reach, p.resolution)
    log_odds, seen = np.zeros(shape, np.float32), np.zeros(shape, bool)
    _draw_beams(log_odds, seen, corner, sensors, free_to, hit_at, w_free, w_occ, p, 30.0, reach)

    expected, expected_seen = np.zeros(shape, np.float32), np.zeros(shape, bool)
    tables = cone_tables(p.resolution, 30.0, reach)
    col, row, degrees, free, lo, hi = beam_codes(sensors, free_to, hit_at, p.resolution,
                                                 p.arc_thickness)
    for i in range(n):
        far = max(free[i], hi[i])
        window = cone_window(tables[degrees[i]], row[i] - corner[1], col[i] - corner[0],
                             far // 2 + 1) if far > 0 else None
        if window is None:
            continue
        rows, cols, sub = window
        delta = np.where(sub < free[i], np.float32(p.l_free * w_free[i]), np.float32(0))
        if np.isfinite(hit_at[i]):
            delta[(sub >= lo[i]) & (sub <= hi[i])] = p.l_occ * w_occ[i]
        expected[rows, cols] += delta
        expected_seen[rows, cols] |= delta != 0
    assert np.array_equal(log_odds, expected) and np.array_equal(seen, expected_seen)
    assert seen.sum() > 1000


def test_parameters_are_checked():
    with pytest.raises(ValueError):
        OfflineMapParams(l_free=0.2)
    with pytest.raises(ValueError):
        OfflineMapParams(confirmed=1.5)
    with pytest.raises(ValueError):
        build_offline_map(np.zeros((3, 3)), np.zeros((2, 16)), MOUNTS)


def test_sonar_visibility_stops_at_the_first_wall_and_stays_in_the_cone():
    from blocks.maps.mapio import occupancy_map_from_world
    from blocks.maps.visibility import sonar_visible
    from sim2d.world import load_world
    from sim2d.worlds import world_path

    world = load_world(world_path("corridor"))  # 20 m long, walls at y = 0.1 and 2.1
    truth = occupancy_map_from_world(world)
    xs, ys = truth.cell_centres()
    seen = sonar_visible(world, np.array([[5.0, 1.1, math.pi / 2]]))  # facing the north wall
    assert seen.shape == truth.occupancy.shape
    rows, cols = np.nonzero(seen)
    assert ys[rows].max() < 2.25  # up to the wall surface, never behind it
    assert np.abs(xs[cols] - 5.0).max() < 1.0 * math.tan(math.radians(15)) + 0.1  # the cone
    wall_row = int(np.argmin(np.abs(ys - 2.1)))
    assert seen[wall_row - 1:wall_row + 2, np.abs(xs - 5.0) < 0.1].any()  # the echoing surface
    along = sonar_visible(world, np.array([[1.0, 1.1, 0.0]]))  # looking down the corridor
    assert np.abs(xs[np.nonzero(along)[1]] - 1.0).max() <= 4.1  # sonar range
    assert not along[:, xs < 0.9].any()


def test_sonar_visibility_in_chunks_equals_visibility_at_once():
    from blocks.maps.visibility import sonar_visible
    from sim2d.world import load_world
    from sim2d.worlds import world_path

    world = load_world(world_path("corridor"))
    rng = np.random.default_rng(5)
    sensors = np.column_stack([rng.uniform(0.5, 19.5, 50), rng.uniform(0.3, 1.9, 50),
                               rng.uniform(-math.pi, math.pi, 50)])
    whole = sonar_visible(world, sensors, chunk=len(sensors))
    assert whole.sum() > 1000  # the cones sweep a good part of the corridor
    assert np.array_equal(sonar_visible(world, sensors, chunk=7), whole)  # the last one short


def test_end_cells_of_all_features_at_once_are_those_one_by_one():
    from blocks.maps.features import LinearFeature
    from blocks.maps.offline import _end_cells
    rng = np.random.default_rng(22)
    res, corner = 0.025, (-40, 10)
    # ends anywhere, and some exactly on cell edges (x.5 after the shift: rounded to even)
    ends = np.concatenate([rng.uniform(-3, 3, (30, 4)),
                           (np.arange(40).reshape(10, 4) + corner[0] + 0.5) * res])
    features = [LinearFeature(e[:2], e[2:], np.array([0.0, 1.0]), np.zeros((3, 2)), 0.0)
                for e in ends]
    first, last = _end_cells(features, corner, res)
    for f, a, b in zip(features, first, last):
        assert np.array_equal(a, np.round(f.p0 / res - np.array(corner) - 0.5).astype(int))
        assert np.array_equal(b, np.round(f.p1 / res - np.array(corner) - 0.5).astype(int))
    assert first.shape == last.shape == (40, 2)
    assert [a.shape for a in _end_cells([], corner, res)] == [(0, 2), (0, 2)]


@pytest.mark.parametrize("spill", [False, True])
def test_features_drawn_on_their_window_are_those_drawn_on_the_whole_grid(spill):
    import cv2

    from blocks.maps.features import LinearFeature
    from blocks.maps.logodds import log_odds_to_probability
    from blocks.maps.offline import _draw_features, finish_map
    rng = np.random.default_rng(21)
    p = OfflineMapParams()
    shape, corner = (120, 150), (-40, 10)
    features = []
    for k in range(12):
        ends = rng.uniform([-0.9, 0.3], [2.6, 3.2], (2, 2))  # cells 4..144 across, 2..118 up
        if spill and k == 5:
            ends[1] = (3.9, 3.5)  # beyond the grid's right and top edges
        features.append(LinearFeature(ends[0], ends[1], np.array([0.0, 1.0]),
                                      np.zeros((int(rng.integers(3, 40)), 2)), 0.0))
    log_odds = rng.choice([0.0, -0.4, 0.85], shape).astype(np.float32)
    seen = log_odds != 0
    # as drawn before: every line on a grid-sized image, added everywhere
    evidence = np.zeros(shape, dtype=np.float32)
    for f in sorted(features, key=lambda f: f.support):
        a = np.round(f.p0 / p.resolution - np.array(corner) - 0.5).astype(int)
        b = np.round(f.p1 / p.resolution - np.array(corner) - 0.5).astype(int)
        cv2.line(evidence, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])),
                 float(p.feature_logodds * min(1.0, f.support / p.full_support)), 1, cv2.LINE_8)
    want, want_seen = log_odds + evidence, seen | (evidence > 0)
    got, got_seen = log_odds.copy(), seen.copy()
    _draw_features(got, got_seen, corner, features, p)
    assert np.array_equal(got, want) and np.array_equal(got_seen, want_seen)
    assert (evidence > 0).sum() > 300
    occupancy = finish_map(log_odds.copy(), seen.copy(), corner, features, p).occupancy
    np.clip(want, -p.clamp, p.clamp, out=want)
    assert np.array_equal(occupancy, np.where(
        want_seen, log_odds_to_probability(want.astype(np.float64)), np.nan), equal_nan=True)


# ---- a corridor that opens into a hall whose far wall is beyond the sonar's range -------
# The corridor (2.75 m wide) runs east to x = 10 and opens into a hall 3.5 m deep: from
# inside it the straight-ahead sonars hear nothing, while the oblique ones hear the
# corridor's walls at their ends and draw arcs across the mouth.
MOUTH_WALLS = np.array([
    [0.0, 0.0, 10.0, 0.0, 0.05], [0.0, 2.75, 10.0, 2.75, 0.05], [0.0, 0.0, 0.0, 2.75, 0.05],
    [10.0, 0.0, 10.0, -5.0, 0.05], [10.0, 2.75, 10.0, 7.75, 0.05],
    [14.5, -5.0, 14.5, 7.75, 0.05]])


def _mouth_map(with_walls: bool) -> tuple[np.ndarray, np.ndarray]:
    """Occupancy probabilities of the mouth (x 10.1..10.6, y 0.6..2.15) and of the
    corridor's south wall (x 2..8) after driving up the corridor to 1 m short of its
    end: the explorer's map, with no-echo readings cleared up to the walls the drift
    correction knows, or (without) only ``no_echo_reach``."""
    from blocks.maps.drift import DriftCorrector
    from blocks.maps.logodds import InverseSonarModel, LogOddsMap, clear_ranges

    model = InverseSonarModel(no_echo_reach=1.0)
    grid = LogOddsMap(model, resolution=0.1)
    corrector = DriftCorrector(MOUNTS)
    rng = np.random.default_rng(3)
    spec = SonarSpec(specular=True, noise_std=0.01)
    for k in range(180):
        pose = np.array([1.0 + 0.045 * k, 1.375, 0.0])
        sensors = sensor_poses_along(pose[None], MOUNTS)[0]
        ranges, echo = sonar_readings(sensors, MOUTH_WALLS, spec, rng)
        corrector.add(pose, ranges, echo)
        clear = clear_ranges(sensors, ranges, corrector.segments(), model) if with_walls \
            else None
        grid.add_scan(sensors, ranges, clear)
    p, (ix, iy) = grid.probabilities()
    xs = (np.arange(p.shape[1]) + ix + 0.5) * 0.1
    ys = (np.arange(p.shape[0]) + iy + 0.5) * 0.1
    mouth = p[np.ix_((ys > 0.6) & (ys < 2.15), (xs > 10.1) & (xs < 10.6))]
    wall = p[np.ix_(np.abs(ys) < 0.1, (xs > 2) & (xs < 8))].max(axis=0)
    return mouth, wall


def test_no_echo_readings_clear_to_the_known_walls_so_an_open_mouth_stays_open():
    """Cleared only 1 m, the silent beams leave the oblique arcs drawn across the mouth
    of the corridor: a wall where there is none, and the explorer calls the floor
    explored.  Cleared up to the walls the robot knows (none ahead), the mouth is free,
    and the corridor's own walls, where a silent beam glances off them, are not crossed."""
    closed, _ = _mouth_map(with_walls=False)
    opened, wall = _mouth_map(with_walls=True)
    assert (closed > 0.65).mean() > 0.1 and (closed < 0.35).mean() < 0.5  # a phantom wall
    assert (opened < 0.35).mean() > 0.9, (opened < 0.35).mean()
    assert (opened > 0.65).sum() == 0
    assert (wall > 0.65).all()
