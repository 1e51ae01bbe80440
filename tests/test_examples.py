"""Every graph shipped in graphs/ loads, validates and runs in strict mode."""
from __future__ import annotations

import pytest

from blocks import Runner, load_graph
from conftest import ROOT

GRAPHS = sorted(p for p in (ROOT / "graphs").rglob("*.yaml") if "lib" not in p.parts)


def test_there_are_examples():
    assert len(GRAPHS) >= 4


@pytest.mark.parametrize("path", GRAPHS, ids=lambda p: str(p.relative_to(ROOT)))
def test_example_runs(path, tmp_path):
    graph = load_graph(path)
    runner = Runner(graph, out_dir=tmp_path, strict=True)
    status = runner.run(min(graph.steps or 60, 60))
    assert status in ("done", "stopped")
    assert runner.finish() == []
