"""The sweep's overhead per run, and its scaling from one worker to two.

What is measured
----------------
**Overhead.** A trivial graph (``graphs/examples/counter.yaml`` with
``limit=10``: 6 ticks of three generic blocks) is run N times, seeds 0..N-1:

* *plain loop* (the reference): one Python process calls
  :func:`blocks.core.session.run_graph` N times in a row, each into its own
  folder, loading the graph each time, as a user's script would; this is the
  floor for "N ordinary runs";
* *shell loop*: ``semmap run`` N times as separate processes, as a user's
  shell loop would, for context;
* *sweep*: :func:`blocks.sweep.run_sweep` with one worker (local engine),
  which adds starting the worker process, planning, the sweep record, a
  run.json per run, the results table and the summary.

Time per run is the total wall time over N; the overhead ratio is the sweep's
time per run over the plain loop's, measured in the same process one after the
other (these machines are noisy: read the ratio, not the milliseconds).

**Scaling.** A small robot graph (``graphs/examples/wander.yaml`` on the
corridor, 2,000 ticks: about a second of CPU per run) is swept over 8 seeds
with one worker and then with two; the speed-up is the one-worker time over the two-worker time
(2.0 would be perfect on a machine with two free cores).

Usage::

    .venv/bin/python benchmarks/bench_sweep.py [--quick] [--json FILE]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_io import write_results  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS_JSON = Path(__file__).resolve().parent / "results" / "sweep.json"
TRIVIAL = ROOT / "graphs" / "examples" / "counter.yaml"
SCALE_STEPS = 2000
ROBOT = ROOT / "graphs" / "examples" / "wander.yaml"  # a world, sonar, a reactive drive


def plain_loop(graph: Path, seeds: range, out: Path, sets: list[str]) -> float:
    from blocks.core.loader import load_graph
    from blocks.core.session import run_graph
    start = time.perf_counter()
    for seed in seeds:
        run_graph(load_graph(graph, sets), out / f"s{seed}", seed=seed)
    return time.perf_counter() - start


def shell_loop(graph: Path, seeds: range, out: Path, sets: list[str]) -> float:
    exe = Path(sys.executable).with_name("semmap")
    extra = [a for s in sets for a in ("--set", s)]
    start = time.perf_counter()
    for seed in seeds:
        subprocess.run([str(exe), "run", str(graph), "--seed", str(seed), "-q", "--out",
                        str(out / f"s{seed}"), *extra], check=True, capture_output=True,
                       env={**os.environ, "CI": "true"})
    return time.perf_counter() - start


def sweep(graph: Path, worlds: list[str], seeds: range, out: Path, jobs: int,
          sets: list[str], steps: int | None = None) -> float:
    from blocks.sweep import run_sweep
    start = time.perf_counter()
    report = run_sweep(graph, worlds, f"{seeds.start}-{seeds.stop - 1}", out, jobs=jobs,
                       sets=sets, steps=steps)
    elapsed = time.perf_counter() - start
    if report.failed or len(report.outcomes) != len(seeds):
        raise RuntimeError(f"the sweep did not run every run: {report.failed}")
    return elapsed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    n = 3 if args.quick else 40
    scale_runs = 2 if args.quick else 8
    scale_steps = 500 if args.quick else SCALE_STEPS
    sets = ["limit=10"]
    with tempfile.TemporaryDirectory(prefix="bench-sweep-") as tmp:
        tmp = Path(tmp)
        seeds = range(n)
        loop_s = plain_loop(TRIVIAL, seeds, tmp / "loop", sets)
        shell_s = shell_loop(TRIVIAL, seeds, tmp / "shell", sets)
        sweep_s = sweep(TRIVIAL, [], seeds, tmp / "sweep", 1, sets)
        scale_seeds = range(scale_runs)
        one_s = sweep(ROBOT, ["corridor"], scale_seeds, tmp / "one", 1, [], scale_steps)
        two_s = sweep(ROBOT, ["corridor"], scale_seeds, tmp / "two", 2, [], scale_steps)
    per = {"plain_loop": loop_s / n, "shell_loop": shell_s / n, "sweep_1_worker": sweep_s / n}
    print(f"trivial graph ({TRIVIAL.relative_to(ROOT)}, --set limit=10), {n} runs: "
          "time per run")
    for name, seconds in per.items():
        print(f"  {name:<16} {seconds * 1e3:8.1f} ms   {seconds / per['plain_loop']:5.2f} x "
              "the plain loop")
    speedup = one_s / two_s
    print(f"scaling: {scale_runs} runs of {ROBOT.name} ({scale_steps} ticks): 1 worker {one_s:.1f} s, "
          f"2 workers {two_s:.1f} s: speed-up {speedup:.2f} (ideal 2.0 on "
          f"{os.cpu_count()} cores)")
    write_results(args.json, {
        "runs": n, "seconds_per_run": per,
        "sweep_over_plain_loop": per["sweep_1_worker"] / per["plain_loop"],
        "shell_over_plain_loop": per["shell_loop"] / per["plain_loop"],
        "scaling_runs": scale_runs, "one_worker_s": one_s, "two_workers_s": two_s,
        "speedup_two_workers": speedup, "cores": os.cpu_count()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
