"""The Ray engine: the same tasks as Ray tasks, on a local cluster started for the
sweep or on an existing one (``--address``).

Every task asks for one CPU; at most ``jobs`` run at once (default: the
cluster's CPUs), so each task's clock starts when it does. The workers write
into the sweep folder themselves, so on a cluster of several machines the
folder must be on storage every node can write (a shared file system), as
for Ray Tune's ``storage_path``; on one machine nothing is needed.

Ctrl-C: the first cancels the running tasks gently (Ray raises
``KeyboardInterrupt`` in them: the runs end ``interrupted`` with their
outputs written) and drops the queued ones; a second forces them.
"""
from __future__ import annotations

import logging
import os
import time
from pathlib import Path
from typing import Callable

from .local import OnDone, hard_limit
from .tasks import SweepConfig, SweepError, SweepTask
from .worker import TaskOutcome, record_failure, run_task

__all__ = ["require_ray", "run_ray"]

POLL_S = 0.5  # how often deadlines are checked while waiting


def require_ray():
    """The ``ray`` module.

    Raises
    ------
    SweepError
        When Ray is not installed, saying how to install it.
    """
    try:
        import ray
    except ImportError:
        raise SweepError("--engine ray needs Ray, which is not installed",
                         field="--engine", hint="Install it with pip install 'semmap[ray]', "
                                                "or use --engine local.") from None
    return ray


def run_ray(tasks: list[SweepTask], config: SweepConfig, root: str | Path, *,
            jobs: int | None, address: str | None, on_done: OnDone,
            on_stopping: Callable[[int], None] | None = None) -> bool:
    """Run ``tasks`` as Ray tasks, calling ``on_done`` in the driver as each ends.

    Parameters
    ----------
    tasks, config
        What to run.
    root : path
        The sweep folder (absolute, and shared by every node).
    jobs : int, optional
        Tasks at once (default: the cluster's CPUs); a local cluster is started
        with this many CPUs.
    address : str, optional
        An existing cluster's address (``ray://HOST:10001``, ``HOST:6379`` or
        ``auto``); None starts a local cluster and stops it afterwards.
    on_done, on_stopping
        As :func:`blocks.sweep.local.run_local`.

    Returns
    -------
    bool
        True if the sweep was stopped by Ctrl-C.

    Raises
    ------
    SweepError
        When Ray is not installed or the cluster cannot be reached.
    """
    ray = require_ray()
    started = not ray.is_initialized()
    if started:
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # no reporting home
        try:
            ray.init(address=address, num_cpus=jobs if address is None else None,
                     include_dashboard=False, log_to_driver=False,
                     logging_level=logging.ERROR, configure_logging=True)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise SweepError(f"cannot start or reach the Ray cluster: {exc}", field="--address",
                             hint="Check the address (ray status on the head node prints it), "
                                  "or leave --address out to start a local cluster.") from None
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(run_task)
        slots = jobs or max(1, int(ray.cluster_resources().get("CPU", 1)))
        return _drive(ray, remote, list(tasks), config, str(root), slots, on_done, on_stopping)
    finally:
        if started:
            ray.shutdown()


def _drive(ray, remote, queue: list[SweepTask], config: SweepConfig, root: str, slots: int,
           on_done: OnDone, on_stopping: Callable[[int], None] | None) -> bool:
    """Keep ``slots`` tasks in flight until all have ended; kill those past the hard limit."""
    hard = hard_limit(config.timeout_s)
    inflight: dict = {}  # ObjectRef -> (task, monotonic start)
    try:
        while queue or inflight:
            while queue and len(inflight) < slots:
                task = queue.pop(0)
                inflight[remote.remote(task, config, root)] = (task, time.monotonic())
            ready, _ = ray.wait(list(inflight), num_returns=1, timeout=POLL_S)
            for ref in ready:
                task, _ = inflight.pop(ref)
                on_done(task, _outcome(ray, ref, task, config, root, "failed"))
            if hard is not None:
                now = time.monotonic()
                for ref, (task, began) in list(inflight.items()):
                    if now - began > hard:
                        ray.cancel(ref, force=True)
                        inflight.pop(ref)
                        message = (f"killed after {hard:g} s: it did not stop at its "
                                   f"{config.timeout_s:g} s timeout")
                        record_failure(root, task, config, "timeout", message)
                        on_done(task, TaskOutcome(task.name, "timeout", message))
        return False
    except KeyboardInterrupt:
        if on_stopping is not None:
            on_stopping(len(inflight))
        for ref in inflight:
            ray.cancel(ref)  # KeyboardInterrupt inside the task: the run writes its outputs
        try:
            while inflight:
                ready, _ = ray.wait(list(inflight), num_returns=1, timeout=POLL_S)
                for ref in ready:
                    task, _ = inflight.pop(ref)
                    on_done(task, _outcome(ray, ref, task, config, root, "interrupted"))
        except KeyboardInterrupt:
            for ref, (task, _) in inflight.items():
                ray.cancel(ref, force=True)
                record_failure(root, task, config, "interrupted", "killed by a second Ctrl-C")
        return True


def _outcome(ray, ref, task: SweepTask, config: SweepConfig, root: str,
             status_if_lost: str) -> TaskOutcome:
    """A finished task's outcome; a task Ray lost or cancelled is recorded here."""
    try:
        return ray.get(ref)
    except ray.exceptions.TaskCancelledError:
        message, status = "cancelled by Ctrl-C", "interrupted"
    except ray.exceptions.RayTaskError as exc:  # raised by the task outside the run: a bug
        message, status = str(exc), "failed"
    except ray.exceptions.RayError as exc:  # the worker died, the node was lost, ...
        message, status = f"{type(exc).__name__}: {exc}", status_if_lost
    record_failure(root, task, config, status, message)
    return TaskOutcome(task.name, status, message.splitlines()[0] if message else None)
