"""Sweeps: one graph run over many worlds and seeds, and what came of it.

``semmap sweep GRAPH --worlds SPEC --seeds SPEC --out DIR`` runs every
(world, seed) pair as an ordinary run into ``DIR/runs/WORLD-sSEED/`` on a
local process pool (:mod:`.local`) or a Ray cluster (:mod:`.ray_engine`),
skips the runs an earlier sweep into ``DIR`` finished, and writes
``DIR/results.csv`` (:mod:`.results`) and ``DIR/summary.md`` and
``summary.png`` (:mod:`.summary`) over the scores the graph declares. The
same from Python::

    from blocks.sweep import run_sweep
    report = run_sweep("graphs/semantic_mapping.yaml", ["gen:any:1000-1009"], "0",
                       "runs/eval", jobs=2)

See ``docs/sweep.md``.
"""
from .sweep import SweepReport, report_sweep, run_sweep
from .tasks import SweepConfig, SweepError, SweepTask, plan_tasks

__all__ = ["SweepConfig", "SweepError", "SweepReport", "SweepTask", "plan_tasks",
           "report_sweep", "run_sweep"]
