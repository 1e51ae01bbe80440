"""Driving a plan on a map: the pose on the map with Monte Carlo localisation, and without.

`semmap ask --execute` drives a plan with ``graphs/ask.yaml``. The robot's
pose on the map is its odometry corrected by ``maps.amcl`` (particles, the
sonar ring, the simulator's ranger model on the map's walls); with
``--set localise=false`` it is the odometry alone. On each generated
building of a family, the longest plan among the building's own commands
(its ``*.commands.yaml``, planned on the surveyed floor) is driven both ways,
and run.json's ``amcl`` section gives the position error against the true
pose (scoring only) along the way and at the end. Longer drives drift
further, so the longest plan is the telling one.

    python benchmarks/localisation.py --worlds gen:any:1000-1019
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from blocks.core.errors import SemmapError  # noqa: E402
from semantic.query import ask, load_map, parse_now  # noqa: E402
from semantic.query.exam import load_commands  # noqa: E402
from sim2d.worlds.family import expand_worlds, generated_world  # noqa: E402


def longest_plan(world: Path) -> tuple[str, str, float] | None:
    """The building's own command with the longest plan on its surveyed floor: (command,
    now, path length in m)."""
    commands_file = world.with_name(world.stem + ".commands.yaml")
    cases, now = load_commands(commands_file)
    qm = load_map(world)
    best = None
    for case in cases:
        try:
            plan = ask(case.command, qm, now=parse_now(now))
        except SemmapError:  # refusals have no plan to drive
            continue
        length = float(plan.to_dict().get("path_length_m") or 0.0)
        if plan.goals() and (best is None or length > best[2]):
            best = (case.command, now, length)
    return best


def drive(world: Path, command: str, now: str, localise: bool, out: Path) -> dict:
    """One `semmap run graphs/ask.yaml`; run.json's scores of it."""
    args = [sys.executable, "-m", "blocks", "run", str(ROOT / "graphs" / "ask.yaml"),
            "--set", f"world={json.dumps(str(world))}", "--set", f"command={json.dumps(command)}",
            "--set", f"now={json.dumps(now)}", "--set", f"localise={str(localise).lower()}",
            "--out", str(out), "--quiet"]
    subprocess.run(args, check=True, cwd=ROOT, capture_output=True)
    run = json.loads((out / "run.json").read_text())
    m = run["metrics"]
    goals = m.get("goto", {}).get("goals", [])
    return {"error_median_m": m["amcl"]["error_median_m"], "error_max_m": m["amcl"]["error_max_m"],
            "error_final_m": m["amcl"]["error_final_m"],
            "reached": sum(g["status"] == "reached" for g in goals), "goals": len(goals),
            "collisions": m["world"]["collisions"], "wall_s": run["wall_time_s"],
            "sim_s": run["sim_time_s"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", default="gen:any:1000-1019")
    parser.add_argument("--json", type=Path, help="also write every run's scores here")
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for ref in expand_worlds(args.worlds):
            spec = ref.name
            world = generated_world(ref.spec, Path(tmp) / "worlds") \
                if ref.kind not in ("file", "library") else Path(ref.spec)
            best = longest_plan(world)
            if best is None:
                continue
            command, now, length = best
            row = {"world": spec, "command": command, "path_m": round(length, 1)}
            for localise in (True, False):
                t0 = time.perf_counter()
                scores = drive(world, command, now, localise,
                               Path(tmp) / f"{world.stem}-{localise}")
                key = "amcl" if localise else "odometry"
                row[key] = scores
                print(f"{spec} ({length:.0f} m) {key}: error median {scores['error_median_m']:.2f}"
                      f" max {scores['error_max_m']:.2f} final {scores['error_final_m']:.2f} m,"
                      f" {scores['reached']}/{scores['goals']} reached, "
                      f"{scores['collisions']} collisions ({time.perf_counter() - t0:.0f} s)",
                      flush=True)
            rows.append(row)
    print(f"\n{len(rows)} drives, the longest plan of each building "
          f"(median {np.median([r['path_m'] for r in rows]):.0f} m):\n")
    print("| pose | error median (median · worst run) | error max (median · worst) | "
          "final error (median · worst) | goals reached | collisions |")
    print("| --- | --- | --- | --- | --- | --- |")
    for key in ("amcl", "odometry"):
        def stat(name: str) -> str:
            values = [r[key][name] for r in rows]
            return f"{np.median(values):.2f} · {max(values):.2f} m"
        reached = sum(r[key]["reached"] for r in rows)
        goals = sum(r[key]["goals"] for r in rows)
        print(f"| {key} | {stat('error_median_m')} | {stat('error_max_m')} | "
              f"{stat('error_final_m')} | {reached}/{goals} | "
              f"{sum(r[key]['collisions'] for r in rows)} |")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
