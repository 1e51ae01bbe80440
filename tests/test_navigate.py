"""Navigation: inflated grid, A* planner, pure pursuit, the go-to state machine, the block,
and closed-loop runs in the simulated office (zero collisions)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from blocks.core.block import RunContext
from blocks.core.errors import BlockError, SemmapError
from blocks.maps.mapio import OccupancyMap, occupancy_map_from_world
from blocks.navigate.grid import inflate, inflate_occupied
from blocks.navigate.planner import PlanningError, plan, plan_via
from blocks.navigate.pursuit import PurePursuit, PursuitParams
from blocks.navigate.visit import Goal, Visit, parse_goals
from sim2d.robot import load_robot
from sim2d.simulation import Simulation
from sim2d.world import load_world
from sim2d.worlds import world_path

MANAGER_DOOR_CORRIDOR = (9.0, 6.1, 0.0)  # in front of the MANAGER door (wall y=5, door x 9..10)
MANAGER_CENTRE = (9.0, 2.8)  # 0.2 m north of the manager's desk (8.0..9.8, 1.8..2.6)
MAIL_ROOM = (3.0, 3.8)  # the mail room north of its sorting table (1.5..4.0, 2.0..2.8)


@pytest.fixture(scope="module")
def office():
    return load_world(world_path("office"))


@pytest.fixture(scope="module")
def office_grid(office):
    return inflate(occupancy_map_from_world(office))


def box_map(w: float = 6.0, h: float = 4.0, res: float = 0.05) -> OccupancyMap:
    """A walled room: one-cell walls on the border, free inside."""
    occ = np.zeros((int(round(h / res)), int(round(w / res))))
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1.0
    return OccupancyMap(occupancy=occ, resolution=res, origin=(0.0, 0.0, 0.0))


# ---- grid -------------------------------------------------------------------------------------
def test_cell_conversion_matches_occupancy_map():
    m = OccupancyMap(occupancy=np.zeros((40, 60)), resolution=0.05, origin=(-1.0, 2.0, 0.0))
    g = inflate(m)
    xs, ys = m.cell_centres()
    assert g.world_to_cell(xs[7], ys[3]) == (3, 7)  # row 0 = lowest y
    assert np.allclose(g.cell_to_world(3, 7), (xs[7], ys[3]))
    assert g.world_to_cell(-1.0 + 1e-9, 2.0 + 1e-9) == (0, 0)


def test_inflation_blocks_within_radius_and_costs_more_near_walls():
    g = inflate(box_map(), radius=0.36)
    # the west wall occupies x 0..0.05; its surface is at x = 0.05
    row = g.world_to_cell(3.0, 2.0)[0]
    cols = [g.world_to_cell(x, 2.0)[1] for x in (0.3, 0.45, 0.7, 1.2)]
    assert g.blocked[row, cols[0]] and not g.blocked[row, cols[1]]
    assert g.clearance[row, cols[1]] == pytest.approx(0.475 - 0.05, abs=1e-6)  # centre - surface
    assert g.cost[row, cols[1]] > g.cost[row, cols[2]] > g.cost[row, cols[3]] == 1.0
    assert np.isinf(g.cost[g.blocked]).all() and (g.cost[~g.blocked] >= 1).all()


def test_unknown_cells_blocked_by_default_or_crossed_at_a_cost():
    m = box_map()
    m.occupancy[:, 55:65] = np.nan  # an unknown band across the room at x 2.75..3.25
    with pytest.raises(PlanningError, match="goal"):
        plan(inflate(m), (1.0, 2.0), (5.0, 2.0))
    g = inflate(m, unknown="cost", unknown_cost=4.0)
    path = plan(g, (1.0, 2.0), (5.0, 2.0))
    assert path.length == pytest.approx(4.0, abs=0.1)
    with pytest.raises(ValueError):
        inflate(m, unknown="free")


# ---- planner ----------------------------------------------------------------------------------
def test_cross_floor_plan_is_clear_short_and_fast(office_grid):
    g = office_grid
    path = plan(g, (1.0, 5.8), (28.5, 19.0))  # corridor SW corner -> OFFICE 103's far corner
    assert len(path.points) >= 3 and not path.start_snapped
    assert np.allclose(path.points[0], (1.0, 5.8)) and np.allclose(path.points[-1], (28.5, 19.0))
    assert not g.blocked[path.cells[:, 0], path.cells[:, 1]].any()
    for a, b in zip(path.points[:-1], path.points[1:]):
        assert g.segment_clearance(a, b) >= g.radius
    straight = math.hypot(27.5, 13.2)
    assert straight < path.length < 1.45 * straight


def test_path_goes_through_the_middle_of_a_door(office_grid):
    path = plan(office_grid, MANAGER_DOOR_CORRIDOR[:2], MANAGER_CENTRE)
    assert path.goal_snapped  # the centre is 0.2 m from the desk: snapped to free floor
    assert np.hypot(*(path.goal - MANAGER_CENTRE)) < 0.3
    # where the path crosses the wall line y = 5 (door x 9..10), it is near the door's middle
    pts = path.points
    k = int(np.nonzero((pts[:-1, 1] >= 5.0) & (pts[1:, 1] < 5.0))[0][0])
    t = (pts[k, 1] - 5.0) / (pts[k, 1] - pts[k + 1, 1])
    x_cross = pts[k, 0] + t * (pts[k + 1, 0] - pts[k, 0])
    assert abs(x_cross - 9.5) < 0.1


def test_blocked_goal_far_from_free_floor_is_a_clear_error(office_grid):
    with pytest.raises(PlanningError) as info:
        plan(office_grid, MANAGER_DOOR_CORRIDOR[:2], (3.0, 2.5))  # on the mail-room table
    err = info.value
    assert isinstance(err, SemmapError) and err.field == "goal"
    assert "(3.00, 2.50)" in str(err) and "blocked" in str(err)
    with pytest.raises(PlanningError, match="start .*blocked"):
        plan(office_grid, (0.2, 6.1), (9.0, 3.5), snap_radius=0.1)  # 0.1 m from the west wall
    with pytest.raises(PlanningError, match="off the map"):
        plan(office_grid, (1.0, 5.8), (45.0, 5.8))


def test_start_near_a_wall_snaps_and_the_path_begins_at_the_robot(office_grid):
    start = (5.0, 5.3)  # 0.2 m from the corridor's south wall: inside the inflation
    path = plan(office_grid, start, (5.0, 6.6))
    assert path.start_snapped and np.allclose(path.points[0], start)
    assert office_grid.is_free(*path.points[1])


def test_goal_behind_a_wall_snaps_to_the_reachable_side(office_grid):
    # (9.5, 4.8) is 0.1 m inside the manager's room, below the wall: with the start in the
    # corridor, the snap must not pick a corridor cell just north of the wall.
    path = plan(office_grid, MANAGER_DOOR_CORRIDOR[:2], (7.0, 4.75))
    assert path.goal[1] < 4.9


def test_coarse_route_through_a_thin_wall_falls_back_to_the_full_search():
    # With no inflation, a 1-cell wall shares coarse blocks with free cells, so the coarse
    # route goes straight through it; the fine search in its band fails and the full one
    # finds the gap at the top.
    import blocks.navigate.planner as planner

    searches = []

    def spy(cost, start, goal):
        cells = original(cost, start, goal)
        searches.append((cost.shape, cells is not None))
        return cells

    obstacle = np.zeros((400, 400), dtype=bool)
    obstacle[:380, 200] = True  # x = 10.0..10.05, y 0..19; the gap is y 19..20
    g = inflate_occupied(obstacle, 0.05, (0.0, 0.0), radius=0.0)
    original, planner._astar = planner._astar, spy
    try:
        path = plan(g, (2.0, 10.0), (18.0, 10.0))
    finally:
        planner._astar = original
    assert searches == [((134, 134), True), ((400, 400), False), ((400, 400), True)]
    assert not g.blocked[path.cells[:, 0], path.cells[:, 1]].any()
    assert path.points[:, 1].max() > 19.0


def test_plan_via_joins_legs(office_grid):
    route = [(1.0, 5.8), (1.1, 13.9), (9.5, 14.0), (9.5, 16.5)]  # west leg, north leg, MEETING
    path = plan_via(office_grid, route)
    assert len(path.legs) == 3 and path.legs[-1] == len(path.points) - 1
    for end, waypoint in zip(path.legs, route[1:]):
        assert np.hypot(*(path.points[end] - waypoint)) < 0.3
    direct = plan(office_grid, route[0], route[-1])
    assert path.length >= direct.length - 1e-6
    with pytest.raises(PlanningError, match="leg 2 of 2"):
        plan_via(office_grid, [(1.0, 5.8), (1.1, 13.9), (3.0, 2.5)])


# ---- pursuit ----------------------------------------------------------------------------------
def unicycle(pose, v, w, dt):
    x, y, th = pose
    return np.array([x + v * dt * math.cos(th), y + v * dt * math.sin(th), th + w * dt])


def test_pure_pursuit_follows_an_l_path_within_limits_and_stops_at_the_goal():
    path = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]])
    f = PurePursuit(path, PursuitParams())
    pose, worst, statuses = np.array([0.0, 0.0, 0.0]), 0.0, set()
    for _ in range(400):
        v, w, status = f.step(pose, 0.1)
        statuses.add(status)
        assert abs(v) <= 0.4 + 1e-9 and abs(w) <= 1.5 + 1e-9
        if status == "arrived":
            break
        pose = unicycle(pose, v, w, 0.1)
        worst = max(worst, f.cross_track)
    assert status == "arrived" and np.hypot(pose[0] - 3.0, pose[1] - 3.0) <= 0.08
    assert worst < 0.3  # the corner is cut by less than 0.3 m
    assert f.step(pose, 0.1) == (0.0, 0.0, "arrived")


def test_pure_pursuit_turns_in_place_when_the_path_is_behind():
    f = PurePursuit(np.array([[0.0, 0.0], [-3.0, 0.0]]))
    v, w, status = f.step(np.array([0.0, 0.0, 0.0]), 0.1)
    assert status == "turning" and v == 0.0 and abs(w) > 0.5


# ---- the state machine ------------------------------------------------------------------------
def test_goals_parse_from_lists_and_dicts():
    goals = parse_goals([[1, 2], [3, 4, True], {"x": 5, "y": 6, "spin": False, "name": "A"}])
    assert goals == [Goal(1.0, 2.0), Goal(3.0, 4.0, True), Goal(5.0, 6.0, False, "A")]
    assert parse_goals([1, 2]) == [Goal(1.0, 2.0)]
    with pytest.raises(ValueError, match="goal 1"):
        parse_goals([[1, 2], {"x": 1, "z": 2}])


def test_visit_gives_up_after_timeout_and_goes_on():
    g = inflate(box_map())
    visit = Visit([(5.0, 2.0), (1.2, 1.5)], g, timeout=3.0)
    stuck = np.array([1.0, 2.0, 0.0])  # the robot never moves
    events = []
    for _ in range(100):
        visit.step(stuck, 0.1)
        events.append(visit.event)
    assert visit.failed and visit.failed[0].reason.startswith("timeout")
    assert visit.failed[0].duration == pytest.approx(3.0, abs=0.15)
    assert events.count("failed") == 2 and visit.done and not visit.active


def test_visit_reports_an_unplannable_goal_and_replans_when_pushed_off():
    g = inflate(box_map())
    visit = Visit([(50.0, 2.0), (5.0, 2.0)], g)
    pose = np.array([1.0, 2.0, 0.0])
    visit.step(pose, 0.1)
    assert visit.failed and "off the map" in visit.failed[0].reason
    for tick in range(600):
        v, w, _ = visit.step(pose, 0.1)
        if visit.done:
            break
        pose = unicycle(pose, v, w, 0.1)
        if tick == 20:
            pose = pose + [0.0, 1.0, 0.0]  # kicked 1 m off the path: replan
    assert visit.reached and visit.reached[0].replans >= 1


def test_visit_replans_when_a_new_map_blocks_the_path():
    m = box_map(10.0, 4.0)
    visit = Visit([(9.0, 1.0)], inflate(m))
    pose = np.array([1.0, 1.0, 0.0])
    visit.step(pose, 0.1)
    blocked = m.occupancy.copy()
    blocked[:50, 100:110] = 1.0  # a wall from y 0 to 2.5 at x 5.0..5.5 across the straight path
    visit.set_grid(inflate(OccupancyMap(blocked, m.resolution, m.origin)))
    visit.step(pose, 0.1)
    assert visit.current.replans == 1
    assert visit.path[:, 1].max() > 2.5 + 0.36  # the new path goes round the wall's end


# ---- closed loop in the simulator ---------------------------------------------------------------
def run_visit(world, grid, start, goals, *, odometry=False, seconds=200.0, seed=0, **kw):
    spec = load_robot("atrv_mini")
    sim = Simulation(world, [("r", spec, start)], seed=seed)
    visit = Visit(goals, grid, **kw)
    robot = sim.robots["r"]
    at_event, spun, deepest = [], 0.0, 0.0
    heading = robot.pose[2]
    for _ in range(int(seconds / 0.1)):
        v, w, status = visit.step(robot.odom if odometry else robot.pose, 0.1)
        if visit.event:
            at_event.append(robot.pose.copy())
        if visit.done:
            break
        sim.command("r", v, w)
        sim.step(0.1)
        deepest = max(deepest, sim.penetration("r"))
        if status == "spinning":
            spun += abs((robot.pose[2] - heading + math.pi) % (2 * math.pi) - math.pi)
        heading = robot.pose[2]
    return visit, robot, at_event, spun, deepest


def test_office_visit_manager_spin_return_and_mail_room_without_collisions(office, office_grid):
    goals = [Goal(*MANAGER_CENTRE, spin=True, name="MANAGER"),
             Goal(*MANAGER_DOOR_CORRIDOR[:2], name="corridor"),
             Goal(*MAIL_ROOM, name="MAIL ROOM")]
    visit, robot, at_event, spun, deepest = run_visit(office, office_grid,
                                                      MANAGER_DOOR_CORRIDOR, goals)
    assert [r.status for r in visit.results] == ["reached"] * 3
    for goal, pose in zip(goals, at_event):
        assert math.hypot(pose[0] - goal.x, pose[1] - goal.y) < 0.3
    assert spun >= 2 * math.pi - 0.1  # the look-around in the manager's room
    assert robot.collisions == 0 and deepest == 0.0
    times = [r.finished for r in visit.results]
    assert times == sorted(times) and times[-1] < 120.0


def test_short_visit_on_odometry_has_no_collisions(office, office_grid):
    goals = [Goal(*MANAGER_CENTRE, spin=True), Goal(*MANAGER_DOOR_CORRIDOR[:2])]
    visit, robot, at_event, _, deepest = run_visit(office, office_grid, MANAGER_DOOR_CORRIDOR,
                                                   goals, odometry=True, seed=2)
    assert len(visit.reached) == 2
    assert robot.collisions == 0 and deepest == 0.0
    assert math.hypot(at_event[-1][0] - 9.0, at_event[-1][1] - 6.1) < 0.5  # drift included


# ---- the block --------------------------------------------------------------------------------
def make_goto(**params):
    from blocks.navigate.blocks import Goto
    values = {name: p.default for name, p in Goto.params.items()}
    values.update(params)
    b = Goto(values, name="nav", ctx=RunContext(dt=0.1, seed=0))
    b.reset()
    return b


def test_goto_block_drives_the_robot_to_message_goals(office):
    spec = load_robot("atrv_mini")
    sim = Simulation(office, [("r", spec, MANAGER_DOOR_CORRIDOR)])
    b = make_goto(world="office")
    goals = [{"x": 9.0, "y": 3.5, "name": "MANAGER"}, [3.0, 2.5]]  # the second is on a table
    reached = failed = 0
    for tick in range(800):
        b.ctx.tick = tick
        out = b.step(sim.robots["r"].pose, goals=list(goals), map=None)  # a new list each tick
        reached += out["reached"]
        failed += out["failed"]
        if out["done"]:
            break
        sim.command("r", out["v"], out["w"])
        sim.step(0.1)
    assert out["done"] and not out["active"] and (reached, failed) == (1, 1)
    assert sim.robots["r"].collisions == 0
    b.finish()
    metrics = b.ctx.metrics["nav"]
    assert metrics["goals_reached"] == 1 and metrics["goals_failed"] == 1
    assert metrics["goals"][1]["reason"].startswith("planning")


def test_goto_block_plans_on_a_connected_map_and_needs_one():
    class Handle:
        calls = 0

        def snapshot(self):
            Handle.calls += 1
            return box_map()

    b = make_goto(goals=[[5.0, 2.0]])
    out = b.step(np.array([1.0, 2.0, 0.0]), goals=None, map=Handle())
    assert out["active"] and out["v"] >= 0.0 and Handle.calls == 1
    with pytest.raises(BlockError, match="no map"):
        make_goto(goals=[[5.0, 2.0]]).step(np.array([1.0, 2.0, 0.0]), goals=None, map=None)
    with pytest.raises(BlockError, match="goal 0"):
        make_goto(goals=[["a", 2.0]])


@pytest.mark.parametrize("shape, density", [((1, 1), 0.5), ((3, 200), 0.05), ((257, 61), 0.01),
                                            ((400, 500), 0.002), ((120, 90), 0.3)])
def test_distance_to_obstacles_is_scipys_transform(shape, density):
    from scipy import ndimage

    from blocks.navigate.grid import distance_to_obstacles
    rng = np.random.default_rng(shape[0] * 1000 + shape[1])
    free = rng.random(shape) >= density
    free[rng.integers(shape[0]), rng.integers(shape[1])] = False  # at least one obstacle
    want = ndimage.distance_transform_edt(free)
    got = distance_to_obstacles(free)
    assert got.dtype == want.dtype == np.float64
    assert np.array_equal(got, want)
    assert np.array_equal(distance_to_obstacles(np.ones(shape, bool)),
                          ndimage.distance_transform_edt(np.ones(shape, bool)))
