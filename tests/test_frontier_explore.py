"""Frontier exploration: the frontier finder, goal choice, the explorer's outcomes, and the
explorer in closed loop on a small ring corridor the perimeter follower would not finish and
round a free-standing block it would circle for ever."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from blocks.explore.explorer import ExploreParams, FrontierExplorer
from blocks.explore.frontiers import find_frontiers, frontier_goals, frontier_mask
from blocks.maps.features import sensor_poses_along
from blocks.maps.logodds import InverseSonarModel, LogOddsMap
from blocks.maps.mapio import OccupancyMap
from blocks.navigate.grid import inflate
from blocks.navigate.collision_monitor import MonitorParams
from blocks.navigate.guard import SonarGuard
from sim2d.robot import load_robot
from sim2d.simulation import Simulation
from sim2d.world import load_world

from conftest import floor_plan, write_world

RES = 0.1
FREE, OCC, UNKNOWN = 0.05, 0.95, 0.5


def unknown_floor(width: float, height: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An all-unknown map ``width`` x ``height`` m, and its cells' centre x and y."""
    h, w = int(height / RES), int(width / RES)
    y, x = np.mgrid[0:h, 0:w]
    return np.full((h, w), UNKNOWN), (x + 0.5) * RES, (y + 0.5) * RES


def room_map(opening: bool = True, pocket: bool = False) -> OccupancyMap:
    """An 8 x 6 m grid: a free 5 x 4 m room (walls mapped) at x 1..6, y 1..5.

    ``opening``: the east wall has a 1.2 m gap to unknown space (a frontier);
    ``pocket``: a free strip beyond a closed wall at x 6.5..7.5 (seen through
    it, not reachable), bordering unknown.
    """
    p, xc, yc = unknown_floor(8, 6)
    inside = (xc > 1.0) & (xc < 6.0) & (yc > 1.0) & (yc < 5.0)
    p[inside] = FREE
    wall = ((xc > 0.8) & (xc < 6.2) & (yc > 0.8) & (yc < 5.2)) & ~inside
    p[wall] = OCC
    if opening:
        p[wall & (xc > 6.0) & (yc > 2.4) & (yc < 3.6)] = FREE
    if pocket:
        p[(xc > 6.6) & (xc < 7.4) & (yc > 1.0) & (yc < 2.0)] = FREE
    return OccupancyMap(p, RES, (0.0, 0.0, 0.0))


# ---- finding frontiers and goals ---------------------------------------------------------------
def test_the_opening_is_the_one_frontier_and_its_goal_is_inside_within_reach():
    m = room_map()
    [frontier] = find_frontiers(m, min_length=0.6)
    assert frontier.length == pytest.approx(1.2, abs=0.25)
    assert frontier.middle[0] == pytest.approx(6.1, abs=0.15)
    assert frontier.middle[1] == pytest.approx(3.0, abs=0.15)
    grid = inflate(m, radius=0.36)
    [goal] = frontier_goals(grid, [frontier], (2.0, 3.0), reach=1.0)
    gx, gy = goal.goal
    assert not grid.blocked[grid.world_to_cell(gx, gy)]
    assert math.hypot(gx - frontier.middle[0], gy - frontier.middle[1]) <= 1.0 + 1e-9
    assert goal.distance == pytest.approx(math.hypot(gx - 2.05, gy - 3.05), abs=0.1)


def test_a_closed_room_has_no_frontier_and_short_runs_are_noise():
    assert find_frontiers(room_map(opening=False)) == []
    assert find_frontiers(room_map(), min_length=2.0) == []


def test_a_frontier_seen_through_a_wall_has_no_goal():
    m = room_map(opening=False, pocket=True)
    frontiers = find_frontiers(m)
    assert frontiers  # the pocket's edges
    assert frontier_goals(inflate(m, radius=0.36), frontiers, (2.0, 3.0)) == []


def test_a_frontier_just_beyond_a_wall_has_no_goal_that_sees_it():
    """A beam that passed a wall at a grazing angle marks free floor just outside it: a
    frontier a wall's thickness from the room, within reach of goals inside (the test
    above has its pocket beyond reach).  Going there shows nothing; with the map's walls
    given, no goal sees it, while the real opening keeps its goal."""
    p = room_map(opening=False).occupancy.copy()
    y, x = np.mgrid[0:p.shape[0], 0:p.shape[1]]
    xc, yc = (x + 0.5) * RES, (y + 0.5) * RES
    p[(xc > 0.8) & (xc < 1.0) & (yc > 2.4) & (yc < 3.6)] = FREE  # an opening in the west wall
    p[(xc > 6.2) & (xc < 6.6) & (yc > 1.0) & (yc < 5.0)] = FREE  # leaked past the east wall
    m = OccupancyMap(p, RES, (0.0, 0.0, 0.0))
    grid = inflate(m, radius=0.36)
    frontiers = find_frontiers(m)
    west = [f for f in frontiers if f.middle[0] < 1.5]
    east = [f for f in frontiers if f.middle[0] > 6.0]
    assert len(west) == 1 and east
    blind = frontier_goals(grid, frontiers, (3.0, 3.0))
    assert {id(g.frontier) for g in blind} >= {id(f) for f in east}  # within reach, through it
    walls = m.classes()[0]
    [goal] = frontier_goals(grid, frontiers, (3.0, 3.0), walls=walls)
    assert goal.frontier is west[0]


def test_frontier_mask_counts_the_grid_edge_as_unknown():
    free = np.ones((3, 3), dtype=bool)
    assert frontier_mask(free, ~free).sum() == 8  # every cell but the middle one


def two_rooms_map() -> OccupancyMap:
    """A free room at x 1..6 and another at x 6.2..8 beyond a wall with a door 0.9 m wide
    (y 2.55..3.45); unknown east of x 8 (the frontier)."""
    p, xc, yc = unknown_floor(10, 6)
    inside = (xc > 1.0) & (xc < 8.0) & (yc > 1.0) & (yc < 5.0)
    p[inside] = FREE
    p[((xc > 0.8) & (xc < 8.0) & (yc > 0.8) & (yc < 5.2)) & ~inside] = OCC
    p[(xc > 6.0) & (xc < 6.2) & inside & (np.abs(yc - 3.0) > 0.45)] = OCC
    return OccupancyMap(p, RES, (0.0, 0.0, 0.0))


@pytest.mark.parametrize("heading", [-30.0, 0.0, 30.0])
def test_a_way_from_inside_a_doorway_lines_up_with_it_before_driving_on(heading):
    """Planning while standing in a door (a way back out of a room, a way after a failed
    one), the doorway is under the robot, not ahead of it: it turns square to the door
    before it drives, rather than leaving at a slant that puts a jamb under a corner
    (``door_underfoot``; off, the way's start is not looked at for doorways)."""
    pose = np.array([6.1, 3.0, math.radians(heading)])
    plain = FrontierExplorer(two_rooms_map, GUARD, ExploreParams())
    plain.step(0.0, pose, CLEAR, follower_done=True)
    assert plain.phase == "drive" and not plain._squeeze
    explorer = FrontierExplorer(two_rooms_map, GUARD, ExploreParams(door_underfoot=True))
    v, w = explorer.step(0.0, pose, CLEAR, follower_done=True)
    assert explorer.target is not None and explorer.target.goal[0] > 6.5
    if heading:  # a turn on the spot towards the door's axis first
        assert explorer.phase == "align" and v == 0.0 and w * heading < 0.0
        assert [kind for kind, _ in explorer._pending] == ["door", "leg"]
    else:  # already square to it: straight through, as through any doorway
        assert explorer.phase == "drive" and explorer._squeeze


# ---- the explorer's outcomes, with a point robot -----------------------------------------------
class PointRobot:
    """A kinematic unicycle: enough to follow the explorer's commands on a fixed map."""

    def __init__(self, x: float, y: float, theta: float = 0.0) -> None:
        self.pose = np.array([x, y, theta])

    def move(self, v: float, w: float, dt: float = 0.1) -> None:
        self.pose[2] += w * dt
        self.pose[0] += v * dt * math.cos(self.pose[2])
        self.pose[1] += v * dt * math.sin(self.pose[2])


#: A guard with one sonar ahead and one behind.
GUARD = SonarGuard(np.array([[0.25, 0.0, 0.0], [-0.25, 0.0, math.pi]]))
CLEAR = np.array([4.0, 4.0])


def run(explorer: FrontierExplorer, robot: PointRobot, ticks: int, ranges=CLEAR, **kw):
    for tick in range(ticks):
        out = explorer.step(0.1 * tick, robot.pose, ranges, follower_done=True, **kw)
        if explorer.ended:
            return tick
        if out is not None:
            robot.move(*out)
    return None


def test_it_drives_to_the_opening_and_ends_explored_when_the_frontier_is_seen():
    state = {"map": room_map()}
    explorer = FrontierExplorer(lambda: state["map"], GUARD)
    robot = PointRobot(2.0, 3.0)
    assert run(explorer, robot, 400) is None or explorer.result.goals_reached
    # the robot stood near the opening; "seeing" it closes the frontier
    assert robot.pose[0] > 4.5
    state["map"] = room_map(opening=False)
    assert run(explorer, robot, 100) is not None
    assert explorer.result.end_reason == "explored" and explorer.result.goals_reached >= 1
    assert explorer.step(100.0, robot.pose, CLEAR) is None  # ended: the follower's commands


def test_a_way_blocked_ahead_again_and_again_ends_stuck():
    # Every way is blocked at once: the robot gets nowhere.
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(max_failures=3, max_attempts=5, hand_backs=0,
                                              back_off_time=0.3, bump_memory=0.0))
    robot = PointRobot(2.0, 3.0)
    assert run(explorer, robot, 600, ranges=np.array([0.2, 4.0])) is not None
    r = explorer.result
    assert r.end_reason == "stuck" and r.blocked_ahead == 3 and r.goals_given_up == 0
    assert r.log[1]["failed"] == "blocked ahead"


def test_stuck_it_hands_back_to_the_follower_and_plans_again_from_where_that_took_it():
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(max_failures=3, max_attempts=50, hand_backs=1,
                                              hand_back_distance=2.0, back_off_time=0.3,
                                              bump_memory=0.0))
    robot = PointRobot(2.0, 3.0)
    followed, blocked = 0.0, np.array([0.2, 4.0])
    for tick in range(1200):
        out = explorer.step(0.1 * tick, robot.pose, blocked, follower_done=True,
                            follower_v=0.3, follower_w=0.1)
        if explorer.ended:
            break
        if out is None:  # the follower drives (its loop long closed: that does not count)
            robot.move(0.3, 0.1)
            followed += 0.03
        else:
            robot.move(*out)
    r = explorer.result
    assert r.hand_backs == 1 and r.end_reason == "stuck"
    assert 2.0 <= followed <= 2.2  # the hand-back's distance, then planning again
    assert [e["hand back"] for e in r.log if "hand back" in e] == ["stuck"]
    assert [e["take over"] for e in r.log if "take over" in e] == ["handed back"]
    assert r.start_reason == "loop closed" and r.blocked_ahead == 6


def test_ways_that_fail_here_and_there_while_the_robot_gets_about_are_not_stuck():
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(max_failures=3, max_attempts=50,
                                              back_off_time=0.3, bump_memory=0.0,
                                              max_retraces=0))
    robot = PointRobot(2.0, 2.0)
    spots = [(2.0, 2.0), (4.5, 2.0), (4.5, 4.5), (2.0, 4.5)] * 3
    for tick in range(600):
        explorer.step(0.1 * tick, robot.pose, np.array([0.2, 4.0]), follower_done=True)
        if explorer.ended or explorer.result.ways_failed == len(spots):
            break
        robot.pose[:2] = spots[explorer.result.ways_failed]  # it got 2.5 m on each time
    assert explorer.result.ways_failed == len(spots) and not explorer.ended


def corridor_open_along_its_side() -> OccupancyMap:
    """A 12 x 1.6 m corridor (x 1..13, y 1..2.6) whose north side is open to unknown floor
    all along: one frontier 12 m long, which no look from one place clears (the map
    given to the explorer never changes)."""
    p, xc, yc = unknown_floor(14, 5)
    inside = (xc > 1.0) & (xc < 13.0) & (yc > 1.0) & (yc < 2.6)
    p[inside] = FREE
    p[((xc > 0.8) & (xc < 13.2) & (yc > 0.8) & (yc < 2.6)) & ~inside] = OCC
    return OccupancyMap(p, RES, (0.0, 0.0, 0.0))


def test_a_long_frontier_still_there_after_a_goal_is_reached_is_visited_along_its_length():
    """Reaching the goal at the frontier's middle used up only the part seen from there
    (``seen_radius``); its two ends are visited too, and then the floor counts as done.
    With ``seen_radius`` 0 the whole frontier goes with the goal at its middle."""
    def goals_visited(seen_radius: float) -> list[float]:
        explorer = FrontierExplorer(corridor_open_along_its_side, GUARD,
                                    ExploreParams(spin_rate=3.0, seen_radius=seen_radius,
                                                  end_seen_radius=0.0))
        assert run(explorer, PointRobot(7.0, 1.5), 3000) is not None
        assert explorer.result.end_reason == "explored"
        return [e["goal"][0] for e in explorer.result.log if "goal" in e]
    assert len(goals_visited(0.0)) == 1
    goals = goals_visited(3.0)
    # every part of it was looked at from within seen_radius, not only its middle...
    seen = 3.0 + 0.2  # seen_radius, and a cell
    assert all(min(abs(x - g) for g in goals) <= seen for x in np.arange(1.05, 13.0, 0.1)), goals
    assert len(goals) <= 4, goals  # ...and not from every metre of it


def painted(m: OccupancyMap, *boxes: tuple[float, float, float, float, float]) -> OccupancyMap:
    """``m`` with the cells inside each box (x0, x1, y0, y1, value) set to that value."""
    p = m.occupancy.copy()
    y, x = np.mgrid[0:p.shape[0], 0:p.shape[1]]
    xc, yc = (x + 0.5) * RES, (y + 0.5) * RES
    for x0, x1, y0, y1, value in boxes:
        p[(xc > x0) & (xc < x1) & (yc > y0) & (yc < y1)] = value
    return OccupancyMap(p, RES, (0.0, 0.0, 0.0))


def corridor_open_along_its_side_and_at_its_end() -> OccupancyMap:
    """:func:`corridor_open_along_its_side` with a 0.8 m gap in its east wall as well (y
    1.1..1.9): a second frontier, short and apart from the long one."""
    return painted(corridor_open_along_its_side(), (12.9, 13.3, 1.1, 1.9, FREE))


def test_a_long_frontier_is_looked_at_along_its_length_once_nothing_else_is_left():
    """``end_seen_radius``: its middle, then the other frontier, as without it; then, with
    nothing else left, the long one's parts, before the floor counts as explored."""
    explorer = FrontierExplorer(corridor_open_along_its_side_and_at_its_end, GUARD,
                                ExploreParams(spin_rate=3.0, end_seen_radius=3.0))
    assert run(explorer, PointRobot(7.0, 1.5), 4000) is not None
    assert explorer.result.end_reason == "explored"
    log = explorer.result.log
    switch = next(i for i, e in enumerate(log) if "long frontiers" in e)
    before = [e["goal"] for e in log[:switch] if "goal" in e]
    after = [e["goal"][0] for e in log[switch:] if "goal" in e]
    assert len(before) == 2 and before[1][0] > 11.5, before  # the middle, then the gap
    goals = [g[0] for g in before] + after
    seen = 3.0 + 0.2  # end_seen_radius, and a cell
    assert all(min(abs(x - g) for g in goals) <= seen for x in np.arange(1.05, 13.0, 0.1)), goals
    assert 1 <= len(after) <= 3, after


def two_rooms_joined_at_one_end() -> OccupancyMap:
    """Two 5 x 2 m rooms, one above the other (x 1..6; y 1..3 and 3.4..5.4), a wall between
    them but for a 1.2 m door at its east end (x 4.8..6).  Each room has a 2 m gap to
    unknown floor: the lower one in its south wall at x 3.5..5.5, the upper one in its west
    wall at y 3.6..5.4, right above the lower room's west end."""
    p, xc, yc = unknown_floor(8, 7)
    p[(xc > 0.8) & (xc < 6.2) & (yc > 0.8) & (yc < 5.6)] = OCC
    m = painted(OccupancyMap(p, RES, (0.0, 0.0, 0.0)),
                (1.0, 6.0, 1.0, 3.0, FREE), (1.0, 6.0, 3.4, 5.4, FREE), (4.8, 6.0, 2.9, 3.5, FREE))
    return painted(m, (3.5, 5.5, 0.7, 1.1, FREE), (0.7, 1.1, 3.6, 5.4, FREE))


@pytest.mark.parametrize("goal_distance, room", [("straight", "upper"), ("path", "lower")])
def test_a_goal_is_as_near_as_the_way_there_with_path_distances(goal_distance, room):
    """From the lower room's west end the upper room's gap is 2 m away through the wall
    and 9 m by the door; the lower room's own gap is 3 m either way.  Measured along the
    straight line the explorer leaves the room for the other; along the way, it finishes
    the room it is in."""
    explorer = FrontierExplorer(two_rooms_joined_at_one_end, GUARD,
                                ExploreParams(goal_distance=goal_distance))
    run(explorer, PointRobot(1.8, 2.0), 5)
    first = next(e["goal"] for e in explorer.result.log if "goal" in e)
    assert (first[1] < 3.0) == (room == "lower"), first


def corridor_with_floor_seen_through_its_wall() -> OccupancyMap:
    """A closed 12 x 1.6 m corridor (x 1..13, y 1..2.6) with a strip of free floor 0.4 m
    wide just outside its north wall (what beams passing the wall at a grazing angle
    clear) and unknown beyond: a frontier 12 m long that no place inside sees."""
    return painted(corridor_open_along_its_side(), (0.8, 13.2, 2.6, 2.8, OCC),
                   (1.0, 13.0, 2.8, 3.2, FREE))


def test_a_long_frontier_seen_through_a_wall_is_not_visited_along_its_length():
    """Its goal within reach across the wall is visited once (as any frontier's is), but
    its other parts are approached again only from goals that see them: none does."""
    explorer = FrontierExplorer(corridor_with_floor_seen_through_its_wall, GUARD,
                                ExploreParams(spin_rate=3.0, seen_radius=3.0))
    robot = PointRobot(7.0, 1.5)
    assert run(explorer, robot, 3000) is not None
    goals = [e["goal"] for e in explorer.result.log if "goal" in e]
    assert explorer.result.end_reason == "explored"
    assert len(goals) == 1, goals


def test_at_the_end_a_long_frontier_seen_through_a_wall_is_still_not_visited():
    explorer = FrontierExplorer(corridor_with_floor_seen_through_its_wall, GUARD,
                                ExploreParams(spin_rate=3.0, end_seen_radius=3.0))
    assert run(explorer, PointRobot(7.0, 1.5), 3000) is not None
    assert explorer.result.end_reason == "explored"
    assert any("long frontiers" in e for e in explorer.result.log)
    assert len([e for e in explorer.result.log if "goal" in e]) == 1


def test_a_frontier_whose_way_keeps_failing_is_given_up_and_counted():
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(max_attempts=2, back_off_time=0.3,
                                              bump_memory=0.0))
    robot = PointRobot(2.0, 3.0)
    assert run(explorer, robot, 600, ranges=np.array([0.2, 4.0])) is not None
    r = explorer.result
    assert r.end_reason == "frontiers given up" and r.goals_given_up == 1
    assert r.frontiers_given_up == 1


def test_frontiers_given_up_are_tried_again_before_the_floor_counts_as_explored():
    """The first way to the opening is blocked; by the time every other frontier is done,
    the way is clear (a door that was shut, a person who stood there)."""
    state = {"blocked": True}
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(max_attempts=2, back_off_time=0.3,
                                              bump_memory=0.0, retry_given_up=1))
    robot = PointRobot(2.0, 3.0)
    for tick in range(1500):
        ranges = np.array([0.2, 4.0]) if state["blocked"] else CLEAR
        out = explorer.step(0.1 * tick, robot.pose, ranges, follower_done=True)
        if explorer.result.goals_given_up:
            state["blocked"] = False
        if explorer.ended:
            break
        robot.move(*out)
    r = explorer.result
    assert r.frontiers_retried == 1 and any("retry" in e for e in r.log)
    assert r.goals_reached >= 1 and robot.pose[0] > 4.5  # it went there after all


def test_hold_stops_the_robot_and_the_follower_drives_until_its_loop_closes():
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(stale_distance=0.0))
    pose = np.array([2.0, 3.0, 0.0])
    assert explorer.step(0.0, pose, CLEAR) is None  # the follower's turn
    assert explorer.step(0.1, pose, CLEAR, follower_done=True, hold=True) == (0.0, 0.0)
    assert explorer.result.start_reason == "loop closed"
    v, _ = explorer.step(0.2, pose, CLEAR, follower_done=True)
    assert explorer.active and explorer.target is not None
    assert explorer.step(0.3, pose, CLEAR, preempted=True) == (0.0, 0.0)
    assert explorer.target is None and explorer.phase == "plan"  # planned again afterwards


def test_a_follower_that_brings_no_new_floor_is_taken_over():
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(stale_distance=10.0, stale_gain=1.0))
    robot = PointRobot(2.0, 2.0)
    took_over = None
    for tick in range(600):  # circling (as round an island), always on the same mapped floor
        out = explorer.step(0.1 * tick, robot.pose, CLEAR)
        if out is not None:
            took_over = tick
            break
        robot.move(0.5, 0.5)
    assert took_over is not None and explorer.result.start_reason == "no new floor"
    assert 10.0 <= explorer._driven <= 13.0  # within one look (2 s) after 10 m


# ---- closed loop: a ring corridor in the simulator -----------------------------------------------
class ExploreMap:
    """The explorer's log-odds map of a closed-loop test, drawn from odometry and the sonar."""

    def __init__(self, spec) -> None:
        self.mounts = np.asarray(spec.sonar_mounts)
        self.grid = LogOddsMap(InverseSonarModel(cone_deg=spec.sonar.cone_deg,
                                                 max_range=spec.sonar.max_range,
                                                 no_echo_reach=1.0), resolution=RES)

    def add(self, pose: np.ndarray, ranges: np.ndarray) -> None:
        self.grid.add_scan(sensor_poses_along(np.asarray(pose)[None], self.mounts)[0], ranges)

    def snapshot(self) -> OccupancyMap:
        p, (ix, iy) = self.grid.probabilities()
        return OccupancyMap(p, RES, (ix * RES, iy * RES, 0.0))

    def free_at(self, xc: np.ndarray, yc: np.ndarray) -> np.ndarray:
        """Whether the map marks each point (xc, yc) free."""
        m = self.snapshot()
        _, mapped_free, _ = m.classes()
        cols = np.floor((xc - m.origin[0]) / RES).astype(int)
        rows = np.floor((yc - m.origin[1]) / RES).astype(int)
        ok = (rows >= 0) & (rows < m.shape[0]) & (cols >= 0) & (cols < m.shape[1])
        seen = np.zeros(xc.shape, dtype=bool)
        seen[ok] = mapped_free[rows[ok], cols[ok]]
        return seen


def ring_world(tmp_path) -> tuple[object, np.ndarray]:
    """A ring corridor 2 m wide round a solid 6 x 3 m block (outer 10 x 7 m); its floor."""
    res = 0.05
    xc, yc = floor_plan(10.0, 7.0, res)
    outer = (xc < 0) | (xc > 10) | (yc < 0) | (yc > 7)
    block = (xc > 2) & (xc < 8) & (yc > 2) & (yc < 5)
    path = write_world(tmp_path, "ring", outer | block, start=(1.0, 3.5, 1.5708),
                       doc="A ring corridor round a solid block.")
    # the floor at least 0.2 m from a wall: the sonar draws walls a cone's arc thick
    free = ndimage.distance_transform_edt(~(outer | block)) * res >= 0.2
    return load_world(path), (xc, yc, free)


def test_the_explorer_goes_round_a_ring_corridor_without_touching_a_wall(tmp_path):
    world, (xc, yc, free) = ring_world(tmp_path)
    spec = load_robot("atrv_mini")
    sim = Simulation(world, [("r", spec, world.start)], seed=0)
    robot = sim.robots["r"]
    grid = ExploreMap(spec)
    explorer = FrontierExplorer(grid.snapshot, SonarGuard.for_robot(spec))
    for tick in range(6000):
        ranges, _ = sim.sonar("r")
        grid.add(robot.odom, ranges)
        out = explorer.step(0.1 * tick, robot.odom, ranges, follower_done=True)
        if explorer.ended:
            break
        sim.command("r", *out)
        sim.step(0.1)
    assert explorer.result.end_reason == "explored", explorer.result.log[-5:]
    assert robot.collisions == 0
    # the whole ring is on the map as free floor (odometry ~ truth over a few minutes)
    seen = grid.free_at(xc, yc)
    assert (seen & free).sum() / free.sum() >= 0.85
    # ...including the far side of the block, which the robot had to drive round to see
    far = free & (xc > 8.3)
    assert (seen & far).sum() / far.sum() >= 0.8


# ---- the sonar guard -----------------------------------------------------------------------------
ATRV = load_robot("atrv_mini")


def reading(name: str, value: float) -> np.ndarray:
    ranges = np.full(len(ATRV.sonar_names), 4.0)
    ranges[ATRV.sonar_names.index(name)] = value
    return ranges


@pytest.mark.parametrize("name, value, v, w, why", [
    ("Fr1", 0.2, 0.4, 0.0, "ahead"),
    ("Fr1", 0.2, -0.2, 0.0, ""),  # backing away from it is fine
    ("Fr1", 0.7, 0.4, 0.0, ""),  # beyond the stop distance
    ("FrRt1", 0.15, 0.4, 0.0, "ahead"),  # a jamb at the front corner, heard by a side-front sonar
    ("Bk1", 0.2, -0.2, 0.0, "behind"),
    ("Rt1", 0.05, 0.0, 1.0, "turning"),  # a wall 5 cm from the side: the corners would hit it
    ("Rt1", 0.3, 0.0, 1.0, ""),  # clear of the corners' circle
    ("Rt1", 0.05, 0.4, 0.0, ""),  # driving along the wall beside it is fine
])
def test_the_guard_refuses_motions_into_echoes(name, value, v, w, why):
    guard = SonarGuard(ATRV.sonar_mounts, length=ATRV.length, width=ATRV.width)
    assert guard.blocked(reading(name, value), v, w) == why


def test_readings_without_an_echo_say_nothing():
    guard = SonarGuard(ATRV.sonar_mounts)
    assert len(guard.echo_points(np.full(16, 4.0))) == 0
    assert len(guard.echo_points(reading("Lt1", 1.0))) == guard.arc_samples


# ---- bumps and stalls ------------------------------------------------------------------------------
SPANS = [(name, math.radians(a), math.radians(b)) for name, a, b in
         [("front", -45, 45), ("left", 45, 135), ("rear", 135, -135), ("right", -135, -45)]]
FRONT_BUMP = np.array([True, False, False, False])
NO_BUMP = np.zeros(4, dtype=bool)


def test_a_bump_while_driving_fails_the_way_backs_off_and_marks_the_map():
    explorer = FrontierExplorer(lambda: room_map(), GUARD, bumpers=SPANS)
    robot = PointRobot(2.0, 3.0)
    for tick in range(50):  # under way to the opening
        robot.move(*explorer.step(0.1 * tick, robot.pose, CLEAR, follower_done=True,
                                  bumpers=NO_BUMP))
    assert explorer.phase == "drive" and robot.pose[0] > 2.3
    at = robot.pose.copy()
    assert explorer.step(5.0, robot.pose, CLEAR, bumpers=FRONT_BUMP) == (0.0, 0.0)
    assert explorer.phase == "escape" and explorer.result.log[-1]["failed"] == "bumped front"
    v, w = explorer.step(5.1, robot.pose, CLEAR, bumpers=NO_BUMP)
    assert v < 0 and abs(w) < 0.1  # undoing the motion that got it there
    # what the body touched is an obstacle on the map the explorer plans on, ahead of it
    touched = explorer._map()
    occupied, _, _ = touched.classes()
    ahead = at[:2] + 0.37 * np.array([math.cos(at[2]), math.sin(at[2])])
    r, c = int(ahead[1] / RES), int(ahead[0] / RES)
    assert occupied[r, c] and not room_map().classes()[0][r, c]


def test_a_command_odometry_does_not_see_is_a_stall():
    explorer = FrontierExplorer(lambda: room_map(), GUARD, bumpers=SPANS)
    pose = np.array([2.0, 3.0, 0.0])  # jammed: whatever it asks, it does not move
    results = [explorer.step(0.1 * k, pose, CLEAR, follower_done=True, bumpers=NO_BUMP)
               for k in range(60)]
    assert explorer.result.stalls >= 1
    assert any(e.get("failed") == "stalled" for e in explorer.result.log)
    assert any(v < 0 for v, _ in results)  # it backed off


def test_the_follower_is_backed_off_turned_away_and_taken_over_when_caught_again():
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(stale_distance=0.0), bumpers=SPANS)
    pose = np.array([2.0, 3.0, 0.0])
    assert explorer.step(0.0, pose, CLEAR, bumpers=NO_BUMP, follower_v=0.4) is None
    commands = [explorer.step(0.1, pose, CLEAR, bumpers=FRONT_BUMP, follower_v=0.4)]
    commands += [explorer.step(0.1 * k, pose, CLEAR, bumpers=NO_BUMP, follower_v=0.4)
                 for k in range(2, 40)]
    taken = [c for c in commands if c is not None]
    assert any(v < 0 for v, _ in taken) and any(w > 0 and v == 0 for v, w in taken)
    assert commands[-1] is None and explorer.phase == "follow"  # handed back
    assert explorer.result.started is None
    # the same place again: the follower is going round in a cycle
    explorer.step(5.0, pose, CLEAR, bumpers=FRONT_BUMP, follower_v=0.4)
    assert explorer.result.start_reason == "follower jammed"


def test_a_hand_back_lets_the_follower_escape_where_it_was_jammed_before():
    """Jammed twice at one place, the follower was taken over; the explorer got stuck
    there and hands back.  The follower's bump there again is what it was handed back
    to get out of, not a cycle to be taken over for at once."""
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(stale_distance=0.0, max_failures=3,
                                              max_attempts=50, hand_backs=1,
                                              hand_back_distance=2.0, back_off_time=0.3,
                                              bump_memory=0.0), bumpers=SPANS)
    robot = PointRobot(2.0, 3.0)
    spot = robot.pose.copy()

    def drive(time: float, ranges: np.ndarray, bump: bool = False) -> None:
        out = explorer.step(time, robot.pose, ranges, bumpers=FRONT_BUMP if bump else NO_BUMP,
                            follower_v=0.3)
        robot.move(*((0.3, 0.0) if out is None else out))

    for time in (0.0, 10.0):  # bumped at the same place twice: taken over
        robot.pose[:] = spot
        drive(time, CLEAR, bump=True)
        for k in range(1, 40):
            if explorer.result.started is None:
                drive(time + 0.1 * k, CLEAR)
    assert explorer.result.start_reason == "follower jammed"
    robot.pose[:] = spot
    time = 20.0
    while not explorer.result.hand_backs and time < 80.0:  # every way blocked at once
        drive(time, np.array([0.2, 4.0]))
        time += 0.1
    while explorer.phase != "follow" and time < 90.0:  # the back-off after the last way
        drive(time, CLEAR)
        time += 0.1
    assert explorer.result.hand_backs == 1
    robot.pose[:] = spot
    drive(time, CLEAR, bump=True)  # where it was jammed before
    for k in range(1, 40):
        drive(time + 0.1 * k, CLEAR)
    assert explorer.phase == "follow"  # backed off, turned away and following
    assert [e["take over"] for e in explorer.result.log if "take over" in e] == []
    assert sum("follower" in e for e in explorer.result.log) == 3


def test_an_echo_that_stops_the_way_goes_on_the_map_and_the_way_round_is_planned():
    explorer = FrontierExplorer(lambda: room_map(), GUARD)
    robot = PointRobot(2.0, 3.0)
    for tick in range(30):
        robot.move(*explorer.step(0.1 * tick, robot.pose, CLEAR, follower_done=True))
    assert explorer.phase == "drive"
    explorer.step(3.0, robot.pose, np.array([0.2, 4.0]))  # a box 0.2 m ahead of the sonar
    assert explorer.result.blocked_ahead == 1
    box = robot.pose[:2] + 0.45 * np.array([math.cos(robot.pose[2]), math.sin(robot.pose[2])])
    occupied, _, _ = explorer._map().classes()
    assert occupied[int(box[1] / RES), int(box[0] / RES)]
    for tick in range(31, 400):  # backs off, plans round the box, and gets to the opening
        out = explorer.step(0.1 * tick, robot.pose, CLEAR)
        if explorer.result.goals_reached:
            break
        robot.move(*out)
        assert math.hypot(*(robot.pose[:2] - box)) > 0.3
    assert explorer.result.goals_reached == 1 and robot.pose[0] > 4.5


def door_map(door: float) -> OccupancyMap:
    """Two rooms side by side (x 1..5 and 5.2..7.5, y 1..5) through a door ``door`` m wide
    in the wall between them (centred at y = 3), the second room seen only up to x = 7:
    its far side is unknown, a frontier 4 m long."""
    p, xc, yc = unknown_floor(9, 6)
    rooms = (yc > 1.0) & (yc < 5.0) & (((xc > 1.0) & (xc < 5.0)) | ((xc > 5.2) & (xc < 7.0)))
    walls = (yc > 0.8) & (yc < 5.2) & (xc > 0.8) & (xc < 5.2) & ~rooms
    p[rooms] = FREE
    p[walls] = OCC
    p[(xc > 5.0) & (xc < 5.2) & (np.abs(yc - 3.0) < door / 2)] = FREE
    p[(yc > 0.8) & (yc < 1.0) & (xc > 5.0) & (xc < 7.0)] = OCC
    p[(yc > 5.0) & (yc < 5.2) & (xc > 5.0) & (xc < 7.0)] = OCC
    return OccupancyMap(p, RES, (0.0, 0.0, 0.0))


def test_a_door_the_grown_grid_closes_is_planned_through_on_the_tight_grid():
    """A sonar map draws a door narrower than it is; grown by the circumscribed radius
    the door closes and the room beyond is out of reach.  The explorer plans through it
    on the grid grown by the body's half-width (and drives through the middle); with the
    tight grid turned off the frontier is out of reach and the floor "explored"."""
    m = door_map(0.8)
    [frontier] = [f for f in find_frontiers(m) if f.middle[0] > 6.5]
    assert frontier_goals(inflate(m, radius=0.36), [frontier], (2.0, 3.0)) == []  # closed
    [goal] = frontier_goals(inflate(m, radius=0.28), [frontier], (2.0, 3.0))
    assert goal.goal[0] > 5.5  # beyond the door

    robot = PointRobot(2.0, 3.0)
    explorer = FrontierExplorer(lambda: m, GUARD)
    furthest = 0.0
    for tick in range(400):
        out = explorer.step(0.1 * tick, robot.pose, CLEAR, follower_done=True)
        if explorer.ended or out is None:
            break
        robot.move(*out)
        furthest = max(furthest, robot.pose[0])
        if 5.0 < robot.pose[0] < 5.2:  # in the door, keeping to its middle
            assert abs(robot.pose[1] - 3.0) < 0.15
    assert furthest > 5.5, explorer.result.log

    without = FrontierExplorer(lambda: m, GUARD, ExploreParams(tight_radius=0.0))
    robot = PointRobot(2.0, 3.0)
    assert run(without, robot, 400) is not None
    assert without.result.end_reason == "explored" and robot.pose[0] < 5.0
    assert without.result.frontiers_out_of_reach >= 1


def test_a_turn_on_the_spot_beside_a_felt_wall_end_first_moves_clear_of_it():
    """The sonar does not hear a thin wall end seen edge on; once a bumper has felt it,
    a turn on the spot that would sweep a corner into it waits until the robot has
    eased straight away from it (turning at once hit it again, ten times in a row on
    a generated office)."""
    def first_commands(felt: bool) -> list[tuple[float, float]]:
        explorer = FrontierExplorer(lambda: room_map(), GUARD)
        robot = PointRobot(2.0, 2.2, math.pi / 2)  # driven north; the goal is east
        for tick in range(9):  # the track it came by (held: the explorer only watches)
            explorer.step(0.1 * tick, robot.pose, CLEAR, follower_done=True, hold=True)
            robot.pose[1] += 0.1
        if felt:  # what a right bumper pressed here left behind: a touch 0.06 m off its side
            explorer._bumps.append((2.31, 3.0))
        out = []
        for tick in range(10, 50):
            command = explorer.step(0.1 * tick, robot.pose, CLEAR, follower_done=True)
            out.append(command)
            robot.move(*command)
        return out

    plain = [c for c in first_commands(felt=False) if c != (0.0, 0.0)]
    assert abs(plain[0][1]) > 0.1 and abs(plain[0][0]) < 0.05  # turns on the spot at once
    careful = [c for c in first_commands(felt=True) if c != (0.0, 0.0)]
    assert careful[0] == (0.1, 0.0)  # eases ahead, away from the touch beside it
    assert any(abs(w) > 0.1 for _, w in careful[1:])  # then turns


@pytest.mark.parametrize("start", [(2.0, 1.5, 0.0), (3.5, 1.4, math.pi / 2), (4.3, 4.6, 0.0)])
def test_a_door_approached_slantwise_is_lined_up_with_before_it_is_entered(start):
    """Pure pursuit cuts the corner into a door and crosses it slantwise (10 to 22 degrees
    here), a jamb under the body's corner; lined up first, it crosses square."""
    m = door_map(0.8)

    def crossing(params: ExploreParams) -> tuple[float, float]:
        robot = PointRobot(*start)
        explorer = FrontierExplorer(lambda: m, GUARD, params)
        for tick in range(600):
            out = explorer.step(0.1 * tick, robot.pose, CLEAR, follower_done=True)
            if explorer.ended or out is None:
                break
            robot.move(*out)
            if robot.pose[0] > 5.0:  # in the door
                return abs(math.degrees(robot.pose[2])), abs(robot.pose[1] - 3.0)
        raise AssertionError(f"never reached the door: {explorer.result.log}")

    heading, offset = crossing(ExploreParams())
    assert heading < 5.0 and offset < 0.05
    slanted, _ = crossing(ExploreParams(door_narrow=0.0))
    assert slanted > 2 * heading


def test_a_robot_jammed_where_every_way_fails_backs_out_along_its_own_track():
    """Wedged (every way it plans is blocked at once, three times in the same spot),
    backing off and planning again keeps it there; it backs out the way it came."""
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(back_off_time=0.0, bump_memory=0.0,
                                              max_attempts=10))
    robot = PointRobot(2.0, 1.6, math.pi / 2)
    for tick in range(15):  # it came north from y = 1.6 (the explorer only watches)
        explorer.step(0.1 * tick, robot.pose, CLEAR, follower_done=True, hold=True)
        robot.pose[1] += 0.1
    jammed_at = robot.pose[:2].copy()
    blocked = np.array([0.2, 4.0])  # something just ahead, nothing behind
    commands = []
    for tick in range(15, 200):
        out = explorer.step(0.1 * tick, robot.pose, blocked, follower_done=True)
        commands.append(out)
        robot.move(*out)
        if explorer.result.retraces and explorer.phase == "plan":
            break
    assert explorer.result.retraces == 1 and explorer.result.ways_failed == 3
    assert [e for e in explorer.result.log if "retrace" in e]
    assert any(v < 0 for v, _ in commands)
    assert jammed_at[1] - robot.pose[1] > 1.0  # backed out south, along the track
    assert abs(robot.pose[0] - 2.0) < 0.15
    assert explorer.result.end_reason == ""  # not stuck


# ---- closed loop: an island the follower would circle for ever ----------------------------------
def island_world(tmp_path) -> tuple[object, tuple]:
    """A 12 x 10 m room with a free-standing 3 x 2 m block in its middle; the robot starts
    beside the block, which is on its right: the follower's 'perimeter' is the block."""
    res = 0.05
    xc, yc = floor_plan(12.0, 10.0, res)
    outer = (xc < 0) | (xc > 12) | (yc < 0) | (yc > 10)
    block = (xc > 4.5) & (xc < 7.5) & (yc > 4) & (yc < 6)
    path = write_world(tmp_path, "island", outer | block, start=(6.0, 3.45, math.pi),
                       doc="A free-standing block in a room.")
    free = ndimage.distance_transform_edt(~(outer | block)) * res >= 0.2
    return load_world(path), (xc, yc, free)


def test_a_free_standing_block_is_circled_once_and_left_for_the_rest_of_the_room(tmp_path):
    from blocks.explore.controller import (GROUP_INPUTS, KnowledgeBases, PerimeterController,
                                           sonar_group_index, sonar_groups_one)
    from blocks.explore.loop import LoopClosure

    world, (xc, yc, free) = island_world(tmp_path)
    spec = load_robot("atrv_mini")
    sim = Simulation(world, [("r", spec, world.start)], seed=0)
    robot = sim.robots["r"]
    follower = PerimeterController(KnowledgeBases.load(), spec.limits.max_speed,
                                   spec.limits.max_turn_rate)
    index = sonar_group_index(spec)
    loop = LoopClosure()
    grid = ExploreMap(spec)
    explorer = FrontierExplorer(grid.snapshot, SonarGuard.for_robot(spec))
    driven_before_take_over = None
    for tick in range(9000):
        ranges, _ = sim.sonar("r")
        grid.add(robot.odom, ranges)
        x, y, th = robot.odom
        groups = sonar_groups_one(ranges, index)
        v, w = follower.decide(np.array([[groups[n] for n in GROUP_INPUTS]]))[0]
        done = loop.update(x, y, 0.1 * tick, th)
        out = explorer.step(0.1 * tick, robot.odom, ranges, follower_done=done,
                            follower_v=float(v), odometry=robot.odom)
        if explorer.active and driven_before_take_over is None:
            driven_before_take_over = loop.travelled
        if explorer.ended:
            break
        sim.command("r", *(out if out is not None else (v, w)))
        sim.step(0.1)
    # the block's perimeter is about 11 m at the follower's distance: one lap, then on
    assert explorer.result.start_reason in ("loop closed", "no new floor")
    assert driven_before_take_over is not None and driven_before_take_over < 25.0
    assert explorer.result.end_reason == "explored", explorer.result.log[-5:]
    assert robot.collisions == 0
    seen = grid.free_at(xc, yc)
    # the room round the block, out to its walls, is mapped (not just the ring by the block)
    assert (seen & free).sum() / free.sum() >= 0.85
    far = free & ((xc < 1.5) | (xc > 10.5))
    assert (seen & far).sum() / far.sum() >= 0.8


# ---- with a collision monitor downstream ----------------------------------------------------------
LEFT_BUMP = np.array([False, True, False, False])


@pytest.mark.parametrize("monitored", [False, True])
def test_a_side_bumper_held_while_driving_on_is_one_bump_when_a_monitor_drives(monitored):
    """Pressed against a wall by its side, the robot may still drive along it; without a
    monitor to stop it pushing on, every tick the bumper is held fails the way."""
    params = ExploreParams(monitor=MonitorParams() if monitored else None, max_failures=50,
                           bump_memory=0.0)
    explorer = FrontierExplorer(lambda: room_map(), GUARD, params, bumpers=SPANS)
    robot = PointRobot(2.0, 3.0)
    for tick in range(120):
        out = explorer.step(0.1 * tick, robot.pose, CLEAR, follower_done=True,
                            bumpers=LEFT_BUMP if tick >= 20 else NO_BUMP)
        robot.move(*out)
    bumped = [e for e in explorer.result.log if e.get("failed") == "bumped left"]
    if monitored:
        assert explorer.result.bumps == 1 and len(bumped) == 1
        assert robot.pose[0] > 3.5  # it drove on along the wall
    else:
        assert explorer.result.bumps > 10 and explorer.result.goals_given_up == 1
        assert robot.pose[0] < 3.0


def test_with_a_monitor_the_explorer_refuses_the_motions_the_monitor_would_stop():
    guard = SonarGuard.for_robot(ATRV)
    echo = reading("LtFr", 0.1)  # beside the front left corner, outside the straight lane
    plain = FrontierExplorer(lambda: room_map(), guard)
    monitored = FrontierExplorer(lambda: room_map(), guard, ExploreParams(monitor=MonitorParams()))
    for explorer in (plain, monitored):
        explorer.step(0.0, np.array([2.0, 3.0, 0.0]), echo)
    assert plain._blocked(echo, 0.3, 0.8) == ""  # the strip ahead is clear
    assert monitored._blocked(echo, 0.3, 0.8) == "ahead"  # the curve swings the body onto it
    assert monitored._blocked(echo, 0.3, 0.0) == ""  # straight on passes beside it
    # the echo is remembered after it is gone (a corner seen at a grazing angle comes and goes)
    monitored.step(0.1, np.array([2.0, 3.0, 0.0]), np.full(16, 4.0))
    assert monitored._blocked(np.full(16, 4.0), 0.3, 0.8) == "ahead"


def test_a_follower_the_monitor_keeps_stopping_is_backed_off_and_then_taken_over():
    """The monitor frees a stopped robot blindly after a second; a follower that turns
    back into the same wall end would touch it again each time."""
    explorer = FrontierExplorer(lambda: room_map(), GUARD,
                                ExploreParams(stale_distance=0.0, monitor=MonitorParams()),
                                bumpers=SPANS)
    pose = np.array([2.0, 3.0, 0.0])

    def held_then_released(start: float) -> list:
        held = [explorer.step(start + 0.1 * k, pose, CLEAR, bumpers=NO_BUMP, follower_v=0.4,
                              monitor_scale=0.0 if k else 1.0) for k in range(10)]
        # released, it creeps on (too slowly to count as stalled where it stands)
        return held + [explorer.step(start + 1.0 + 0.1 * k, pose, CLEAR, bumpers=NO_BUMP,
                                     follower_v=0.05) for k in range(30)]

    commands = held_then_released(0.0)
    assert commands[:8] == [None] * 8 and commands[9] is not None  # 0.8 s stopped: held
    assert explorer.result.holds == 1 and explorer.result.log[-1]["follower"] == "held"
    assert any(c is not None and c[0] < 0 for c in commands)  # backed off
    assert commands[-1] is None and explorer.result.started is None  # and handed back
    held_then_released(5.0)  # held again at the same place: backed off once more
    assert explorer.result.holds == 2 and explorer.result.started is None
    held_then_released(10.0)  # a third time: a cycle
    assert explorer.result.start_reason == "follower jammed"


@pytest.mark.parametrize("monitored", [False, True])
def test_a_robot_pinned_by_its_side_backs_along_the_wall_until_it_can_turn(monitored):
    """Flush against a wall on its right, with a wall ahead: it can neither turn nor go on,
    so each way planned from there fails at once; it backs along the wall instead."""
    guard = SonarGuard.for_robot(ATRV)

    def ranges(pose):
        r = np.full(16, 4.0)
        if pose[0] > 1.6:
            r[[ATRV.sonar_names.index(n) for n in ("Fr1", "Fr2")]] = 0.2
        if pose[0] > 1.2:
            r[[ATRV.sonar_names.index(n) for n in ("Rt1", "Rt2")]] = 0.1
        return r

    params = ExploreParams(monitor=MonitorParams() if monitored else None, max_failures=3,
                           max_attempts=10, hand_backs=0, bump_memory=0.0)
    explorer = FrontierExplorer(lambda: room_map(), guard, params)
    robot = PointRobot(2.0, 3.0)
    least_x = robot.pose[0]
    for tick in range(150):
        out = explorer.step(0.1 * tick, robot.pose, ranges(robot.pose), follower_done=True)
        if out is None:
            break
        robot.move(*out)
        least_x = min(least_x, robot.pose[0])
    unpinned = [e for e in explorer.result.log if "unpin" in e]
    if monitored:
        assert unpinned and least_x < 1.2  # backed 0.8 m, past the wall's end
    else:
        assert not unpinned and least_x > 1.5  # back-offs of 0.2 m, then stuck
        assert explorer.result.end_reason == "stuck"


def test_a_curve_only_the_monitor_would_stop_is_crept_round_not_failed():
    class Curving:  # a way whose pursuit asks for a left curve
        remaining, progress = 3.0, 0.0

        def step(self, pose, speed):
            return 0.3, 0.8, "turning"

    guard = SonarGuard.for_robot(ATRV)
    explorer = FrontierExplorer(lambda: room_map(), guard, ExploreParams(monitor=MonitorParams()))
    pose = np.array([2.0, 3.0, 0.0])
    explorer.step(0.0, pose, np.full(16, 4.0), follower_done=True)
    assert explorer.phase == "drive"
    explorer._leg = Curving()
    echo = reading("LtFr", 0.1)  # beside the front left corner: the curve swings onto it
    v, w = explorer.step(0.1, pose, echo, follower_done=True)
    assert explorer.phase == "drive" and not any("failed" in e for e in explorer.result.log)
    assert (v, w) != (0.3, 0.8) and abs(v) <= 0.15 + 1e-9 and abs(w) <= 0.6 + 1e-9
    assert explorer._echoes.collision_time(pose, v, w) == math.inf


@pytest.mark.parametrize("monitored", [False, True])
def test_a_robot_boxed_in_creeps_the_way_the_monitor_lets_it_instead_of_ending_stuck(monitored):
    """An echo at its front-right corner and one close behind: the guard refuses the first
    command of every way and a back-off too; with a monitor, it turns clear on the spot."""
    guard = SonarGuard.for_robot(ATRV)
    start = np.array([2.0, 3.0, 0.0])

    def ranges(pose):
        r = np.full(16, 4.0)
        if np.hypot(*(pose[:2] - start[:2])) < 0.05 and abs(pose[2]) < 0.35:
            r[ATRV.sonar_names.index("FrRt1")] = 0.15
            r[ATRV.sonar_names.index("Bk1")] = 0.2
        return r

    params = ExploreParams(monitor=MonitorParams() if monitored else None, max_failures=6,
                           max_attempts=10, hand_backs=0, bump_memory=0.0)
    explorer = FrontierExplorer(lambda: room_map(), guard, params)
    robot = PointRobot(*start)
    for tick in range(400):
        out = explorer.step(0.1 * tick, robot.pose, ranges(robot.pose), follower_done=True)
        if out is None:
            break
        robot.move(*out)
    boxed = [e for e in explorer.result.log if "boxed in" in e]
    if monitored:
        assert explorer.result.boxed_in == 1 and len(boxed) == 1
        assert explorer.result.end_reason != "stuck" and explorer.result.goals_reached >= 1
        assert np.hypot(*(robot.pose[:2] - start[:2])) > 0.5
    else:
        assert explorer.result.end_reason == "stuck" and not boxed


def test_a_look_round_that_cannot_turn_counts_as_taken():
    """With no frontier left the explorer looks round on the spot before it calls the
    floor explored; a robot that cannot turn (a monitor stopping it at furniture) waited
    for that turn for ever.  Now the look counts as taken after ``stall_time``."""
    explorer = FrontierExplorer(lambda: room_map(opening=False), GUARD,
                                ExploreParams(stall_time=5.0))
    robot = PointRobot(3.0, 3.0)
    assert run(explorer, robot, 200, ranges=CLEAR) == 81  # a whole turn at 0.8 rad/s...
    assert explorer.result.end_reason == "explored"
    assert not any("look round" in e for e in explorer.result.log)
    explorer = FrontierExplorer(lambda: room_map(opening=False), GUARD,
                                ExploreParams(stall_time=5.0))
    pinned = PointRobot(3.0, 3.0)
    for tick in range(200):  # ...unless nothing it asks moves the robot
        explorer.step(0.1 * tick, pinned.pose, CLEAR, follower_done=True)
        if explorer.ended:
            break
    assert explorer.result.end_reason == "explored" and 50 <= tick <= 60
    assert [e["look round"] for e in explorer.result.log if "look round" in e] == ["cannot turn"]


@pytest.mark.parametrize("by_ends", [True, False])
def test_flush_along_a_wall_with_its_way_behind_it_eases_out_ahead_not_backing_blind(by_ends):
    """Too close to the wall on its right to turn round, the robot must move straight
    first.  By the ends (``ease_by_ends``) it goes ahead, where its sonars look, and turns
    once past the wall's end; by the nearest echo (the default until measured) it would
    back, leading with a rear corner that may have no sonar looking past it, and here,
    where that is refused, it stays."""
    guard = SonarGuard.for_robot(ATRV)
    beside = [ATRV.sonar_names.index(n) for n in ("RtFr2", "Rt1", "Rt2", "BkRt")]

    def ranges(pose):
        r = np.full(16, 4.0)
        if pose[0] > 1.7:  # facing west along a wall that ends at x 1.7
            r[beside] = 0.05
        return r

    params = ExploreParams(monitor=MonitorParams(), bump_memory=0.0, ease_by_ends=by_ends)
    explorer = FrontierExplorer(lambda: room_map(), guard, params)
    robot = PointRobot(2.0, 3.0, math.pi)  # the opening is behind it, east
    path = [robot.pose.copy()]
    for tick in range(60):
        out = explorer.step(0.1 * tick, robot.pose, ranges(robot.pose), follower_done=True)
        if out is None:
            break
        robot.move(*out)
        path.append(robot.pose.copy())
    path = np.array(path)
    pinned = path[:, 0] > 1.7
    if not by_ends:
        assert pinned.all()  # the nearest echo is ahead of the middle: never out
        return
    assert pinned[0] and not pinned[-1]  # it got out
    assert np.all(np.diff(path[: np.argmin(pinned) + 1, 0]) <= 1e-9)  # ahead, never back
    assert abs(math.remainder(path[-1, 2] - math.pi, 2 * math.pi)) > 0.3  # and turned
