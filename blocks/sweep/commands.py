"""``semmap sweep``: the command over :func:`blocks.sweep.run_sweep` and
:func:`blocks.sweep.report_sweep`, with its progress display."""
from __future__ import annotations

import sys
import time

import click

from blocks.core.errors import SemmapError

from .sweep import ENGINES, report_sweep, run_sweep
from .tasks import SweepTask
from .worker import TaskOutcome


class SweepInterrupted(SemmapError):
    """Ctrl-C stopped the sweep (exit 130, as for any interrupted command)."""

    exit_code = 130


class _BarProgress:
    """A tqdm bar of runs ended, with the failures counted and named as they happen."""

    def __init__(self) -> None:
        self.bar = None
        self.failed = 0

    def start(self, total: int, skipped: int) -> None:
        from tqdm import tqdm
        if skipped:
            click.echo(f"{skipped} runs ended earlier: skipped", err=True)
        self.bar = tqdm(total=total, unit="run", desc="sweep", dynamic_ncols=True)

    def done(self, task: SweepTask, outcome: TaskOutcome) -> None:
        if outcome.failed:
            self.failed += 1
            self.bar.write(f"{task.name}: {outcome.status}: {outcome.error}")
        self.bar.update(1)
        self.bar.set_postfix_str(f"{self.failed} failed")

    def stopping(self, running: int) -> None:
        self.bar.write(f"stopping: waiting for {running} running runs to write their outputs "
                       "(Ctrl-C again to kill them)")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


class _LineProgress:
    """One line per run ended, for logs (output that is not a terminal)."""

    def __init__(self) -> None:
        self.total = self.count = self.failed = 0
        self.began = time.monotonic()

    def start(self, total: int, skipped: int) -> None:
        self.total = total
        click.echo(f"sweep: {total} runs to run" + (f", {skipped} ended earlier" if skipped
                                                     else ""), err=True)

    def done(self, task: SweepTask, outcome: TaskOutcome) -> None:
        self.count += 1
        if outcome.failed:
            self.failed += 1
        elapsed = time.monotonic() - self.began
        left = elapsed / self.count * (self.total - self.count)
        error = f": {outcome.error}" if outcome.error else ""
        click.echo(f"[{self.count}/{self.total}] {task.name} {outcome.status} in "
                   f"{outcome.task_time_s:.0f} s{error} ({self.failed} failed, about "
                   f"{left / 60:.0f} min left)", err=True)

    def stopping(self, running: int) -> None:
        click.echo(f"stopping: waiting for {running} running runs to write their outputs "
                   "(Ctrl-C again to kill them)", err=True)

    def close(self) -> None:
        pass


def _progress(quiet: bool):
    from blocks.cli import in_ci
    if quiet or in_ci():
        return None
    return _BarProgress() if sys.stderr.isatty() else _LineProgress()


@click.command(name="sweep")
@click.argument("graph", type=click.Path(dir_okay=False), required=False)
@click.option("--worlds", "worlds", multiple=True, metavar="SPEC",
              help="Worlds: a library name, a world file, or gen:KIND:SEEDS (gen:any:0-199). "
                   "Repeatable; leave out for a graph without a world.")
@click.option("--seeds", default="0", show_default=True, metavar="SPEC",
              help="Run seeds: 0, 0-4 or 1,3,10-12.")
@click.option("--set", "sets", multiple=True, metavar="NODE.PARAM=VALUE",
              help="Override a parameter in every run. Repeatable.")
@click.option("--out", "out", type=click.Path(file_okay=False),
              help="The sweep folder (resumed if it holds this sweep already).")
@click.option("--jobs", "-j", type=int, help="Runs at once (default: one per core; Ray: the "
                                             "cluster's CPUs).")
@click.option("--engine", type=click.Choice(ENGINES), default="local", show_default=True,
              help="local: a process pool here; ray: Ray tasks (pip install 'semmap[ray]').")
@click.option("--address", metavar="ADDR", help="With --engine ray: join this cluster "
                                                "instead of starting a local one.")
@click.option("--timeout", "timeout_s", type=float, metavar="S",
              help="Stop a run after S seconds of wall time and record it as timed out.")
@click.option("--retry-failed", is_flag=True, help="Also re-run the folder's failed and "
                                                   "timed-out runs.")
@click.option("--steps", type=click.IntRange(min=0), help="Ticks per run (default: the "
                                                           "graph's).")
@click.option("--record", "records", multiple=True, metavar="NODE.PORT",
              help="Probe a port in every run. Repeatable.")
@click.option("--report", "report_dir", type=click.Path(file_okay=False), metavar="DIR",
              help="Run nothing: rebuild DIR's results.csv and summary from its runs.")
@click.option("--quiet", "-q", is_flag=True, help="No progress; print only the result files.")
def sweep(graph: str | None, worlds: tuple[str, ...], seeds: str, sets: tuple[str, ...],
          out: str | None, jobs: int | None, engine: str, address: str | None,
          timeout_s: float | None, retry_failed: bool, steps: int | None,
          records: tuple[str, ...], report_dir: str | None, quiet: bool) -> None:
    """Run GRAPH on every (world, seed) pair and summarise the scores.

    Each pair runs as an ordinary `semmap run` into OUT/runs/WORLD-sSEED/; runs
    that an earlier sweep into OUT finished are skipped. OUT/results.csv has a
    row per run, OUT/summary.md and summary.png the distribution of each score
    the graph declares, overall and per layout kind, with the worst runs by name.
    """
    if report_dir is not None:
        if graph is not None or worlds or out:
            raise SemmapError("--report rebuilds a finished sweep's summary and runs nothing",
                              field="--report", hint="Give only --report DIR, or drop it to "
                                                     "run a sweep.")
        result = report_sweep(report_dir)
    else:
        if graph is None:
            raise SemmapError("which graph should the sweep run?", field="GRAPH",
                              hint="semmap sweep GRAPH --worlds SPEC --seeds SPEC --out DIR, "
                                   "or semmap sweep --report DIR.")
        if out is None:
            raise SemmapError("a sweep needs an output folder", field="--out",
                              hint="Add --out DIR (rerunning with the same DIR resumes it).")
        result = run_sweep(graph, worlds, seeds, out, sets=sets, jobs=jobs, engine=engine,
                           address=address, timeout_s=timeout_s, retry_failed=retry_failed,
                           steps=steps, records=records, progress=_progress(quiet))
    if not quiet:
        ran = len(result.outcomes)
        earlier = (f" ({result.skipped_failed} of them failed: --retry-failed re-runs them)"
                   if result.skipped_failed else "")
        click.echo(f"{result.total} runs in {result.root}: {ran} run now, {result.skipped} "
                   f"ended earlier{earlier}, {len(result.failed)} failed now", err=True)
        for outcome in result.failed:
            click.echo(f"  {outcome.name}: {outcome.status}: {outcome.error}", err=True)
    for path in result.files:
        click.echo(str(path))
    if result.interrupted:
        raise SweepInterrupted("the sweep was interrupted; finished runs are kept and the "
                               "summary covers them",
                               hint="Run the same command again to resume it.")
