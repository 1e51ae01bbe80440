"""The room visits' local maps: cone runs, exact beam sums kept between calls, the feature
memo, and LocalMaps against build_offline_map on sliding windows."""
from __future__ import annotations

import math

import numpy as np
import pytest

from blocks.maps.cones import cone_spans, cone_tables, cone_window
from blocks.maps.features import (FeatureMemo, _fit_line, _line_tests, extract_linear_features,
                                  merge_features, predict_ranges, sensor_poses_along)
from blocks.maps.local import LocalMaps
from blocks.maps.offline import OfflineMapParams, _draw_beams, beam_codes, build_offline_map
from blocks.maps.sectors import BeamSums, Beams, beam_terms, exact_weights, sum_beams
from sim2d.robot import load_robot
from sim2d.sonar import SonarSpec, sonar_readings

MOUNTS = np.asarray(load_robot("atrv_mini").sonar_mounts)
CORRIDOR = np.array([[0.0, 0.0, 12.0, 0.0, 0.05], [0.0, 3.0, 12.0, 3.0, 0.05],
                     [0.0, 0.0, 0.0, 3.0, 0.05], [12.0, 0.0, 12.0, 3.0, 0.05],
                     [5.0, 1.6, 5.6, 2.2, 0.05]])  # a crate at an angle


@pytest.fixture(scope="module")
def corridor():
    """A drive east along the corridor, a turn on the spot, and back: poses, readings."""
    rng = np.random.default_rng(3)
    out = [[1.0 + 0.045 * k, 0.9, 0.0] for k in range(150)]
    turn = [[out[-1][0], 0.9, math.pi * k / 30] for k in range(1, 31)]
    back = [[out[-1][0] - 0.045 * k, 0.9 + 0.01 * k, math.pi] for k in range(1, 120)]
    poses = np.array(out + turn + back)
    spec = SonarSpec(specular=True, noise_std=0.01)
    ranges = np.array([sonar_readings(sensor_poses_along(p[None], MOUNTS)[0], CORRIDOR, spec,
                                      rng)[0] for p in poses])
    return poses, ranges


# ---- cone runs ------------------------------------------------------------------------------
def test_cone_spans_cut_by_the_disk_are_the_table_cells_below_each_code():
    res, cone, reach = 0.1, 30.0, 12
    spans = cone_spans(res, cone, reach)
    for k, (dr, dc, codes) in enumerate(cone_tables(res, cone, reach)):
        for t in range(spans.limit + 1):
            want = np.zeros((2 * reach + 1, 2 * reach + 1), dtype=bool)
            want[reach + dr:reach + dr + codes.shape[0],
                 reach + dc:reach + dc + codes.shape[1]] = codes < t
            got = np.zeros_like(want)
            for e in range(spans.first[k, 0], spans.first[k, -1]):
                w = spans.half_width[t, abs(spans.row[e])]
                a, b = max(spans.start[e], -w), min(spans.stop[e], w + 1)
                got[reach + spans.row[e], reach + a:reach + max(a, b)] = True
            assert np.array_equal(got, want), (k, t)


# ---- exact sums -------------------------------------------------------------------------------
def _random_beams(rng: np.random.Generator, n: int, size: int, reach: int,
                  weights=(1.0, 0.5, 0.25)) -> Beams:
    p = OfflineMapParams(resolution=0.1)
    sensors = np.column_stack([rng.uniform(reach + 3, size - reach - 3, (n, 2)) * 0.1,
                               rng.uniform(-math.pi, math.pi, n)])
    ranges = rng.uniform(0.05, 1.1, n)
    echo = rng.random(n) < 0.7
    free_to = np.where(echo, ranges - 0.025, ranges)
    hit_at = np.where(echo, ranges, np.nan)
    weight = rng.choice(weights, n)
    col, row, degree, free, lo, hi = beam_codes(sensors, free_to, hit_at, p.resolution,
                                                p.arc_thickness)
    return Beams(row, col, degree, free, lo, hi,
                 (p.l_free * weight).astype(np.float32).astype(np.float64),
                 (p.l_occ * weight).astype(np.float32).astype(np.float64)), \
        (sensors, free_to, hit_at, weight, p)


def _cell_by_cell(beams: Beams, shape, reach: int, res: float = 0.1):
    """Every beam added cell by cell from the cone tables, in float64 (exact here)."""
    tables = cone_tables(res, 30.0, reach)
    total = np.zeros(shape)
    seen = np.zeros(shape, dtype=bool)
    for i in range(len(beams)):
        far = max(beams.free[i], beams.hi[i])
        if far <= 0:
            continue
        rows, cols, sub = cone_window(tables[beams.degree[i]], beams.row[i], beams.col[i],
                                      far // 2 + 1)
        delta = np.where(sub < beams.free[i], beams.free_value[i], 0.0)
        delta[(sub >= beams.lo[i]) & (sub <= beams.hi[i])] = beams.occ_value[i]
        total[rows, cols] += delta
        seen[rows, cols] |= delta != 0
    return total, seen


def test_beam_sums_are_the_exact_cell_by_cell_sums_and_the_float32_loop_to_rounding():
    rng = np.random.default_rng(0)
    reach, size = 12, 60
    beams, (sensors, free_to, hit_at, weight, p) = _random_beams(rng, 300, size, reach)
    spans = cone_spans(0.1, 30.0, reach)
    total = sum_beams(spans, beams, (0, 0), (size, size))
    want, want_seen = _cell_by_cell(beams, (size, size), reach)
    assert np.array_equal(total, want)  # exact: the order of the additions does not matter
    assert np.array_equal(total != 0, want_seen)  # no cell's readings cancel out here
    old = np.zeros((size, size), dtype=np.float32)
    old_seen = np.zeros((size, size), dtype=bool)
    _draw_beams(old, old_seen, (0, 0), sensors, free_to, hit_at, weight, weight, p, 30.0, reach)
    assert np.array_equal(old_seen, want_seen)
    assert np.abs(total - old).max() < 1e-5
    assert np.abs(total).max() > 1.0


def test_beam_terms_of_a_reading_without_echo_and_of_a_silent_one():
    b = Beams(*[np.array([v, v]) for v in (0, 0, 0)],
              np.array([8, 0]), np.array([0, 0]), np.array([-1, -1]),
              np.array([-0.4, -0.4]), np.array([0.85, 0.85]))
    beam, t, value = beam_terms(b, limit=100)
    assert beam.tolist() == [0] and t.tolist() == [8] and value.tolist() == [-0.4]


def test_cones_must_fit_in_the_grid():
    rng = np.random.default_rng(1)
    beams, _ = _random_beams(rng, 5, 60, 12)
    with pytest.raises(ValueError, match="outside the grid"):
        sum_beams(cone_spans(0.1, 30.0, 12), beams, (0, 0), (20, 20))


def test_kept_sums_give_the_sums_from_scratch_whatever_changes():
    rng = np.random.default_rng(2)
    reach, size = 12, 80
    pool, _ = _random_beams(rng, 400, size, reach)
    spans = cone_spans(0.1, 30.0, reach)
    sums = BeamSums(spans, keep=3)
    keys = np.arange(len(pool))
    windows = [(0, 200), (20, 230), (40, 260), (0, 200), (300, 400), (35, 250)]
    drawn_from_scratch = 0
    for step, (a, b) in enumerate(windows):
        index = keys[a:b]
        beams = pool.take(index)
        if step == 2:  # some readings change class: other weights, other free range
            beams = Beams(beams.row, beams.col, beams.degree, beams.free + (index % 7 == 0),
                          beams.lo, beams.hi, beams.free_value, beams.occ_value)
        # a grid that holds these cones only, at another corner every time
        r0, c0 = beams.row.min() - reach - 2, beams.col.min() - reach - 2
        shape = (beams.row.max() + reach + 3 - r0, beams.col.max() + reach + 3 - c0)
        got = sums(index, beams, (r0, c0), shape)
        assert np.array_equal(got, sum_beams(spans, beams, (r0, c0), shape)), step
        drawn_from_scratch += len(beams)
    assert sums.readings_drawn < 0.6 * drawn_from_scratch


def test_the_kept_sums_to_start_from_change_the_fewest_readings():
    """Against every kept call's cost worked out in full: windows that overlap, touch at
    one key, or lie apart."""
    from blocks.maps import sectors
    rng = np.random.default_rng(19)
    reach, size = 12, 80
    pool, _ = _random_beams(rng, 500, size, reach)
    spans = cone_spans(0.1, 30.0, reach)
    table = pool.table()
    for trial in range(20):
        sums = BeamSums(spans, keep=6)
        for _ in range(6):  # kept calls: windows of the pool, some readings changed
            a = int(rng.integers(0, 400))
            keys = np.arange(a, a + int(rng.integers(1, 100)))
            changed = table[keys].copy()
            changed[rng.uniform(size=len(keys)) < 0.1, 3] += 1
            sums._states.insert(0, sectors._State(keys, changed, pool.take(keys), (0, 0),
                                                  np.zeros((1, 2))))
        a = int(rng.integers(0, 400))
        keys = np.arange(a, a + int(rng.integers(1, 100)))
        if trial % 3 == 0:  # touching a kept window at its last key
            keys = np.arange(sums._states[0].keys[-1], sums._states[0].keys[-1] + 50)
        costs = []
        for state in sums._states:
            shared, i_old, i_new = np.intersect1d(state.keys, keys, return_indices=True)
            same = (state.table[i_old] == table[keys][i_new]).all(axis=1)
            costs.append(len(state.keys) + len(keys) - 2 * int(same.sum()))
        best, plan = sums._best_start(keys, table[keys])
        if min(costs) >= len(keys):
            assert best is None
        else:
            assert best is not None
            assert len(plan[0]) + len(plan[1]) == min(costs)
            assert costs[[id(s) for s in sums._states].index(id(best))] == min(costs)


def test_fraction_bits_are_the_least_power_that_makes_every_value_whole():
    from blocks.maps.sectors import fraction_bits
    rng = np.random.default_rng(20)
    sets = [rng.normal(0, 3, 9), rng.normal(0, 3, 9).astype(np.float32).astype(np.float64),
            np.float32([-0.4, 0.85, -0.2, 0.425]).astype(np.float64),
            np.array([5e-324, 3.0]), np.array([6 * 2.0 ** -1074]), np.array([1e300, 2.0]),
            np.array([1.0, 2.0, 3.0]), np.array([0.5, -0.75])]
    sets += [rng.integers(-999, 999, 5) * 2.0 ** int(k) for k in rng.integers(-70, 20, 30)]
    for values in sets:
        values = values[values != 0]
        e = 0  # as exact_weights tried it: e = 0, 1, ... until every value is whole
        with np.errstate(over="ignore"):  # inf is whole
            while e <= 1100 and not (np.ldexp(values, e) == np.round(np.ldexp(values, e))
                                     ).all():
                e += 1
        assert fraction_bits(values) == e, values


def test_weights_that_do_not_sum_exactly_are_never_kept():
    rng = np.random.default_rng(4)
    beams, _ = _random_beams(rng, 50, 60, 12)
    odd = Beams(beams.row, beams.col, beams.degree, beams.free, beams.lo, beams.hi,
                beams.free_value + 0.1, beams.occ_value)
    assert not exact_weights(odd.free_value, 100)
    sums = BeamSums(cone_spans(0.1, 30.0, 12))
    for _ in range(2):
        got = sums(np.arange(50), odd, (0, 0), (60, 60))
    assert sums.readings_drawn == 100  # drawn from scratch both times
    # the same sums, rounded the same way (running sums in np.cumsum's order)
    assert np.array_equal(got, sum_beams(sums.spans, odd, (0, 0), (60, 60)))


# ---- features ---------------------------------------------------------------------------------
def _fit_test(points: np.ndarray, q: np.ndarray, tol: float) -> bool:
    centre, direction = _fit_line(points)
    return abs(direction[0] * (q[1] - centre[1]) - direction[1] * (q[0] - centre[0])) > tol


def test_fast_line_tests_agree_with_the_fit_or_say_they_are_unsure():
    rng = np.random.default_rng(5)
    along = np.cumsum(rng.uniform(0.0, 0.06, 300))
    pts = np.column_stack([10 + along, 3 + 0.02 * np.sin(along * 3) + rng.normal(0, 0.02, 300)])
    pts[150:160] = pts[150]  # the robot standing still: all echoes in one place
    status = _line_tests(pts, 20, 0.04)
    decided = unsure = 0
    for s in range(len(pts) - 21):
        for length in range(3, 21):
            code = status[s, length]
            if code == 2:
                unsure += 1
                continue
            decided += 1
            assert bool(code) == _fit_test(pts[s:s + length], pts[s + length], 0.04)
    assert unsure > 0 and decided > 50 * unsure
    assert (status[150, 3:10] == 2).all()  # identical points: no line to trust


def test_line_tests_of_some_starts_are_those_rows():
    rng = np.random.default_rng(12)
    pts = np.cumsum(rng.normal(0, 0.05, (700, 2)), axis=0)
    starts = np.sort(rng.choice(700, 300, replace=False))
    assert np.array_equal(_line_tests(pts, 20, 0.04, starts), _line_tests(pts, 20, 0.04)[starts])


def _readable(status: np.ndarray, lengths) -> np.ndarray:
    """The entries (s, L) with s + L inside s's segment: those extract_linear_features reads."""
    end = np.repeat(np.cumsum(lengths), lengths)
    return np.arange(len(status))[:, None] + np.arange(status.shape[1])[None, :] < end[:, None]


def test_kept_line_tests_are_those_of_the_same_echoes(monkeypatch):
    from blocks.maps import features
    from blocks.maps.features import _echo_windows
    rng = np.random.default_rng(13)
    pool = np.cumsum(rng.normal(0, 0.03, (400, 2)), axis=0)  # echo k of a sensor at pool[k]
    tested = []
    plain = features._line_tests

    def counted(pts, recent, line_tol, starts=None):
        tested.append(len(pts) if starts is None else len(starts))
        return plain(pts, recent, line_tol, starts)

    monkeypatch.setattr(features, "_line_tests", counted)
    memo = FeatureMemo()
    calls = [[np.arange(0, 150), np.arange(200, 260)],
             [np.arange(0, 170), np.arange(200, 260)],  # grew at its end
             [np.arange(10, 80), np.arange(81, 170), np.arange(200, 300)],  # a hole at 80
             [np.arange(10, 80), np.arange(81, 170), np.arange(200, 300)]]  # the same again
    for segments in calls:
        names = np.concatenate(segments)
        lengths = np.array([len(part) for part in segments])
        got = memo.line_tests(pool[names], _echo_windows(names, lengths, 20), 0.04)
        want = plain(pool[names], 20, 0.04)
        readable = _readable(want, lengths)
        assert np.array_equal(got[readable], want[readable])
    assert tested[0] == 210 and tested[1] < 60 and tested[3] == 0


def _same_features(a, b) -> bool:
    return len(a) == len(b) and all(
        np.array_equal(f.points, g.points) and np.array_equal(f.p0, g.p0)
        and np.array_equal(f.p1, g.p1) and f.residual == g.residual for f, g in zip(a, b))


def test_the_memo_gives_the_features_of_a_call_without_it(corridor):
    poses, ranges = corridor
    echo = ranges < 3.95
    memo = FeatureMemo(max_age=2)
    for a, b in [(0, 120), (10, 140), (10, 200), (60, 299), (0, 120), (100, 250)]:
        index = np.arange(a, b)
        index = index[index % 9 != 4]  # holes, as the distance filter leaves
        sensors = sensor_poses_along(poses[index], MOUNTS)
        plain = extract_linear_features(sensors, ranges[index], echo[index])
        kept = extract_linear_features(sensors, ranges[index], echo[index], ids=index, memo=memo)
        assert plain and _same_features(plain, kept)
        assert _same_features(merge_features(plain), merge_features(kept, memo=memo))
    assert memo.hits > 100  # segments, runs and merges seen before


def test_a_memo_needs_ids():
    with pytest.raises(ValueError, match="ids"):
        extract_linear_features(np.zeros((2, 1, 3)), np.ones((2, 1)), np.ones((2, 1), bool),
                                memo=FeatureMemo())


# ---- local maps -------------------------------------------------------------------------------
def test_local_maps_are_the_offline_maps_of_their_windows(corridor):
    poses, ranges = corridor
    maps = LocalMaps(MOUNTS, params=OfflineMapParams(correct_drift=False))
    params = OfflineMapParams(correct_drift=False)
    checked = 0
    for t, (pose, r) in enumerate(zip(poses, ranges)):
        maps.add(0.1 * t, pose, r)
        if t % 40 != 39:
            continue
        for since, near in [(0.1 * t - 12.0, tuple(pose[:2])), (0.1 * t - 20.0, (6.0, 1.5))]:
            index = maps.window(since, near, 4.0)
            built = maps.build(index)
            want = build_offline_map(poses[index], ranges[index], MOUNTS, params=params)
            assert _same_features(built.features, want.features)
            assert np.array_equal(built.predicted, want.predicted)
            assert np.array_equal(built.reading_class, want.reading_class)
            assert built.map.origin == want.map.origin
            for got, exp in zip(built.map.classes(), want.map.classes()):
                assert np.array_equal(got, exp)
            assert np.nanmax(np.abs(built.map.occupancy - want.map.occupancy)) < 1e-4
            checked += 1
    assert checked == 14
    assert len(maps) == len(poses)


def test_local_maps_take_scans_in_time_order_and_known_indices():
    maps = LocalMaps(MOUNTS)
    maps.add(1.0, np.zeros(3), np.full(16, 2.0))
    with pytest.raises(ValueError, match="time order"):
        maps.add(0.5, np.zeros(3), np.full(16, 2.0))
    with pytest.raises(ValueError, match="index"):
        maps.build(np.array([0, 1]))
    assert maps.window(0.0, (10.0, 0.0), 1.0).size == 0


def test_cone_geometry_element_by_element_is_cone_ranges():
    from sim2d.sonar import cone_ranges, nearest_in_cone
    rng = np.random.default_rng(6)
    sensors = np.column_stack([rng.uniform(0, 12, 200), rng.uniform(0, 3, 200),
                               rng.uniform(-math.pi, math.pi, 200)])
    half = math.radians(15)
    for segment in CORRIDOR:  # paired with each sensor: as cone_ranges, one capsule at a time
        want, _ = cone_ranges(sensors, segment[None], half, 4.0)
        dist = nearest_in_cone(sensors[:, 0], sensors[:, 1], np.cos(sensors[:, 2]),
                               np.sin(sensors[:, 2]), np.tile(segment, (200, 1)), half)[0]
        got = np.where(dist <= 4.0, np.maximum(dist, 0.0), np.inf)
        assert np.array_equal(got, want)
        assert np.isfinite(want).any()


def test_kept_predictions_are_the_predictions(corridor):
    poses, ranges = corridor
    echo = ranges < 3.95
    memo = FeatureMemo()
    kept = []
    # sliding windows, as LocalMaps builds them, and one window again (its every feature kept)
    for a, b in [(0, 150), (30, 200), (30, 260), (30, 260), (40, 260)]:
        index = np.arange(a, b)
        sensors = sensor_poses_along(poses[index], MOUNTS)
        # features from the memo: those the windows share are the same objects, whose
        # kept predictions the later windows look up
        features = merge_features(extract_linear_features(sensors, ranges[index], echo[index],
                                                          ids=index, memo=memo), memo=memo)
        flat = sensors.reshape(-1, 3)
        keys = (index[:, None] * 16 + np.arange(16)).ravel()
        want = predict_ranges(flat, features, 30.0, 4.0)
        hits = memo.hits
        assert np.array_equal(predict_ranges(flat, features, 30.0, 4.0, ids=keys, memo=memo),
                              want)
        kept.append((memo.hits - hits, len(features)))
        assert np.isfinite(want).mean() > 0.5
    # (hits, features) per window: none at first; some kept rows, all, and some matched
    # into another window's sensor ids
    assert kept[0][0] == 0 and kept[2][0] > 0 and kept[3][0] == kept[3][1] > 0
    assert kept[4][0] > 0


def test_kept_predictions_of_windows_that_gain_and_lose_sensors(corridor):
    """Features kept from calls two and one back, sensors that come, go and come back."""
    poses, ranges = corridor
    sensors = sensor_poses_along(poses, MOUNTS).reshape(-1, 3)
    keys = np.arange(len(sensors))
    features = merge_features(extract_linear_features(
        sensor_poses_along(poses, MOUNTS), ranges, ranges < 3.95))
    memo = FeatureMemo()
    rng = np.random.default_rng(12)
    for step in range(6):
        index = np.sort(rng.choice(len(sensors), 1500, replace=False))
        some = [f for f in features if rng.uniform() < 0.7]  # some known, some not
        want = predict_ranges(sensors[index], some, 30.0, 4.0)
        got = predict_ranges(sensors[index], some, 30.0, 4.0, ids=keys[index], memo=memo)
        assert np.array_equal(got, want), step
        assert np.isfinite(want).mean() > 0.3
    assert memo.hits > 0


def test_kept_predictions_need_increasing_ids():
    sensors = np.zeros((3, 3))
    features = merge_features(extract_linear_features(*_wall_run()))
    with pytest.raises(ValueError, match="increasing"):
        predict_ranges(sensors, features, 30.0, 4.0, ids=np.array([0, 2, 1]),
                       memo=FeatureMemo())


def _wall_run():
    """A sensor driving along a wall 1 m to its left: sensors, ranges, echo."""
    poses = np.column_stack([np.linspace(0, 3, 40), np.zeros(40), np.zeros(40)])
    sensors = sensor_poses_along(poses, np.array([[0.0, 0.0, math.pi / 2]]))
    ranges = np.ones((40, 1))
    return sensors, ranges, ranges < 3.9


def test_box_pairs_are_the_sensors_near_each_box():
    from blocks.maps.features import _box_pairs
    rng = np.random.default_rng(13)
    ends = rng.uniform(0, 10, (7, 4))
    sx, sy = rng.uniform(-5, 15, 400), rng.uniform(-5, 15, 400)
    for members, cand in [(np.arange(7), None), (np.array([1, 4, 6]), np.arange(0, 400, 3))]:
        which, i = _box_pairs(ends, members, sx, sy, cand, 2.0)
        want = set()
        for k in members:
            for j in (range(400) if cand is None else cand):
                if min(ends[k, 0], ends[k, 2]) - 2 <= sx[j] <= max(ends[k, 0], ends[k, 2]) + 2 \
                        and min(ends[k, 1], ends[k, 3]) - 2 <= sy[j] <= \
                        max(ends[k, 1], ends[k, 3]) + 2:
                    want.add((int(k), int(j)))
        assert set(zip(which.tolist(), i.tolist())) == want
        assert 0 < len(want) < len(members) * 400


def test_the_quick_merge_test_agrees_or_defers():
    rng = np.random.default_rng(7)
    from blocks.maps.features import LinearFeature, _mergeable, _mergeable_quick

    def feature(x0, y0, x1, y1):
        d = np.array([x1 - x0, y1 - y0]) / math.hypot(x1 - x0, y1 - y0)
        return LinearFeature(np.array([x0, y0]), np.array([x1, y1]), np.array([-d[1], d[0]]),
                             np.zeros((0, 2)), 0.0)

    def numbers(f):
        return (*f.normal.tolist(), *f.p0.tolist(), *f.p1.tolist())

    deferred = 0
    for _ in range(2000):
        x, y = rng.uniform(0, 10, 2)
        a = feature(x, y, x + rng.uniform(0.5, 3), y + rng.normal(0, 0.05))
        b = feature(*(a.p1 + rng.normal(0, 0.2, 2)), *(a.p1 + [rng.uniform(0.3, 2), 0]
                                                       + rng.normal(0, 0.1, 2)))
        quick = _mergeable_quick(numbers(a), numbers(b), math.cos(math.radians(6)), 0.1, 0.3)
        if quick is None:
            deferred += 1
        else:
            assert quick == _mergeable(a, b, math.radians(6), 0.1, 0.3)
    edge = feature(0, 0, 1, 0), feature(1.3, 0, 2, 0)  # a gap of exactly max_gap
    assert _mergeable_quick(numbers(edge[0]), numbers(edge[1]), 0.99, 0.1, 0.3) is None
    assert deferred < 20


def test_readings_checks_at_once_are_the_checks_one_by_one(corridor):
    from blocks.maps.features import _explained, _explains
    poses, ranges = corridor
    sensors = sensor_poses_along(poses[:150], MOUNTS)
    features = extract_linear_features(sensors, ranges[:150], ranges[:150] < 3.95)
    rng = np.random.default_rng(8)
    checks = []
    for i, f in enumerate(features[:12]):
        rows, j = rng.choice(150, 30, replace=False), int(rng.integers(16))
        checks.append((i, f, sensors[rows, j], ranges[rows, j]))
    want = [_explains(f, s, r, 30.0, 0.08) for _, f, s, r in checks]
    assert _explained(checks, 30.0, 0.08) == want
    assert any(want) and not all(want)


def test_segments_without_line_breaks_are_those_first_break_passes_over():
    from blocks.maps.features import _no_line_breaks
    rng = np.random.default_rng(18)
    recent = 6
    for _ in range(300):
        lengths = rng.integers(1, 16, int(rng.integers(1, 6)))
        status = np.zeros((int(lengths.sum()), recent + 1), dtype=np.int8)
        hits = rng.integers(0, status.size, int(rng.integers(0, 3)))
        status.ravel()[hits] = rng.integers(1, 3, len(hits))
        want, at = [], 0
        for n in lengths.tolist():  # what first_break reads from a segment's first echo
            part = status[at:at + n]
            short, long = part[0, 3:min(recent, n)], part[:max(0, n - recent), recent]
            want.append(not np.concatenate([short, long]).any())
            at += n
        assert _no_line_breaks(status, lengths, recent).tolist() == want


def test_line_tests_need_three_echoes():
    with pytest.raises(ValueError, match="recent"):
        extract_linear_features(np.zeros((2, 1, 3)), np.ones((2, 1)), np.ones((2, 1), bool),
                                recent=2)


def test_line_tests_in_chunks_equal_line_tests_at_once(monkeypatch):
    from blocks.maps import features
    rng = np.random.default_rng(3)
    pts = np.cumsum(rng.normal(0, 0.05, (301, 2)), axis=0)
    whole = _line_tests(pts, 20, 0.04)
    monkeypatch.setattr(features, "LINE_TEST_ROWS", 7)  # 43 chunks, the last one short
    assert np.array_equal(_line_tests(pts, 20, 0.04), whole)


# ---- the cheaper paths give what the plain ones give -----------------------------------------
def test_cut_cones_leave_no_run_outside_the_rows_they_reach():
    spans = cone_spans(0.1, 30.0, 12)
    narrower = 0
    for k in range(0, 360, 7):
        for t in range(spans.limit + 1):
            lo, hi = spans.reached_from[k, t], spans.reached_to[k, t]
            y = spans.rows_below[t]
            band = range(spans.first[k, spans.reach - y], spans.first[k, spans.reach + y + 1]) \
                if y >= 0 else range(0)
            assert lo >= hi or (band.start <= lo and hi <= band.stop)
            for e in band:
                if lo <= e < hi:
                    continue
                w = spans.half_width[t, spans.abs_row[e]]
                assert max(spans.start[e], -w) >= min(spans.stop[e], w + 1), (k, t, e)
                narrower += 1
    assert narrower > 1000


def test_rings_leave_no_run_outside_the_rows_they_cross():
    spans = cone_spans(0.1, 30.0, 12)

    def cut(e, t):
        w = spans.half_width[t, spans.abs_row[e]]
        a = max(spans.start[e], -w)
        return a, max(a, min(spans.stop[e], w + 1))

    skipped = 0
    for k in range(0, 360, 7):
        for inner in range(spans.limit + 1):
            for outer in range(inner + 1, min(inner + 7, spans.limit) + 1):
                lo = max(spans.reached_from[k, outer], spans.beyond_from[k, inner])
                hi = min(spans.reached_to[k, outer], spans.beyond_to[k, inner])
                for e in range(spans.first[k, 0], spans.first[k, -1]):
                    if lo <= e < hi:
                        continue
                    a_out, b_out = cut(e, outer)
                    a_in, b_in = cut(e, inner)
                    # the same run, or none, at both bounds: the ring's entries would cancel
                    assert (a_out, b_out) == (a_in, b_in) or (a_out == b_out and a_in == b_in), \
                        (k, inner, outer, e)
                    skipped += b_out > a_out
    assert skipped > 10000  # runs of the cones that the rings pass over


def test_beam_rings_are_the_beam_terms_paired():
    from blocks.maps.sectors import beam_rings
    rng = np.random.default_rng(11)
    beams, _ = _random_beams(rng, 300, 60, 12)
    beam, t, value = beam_terms(beams, limit=26)
    r_beam, outer, inner, r_value = beam_rings(beams, limit=26)
    assert (inner > 0).sum() > 100
    as_terms = sorted(zip(beam.tolist(), t.tolist(), value.tolist()))
    from_rings = sorted([(b, o, v) for b, o, v in zip(r_beam.tolist(), outer.tolist(),
                                                       r_value.tolist())]
                        + [(b, i, -v) for b, i, v in zip(r_beam.tolist(), inner.tolist(),
                                                          r_value.tolist()) if i > 0])
    assert from_rings == as_terms


def test_run_ends_with_fewer_rows_or_in_int32_sum_the_same():
    from blocks.maps.sectors import run_ends
    rng = np.random.default_rng(9)
    reach, size = 12, 60
    beams, _ = _random_beams(rng, 200, size, reach)
    assert exact_weights(np.concatenate([beams.free_value, beams.occ_value]), 400)
    spans = cone_spans(0.1, 30.0, reach)
    cells = size * (size + 1)

    def grid(index, value, offset=0):
        return np.bincount(index - offset, value, minlength=cells)

    every_row = run_ends(spans, beams, (0, 0), size + 1)
    fewer = run_ends(spans, beams, (0, 0), size + 1, exact=True)
    assert every_row[0].dtype == fewer[0].dtype == np.int64
    assert len(fewer[0]) < 0.6 * len(every_row[0])  # rows passed over, rings on their rows
    assert np.array_equal(grid(*every_row), grid(*fewer))
    # a grid so far from the corner that its indices need int64: the same runs, moved
    far = (2 ** 31) // (size + 1) + 5
    moved = run_ends(spans, beams, (-far, 0), size + 1, exact=True)
    assert moved[0].min() > 2 ** 31
    assert np.array_equal(moved[0] - far * (size + 1), fewer[0])
    assert np.array_equal(moved[1], fewer[1])


@pytest.mark.parametrize("piece", [7, 300, 10 ** 9])
def test_runs_added_a_piece_at_a_time_are_the_run_ends(monkeypatch, piece):
    from blocks.maps import sectors
    rng = np.random.default_rng(14)
    reach, size = 12, 60
    beams, _ = _random_beams(rng, 200, size, reach)
    spans = cone_spans(0.1, 30.0, reach)
    cells = size * (size + 1)
    index, value = sectors.run_ends(spans, beams, (0, 0), size + 1, exact=True)
    monkeypatch.setattr(sectors, "RUN_PIECE", piece)
    grid = np.zeros(cells)
    sectors.add_runs(grid, spans, beams, (0, 0), size + 1)
    assert np.array_equal(grid, np.bincount(index, value, minlength=cells))
    with pytest.raises(ValueError, match="outside the grid"):
        sectors.add_runs(np.zeros(cells), spans, beams, (20, 0), size + 1, check=True)


@pytest.mark.parametrize("width", [1, 7, 32, 33, 64, 95])
def test_block_sums_are_the_running_sums_of_exact_terms(width):
    from blocks.maps.sectors import block_sums
    rng = np.random.default_rng(15)
    diff = np.zeros((40, 96))
    values = np.float32([-0.4, 0.85, -0.2, 0.425]).astype(np.float64)
    for row in diff:  # runs: a value at the start, taken back after the end
        start = rng.integers(0, 96, 30)
        stop = np.minimum(start + rng.integers(1, 60, 30), 95)
        value = rng.choice(values, 30)
        np.add.at(row, start, value)
        np.subtract.at(row, stop, value)
    want = np.cumsum(diff, axis=1)[:, :width]
    for block in (None, 1, 3, 8):
        got = block_sums(diff, width, block)
        assert got.shape == want.shape and np.array_equal(got, want), block
        assert not np.signbit(got[got == 0]).any()


def test_running_sums_that_round_keep_cumsum_order():
    from blocks.maps.sectors import _integrate, block_sums
    rng = np.random.default_rng(16)
    diff = rng.normal(0, 1, (30, 200)) * 0.1  # sums that round, differently in blocks
    want = np.cumsum(diff, axis=1)[:, :199]
    assert np.array_equal(_integrate(diff, 199), want)
    assert not np.array_equal(block_sums(diff, 199), want)
    assert np.allclose(block_sums(diff, 199), want)


def test_cone_distances_pass_over_only_pairs_found_inf():
    from blocks.maps.features import _distances_in_cones
    from sim2d.sonar import nearest_in_cone
    rng = np.random.default_rng(10)
    n = 20000
    sensors = np.column_stack([rng.uniform(0, 4, n), rng.uniform(0, 4, n),
                               rng.uniform(-math.pi, math.pi, n)])
    ends = rng.uniform(-1, 5, (n, 4))
    # some segments through the sensor's cone edges, and some ending at the sensor
    half = math.radians(15)
    edge = sensors[:2000, 2] + rng.choice([-half, half], 2000)
    ends[:2000, :2] = sensors[:2000, :2] + rng.uniform(0.5, 3, (2000, 1)) * np.column_stack(
        [np.cos(edge), np.sin(edge)])
    ends[2000:2500, 2:] = sensors[2000:2500, :2]
    segments = np.column_stack([ends, np.zeros(n)])
    want = nearest_in_cone(sensors[:, 0], sensors[:, 1], np.cos(sensors[:, 2]),
                           np.sin(sensors[:, 2]), segments, half)[0]
    got = _distances_in_cones(sensors[:, 0], sensors[:, 1], np.cos(sensors[:, 2]),
                              np.sin(sensors[:, 2]), ends, np.arange(n), half)
    assert np.array_equal(got, want)
    assert 0.05 < np.isfinite(want).mean() < 0.5


def _merged_one_pair_at_a_time(features):
    """merge_features without its shortcuts: every pair through _mergeable."""
    from blocks.maps.features import _mergeable, _refit

    def order(f):
        return -f.support, -f.length

    pool, again = sorted(features, key=order), True
    while again:
        again, out = False, []
        for f in pool:
            for i, g in enumerate(out):
                if _mergeable(g, f, math.radians(6.0), 0.1, 0.3):
                    out[i] = _refit(np.vstack([g.points, f.points]), g.normal)
                    again = True
                    break
            else:
                out.append(f)
        pool = sorted(out, key=order)
    return pool


def test_merges_are_those_of_every_pair_tested_in_full(corridor):
    poses, ranges = corridor
    sensors = sensor_poses_along(poses, MOUNTS)
    found = extract_linear_features(sensors, ranges, ranges < 3.95)
    merged = merge_features(found)
    assert len(merged) < len(found)
    assert _same_features(merged, _merged_one_pair_at_a_time(found))


def test_features_of_many_runs_at_once_are_those_run_by_run(corridor):
    from blocks.maps.features import _features_from, _mean_rows, _reflection_points, _refit
    poses, ranges = corridor
    sensors = sensor_poses_along(poses, MOUNTS)
    axis = sensors[..., :2] + ranges[..., None] * np.stack(
        [np.cos(sensors[..., 2]), np.sin(sensors[..., 2])], axis=-1)
    rng = np.random.default_rng(14)
    runs = []
    for _ in range(60):  # runs of echoes of one sensor: some along a wall, some not
        j, a = int(rng.integers(16)), int(rng.integers(0, len(poses) - 40))
        run = np.arange(a, a + int(rng.integers(2, 40)))
        runs.append((axis[run, j], sensors[run, j], ranges[run, j]))
    half = math.radians(15)
    want = []
    for points, sens, r in runs:  # a feature fitted run by run, as it was written
        centre, direction = _fit_line(points)
        normal = np.array([-direction[1], direction[0]])
        seen_from = _mean_rows(sens[:, :2])
        normal = -normal if np.dot(seen_from - centre, normal) < 0 else normal
        wall = _reflection_points(sens, r, normal, half)
        want.append(_refit(wall, seen_from - _mean_rows(wall)))
    got = _features_from(runs, half)
    assert _same_features(got, want)
    assert all(np.array_equal(f.normal, g.normal) for f, g in zip(got, want))
    assert _features_from([], half) == []


def test_a_bent_run_is_no_feature():
    """A sensor passing a gently curved wall: every recent stretch is straight enough to
    go on the run, the whole run is not (its reflection points' residual is above the
    tolerance), so it gives no feature; a flatter curve gives one."""
    x = np.arange(0, 3.0, 0.05)
    poses = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    sensors = sensor_poses_along(poses, np.array([[0.0, 0.0, math.pi / 2]]))
    found = []
    for bend in (0.04, 0.06):
        ranges = (1 + bend * (x - 1.5) ** 2)[:, None]
        found.append(extract_linear_features(sensors, ranges, ranges < 3.9, line_tol=0.04))
    assert [len(f) for f in found] == [1, 0]
    assert found[0][0].support == len(x) and 0.02 < found[0][0].residual < 0.04


def test_a_run_that_ends_where_it_began_is_no_feature():
    """Out along a wall and back: the echoes span 0.5 m, but the run's first and last lie
    closer than ``min_length`` (a robot turning back), so it is not fitted at all."""
    x = np.concatenate([np.arange(0, 0.5, 0.05), np.arange(0.5, 0.0, -0.05)])
    poses = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    sensors = sensor_poses_along(poses, np.array([[0.0, 0.0, math.pi / 2]]))
    ranges = np.ones((len(x), 1))
    assert extract_linear_features(sensors, ranges, ranges < 3.9, min_length=0.3) == []
    assert len(extract_linear_features(sensors[:12], ranges[:12], ranges[:12] < 3.9,
                                       min_length=0.3)) == 1


def _piece(rng: np.random.Generator, angle: float, n: int, start: float):
    """A wall piece of n echoes through near the origin, at ``angle``."""
    from blocks.maps.features import _refit
    d = np.array([math.cos(angle), math.sin(angle)])
    t = np.sort(rng.uniform(start, start + rng.uniform(0.3, 1.5), n))
    return _refit(t[:, None] * d + rng.normal(0, 0.005, (n, 2)), np.array([-d[1], d[0]]))


def test_merges_of_pieces_turned_a_little_are_those_of_every_pair_tested_in_full():
    """Pieces within a few degrees of each other: a merge turns the merged wall, and the
    pieces after it are tested against the turned wall."""
    rng = np.random.default_rng(17)
    merged_some = 0
    for _ in range(150):
        pieces = [_piece(rng, math.radians(rng.uniform(-9, 9)), int(rng.integers(6, 40)),
                         rng.uniform(-1, 1)) for _ in range(int(rng.integers(3, 7)))]
        got = merge_features(pieces)
        assert _same_features(got, _merged_one_pair_at_a_time(pieces))
        merged_some += len(got) < len(pieces)
    assert merged_some > 50


def test_pieces_exactly_at_the_offset_bound_merge():
    """End points exactly ``offset_tol`` off the line: too close to call in plain floats,
    decided by the full test (within the bound: they merge)."""
    from blocks.maps.features import LinearFeature
    x = np.linspace(0.0, 1.0, 10)
    a = LinearFeature(np.array([0.0, 0.0]), np.array([1.0, 0.0]), np.array([0.0, 1.0]),
                      np.column_stack([x, np.zeros(10)]), 0.0)
    b = LinearFeature(np.array([0.0, 0.25]), np.array([1.0, 0.25]), np.array([0.0, 1.0]),
                      np.column_stack([x, np.full(10, 0.25)]), 0.0)
    assert len(merge_features([a, b], offset_tol=0.25)) == 1
    assert len(merge_features([a, b], offset_tol=0.2499)) == 2
    assert len(merge_features([a, b], offset_tol=0.25 - 1e-12)) == 2  # unsure, then out


def test_line_fits_without_mean_are_the_fits_with_it():
    from blocks.maps.features import _mean_rows, _refit
    rng = np.random.default_rng(11)
    for n in (2, 3, 7, 8, 9, 16, 17, 40, 333):
        points = rng.normal(0, 3, (n, 2)) + rng.uniform(-20, 20, 2)
        assert np.array_equal(_mean_rows(points), points.mean(axis=0))
        hint = rng.normal(0, 1, 2)
        # _refit as it was written with mean()
        centre, direction = points.mean(axis=0), None
        d = points - centre
        angle = 0.5 * math.atan2(2 * float(d[:, 0] @ d[:, 1]),
                                 float(d[:, 0] @ d[:, 0]) - float(d[:, 1] @ d[:, 1]))
        direction = np.array([math.cos(angle), math.sin(angle)])
        normal = np.array([-direction[1], direction[0]])
        normal = -normal if np.dot(normal, hint) < 0 else normal
        along, across = (points - centre) @ direction, (points - centre) @ normal
        got = _refit(points, hint)
        assert np.array_equal(got.p0, centre + along.min() * direction)
        assert np.array_equal(got.p1, centre + along.max() * direction)
        assert np.array_equal(got.normal, normal)
        assert got.residual == float(np.sqrt(np.mean(across ** 2)))
