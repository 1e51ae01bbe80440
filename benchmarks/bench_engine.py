"""Engine overhead per block call: the lockstep runner against a plain Python loop.

What is measured
----------------
For each scenario graph, the wall time of ``Runner.run(N)`` divided by
``N * block_calls_per_tick`` gives the engine's cost per block call, in µs.
This total includes the blocks' own work (their ``step`` bodies), the
generated tick function (value slots, ``_o.get``, profiling timers) and the
per-tick loop in ``Runner.run``.

To separate the engine's share from the blocks' own cost, the same block
instances (the runner's own objects) are also driven by a hand-written
reference loop: a list of ``(bound method, input slot(s), output slot, port)``
tuples walked in the runner's schedule order, reading and writing a plain list
of values. That loop is the floor for "calling these blocks from CPython"
without an engine, so

* ``overhead = engine - reference`` (µs per call) is what the engine adds, and
* ``ratio = engine / reference`` is how many times the floor it costs.

The reference is a loop, so it pays a little per call for its own dispatch
(unpacking a tuple, choosing the arity, checking for an output) that the
engine's generated straight-line tick function does not; the engine in turn
pays for ``if _o is not None`` and ``_o.get(port, old)`` per output and for
its per-tick loop. The two are of the same size, so with ``profile=False``
the overhead can come out near zero or slightly negative: read that as "no
measurable overhead over calling the blocks by hand", not as a bug.

Both are measured in the same process, interleaved repeat by repeat, because
the machines this runs on are noisy (2 shared cores): the ratio is meant to be
comparable across machines, the absolute µs less so. Every figure is the best
(minimum) of several repeats, each sized to a fixed amount of wall time; the
garbage collector is off while timing (as in ``timeit``). Before timing, the
reference loop is checked to compute exactly the same values as the engine.

The engine is measured with ``profile=True`` (the default: per-block timers)
and ``profile=False``.

What counts as a block call
---------------------------
One block call = one flat node run once in one tick (``len(graph.nodes)``
calls per tick; every node here runs every tick). A delay node (inserted by
the loader for a feedback edge with ``delay:``) counts as ONE block call even
though the schedule calls it twice per tick (``output`` early, ``update``
late); the reference loop makes the same two calls, so both sides divide the
same work by the same count. The number of scheduled method calls per tick is
reported alongside (``method_calls_per_tick``).

Scenarios (YAML generated into a temporary folder at run time)
---------------------------------------------------------------
``chain50``
    A ``constant`` source (value 1.0) then 49 ``scale`` blocks (gain 1.0) in
    series: 50 block calls per tick.
``subgraphs``
    A ``constant`` source then 10 subgraph instances in series, alternating a
    leaky integrator (``scale``, ``scale``, ``arith`` and a feedback edge with
    ``delay: 1, initial: 0.0``, so 4 flat nodes) and a nested two-stage filter
    (a subgraph including the leaky integrator twice, 8 flat nodes):
    1 + 5*4 + 5*8 = 61 block calls per tick, 15 of them delays.

Targets (from the issue)
------------------------
At most 2 µs per block call, engine total (PASS/FAIL lines below); "a static
schedule in CPython can reach about 0.25 µs" per call (printed for context).
This is a report, not a test: the exit status is 0 unless something crashes.
Results are also written as JSON to ``benchmarks/results/engine.json``.

Usage::

    .venv/bin/python benchmarks/run_all.py            # full run (~25 s)
    .venv/bin/python benchmarks/run_all.py --quick    # smoke test (a few seconds)
"""
from __future__ import annotations

import argparse
import datetime as _dt
import gc
import math
import os
import platform
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from blocks.core.loader import load_graph
from blocks.core.model import FlatGraph
from blocks.core.runner import Runner

TARGET_US_PER_CALL = 2.0  # the requirement, engine total per block call
STATIC_SCHEDULE_US_PER_CALL = 0.25  # the "a static schedule in CPython can reach"
FULL = (0.5, 7)  # (seconds per repeat, repeats) of a full run
QUICK = (0.05, 3)  # the same for --quick
sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_io import write_results  # noqa: E402

RESULTS_JSON = Path(__file__).resolve().parent / "results" / "engine.json"

# ---- scenario graphs -------------------------------------------------------------------

CHAIN_LENGTH = 50  # 1 constant + 49 scale blocks

LEAKY_YAML = """\
# Leaky integrator, y[t] = alpha * y[t-1] + (1 - alpha) * x[t]: a feedback edge
# with a one-tick delay (the loader inserts a delay node for it).
name: bench_leaky
params:
  alpha: {default: 0.5, type: float, min: 0.0, max: 1.0}
inputs:
  x: input_gain.x
outputs:
  y: total.y
nodes:
  - {id: input_gain, type: scale, params: {gain: "${1 - alpha}"}}
  - {id: memory_gain, type: scale, params: {gain: "${alpha}"}}
  - {id: total, type: arith, params: {op: add}}
edges:
  - input_gain.y -> total.a
  - memory_gain.y -> total.b
  - {from: total.y, to: memory_gain.x, delay: 1, initial: 0.0}
"""

TWO_STAGE_YAML = """\
# Two leaky integrators in series: a subgraph that includes another.
name: bench_two_stage
params:
  alpha: {default: 0.5, type: float, min: 0.0, max: 1.0}
inputs:
  x: first.x
outputs:
  y: second.y
nodes:
  - {id: first, include: leaky.yaml, params: {alpha: "${alpha}"}}
  - {id: second, include: leaky.yaml, params: {alpha: "${alpha}"}}
edges:
  - first.y -> second.x
"""

SUBGRAPH_INSTANCES = 10  # even indices: leaky integrator; odd: nested two-stage


def chain_yaml(length: int = CHAIN_LENGTH) -> str:
    """A constant followed by ``length - 1`` scale blocks in series."""
    lines = ["name: bench_chain", "dt: 0.1", "nodes:",
             "  - {id: src, type: constant, params: {value: 1.0}}"]
    lines += [f"  - {{id: s{i}, type: scale, params: {{gain: 1.0}}}}" for i in range(1, length)]
    lines.append("edges:")
    previous = "src.value"
    for i in range(1, length):
        lines.append(f"  - {previous} -> s{i}.x")
        previous = f"s{i}.y"
    return "\n".join(lines) + "\n"


def subgraphs_yaml(instances: int = SUBGRAPH_INSTANCES) -> str:
    """A constant followed by ``instances`` subgraph instances in series."""
    lines = ["name: bench_subgraphs", "dt: 0.1", "nodes:",
             "  - {id: src, type: constant, params: {value: 1.0}}"]
    for i in range(instances):
        lib = "lib/leaky.yaml" if i % 2 == 0 else "lib/two_stage.yaml"
        lines.append(f"  - {{id: f{i}, include: {lib}, params: {{alpha: 0.5}}}}")
    lines.append("edges:")
    previous = "src.value"
    for i in range(instances):
        lines.append(f"  - {previous} -> f{i}.x")
        previous = f"f{i}.y"
    return "\n".join(lines) + "\n"


def write_scenarios(folder: Path) -> dict[str, tuple[Path, str]]:
    """Write the scenario graphs into ``folder``; return name -> (path, description)."""
    (folder / "lib").mkdir()
    (folder / "lib" / "leaky.yaml").write_text(LEAKY_YAML)
    (folder / "lib" / "two_stage.yaml").write_text(TWO_STAGE_YAML)
    chain = folder / "chain50.yaml"
    chain.write_text(chain_yaml())
    subgraphs = folder / "subgraphs.yaml"
    subgraphs.write_text(subgraphs_yaml())
    return {
        "chain50": (chain, f"constant + {CHAIN_LENGTH - 1} scale blocks in series"),
        "subgraphs": (subgraphs, f"constant + {SUBGRAPH_INSTANCES} subgraph instances in "
                                 "series (leaky integrators with a delayed feedback edge, "
                                 "every other one a nested two-stage subgraph)"),
    }


# ---- the reference loop ----------------------------------------------------------------

# (bound method, first input slot or -1, second input slot or -1, output slot or -1, port)
RefCall = tuple[Callable[..., Any], int, int, int, str]


def build_reference(runner: Runner) -> tuple[list[RefCall], list[Any], dict[tuple[str, str], int]]:
    """The runner's schedule as a plain call list over the same block instances.

    Returns the call list, a fresh value list and the slot of every output port.
    Supports what the scenarios use: at most two inputs and one output per call.
    """
    graph = runner.graph
    slot: dict[tuple[str, str], int] = {}
    for node in runner.nodes:
        for port in node.outputs:
            slot[(node.path, port)] = len(slot)
    incoming = {(e.dst.node, e.dst.port): (e.src.node, e.src.port) for e in graph.edges}
    plan: list[RefCall] = []
    for task in runner.tasks:
        i = runner.index[task.node]
        node, blk = runner.nodes[i], runner.blocks[i]
        if node.period != 1 or node.triggers:
            raise ValueError(f"{node.path}: the reference loop assumes every node runs every tick")
        args: list[int] = []
        if task.phase != "output":
            # The order the engine passes inputs in (checked against the signature
            # when the block class registered).
            for name in node.cls._input_order:
                args.append(slot[incoming[(node.path, name)]])
        outputs = [] if task.phase == "update" else list(node.outputs)
        if len(args) > 2 or len(outputs) > 1:
            raise ValueError(f"{node.path}: the reference loop handles <= 2 inputs, <= 1 output")
        a, b = (args + [-1, -1])[:2]
        out, port = (slot[(node.path, outputs[0])], outputs[0]) if outputs else (-1, "")
        plan.append((getattr(blk, task.phase), a, b, out, port))
    return plan, [None] * len(slot), slot


def run_reference(plan: list[RefCall], v: list[Any], ticks: int) -> None:
    """Call every block of the schedule ``ticks`` times: no engine, just the calls."""
    for _ in range(ticks):
        for f, a, b, out, port in plan:
            if a < 0:
                o = f()
            elif b < 0:
                o = f(v[a])
            else:
                o = f(v[a], v[b])
            if out >= 0:
                v[out] = o[port]


def check_reference(runner: Runner, plan: list[RefCall], values: list[Any],
                    slot: dict[tuple[str, str], int], ticks: int = 25) -> None:
    """The reference loop must compute exactly what the engine computes."""
    runner.reset()
    runner.run(ticks)
    engine = {key: runner.value(f"{key[0]}.{key[1]}") for key in slot}
    runner.reset()  # resets the (shared) blocks: delay buffers back to their initial value
    values[:] = [None] * len(values)
    run_reference(plan, values, ticks)
    for key, i in slot.items():
        if values[i] != engine[key]:
            raise AssertionError(f"reference loop disagrees with the engine on {key[0]}.{key[1]}"
                                 f" after {ticks} ticks: {values[i]!r} != {engine[key]!r}")
    runner.reset()


# ---- timing ------------------------------------------------------------------------------

@dataclass
class Timing:
    """One measured variant: µs per block call over the repeats."""

    ticks_per_repeat: int
    repeats_us_per_call: list[float] = field(default_factory=list)

    @property
    def best(self) -> float:
        return min(self.repeats_us_per_call)

    @property
    def median(self) -> float:
        return statistics.median(self.repeats_us_per_call)

    def as_dict(self) -> dict[str, Any]:
        return {"us_per_call": round(self.best, 4), "median_us_per_call": round(self.median, 4),
                "ticks_per_repeat": self.ticks_per_repeat,
                "repeats_us_per_call": [round(x, 4) for x in self.repeats_us_per_call]}


def _timed(fn: Callable[[int], Any], ticks: int) -> float:
    """Seconds for ``fn(ticks)``, with the garbage collector off."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        start = time.perf_counter_ns()
        fn(ticks)
        return (time.perf_counter_ns() - start) / 1e9
    finally:
        if enabled:
            gc.enable()


def calibrate(fn: Callable[[int], Any], seconds: float) -> int:
    """Warm ``fn`` up and return a tick count that takes about ``seconds``."""
    ticks, elapsed = 16, 0.0
    while elapsed < min(0.05, seconds / 4):
        ticks *= 2
        elapsed = _timed(fn, ticks)
    return max(100, math.ceil(ticks * seconds / elapsed))


def measure(variants: dict[str, Callable[[int], Any]], calls_per_tick: int, seconds: float,
            repeats: int) -> dict[str, Timing]:
    """Time every variant ``repeats`` times, interleaved so drift hits all alike."""
    timings = {name: Timing(calibrate(fn, seconds)) for name, fn in variants.items()}
    for _ in range(repeats):
        for name, fn in variants.items():
            t = timings[name]
            elapsed = _timed(fn, t.ticks_per_repeat)
            t.repeats_us_per_call.append(elapsed / (t.ticks_per_repeat * calls_per_tick) * 1e6)
    return timings


# ---- one scenario ------------------------------------------------------------------------

ENGINE_VARIANTS = {"profile_on": True, "profile_off": False}


def run_scenario(name: str, path: Path, description: str, seconds: float,
                 repeats: int) -> dict[str, Any]:
    graph: FlatGraph = load_graph(path)
    runners = {key: Runner(graph, seed=0, out_dir=None, profile=profile)
               for key, profile in ENGINE_VARIANTS.items()}
    reference_runner = runners["profile_off"]  # the reference calls these very blocks
    plan, values, slot = build_reference(reference_runner)
    check_reference(reference_runner, plan, values, slot)

    calls_per_tick = len(graph.nodes)
    variants: dict[str, Callable[[int], Any]] = {
        "reference": lambda n: run_reference(plan, values, n)}
    for key, runner in runners.items():
        variants[key] = runner.run
    timings = measure(variants, calls_per_tick, seconds, repeats)

    ref = timings["reference"].best
    engine: dict[str, Any] = {}
    for key in ENGINE_VARIANTS:
        t = timings[key]
        engine[key] = {**t.as_dict(), "overhead_us_per_call": round(t.best - ref, 4),
                       "ratio_to_reference": round(t.best / ref, 3),
                       "meets_target": t.best <= TARGET_US_PER_CALL}
    return {
        "name": name,
        "description": description,
        "block_calls_per_tick": calls_per_tick,
        "method_calls_per_tick": len(reference_runner.tasks),
        "delay_nodes": sum(1 for n in graph.nodes.values() if n.type_name == "delay"),
        "subgraph_instances": len(graph.groups),
        "nested_subgraph_instances": sum(1 for g in graph.groups if "." in g),
        "reference": timings["reference"].as_dict(),
        "engine": engine,
    }


# ---- report ------------------------------------------------------------------------------

def print_scenario(result: dict[str, Any]) -> None:
    print(f"\n[{result['name']}] {result['description']}")
    groups = result["subgraph_instances"]
    nested = result["nested_subgraph_instances"]
    print(f"  {result['block_calls_per_tick']} block calls/tick "
          f"({result['method_calls_per_tick']} method calls: {result['delay_nodes']} delays "
          f"call output+update); {groups} subgraph instances ({groups - nested} top-level, "
          f"{nested} nested)")
    print(f"  {'':22}{'µs/call':>10}{'overhead µs':>14}{'× reference':>14}{'median µs':>12}")
    ref = result["reference"]
    print(f"  {'reference loop':22}{ref['us_per_call']:>10.3f}{'-':>14}{1.0:>14.2f}"
          f"{ref['median_us_per_call']:>12.3f}")
    for key, row in result["engine"].items():
        label = "engine " + key.replace("_", "=")
        print(f"  {label:22}{row['us_per_call']:>10.3f}{row['overhead_us_per_call']:>14.3f}"
              f"{row['ratio_to_reference']:>14.2f}{row['median_us_per_call']:>12.3f}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true",
                        help="short repeats, for a smoke test (numbers are rougher)")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON,
                        help=f"where to write the results (default: {RESULTS_JSON})")
    parser.add_argument("--repeats", type=int, default=None,
                        help=f"repeats per variant (default: {FULL[1]}, --quick: {QUICK[1]})")
    parser.add_argument("--seconds", type=float, default=None,
                        help=f"seconds per repeat (default: {FULL[0]}, --quick: {QUICK[0]})")
    args = parser.parse_args(argv)
    seconds, repeats = QUICK if args.quick else FULL
    seconds = args.seconds if args.seconds is not None else seconds
    repeats = args.repeats if args.repeats is not None else repeats
    if seconds <= 0 or repeats < 1:
        parser.error("--seconds must be > 0 and --repeats >= 1")

    started = time.perf_counter()
    print(f"semmap engine overhead per block call ({'quick' if args.quick else 'full'} run)")
    print(f"Python {platform.python_version()} ({platform.python_implementation()}), "
          f"{platform.system()} {platform.machine()}, {os.cpu_count()} CPUs")
    print(f"best of {repeats} interleaved repeats of ~{seconds} s each, gc off while timing")
    with tempfile.TemporaryDirectory(prefix="semmap-bench-") as tmp:
        scenarios = write_scenarios(Path(tmp))
        results = [run_scenario(name, path, description, seconds, repeats)
                   for name, (path, description) in scenarios.items()]
    for result in results:
        print_scenario(result)

    print()
    for result in results:
        for key, row in result["engine"].items():
            verdict = "PASS" if row["meets_target"] else "FAIL"
            print(f"{verdict} {result['name']} engine {key.replace('_', '=')}: "
                  f"{row['us_per_call']:.3f} µs/call (target <= {TARGET_US_PER_CALL} µs/call)")
    if any(row["overhead_us_per_call"] < 0 for r in results for row in r["engine"].values()):
        print("note: a negative overhead means the engine's straight-line tick function beat "
              "the reference loop's own per-call dispatch (see the module docstring)")
    floors = ", ".join(f"{r['reference']['us_per_call']:.3f}" for r in results)
    print(f"note: the issue says a static schedule in CPython can reach about "
          f"{STATIC_SCHEDULE_US_PER_CALL} µs/call; the reference loop (blocks called with no "
          f"engine) measured {floors} µs/call here")

    report = {
        "benchmark": "engine overhead per block call",
        "quick": args.quick,
        "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "implementation": platform.python_implementation(),
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "units": "microseconds per block call (best of repeats)",
        "block_call": "one flat node run once per tick; a delay node's output+update count as one",
        "method": {"repeats": repeats, "seconds_per_repeat": seconds, "timer": "perf_counter_ns",
                   "gc": "disabled while timing", "statistic": "min over repeats",
                   "reference": "same block instances' bound methods called by a plain Python "
                                "loop over (method, input slots, output slot) in schedule order"},
        "targets": {"max_us_per_call": TARGET_US_PER_CALL,
                    "static_schedule_us_per_call": STATIC_SCHEDULE_US_PER_CALL},
        "scenarios": results,
        "wall_time_s": round(time.perf_counter() - started, 2),
    }
    write_results(args.json, report, f" ({report['wall_time_s']} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
