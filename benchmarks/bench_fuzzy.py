"""Decision latency of the two-layer fuzzy controller: scikit-fuzzy against the compiled form.

A *decision* is what one robot needs per control tick: layer 1 (front, 64 rules,
and side, 16 rules) then layer 2 (48 rules). The reference is scikit-fuzzy's
``ControlSystemSimulation.compute()`` on the same knowledge bases, measured in
the same run (the issue quotes ~95 ms for one 64-rule controller here). The
compiled controller is timed for one robot and for batches of 100 and 1000.
Targets: >= 1000x faster than scikit-fuzzy for one robot; <= 20 us per robot batched.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from blocks.explore.controller import KnowledgeBases, PerimeterController  # noqa: E402
from blocks.fuzzy.oracle import build_skfuzzy  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_io import write_results  # noqa: E402

RESULTS_JSON = Path(__file__).resolve().parent / "results" / "fuzzy.json"


def skfuzzy_decision_seconds(kbs: KnowledgeBases, groups: np.ndarray, count: int) -> float:
    """Mean seconds per two-layer decision with scikit-fuzzy (scalar inputs, as in a loop)."""
    from skfuzzy import control as ctrl
    systems = {name: build_skfuzzy(getattr(kbs, name)) for name in ("front", "side", "follow")}
    sims = {name: ctrl.ControlSystemSimulation(s, cache=False) for name, s in systems.items()}
    start = time.perf_counter()
    for fr, frlt, frrt, rt, rtfr, drt in groups[:count]:
        front, side, follow = sims["front"], sims["side"], sims["follow"]
        front.input["Fr"], front.input["FrLt"], front.input["FrRt"] = fr, frlt, frrt
        front.compute()
        side.input["Rt"], side.input["RtFr"] = rt, rtfr
        side.compute()
        follow.input["FrontCP"] = front.output["FrontCP"]
        follow.input["RightCP"] = side.output["RightCP"]
        follow.input["dRt"] = drt
        follow.compute()
    return (time.perf_counter() - start) / count


def compiled_seconds(controller: PerimeterController, groups: np.ndarray, batch: int,
                     seconds: float) -> float:
    """Best seconds per robot for batches of ``batch`` decisions."""
    rows = groups[:batch]
    best, start = float("inf"), time.perf_counter()
    calls = 0
    while time.perf_counter() - start < seconds or calls < 5:
        if batch == 1:
            t0 = time.perf_counter()
            for row in groups[:200]:
                controller.decide(row[None])
            best = min(best, (time.perf_counter() - t0) / 200)
        else:
            t0 = time.perf_counter()
            controller.decide(rows)
            best = min(best, (time.perf_counter() - t0) / batch)
        calls += 1
    return best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    kbs = KnowledgeBases.load()
    controller = PerimeterController(kbs, max_speed=1.0, max_turn_rate=1.5)
    rng = np.random.default_rng(0)
    groups = np.column_stack([rng.uniform(0.1, 4.0, (1000, 5)), rng.uniform(-1, 1, 1000)])
    reference = skfuzzy_decision_seconds(kbs, groups, 10 if args.quick else 20)
    print("semmap fuzzy controller: one decision = front (64 rules) + side (16) + follow (48)")
    print(f"reference: scikit-fuzzy ControlSystemSimulation: {reference * 1e3:.1f} ms per decision")
    results = {"skfuzzy_ms_per_decision": round(reference * 1e3, 3), "compiled": []}
    print(f"\n{'robots':>7}{'us per robot':>14}{'x faster than skfuzzy':>24}")
    for batch in (1, 100, 1000):
        per_robot = compiled_seconds(controller, groups, batch, 0.2 if args.quick else 1.5)
        speedup = reference / per_robot
        results["compiled"].append({"robots": batch, "us_per_robot": round(per_robot * 1e6, 2),
                                    "speedup": round(speedup)})
        print(f"{batch:>7}{per_robot * 1e6:>14.1f}{speedup:>24,.0f}")
    single, batched = results["compiled"][0], results["compiled"][-1]
    print(f"\n{'PASS' if single['speedup'] >= 1000 else 'FAIL'} one robot: "
          f"{single['speedup']:,}x faster than scikit-fuzzy (target >= 1000x)")
    print(f"{'PASS' if batched['us_per_robot'] <= 20 else 'FAIL'} 1000 robots: "
          f"{batched['us_per_robot']} us per robot (target <= 20 us)")
    write_results(args.json, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
