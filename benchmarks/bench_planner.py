"""Path planning time: A* plus line-of-sight shortcutting on the office map.

Twenty cross-floor queries (a room on one side of the floor to a room on the
other, most of them round the corridor loop) are planned on the office
world's true floor plan (30 m x 20 m at 0.05 m: 620 x 420 cells with the
margin), inflated by the ATRV-Mini's radius.  Each query is timed as
:func:`blocks.navigate.planner.plan` runs it: snapping the ends, pyastar2d's
A*, shortcutting.  The reference, measured in the same run on the same grid,
is one ``scipy.ndimage.distance_transform_edt`` of the obstacle grid, the
operation that builds the inflation: the ratio says how many such transforms
one plan costs.  Building the grid itself (``inflate``) is reported too; it
is done once per map, not per query.
Target: every query < 20 ms (issue 8 allows 50 ms for parsing plus planning).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from blocks.maps.mapio import occupancy_map_from_world  # noqa: E402
from blocks.navigate.grid import inflate  # noqa: E402
from blocks.navigate.planner import plan  # noqa: E402
from sim2d.world import load_world  # noqa: E402
from sim2d.worlds import world_path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_io import write_results  # noqa: E402

RESULTS_JSON = Path(__file__).resolve().parent / "results" / "planner.json"
TARGET_MS = 20.0

#: Free points in the office's rooms and corridor (world x, y).
SOUTH = [(3.0, 3.8), (9.0, 3.5), (15.0, 3.8), (21.0, 4.0), (26.0, 3.5)]
NORTH = [(3.0, 16.5), (9.0, 16.0), (15.0, 16.5), (21.0, 16.5), (27.0, 17.5)]
CORE = [(8.0, 8.5), (14.5, 10.0), (17.5, 10.0), (23.0, 11.5)]
CORRIDOR = [(1.0, 5.8), (29.0, 10.0), (1.0, 14.0), (15.0, 6.1)]


def queries() -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """20 cross-floor pairs: south to north rooms (both ways round), core to far rooms, corners."""
    pairs = [(s, n) for s, n in zip(SOUTH, reversed(NORTH))]      # 5 diagonal crossings
    pairs += [(n, s) for n, s in zip(NORTH, SOUTH)]                # 5 straight across
    pairs += [(c, r) for c, r in zip(CORE, [NORTH[4], SOUTH[0], NORTH[0], SOUTH[4]])]  # 4
    pairs += [(SOUTH[0], SOUTH[4]), (NORTH[0], NORTH[4]), (CORRIDOR[0], NORTH[4]),
              (CORRIDOR[1], SOUTH[0]), (CORRIDOR[2], SOUTH[4]), (CORRIDOR[3], NORTH[2])]
    return pairs


def best_of(fn, repeats: int) -> float:
    """Least wall time (s) of ``repeats`` calls: the least disturbed by the machine."""
    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    repeats = 1 if args.quick else 5
    occupancy_map = occupancy_map_from_world(load_world(world_path("office")))
    occupied = occupancy_map.classes()[0]
    build_ms = 1e3 * best_of(lambda: inflate(occupancy_map), repeats)
    grid = inflate(occupancy_map)
    reference_ms = 1e3 * best_of(lambda: ndimage.distance_transform_edt(~occupied), repeats)
    pairs = queries()
    times, lengths = [], []
    for start, goal in pairs:
        times.append(1e3 * best_of(lambda s=start, g=goal: plan(grid, s, g), repeats))
        lengths.append(plan(grid, start, goal).length)
    times_a = np.array(times)
    h, w = grid.shape
    print(f"A* + shortcut on the office map ({w} x {h} cells, {grid.resolution} m), "
          f"{len(pairs)} cross-floor queries, best of {repeats}")
    print(f"reference: scipy.ndimage.distance_transform_edt of the same grid: "
          f"{reference_ms:.2f} ms\n")
    print(f"{'query':>5}  {'from':>14}  {'to':>14}  {'length m':>8}  {'ms':>6}  {'x ref':>6}")
    for k, ((s, g), ms, length) in enumerate(zip(pairs, times, lengths)):
        print(f"{k:5d}  {str(s):>14}  {str(g):>14}  {length:8.1f}  {ms:6.2f}  "
              f"{ms / reference_ms:6.2f}")
    print(f"\ngrid build (inflate: EDT, cost, components): {build_ms:.1f} ms, once per map")
    print(f"plan ms: median {np.median(times_a):.2f}, mean {times_a.mean():.2f}, "
          f"max {times_a.max():.2f}")
    ok = bool(times_a.max() < TARGET_MS)
    print(f"{'PASS' if ok else 'MISS'} slowest query {times_a.max():.1f} ms "
          f"(target < {TARGET_MS:.0f} ms)")
    results = {"queries": len(pairs), "grid_cells": [int(w), int(h)],
               "resolution_m": grid.resolution, "repeats": repeats,
               "reference": "scipy.ndimage.distance_transform_edt of the obstacle grid",
               "reference_ms": round(reference_ms, 3), "grid_build_ms": round(build_ms, 3),
               "plan_ms_median": round(float(np.median(times_a)), 3),
               "plan_ms_mean": round(float(times_a.mean()), 3),
               "plan_ms_max": round(float(times_a.max()), 3),
               "plan_x_reference_median": round(float(np.median(times_a)) / reference_ms, 3),
               "plan_x_reference_max": round(float(times_a.max()) / reference_ms, 3),
               "path_length_m_mean": round(float(np.mean(lengths)), 2),
               "target_ms": TARGET_MS, "pass": ok,
               "per_query_ms": [round(t, 3) for t in times]}
    write_results(args.json, results)
    return 0 if args.quick else (0 if ok else 1)


if __name__ == "__main__":
    sys.exit(main())
