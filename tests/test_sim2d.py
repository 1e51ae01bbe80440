"""sim2d geometry and physics: sonar cone, max range, specular loss, walls, odometry, robots."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sim2d.robot import load_robot
from sim2d.simulation import Simulation
from sim2d.sonar import SonarSpec, cone_ranges, sonar_readings
from sim2d.world import make_world

BOX = [[0, 0, 10, 0], [10, 0, 10, 4], [10, 4, 0, 4], [0, 4, 0, 0]]  # 10 x 4 m room


def pole(cx: float, cy: float, r: float = 0.02, n: int = 12) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, n + 1)
    pts = np.c_[cx + r * np.cos(a), cy + r * np.sin(a)]
    return np.c_[pts[:-1], pts[1:], np.zeros(n)]


def test_sonar_facing_wall_reads_distance_within_noise():
    spec = load_robot("atrv_mini")
    fr1 = spec.sonar_index("Fr1")
    mount = spec.sonar_mounts[fr1]
    world = make_world(BOX, thickness=0.1)  # wall surface at x = 9.95
    x = 9.95 - 2.0 - mount[0]  # Fr1 exactly 2.0 m from the wall
    sim = Simulation(world, [("r", spec, (x, 2.0 - mount[1], 0.0))], seed=1)
    readings = np.array([sim.sonar("r")[0][fr1] for _ in range(200)])
    sigma = spec.sonar.noise_std
    assert abs(readings.mean() - 2.0) < 3 * sigma / math.sqrt(200) + 1e-3
    assert np.all(np.abs(readings - 2.0) < 5 * sigma)
    assert 0.5 * sigma < readings.std() < 1.5 * sigma


def test_beyond_max_range_is_no_echo():
    spec = load_robot("atrv_mini")
    world = make_world([[20, -5, 20, 5]])  # one wall 20 m ahead
    sim = Simulation(world, [("r", spec, (0.0, 0.0, 0.0))])
    ranges, echo = sim.sonar("r")
    assert not echo.any()
    assert np.all(ranges == spec.sonar.max_range)
    # and the same wall within range is an echo, distinguishable from "no echo"
    near = Simulation(make_world([[3.5, -5, 3.5, 5]], thickness=0.0), [("r", spec, (0, 0, 0))])
    ranges, echo = near.sonar("r")
    fr1 = spec.sonar_index("Fr1")
    assert echo[fr1] and ranges[fr1] < spec.sonar.max_range


@pytest.mark.parametrize("degrees,seen", [(0, True), (13, True), (-13, True), (17, False),
                                          (-17, False), (40, False)])
def test_thin_pole_inside_cone_is_seen(degrees, seen):
    a = math.radians(degrees)
    segments = pole(2.0 * math.cos(a), 2.0 * math.sin(a))
    ranges, _ = cone_ranges(np.array([[0.0, 0.0, 0.0]]), segments, math.radians(15), 4.0)
    assert np.isfinite(ranges[0]) == seen
    if seen:
        assert ranges[0] == pytest.approx(1.98, abs=0.005)


def test_cone_reports_nearest_echo_not_the_axis_one():
    # A far wall on the axis and a near pole 10 degrees off: the pole wins.
    a = math.radians(10)
    segments = np.vstack([pole(1.5 * math.cos(a), 1.5 * math.sin(a)),
                          make_world([[3.0, -5, 3.0, 5]], thickness=0.0).segments])
    ranges, _ = cone_ranges(np.array([[0.0, 0.0, 0.0]]), segments, math.radians(15), 4.0)
    assert ranges[0] == pytest.approx(1.48, abs=0.005)


def test_specular_loss_at_grazing_incidence():
    # A wall through (2, 0) at 30 degrees to the beam axis: its normal points 60 degrees
    # off-axis, outside the 30-degree cone. The nearest return is on the cone's -15 degree
    # edge ray, which meets the wall at 45 degrees of incidence.
    a = math.radians(30)
    wall = [[2 - 5 * math.cos(a), -5 * math.sin(a), 2 + 5 * math.cos(a), 5 * math.sin(a)]]
    wall = make_world(wall, thickness=0.0).segments
    sensors = np.array([[0.0, 0.0, 0.0]])
    rng = np.random.default_rng(0)
    ranges, incidence = cone_ranges(sensors, wall, math.radians(15), 4.0)
    assert math.degrees(incidence[0]) == pytest.approx(45.0, abs=0.1)
    assert ranges[0] == pytest.approx(1.0 / math.sin(math.radians(45)), abs=1e-6)
    assert not sonar_readings(sensors, wall, SonarSpec(specular_deg=40.0), rng)[1][0]
    assert sonar_readings(sensors, wall, SonarSpec(specular_deg=50.0), rng)[1][0]
    assert sonar_readings(sensors, wall, SonarSpec(specular=False, specular_deg=40.0), rng)[1][0]
    # A wall whose normal lies inside the cone is met square on.
    square = make_world([[2, -5, 2.5, 5]], thickness=0.0).segments
    assert cone_ranges(sensors, square, math.radians(15), 4.0)[1][0] == 0.0


@pytest.mark.parametrize("heading", [0.0, 0.3, -0.6, 1.2])
def test_full_speed_into_wall_no_penetration_one_collision(heading):
    spec = load_robot("atrv_mini")
    sim = Simulation(make_world(BOX, thickness=0.1), [("r", spec, (2.0, 2.0, heading))])
    deepest = 0.0
    reached_top_speed = False
    for _ in range(150):
        sim.command("r", spec.limits.max_speed, 0.0)
        sim.step(0.1)
        deepest = max(deepest, sim.penetration("r"))
        reached_top_speed |= sim.robots["r"].velocity[0] == spec.limits.max_speed
    robot = sim.robots["r"]
    assert reached_top_speed
    assert deepest < 0.005  # transient overlap at impact: < 1% of the body length
    assert sim.penetration("r") <= 0.001
    assert robot.collisions == 1
    x, y, _ = robot.pose
    assert 0.0 < x < 10.0 and 0.0 < y < 4.0  # still inside the room
    # the log says when and where: ahead of the body, on the wall it drove into
    [(t, bx, by, cx, cy)] = robot.collision_log
    assert 0.0 < t < 15.0
    assert math.hypot(cx - bx, cy - by) <= math.hypot(spec.length, spec.width) / 2 + 0.01
    assert (cx - bx) * math.cos(heading) + (cy - by) * math.sin(heading) > 0


def test_penetration_probe_detects_overlap():
    spec = load_robot("atrv_mini")
    sim = Simulation(make_world(BOX, thickness=0.1), [("r", spec, (9.8, 2.0, 0.0))])
    assert sim.penetration("r") == pytest.approx(0.1, abs=0.002)


def test_limits_are_enforced():
    spec = load_robot("atrv_mini")
    lim = spec.limits
    sim = Simulation(make_world(BOX), [("r", spec, (2.0, 2.0, 0.0))])
    sim.command("r", 5.0, -9.0)
    assert sim.robots["r"].command == (lim.max_speed, -lim.max_turn_rate)
    sim.step(0.1)
    v, w = sim.robots["r"].velocity
    assert v == pytest.approx(lim.max_accel * 0.1)
    assert w == pytest.approx(-lim.max_turn_accel * 0.1)
    sim.command("r", float("nan"), 0.0)
    assert sim.robots["r"].command == (0.0, 0.0)


def test_odometry_drifts_with_noise_and_is_exact_without():
    spec = load_robot("atrv_mini")
    quiet = dataclasses.replace(spec, odometry=dataclasses.replace(
        spec.odometry, trans_per_trans=0, trans_per_rot=0, rot_per_rot=0, rot_per_trans=0))
    world = make_world([[-50, -50, 50, -50]])
    for model, exact in ((quiet, True), (spec, False)):
        sim = Simulation(world, [("r", model, (0.0, 0.0, 0.0))], seed=3)
        for k in range(100):
            sim.command("r", 0.8, 0.5 * math.sin(k / 10))
            sim.step(0.1)
        robot = sim.robots["r"]
        error = np.hypot(*(robot.odom[:2] - robot.pose[:2]))
        assert (error < 1e-6) == exact
        assert error < 0.5  # drift stays plausible over ~8 m


def test_a_body_jostled_on_the_spot_keeps_its_odometry_heading():
    """Millimetre steps in random directions (a body pressed into a corner) are no
    rotation: the wheels did not turn it, so its odometry heading must not wander."""
    spec = load_robot("atrv_mini")
    world = make_world(BOX, thickness=0.1)
    sim = Simulation(world, [("r", spec, (5.0, 2.0, 0.3))], seed=1)
    robot = sim.robots["r"]
    jostle = np.random.default_rng(0)
    for _ in range(600):  # a minute at 10 Hz
        angle = jostle.uniform(-math.pi, math.pi)
        robot.body.position = (5.0 + 0.002 * math.cos(angle), 2.0 + 0.002 * math.sin(angle))
        sim._odometry(robot)
    assert abs(math.remainder(robot.odom[2] - 0.3, 2 * math.pi)) < 0.01
    assert np.hypot(*(robot.odom[:2] - robot.pose[:2])) < 0.05


def test_a_slow_creep_backwards_is_measured_backwards():
    spec = load_robot("atrv_mini")
    sim = Simulation(make_world(BOX, thickness=0.1), [("r", spec, (5.0, 2.0, 0.0))], seed=1)
    robot = sim.robots["r"]
    for k in range(1, 101):  # 5 mm a tick: too short for a bearing
        robot.body.position = (5.0 - 0.005 * k, 2.0)
        sim._odometry(robot)
    assert robot.odom[0] == pytest.approx(4.5, abs=0.02)
    assert abs(robot.odom[2]) < 0.01


def test_same_seed_same_trajectory_different_seed_different_odometry():
    spec = load_robot("atrv_mini")
    world = make_world(BOX, thickness=0.1)

    def drive(seed):
        sim = Simulation(world, [("r", spec, (1.0, 2.0, 0.2))], seed=seed)
        out = []
        for k in range(80):
            sim.command("r", 0.7, 0.8 * math.sin(k / 7))
            sim.step(0.1)
            out.append(np.r_[sim.robots["r"].pose, sim.robots["r"].odom, sim.sonar("r")[0]])
        return np.array(out)

    a, b, c = drive(5), drive(5), drive(6)
    assert np.array_equal(a, b)
    assert np.array_equal(a[:, :3], c[:, :3])  # physics is deterministic and noise-free
    assert not np.array_equal(a[:, 3:], c[:, 3:])  # odometry and sonar noise follow the seed


def test_two_robots_see_and_bump_each_other():
    spec = load_robot("atrv_mini")
    world = make_world(BOX, thickness=0.1)
    sim = Simulation(world, [("a", spec, (3.0, 2.0, 0.0)), ("b", spec, (6.0, 2.0, math.pi))])
    fr1 = spec.sonar_index("Fr1")
    ranges, echo = sim.sonar("a")
    assert echo[fr1] and ranges[fr1] == pytest.approx(3.0 - 0.25 - 0.25, abs=0.05)
    for _ in range(40):
        sim.command("a", 0.5, 0.0)
        sim.command("b", 0.5, 0.0)
        sim.step(0.1)
    a, b = sim.robots["a"], sim.robots["b"]
    assert a.collisions == 1 and b.collisions == 1
    assert b.pose[0] - a.pose[0] == pytest.approx(0.5, abs=0.01)  # touching, not overlapping


def test_cone_ranges_near_are_cone_ranges_to_the_bit():
    """Culling the capsules far from a chunk of sensors changes no range: along a path
    (compact chunks) and for sensors scattered over the floor (chunks that cull little)."""
    from sim2d.sonar import cone_ranges_near
    from sim2d.world import load_world
    from sim2d.worlds import world_path
    world = load_world(world_path("office"))
    rng = np.random.default_rng(4)
    steps = rng.normal(0, 0.05, (3000, 2)).cumsum(axis=0) + (15.0, 5.5)
    path = np.column_stack([steps, rng.uniform(-np.pi, np.pi, 3000)])
    scattered = np.column_stack([rng.uniform(-2, 32, 3000), rng.uniform(-2, 22, 3000),
                                 rng.uniform(-np.pi, np.pi, 3000)])
    half = math.radians(15.0)
    for sensors, chunk in ((path, 100), (path, 1), (scattered, 100)):
        expected, _ = cone_ranges(sensors, world.segments, half, 4.0)
        got = cone_ranges_near(sensors, world.segments, half, 4.0, chunk=chunk)
        assert np.array_equal(got, expected)
        assert np.isfinite(expected).mean() > 0.3


@pytest.mark.parametrize("heading, v, w, pressed", [
    (0.0, 0.5, 0.0, "front"),  # head on into the east wall
    (0.4, 0.5, 0.0, "front"),  # at an angle: the front face still meets it
    (math.pi, -0.5, 0.0, "rear"),  # backing into it
    (math.pi / 2, 0.0, 0.0, ""),  # standing clear of everything
])
def test_bumpers_say_which_side_touches(heading, v, w, pressed):
    spec = load_robot("atrv_mini")
    assert [name for name, _, _ in spec.bumpers] == ["front", "left", "rear", "right"]
    sim = Simulation(make_world(BOX, thickness=0.1), [("r", spec, (9.0, 2.0, heading))])
    for _ in range(40):
        sim.command("r", v, w)
        sim.step(0.1)
    names = [name for (name, _, _), on in zip(spec.bumpers, sim.bumpers("r")) if on]
    assert names == ([pressed] if pressed else [])


def test_a_corner_swept_into_a_wall_presses_the_bumper_on_that_side():
    spec = load_robot("atrv_mini")
    # Facing north, its right face 5 cm from the east wall: turning clockwise on the spot
    # swings the front-right corner into it.
    sim = Simulation(make_world(BOX, thickness=0.1), [("r", spec, (9.65, 2.0, math.pi / 2))])
    for _ in range(30):
        sim.command("r", 0.0, -1.0)
        sim.step(0.1)
        if sim.robots["r"].collisions:
            break
    pressed = [n for (n, _, _), on in zip(spec.bumpers, sim.bumpers("r")) if on]
    assert sim.robots["r"].collisions == 1 and pressed == ["right"]
