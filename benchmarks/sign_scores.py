"""The sign table: on each shipped world with signs, what the main pipeline found and read.

Runs ``semmap run graphs/semantic_mapping.yaml --world W`` (exploration with the
sign seeker) and, as the reference, ``semmap run graphs/mapping.yaml --world W``
(the same exploration without it), and prints a Markdown table (the one in
README.md and docs/signs.md): signs along the explored path, found, read
exactly, position error, false signs, and the time the stops added.

    python benchmarks/sign_scores.py [--worlds office,hospital] [--out runs/sign_scores] [--json F]
        [--set NAME=VALUE ...]  (graph parameters of the main pipeline's runs)
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from results_io import write_results  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORLDS = ("office", "hospital")


def run(graph: str, world: str, out: Path, seed: int, sets: Sequence[str] = ()) -> dict:
    semmap = Path(sys.executable).with_name("semmap")
    subprocess.run([str(semmap), "run", str(ROOT / "graphs" / graph), "--world", world,
                    "--seed", str(seed), "--out", str(out), "--quiet",
                    *(arg for value in sets for arg in ("--set", value))],
                   check=True, stdout=subprocess.DEVNULL)
    return json.loads((out / "run.json").read_text())["metrics"]


def perimeter_end(metrics: dict) -> tuple[float | None, str]:
    """When and why the perimeter phase ended: its loop closed, or the frontier explorer
    took over before it did (e.g. "no new floor" on a second lap the drift kept open)."""
    loop = metrics["follower.loop"]["loop_time_s"]
    if loop is not None:
        return loop, "loop closed"
    explorer = metrics.get("explorer", {})
    return explorer.get("started"), explorer.get("start_reason", "not ended")


def measure(world: str, out: Path, seed: int = 0, sets: Sequence[str] = ()) -> dict:
    """One world's sign figures (see the module docstring); ``sets`` are graph
    parameters (``NAME=VALUE``) of the main pipeline's run."""
    with_signs = run("semantic_mapping.yaml", world, out / f"{world}_signs", seed, sets)
    without = run("mapping.yaml", world, out / f"{world}_nosigns", seed)
    signs, seek = with_signs["signs"], with_signs["seek"]
    t_with, how = perimeter_end(with_signs)
    t_without, _ = perimeter_end(without)
    along = signs.get("signs_along_path", signs["true_signs"])
    return {
        "world": world, "signs_along_path": along, "found": signs["found"],
        "read_exactly": signs["read_exactly"],
        "read_exactly_share": signs["read_exactly"] / along if along else 0.0,
        "position_error_mean_m": signs["position_error_mean"],
        "position_error_max_m": signs["position_error_max"],
        "false_signs": signs["false_positions"] + signs["wrong_text"],
        "stops": seek["stops"], "stopped_time_s": seek["stopped_time_s"],
        "exploration_s": t_with, "perimeter_ended": how,
        "exploration_without_signs_s": t_without,
        "time_added": t_with / t_without - 1.0 if t_with and t_without else float("nan"),
        "detector_false_positives": with_signs["detector"].get("false_positives"),
        "detector_frames": with_signs["detector"]["frames"],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", default=",".join(WORLDS))
    parser.add_argument("--out", type=Path, default=ROOT / "runs/sign_scores")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a graph parameter of the main pipeline's runs (repeatable)")
    args = parser.parse_args(argv)
    rows = []
    print("| world | signs along the path | found | read exactly | position error mean / max "
          "| false signs | stopped | perimeter loop with stops and room visits / without |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for world in args.worlds.split(","):
        r = measure(world, args.out, args.seed, args.set)
        rows.append(r)
        print(f"| {world} | {r['signs_along_path']} | {r['found']} | {r['read_exactly']} "
              f"({100 * r['read_exactly_share']:.0f} %) | {r['position_error_mean_m']:.2f} / "
              f"{r['position_error_max_m']:.2f} m | {r['false_signs']} | {r['stops']} stops, "
              f"{r['stopped_time_s']:.1f} s | {_seconds(r['exploration_s'])} / "
              f"{_seconds(r['exploration_without_signs_s'])} s "
              f"(+{100 * r['time_added']:.0f} %){_why(r['perimeter_ended'])} |",
              flush=True)
    if args.json:
        write_results(args.json, {"worlds": rows})
    return 0


def _seconds(t: float | None) -> str:
    return "-" if t is None else f"{t:.0f}"


def _why(how: str) -> str:
    return "" if how == "loop closed" else f", {how}"


if __name__ == "__main__":
    sys.exit(main())
