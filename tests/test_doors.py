"""Doors in closed loop: the main pipeline on two rooms joined by one door.

Why here and not on a hand-made map: a sonar map draws a door narrower than
it is (the jambs' echo arcs spread across it), and the explorer must both
find the door on that map and get the body through it.  Only the whole
loop (simulated sonar, the explorer's own map, the planner and the guard)
shows whether it does.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, floor_plan, write_world

pytestmark = pytest.mark.slow  # the main pipeline end to end

GRAPH = ROOT / "graphs" / "semantic_mapping.yaml"
WALL_X = 4.0  # the wall between the rooms (its west face)


def two_rooms(tmp_path: Path, door: float, jamb: float, start: list[float]) -> Path:
    """Two rooms of 4 x 5 m and about 5 x 5 m; a door ``door`` m wide in the wall
    between them, which is ``jamb`` m thick (a deep jamb: a doorway in a thick wall)."""
    xc, yc = floor_plan(9.0, 5.0)
    outer = (xc < 0) | (xc > 9) | (yc < 0) | (yc > 5)
    wall = (xc > WALL_X) & (xc < WALL_X + jamb) & (np.abs(yc - 2.5) > door / 2)
    return write_world(tmp_path, "rooms", outer | wall, start=start,
                       doc=f"Two rooms and a door {door} m wide in a wall {jamb} m thick.")


def explore(cli, tmp_path: Path, world: Path) -> tuple[dict, np.ndarray]:
    out = tmp_path / "run"
    result = cli("run", GRAPH, "--world", world, "--out", out, "--quiet", "--steps", 5000)
    assert result.code == 0, result.err
    metrics = json.loads((out / "run.json").read_text())["metrics"]
    with open(out / "trajectory.csv") as f:
        xs = np.array([float(row["x"]) for row in csv.DictReader(f)])
    return metrics, xs


@pytest.mark.parametrize("start", [[1.0, 1.0, 0.0], [1.5, 2.5, 1.5708]])
def test_a_door_0_9_m_wide_is_found_on_the_sonar_map_and_passed(cli, tmp_path, start):
    metrics, xs = explore(cli, tmp_path, two_rooms(tmp_path, door=0.9, jamb=0.1, start=start))
    assert xs.max() > WALL_X + 0.1 + 1.0, "never got into the second room"
    assert metrics["world"]["collisions"] == 0
    assert metrics["explorer"]["end_reason"] == "explored"
    assert metrics["offline_map"]["free_coverage"] >= 0.85  # both rooms


def test_a_door_in_a_thick_wall_is_entered(cli, tmp_path):
    world = two_rooms(tmp_path, door=1.2, jamb=0.75, start=[1.0, 1.0, 0.0])
    metrics, xs = explore(cli, tmp_path, world)
    assert xs.max() > WALL_X + 0.75 + 1.0, "never got through the doorway"
    assert metrics["explorer"]["end_reason"] == "explored"
    assert metrics["offline_map"]["free_coverage"] >= 0.85
