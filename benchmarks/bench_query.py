"""Text query planner latency: parse + ground + plan (A* included) per command, office world.

Each command of a fixed list (carrying, going, finding, questions with times) is
answered by :func:`semantic.query.ask` on the office world surveyed (its floor
plan at 0.05 m inflated by the ATRV-Mini's radius, its knowledge base reasoned
once beforehand: loading a map is not part of a command). The reference,
measured in the same run on the same grid, is one
``scipy.ndimage.distance_transform_edt`` of the obstacle grid, as in
``bench_planner``: the ratio says how many such transforms a command costs.
Target (issue 8): every command < 50 ms.
"""
from __future__ import annotations

import argparse
import datetime as dt
import sys
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from semantic.query import ask, load_map  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_planner import best_of  # noqa: E402
from results_io import write_results  # noqa: E402

RESULTS_JSON = Path(__file__).resolve().parent / "results" / "query.json"
TARGET_MS = 50.0
NOW = dt.datetime(2026, 11, 23, 10, 0)
COMMANDS = [
    "fetch the manager's mail",
    "send the admin laptop to maintenance",
    "please take the admin's laptop to the maintenance room",
    "bring me a book",
    "take the toolbox to the kitchen",
    "go to office 103",
    "go to Ada's office",
    "find the shredder",
    "bring Dr Lovelace the mail at 2 pm on friday",
    "how do I get to the lab?",
    "where is the shredder?",
    "where is Ada at 10:30 on monday?",
    "who works in the mail room?",
]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    repeats = 1 if args.quick else 5
    t = time.perf_counter()
    qm = load_map("office")
    load_ms = (time.perf_counter() - t) * 1e3
    obstacle = qm.grid.clearance <= 0
    reference_ms = 1e3 * best_of(lambda: ndimage.distance_transform_edt(~obstacle), repeats)
    times, lengths = [], []
    for command in COMMANDS:
        ask(command, qm, now=NOW)  # warm the per-map caches (place points) like a session
        times.append(1e3 * best_of(lambda c=command: ask(c, qm, now=NOW), repeats))
        lengths.append(ask(command, qm, now=NOW).path_length)
    times_a = np.array(times)
    h, w = qm.grid.shape
    print(f"parse + ground + plan on the office world ({w} x {h} cells, "
          f"{qm.grid.resolution} m), {len(COMMANDS)} commands, best of {repeats}")
    print(f"reference: scipy.ndimage.distance_transform_edt of the same grid: "
          f"{reference_ms:.2f} ms; loading the map (once): {load_ms:.0f} ms\n")
    print(f"{'ms':>6}  {'x ref':>6}  {'path m':>6}  command")
    for command, ms, length in zip(COMMANDS, times, lengths):
        print(f"{ms:6.2f}  {ms / reference_ms:6.2f}  {length:6.1f}  {command}")
    ok = bool(times_a.max() < TARGET_MS)
    print(f"\nms per command: median {np.median(times_a):.2f}, max {times_a.max():.2f}")
    print(f"{'PASS' if ok else 'MISS'} slowest command {times_a.max():.1f} ms "
          f"(target < {TARGET_MS:.0f} ms)")
    write_results(args.json, {
        "commands": len(COMMANDS), "grid_cells": [int(w), int(h)],
        "resolution_m": qm.grid.resolution, "repeats": repeats,
        "reference": "scipy.ndimage.distance_transform_edt of the obstacle grid",
        "reference_ms": round(reference_ms, 3), "map_load_ms": round(load_ms, 1),
        "ask_ms_median": round(float(np.median(times_a)), 3),
        "ask_ms_max": round(float(times_a.max()), 3),
        "ask_x_reference_median": round(float(np.median(times_a)) / reference_ms, 3),
        "ask_x_reference_max": round(float(times_a.max()) / reference_ms, 3),
        "target_ms": TARGET_MS, "pass": ok,
        "per_command_ms": dict(zip(COMMANDS, (round(v, 3) for v in times)))})
    return 0 if args.quick else (0 if ok else 1)


if __name__ == "__main__":
    sys.exit(main())
