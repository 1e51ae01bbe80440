"""semmap sweep: tasks from specs, results and summaries from run.json, and whole sweeps on
two workers with both engines: resumed after a kill, a failing run recorded without
losing the others, a run past its timeout stopped with its outputs kept."""
from __future__ import annotations

import csv
import dataclasses
import json
import os
import signal
import subprocess
import sys
import re
import time
from pathlib import Path

import pytest

from blocks.core.errors import GraphError
from blocks.core.loader import load_graph
from blocks.core.scores import Score
from blocks.sweep import SweepError, plan_tasks
from blocks.sweep.results import flatten_metrics, run_row
from blocks.sweep.summary import is_yes_no, score_stats, summary_markdown
from blocks.sweep.tasks import SweepConfig, SweepTask, save_manifest

SEMMAP = Path(sys.executable).with_name("semmap")

# A cheap graph with a world: the robot drives at 0.3 m/s, turning at random.
TINY = """
    name: tiny
    steps: 60
    params:
      world: {default: corridor, type: str, doc: the world}
    scores:
      - {name: collisions, metric: world.collisions, better: lower}
      - {metric: x_real_time, better: higher}
    nodes:
      - {id: world, type: sim2d.world, params: {world: "${world}"}}
      - {id: sonar, type: sim2d.sonar}
      - {id: drive, type: sim2d.drive}
      - {id: v, type: constant, params: {value: 0.3}}
      - {id: w, type: noise, params: {std: 0.5}}
    edges:
      - world.sim -> sonar.sim
      - world.sim -> drive.sim
      - v.value -> drive.v
      - w.value -> drive.w
"""


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """Generated worlds in a folder of the tests' own, shared by the workers (environment)."""
    folder = tmp_path_factory.mktemp("cache")
    old = os.environ.get("SEMMAP_CACHE")
    os.environ["SEMMAP_CACHE"] = str(folder)
    yield folder
    if old is None:
        os.environ.pop("SEMMAP_CACHE", None)
    else:
        os.environ["SEMMAP_CACHE"] = old


@pytest.fixture
def tiny(write):
    return write("tiny.yaml", TINY)


def sweep(*args, timeout=300, env=None):
    """``semmap sweep ARGS`` in a process of its own (it starts worker processes)."""
    proc = subprocess.run([str(SEMMAP), "sweep", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout, env={**os.environ, "CI": "true",
                                                           **(env or {})})
    assert "Traceback" not in proc.stderr, proc.stderr
    return proc


def rows(folder):
    with open(folder / "results.csv", newline="") as fh:
        return {r["run"]: r for r in csv.DictReader(fh)}


def run_json(folder, name):
    return json.loads((folder / "runs" / name / "run.json").read_text())


# ---- plans ----------------------------------------------------------------------------------
def test_every_world_goes_with_every_seed_in_the_order_given():
    tasks = plan_tasks(["gen:any:5-6", "corridor"], "0,2")
    assert [t.name for t in tasks] == ["office-5-s0", "office-5-s2", "ring-6-s0", "ring-6-s2",
                                       "corridor-s0", "corridor-s2"]
    assert tasks[2].world == "gen:ring:6" and tasks[2].kind == "ring"
    assert tasks[2].world_seed == 6 and tasks[2].seed == 0
    assert tasks[4].kind == "library" and tasks[4].world_seed is None


def test_a_graph_without_a_world_sweeps_its_seeds():
    assert [(t.name, t.seed, t.world) for t in plan_tasks([], "3-4")] == [("s3", 3, None),
                                                                         ("s4", 4, None)]


def test_a_world_file_is_named_by_its_stem_and_kept_absolute(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "floors").mkdir()
    (tmp_path / "floors" / "mine.yaml").write_text("image: x.png\n")
    task, = plan_tasks(["floors/mine.yaml"], "1")
    assert task.name == "mine-s1" and task.kind == "file"
    assert task.world == str(tmp_path / "floors" / "mine.yaml")


@pytest.mark.parametrize("worlds, seeds, message", [
    (["gen:tower:1"], "0", "no building kind 'tower'"),
    (["offce"], "0", "Did you mean 'office'"),
    ([], "3-1", "runs backwards"),
    ([], "x", "cannot read 'x'"),
])
def test_bad_specs_are_refused_by_name(worlds, seeds, message):
    with pytest.raises(Exception, match=message):
        plan_tasks(worlds, seeds)


def test_a_folder_of_another_graph_is_refused(tmp_path):
    task = [SweepTask("s0", 0)]
    first = save_manifest(tmp_path, SweepConfig("/g/a.yaml"), task, None)
    save_manifest(tmp_path, SweepConfig("/g/a.yaml", timeout_s=5), task, first)  # same sweep
    with pytest.raises(SweepError, match="another graph, sets"):
        save_manifest(tmp_path, SweepConfig("/g/b.yaml", sets=("a.b=1",)), task, first)


# ---- scores, rows, summaries ------------------------------------------------------------------
def test_a_graph_declares_its_scores(write):
    path = write("g.yaml", TINY)
    scores = load_graph(path).scores
    assert scores == [Score("collisions", "world.collisions", "lower"),
                      Score("x_real_time", "x_real_time", "higher")]


@pytest.mark.parametrize("entry, message", [
    ("{metric: world.collisions, better: up}", "better must be higher or lower"),
    ("{metric: wrold.collisions, better: lower}", "names no node of the graph"),
    ("{metric: world.collisions, better: lower, weight: 2}", "unknown score field 'weight'"),
    ("{better: lower}", "needs a metric"),
])
def test_a_bad_score_is_a_graph_error_with_its_line(write, entry, message):
    text = TINY.replace("      - {metric: x_real_time, better: higher}", f"      - {entry}")
    path = write("g.yaml", text)
    with pytest.raises(GraphError, match=message) as info:
        load_graph(path)
    assert info.value.line == 7  # the entry's own line


def test_a_row_holds_the_task_the_ending_and_every_scalar_metric():
    task = SweepTask("ring-6-s2", 2, "gen:ring:6", "ring-6", "ring", 6)
    summary = {"status": "timeout", "error": {"message": "timed out\nmore"}, "wall_time_s": 3.5,
               "x_real_time": 10.0, "sim_time_s": 35.0, "ticks": 350,
               "sweep": {"task_time_s": 4.0},
               "metrics": {"signs": {"recall": 0.5, "rooms": [1, 2]},
                           "follower.loop": {"loop_closed": False}}}
    row = run_row(task, summary)
    assert row["kind"] == "ring" and row["world_seed"] == 6 and row["seed"] == 2
    assert row["status"] == "timeout" and row["error"] == "timed out"
    assert row["task_time_s"] == 4.0 and row["signs.recall"] == 0.5
    assert row["follower.loop.loop_closed"] == 0 and "signs.rooms" not in row
    assert run_row(task, None)["status"] == "not run"


def test_flatten_keeps_numbers_only():
    assert flatten_metrics({"a": {"b": {"c": 1.5, "d": float("nan"), "e": None, "f": "x"}},
                            "g": True}) == {"a.b.c": 1.5, "g": 1}


def test_the_worst_runs_lie_on_the_bad_side_of_each_score():
    data = [{"run": f"r{i}", "m": v} for i, v in enumerate([5, 1, 9, 3, 7, 2, 8, 4, 6, 0])]
    data.append({"run": "none", "m": ""})  # a run without the metric does not count
    up = score_stats(data, Score("m", "m", "higher"))
    down = score_stats(data, Score("m", "m", "lower"))
    assert up.runs == 10 and up.median == 4.5 and up.min == 0 and up.max == 9
    assert up.p10 == pytest.approx(0.9) and up.p90 == pytest.approx(8.1)
    assert up.bad_tail == up.p10 and down.bad_tail == down.p90
    assert up.worst == [("r9", 0.0), ("r1", 1.0), ("r5", 2.0)]
    assert down.worst == [("r2", 9.0), ("r6", 8.0), ("r4", 7.0)]


def test_the_summary_has_a_table_per_kind_and_names_the_unfinished():
    data = [{"run": "ring-1-s0", "kind": "ring", "status": "done", "m": 0.9},
            {"run": "ring-2-s0", "kind": "ring", "status": "timeout", "m": 0.2},
            {"run": "ring-3-s0", "kind": "ring", "status": "interrupted", "m": 0.0},
            {"run": "hall-3-s0", "kind": "hall", "status": "failed", "error": "bad | world"}]
    text = summary_markdown(data, [Score("coverage", "m", "higher")], title="T")
    assert "4 runs: 1 done, 1 failed, 1 interrupted, 1 timeout." in text
    assert "| ring | 2 | 0.55 · 0.27 · 0.2 |" in text  # median · p10 · worst; not interrupted
    assert "| hall | 0 | – · – · – |" in text
    assert "ring-2-s0 (0.2), ring-1-s0 (0.9)" in text
    assert "| hall-3-s0 | failed | bad \\| world |" in text
    assert "| ring-3-s0 | interrupted |" in text


def test_a_flag_is_a_share_of_runs_and_a_count_of_zeros_and_ones_is_not():
    """False signs were 0 or 1 in every run of a sweep, and the summary gave them as
    '50% of runs'; only what run.json holds as a boolean is a yes/no score."""
    task = SweepTask("ring-1-s0", 0, "gen:ring:1", "ring-1", "ring", 1)
    rows = [run_row(dataclasses.replace(task, name=f"ring-{i}-s0"),
                    {"status": "done", "metrics": {"signs": {"false_signs": i % 2},
                                                   "loop": {"closed": bool(i % 2)}}})
            for i in range(4)]
    assert is_yes_no(rows, "loop.closed") and not is_yes_no(rows, "signs.false_signs")
    text = summary_markdown(rows, [Score("false signs", "signs.false_signs", "lower"),
                                   Score("loop closed", "loop.closed", "higher")], title="T")
    assert "| ring | 4 | 0.5 · 1 · 1 | 50% of runs |" in text


# ---- whole sweeps -------------------------------------------------------------------------------
def test_a_sweep_on_two_workers_runs_every_pair_as_an_ordinary_run(tiny, tmp_path, cache, cli):
    out = tmp_path / "sweep"
    proc = sweep(tiny, "--worlds", "gen:any:0-2", "--seeds", "0-1", "--out", out, "-j", "2")
    assert proc.returncode == 0, proc.stderr
    table = rows(out)
    assert sorted(table) == sorted(f"{w}-s{s}" for w in ("office-0", "ring-1", "hospital-2")
                                   for s in (0, 1))
    assert {r["status"] for r in table.values()} == {"done"}
    assert table["ring-1-s1"]["kind"] == "ring" and table["ring-1-s1"]["seed"] == "1"
    assert float(table["ring-1-s1"]["task_time_s"]) > 0 and "world.collisions" in table["ring-1-s1"]
    summary = (out / "summary.md").read_text()
    assert "## collisions" in summary and "| ring | 2 |" in summary
    assert (out / "summary.png").read_bytes()[:4] == b"\x89PNG"
    # the same pair run alone by `semmap run` gives the same trajectory, byte for byte
    assert cli("run", tiny, "--world", "gen:ring:1", "--seed", "1", "--out", tmp_path / "alone",
               "-q").code == 0
    alone = (tmp_path / "alone" / "trajectory.csv").read_bytes()
    assert (out / "runs" / "ring-1-s1" / "trajectory.csv").read_bytes() == alone
    assert run_json(out, "ring-1-s1")["sweep"]["task"]["world"] == "gen:ring:1"
    # a second sweep into the folder runs nothing and changes no run
    before = {p: p.stat().st_mtime_ns for p in out.glob("runs/*/run.json")}
    again = sweep(tiny, "--worlds", "gen:any:0-2", "--seeds", "0-1", "--out", out, "-j", "2")
    assert again.returncode == 0 and "0 run now, 6 ended earlier," in again.stderr
    assert {p: p.stat().st_mtime_ns for p in out.glob("runs/*/run.json")} == before
    # --report rebuilds the summary from the runs alone
    (out / "summary.md").unlink()
    assert sweep("--report", out).returncode == 0 and (out / "summary.md").read_text() == summary


def test_a_failing_run_is_recorded_and_the_others_finish(tiny, tmp_path, cache):
    broken = tmp_path / "broken.yaml"
    broken.write_text("image: missing.png\nresolution: 0.05\norigin: [0, 0, 0]\n"
                      "start: [1, 1, 0]\n")
    out = tmp_path / "sweep"
    proc = sweep(tiny, "--worlds", "corridor", "--worlds", broken, "--worlds", "gen:any:1",
                 "--seeds", "0", "--out", out, "-j", "2")
    assert proc.returncode == 0, proc.stderr
    table = rows(out)
    assert table["corridor-s0"]["status"] == "done" and table["ring-1-s0"]["status"] == "done"
    assert table["broken-s0"]["status"] == "failed"
    assert "missing.png" in table["broken-s0"]["error"]
    assert "broken-s0: failed" in proc.stderr
    assert "| broken-s0 | failed |" in (out / "summary.md").read_text()
    # a later sweep leaves the failure alone unless asked to retry it
    assert "0 run now, 3 ended earlier (1 of them failed" in sweep(
        tiny, "--worlds", "corridor", "--worlds", broken, "--worlds", "gen:any:1",
        "--out", out).stderr
    retried = sweep(tiny, "--worlds", "corridor", "--worlds", broken, "--worlds", "gen:any:1",
                    "--out", out, "--retry-failed")
    assert "1 run now" in retried.stderr


def test_a_run_past_its_timeout_stops_with_its_outputs_kept(tiny, tmp_path, cache):
    out = tmp_path / "sweep"
    proc = sweep(tiny, "--worlds", "corridor", "--seeds", "0", "--steps", "100000000",
                 "--timeout", "2", "--out", out, "-j", "1")
    assert proc.returncode == 0, proc.stderr
    run = run_json(out, "corridor-s0")
    assert run["status"] == "timeout" and "timed out after 2 s" in run["error"]["message"]
    assert 0 < run["ticks"] < 100000000
    assert (out / "runs" / "corridor-s0" / "trajectory.csv").stat().st_size > 0
    assert rows(out)["corridor-s0"]["status"] == "timeout"


# long enough that a sweep stopped when its first run has ended has runs left to do
MIDWAY_STEPS = "6000"


def _start(tiny, out):
    return subprocess.Popen([str(SEMMAP), "sweep", str(tiny), "--worlds", "gen:any:0-5",
                             "--steps", MIDWAY_STEPS, "--out", str(out), "-j", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "CI": "true"}, start_new_session=True,
                            preexec_fn=_hear_ctrl_c)


def _hear_ctrl_c() -> None:
    """In the child: a shell that ran the suite in the background left SIGINT ignored, and
    an ignored signal stays ignored across exec; Ctrl-C is what the test sends."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _wait_for_finished(out, count, proc, deadline=240):
    end = time.time() + deadline
    while time.time() < end and proc.poll() is None:
        statuses = [json.loads(p.read_text()).get("status") for p in out.glob("runs/*/run.json")
                    if p.stat().st_size]
        if sum(s == "done" for s in statuses) >= count:
            return
        time.sleep(0.2)
    raise AssertionError("the sweep finished no runs in time")


@pytest.mark.slow
def test_a_sweep_killed_midway_resumes_without_rerunning_finished_runs(tiny, tmp_path, cache):
    out = tmp_path / "sweep"
    proc = _start(tiny, out)
    _wait_for_finished(out, 1, proc)
    os.killpg(proc.pid, signal.SIGKILL)  # the sweep and its workers, with no chance to clean up
    proc.wait(timeout=30)
    finished = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("runs/*/run.json")
                if json.loads(p.read_text())["status"] == "done"}
    assert 1 <= len(finished) < 6
    resumed = sweep(tiny, "--worlds", "gen:any:0-5", "--steps", MIDWAY_STEPS, "--out", out,
                    "-j", "2")
    assert resumed.returncode == 0, resumed.stderr
    assert f"{6 - len(finished)} run now, {len(finished)} ended earlier," in resumed.stderr
    for name, mtime in finished.items():
        assert (out / "runs" / name / "run.json").stat().st_mtime_ns == mtime
    assert {r["status"] for r in rows(out).values()} == {"done"}


def test_ctrl_c_stops_the_sweep_cleanly_and_keeps_what_finished(tiny, tmp_path, cache):
    out = tmp_path / "sweep"
    proc = _start(tiny, out)
    _wait_for_finished(out, 1, proc)
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C reaches the whole group
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "Traceback" not in stderr, stderr
    assert "Run the same command again to resume it" in stderr
    statuses = {r["run"]: r["status"] for r in rows(out).values()}
    assert "done" in statuses.values() and set(statuses.values()) <= {"done", "interrupted",
                                                                       "not run"}
    for name, status in statuses.items():
        if status == "interrupted":  # stopped at a tick, its outputs written
            run = run_json(out, name)
            assert run["ticks"] > 0 and (out / "runs" / name / "trajectory.csv").exists()


@pytest.mark.slow
def test_the_ray_engine_gives_the_local_engines_results(tiny, tmp_path, cache):
    pytest.importorskip("ray")
    local, ray = tmp_path / "local", tmp_path / "ray"
    spec = ["--worlds", "gen:any:0-1", "--seeds", "0-1", "-j", "2"]
    assert sweep(tiny, *spec, "--out", local).returncode == 0
    proc = sweep(tiny, *spec, "--out", ray, "--engine", "ray", timeout=600)
    assert proc.returncode == 0, proc.stderr

    def scores(folder):
        return {run: {k: v for k, v in row.items() if "time" not in k}
                for run, row in rows(folder).items()}

    assert scores(ray) == scores(local) and len(scores(ray)) == 4


def test_user_mistakes_are_one_paragraph(tiny, tmp_path):
    cases = [
        ((tiny, "--seeds", "0", "--out", tmp_path / "a", "--set", "world.nope=1"), "nope"),
        ((tiny, "--out", tmp_path / "b", "--jobs", "0"), "--jobs must be at least 1"),
        ((tiny, "--out", tmp_path / "c", "--address", "auto"), "Add --engine ray"),
        ((tiny,), "needs an output folder"),
        (("--report", tmp_path), "holds no sweep"),
        ((tiny, "--worlds", tmp_path / "none.yaml", "--out", tmp_path / "d"), "none.yaml"),
        ((tiny, "--worlds", "", "--out", tmp_path / "e"), "empty world spec"),
    ]
    for args, message in cases:
        proc = sweep(*args, timeout=120)
        assert proc.returncode == 2 and message in proc.stderr, (args, proc.stderr)
        assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_the_docs_table_lists_every_option_of_the_command():
    from blocks.sweep.commands import sweep as command
    doc = (Path(__file__).resolve().parents[1] / "docs" / "sweep.md").read_text()
    documented = set(re.findall(r"^\| `(--[a-z-]+)", doc, re.M))
    documented |= set(re.findall(r"`(--[a-z-]+) [A-Z.]+`", doc))
    options = {opt for p in command.params for opt in getattr(p, "opts", [])
               if opt.startswith("--")} - {"--help"}
    assert options <= documented, options - documented


def test_the_pool_has_no_more_workers_than_runs(monkeypatch, tmp_path):
    """A worker with no run to do may still be starting when the last run ends and the
    pool goes; it then printed a traceback (seen when one quick run was left to do)."""
    from concurrent.futures import Future
    from types import SimpleNamespace

    import pebble

    from blocks.sweep.local import run_local

    made = []

    class Pool:
        def __init__(self, max_workers, **_):
            made.append(max_workers)
            self.active = True

        def schedule(self, fn, args, timeout=None):
            future = Future()
            future.set_result(None)
            return future

        def close(self):
            self.active = False

        def join(self):
            pass

    monkeypatch.setattr(pebble, "ProcessPool", Pool)
    monkeypatch.setattr("blocks.sweep.local._outcome", lambda *a: {})
    ended = []
    config = SimpleNamespace(timeout_s=None)
    run_local(["one run"], config, tmp_path, jobs=4, on_done=lambda task, out: ended.append(task))
    assert made == [1] and ended == ["one run"]
