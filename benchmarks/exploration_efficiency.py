"""Exploration time per 100 m² and path length against a coverage path on the true map, per kind.

Issue 20 asks how long exploring takes for the floor it covers, and how the
path driven compares with a path planned to see the whole floor on the true
map (:func:`blocks.explore.coverage_path.coverage_path`: viewpoints seeing
95 % of the floor within 2 m, toured from the start; scoring only). For each
run of one or more sweeps (``semmap sweep`` output folders), it reads the
run's simulated time, its true path (trajectory.csv) and its free coverage,
and prints per layout kind the median and the worst run of

time / 100 m²
    the run's simulated time per 100 m² of reachable floor;
time / 100 m² mapped
    the same per 100 m² of floor its offline map marks free;
path / coverage path
    the length driven over the coverage path's length (below 1 is possible:
    the coverage path is an approximation, and a run may not see it all);

beside the free coverage, which says how much of the job those figures paid for.

    python benchmarks/exploration_efficiency.py runs/eval --json runs/eval/efficiency.json
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from blocks.explore.coverage_path import coverage_path  # noqa: E402
from blocks.maps.score import read_path_csv  # noqa: E402
from sim2d.blocks import resolve_world  # noqa: E402
from sim2d.world import load_world  # noqa: E402


def run_rows(sweep: Path) -> list[dict]:
    """(name, world spec, kind) of each task of a sweep folder."""
    tasks = json.loads((sweep / "sweep.json").read_text())["tasks"]
    return [{"name": t["name"], "world": t["world"], "kind": t.get("kind") or "world"}
            for t in tasks]


def path_length(trajectory: Path) -> float:
    """Length (m) of the first robot's true path."""
    xy = read_path_csv(trajectory)
    return float(np.hypot(*np.diff(xy, axis=0).T).sum()) if len(xy) > 1 else 0.0


def measure(sweeps: list[Path], quiet: bool = False, cache: Path | None = None) -> list[dict]:
    """One row per finished run: kind, times per 100 m², path ratio, coverage.

    ``cache`` (JSON) keeps each world's coverage path length and floor area
    between invocations: the worlds are deterministic, and planning is the slow part.
    """
    known = json.loads(cache.read_text()) if cache is not None and cache.is_file() else {}
    rows = []
    for sweep in sweeps:
        for task in run_rows(sweep):
            folder = sweep / "runs" / task["name"]
            try:
                run = json.loads((folder / "run.json").read_text())
            except (OSError, ValueError):
                continue
            metrics = run.get("metrics", {})
            if run.get("status") not in ("done", "stopped") or "offline_map" not in metrics:
                continue
            if task["world"] not in known:
                if not quiet:
                    print(f"coverage path of {task['world']}", file=sys.stderr)
                best = coverage_path(load_world(resolve_world(task["world"])))
                known[task["world"]] = {"length": best.length, "area": best.floor_area}
                if cache is not None:
                    cache.write_text(json.dumps(known, indent=1) + "\n")
            length, area = known[task["world"]]["length"], known[task["world"]]["area"]
            coverage = float(metrics["offline_map"].get("free_coverage", 0.0))
            time_s = float(run["sim_time_s"])
            driven = path_length(folder / "trajectory.csv")
            rows.append({"sweep": sweep.name, "run": task["name"], "kind": task["kind"],
                         "floor_m2": round(area, 1), "time_s": round(time_s, 1),
                         "time_per_100m2": round(100 * time_s / area, 1),
                         "time_per_100m2_mapped": round(100 * time_s / max(coverage * area, 1e-9), 1),
                         "driven_m": round(driven, 1), "coverage_path_m": round(length, 1),
                         "path_ratio": round(driven / length, 2) if length else None,
                         "free_coverage": round(coverage, 3)})
    return rows


def table(rows: list[dict]) -> str:
    """Markdown: per sweep and kind, median · worst of each figure."""
    lines = ["| sweep | kind | runs | time / 100 m² (s) | time / 100 m² mapped (s) | "
             "path / coverage path | free coverage |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for sweep in dict.fromkeys(r["sweep"] for r in rows):
        mine = [r for r in rows if r["sweep"] == sweep]
        for kind in ["all"] + sorted({r["kind"] for r in mine}):
            group = [r for r in mine if kind == "all" or r["kind"] == kind]
            t = [r["time_per_100m2"] for r in group]
            tm = [r["time_per_100m2_mapped"] for r in group]
            p = [r["path_ratio"] for r in group if r["path_ratio"] is not None]
            c = [r["free_coverage"] for r in group]
            lines.append(f"| {sweep} | {'**all**' if kind == 'all' else kind} | {len(group)} | "
                         f"{np.median(t):.0f} · {max(t):.0f} | {np.median(tm):.0f} · {max(tm):.0f} | "
                         f"{np.median(p):.2f} · {max(p):.2f} | "
                         f"{np.median(c):.2f} · {min(c):.2f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("sweeps", nargs="+", type=Path, help="semmap sweep output folders")
    parser.add_argument("--json", type=Path, help="write every run's figures here")
    parser.add_argument("--csv", type=Path, help="...or as CSV")
    parser.add_argument("--cache", type=Path, help="JSON file keeping each world's coverage "
                                                   "path between invocations")
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args(argv)
    for sweep in args.sweeps:
        if not (sweep / "sweep.json").is_file():
            print(f"error: {sweep} has no sweep.json: give a folder `semmap sweep --out` wrote.",
                  file=sys.stderr)
            return 2
    rows = measure(args.sweeps, quiet=args.quiet, cache=args.cache)
    if not rows:
        print("error: no finished runs in those sweeps.", file=sys.stderr)
        return 2
    print("each cell: median · worst run (free coverage: median · lowest)\n")
    print(table(rows))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")
    if args.csv:
        with args.csv.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
