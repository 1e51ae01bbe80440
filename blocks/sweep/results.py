"""A sweep's results table: one row per run, read from the runs' own run.json files.

Columns: the run and its world (``run``, ``world``, ``kind``, ``world_seed``,
``seed``), how it ended (``status``, ``error``), its timings (``wall_time_s``
of the ticks, ``task_time_s`` of the whole task with loading and writing,
``x_real_time``, ``sim_time_s``, ``ticks``), then every scalar metric in
run.json's ``metrics``, flattened to ``NODE.KEY[.SUB]`` (booleans as 1 and 0),
in sorted order. Nothing is scored here: the numbers are the blocks' own.
"""
from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any

from blocks.core.atomic import atomic_write_text

from .tasks import SweepTask, run_dir

__all__ = ["FIXED_COLUMNS", "Flag", "flatten_metrics", "read_rows", "run_row", "write_results"]

FIXED_COLUMNS = ("run", "world", "kind", "world_seed", "seed", "status", "error",
                 "wall_time_s", "task_time_s", "x_real_time", "sim_time_s", "ticks")
RESULTS = "results.csv"


class Flag(int):
    """A yes/no metric flattened to 1 or 0, still known for one.

    Why: the summary gives a flag's mean as a share of runs, and a count that
    happens to be 0 or 1 in every run (false signs) is not a flag.
    """


def flatten_metrics(metrics: dict[str, Any], prefix: str = "") -> dict[str, float | int]:
    """The scalar numbers of a nested metrics dict, keyed by their dotted path.

    Lists and strings are left out (per-room tables, messages); booleans
    become 1 and 0 (as :class:`Flag`); NaN and None are left out.

    Examples
    --------
    >>> flatten_metrics({"world": {"collisions": 2, "world": "a.yaml"},
    ...                  "follower.loop": {"loop_closed": True, "path": [1, 2]}})
    {'world.collisions': 2, 'follower.loop.loop_closed': 1}
    """
    flat: dict[str, float | int] = {}
    for key, value in metrics.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            flat.update(flatten_metrics(value, name + "."))
        elif isinstance(value, bool):
            flat[name] = Flag(value)
        elif isinstance(value, (int, float)) and not (isinstance(value, float)
                                                      and math.isnan(value)):
            flat[name] = value
    return flat


def run_row(task: SweepTask, summary: dict[str, Any] | None) -> dict[str, Any]:
    """One run's row: the task, how it ended and its flattened metrics."""
    summary = summary or {}
    error = summary.get("error") or {}
    row: dict[str, Any] = {
        "run": task.name, "world": task.world_name, "kind": task.kind,
        "world_seed": task.world_seed, "seed": task.seed,
        "status": summary.get("status", "not run"),
        "error": _first_line(error.get("message") if isinstance(error, dict) else ""),
        "wall_time_s": summary.get("wall_time_s"),
        "task_time_s": (summary.get("sweep") or {}).get("task_time_s"),
        "x_real_time": summary.get("x_real_time"), "sim_time_s": summary.get("sim_time_s"),
        "ticks": summary.get("ticks"),
    }
    row.update(flatten_metrics(summary.get("metrics") or {}))
    return row


def _first_line(text: str | None) -> str:
    lines = str(text or "").splitlines()
    return lines[0] if lines else ""


def read_rows(root: str | Path, tasks: list[SweepTask]) -> list[dict[str, Any]]:
    """The rows of every task in a sweep folder, in task order (``not run`` where a task
    has no readable run.json)."""
    rows = []
    for task in tasks:
        try:
            summary = json.loads((run_dir(root, task) / "run.json").read_text())
        except (OSError, ValueError):
            summary = None
        rows.append(run_row(task, summary if isinstance(summary, dict) else None))
    return rows


def write_results(root: str | Path, rows: list[dict[str, Any]]) -> Path:
    """Write ``DIR/results.csv`` (atomically): the fixed columns, then every metric."""
    metrics = sorted({k for row in rows for k in row} - set(FIXED_COLUMNS))
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=[*FIXED_COLUMNS, *metrics], restval="",
                            lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    path = Path(root) / RESULTS
    atomic_write_text(path, buf.getvalue())
    return path
