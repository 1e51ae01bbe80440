"""Which true doors the explorer's map lets the robot through, replayed from recorded runs.

A room whose door the exploration map draws shut is never explored: its
frontier, seen through the door, lies beyond a wall the planner cannot cross,
and no failure is logged.  This replays a run's exploration map (the online
drift correction and the log-odds map of ``graphs/semantic_mapping.yaml``,
fed the run's recorded odometry and sonar: the robot's path stays as it was,
open loop) and asks, for every open door of the world, whether the planner's
grid joins the two sides at the end of the run: ``passable`` (on the wide
grid), ``tight`` (only on the tight grid the explorer uses for doors the wide
one closes), ``shut`` (both sides seen free, no way through) or ``unseen`` (a
side never seen free).  A door's sides are found on the true map (scoring
only).  With ``--set KEY=VALUE`` (fields of
:class:`blocks.maps.logodds.InverseSonarModel`) it replays a variant of the
map model instead, so a change to the model is measured on many doors before
a robot drives on it; the map's wall precision and false free space against
the true floor (:func:`blocks.maps.score.score_map`) say what the change costs.

    python benchmarks/doorways.py runs/dev [--set shared_arc=0.2] [--list]
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from collections import Counter
from dataclasses import fields
from pathlib import Path

import numpy as np
import yaml
from scipy import ndimage

from blocks.maps.drift import DriftCorrection, DriftCorrector
from blocks.maps.logodds import InverseSonarModel, LogOddsMap, clear_ranges
from blocks.maps.mapio import OccupancyMap, occupancy_map_from_world
from blocks.maps.score import score_map
from blocks.navigate.grid import inflate
from sim2d.world import load_world

GRAPH = Path(__file__).resolve().parents[1] / "graphs" / "semantic_mapping.yaml"
#: The explorer's grids (explore.frontiers' radius and tight_radius, m).
WIDE, TIGHT = 0.36, 0.2
#: How far (m) either side of a door's middle its two sides are tested.
SIDE = 0.7
#: A side's cell may be this many cells from the grid's free space it joins.
SLACK = 3


def graph_map() -> tuple[dict, float]:
    """The inverse sonar model's settings and the cell size of the exploration map in
    graphs/semantic_mapping.yaml (its ``explore_map`` node; parameters given as graph
    parameters, off by default there, are left at the model's defaults)."""
    doc = yaml.safe_load(GRAPH.read_text())
    node = next(n for n in doc["nodes"] if n["id"] == "explore_map")
    known = {f.name for f in fields(InverseSonarModel)}
    literal = {k: v for k, v in node.get("params", {}).items() if not str(v).startswith("${")}
    return {k: v for k, v in literal.items() if k in known}, float(literal["resolution"])


def replay_exploration_map(run: Path, model: InverseSonarModel,
                           resolution: float) -> OccupancyMap:
    """The exploration map at the end of a recorded run, drawn with ``model``."""
    sonar = np.load(run / "sonar.npz")
    with open(run / "trajectory.csv", newline="") as f:
        odometry = np.array([[float(r[f"odom_{k}"]) for k in ("x", "y", "theta")]
                             for r in csv.DictReader(f)])
    mounts = sonar["robot@mounts"]
    corrector = DriftCorrector(mounts, float(sonar["robot@cone_deg"]), DriftCorrection())
    grid = LogOddsMap(model, resolution=resolution)
    silent = model.max_range - model.max_range_margin
    mx, my, mt = mounts[:, 0], mounts[:, 1], mounts[:, 2]
    for tick, ranges in zip(sonar["robot@tick"], sonar["robot@ranges"]):
        x, y, theta = corrector.add(odometry[tick], ranges, ranges < silent)
        c, s = math.cos(theta), math.sin(theta)
        sensors = np.column_stack([x + c * mx - s * my, y + s * mx + c * my, theta + mt])
        grid.add_scan(sensors, ranges, clear_ranges(sensors, ranges, corrector.segments(), model))
    p, (ix, iy) = grid.probabilities()
    return OccupancyMap(p, resolution, (ix * resolution, iy * resolution, 0.0))


def door_sides(truth: OccupancyMap, x: float, y: float, width: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Two points ``SIDE`` either side of a door's middle, square to its wall: the wall runs
    the way whose jambs, just beyond the opening, are walls on the true map."""
    walls = truth.classes()[0]

    def wall_at(p: np.ndarray) -> bool:
        r = int((p[1] - truth.origin[1]) / truth.resolution)
        c = int((p[0] - truth.origin[0]) / truth.resolution)
        return 0 <= r < walls.shape[0] and 0 <= c < walls.shape[1] and bool(walls[r, c])
    middle = np.array([x, y])
    best, along = -1, np.array([1.0, 0.0])
    for k in range(72):
        u = np.array([math.cos(math.pi * k / 72), math.sin(math.pi * k / 72)])
        jambs = sum(wall_at(middle + sign * (width / 2 + e) * u)
                    for sign in (-1, 1) for e in (0.05, 0.1, 0.15))
        if jambs > best:
            best, along = jambs, u
    normal = np.array([-along[1], along[0]])
    return middle + SIDE * normal, middle - SIDE * normal


def passages(m: OccupancyMap) -> tuple[np.ndarray, list[tuple[np.ndarray, str]]]:
    """The map's free cells, and the connected free space of the wide and the tight grid
    (labelled, with the state a door joined on it is in), computed once per map."""
    grids = [(ndimage.label(~inflate(m, radius=radius).blocked, structure=np.ones((3, 3)))[0],
              state) for radius, state in ((WIDE, "passable"), (TIGHT, "tight"))]
    return m.classes()[1], grids


def door_state(m: OccupancyMap, reach: tuple[np.ndarray, list[tuple[np.ndarray, str]]],
               sides: tuple[np.ndarray, np.ndarray]) -> str:
    """``passable``, ``tight``, ``shut`` or ``unseen`` (see the module docstring);
    ``reach`` is :func:`passages` of ``m``."""
    free, grids = reach
    cells = []
    for p in sides:
        r = int(math.floor((p[1] - m.origin[1]) / m.resolution))
        c = int(math.floor((p[0] - m.origin[0]) / m.resolution))
        if not (0 <= r < free.shape[0] and 0 <= c < free.shape[1]) or not free[r, c]:
            return "unseen"
        cells.append((r, c))
    for labels, state in grids:
        near = [set(labels[max(r - SLACK, 0):r + SLACK + 1,
                           max(c - SLACK, 0):c + SLACK + 1].ravel().tolist()) - {0}
                for r, c in cells]
        if near[0] & near[1]:
            return state
    return "shut"


def width_bin(width: float) -> str:
    return "under 1 m" if width < 1.0 else "1 m and over"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", help="a sweep's folder (its runs/*) or one run's folder")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a field of the inverse sonar model to replay instead of the graph's")
    ap.add_argument("--list", action="store_true", help="print every door")
    args = ap.parse_args(argv)
    settings, resolution = graph_map()
    known = {f.name: f for f in fields(InverseSonarModel)}
    for item in args.set:
        key, _, value = item.partition("=")
        if key not in known:
            ap.error(f"--set {item}: not a field of InverseSonarModel ({', '.join(known)})")
        settings[key] = None if value.lower() == "none" else float(value)
    root = Path(args.runs)
    runs = sorted(p for p in (root / "runs").glob("*") if (p / "sonar.npz").exists()) \
        if (root / "runs").is_dir() else [root]
    totals: Counter = Counter()
    print(f"model: {settings}")
    print("| run | passable | tight | shut | unseen | wall precision | false free |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for run in runs:
        meta = json.loads((run / "run.json").read_text())
        world = load_world(meta["metrics"]["world"]["world"])
        sonar = np.load(run / "sonar.npz")
        model = InverseSonarModel(cone_deg=float(sonar["robot@cone_deg"]),
                                  max_range=float(sonar["robot@max_range"]), **settings)
        m = replay_exploration_map(run, model, resolution)
        truth = occupancy_map_from_world(world)
        counts: Counter = Counter()
        reach = passages(m)
        for door in world.doors:
            if door.closed:
                continue
            state = door_state(m, reach, door_sides(truth, door.x, door.y, door.width))
            counts[state] += 1
            totals[(width_bin(door.width), state)] += 1
            if args.list:
                print(f"    {run.name} {door.between[0]} ({door.width:.2f} m): {state}")
        score = score_map(m, world)
        print(f"| {run.name} | {counts['passable']} | {counts['tight']} | {counts['shut']} | "
              f"{counts['unseen']} | {score['precision']:.3f} | {score['false_free']:.3f} |",
              flush=True)
    print("\n| door width | passable | tight | shut | unseen |\n| --- | --- | --- | --- | --- |")
    for label in ("under 1 m", "1 m and over"):
        print(f"| {label} | " + " | ".join(str(totals[(label, s)]) for s in
                                           ("passable", "tight", "shut", "unseen")) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
