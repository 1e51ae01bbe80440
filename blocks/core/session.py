"""One run of a graph from first tick to last file: what ``semmap run`` and a sweep's
workers both do, so that a run in a sweep is an ordinary run.

``run.json`` is written when the run starts (status ``running``) and again
when it ends, however it ends: ``done`` (its steps ran out), ``stopped`` (a
block asked), ``interrupted`` (Ctrl-C, or the caller's stop), ``failed`` (a
block crashed or met a user error). The blocks' ``finish`` runs in every case,
so outputs produced before a failure are kept.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from .atomic import atomic_write_json, atomic_write_text
from .errors import SemmapError
from .model import FlatGraph
from .runner import BlockFailure, Runner

__all__ = ["FINISHED", "RunOutcome", "run_graph"]

#: Statuses of a run that ended as its graph meant it to.
FINISHED = ("done", "stopped")


@dataclass
class RunOutcome:
    """How a run ended.

    Attributes
    ----------
    out : Path
        The run folder.
    summary : dict
        What was written to ``out/run.json``.
    failure : BlockFailure or SemmapError or None
        Why the run failed, if it did.
    finish_errors : list of str
        Blocks whose ``finish`` failed (their files may be missing).
    runner : Runner
        The runner, for a summary on the terminal.
    """

    out: Path
    summary: dict[str, Any]
    failure: BlockFailure | SemmapError | None
    finish_errors: list[str] = field(default_factory=list)
    runner: Runner | None = None

    @property
    def status(self) -> str:
        return str(self.summary["status"])


def run_graph(flat: FlatGraph, out: str | Path, *, seed: int = 0, steps: int | None = None,
              records: list[str] | tuple[str, ...] = (), strict: bool = False,
              on_tick: Callable[[int], None] | None = None,
              on_ticks_end: Callable[[], None] | None = None,
              extra: dict[str, Any] | None = None) -> RunOutcome:
    """Run a loaded graph into ``out`` and write ``run.json`` however the run ends.

    Parameters
    ----------
    flat : FlatGraph
        The graph (see :func:`blocks.core.loader.load_graph`).
    out : path
        The run folder; created if missing.
    seed : int
        The run seed.
    steps : int, optional
        Ticks to run (default: the graph's own ``steps``; None runs until a
        block asks to stop).
    records : list of str
        ``node.port`` names to probe.
    strict : bool
        Check every value against its port schema.
    on_tick : callable, optional
        Called with the tick count after every tick; raising
        ``KeyboardInterrupt`` from it ends the run as ``interrupted``.
    on_ticks_end : callable, optional
        Called when the last tick has run, before the blocks write their
        outputs (to close a progress bar, say).
    extra : dict, optional
        Added to run.json at the end (a key given here replaces the runner's).

    Returns
    -------
    RunOutcome

    Raises
    ------
    SemmapError, BlockFailure
        When the graph cannot be built (nothing is written then).
    """
    out = Path(out)
    n_steps = steps if steps is not None else flat.steps
    runner = Runner(flat, seed=seed, out_dir=out, records=list(records), strict=strict)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "run.json", runner.summary({"status": "running", **(extra or {})}))
    failure: BlockFailure | SemmapError | None = None
    try:
        runner.run(n_steps, on_tick=on_tick)
    except (BlockFailure, SemmapError) as exc:
        failure = exc
    finally:
        if on_ticks_end is not None:
            on_ticks_end()
        finish_errors = runner.finish()
        ending: dict[str, Any] = {"finish_errors": finish_errors} if finish_errors else {}
        if isinstance(failure, BlockFailure):
            atomic_write_text(out / "error.log", failure.traceback)
            ending["error"] = {"node": failure.node, "tick": failure.tick,
                               "message": str(failure), "traceback": str(out / "error.log")}
        elif failure is not None:
            ending["error"] = {"message": str(failure)}
        summary = runner.summary({**ending, **(extra or {})})
        atomic_write_json(out / "run.json", summary)
    return RunOutcome(out, summary, failure, finish_errors, runner)
