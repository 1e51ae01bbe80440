"""Run every benchmark (``make bench``); ``--quick`` shortens them all for a smoke test."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_engine  # noqa: E402
import bench_fuzzy  # noqa: E402
import bench_maps  # noqa: E402
import bench_planner  # noqa: E402
import bench_query  # noqa: E402
import bench_reasoner  # noqa: E402
import bench_sim  # noqa: E402
import object_gate  # noqa: E402
import object_recogniser  # noqa: E402
import sign_detector  # noqa: E402
import sign_reader  # noqa: E402
import bench_sweep  # noqa: E402
import bench_pipeline  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--results", type=Path, default=None,
                        help="folder for the JSON results (default: benchmarks/results)")
    args = parser.parse_args(argv)
    common = ["--quick"] if args.quick else []
    status = 0
    for name, module in (("engine", bench_engine), ("sim", bench_sim), ("fuzzy", bench_fuzzy),
                         ("maps", bench_maps), ("sign_detector", sign_detector),
                         ("sign_reader", sign_reader), ("object_recogniser", object_recogniser),
                         ("object_gate", object_gate),
                         ("reasoner", bench_reasoner), ("planner", bench_planner),
                         ("query", bench_query), ("sweep", bench_sweep),
                         ("pipeline", bench_pipeline)):
        extra = ["--json", str(args.results / f"{name}.json")] if args.results else []
        if name == "engine" and args.quick:
            extra += ["--seconds", "0.01", "--repeats", "1"]
        print(f"\n===== {name} =====")
        code = module.main(common + extra)
        if not args.quick:  # a quick smoke run measures too little to judge a target
            status |= code
    return status


if __name__ == "__main__":
    sys.exit(main())
