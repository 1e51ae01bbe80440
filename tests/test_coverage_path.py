"""The coverage path on the true floor plan: the yardstick of an exploration's path length."""
from __future__ import annotations

import numpy as np
import pytest

from blocks.explore.coverage_path import _greedy_cover, _open_tour, coverage_path
from sim2d.world import load_world

from conftest import floor_plan, write_world


def test_the_open_tour_of_points_on_a_line_goes_along_it():
    xs = np.array([0.0, 3.0, 1.0, 4.0, 2.0])
    dist = np.abs(xs[:, None] - xs[None, :])
    order = _open_tour(dist)
    assert order[0] == 0 and sorted(order) == list(range(5))
    assert sum(dist[a, b] for a, b in zip(order[:-1], order[1:])) == 4.0


def test_greedy_cover_takes_the_big_view_first_and_stops_at_the_target():
    views = [np.arange(0, 6), np.arange(5, 8), np.arange(7, 10), np.array([9])]
    assert _greedy_cover(views, 10, 1.0) == [0, 2, 1]
    assert _greedy_cover(views, 10, 0.6) == [0]


def test_a_corridor_is_covered_by_driving_to_within_sensing_range_of_its_far_end(tmp_path):
    xc, yc = floor_plan(12.0, 1.6, 0.05)
    walls = (xc < 0) | (xc > 12) | (yc < 0) | (yc > 1.6)
    world = load_world(write_world(tmp_path, "corridor", walls, start=(0.6, 0.8, 0.0),
                                   doc="A straight corridor."))
    path = coverage_path(world, sensing_range=2.0, coverage=1.0)
    assert abs(path.floor_area - 12 * 1.6) < 1.0
    assert path.seen_share > 0.99
    # it must come within 2 m of the far end, and has no reason to go much further
    assert 12 - 2.0 - 0.6 - 0.5 <= path.length <= 12 - 0.6 + 0.3
    assert path.viewpoints[-1][0] >= 9.5


def test_a_room_off_the_corridor_is_entered(tmp_path):
    """A 4 x 4 m room behind a 1 m door: what is seen from the corridor is not enough."""
    xc, yc = floor_plan(8.0, 6.0, 0.05)
    outer = (xc < 0) | (xc > 8) | (yc < 0) | (yc > 6)
    wall = (yc > 1.5) & (yc < 1.7) & ~((xc > 3.5) & (xc < 4.5))  # corridor below, room above
    world = load_world(write_world(tmp_path, "room", outer | wall, start=(0.6, 0.75, 0.0),
                                   doc="A corridor and a room behind a door."))
    path = coverage_path(world, sensing_range=2.0)
    assert path.seen_share >= 0.95
    assert (path.viewpoints[:, 1] > 2.5).any()  # a viewpoint well inside the room


def test_the_efficiency_benchmark_reads_a_sweep_and_sets_each_path_beside_the_coverage_path(
        tmp_path):
    """A sweep folder with one run on the corridor: a robot that drove 8 m of it and back."""
    import json
    import subprocess
    import sys

    from conftest import ROOT
    xc, yc = floor_plan(12.0, 1.6, 0.05)
    walls = (xc < 0) | (xc > 12) | (yc < 0) | (yc > 1.6)
    world = write_world(tmp_path, "corridor", walls, start=(0.6, 0.8, 0.0), doc="A corridor.")
    sweep = tmp_path / "sweep"
    run = sweep / "runs" / "corridor-s0"
    run.mkdir(parents=True)
    (sweep / "sweep.json").write_text(json.dumps(
        {"tasks": [{"name": "corridor-s0", "world": str(world), "kind": "corridor"}]}))
    (run / "run.json").write_text(json.dumps(
        {"status": "done", "sim_time_s": 96.0,
         "metrics": {"offline_map": {"free_coverage": 0.8}}}))
    xs = list(np.arange(0.6, 8.6, 0.1)) + list(np.arange(8.6, 0.6, -0.1))
    (run / "trajectory.csv").write_text(
        "tick,time,robot,x,y,theta,odom_x,odom_y,odom_theta,v,w\n" + "".join(
            f"{k},{k * 0.1:.1f},robot,{x:.3f},0.8,0,{x:.3f},0.8,0,0,0\n" for k, x in enumerate(xs)))
    out = tmp_path / "rows.json"
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks/exploration_efficiency.py"),
                           str(sweep), "--json", str(out), "--quiet"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    (row,) = json.loads(out.read_text())
    assert row["time_per_100m2"] == pytest.approx(100 * 96.0 / (12 * 1.6), rel=0.05)
    assert row["driven_m"] == pytest.approx(16.0, abs=0.3)
    assert row["path_ratio"] == pytest.approx(16.0 / row["coverage_path_m"], abs=0.01)
    assert 1.3 < row["path_ratio"] < 2.2  # there and back, where the best goes there only
    assert "| corridor |" in proc.stdout
