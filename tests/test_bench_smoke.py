"""The benchmark script still runs (its figures are a report, not a test)."""
from __future__ import annotations

import json
import subprocess
import sys

from conftest import ROOT


def test_engine_benchmark_quick_run(tmp_path):
    out = tmp_path / "engine.json"
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks/run_all.py"), "--quick",
                           "--json", str(out), "--seconds", "0.01", "--repeats", "1"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "µs/call" in proc.stdout
    data = json.loads(out.read_text())
    assert data
