"""The main pipeline's speed and memory, against the bare simulator in the same run.

What is measured
----------------
* **Pipeline**: ``graphs/semantic_mapping.yaml`` on the office world, room visits
  on (as ``make demo`` runs it), seed 0, as its own ``semmap run`` process:
  ×-real-time of its ticks (run.json), and the process's peak resident memory
  (``ru_maxrss`` from ``wait4``), finishing phase included; and the whole
  process's time, what a user waits for (start-up, ticks, and the finishing
  phase: offline map, scores, pictures). run.json's profile gives the slowest
  blocks.
* **Reference**: sim2d alone for one robot through the same engine
  (``graphs/examples/wander.yaml``: the world, 16 sonars, odometry, a drive and
  a few generic blocks) on the same world, 3,000 ticks, run before and after
  the pipeline; the faster of the two is the reference.

Target (issue 19): the pipeline runs at least 15 % of the reference's rate,
and its peak RSS is at most 600 MB. This is a report: the exit status is 0
unless something crashes. ``--quick`` runs 300 ticks of the pipeline, too
few to judge the targets.

Usage::

    .venv/bin/python benchmarks/bench_pipeline.py [--quick] [--json FILE]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_io import write_results  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS_JSON = Path(__file__).resolve().parent / "results" / "pipeline.json"
PIPELINE = ROOT / "graphs" / "semantic_mapping.yaml"
BARE = ROOT / "graphs" / "examples" / "wander.yaml"
WORLD = "office"
TARGET_SHARE = 0.15
TARGET_RSS_MB = 600.0


def run(graph: Path, out: Path, *extra: str) -> tuple[dict, float, float]:
    """``semmap run`` in a process of its own: its run.json, its peak RSS (MB) and how long
    the whole process took (s: start-up, ticks and the finishing phase)."""
    exe = Path(sys.executable).with_name("semmap")
    # stderr to a file, not a pipe: nobody reads a pipe while wait4 waits, and a
    # child writing more than the pipe holds would block for ever
    with tempfile.TemporaryFile() as errors:
        start = time.perf_counter()
        proc = subprocess.Popen([str(exe), "run", str(graph), "--world", WORLD, "--out",
                                 str(out), "-q", *extra], stdout=subprocess.DEVNULL,
                                stderr=errors, env={**os.environ, "CI": "true"})
        _, status, usage = os.wait4(proc.pid, 0)
        elapsed = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            errors.seek(0)
            raise RuntimeError(f"{graph.name} failed: {errors.read().decode()[-2000:]}")
    rss_mb = usage.ru_maxrss / 1024.0  # kB on Linux
    return json.loads((out / "run.json").read_text()), rss_mb, elapsed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    steps = ["--steps", "300"] if args.quick else []
    with tempfile.TemporaryDirectory(prefix="bench-pipeline-") as tmp:
        tmp = Path(tmp)
        before, _, _ = run(BARE, tmp / "bare1", "--steps", "3000")
        pipe, rss_mb, whole_s = run(PIPELINE, tmp / "pipeline", *steps)
        after, _, _ = run(BARE, tmp / "bare2", "--steps", "3000")
    bare_xrt = max(float(before["x_real_time"]), float(after["x_real_time"]))
    xrt = float(pipe["x_real_time"])
    share = xrt / bare_xrt
    print(f"pipeline ({PIPELINE.relative_to(ROOT)}, {WORLD}, room visits on): "
          f"{pipe['sim_time_s']:.1f} s simulated in {pipe['wall_time_s']:.1f} s: "
          f"{xrt:.1f}x real time; peak RSS {rss_mb:.0f} MB")
    print(f"whole run: {whole_s:.1f} s ({pipe['wall_time_s']:.1f} s of ticks, "
          f"{whole_s - pipe['wall_time_s']:.1f} s of start-up and finishing: maps, scores, "
          f"pictures)")
    print(f"reference (sim2d alone: {BARE.relative_to(ROOT)}, 3000 ticks): "
          f"{float(before['x_real_time']):.0f}x and {float(after['x_real_time']):.0f}x real "
          f"time (before and after)")
    print("slowest blocks: " + ", ".join(f"{r['node']} {r['total_s']:.1f} s"
                                         for r in pipe["profile"][:5]))
    if not args.quick:
        print(f"{'PASS' if share >= TARGET_SHARE else 'MISS'} the pipeline runs at "
              f"{share:.1%} of the bare simulator's rate (target >= {TARGET_SHARE:.0%})")
        print(f"{'PASS' if rss_mb <= TARGET_RSS_MB else 'MISS'} peak RSS {rss_mb:.0f} MB "
              f"(target <= {TARGET_RSS_MB:.0f} MB)")
    write_results(args.json, {
        "world": WORLD, "ticks": pipe["ticks"], "sim_time_s": pipe["sim_time_s"],
        "wall_time_s": pipe["wall_time_s"], "x_real_time": xrt, "peak_rss_mb": rss_mb,
        "whole_run_s": whole_s,
        "bare_x_real_time": bare_xrt, "share_of_bare": share,
        "profile": pipe["profile"][:10], "quick": bool(args.quick)})
    return 0


if __name__ == "__main__":
    sys.exit(main())
