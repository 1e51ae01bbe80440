"""The local engine: a pool of worker processes on this machine (pebble's ``ProcessPool``).

Each worker is a fresh interpreter (``spawn``) that runs one task at a time
and keeps its imports between tasks; pebble starts its workers with Ctrl-C
ignored, so only the parent decides how a sweep stops. pebble kills a worker
whose task outlives its hard limit and replaces it, and reports a worker that
died (a crash in native code, the kernel's OOM killer) as its task's failure,
so one bad run never stops the others. At most ``jobs`` tasks are handed to
the pool at a time, so nothing queued inside pebble starts after a stop.

Ctrl-C: the first stops the sweep cleanly (nothing new starts, running runs
end as ``interrupted`` with their outputs written); a second kills the
workers at once.
"""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import FIRST_COMPLETED, CancelledError, TimeoutError, wait
from pathlib import Path
from typing import Callable

from .tasks import SweepConfig, SweepTask
from .worker import TaskOutcome, init_pool_worker, record_failure, run_task_in_pool

__all__ = ["hard_limit", "run_local"]

OnDone = Callable[[SweepTask, TaskOutcome], None]


def hard_limit(timeout_s: float | None) -> float | None:
    """When a run's worker is killed: its timeout plus time to write its outputs.

    A run past its ``--timeout`` stops itself at its next tick and writes its
    outputs, which for a large map takes up to a minute; a worker stuck
    inside one tick (native code) is killed after this.

    Examples
    --------
    >>> hard_limit(30), hard_limit(600), hard_limit(None)
    (90.0, 900.0, None)
    """
    if timeout_s is None:
        return None
    return float(timeout_s) + max(60.0, 0.5 * float(timeout_s))


def run_local(tasks: list[SweepTask], config: SweepConfig, root: str | Path, *, jobs: int,
              on_done: OnDone, on_stopping: Callable[[int], None] | None = None) -> bool:
    """Run ``tasks`` on ``jobs`` worker processes, calling ``on_done`` as each ends.

    Parameters
    ----------
    tasks, config
        What to run.
    root : path
        The sweep folder.
    jobs : int
        Worker processes (>= 1).
    on_done : callable
        ``on_done(task, outcome)``, in the parent, in the order runs end.
    on_stopping : callable, optional
        Called with the number of runs still running after the first Ctrl-C.

    Returns
    -------
    bool
        True if the sweep was stopped by Ctrl-C.
    """
    from pebble import ProcessPool

    # No more workers than runs: a worker with nothing to do may still be starting up
    # (unpickling its pool's semaphore) when the last run ends and the pool is torn
    # down, and it then prints a traceback.
    jobs = max(1, min(jobs, len(tasks)))
    context = multiprocessing.get_context("spawn")
    stop = context.Event()
    hard = hard_limit(config.timeout_s)
    queue = list(tasks)
    inflight: dict = {}  # future -> task

    def finish(done) -> None:
        for future in done:
            task = inflight.pop(future)
            on_done(task, _outcome(future, task, config, root, hard))

    # a run's helper thread (the camera noise) pays only while a core is idle
    helper_threads = jobs < (os.cpu_count() or 1)
    pool = ProcessPool(max_workers=jobs, initializer=init_pool_worker,
                       initargs=(stop, helper_threads), context=context)
    try:
        while queue or inflight:
            while queue and len(inflight) < jobs:
                task = queue.pop(0)
                inflight[pool.schedule(run_task_in_pool, args=(task, config, str(root)),
                                       timeout=hard)] = task
            done, _ = wait(list(inflight), return_when=FIRST_COMPLETED)
            finish(done)
        return False
    except KeyboardInterrupt:
        stop.set()
        if on_stopping is not None:
            on_stopping(len(inflight))
        try:
            while inflight:
                done, _ = wait(list(inflight), return_when=FIRST_COMPLETED)
                finish(done)
        except KeyboardInterrupt:
            pool.stop()  # kills the workers; join() below waits for them
            for task in inflight.values():
                record_failure(root, task, config, "interrupted", "killed by a second Ctrl-C")
        return True
    finally:
        if pool.active:
            pool.close()
        pool.join()


def _outcome(future, task: SweepTask, config: SweepConfig, root: str | Path,
             hard: float | None) -> TaskOutcome:
    """A finished future's outcome; a killed or dead worker's run is recorded here."""
    from pebble import ProcessExpired

    try:
        return future.result()
    except CancelledError:
        message, status = "stopped before it ended", "interrupted"
    except TimeoutError:
        message, status = (f"killed after {hard:g} s: it did not stop at its {config.timeout_s:g} "
                           "s timeout (stuck inside a tick, or writing its outputs)"), "timeout"
    except ProcessExpired as exc:
        message, status = f"its worker process died (exit code {exc.exitcode})", "failed"
    except Exception as exc:  # raised by the task outside the run: a bug, kept with its trace
        trace = getattr(exc, "traceback", "")
        message, status = f"{type(exc).__name__}: {exc}" + (f"\n{trace}" if trace else ""), \
            "failed"
    record_failure(root, task, config, status, message)
    return TaskOutcome(task.name, status, message.split("\n", 1)[0])
