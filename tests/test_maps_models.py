"""The paper's beam, robot, local and global maps, and the log-odds model, without the framework."""
from __future__ import annotations

import math

import numpy as np
import pytest

from blocks.maps.logodds import InverseSonarModel, LogOddsMap, log_odds_to_probability
from blocks.maps.paper import (BeamModel, LocalMapper, PaperGlobalMap, RobotModel, SensorMount,
                               free_space_borders, orient_local_map)


def test_beam_is_a_30_degree_triangle_80_pixels_long_at_level_01():
    beam = BeamModel()
    m = beam.matrix()
    assert m.shape == (161, 161) and m.dtype == np.uint8  # a square matrix, apex at the centre
    assert set(np.unique(m)) == {0, 1}  # uniform grey level 01
    assert m[80, 80:161].all() and not m[80, :80].any()  # along +x from the apex, 80 px
    # the half-width at axial distance d is d * tan(15 deg)
    for d in (20, 40, 80):
        column = m[:, 80 + d]
        assert column.sum() == 2 * math.floor(d * math.tan(math.radians(15)) + 1e-9) + 1
    area = m.sum()
    assert area == pytest.approx(80 ** 2 * math.tan(math.radians(15)), rel=0.03)


def test_clipping_cuts_the_beam_at_the_reading():
    beam = BeamModel()
    clipped = beam.clipped(30)
    assert clipped[80, 80 + 30] == 1 and not clipped[:, 80 + 31:].any()
    assert beam.clipped(80).sum() == beam.matrix().sum()


def test_robot_model_is_a_free_10_by_10_square_at_every_degree():
    robot = RobotModel()
    assert len(robot.rotations) == 360
    assert robot.at(0.0).sum() == 100 * 3  # 100 pixels at level 11
    for degrees in range(0, 360, 15):
        assert 95 <= robot.at(math.radians(degrees)).sum() // 3 <= 115


def _one_beam_mapper() -> LocalMapper:
    return LocalMapper([SensorMount(0.25, 0.0, 0.0)])


def test_local_map_pivots_the_beam_at_its_sensor_and_superposes():
    mapper = LocalMapper([SensorMount(0.25, 0.0, 0.0), SensorMount(0.25, 0.0, 0.0)])
    lm = mapper.local_map(np.array([1.0, 1.0]))
    c = mapper.half
    assert lm[c, c] == 3  # the robot model: 11
    assert lm[c, c + 5 + 20] == 2  # two overlapping beams: 01 + 01 = 10
    assert lm[c, c + 5 + 21] == 0  # clipped at the 1 m reading (20 px from the sensor)
    assert lm[c, c - 6] == 0  # behind the robot: unknown


def test_overlaps_saturate_at_11():
    mapper = LocalMapper([SensorMount(0.25, 0.0, 0.0)] * 5)
    lm = mapper.local_map(np.full(5, 4.0))
    assert lm.max() == 3 and lm[mapper.half, mapper.half + 40] == 3


def test_orienting_turns_counter_clockwise_in_the_world():
    lm = np.zeros((41, 41), np.uint8)
    lm[20, 21:41] = 1  # a ray along +x
    turned = orient_local_map(lm, math.pi / 2)
    rows, cols = np.nonzero(turned)
    assert set(cols) == {20} and rows.min() >= 20  # now along +y (rows grow upward)


def test_a_known_pose_lands_the_local_map_exactly():
    mapper = _one_beam_mapper()
    gm = PaperGlobalMap(0.05)
    gm.add(mapper.local_map(np.array([1.0])), np.array([2.0, 3.0, math.pi / 2]))
    levels, (ix, iy) = gm.levels()

    def level_at(x: float, y: float) -> int:
        return int(levels[int(math.floor(y / 0.05)) - iy, int(math.floor(x / 0.05)) - ix])

    assert level_at(2.0, 3.0) == 3  # the robot
    assert level_at(2.0, 3.0 + 0.25 + 0.9) == 1  # the beam points north now
    assert level_at(2.0, 3.0 + 0.25 + 1.1) == 0  # beyond the reading
    assert level_at(2.0 + 0.9, 3.0) == 0  # nothing east


def test_global_map_skips_unknown_pixels_and_saturates():
    mapper = _one_beam_mapper()
    gm = PaperGlobalMap(0.05)
    for _ in range(5):
        gm.add(mapper.local_map(np.array([2.0])), np.array([0.0, 0.0, 0.0]))
    levels, _ = gm.levels()
    assert levels.max() == 3 and set(np.unique(levels)) <= {0, 3}
    before = gm.grid.n_tiles
    gm.add(np.zeros_like(mapper.local_map(np.array([2.0]))), np.array([50.0, 50.0, 0.0]))
    assert gm.grid.n_tiles == before  # an all-unknown local map allocates nothing


def _local_map_stamp_by_stamp(mapper: LocalMapper, mounts: list[SensorMount],
                              ranges: np.ndarray) -> np.ndarray:
    """The paper's steps 3a-3e written out: every clipped beam added with saturation in turn."""
    n, res = mapper.beam.length_px, mapper.resolution
    lm = np.zeros((mapper.size, mapper.size), np.uint8)
    for m, reading in zip(mounts, ranges):
        k = min(max(int(round(min(float(reading), mapper.max_range) / res)), 0), n)
        beam = mapper.beam.clipped(k + 0.5, m.theta)  # whole pixels: k + 1/2 keeps pixel k
        r0 = mapper.half + int(round(m.y / res)) - n
        c0 = mapper.half + int(round(m.x / res)) - n
        view = lm[r0:r0 + 2 * n + 1, c0:c0 + 2 * n + 1]
        view[:] = np.minimum(view + beam, 3)
    foot = mapper.robot.at(0.0)
    k = len(foot) // 2
    view = lm[mapper.half - k:mapper.half + k + 1, mapper.half - k:mapper.half + k + 1]
    view[:] = np.minimum(view + foot, 3)
    return lm


def test_local_map_sums_then_saturates_as_beam_by_beam_saturation():
    rng = np.random.default_rng(5)
    mounts = [SensorMount(*rng.uniform(-0.3, 0.3, 2), rng.uniform(-math.pi, math.pi))
              for _ in range(16)] + [SensorMount(0.1, 0.0, 0.2)] * 4  # overlapping beams
    mapper = LocalMapper(mounts)
    for _ in range(40):
        ranges = rng.choice([rng.uniform(-0.1, 4.5), 0.0, 4.0, 9.0, 0.024, 0.026], len(mounts))
        ranges = np.where(rng.random(len(mounts)) < 0.5, rng.uniform(0.0, 4.2, len(mounts)),
                          ranges)
        assert np.array_equal(mapper.local_map(ranges),
                              _local_map_stamp_by_stamp(mapper, mounts, ranges))


def test_local_map_saturates_even_past_255_overlapping_beams():
    mounts = [SensorMount(0.25, 0.0, 0.0)] * 256  # a uint8 sum that wrapped would read 0
    mapper = LocalMapper(mounts)
    ranges = np.full(256, 2.0)
    lm = mapper.local_map(ranges)
    assert np.array_equal(lm, _local_map_stamp_by_stamp(mapper, mounts, ranges))
    assert lm[mapper.half, mapper.half + 5 + 20] == 3


def test_global_map_adds_only_the_known_box_and_allocates_the_same_tiles():
    mapper = LocalMapper([SensorMount(0.25, 0.0, a) for a in np.linspace(-1.0, 1.0, 5)])
    rng = np.random.default_rng(11)
    cropped, whole = PaperGlobalMap(0.05), PaperGlobalMap(0.05)
    for _ in range(60):
        pose = np.array([*rng.uniform(-6.0, 6.0, 2), rng.uniform(-math.pi, math.pi)])
        lm = mapper.local_map(rng.uniform(0.1, 4.0, 5))
        cropped.add(lm, pose)
        # the whole oriented local map, as step 4 states it
        oriented = orient_local_map(lm, pose[2])
        half = lm.shape[0] // 2
        ix, iy = whole.grid.cell_of(pose[0], pose[1])
        whole.grid.update(ix - half, iy - half, oriented,
                          lambda d, s: np.minimum(d + s, 3, out=d), mask=oriented != 0)
    (a, corner_a), (b, corner_b) = cropped.levels(), whole.levels()
    assert corner_a == corner_b and np.array_equal(a, b)
    assert [k for k, _ in cropped.grid.tiles()] == [k for k, _ in whole.grid.tiles()]


def test_borders_are_unknown_cells_next_to_free_space():
    levels = np.zeros((5, 5), np.uint8)
    levels[1:4, 1:4] = 2
    border = free_space_borders(levels)
    assert border.sum() == 25 - 9 and not border[2, 2]


def test_inverse_sonar_model_free_then_occupied_arc_then_unknown():
    model = InverseSonarModel()
    rho = np.array([0.5, 1.0, 1.5, 1.99, 2.0, 2.04, 2.2, 3.0])
    delta = model.beam_update(rho, np.ones_like(rho, bool), 2.0)
    assert list(delta[:3]) == [model.l_free] * 3
    assert delta[4] == model.l_occ and delta[5] == model.l_occ
    assert delta[6] == 0 and delta[7] == 0
    # no echo: clears free space, marks nothing occupied
    no_echo = model.beam_update(rho, np.ones_like(rho, bool), 4.0)
    assert (no_echo <= 0).all() and no_echo[-1] == model.l_free


def test_log_odds_map_accumulates_and_clamps():
    lo = LogOddsMap(resolution=0.05)
    sensors = np.array([[0.0, 0.0, 0.0]])
    for _ in range(20):
        lo.add_scan(sensors, np.array([2.0]))
    p, (ix, iy) = lo.probabilities()

    def prob(x: float, y: float) -> float:
        return float(p[int(math.floor(y / 0.05)) - iy, int(math.floor(x / 0.05)) - ix])

    assert prob(1.0, 0.0) == pytest.approx(log_odds_to_probability(-4.0), abs=1e-6)  # clamped
    assert prob(2.0, 0.0) == pytest.approx(log_odds_to_probability(4.0), abs=1e-6)
    assert prob(3.0, 0.0) == pytest.approx(0.5)  # beyond the wall: never touched
    assert prob(1.0, 0.5) == pytest.approx(0.5)  # outside the 30-degree cone (about 27 deg off)
    one = LogOddsMap(resolution=0.05)
    one.add_scan(sensors, np.array([2.0]))
    p1, (jx, jy) = one.probabilities()
    assert p1[int(round(0 / 0.05)) - jy, int(math.floor(1.0 / 0.05)) - jx] == pytest.approx(
        log_odds_to_probability(-0.4), abs=1e-6)


def test_log_odds_cone_turns_with_the_heading():
    lo = LogOddsMap(resolution=0.05)
    lo.add_scan(np.array([[0.0, 0.0, math.pi / 2]]), np.array([1.0]))
    p, (ix, iy) = lo.probabilities()
    assert p[int(math.floor(1.0 / 0.05)) - iy, 0 - ix] > 0.6  # the wall arc is north
    assert p[0 - iy, int(math.floor(0.5 / 0.05)) - ix] == pytest.approx(0.5)  # east untouched


def test_a_far_echo_shares_its_evidence_along_its_arc():
    shared = InverseSonarModel(shared_arc=0.3)
    width_at_2m = 2 * 2.0 * math.tan(math.radians(15))
    assert shared.occupied_evidence(2.0) == pytest.approx(shared.l_occ * 0.3 / width_at_2m)
    assert shared.occupied_evidence(0.5) == shared.l_occ  # an arc narrower than 0.3 m
    assert InverseSonarModel().occupied_evidence(2.0) == InverseSonarModel().l_occ
    with pytest.raises(ValueError, match="shared_arc"):
        InverseSonarModel(shared_arc=0.0)


@pytest.mark.parametrize("shared_arc, doorway_free", [(None, False), (0.3, True)])
def test_beams_through_a_doorway_open_what_a_jambs_arc_painted(shared_arc, doorway_free):
    """A jamb 2 m away echoes on an arc a metre wide, across the doorway beside it;
    as many readings that pass through the doorway from close by must open it
    again, or the explorer never finds the door."""
    lo = LogOddsMap(InverseSonarModel(shared_arc=shared_arc), resolution=0.05)
    for _ in range(6):
        lo.add_scan(np.array([[0.0, 0.0, 0.0]]), np.array([2.0]))  # the jamb's arc at x = 2
        lo.add_scan(np.array([[1.2, 0.0, 0.0]]), np.array([3.0]))  # through the doorway
    p, (ix, iy) = lo.probabilities()
    doorway = p[0 - iy, int(math.floor(2.0 / 0.05)) - ix]
    assert (doorway < 0.5) == doorway_free


def _wall_then_glance(occlusion: float | None) -> tuple[float, float]:
    """A wall along y = 1 m, heard square on from below, then glanced at by silent readings
    from along the corridor: its probability at x = 2 m, and that of the floor behind it."""
    lo = LogOddsMap(InverseSonarModel(occlusion=occlusion), resolution=0.05)
    for x in np.arange(1.0, 3.01, 0.05):  # a side sonar passes under the wall
        lo.add_scan(np.array([[x, 0.0, math.pi / 2]]), np.array([1.0]))
    for x in np.arange(-2.0, 0.01, 0.05):  # a diagonal sonar 25 deg up: its sound glances off
        lo.add_scan(np.array([[x, 0.0, math.radians(25.0)]]), np.array([4.0]))
    p, (ix, iy) = lo.probabilities()

    def prob(x: float, y: float) -> float:
        return float(p[int(math.floor(y / 0.05)) - iy, int(math.floor(x / 0.05)) - ix])

    return prob(2.0, 1.0), prob(2.0, 1.4)


def test_a_silent_reading_does_not_clear_through_a_wall_the_map_is_sure_of():
    wall, behind = _wall_then_glance(occlusion=1.5)
    assert wall > 0.9 and behind == pytest.approx(0.5)  # the wall stays; behind it, unknown
    wall, behind = _wall_then_glance(occlusion=None)
    assert wall < 0.5 and behind < 0.5  # cleared through: free floor drawn across the wall


def test_occlusion_leaves_the_floor_before_the_wall_and_echoes_alone():
    lo = LogOddsMap(InverseSonarModel(occlusion=1.5), resolution=0.05)
    for _ in range(5):
        lo.add_scan(np.array([[0.0, 0.0, 0.0]]), np.array([1.0]))  # a wall 1 m ahead
    lo.add_scan(np.array([[0.0, 0.0, 0.0]]), np.array([4.0]))  # then silence
    p, (ix, iy) = lo.probabilities()
    assert p[0 - iy, int(math.floor(0.5 / 0.05)) - ix] < 0.5  # before the wall: free
    assert p[0 - iy, int(math.floor(1.0 / 0.05)) - ix] > 0.9  # the wall kept
    assert p[0 - iy, int(math.floor(2.0 / 0.05)) - ix] == pytest.approx(0.5)  # behind: unknown
    with pytest.raises(ValueError, match="occlusion"):
        InverseSonarModel(occlusion=0.0)


def _pass_a_door(seen_through: int | None):
    """The ATRV's 16 sonars (the simulator's ranger, specular losses and all) driven past
    a 0.85 m door in a wall 1 m to its left, a room 2.5 m deep behind it, stopping
    15 s 1.4 m before the door (to read the plate beside it, say): the map."""
    from blocks.maps.mapio import OccupancyMap
    from sim2d.robot import load_robot
    from sim2d.sonar import sonar_readings
    spec = load_robot("atrv_mini")
    walls = np.array([[-6.0, 1.0, -0.425, 1.0], [0.425, 1.0, 6.0, 1.0],  # the door at x = 0
                      [-6.0, 3.5, 6.0, 3.5], [-3.0, 1.0, -3.0, 3.5], [3.0, 1.0, 3.0, 3.5],
                      [-6.0, -1.0, 6.0, -1.0]])  # the corridor's other wall
    capsules = np.column_stack([walls, np.zeros(len(walls))])
    lo = LogOddsMap(InverseSonarModel(shared_arc=0.3, seen_through=seen_through),
                    resolution=0.1)
    rng = np.random.default_rng(0)
    mx, my, mt = spec.sonar_mounts.T
    path = np.arange(-3.0, 3.01, 0.04)  # 0.4 m/s at 10 Hz
    for x in np.concatenate([path[path < -1.4], np.full(150, -1.4), path[path >= -1.4]]):
        sensors = np.column_stack([x + mx, my, mt])
        ranges, _ = sonar_readings(sensors, capsules, spec.sonar, rng)
        lo.add_scan(sensors, ranges)
    p, (ix, iy) = lo.probabilities()
    return OccupancyMap(p, 0.1, (ix * 0.1, iy * 0.1, 0.0))


@pytest.mark.parametrize("seen_through, passable", [(None, False), (3, True)])
def test_jambs_arcs_do_not_shut_a_door_the_beams_have_seen_through(seen_through, passable):
    """Waiting beside a narrow door, the diagonal sonars hear its jamb again and again;
    their arcs lie across the opening that beams through it have seen free.  Counting
    those beams keeps the arcs off the opening, so the explorer's tight grid (0.2 m
    inflation) has a way into the room; the walls beside the door stay walls."""
    from scipy import ndimage

    from blocks.navigate.grid import inflate
    m = _pass_a_door(seen_through)
    grid = inflate(m, radius=0.2)
    labels, _ = ndimage.label(~grid.blocked, structure=np.ones((3, 3)))
    corridor, room = grid.world_to_cell(0.0, 0.0), grid.world_to_cell(0.0, 1.8)
    assert (labels[corridor] != 0 and labels[corridor] == labels[room]) == passable
    occupied = m.classes()[0]
    for x in (-0.8, 1.0, 2.0):  # the wall either side of the door
        r = int(math.floor((1.0 - m.origin[1]) / m.resolution))
        c = int(math.floor((x - m.origin[0]) / m.resolution))
        assert occupied[r - 1:r + 2, c].any(), x


def test_silent_beams_across_a_wall_do_not_make_it_seen_through():
    """A sonar whose sound glanced off a wall hears nothing and clears across it; were
    that seeing through, the wall's own echoes would be kept off it and it would fade."""
    lo = LogOddsMap(InverseSonarModel(seen_through=1), resolution=0.05)
    for _ in range(3):
        for x in np.arange(-2.0, 0.01, 0.05):  # silent, 25 deg up across the wall y = 1
            lo.add_scan(np.array([[x, 0.0, math.radians(25.0)]]), np.array([4.0]))
        for x in np.arange(1.0, 3.01, 0.05):  # the wall heard square on
            lo.add_scan(np.array([[x, 0.0, math.pi / 2]]), np.array([1.0]))
    p, (ix, iy) = lo.probabilities()
    wall = int(math.floor(1.0 / 0.05)) - iy, int(math.floor(2.0 / 0.05)) - ix
    assert p[wall] > 0.9
    passed, (jx, jy) = lo.through.to_dense()
    assert passed[:int(math.floor(0.65 / 0.05)) - jy].max() > 0  # the echoes' floor
    assert passed[int(math.floor(0.7 / 0.05)) - jy:].max() == 0  # none up to the wall
    with pytest.raises(ValueError, match="seen_through"):
        InverseSonarModel(seen_through=0)
