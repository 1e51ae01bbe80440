"""The collision monitor: the swept footprint, the scaling of commands, the echo memory, and
in closed loop the turn round a wall end whose corner a straight-ahead check misses."""
from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest

from blocks.navigate.collision_monitor import (CollisionMonitor, EchoMemory, MonitorParams,
                                               carry_points)
from blocks.navigate.guard import SonarGuard, swept_poses
from sim2d.robot import load_robot
from sim2d.sonar import cone_ranges, sensor_poses
from sim2d.simulation import Simulation
from sim2d.world import load_world

from conftest import ROOT, floor_plan, write_world

sys.path.insert(0, str(ROOT / "benchmarks"))

ATRV = load_robot("atrv_mini")


def guard() -> SonarGuard:
    return SonarGuard.for_robot(ATRV)


def reading(**values: float) -> np.ndarray:
    ranges = np.full(len(ATRV.sonar_names), ATRV.sonar.max_range)
    for name, value in values.items():
        ranges[ATRV.sonar_names.index(name)] = value
    return ranges


@pytest.mark.parametrize("v, w", [(0.4, 0.0), (0.3, -0.8), (0.0, 1.2), (-0.2, 0.5)])
def test_swept_poses_follow_the_unicycle(v, w):
    times = np.linspace(0.0, 2.0, 21)
    x = y = th = 0.0
    fine = [(x, y, th)]
    for _ in range(2000):  # Euler steps of 1 ms
        x, y, th = x + v * math.cos(th) * 1e-3, y + v * math.sin(th) * 1e-3, th + w * 1e-3
        fine.append((x, y, th))
    expected = np.array(fine)[::100]
    assert np.allclose(swept_poses(v, w, times), expected, atol=2e-3)


def test_a_corner_off_the_front_right_is_clear_ahead_but_hit_by_a_right_turn():
    """A wall end 12 cm off the front-right diagonal sonar: beside the straight lane, but
    the body's front corner swings onto it in a right turn (the follower's collisions)."""
    g = guard()
    arcs = g.echo_arcs(reading(FrRt2=0.12))
    assert g.collision_time(arcs, 0.4, 0.0, horizon=1.0) == math.inf
    assert g.collision_time(arcs, 0.3, -0.8, horizon=1.0) < 0.6
    assert g.collision_time(arcs, 0.3, 0.8, horizon=1.0) == math.inf  # turning away is fine


def test_a_wall_alongside_and_readings_without_echo_do_not_slow_the_robot():
    monitor = CollisionMonitor(guard())
    # a wall (or a door jamb) 0.2 m beside the body, driving along it
    assert monitor.step(0.0, np.zeros(3), reading(Rt1=0.2, Rt2=0.2, RtFr2=0.25), 0.45, 0.0) \
        == (0.45, 0.0)
    assert monitor.step(0.1, np.zeros(3), reading(), 0.45, -0.6) == (0.45, -0.6)


def test_a_command_towards_an_echo_is_scaled_along_its_own_path_and_stopped_at_the_body():
    p = MonitorParams(time_before_collision=0.6)
    far = CollisionMonitor(guard(), p)
    v, w = far.step(0.0, np.zeros(3), reading(Fr1=0.25, Fr2=0.25), 0.4, 0.1)
    assert 0.0 < far.scale < 1.0
    assert math.isclose(v / w, 4.0)  # the same arc, driven slower
    near = CollisionMonitor(guard(), p)
    assert near.step(0.0, np.zeros(3), reading(Fr1=0.1, Fr2=0.1), 0.4, 0.0) == (0.0, 0.0)
    assert near.scale == 0.0 and near.stopped_ticks == 1
    # backing away from it is let through
    assert near.step(0.1, np.zeros(3), reading(Fr1=0.1, Fr2=0.1), -0.2, 0.0) == (-0.2, 0.0)


def test_an_echo_heard_once_is_carried_along_by_odometry_and_forgotten_after_the_memory():
    monitor = CollisionMonitor(guard(), MonitorParams(memory=1.0, near_memory=0.0))
    monitor.step(0.0, np.zeros(3), reading(Fr1=0.3, Fr2=0.3), 0.0, 0.0)
    # the next scans hear nothing (a corner at grazing incidence); the robot has come 0.15 m
    pose = np.array([0.15, 0.0, 0.0])
    v, _ = monitor.step(0.5, pose, reading(), 0.4, 0.0)
    assert monitor.scale < 1.0 and v < 0.4
    v, _ = monitor.step(1.05, pose, reading(), 0.4, 0.0)
    assert v == 0.4


def test_near_echoes_are_kept_for_the_near_memory_far_and_touching_ones_for_the_memory():
    echoes = EchoMemory(guard(), MonitorParams(memory=1.0, near_range=0.6, near_memory=30.0))
    echoes.add(0.0, np.zeros(3), reading(Fr1=0.3, Lt1=1.5, Rt1=0.1))
    assert len(echoes.arcs(np.zeros(3))) == 3
    for k in range(1, 200):  # 20 s on, the robot 0.2 m further on, hearing nothing
        echoes.add(0.1 * k, np.array([0.001 * k, 0.0, 0.0]), reading())
    kept = echoes.arcs(np.array([0.2, 0.0, 0.0]))
    assert len(kept) == 1  # the near echo ahead, not the far one nor the touch
    # carried by odometry: 0.25 + 0.3 ahead of the centre then, 0.2 m nearer now
    assert math.isclose(kept[0, 1, 0], 0.35, abs_tol=0.01)
    for k in range(200, 320):
        echoes.add(0.1 * k, np.array([0.2, 0.0, 0.0]), reading())
    assert len(echoes.arcs(np.array([0.2, 0.0, 0.0]))) == 0  # past the near memory


def test_a_kept_near_echo_is_freed_where_a_later_echo_from_farther_off_crosses_it():
    """Beside a doorway the jambs' kept arcs reach across the opening; a sonar that later
    hears its nearest echo beyond them shows that part free.  No echo shows nothing."""
    one = SonarGuard(np.array([[0.25, 0.0, 0.0]]))
    echoes = EchoMemory(one, MonitorParams(memory=1.0, near_range=0.6, near_memory=30.0))
    echoes.add(0.0, np.zeros(3), np.array([0.4]))  # an arc 0.65 m ahead, 0.1 m either side
    for k in range(1, 20):  # no echo (a grazing wall is silent): kept
        echoes.add(0.1 * k, np.zeros(3), np.array([4.0]))
    assert len(echoes.arcs(np.zeros(3))) == 1
    def hear_far(time: float, heading: float) -> float:
        """Hear an echo 2 m off turned ``heading`` (deg), then nothing for over the memory."""
        echoes.add(time, np.array([0.0, 0.0, math.radians(heading)]), np.array([2.0]))
        for k in range(1, 12):
            echoes.add(time + 0.1 * k, np.zeros(3), np.array([4.0]))
        return time + 1.2

    # turned 10 degrees left: the arc's left end is inside the cone, nearer than 2 m, and
    # free; the rest is not, and the echo is there
    time = hear_far(2.0, 10.0)
    kept = echoes.arcs(np.zeros(3))
    assert len(kept) == 1 and kept[0, 2].tolist() == kept[0, 0].tolist()  # the left end
    assert kept[0, :, 1].max() < 0.05 and kept[0, :, 1].min() < -0.05  # is freed, the rest not
    hear_far(time, 0.0)  # straight on: all of it free
    assert len(echoes.arcs(np.zeros(3))) == 0


def test_monitors_sharing_one_memory_add_no_scans_and_check_with_their_own_horizon():
    """navigate.echo_memory feeds one memory to the monitor and the behaviours; each checks
    motions on it with its own parameters."""
    shared = EchoMemory(guard(), MonitorParams(memory=1.0))
    shared.add(0.0, np.zeros(3), reading(Fr1=0.5, Fr2=0.5))
    quick = CollisionMonitor(guard(), MonitorParams(time_before_collision=0.6), echoes=shared)
    wary = CollisionMonitor(guard(), MonitorParams(time_before_collision=3.0), echoes=shared)
    assert quick.step(0.0, np.zeros(3), reading(), 0.4, 0.0) == (0.4, 0.0)
    v, _ = wary.step(0.0, np.zeros(3), reading(), 0.4, 0.0)  # the echo within its 3 s
    assert 0.0 < v < 0.4
    assert len(shared.arcs(np.zeros(3))) == 2  # their readings (none) were not added


def backing_flush_against_a_wall(near_memory: float) -> float:
    """A robot drove along a wall 0.2 m off its right side, then turned 17 degrees left
    with its right side to it; its right sonars now read their least range (the wall is
    within 0.1 m, at an angle they cannot tell) and it is asked to back for 3 s, which
    brings its rear-right corner in.  How far the corner stays off the wall (m; < 0: in)."""
    monitor = CollisionMonitor(guard(), MonitorParams(memory=1.0, near_memory=near_memory))
    along = reading(Rt1=0.2, Rt2=0.2, RtFr2=0.213, RtFr1=0.244, FrRt2=0.31, BkRt=0.31)
    for k in range(20):  # the wall is the line y = -0.45
        monitor.step(0.1 * k, np.array([0.05 * k, 0.0, 0.0]), along, 0.5, 0.0)
    touching = reading(Rt1=0.1, Rt2=0.1, RtFr2=0.1, RtFr1=0.1, BkRt=0.1)
    x, y, th = 1.2, -0.10, 0.3  # the rear-right corner 0.04 m off the wall
    gap = math.inf
    for k in range(30, 60):
        v, w = monitor.step(0.1 * k, np.array([x, y, th]), touching, -0.15, 0.0)
        x, y, th = x + 0.1 * v * math.cos(th), y + 0.1 * v * math.sin(th), th + 0.1 * w
        corner_y = y - 0.25 * math.sin(th) - 0.25 * math.cos(th)
        gap = min(gap, corner_y + 0.45)
    return gap


def test_backing_into_a_wall_heard_before_it_came_flush_stops_short_of_it():
    assert backing_flush_against_a_wall(near_memory=30.0) > 0.0
    # with only the last second's echoes, the least-range readings say nothing of the angle
    assert backing_flush_against_a_wall(near_memory=0.0) < 0.0


def test_held_still_with_every_asked_motion_refused_it_backs_or_turns_the_clear_way():
    """Something touches the front-right corner (the sonar's least range) and a wall is close
    behind: the behaviour's escape asks to turn left on the spot, which pushes the front
    corner into it. After ``patience`` s the monitor drives the nearest clear motion."""
    monitor = CollisionMonitor(guard(), MonitorParams(patience=1.0, recovery_time=1.0))
    scan = reading(FrRt1=0.1, Bk2=0.28)
    held = [monitor.step(0.1 * k, np.zeros(3), scan, 0.0, 0.6) for k in range(10)]
    assert held == [(0.0, 0.0)] * 10
    v, w = monitor.step(1.0, np.zeros(3), scan, 0.0, 0.6)
    assert monitor.recoveries == 1 and (v, w) != (0.0, 0.0) and v <= 0.0
    assert monitor._clear(monitor.arcs(np.zeros(3)), v, w)
    # it keeps that motion for recovery_time, then hands back to what is asked
    assert monitor.step(1.5, np.zeros(3), scan, 0.0, 0.6) == (v, w)
    assert monitor.step(2.05, np.zeros(3), scan, 0.0, 0.6) == (0.0, 0.0)


def test_carry_points_is_the_inverse_of_the_motion():
    points = np.array([[1.0, 0.5], [-0.3, 0.2]])
    then, now = np.array([1.0, 2.0, 0.3]), np.array([1.5, 1.8, -0.4])
    back = carry_points(carry_points(points, then, now), now, then)
    assert np.allclose(back, points)


# ---- closed loop ----------------------------------------------------------------------------------
def wall_end_world(tmp_path):
    """A wall whose end is just off the robot's front-right corner (robot at the origin, east)."""
    xc, yc = floor_plan(6.0, 5.0, 0.05)
    x, y = xc - 2.0, yc - 3.0  # the robot's frame: the start at (2, 3) facing east
    outer = (xc < 0) | (xc > 6) | (yc < 0) | (yc > 5)
    block = (x > 0.32) & (x < 2.5) & (y > -2.5) & (y < -0.38)
    path = write_world(tmp_path, "wall_end", outer | block, start=(2.0, 3.0, 0.0),
                       doc="A wall end off the front-right corner.")
    return load_world(path)


@pytest.mark.parametrize("monitored, touches", [(False, True), (True, False)])
def test_a_right_turn_round_a_wall_end_clips_it_unless_monitored(tmp_path, monitored, touches):
    world = wall_end_world(tmp_path)
    sim = Simulation(world, [("r", ATRV, world.start)], seed=0)
    robot = sim.robots["r"]
    monitor = CollisionMonitor(guard())
    for tick in range(30):
        ranges, _ = sim.sonar("r")
        v, w = 0.3, -0.9  # the follower's turn round the end of its wall
        if monitored:
            v, w = monitor.step(0.1 * tick, robot.odom, ranges, v, w)
        sim.command("r", v, w)
        sim.step(0.1)
    assert (robot.collisions > 0) == touches


#: The sonars of gen:office:10 at 9.8 s, in the robot file's order: the follower turning
#: left from a wall it meets 60 degrees off its heading, 0.12 m ahead of the front-right
#: corner; the front sonars, at a grazing angle, hear nothing (the run's first contact).
OBLIQUE_WALL = [4.0, 4.0, 4.0, 0.77, 0.15, 0.15, 0.19, 0.27, 0.3, 0.6, 4.0, 3.58, 3.31, 1.13,
                0.92, 0.53]


@pytest.mark.parametrize("wall_extent, stopped", [(0.0, False), (0.05, True)])
def test_a_wall_met_obliquely_is_a_wall_across_the_beams_not_points_beside_the_path(
        wall_extent, stopped):
    """Each echo's arc has a point just outside the body swept by the follower's gentle left
    turn, so the arc rule lets it on into the wall; the walls across the beams at those
    points (the sonar hears a wall square on) stop it in time."""
    arcs = guard().echo_arcs(np.array(OBLIQUE_WALL))
    t = guard().collision_time(arcs, 0.42, 0.45, horizon=0.6, wall_extent=wall_extent)
    assert (t < 0.6) == stopped


def test_a_monitor_on_a_shared_memory_takes_its_walls_from_the_memory():
    """What an echo stands for is the memory's: the monitor and the behaviours checking on
    one memory cannot disagree about it."""
    shared = EchoMemory(guard(), MonitorParams(wall_extent=0.05))
    monitor = CollisionMonitor(guard(), MonitorParams(), echoes=shared)
    shared.add(0.0, np.zeros(3), np.array(OBLIQUE_WALL))
    v, w = monitor.step(0.0, np.zeros(3), np.array(OBLIQUE_WALL), 0.42, 0.45)
    assert monitor.scale < 1.0 and shared.collision_time(np.zeros(3), 0.42, 0.45) < 0.6
    alone = CollisionMonitor(guard(), MonitorParams())
    alone.step(0.0, np.zeros(3), np.array(OBLIQUE_WALL), 0.42, 0.45)
    assert alone.scale == 1.0


# ---- echoes located by their closing rate ----------------------------------------------------------
@pytest.mark.parametrize("triangulate", [False, True])
def test_an_echo_closing_as_fast_as_the_robot_drives_is_in_its_way(triangulate):
    """A wall end straight ahead of the front corner, heard by the front-right sonar at the
    inner edge of its cone until the echo is lost at a grazing angle: its arc reaches out to
    the side, clear of the path; its closing rate puts it in the path."""
    target = np.array([0.7, -0.24])  # world, the robot drives along y = 0
    mount = ATRV.sonar_mounts[ATRV.sonar_names.index("FrRt1")]
    memory = EchoMemory(guard(), MonitorParams(triangulate=triangulate))
    for k in range(7):
        pose = np.array([0.04 * k, 0.0, 0.0])
        r = float(np.hypot(*(target - pose[:2] - mount[:2])))
        memory.add(0.1 * k, pose, reading(FrRt1=r) if k < 6 else reading())
    t = memory.collision_time(pose, 0.4, 0.0)
    if triangulate:
        assert t < 0.6
    else:
        assert t == math.inf


@pytest.mark.parametrize("triangulate, wall_extent", [(True, 0.0), (False, 0.05)])
def test_an_echo_beside_the_path_stays_beside_it(triangulate, wall_extent):
    """A door jamb 0.2 m right of the body's side closes slower than the robot drives:
    located beside the path, it does not stop a robot driving through the door (nor does
    the wall across the beam that each point of its arcs may stand for)."""
    memory = EchoMemory(guard(), MonitorParams(triangulate=triangulate,
                                               wall_extent=wall_extent))
    jamb = np.array([1.0, -0.45])
    for k in range(12):
        pose = np.array([0.04 * k, 0.0, 0.0])
        ranges = reading(**{name: float(np.hypot(*(jamb - pose[:2] - m[:2])))
                            for name, m in zip(ATRV.sonar_names, ATRV.sonar_mounts)
                            if name in ("FrRt1", "FrRt2", "RtFr1")})
        memory.add(0.1 * k, pose, ranges)
        assert memory.collision_time(pose, 0.4, 0.0) == math.inf, k


def recorded_run(folder, front: list[float], contact_tick: int | None):
    """A run folder as a sweep records it: the robot drives straight on at 0.4 m/s while
    its front sonars read ``front`` tick by tick (4 m: no echo)."""
    folder.mkdir(parents=True)
    n = len(front)
    ranges = np.full((n, 16), ATRV.sonar.max_range)
    for name in ("Fr1", "Fr2"):
        ranges[:, ATRV.sonar_names.index(name)] = front
    np.savez(folder / "sonar.npz", **{"robot@tick": np.arange(n), "robot@ranges": ranges,
                                       "robot@echo": ranges < ATRV.sonar.max_range,
                                       "robot@mounts": ATRV.sonar_mounts,
                                       "robot@cone_deg": ATRV.sonar.cone_deg,
                                       "robot@max_range": ATRV.sonar.max_range})
    rows = "".join(f"{k},{k * 0.1:.1f},robot,{0.04 * k:.3f},0,0,{0.04 * k:.3f},0,0,0.4,0\n"
                   for k in range(n))
    (folder / "trajectory.csv").write_text(
        "tick,time,robot,x,y,theta,odom_x,odom_y,odom_theta,v,w\n" + rows)
    log = [] if contact_tick is None else [{"t": contact_tick * 0.1}]
    (folder / "run.json").write_text(json.dumps({"metrics": {"world": {"collision_log": log}}}))


def test_the_replay_counts_contacts_seen_coming_and_stops_where_nothing_was_hit(tmp_path):
    from monitor_replay import replay_run
    # a wall 2 m ahead, closing at 0.04 m a tick: touched at tick 48
    wall = [max(2.0 - 0.04 * k, 0.1) for k in range(60)]
    recorded_run(tmp_path / "wall", wall, contact_tick=48)
    counts = replay_run(tmp_path / "wall", MonitorParams())
    assert counts == {"foreseen": 1, "missed": 0, "moving": 2, "stopped": 0}  # ticks 10, 17
    # a robot driving on against something touching its front, with no contact recorded:
    # every moving tick sampled then is a stop
    recorded_run(tmp_path / "open", [4.0] * 40 + [0.1] * 40, contact_tick=None)
    counts = replay_run(tmp_path / "open", MonitorParams())
    assert counts["foreseen"] == counts["missed"] == 0
    assert counts["stopped"] == 5 and counts["moving"] == 10  # ticks 45, 52, ... 73 of 10..73


def test_contacts_are_named_by_the_part_of_the_body_and_the_motion(tmp_path):
    from contacts import contacts
    # driving ahead along +x, then backing: touched at the front-right, then the rear-left
    run = tmp_path / "runs" / "hall-1-s0"
    run.mkdir(parents=True)
    rows = "".join(f"{k},{k * 0.1:.1f},robot,{0.04 * k:.3f},0,0,0,0,0,"
                   f"{0.4 if k < 30 else -0.15},0\n" for k in range(60))
    (run / "trajectory.csv").write_text(
        "tick,time,robot,x,y,theta,odom_x,odom_y,odom_theta,v,w\n" + rows)
    log = [{"t": 2.0, "contact": [0.8 + 0.25, -0.25]},  # the robot at x = 0.8, then 2.0
           {"t": 5.0, "contact": [2.0 - 0.25, 0.24]}]
    (run / "run.json").write_text(json.dumps({"metrics": {"world": {"collision_log": log}}}))
    found = contacts(run)
    assert [(c["part"], c["motion"]) for c in found] == [("front-right", "ahead"),
                                                         ("rear-left", "backing")]


def ranges_to_wall(a, b) -> np.ndarray:
    """The ATRV's sonar readings of a thin wall from ``a`` to ``b`` in the robot's frame, the
    robot at the origin: sim2d's cone model, without noise or specular loss."""
    spec = ATRV.sonar
    sensors = sensor_poses(np.zeros(3), np.asarray(ATRV.sonar_mounts, dtype=np.float64))
    ranges, _ = cone_ranges(sensors, np.array([[*a, *b, 0.0]]), math.radians(spec.cone_deg) / 2,
                            spec.max_range)
    return np.where(np.isfinite(ranges), ranges, spec.max_range)


@pytest.mark.parametrize("wall, way", [
    (((0.27, -0.27), (-2.0, -0.67)), -1),  # askew, touching by the front-right corner: back
    (((-0.27, -0.27), (2.0, -0.67)), 1),   # askew, by the rear-right corner: ahead
    (((2.0, -0.3), (-2.0, -0.3)), 1),      # flush along the right side: ahead
])
def test_too_close_to_turn_the_robot_eases_out_by_the_end_farther_from_the_wall(wall, way):
    guard = SonarGuard.for_robot(ATRV)
    ranges = ranges_to_wall(*wall)
    assert guard.blocked(ranges, 0.0, 0.8) == "turning"
    assert guard.ease_direction(ranges) == way


# ---- bumpers ----------------------------------------------------------------------------------
LEFT = [(math.radians(45), math.radians(135))]


def test_a_left_bumper_pressed_backing_stops_backing_and_lets_the_robot_go_ahead():
    """Pressed while backing, the left switch was met by the rear-left corner: backing (and
    a turn that swings that corner left) would push on, going ahead frees it."""
    memory = EchoMemory(guard())
    pose, none = np.array([1.0, 2.0, 0.3]), reading()
    memory.add(0.0, pose, none)
    assert not memory.stops(pose, -0.15, 0.0)  # no sonar looks past the rear-left corner
    memory.add_touch(0.0, pose, LEFT, -0.15, 0.0)
    assert memory.stops(pose, -0.15, 0.0) and memory.stops(pose, 0.0, -0.6)
    assert not memory.stops(pose, 0.15, 0.0) and not memory.stops(pose, 0.0, 0.6)
    # felt walls are kept as long as near echoes, then forgotten
    memory.add(29.0, pose, none)
    memory.add_touch(29.0, pose, [], 0.0, 0.0)
    assert memory.stops(pose, -0.15, 0.0)
    memory.add(31.0, pose, none)
    memory.add_touch(31.0, pose, [], 0.0, 0.0)
    assert not memory.stops(pose, -0.15, 0.0)


def felt_stops(switch: int, v: float, w: float) -> dict[tuple[float, float], bool]:
    """Which slow motions a memory that felt one switch pressed at (v, w) refuses."""
    spans = [(start, end) for _, start, end in ATRV.bumpers]
    memory = EchoMemory(guard())
    memory.add(0.0, np.zeros(3), reading())
    memory.add_touch(0.0, np.zeros(3), [spans[switch]], v, w)
    return {(a, b): memory.stops(np.zeros(3), a, b)
            for a in (-0.15, 0.0, 0.15) for b in (-0.6, 0.0, 0.6) if a or b}


@pytest.mark.parametrize("switch", range(4))
@pytest.mark.parametrize("v, w", [(0.3, 0.0), (0.2, 0.3), (-0.15, 0.0), (0.0, 0.6), (0.0, 0.0)])
def test_one_switch_pressed_leaves_a_way_to_go(switch, v, w):
    """Whatever pressed one switch (or nothing known did: the robot stood still), the wall
    it felt leaves the robot a way to drive off: a memory that boxed it in would end the
    run where it stands."""
    stops = felt_stops(switch, v, w)
    assert not (stops[(0.15, 0.0)] and stops[(-0.15, 0.0)]), stops


@pytest.mark.parametrize("switch, v, w", [
    (0, 0.3, 0.0), (0, 0.2, 0.3), (0, 0.2, -0.3),  # front, driving ahead
    (1, -0.15, 0.0), (1, 0.2, 0.3), (1, 0.0, 0.6),  # left: backing, turning left
    (2, -0.15, 0.0), (2, -0.1, 0.4),  # rear, backing
    (3, 0.2, -0.3), (3, 0.0, -0.6)])  # right, turning right
def test_the_motion_that_pressed_a_switch_is_refused_and_a_turn_stays_free(switch, v, w):
    """A switch the motion pressed: the wall is where the corner that drove in met it, so
    going on is refused, and the robot may still turn one way (a square body flush with a
    wall could not, but one corner on it can)."""
    stops = felt_stops(switch, v, w)
    going_on = (0.15 * np.sign(v), 0.6 * np.sign(w)) if v else (0.0, 0.6 * np.sign(w))
    assert stops[going_on], stops
    assert not (stops[(0.0, 0.6)] and stops[(0.0, -0.6)]), stops


def slanted_wall_behind_left(tmp_path):
    """A wall behind the robot's left, 16 degrees off its heading, out of every sonar's sight
    (the nearest side sonar reads its least range, the rear one meets it at a grazing
    angle): backing 0.17 m brings the rear-left corner onto it."""
    xc, yc = floor_plan(6.0, 5.0, 0.05)
    x, y = xc - 3.0, yc - 2.0  # the robot's frame: the start at (3, 2) facing east
    outer = (xc < 0) | (xc > 6) | (yc < 0) | (yc > 5)
    wall = (y > 0.27 + (x + 0.35) * math.tan(math.radians(16))) & (x < 1.0) & (y < 1.5)
    path = write_world(tmp_path, "slanted", outer | wall, start=(3.0, 2.0, 0.0),
                       doc="A slanted wall behind the robot's left.")
    return load_world(path)


@pytest.mark.parametrize("felt", [False, True])
def test_backing_into_a_wall_no_sonar_hears_stops_once_the_bumper_has_felt_it(tmp_path, felt):
    """A behaviour asks to back for 8 s.  Without its bumpers the monitor lets the robot
    push on into the wall; with them it stops there, and once its patience is out it
    drives clear the way that is free and does not come back."""
    world = slanted_wall_behind_left(tmp_path)
    sim = Simulation(world, [("r", ATRV, world.start)], seed=0)
    robot = sim.robots["r"]
    monitor = CollisionMonitor(guard())
    spans = [(start, end) for _, start, end in ATRV.bumpers]
    pressed_ticks, v, w = 0, 0.0, 0.0
    for tick in range(80):
        ranges, _ = sim.sonar("r")
        pressed = sim.bumpers("r")
        pressed_ticks += bool(pressed.any())
        if felt:  # before the monitor's step, which adds the scan and checks
            monitor.echoes.add_touch(0.1 * tick, robot.odom,
                                     [s for s, on in zip(spans, pressed) if on], v, w)
        v, w = monitor.step(0.1 * tick, robot.odom, ranges, -0.15, 0.0)
        sim.command("r", v, w)
        sim.step(0.1)
    assert robot.collisions >= 1  # the first touch is how it learns of the wall
    if felt:
        assert robot.collisions == 1 and pressed_ticks <= 15, (robot.collisions, pressed_ticks)
        assert not sim.bumpers("r").any()
    else:
        assert pressed_ticks >= 30, pressed_ticks


def test_the_memory_block_feels_what_pressed_the_bumper_from_odometry(tmp_path):
    """navigate.echo_memory takes the motion that pressed a switch from the last 0.3 s of
    odometry (against a wall the robot hardly moves on the tick it is pressed), and says
    which input is wrong when the switches are not the robot's."""
    from blocks.core import BlockError
    from blocks.core.block import RunContext
    from blocks.navigate.blocks import EchoMemoryBlock
    block = EchoMemoryBlock({name: p.default for name, p in EchoMemoryBlock.params.items()},
                            name="echoes", ctx=RunContext(dt=0.1, seed=0))
    block.reset()
    none, left = np.zeros(4, bool), np.array([False, True, False, False])
    for k in range(4):  # backing along x at 0.15 m/s
        block.ctx.tick = k
        block.step(np.array([1.0 - 0.015 * k, 0.0, 0.0]), reading(), none)
    block.ctx.tick = 4
    memory = block.step(np.array([0.955, 0.0, 0.0]), reading(), left)["echoes"]
    assert memory.stops(np.array([0.955, 0.0, 0.0]), -0.15, 0.0)
    assert not memory.stops(np.array([0.955, 0.0, 0.0]), 0.15, 0.0)
    with pytest.raises(BlockError, match="input 'bumpers'"):
        block.step(np.zeros(3), reading(), np.zeros(2, bool))
