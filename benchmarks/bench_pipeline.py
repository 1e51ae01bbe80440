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

``--rounds N`` runs the pipeline N times, each between two reference runs
(the one after a round is the one before the next), and judges the medians.
This machine's speed drifts by 10-20 % within an hour, so a change of a few
per cent needs several rounds; each round's share is taken against the
reference runs beside it, which drift with it.

Usage::

    .venv/bin/python benchmarks/bench_pipeline.py [--quick] [--rounds N] [--json FILE]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
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


def summarise(pipes: list[tuple[dict, float, float]], bares: list[dict]) -> dict:
    """The rounds' figures: each pipeline run (run.json, peak RSS MB, whole-run s) against
    the faster of the reference runs before and after it (``bares`` has one more entry).

    The headline figures are the medians over the rounds (the round with the median share
    gives the profile), the peak RSS the largest; ``rounds`` keeps every round.

    Examples
    --------
    >>> pipe = lambda x: ({"x_real_time": x, "wall_time_s": 100 / x, "ticks": 10,
    ...                    "sim_time_s": 100.0, "profile": [{"node": str(x)}]}, 500.0, 9.0)
    >>> bare = lambda x: {"x_real_time": x}
    >>> s = summarise([pipe(40), pipe(60), pipe(50)], [bare(400), bare(390), bare(500), bare(400)])
    >>> s["share_of_bare"], s["x_real_time"], s["profile"]
    (0.1, 50.0, [{'node': '50'}])
    """
    rounds = []
    for i, (pipe, rss_mb, whole_s) in enumerate(pipes):
        ref = max(float(bares[i]["x_real_time"]), float(bares[i + 1]["x_real_time"]))
        xrt = float(pipe["x_real_time"])
        rounds.append({"x_real_time": xrt, "wall_time_s": float(pipe["wall_time_s"]),
                       "whole_run_s": whole_s, "peak_rss_mb": rss_mb,
                       "bare_x_real_time": ref, "share_of_bare": xrt / ref,
                       "profile": pipe["profile"][:10]})
    order = sorted(range(len(rounds)), key=lambda i: rounds[i]["share_of_bare"])
    middle = rounds[order[(len(order) - 1) // 2]]
    median = {key: statistics.median(r[key] for r in rounds)
              for key in ("x_real_time", "wall_time_s", "whole_run_s", "bare_x_real_time",
                          "share_of_bare")}
    first = pipes[0][0]
    return {"ticks": first["ticks"], "sim_time_s": first["sim_time_s"], **median,
            "peak_rss_mb": max(r["peak_rss_mb"] for r in rounds),
            "profile": middle["profile"],
            "rounds": [{k: v for k, v in r.items() if k != "profile"} for r in rounds]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--rounds", type=int, default=1,
                        help="pipeline runs, each between two reference runs (medians judged)")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    if args.rounds < 1:
        parser.error("--rounds must be at least 1")
    steps = ["--steps", "300"] if args.quick else []
    bare_steps = "1000" if args.quick else "3000"
    with tempfile.TemporaryDirectory(prefix="bench-pipeline-") as tmp:
        tmp = Path(tmp)
        bares = [run(BARE, tmp / "bare0", "--steps", bare_steps)[0]]
        pipes = []
        for i in range(args.rounds):
            pipes.append(run(PIPELINE, tmp / f"pipeline{i}", *steps))
            bares.append(run(BARE, tmp / f"bare{i + 1}", "--steps", bare_steps)[0])
    result = summarise(pipes, bares)
    for i, r in enumerate(result["rounds"]):
        print(f"round {i + 1}: {r['wall_time_s']:.1f} s of ticks, {r['x_real_time']:.1f}x real "
              f"time, reference {r['bare_x_real_time']:.0f}x: {r['share_of_bare']:.1%}; "
              f"whole run {r['whole_run_s']:.1f} s, peak RSS {r['peak_rss_mb']:.0f} MB")
    xrt, share, rss_mb = result["x_real_time"], result["share_of_bare"], result["peak_rss_mb"]
    several = "median of the rounds: " if args.rounds > 1 else ""
    print(f"pipeline ({PIPELINE.relative_to(ROOT)}, {WORLD}, room visits on): {several}"
          f"{result['sim_time_s']:.1f} s simulated in {result['wall_time_s']:.1f} s: "
          f"{xrt:.1f}x real time; peak RSS {rss_mb:.0f} MB")
    print(f"whole run: {result['whole_run_s']:.1f} s ({result['wall_time_s']:.1f} s of ticks, "
          f"{result['whole_run_s'] - result['wall_time_s']:.1f} s of start-up and finishing: "
          f"maps, scores, pictures)")
    print(f"reference (sim2d alone: {BARE.relative_to(ROOT)}, {bare_steps} ticks): "
          + ", ".join(f"{float(b['x_real_time']):.0f}x" for b in bares)
          + " real time (before, between and after the rounds)")
    print("slowest blocks: " + ", ".join(f"{r['node']} {r['total_s']:.1f} s"
                                         for r in result["profile"][:5]))
    if not args.quick:
        print(f"{'PASS' if share >= TARGET_SHARE else 'MISS'} the pipeline runs at "
              f"{share:.1%} of the bare simulator's rate (target >= {TARGET_SHARE:.0%})")
        print(f"{'PASS' if rss_mb <= TARGET_RSS_MB else 'MISS'} peak RSS {rss_mb:.0f} MB "
              f"(target <= {TARGET_RSS_MB:.0f} MB)")
    write_results(args.json, {"world": WORLD, **result, "quick": bool(args.quick)})
    return 0


if __name__ == "__main__":
    sys.exit(main())
