"""The Ray engine: the same tasks as Ray tasks, on a local cluster started for the
sweep or on an existing one (``--address``).

Every task asks for one CPU; at most ``jobs`` are in flight at once
(default: the cluster's CPUs). A task's hard time limit counts from when its
run.json shows it running, not from when it was queued. The workers write
into the sweep folder themselves, so on a cluster of several machines the
folder must be on storage every node can write (a shared file system), as
for Ray Tune's ``storage_path``; on one machine nothing is needed.

Ctrl-C: the first cancels the running tasks gently (Ray raises
``KeyboardInterrupt`` in them: the runs end ``interrupted`` with their
outputs written) and drops the queued ones; a second forces them.
"""
from __future__ import annotations

import json
import logging
import os
import time
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from .local import OnDone, hard_limit
from .tasks import SweepConfig, SweepError, SweepTask, run_dir
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


@dataclass
class _InFlight:
    """A submitted task; its clock starts when its run.json carries this try's token."""

    task: SweepTask
    attempt: str
    began: float | None = None  # time.monotonic() when it was seen running


def _drive(ray, remote, queue: list[SweepTask], config: SweepConfig, root: str, slots: int,
           on_done: OnDone, on_stopping: Callable[[int], None] | None) -> bool:
    """Keep ``slots`` tasks in flight until all have ended; kill those past the hard limit."""
    hard = hard_limit(config.timeout_s)
    inflight: dict = {}  # ObjectRef -> _InFlight
    try:
        while queue or inflight:
            while queue and len(inflight) < slots:
                task, attempt = queue.pop(0), uuid.uuid4().hex
                inflight[remote.remote(task, config, root, None, attempt)] = \
                    _InFlight(task, attempt)
            ready, _ = ray.wait(list(inflight), num_returns=1, timeout=POLL_S)
            for ref in ready:
                task = inflight.pop(ref).task
                on_done(task, _outcome(ray, ref, task, config, root, "failed"))
            if hard is not None:
                _kill_overdue(ray, inflight, hard, config, root, on_done)
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
                    task = inflight.pop(ref).task
                    on_done(task, _outcome(ray, ref, task, config, root, "interrupted"))
        except KeyboardInterrupt:
            for ref, entry in inflight.items():
                ray.cancel(ref, force=True)
                record_failure(root, entry.task, config, "interrupted",
                               "killed by a second Ctrl-C")
        return True


def _kill_overdue(ray, inflight: dict, hard: float, config: SweepConfig, root: str,
                  on_done: OnDone) -> None:
    """Start the clocks of tasks seen running; force-cancel those past ``hard`` seconds.

    A task queued in the cluster has not begun, so its clock must not run:
    it starts when the task's run.json shows this try's token (which also
    tells this try from an earlier one's leftover file).
    """
    now = time.monotonic()
    for ref, entry in list(inflight.items()):
        if entry.began is None:
            if _attempt_in_run_json(root, entry.task) == entry.attempt:
                entry.began = now
            continue
        if now - entry.began > hard:
            ray.cancel(ref, force=True)
            inflight.pop(ref)
            message = (f"killed after {hard:g} s: it did not stop at its "
                       f"{config.timeout_s:g} s timeout")
            record_failure(root, entry.task, config, "timeout", message)
            on_done(entry.task, TaskOutcome(entry.task.name, "timeout", message))


def _attempt_in_run_json(root: str, task: SweepTask) -> str | None:
    try:
        doc = json.loads((run_dir(root, task) / "run.json").read_text())
        return doc["sweep"].get("attempt")
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


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
