"""The command line: run outputs, overrides, probes, palette, drawings, debugger."""
from __future__ import annotations

import json

import numpy as np
import pytest

from blocks import load_probes
from conftest import ROOT

EXAMPLES = ROOT / "graphs/examples"


def test_run_writes_run_json_with_provenance(cli, tmp_path):
    out = tmp_path / "out"
    result = cli("run", EXAMPLES / "subgraphs.yaml", "--out", out, "--seed", 4,
                 "--set", "fast.alpha=0.2", "--set", "chain.first.memory_gain.gain=0.5",
                 "--set", "alpha=0.7", "--record", "chain.y", "--record", "gap.y")
    assert result.code == 0, result
    assert f"outputs: {out}/" in result.out
    run = json.loads((out / "run.json").read_text())
    assert run["status"] == "done" and run["seed"] == 4 and run["ticks"] == 50
    assert run["sim_time_s"] == pytest.approx(5.0)
    assert run["wall_time_s"] > 0 and run["x_real_time"] > 0
    nodes = {n["id"]: n for n in run["graph"]["nodes"]}
    assert nodes["fast.memory_gain"]["params"]["gain"]["value"] == pytest.approx(0.2)
    assert nodes["chain.first.memory_gain"]["params"]["gain"] == {"value": 0.5, "from": "--set"}
    assert nodes["slow.memory_gain"]["params"]["gain"]["value"] == pytest.approx(0.7)
    assert run["graph"]["params"]["alpha"] == {"value": 0.7, "from": "--set"}
    assert run["graph"]["subgraphs"]["fast"]["params"]["alpha"] == {"value": 0.2, "from": "--set"}
    assert run["graph"]["subgraphs"]["chain.first"]["type"] == "leaky_integrator.yaml"
    assert {"set": "fast.alpha=0.2", "from": "--set"} in run["graph"]["overrides"]
    assert {r["node"] for r in run["profile"]} >= {"gap", "slow.total"}
    probes = load_probes(out)
    ticks, values = probes["chain.y"]
    assert ticks.tolist() == list(range(50))
    assert values[-1] > values[0] and values.dtype == np.float64


def test_same_seed_gives_identical_outputs(cli, tmp_path):
    """Every output file is byte-identical; run.json differs only in timings."""
    runs = []
    for name in ("a", "b"):
        out = tmp_path / name
        result = cli("run", EXAMPLES / "multirate.yaml", "--out", out, "--seed", 11, "-q",
                     "--record", "sensor.value", "--record", "smooth.y")
        assert result.code == 0, result
        runs.append(out)
    files = sorted(p.relative_to(runs[0]) for p in runs[0].rglob("*") if p.is_file())
    assert len(files) >= 4
    for rel in files:
        if rel.name == "run.json":
            continue
        assert (runs[0] / rel).read_bytes() == (runs[1] / rel).read_bytes(), rel
    timing = {"wall_time_s", "x_real_time", "profile", "command"}
    first, second = (json.loads((r / "run.json").read_text()) for r in runs)
    strip = lambda d: {k: v for k, v in d.items() if k not in timing | {"outputs"}}  # noqa: E731
    assert strip(first) == strip(second)


def test_different_seed_changes_outputs(cli, tmp_path):
    for seed in (1, 2):
        cli("run", EXAMPLES / "feedback.yaml", "--out", tmp_path / str(seed), "--seed", seed, "-q")
    a = np.load(tmp_path / "1" / "walk.npz")["values"]
    b = np.load(tmp_path / "2" / "walk.npz")["values"]
    assert a.shape == b.shape == (200,) and not np.array_equal(a, b)


def test_steps_override_and_stop(cli, tmp_path):
    result = cli("run", EXAMPLES / "counter.yaml", "--out", tmp_path / "c")
    assert result.code == 0 and result.out.startswith("stopped (stop: limit reached)")
    run = json.loads((tmp_path / "c" / "run.json").read_text())
    assert run["status"] == "stopped" and run["stop_reason"] == "stop: limit reached"
    # count = tick, so 2 * tick > 40 first holds at tick 21: ticks 0..21 ran.
    assert run["ticks"] == 22
    result = cli("run", EXAMPLES / "counter.yaml", "--out", tmp_path / "d", "--steps", 5, "-q")
    assert json.loads((tmp_path / "d" / "run.json").read_text())["ticks"] == 5


def test_record_unknown_port_is_a_user_error(cli, tmp_path):
    result = cli("run", EXAMPLES / "counter.yaml", "--out", tmp_path / "x", "--record",
                 "count.cont")
    assert result.code == 2 and "Did you mean 'count'" in result.err
    assert not (tmp_path / "x").exists()


def test_quiet_prints_only_the_output_folder(cli, tmp_path):
    result = cli("run", EXAMPLES / "feedback.yaml", "--out", tmp_path / "q", "--quiet")
    assert result.out.strip() == str(tmp_path / "q") and result.err == ""


def test_blocks_palette_lists_toolboxes(cli):
    result = cli("blocks")
    assert result.code == 0
    for name in ("constant", "delay", "arith", "threshold", "recorder", "logger"):
        assert f"  {name} " in result.out
    assert "sources:" in result.out and "flow:" in result.out


def test_blocks_describe_one(cli):
    result = cli("blocks", "noise")
    assert result.code == 0
    assert "distribution" in result.out and "normal, uniform" in result.out
    data = json.loads(cli("blocks", "scale", "--json").out)
    assert data["outputs"]["y"]["like"] == "x" and data["params"]["gain"]["default"] == 1.0


def test_blocks_unknown_type(cli):
    result = cli("blocks", "scal")
    assert result.code == 2 and "Did you mean 'scale'" in result.err


def test_graph_mermaid_and_dot(cli):
    mermaid = cli("graph", EXAMPLES / "subgraphs.yaml").out
    assert mermaid.startswith("flowchart LR")
    assert 'subgraph n_chain["chain: lib/two_stage.yaml"]' in mermaid
    assert "-.->|\"y→x\"|" in mermaid  # the feedback delay is dashed
    dot = cli("graph", EXAMPLES / "multirate.yaml", "--format", "dot").out
    assert dot.startswith('digraph "multirate"') and "cluster_n_smooth" in dot
    assert "style=dotted" in dot  # trigger links


def test_graph_png(cli, tmp_path):
    path = tmp_path / "g.png"
    result = cli("graph", EXAMPLES / "multirate.yaml", "--format", "png", "-o", path)
    assert result.code == 0
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 5000


def test_debugger_steps_and_prints(cli, monkeypatch):
    commands = iter(["watch count.count", "step 3", "print double.y", "nodes", "bogus",
                     "print nope.y", "quit"])
    monkeypatch.setattr("builtins.input", lambda prompt="": next(commands))
    result = cli("debug", EXAMPLES / "counter.yaml")
    assert result.code == 0
    assert "tick 3 (done)" in result.out and "count.count = 2" in result.out
    assert "double.y = 4.0" in result.out and "unknown command 'bogus'" in result.out
    assert "error: --record 'nope.y': no node 'nope'" in result.out


def test_usage_errors_exit_2(cli):
    assert cli("run").code == 2
    assert cli("frobnicate").code == 2
    result = cli("run", EXAMPLES / "counter.yaml", "--set", "nonsense")
    assert result.code == 2 and "NODE.PARAM=VALUE" in result.err


def test_version(cli):
    result = cli("--version")
    assert result.code == 0 and "semmap" in result.out


def test_check_lists_params_with_sources(cli):
    result = cli("check", EXAMPLES / "subgraphs.yaml", "--params", "--set", "fast.alpha=0.25")
    assert result.code == 0
    assert "alpha = 0.9" in result.out
    assert "fast.memory_gain.gain = 0.25" in result.out
    assert "fast.alpha = 0.25  (--set)" in result.out
    assert "chain.first.alpha = 0.8  (" in result.out  # passed down from chain's default
    assert "chain.first.total.op = 'add'  (" in result.out and "log.format = " in result.out
    assert "  (default)" in result.out


def test_progress_bar_off_in_ci_and_quiet(monkeypatch):
    from blocks.cli import _progress_enabled
    monkeypatch.setattr("sys.stderr.isatty", lambda: True, raising=False)
    monkeypatch.setenv("CI", "true")
    assert not _progress_enabled(False)
    monkeypatch.delenv("CI")
    assert not _progress_enabled(True)
    assert _progress_enabled(False)


def test_progress_bar_shows_ticks_and_real_time_ratio(capsys):
    from blocks.cli import _Bar
    bar = _Bar(total=100, dt=0.1)
    bar.bar.disable = False
    for t in range(1, 101):
        bar.tick(t)
    assert bar.bar.n == 100 and "real time" in bar.bar.postfix
    bar.close()


def test_non_numeric_probe_goes_to_jsonl(write, cli, tmp_path):
    path = write("g.yaml", """
        steps: 3
        nodes:
          - {id: msg, type: constant, params: {value: {text: MAIL ROOM, score: 0.9}}}
          - {id: c, type: counter}
    """)
    out = tmp_path / "out"
    assert cli("run", path, "--out", out, "-q", "--record", "msg.value",
               "--record", "c.count").code == 0
    assert (out / "probes" / "msg.value.jsonl").exists()
    probes = load_probes(out)
    ticks, values = probes["msg.value"]
    assert ticks.tolist() == [0, 1, 2] and values[0] == {"text": "MAIL ROOM", "score": 0.9}
    assert probes["c.count"][1].tolist() == [0, 1, 2]


def test_profile_prints_the_slowest_block_first_and_draws_it(cli, tmp_path):
    out = tmp_path / "run"
    assert cli("run", EXAMPLES / "counter.yaml", "--out", out, "-q").code == 0
    result = cli("profile", out, "--top", "2")
    assert result.code == 0, result.err
    lines = result.out.splitlines()
    assert "sorted by total time" in lines[0] and lines[2].split()[:2] == ["node", "type"]
    totals = [float(line.split()[3]) for line in lines[3:5]]
    assert totals == sorted(totals, reverse=True)
    assert lines[5].startswith("(the other ") and lines[-1] == str(out / "profile.png")
    assert (out / "profile.png").read_bytes()[:4] == b"\x89PNG"


def test_profile_of_a_folder_without_a_run_is_one_paragraph(cli, tmp_path):
    result = cli("profile", tmp_path)
    assert result.code == 2 and "no run.json" in result.err and "Traceback" not in result.err
