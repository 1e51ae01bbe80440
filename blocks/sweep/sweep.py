"""Run a sweep and report it: the steps ``semmap sweep`` takes, as plain functions.

1. check the graph once, with the settings and the first world, so that a
   mistake is one message before anything runs;
2. plan the tasks, record them in ``DIR/sweep.json`` (refusing a folder that
   holds another graph's runs) and leave out those already finished;
3. run the rest on the engine;
4. rebuild ``results.csv``, ``summary.md`` and ``summary.png`` from every
   run in the folder, also after Ctrl-C.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from blocks.core.atomic import ensure_writable_dir
from blocks.core.errors import SemmapError
from blocks.core.scores import Score

from .results import read_rows, write_results
from .summary import write_summary
from .tasks import (FAILED, SweepConfig, SweepError, SweepTask, load_manifest, manifest_tasks,
                    needs_run, plan_tasks, run_dir, run_status, save_manifest)
from .worker import TaskOutcome

__all__ = ["ENGINES", "Progress", "SweepReport", "report_sweep", "run_sweep"]

ENGINES = ("local", "ray")


class Progress(Protocol):
    """What a sweep tells the person waiting for it."""

    def start(self, total: int, skipped: int) -> None: ...
    def done(self, task: SweepTask, outcome: TaskOutcome) -> None: ...
    def stopping(self, running: int) -> None: ...
    def close(self) -> None: ...


@dataclass
class SweepReport:
    """What a sweep did.

    Attributes
    ----------
    root : Path
        The sweep folder.
    total : int
        Tasks recorded in the folder (this sweep's and earlier ones').
    skipped : int
        This sweep's tasks left out because an earlier sweep ended them.
    skipped_failed : int
        How many of those had failed or timed out (``--retry-failed`` re-runs them).
    outcomes : list of TaskOutcome
        The runs this sweep ran, in the order they ended.
    interrupted : bool
        Stopped by Ctrl-C.
    files : list of Path
        ``results.csv``, ``summary.md`` and (with scores) ``summary.png``.
    """

    root: Path
    total: int = 0
    skipped: int = 0
    skipped_failed: int = 0
    outcomes: list[TaskOutcome] = field(default_factory=list)
    interrupted: bool = False
    files: list[Path] = field(default_factory=list)

    @property
    def failed(self) -> list[TaskOutcome]:
        """This sweep's runs that failed or timed out."""
        return [o for o in self.outcomes if o.failed]


def run_sweep(graph: str | Path, worlds: list[str] | tuple[str, ...], seeds: str,
              out: str | Path, *, sets: list[str] | tuple[str, ...] = (),
              jobs: int | None = None, engine: str = "local", address: str | None = None,
              timeout_s: float | None = None, retry_failed: bool = False,
              steps: int | None = None, records: list[str] | tuple[str, ...] = (),
              progress: Progress | None = None) -> SweepReport:
    """Run ``graph`` on every (world, seed) pair into ``out`` and summarise the folder.

    Parameters
    ----------
    graph : path
        The graph file.
    worlds : list of str
        World specs (``office``, a file, ``gen:KIND:SEEDS``); empty for a
        graph without a world.
    seeds : str
        The run seeds: ``0``, ``0-4``, ``1,3,10-12``.
    out : path
        The sweep folder; a folder of an earlier sweep of the same graph and
        settings is resumed (and may be extended by new worlds and seeds).
    sets : list of str
        ``NODE.PARAM=VALUE`` overrides for every run.
    jobs : int, optional
        Runs at once (default: one per core; with Ray, the cluster's CPUs).
    engine : {'local', 'ray'}
        Where the runs run.
    address : str, optional
        With ``engine='ray'``: an existing cluster to join.
    timeout_s : float, optional
        Wall-clock limit per run, after which it stops and is recorded as
        ``timeout`` (its outputs kept).
    retry_failed : bool
        Also re-run the folder's failed and timed-out runs.
    steps : int, optional
        Ticks per run (default: the graph's).
    records : list of str
        ``node.port`` to probe in every run.
    progress : Progress, optional
        Told of each run as it ends.

    Returns
    -------
    SweepReport

    Raises
    ------
    SemmapError
        For a bad graph, setting, world or seed spec, engine option or folder,
        before anything runs.
    """
    _check_options(engine, address, jobs, timeout_s)
    graph_path = Path(graph)
    tasks = plan_tasks(list(worlds), seeds)
    if not tasks:
        raise SweepError("the sweep has nothing to run", field="--seeds",
                         hint="Give at least one seed (--seeds 0).")
    flat = _check_graph(graph_path, sets, tasks[0].world)
    config = SweepConfig(graph=str(graph_path.resolve()), sets=tuple(sets), steps=steps,
                         records=tuple(records), timeout_s=timeout_s,
                         retry_failed=retry_failed, graph_sha256=_digest(graph_path))
    root = ensure_writable_dir(out, what="--out").resolve()
    manifest = save_manifest(root, config, tasks, load_manifest(root),
                             spec={"worlds": list(worlds), "seeds": seeds})
    todo = [t for t in tasks if needs_run(root, t, retry_failed=retry_failed)]
    report = SweepReport(root, total=len(manifest["tasks"]), skipped=len(tasks) - len(todo),
                         skipped_failed=sum(run_status(root, t) in FAILED for t in tasks
                                            if t not in todo))
    if progress is not None:
        progress.start(len(todo), report.skipped)

    def on_done(task: SweepTask, outcome: TaskOutcome) -> None:
        report.outcomes.append(outcome)
        if progress is not None:
            progress.done(task, outcome)

    stopping = progress.stopping if progress is not None else None
    try:
        if todo and engine == "ray":
            from .ray_engine import run_ray
            report.interrupted = run_ray(todo, config, root, jobs=jobs, address=address,
                                         on_done=on_done, on_stopping=stopping)
        elif todo:
            from .local import run_local
            report.interrupted = run_local(todo, config, root, jobs=jobs or _cores(),
                                           on_done=on_done, on_stopping=stopping)
    finally:
        if progress is not None:
            progress.close()
        report.files = _write_report(root, manifest, flat.scores, flat.name)
    return report


def report_sweep(root: str | Path) -> SweepReport:
    """Rebuild ``results.csv``, ``summary.md`` and ``summary.png`` from a sweep folder's runs.

    Raises
    ------
    SweepError
        If the folder holds no sweep.
    """
    root = Path(root)
    manifest = load_manifest(root)
    if manifest is None:
        raise SweepError(f"{root} holds no sweep (no sweep.json)", field="--report",
                         hint="Give the --out folder of a `semmap sweep`.")
    ensure_writable_dir(root, what="--report")
    tasks = manifest_tasks(manifest)
    scores, name = _recorded_scores(root, manifest, tasks)
    report = SweepReport(root, total=len(tasks))
    report.files = _write_report(root, manifest, scores, name)
    return report


def _check_options(engine: str, address: str | None, jobs: int | None,
                   timeout_s: float | None) -> None:
    if engine not in ENGINES:
        raise SweepError(f"unknown engine {engine!r}", field="--engine",
                         hint=f"Use one of {', '.join(ENGINES)}.")
    if address and engine != "ray":
        raise SweepError("--address joins a Ray cluster, but the engine is local",
                         field="--address", hint="Add --engine ray, or drop --address.")
    if jobs is not None and jobs < 1:
        raise SweepError(f"--jobs must be at least 1, got {jobs}", field="--jobs")
    if timeout_s is not None and not timeout_s > 0:
        raise SweepError(f"--timeout must be a positive number of seconds, got {timeout_s}",
                         field="--timeout")
    if engine == "ray":
        from .ray_engine import require_ray
        require_ray()  # before anything is written


def _check_graph(graph: Path, sets, world: str | None, *, build: bool = True):
    """Load, check and (with ``build``) build the graph as its first run will, so that
    a mistake in a setting or the first world is one message, not a failure per run."""
    from blocks.core.loader import load_graph
    from blocks.core.runner import BlockFailure, Runner
    from blocks.core.validate import check_graph
    flat = load_graph(graph, list(sets), roles={"world": world} if world else None)
    check_graph(flat)
    if build:
        try:
            Runner(flat, profile=False)  # builds every block; writes nothing
        except BlockFailure as exc:
            raise SweepError(f"the graph cannot be built{f' on {world}' if world else ''}: "
                             f"{exc}", file=graph,
                             hint="Check the --set values and the world; `semmap run` with "
                                  "them shows the whole traceback.") from None
    return flat


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else \
        (os.cpu_count() or 1)


def _digest(path: Path) -> str:
    import hashlib
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _recorded_scores(root: Path, manifest: dict[str, Any],
                     tasks: list[SweepTask]) -> tuple[list[Score], str]:
    """The scores the runs were made with (run.json records the graph), or, before any
    run wrote one, those the graph file declares."""
    for task in tasks:
        try:
            recorded = json.loads((run_dir(root, task) / "run.json").read_text())["graph"]
            return [Score.from_dict(s) for s in recorded.get("scores", [])], recorded["name"]
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            continue
    graph = Path(str(manifest.get("config", {}).get("graph", "")))
    try:
        flat = _check_graph(graph, manifest["config"].get("sets", []),
                            tasks[0].world if tasks else None, build=False)
        return flat.scores, flat.name
    except (SemmapError, OSError, KeyError):
        return [], graph.stem


def _write_report(root: Path, manifest: dict[str, Any], scores: list[Score],
                  name: str) -> list[Path]:
    rows = read_rows(root, manifest_tasks(manifest))
    specs = manifest.get("specs", [])
    spec_text = "; ".join((f"{' '.join(s['worlds'])} × " if s["worlds"] else "")
                          + f"seeds {s['seeds']}" for s in specs)
    title = f"Sweep of {name}" + (f": {spec_text}" if spec_text else "")
    not_run = [r["run"] for r in rows if r["status"] == "not run"]
    failed = sum(1 for r in rows if r["status"] in FAILED)
    note = []
    if failed:
        note.append(f"`semmap sweep ... --retry-failed` re-runs the {failed} failed")
    if not_run:
        note.append(f"{len(not_run)} not run yet (rerun the sweep to finish them)")
    return [write_results(root, rows),
            *write_summary(root, rows, scores, title=title, note="; ".join(note))]
