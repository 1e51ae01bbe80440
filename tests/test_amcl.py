"""Monte Carlo localisation with the sonar ring (blocks/maps/amcl.py): the motion model, the
resampler, the sensor model against the simulator's, and the filter holding the pose on the
map where odometry drifts away from it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from blocks.maps.amcl import (AMCLParams, MonteCarloLocaliser, kld_resample, kld_sample_limit,
                              low_variance_resample, map_walls, occupied_bins,
                              sample_odometry_motion, walls_in_reach)
from blocks.maps.features import sensor_poses_along
from blocks.maps.mapio import occupancy_map_from_world
from sim2d.robot import load_robot
from sim2d.sonar import SonarSpec, cone_ranges, sensor_poses, sonar_readings
from sim2d.world import load_world
from sim2d.worlds import world_path

ROBOT = load_robot("atrv_mini")


@pytest.fixture(scope="module")
def office():
    world = load_world(world_path("office"))
    return world, map_walls(occupancy_map_from_world(world))


def _localiser(walls, start, **kw) -> MonteCarloLocaliser:
    sonar = ROBOT.sonar
    return MonteCarloLocaliser(walls, ROBOT.sonar_mounts, cone_deg=sonar.cone_deg,
                               max_range=sonar.max_range, specular_deg=sonar.specular_deg,
                               start=np.asarray(start), params=AMCLParams(**kw), rng=3)


def test_without_noise_every_particle_moves_by_the_odometry_step_in_its_own_frame():
    particles = np.array([[0.0, 0.0, 0.0], [5.0, 1.0, math.pi / 2]])
    moved = sample_odometry_motion(particles, np.array([1.0, 1.0, 0.0]),
                                   np.array([2.0, 2.0, math.pi / 2]), (0, 0, 0, 0),
                                   np.random.default_rng(0))
    # one metre forward and one left, ending turned left, seen from each particle
    np.testing.assert_allclose(moved[:, :2], [[1.0, 1.0], [4.0, 2.0]], atol=1e-6)
    np.testing.assert_allclose(np.cos(moved[:, 2] - [math.pi / 2, math.pi]), 1.0, atol=1e-9)


def test_a_step_backwards_is_a_step_back_not_a_half_turn():
    moved = sample_odometry_motion(np.zeros((1, 3)), np.zeros(3), np.array([-0.3, 0.0, 0.0]),
                                   (0, 0, 0, 0), np.random.default_rng(0))
    np.testing.assert_allclose(moved, [[-0.3, 0.0, 0.0]], atol=1e-6)


def test_the_motion_noise_grows_with_the_step():
    rng = np.random.default_rng(1)
    start = np.zeros((2000, 3))
    spreads = [np.std(sample_odometry_motion(start, np.zeros(3), np.array([d, 0.0, 0.0]),
                                             (0.2, 0.05, 0.1, 0.05), rng)[:, 1])
               for d in (0.1, 1.0)]
    assert spreads[1] > 5 * spreads[0]


def test_low_variance_resampling_draws_in_proportion_to_the_weights():
    picks = low_variance_resample(np.array([2.0, 1.0, 1.0, 0.0]), np.random.default_rng(0))
    assert np.bincount(picks, minlength=4).tolist() == [2, 1, 1, 0]


def test_kld_sampling_asks_for_more_particles_the_more_bins_the_cloud_fills():
    # Fox 2003, eq. 13 with amcl's kld_err 0.01 and kld_z 0.99: 2 bins -> ceil(96.4)
    needed = [kld_sample_limit(k, 0.01, 0.99, 1, 10**6) for k in range(1, 30)]
    assert needed[:3] == [1, 97, 182]
    assert all(a < b for a, b in zip(needed, needed[1:]))
    assert kld_sample_limit(1, 0.01, 0.99, 100, 300) == 100  # one bin: the fewest
    assert kld_sample_limit(40, 0.01, 0.99, 100, 300) == 300  # clipped to the most


def test_a_converged_cloud_is_resampled_to_the_fewest_and_a_spread_one_keeps_more():
    rng = np.random.default_rng(0)
    params = AMCLParams(particles=300, min_particles=100)
    tight = np.array([0.25, 0.25, 0.09]) + rng.normal(0.0, [0.03, 0.03, 0.015], (300, 3))
    spread = rng.uniform([0.0, 0.0, -math.pi], [4.0, 4.0, math.pi], (300, 3))
    even = np.full(300, 1 / 300)
    assert len(set(occupied_bins(tight, params.kld_bin).tolist())) == 1
    assert len(kld_resample(tight, even, params, rng)) == 100
    assert len(kld_resample(spread, even, params, rng)) == 300
    # what is kept follows the weights: the heavy half of a cloud gives nearly every draw
    weights = np.where(np.arange(300) < 150, 0.99 / 150, 0.01 / 150)
    kept = kld_resample(spread, weights, params, rng)
    assert np.mean(kept < 150) > 0.95


def test_the_map_walls_give_the_ranges_the_simulator_reads(office):
    world, walls = office
    pose = np.array([*world.start])
    loc = _localiser(walls, pose)
    expected, _ = loc.expected_ranges(pose[None, :])
    quiet = SonarSpec(**{**vars(ROBOT.sonar), "noise_std": 0.0, "specular": False})
    true, echo = sonar_readings(sensor_poses(pose, ROBOT.sonar_mounts), world.segments, quiet,
                                np.random.default_rng(0))
    seen = echo & np.isfinite(expected[0])
    assert seen.sum() >= 10
    np.testing.assert_allclose(expected[0][seen], true[seen], atol=0.06)  # a map cell's width


def test_dropping_the_walls_no_cone_can_reach_changes_no_range(office):
    world, walls = office
    loc = _localiser(walls, world.start, initial_std=(0.3, 0.3, 0.3))
    fast, fast_incidence = loc.expected_ranges(loc.particles)
    sensors = sensor_poses_along(loc.particles, ROBOT.sonar_mounts).reshape(-1, 3)
    full, full_incidence = cone_ranges(sensors, walls, math.radians(15), ROBOT.sonar.max_range)
    assert np.array_equal(fast.ravel(), full)
    assert np.array_equal(fast_incidence.ravel(), full_incidence, equal_nan=True)
    kept = walls_in_reach(sensor_poses_along(loc.particles, ROBOT.sonar_mounts), walls,
                          math.radians(15), ROBOT.sonar.max_range)
    assert max(len(k) for k in kept) < len(walls) / 4  # and it does drop most


def _drive(world, loc, steps, rng_seed=1, scale=1.01, turn_bias=0.03):
    """Bounce round the office: 5 cm steps, turning on the spot before walls, with odometry
    that over-reads distance and turns; returns the filter's and the odometry's errors."""
    rng = np.random.default_rng(rng_seed)
    truth = np.array([*world.start], dtype=float)
    odometry = truth.copy()
    errors, drift = [], []
    for _ in range(steps):
        ranges, echo = sonar_readings(sensor_poses(truth, ROBOT.sonar_mounts), world.segments,
                                      ROBOT.sonar, rng)
        v, w = (0.05, 0.0) if min(ranges[0], ranges[1]) > 0.8 else (0.0, 0.08)
        truth += [v * math.cos(truth[2]), v * math.sin(truth[2]), w]
        odometry += [v * scale * math.cos(odometry[2]), v * scale * math.sin(odometry[2]),
                     w * (1 + turn_bias) + 0.002 * v]
        estimate = loc.step(odometry, ranges, echo)
        errors.append(math.hypot(*(estimate[:2] - truth[:2])))
        drift.append(math.hypot(*(odometry[:2] - truth[:2])))
    return np.array(errors), np.array(drift)


def test_the_filter_holds_the_pose_on_the_map_where_odometry_drifts_off_it(office):
    world, walls = office
    loc = _localiser(walls, world.start)
    errors, drift = _drive(world, loc, 500)
    assert drift.max() > 0.5  # the odometry is half a metre out by the end
    assert errors.max() < 0.15 and np.median(errors) < 0.08
    assert loc.updates > 50 and loc.spread() < 0.2
    # converged, the cloud needs and keeps only the fewest particles
    assert loc.particle_counts[-1] == loc.params.min_particles < loc.params.particles


def test_a_fixed_number_of_particles_holds_the_pose_as_well(office):
    world, walls = office
    loc = _localiser(walls, world.start, min_particles=300)
    errors, _ = _drive(world, loc, 500)
    assert errors.max() < 0.15 and np.median(errors) < 0.08
    assert set(loc.particle_counts) == {300}


def test_the_filter_finds_the_pose_from_a_guess_a_third_of_a_metre_out(office):
    world, walls = office
    guess = np.array(world.start) + [0.25, -0.2, 0.1]
    loc = _localiser(walls, guess, initial_std=(0.3, 0.3, 0.15))
    rng_errors, _ = _drive(world, loc, 300, scale=1.0, turn_bias=0.0)
    assert rng_errors[0] > 0.25
    assert rng_errors[-50:].max() < 0.12


def test_without_sonar_the_filter_only_follows_the_odometry(office):
    # silent sonars where the map says walls: every particle equally unlikely, no pull
    world, walls = office
    loc = _localiser(walls, world.start, initial_std=(0.0, 0.0, 0.0))
    silent = np.full(16, ROBOT.sonar.max_range), np.zeros(16, bool)
    loc.step(np.array(world.start), *silent)  # the first odometry pose is the start
    odometry = np.array(world.start) + [1.0, 0.0, 0.0]
    pose = loc.step(odometry, *silent)
    assert loc.updates == 1
    np.testing.assert_allclose(pose[:2], odometry[:2], atol=0.2)
