"""Room visits: the door finder, the next-best-view rule, the track that keeps a door open,
the visitor in closed loop in the simulated office, and the block's contract."""
from __future__ import annotations

import math

import numpy as np
import pytest

from blocks.core.block import RunContext
from blocks.core.errors import BlockError
from blocks.maps.mapio import OccupancyMap
from blocks.navigate.grid import inflate, inflate_occupied, unblock_traversed
from blocks.navigate.doors import (DoorEstimate, SignRef, find_door, free_run, next_look,
                                   room_box, unseen_nearby)
from blocks.navigate.legs import Leg
from blocks.navigate.planner import PlanningError, plan
from blocks.navigate.pursuit import PurePursuit
from blocks.navigate.rooms import RoomVisitor, RoomVisitParams
from sim2d.robot import load_robot
from sim2d.simulation import Simulation
from sim2d.world import load_world
from sim2d.worlds import world_path

RES = 0.025
FREE, OCC, UNKNOWN = 0.0, 1.0, np.nan


def corridor_and_room(door_x: tuple[float, float] | None = (3.0, 4.0), *,
                      room_seen: bool = True, far_jamb: bool = True) -> OccupancyMap:
    """A 10 x 8 m map: corridor y 5..7 (free), wall y 4.8..5.0, room y 0.5..4.8 behind it.

    ``door_x``: the opening in the wall; ``room_seen``: the room is free (else
    unknown); ``far_jamb``: the wall east of the door is mapped (else unknown,
    as before the robot has passed the door).
    """
    h, w = int(8 / RES), int(10 / RES)
    p = np.full((h, w), UNKNOWN)
    ys = (np.arange(h) + 0.5) * RES
    xs = (np.arange(w) + 0.5) * RES
    Y, X = np.meshgrid(ys, xs, indexing="ij")
    p[(Y >= 5.0) & (Y <= 7.0)] = FREE
    p[(Y > 7.0) & (Y <= 7.2)] = OCC
    wall = (Y >= 4.8) & (Y < 5.0)
    p[wall] = OCC
    if room_seen:
        p[(Y >= 0.7) & (Y < 4.8) & (X > 0.2) & (X < 7.8)] = FREE
        p[(Y >= 0.5) & (Y < 0.7) & (X > 0.2) & (X < 7.8)] = OCC
    if door_x is not None:
        p[wall & (X >= door_x[0]) & (X < door_x[1])] = FREE
    if not far_jamb and door_x is not None:
        p[wall & (X >= door_x[1])] = UNKNOWN
    return OccupancyMap(p, RES, (0.0, 0.0, 0.0), occupied_thresh=0.65, free_thresh=0.2)


SIGN = SignRef("MANAGER", 2.3, 5.0, math.radians(90.0))  # on the wall, facing the corridor


# ---- the door finder --------------------------------------------------------------------------
def test_find_door_finds_the_opening_next_to_the_sign():
    door = find_door(corridor_and_room(), SIGN)
    assert door is not None
    assert door.wall[0] == pytest.approx(3.5, abs=0.05)
    assert door.wall[1] == pytest.approx(5.0, abs=0.05)
    assert door.width == pytest.approx(1.0, abs=0.06)
    assert door.normal == pytest.approx((0.0, 1.0), abs=1e-9)
    assert door.inside == pytest.approx(4.3, abs=0.1)  # free floor from y 5.0 down to 0.7
    assert door.point(1.0) == pytest.approx((door.wall[0], door.wall[1] - 1.0), abs=1e-9)


def test_find_door_tolerates_a_sign_placed_off_the_wall():
    off = SignRef("MANAGER", 2.3, 4.6, SIGN.facing)  # camera estimate 0.4 m behind the wall
    door = find_door(corridor_and_room(), off)
    assert door is not None and door.wall[0] == pytest.approx(3.5, abs=0.05)


@pytest.mark.parametrize("case", ["no opening", "room not seen", "far jamb not mapped",
                                  "too far from the sign", "gap between readings"])
def test_find_door_refuses_what_is_not_a_door_yet(case):
    m = {"no opening": corridor_and_room(None),
         "room not seen": corridor_and_room(room_seen=False),
         "far jamb not mapped": corridor_and_room(far_jamb=False),
         "too far from the sign": corridor_and_room((6.0, 7.0)),
         "gap between readings": corridor_and_room((3.0, 3.15))}[case]
    assert find_door(m, SIGN) is None


def test_classes_at_points_are_the_map_classes_of_their_cells():
    from blocks.navigate.doors import _classes_at
    m = corridor_and_room()
    m.occupancy[::7, ::5] = 0.5  # some cells neither free nor occupied
    rng = np.random.default_rng(0)
    xy = rng.uniform(-1.0, 11.0, (40, 30, 2))  # some points off the map
    occupied, free, _ = m.classes()
    cols, rows = np.floor(xy[..., 0] / RES).astype(int), np.floor(xy[..., 1] / RES).astype(int)
    inside = (rows >= 0) & (rows < m.shape[0]) & (cols >= 0) & (cols < m.shape[1])
    r, c = np.clip(rows, 0, m.shape[0] - 1), np.clip(cols, 0, m.shape[1] - 1)
    got_occupied, got_free = _classes_at(m, xy)
    assert np.array_equal(got_occupied, occupied[r, c] & inside)
    assert np.array_equal(got_free, free[r, c] & inside)
    assert got_occupied.any() and got_free.any() and (~inside).any()


def test_free_run_measures_free_floor_along_a_ray():
    m = corridor_and_room()
    assert free_run(m, (3.5, 4.5), (0.0, -1.0), max_distance=8.0) == pytest.approx(3.8, abs=0.05)
    assert free_run(m, (3.5, 6.0), (0.0, 1.0), max_distance=0.5) == 0.5


# ---- where to look next -----------------------------------------------------------------------
def test_room_box_is_behind_the_wall_around_the_door():
    door = DoorEstimate((3.5, 5.0), (0.0, 1.0), 1.0, 4.0)
    box = room_box((int(8 / RES), int(10 / RES)), RES, (0.0, 0.0), door, half_width=2.0,
                   depth=3.0)
    def at(x, y):
        return bool(box[int(y / RES), int(x / RES)])
    assert at(3.5, 4.0) and at(1.6, 2.1) and at(5.4, 4.9)
    assert not at(3.5, 5.5) and not at(3.5, 1.9) and not at(6.0, 4.0)


def test_unseen_nearby_counts_area_within_the_radius():
    unknown = np.zeros((200, 200), dtype=bool)
    unknown[90:110, 90:110] = True  # 0.5 x 0.5 m at 0.025 m cells
    area = unseen_nearby(unknown, RES, radius=1.0)
    assert area[100, 100] == pytest.approx(0.25, rel=0.05)
    assert area[100, 180] == pytest.approx(0.0, abs=1e-6)  # 2 m away


def test_next_look_goes_where_the_room_is_still_unseen():
    m = corridor_and_room()
    p = m.occupancy.copy()
    # The west end of the room is still unknown (not behind walls: beyond the seen floor).
    ys = (np.arange(p.shape[0]) + 0.5) * RES
    xs = (np.arange(p.shape[1]) + 0.5) * RES
    Y, X = np.meshgrid(ys, xs, indexing="ij")
    p[(Y >= 0.5) & (Y < 4.8) & (X < 1.5)] = UNKNOWN
    m = OccupancyMap(p, RES, (0.0, 0.0, 0.0), occupied_thresh=0.65, free_thresh=0.2)
    grid = inflate(m)
    door = find_door(corridor_and_room(), SIGN)
    here = (5.5, 3.0)
    target = next_look(grid, m.classes()[2], door, here, min_distance=1.0)
    assert target is not None
    assert target[0] < 3.0  # toward the unseen west end
    assert grid.clearance_at(*target) >= 0.5
    # Nothing left to see: no further look.
    assert next_look(grid, np.zeros_like(grid.blocked), door, here) is None


# ---- the track keeps a door open ---------------------------------------------------------------
def test_unblock_traversed_reopens_a_door_the_robot_came_through():
    obstacle = np.zeros((120, 120), dtype=bool)
    obstacle[58:62, :] = True
    obstacle[58:62, 55:70] = False  # a 0.375 m gap at 0.025 m cells: blocked once inflated
    grid = inflate_occupied(obstacle, RES, (0.0, 0.0), radius=0.3)
    with pytest.raises(PlanningError):
        plan(grid, (1.5, 0.5), (1.5, 2.5), snap_radius=0.1)
    track = np.column_stack([np.full(41, 1.55), np.linspace(0.5, 2.5, 41)])
    opened = unblock_traversed(grid, track)
    path = plan(opened, (1.5, 0.5), (1.5, 2.5), snap_radius=0.1)
    assert path.length < 2.3
    assert unblock_traversed(opened, track) is opened  # nothing more to open


# ---- closed loop in the simulated office -------------------------------------------------------
@pytest.fixture(scope="module")
def office():
    return load_world(world_path("office"))


def make_block(**params):
    from blocks.navigate.blocks import RoomVisits
    values = {name: p.default for name, p in RoomVisits.params.items()}
    values.update(params)
    b = RoomVisits(values, name="rooms", ctx=RunContext(dt=0.1, seed=0))
    b.setup()
    b.reset()
    return b


class Signs:
    """A stand-in for signs.correlate's handle."""

    def __init__(self, signs):
        self.signs, self.version = signs, 1

    def current(self):
        return self.signs


def inside(world, name, x, y):
    from matplotlib.path import Path
    polygon = next(p.polygon for p in world.places if p.name == name)
    return Path(np.asarray(polygon)).contains_point((x, y))


@pytest.mark.parametrize("drive_by", [False, True])
def test_the_robot_visits_the_managers_room_and_comes_back_without_collisions(office, drive_by):
    spec = load_robot("atrv_mini")
    start = (6.5, 5.75, 0.0)  # in the corridor, before the MANAGER sign and door
    sim = Simulation(office, [("r", spec, start)], seed=0)
    robot = sim.robots["r"]
    b = make_block(drive_by=drive_by)
    signs = Signs([{"text": "MANAGER", "x": 8.35, "y": 5.1, "facing": 90.0}])
    visiting_at, looks_true, was_visiting = None, [], False
    out = None
    for tick in range(2000):
        b.ctx.tick = tick
        ranges, _ = sim.sonar("r")
        # the explorer drives straight on at 0.3 m/s; its loop has closed from tick 5 on
        out = b.step(robot.odom, ranges, 0.3, 0.0, signs=signs if tick > 5 else None,
                     done_in=tick > 5)
        if out["visiting"] and visiting_at is None:
            visiting_at = robot.pose.copy()
        if b.visitor.phase == "spin" and (not looks_true or
                                          np.hypot(*(looks_true[-1] - robot.pose[:2])) > 0.5):
            looks_true.append(robot.pose[:2].copy())
        if was_visiting and not out["visiting"]:
            break
        was_visiting = out["visiting"]
        sim.command("r", out["v"], out["w"])
        sim.step(0.1)
    result = b.visitor.results[0]
    assert result.status == "visited", result.reason
    assert len(result.looks) >= 2
    assert all(inside(office, "MANAGER", x, y) for x, y in looks_true)
    # back where it left the explorer, facing the same way, and the explorer may finish now
    assert np.hypot(*(robot.pose[:2] - visiting_at[:2])) < 0.4
    assert abs(math.remainder(robot.pose[2] - visiting_at[2], 2 * math.pi)) < 0.15
    assert out["done"] and out["v"] == 0.3  # passes the explorer's command through again
    assert robot.collisions == 0
    # the room is on the local map now: most of its floor was seen
    local, _ = b._map_since(-1.0, (8.35, 5.1))
    _, free, _ = local.classes()
    h, w = free.shape
    xs = local.origin[0] + (np.arange(w) + 0.5) * local.resolution
    ys = local.origin[1] + (np.arange(h) + 0.5) * local.resolution
    X, Y = np.meshgrid(xs, ys)
    room = (X > 6.1) & (X < 11.9) & (Y > 0.1) & (Y < 4.9)
    assert (free & room).sum() / room.sum() >= 0.8
    b.finish()
    metrics = b.ctx.metrics["rooms"]
    assert metrics["visited"] == 1 and metrics["rooms"][0]["sign"] == "MANAGER"
    # the door is not mapped yet when the sign is read: with a drive-by, the drive along
    # its wall finds it at once; without, the search waits for the robot to pass it
    assert (metrics["doors_driven_by"], metrics["doors_found_driving_by"]) == (drive_by, drive_by)
    assert metrics["map_builds"] >= 2


def test_a_sign_with_no_door_in_reach_is_given_up(office):
    spec = load_robot("atrv_mini")
    sim = Simulation(office, [("r", spec, (1.1, 9.0, math.pi / 2))], seed=0)
    b = make_block(give_up_distance=2.0, drive_by=False)
    # a "sign" on the plain west wall of the corridor, with no door anywhere near
    signs = Signs([{"text": "LAB", "x": 0.1, "y": 10.0, "facing": 0.0}])
    robot = sim.robots["r"]
    for tick in range(60):
        b.ctx.tick = tick
        ranges, _ = sim.sonar("r")
        out = b.step(robot.odom, ranges, 0.5, 0.0, signs=signs, done_in=True)
        assert not out["visiting"]
        assert out["done"] == (not b.visitor.pending)  # held back while the door is sought
        sim.command("r", out["v"], out["w"])
        sim.step(0.1)
    [result] = b.visitor.results
    assert result.status == "not_found" and result.attempts >= 2
    assert "no open door" in result.reason


def test_a_door_not_found_is_sought_again_on_a_later_pass():
    # the first pass sees no door (the far jamb unmapped); the second sees it
    maps = {"now": corridor_and_room(far_jamb=False)}
    asked: list[float] = []

    def source(since, near):
        asked.append(since)
        return maps["now"], np.array([[0.5, 6.0], [2.0, 6.0]])

    visitor = RoomVisitor(source, RoomVisitParams(revisits=1, revisit_distance=2.5, drive_by=False))
    visitor.add_sign(SIGN, 0.0)
    for k, x in enumerate(np.arange(0.5, 9.6, 0.5)):  # along the corridor and away
        assert visitor.step(float(k), np.array([x, 6.0, 0.0])) is None
    [first] = visitor.results
    assert first.status == "not_found" and not visitor.pending and visitor.dormant
    assert visitor.step(40.0, np.array([8.0, 6.0, math.pi])) is None  # 5.7 m off: still asleep
    maps["now"] = corridor_and_room()
    assert visitor.step(50.0, np.array([4.5, 6.0, math.pi])) is not None  # back past it
    assert visitor.phase == "enter" and visitor.results == []  # the not_found is withdrawn
    assert asked[-1] == pytest.approx(50.0 - visitor.p.window)  # this pass's scans only
    # given up a second time, it stays given up
    visitor = RoomVisitor(lambda since, near: (corridor_and_room(None), np.zeros((2, 2))),
                          RoomVisitParams(revisits=1, drive_by=False))
    visitor.add_sign(SIGN, 0.0)
    for k, x in enumerate([2.0, 8.0, 3.0, 9.0, 3.0, 9.0]):
        visitor.step(float(k), np.array([x, 6.0, 0.0]))
    [result] = visitor.results
    assert result.status == "not_found" and "passes: 2" in result.reason
    assert not visitor.dormant and not visitor.pending


def test_a_drive_by_that_finds_no_door_comes_back_and_lets_the_explorer_go_on(office):
    spec = load_robot("atrv_mini")
    start = (1.1, 9.0, math.pi / 2)
    sim = Simulation(office, [("r", spec, start)], seed=0)
    b = make_block(give_up_distance=2.0)
    signs = Signs([{"text": "LAB", "x": 0.1, "y": 10.0, "facing": 0.0}])  # on a plain wall
    robot = sim.robots["r"]
    left_at, phases, ended_at = None, set(), None
    for tick in range(900):
        b.ctx.tick = tick
        ranges, _ = sim.sonar("r")
        out = b.step(robot.odom, ranges, 0.5, 0.0,
                     signs=signs, done_in=True)
        phases.add(b.visitor.phase)
        if out["visiting"] and left_at is None:
            left_at = robot.pose.copy()
        if left_at is not None and not out["visiting"] and ended_at is None:
            ended_at = robot.pose.copy()
        if b.visitor.results:
            break
        sim.command("r", out["v"], out["w"])
        sim.step(0.1)
    assert {"drive_by", "drive_back", "align"} <= phases
    [result] = b.visitor.results
    assert result.status == "not_found"
    assert (b.visitor.drive_bys["driven"], b.visitor.drive_bys["found"]) == (1, 0)
    assert 5.0 < b.visitor.drive_bys["time_s"] < 60.0
    assert np.hypot(*(ended_at[:2] - left_at[:2])) < 0.4  # back where it left off
    assert abs(math.remainder(ended_at[2] - left_at[2], 2 * math.pi)) < 0.15
    assert robot.collisions == 0


def test_the_visitor_ignores_a_sign_it_already_knows():
    visitor = RoomVisitor(lambda since, near: None)
    assert visitor.add_sign(SignRef("A", 1.0, 1.0, 0.0))
    assert not visitor.add_sign(SignRef("A", 1.3, 1.2, 0.0))  # the same plate, re-estimated
    assert not visitor.add_sign(SignRef("A", 3.0, 1.5, 0.0))  # same text, odometry drifted
    assert visitor.add_sign(SignRef("B", 2.0, 1.0, 0.0))  # another plate next to it
    assert visitor.add_sign(SignRef("A", 12.0, 1.0, 0.0))  # another door with the same text
    assert len(visitor.pending) == 3


def test_hold_pauses_and_disabled_passes_through():
    b = make_block(enabled=False)
    out = b.step(np.zeros(3), np.full(16, 4.0), 0.4, -0.1, done_in=True)
    assert out == {"v": 0.4, "w": -0.1, "visiting": False, "done": True, "look_at": None}
    b = make_block()
    out = b.step(np.zeros(3), np.full(16, 4.0), 0.4, -0.1, hold=True)
    assert out["v"] == 0.4 and not out["visiting"]  # no visit: the explorer (and its stop) rule


def test_bad_signs_and_params_are_reported_with_the_field():
    b = make_block()
    with pytest.raises(BlockError) as err:
        b.step(np.zeros(3), np.full(16, 4.0), 0.0, 0.0, signs=Signs([{"text": "A", "x": 1}]))
    assert "input 'signs'" in str(err.value)
    with pytest.raises(BlockError) as err:
        make_block(depth_min=2.0, depth_max=1.0)
    assert "depth_max" in str(err.value)


# ---- with a collision monitor downstream ------------------------------------------------------------
def test_a_leg_the_monitor_keeps_stopping_is_held_and_a_pause_is_not():
    leg = Leg(PurePursuit(np.array([[0.0, 0.0], [5.0, 0.0]])), started=0.0)
    pose = np.zeros(3)
    assert leg.step(0.0, pose, timeout=60.0, stall_time=10.0, held_time=0.8)[2] == ""
    outcomes = [leg.step(0.1 * k, pose, timeout=60.0, stall_time=10.0, scale=0.0,
                         held_time=0.8)[2] for k in range(1, 12)]
    assert outcomes[:7] == [""] * 7 and outcomes[8] == "held"  # 0.8 s after the first stop
    # scaled down but moving is not held; nor is a monitor with nothing asked of it
    leg = Leg(PurePursuit(np.array([[0.0, 0.0], [5.0, 0.0]])), started=0.0)
    assert all(leg.step(0.1 * k, pose, timeout=60.0, stall_time=10.0, scale=0.3,
                        held_time=0.8)[2] == "" for k in range(20))


def test_a_leg_creeps_round_what_the_monitor_would_stop_and_keeps_its_way():
    from blocks.navigate.collision_monitor import EchoMemory, MonitorParams
    from blocks.navigate.guard import SonarGuard
    spec = load_robot("atrv_mini")
    echoes = EchoMemory(SonarGuard.for_robot(spec), MonitorParams())
    ranges = np.full(len(spec.sonar_names), spec.sonar.max_range)
    ranges[spec.sonar_names.index("LtFr")] = 0.1  # beside the front left corner
    pose = np.zeros(3)
    echoes.add(0.0, pose, ranges)
    way = np.array([[0.0, 0.0], [1.0, 0.6], [3.0, 1.5]])  # curving left, onto the echo
    plain = Leg(PurePursuit(way), started=0.0).step(0.0, pose, timeout=60.0, stall_time=10.0)
    assert echoes.stops(pose, plain[0], plain[1])  # as asked, the monitor would stop it
    leg = Leg(PurePursuit(way), started=0.0)
    v, w, outcome = leg.step(0.0, pose, timeout=60.0, stall_time=10.0, echoes=echoes)
    assert outcome == "" and (v, w) != plain[:2]
    assert echoes.collision_time(pose, v, w) == math.inf  # a creep the monitor lets through
    assert leg.last == (v, w)
    # creeping that gets nowhere still ends the leg
    outcomes = [leg.step(0.5 * k, pose, timeout=60.0, stall_time=10.0, echoes=echoes)[2]
                for k in range(1, 25)]
    assert "no progress" in outcomes


def test_a_leg_backs_round_what_the_monitor_would_stop_no_more_than_creep_back():
    """Every motion but backing stopped, the nearest clear one is backing: blind (the rear
    has few sonars), so the leg gives up after ``creep_back`` of it, not ``stall_time``."""

    class OnlyBackingClear:  # echoes ahead and at both front corners, none behind
        calls = 0

        def stops(self, pose, v, w):
            return v >= 0.0

        def nearest_clear(self, pose, v, w):
            self.calls += 1  # now and then a turn on the spot is clear
            return (0.0, -0.6) if self.calls % 5 == 0 else (-0.15, 0.0)

    def backed_before_giving_up(creep_back: float) -> float:
        leg = Leg(PurePursuit(np.array([[0.0, 0.0], [5.0, 0.0]])), started=0.0)
        echoes, x = OnlyBackingClear(), 0.0
        for k in range(300):
            v, _, outcome = leg.step(0.1 * k, np.array([x, 0.0, 0.0]), timeout=120.0,
                                     stall_time=60.0, echoes=echoes, creep_back=creep_back)
            if outcome:
                assert outcome == "no progress"
                return -x
            x += 0.1 * v
        return -x

    assert 0.35 <= backed_before_giving_up(0.4) <= 0.45
    assert backed_before_giving_up(math.inf) > 2.0


def test_a_leg_jiggling_ahead_and_back_round_what_the_monitor_stops_gives_up():
    """Pinned by a corner, the way asks for a turn on the spot; the monitor stops it and
    the nearest clear creeps go ahead and back in turn, getting nowhere (ring-1001: 40 s
    of it, a rear corner touching the wall at every back)."""

    class AheadThenBack:  # a turn is stopped; a creep is clear one way, then the other
        calls = 0

        def stops(self, pose, v, w):
            return True

        def nearest_clear(self, pose, v, w):
            self.calls += 1
            return (0.15, 0.0) if self.calls % 2 else (-0.15, 0.0)

    def steps_to_give_up(creep_reversals: int) -> int | None:
        way = np.array([[0.0, 0.0], [0.0, 3.0]])  # straight to the left: turn first
        leg, echoes, x = Leg(PurePursuit(way), started=0.0), AheadThenBack(), 0.0
        for k in range(300):
            v, _, outcome = leg.step(0.1 * k, np.array([x, 0.0, 0.0]), timeout=120.0,
                                     stall_time=10.0, echoes=echoes,
                                     creep_reversals=creep_reversals)
            if outcome:
                assert outcome == "no progress" and leg.why.startswith(
                    "crept ahead and back" if creep_reversals < 100 else "no progress for")
                return k
            x += 0.1 * v
        return None

    assert steps_to_give_up(3) == 4  # the fourth reversal, not stall_time's 100 steps
    assert steps_to_give_up(1000) == 101  # the turn never turned: stall_time ends it


def test_a_turn_on_the_spot_is_progress_only_while_the_heading_moves():
    way = np.array([[0.0, 0.0], [0.0, 3.0]])  # straight to the left: turn first

    def outcome_after(seconds: float, turning: bool) -> str:
        leg, theta = Leg(PurePursuit(way), started=0.0), 0.0
        for k in range(int(seconds * 10)):
            v, w, outcome = leg.step(0.1 * k, np.array([0.0, 0.0, theta]), timeout=120.0,
                                     stall_time=10.0)
            if outcome:
                return outcome
            if turning:
                theta += 0.1 * w * 0.05  # a slow turn, 20 times slower than asked
        return ""

    assert outcome_after(20.0, turning=False) == "no progress"  # wedged: the turn never turns
    assert outcome_after(20.0, turning=True) == ""  # slow, but turning


def test_a_visit_held_on_its_way_to_the_door_ends_failed_at_once():
    local = corridor_and_room()
    positions = np.array([[0.5, 6.0], [2.0, 6.0]])
    visitor = RoomVisitor(lambda since, near: (local, positions),
                          RoomVisitParams(held_time=0.8))
    visitor.add_sign(SIGN, 0.0)
    pose = np.array([0.8, 6.0, 0.0])
    assert visitor.step(0.0, pose) is not None and visitor.phase == "enter"
    for k in range(1, 12):  # whatever it asks, the monitor lets none of it through
        visitor.step(0.1 * k, pose, scale=0.0)
    assert visitor.phase == "idle"
    result = visitor.results[-1]
    assert result.status == "failed" and "held by the collision monitor" in result.reason


def _drive_visit(visitor, pose, *, blocked: str = "", seconds: float = 240.0):
    """Integrate the visitor's commands on a point robot; in the phase ``blocked`` a turn
    on the spot does not happen (a monitor stopping it at furniture).  Returns the phases
    met and the tick the visit ended on (or None)."""
    phases = []
    for k in range(int(seconds / 0.1)):
        out = visitor.step(0.1 * k, pose)
        phases.append(visitor.phase)
        if out is None or (k > 0 and visitor.phase == "idle"):
            return phases, k
        v, w = out
        if visitor.phase == blocked:
            w = 0.0
        pose = pose + 0.1 * np.array([v * math.cos(pose[2]), v * math.sin(pose[2]), w])
    return phases, None


@pytest.mark.parametrize("blocked, given_up", [("", 0), ("spin", 1), ("face", 2),
                                               ("align", 1)])
def test_a_turn_that_cannot_be_made_is_given_up_and_the_visit_goes_on(blocked, given_up):
    """A turn on the spot is measured, not timed: one a collision monitor keeps stopping
    (furniture at a corner of the body) held the visit, and the whole run, for ever.
    Now the look round, facing the door (in and out) and lining up at the end are each
    given up after ``stall_time`` and the visit ends; turns that can be made are made."""
    local = corridor_and_room()
    positions = np.array([[0.5, 6.0], [2.0, 6.0]])
    visitor = RoomVisitor(lambda since, near: (local, positions),
                          RoomVisitParams(stall_time=5.0, looks=1))
    visitor.add_sign(SIGN, 0.0)
    phases, ended = _drive_visit(visitor, np.array([0.8, 6.0, 0.0]), blocked=blocked)
    assert {"spin", "face", "align"} <= set(phases) and ended is not None, phases[-1]
    assert visitor.results[-1].status == "visited"
    assert visitor.summary()["turns_given_up"] == given_up
    if blocked:  # it waited its 5 s (50 ticks) for each such turn, no longer
        assert 50 * given_up <= phases.count(blocked) <= 55 * given_up
