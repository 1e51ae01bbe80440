"""benchmarks/coverage_pair.py: two runs of one world drawn side by side, user errors reported."""
from __future__ import annotations

import importlib.util
import json

from conftest import ROOT

from blocks.maps.mapio import OccupancyMap, occupancy_map_from_world, write_map
from sim2d.world import load_world
from sim2d.worlds import world_path


def _load_script():
    spec = importlib.util.spec_from_file_location("coverage_pair",
                                                  ROOT / "benchmarks" / "coverage_pair.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _fake_run(folder, world_name, occupancy):
    """A run folder as `semmap run` leaves it, as far as the script reads it."""
    (folder / "maps").mkdir(parents=True)
    (folder / "run.json").write_text(json.dumps(
        {"graph": {"params": {"world": {"value": world_name}}}}))
    (folder / "trajectory.csv").write_text("tick,time,robot,x,y,theta\n"
                                           "0,0.0,robot,2.0,8.0,0.0\n1,0.1,robot,3.0,8.0,0.0\n")
    write_map(folder / "maps" / "probabilistic.yaml", occupancy, preview=False)


def test_two_runs_are_drawn_with_their_coverage_and_bad_folders_are_refused(tmp_path, capsys):
    world = load_world(world_path("office"))
    whole = occupancy_map_from_world(world)
    half = whole.occupancy.copy()
    half[:, : half.shape[1] // 2] = 0.5
    _fake_run(tmp_path / "a", "office", whole)
    _fake_run(tmp_path / "b", "office", OccupancyMap(half, whole.resolution, whole.origin))
    script = _load_script()
    out = tmp_path / "pair.png"
    assert script.main([str(tmp_path / "a"), str(tmp_path / "b"), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "free coverage 1.000" in text and out.stat().st_size > 10_000
    coverage_b = float(text.splitlines()[1].rsplit(" ", 1)[1])
    assert 0.2 < coverage_b < 0.8
    assert script.main([str(tmp_path / "a"), str(tmp_path)]) == 2  # not a run folder
    assert "has no run.json" in capsys.readouterr().err
