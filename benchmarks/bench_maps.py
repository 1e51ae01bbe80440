"""Global map update rate: the paper's 2-bit map and the log-odds map, on a recorded exploration.

One *update* is one step's sonar scan accumulated into the global map (for the
paper's map: the local map built, rotated, shifted and added). The scans and
odometry come from the perimeter follower exploring the office world, run
first without the framework. The reference, measured in the same run, is one
simulation step of that robot (physics plus the 16-sonar scan): the ratio says
how many map updates fit in the time of one simulated step.
Target: >= 2000 updates per second on one core, for both models.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from blocks.explore.controller import (GROUP_INPUTS, KnowledgeBases,  # noqa: E402
                                       PerimeterController, sonar_group_index, sonar_groups)
from blocks.maps.logodds import LogOddsMap  # noqa: E402
from blocks.maps.paper import LocalMapper, PaperGlobalMap, SensorMount  # noqa: E402
from sim2d.robot import load_robot  # noqa: E402
from sim2d.simulation import Simulation  # noqa: E402
from sim2d.world import load_world  # noqa: E402
from sim2d.worlds import world_path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_io import write_results  # noqa: E402

RESULTS_JSON = Path(__file__).resolve().parent / "results" / "maps.json"
TARGET = 2000.0


def record_exploration(steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Scans (T, 16), odometry poses (T, 3), sonar mounts, and seconds per simulated step."""
    spec = load_robot("atrv_mini")
    world = load_world(world_path("office"))
    sim = Simulation(world, [("r", spec, world.start)])
    controller = PerimeterController(KnowledgeBases.load(), spec.limits.max_speed,
                                     spec.limits.max_turn_rate)
    index = sonar_group_index(spec)
    scans, poses, sim_seconds = [], [], 0.0
    for _ in range(steps):
        t0 = time.perf_counter()
        ranges, _ = sim.sonar("r")
        sim_seconds += time.perf_counter() - t0
        groups = sonar_groups(ranges, index)
        v, w = controller.decide(np.array([[groups[n][0] for n in GROUP_INPUTS]]))[0]
        t0 = time.perf_counter()
        sim.command("r", v, w)
        sim.step(0.1)
        sim_seconds += time.perf_counter() - t0
        scans.append(ranges.copy())
        poses.append(sim.robots["r"].odom.copy())
    return np.array(scans), np.array(poses), np.asarray(spec.sonar_mounts), sim_seconds / steps


def paper_updates_per_second(scans, poses, mounts) -> float:
    mapper = LocalMapper([SensorMount(*m) for m in mounts])
    gm = PaperGlobalMap()
    start = time.perf_counter()
    for ranges, pose in zip(scans, poses):
        gm.add(mapper.local_map(ranges), pose)
    return len(scans) / (time.perf_counter() - start)


def logodds_updates_per_second(scans, poses, mounts) -> float:
    lo = LogOddsMap()
    start = time.perf_counter()
    for ranges, (x, y, theta) in zip(scans, poses):
        c, s = math.cos(theta), math.sin(theta)
        sensors = np.column_stack([x + c * mounts[:, 0] - s * mounts[:, 1],
                                   y + s * mounts[:, 0] + c * mounts[:, 1], theta + mounts[:, 2]])
        lo.add_scan(sensors, ranges)
    return len(scans) / (time.perf_counter() - start)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    scans, poses, mounts, sim_step = record_exploration(300 if args.quick else 1500)
    repeats = 1 if args.quick else 3
    rates = {"paper": max(paper_updates_per_second(scans, poses, mounts) for _ in range(repeats)),
             "logodds": max(logodds_updates_per_second(scans, poses, mounts)
                            for _ in range(repeats))}
    reference = 1.0 / sim_step
    print(f"semmap global map updates: {len(scans)} office exploration steps")
    print(f"reference: one simulated robot step (physics + 16 sonars): {reference:,.0f} per s\n")
    print(f"{'model':>8}  {'updates/s':>10}  {'x sim steps':>11}")
    status = 0
    results = {"steps": len(scans), "reference_sim_steps_per_s": round(reference, 1),
               "target_updates_per_s": TARGET}
    for name, rate in rates.items():
        print(f"{name:>8}  {rate:10,.0f}  {rate / reference:11.2f}")
        results[f"{name}_updates_per_s"] = round(rate, 1)
        results[f"{name}_x_sim_step"] = round(rate / reference, 3)
    print()
    for name, rate in rates.items():
        ok = rate >= TARGET
        status |= 0 if ok else 1
        print(f"{'PASS' if ok else 'MISS'} {name}: {rate:,.0f} updates per second "
              f"(target >= {TARGET:,.0f})")
    write_results(args.json, results)
    return 0 if args.quick else status  # a quick run is a smoke test on a busy machine


if __name__ == "__main__":
    sys.exit(main())
