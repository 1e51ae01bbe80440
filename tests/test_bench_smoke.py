"""The benchmark scripts still run (their figures are a report, not a test)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from conftest import ROOT


@pytest.mark.slow
def test_benchmarks_quick_run(tmp_path):
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks/run_all.py"), "--quick",
                           "--results", str(tmp_path)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "µs/call" in proc.stdout and "robot steps/s" in proc.stdout
    sim = json.loads((tmp_path / "sim.json").read_text())
    assert [s["robots"] for s in sim["scenarios"]] == [1, 10, 100]
    assert json.loads((tmp_path / "engine.json").read_text())
    fuzzy = json.loads((tmp_path / "fuzzy.json").read_text())
    assert [c["robots"] for c in fuzzy["compiled"]] == [1, 100, 1000]
    maps = json.loads((tmp_path / "maps.json").read_text())
    assert maps["paper_updates_per_s"] > 0 and maps["logodds_updates_per_s"] > 0
    detector = json.loads((tmp_path / "sign_detector.json").read_text())
    reader = json.loads((tmp_path / "sign_reader.json").read_text())
    assert detector and reader
    pipeline = json.loads((tmp_path / "pipeline.json").read_text())
    assert pipeline["x_real_time"] > 0 and pipeline["peak_rss_mb"] > 0
    sweep = json.loads((tmp_path / "sweep.json").read_text())
    assert sweep["sweep_over_plain_loop"] > 0 and sweep["speedup_two_workers"] > 0
    for name in ("object_recogniser", "reasoner", "planner", "query"):
        assert json.loads((tmp_path / f"{name}.json").read_text()), name
    gate = json.loads((tmp_path / "object_gate.json").read_text())
    assert gate["frames_that_differ"] == 0 and gate["frames_with_recognitions"] > 0


def test_the_pipeline_bench_judges_each_round_against_the_references_beside_it():
    import doctest
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_pipeline
    assert doctest.testmod(bench_pipeline).failed == 0

    def pipe(xrt, rss=500.0):
        return ({"x_real_time": xrt, "wall_time_s": 900 / xrt, "ticks": 9000,
                 "sim_time_s": 900.0, "profile": [{"node": f"n{xrt}"}]}, rss, 30.0)

    one = bench_pipeline.summarise([pipe(45)], [{"x_real_time": 380}, {"x_real_time": 400}])
    assert one["share_of_bare"] == 45 / 400 and one["bare_x_real_time"] == 400
    assert len(one["rounds"]) == 1 and "profile" not in one["rounds"][0]
    drift = bench_pipeline.summarise(  # the machine slows down round by round
        [pipe(60, 510), pipe(50, 530), pipe(40, 520)],
        [{"x_real_time": x} for x in (500, 420, 330, 320)])
    assert [round(r["share_of_bare"], 3) for r in drift["rounds"]] == [0.12, 0.119, 0.121]
    assert drift["share_of_bare"] == drift["rounds"][0]["share_of_bare"]
    assert drift["profile"] == [{"node": "n60"}] and drift["peak_rss_mb"] == 530
