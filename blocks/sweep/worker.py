"""One task of a sweep, as a worker runs it: an ordinary run (the same
:func:`blocks.core.session.run_graph` as ``semmap run``) into the task's folder,
with the sweep's record added to its run.json under ``sweep``.

A run stops early, cleanly, when the sweep is stopped (Ctrl-C) or its time is
up: the blocks still write their outputs, and run.json says ``interrupted``
or ``timeout``. Whatever a run does, the worker returns a
:class:`TaskOutcome`; only a worker that dies leaves the parent to write the
record (:func:`record_failure`).
"""
from __future__ import annotations

import json
import os
import shutil
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable

from blocks.core.atomic import atomic_write_json, atomic_write_text
from blocks.core.errors import SemmapError
from blocks.core.loader import load_graph
from blocks.core.runner import BlockFailure
from blocks.core.session import run_graph

from .tasks import FAILED, SweepConfig, SweepTask, run_dir

__all__ = ["TaskOutcome", "init_pool_worker", "record_failure", "run_task", "run_task_in_pool"]

STOP_CHECK_TICKS = 25  # how often a run looks at the sweep's stop flag and its clock


@dataclass
class TaskOutcome:
    """What became of one task (the full record is the run's run.json)."""

    name: str
    status: str
    error: str | None = None
    task_time_s: float = 0.0

    @property
    def failed(self) -> bool:
        """Whether the run ended badly (``failed`` or ``timeout``; not a Ctrl-C)."""
        return self.status in FAILED

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _sweep_record(task: SweepTask, config: SweepConfig, **more: Any) -> dict[str, Any]:
    return {"task": task.as_dict(), "config": config.identity(), **more}


def run_task(task: SweepTask, config: SweepConfig, root: str | Path,
             should_stop: Callable[[], bool] | None = None,
             attempt: str | None = None) -> TaskOutcome:
    """Run one task into ``root/runs/NAME`` (cleared first) and record how it ended.

    Parameters
    ----------
    task, config
        What to run.
    root : path
        The sweep folder.
    should_stop : callable, optional
        Polled every :data:`STOP_CHECK_TICKS` ticks; when it returns True the
        run ends as ``interrupted``, its outputs written.
    attempt : str, optional
        A token of this try, written into run.json's ``sweep`` record as soon
        as the run starts, so an engine can tell when its task began.

    Returns
    -------
    TaskOutcome
        ``failed`` with the error's one-paragraph message when the graph or
        world cannot be built or a block crashes.
    """
    start = time.perf_counter()
    out = run_dir(root, task)
    if out.exists():  # an earlier try's leftovers must not mix with this run's files
        shutil.rmtree(out)
    timed_out = False

    def watch(tick: int) -> None:
        nonlocal timed_out
        if tick % STOP_CHECK_TICKS:
            return
        if should_stop is not None and should_stop():
            raise KeyboardInterrupt
        if config.timeout_s is not None and time.perf_counter() - start > config.timeout_s:
            timed_out = True
            raise KeyboardInterrupt

    roles = {"world": task.world} if task.world else None
    mark = {"attempt": attempt} if attempt else {}
    try:
        flat = load_graph(config.graph, list(config.sets), roles=roles)
        outcome = run_graph(flat, out, seed=task.seed, steps=config.steps,
                            records=config.records, on_tick=watch,
                            extra={"sweep": _sweep_record(task, config, **mark)})
    except (SemmapError, BlockFailure) as exc:  # nothing ran: the graph or world is bad
        elapsed = time.perf_counter() - start
        if isinstance(exc, BlockFailure):  # a bug in a block's setup: keep its traceback
            out.mkdir(parents=True, exist_ok=True)
            atomic_write_text(out / "error.log", exc.traceback)
        record_failure(root, task, config, "failed", str(exc), elapsed)
        return TaskOutcome(task.name, "failed", str(exc), round(elapsed, 3))
    summary = dict(outcome.summary)
    error = summary.get("error", {}).get("message") if summary.get("error") else None
    if timed_out:
        summary["status"] = "timeout"
        error = (f"timed out after {config.timeout_s:g} s (at {summary['sim_time_s']:.1f} s "
                 "simulated); its outputs up to then are kept")
        summary["error"] = {"message": error}
    elapsed = time.perf_counter() - start
    summary["sweep"] = _sweep_record(task, config, **mark, task_time_s=round(elapsed, 3))
    atomic_write_json(out / "run.json", summary)
    return TaskOutcome(task.name, str(summary["status"]), error, round(elapsed, 3))


def record_failure(root: str | Path, task: SweepTask, config: SweepConfig, status: str,
                   message: str, elapsed: float | None = None) -> None:
    """Mark a task's run.json as ended badly (``failed``, ``timeout``, ``interrupted``),
    keeping what the run wrote; a run that wrote nothing gets a run.json of its own."""
    path = run_dir(root, task) / "run.json"
    try:
        summary = json.loads(path.read_text())
        if not isinstance(summary, dict):
            raise ValueError
    except (OSError, ValueError):
        summary = {"seed": task.seed, "metrics": {}}
    summary["status"] = status
    summary["error"] = {"message": message}
    more = {"task_time_s": round(elapsed, 3)} if elapsed is not None else {}
    summary["sweep"] = _sweep_record(task, config, **more)
    atomic_write_json(path, summary)


# ---- in a local pool's worker process -------------------------------------------------------
# The pool's initializer hands each worker process the sweep's stop flag (pebble
# starts workers with Ctrl-C ignored: the parent raises the flag instead); the
# process runs one task at a time, so one flag per process is all the state there is.
_STOP_FLAG: Any = None


def init_pool_worker(stop_flag: Any, helper_threads: bool = True) -> None:
    """Start a pool worker with the sweep's stop flag (a ``multiprocessing.Event``), and
    without the runs' helper threads (``SEMMAP_THREADS=0``: the camera draws its noise in
    turn) when the sweep's runs keep every core busy already."""
    global _STOP_FLAG
    _STOP_FLAG = stop_flag
    if not helper_threads:
        os.environ["SEMMAP_THREADS"] = "0"


def run_task_in_pool(task: SweepTask, config: SweepConfig, root: str) -> TaskOutcome:
    """:func:`run_task` stopped by the pool's stop flag; not begun once it is raised."""
    flag = _STOP_FLAG
    if flag is not None and flag.is_set():
        return TaskOutcome(task.name, "interrupted", "the sweep stopped before it began")
    return run_task(task, config, root, should_stop=flag.is_set if flag is not None else None)
