"""What a sweep runs: every (world, seed) pair of its specs, each into its own run folder,
and the record in ``DIR/sweep.json`` that lets a later sweep resume it.

A task's folder is ``DIR/runs/WORLD-sSEED`` (``DIR/runs/sSEED`` for a graph
without a world). A task is done when its ``run.json`` says the run finished
(status ``done`` or ``stopped``); anything else (no run.json, ``running``
left by a killed worker, ``interrupted``, ``failed``, ``timeout``) is run
again, failed and timed-out runs only when asked (``--retry-failed``).
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from blocks.core.atomic import atomic_write_json
from blocks.core.errors import SemmapError
from blocks.core.session import FINISHED

__all__ = ["FAILED", "MANIFEST", "SweepConfig", "SweepError", "SweepTask", "load_manifest",
           "manifest_tasks", "needs_run", "plan_tasks", "run_dir", "run_status",
           "save_manifest"]

MANIFEST = "sweep.json"
RUNS = "runs"
#: Statuses of a run that ended badly; re-run only with ``retry_failed``.
FAILED = ("failed", "timeout")


class SweepError(SemmapError):
    """A sweep that cannot start or be reported (bad specs, a folder of another sweep)."""


@dataclass(frozen=True)
class SweepTask:
    """One run of a sweep.

    Attributes
    ----------
    name : str
        The run folder's name: ``WORLD-sSEED``, or ``sSEED`` without a world.
    seed : int
        The run seed (``semmap run --seed``).
    world : str or None
        What ``semmap run --world`` takes (``office``, a path, ``gen:ring:7``).
    world_name : str
        The world's short name (``ring-7``); empty without a world.
    kind : str
        A generated building's layout kind, ``library`` or ``file``; empty
        without a world.
    world_seed : int or None
        A generated building's generator seed.
    """

    name: str
    seed: int
    world: str | None = None
    world_name: str = ""
    kind: str = ""
    world_seed: int | None = None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class SweepConfig:
    """What every run of a sweep shares: the graph and its settings.

    Two sweeps with the same config may share a folder (the second resumes
    or extends the first); a folder holding runs of another config is refused.
    """

    graph: str  # absolute path
    sets: tuple[str, ...] = ()
    steps: int | None = None
    records: tuple[str, ...] = ()
    timeout_s: float | None = None  # per run; None: no limit
    retry_failed: bool = False
    graph_sha256: str = ""  # of the graph file's bytes

    def identity(self) -> dict[str, Any]:
        """What must match for two sweeps to share a folder (an edited graph file is
        another graph; an edited subgraph or block is not seen)."""
        return {"graph": self.graph, "graph_sha256": self.graph_sha256,
                "sets": list(self.sets), "steps": self.steps, "records": list(self.records)}


def plan_tasks(worlds: list[str] | tuple[str, ...], seeds: str) -> list[SweepTask]:
    """Every (world, seed) pair of the specs, worlds first, in the order given.

    Parameters
    ----------
    worlds : list of str
        World specs (``office``, a file, ``gen:KIND:SEEDS``); empty for a
        graph without a world.
    seeds : str
        A seed spec: ``0``, ``0-4``, ``1,3,10-12``.

    Returns
    -------
    list of SweepTask
        Without repeats.

    Raises
    ------
    SweepError
        For a spec that cannot be read (naming it), or one that names nothing.
    """
    from sim2d.worlds.family import expand_worlds, parse_seeds

    seed_list = parse_seeds(seeds, what="--seeds")
    if not worlds:
        return [SweepTask(name=f"s{s}", seed=s) for s in seed_list]
    tasks: dict[str, SweepTask] = {}
    for spec in worlds:
        for ref in expand_worlds(spec):
            world = ref.spec if ref.kind != "file" else str(Path(ref.spec).resolve())
            for s in seed_list:
                task = SweepTask(name=f"{ref.name}-s{s}", seed=s, world=world,
                                 world_name=ref.name, kind=ref.kind, world_seed=ref.seed)
                if task.name in tasks and tasks[task.name].world != task.world:
                    raise SweepError(f"--worlds: two worlds are both named {ref.name!r} "
                                     f"({tasks[task.name].world} and {world})",
                                     field="--worlds",
                                     hint="Run folders are named after the world; rename one "
                                          "of the files.")
                tasks[task.name] = task
    return list(tasks.values())


def run_dir(root: str | Path, task: SweepTask | str) -> Path:
    """The run folder of a task in a sweep folder."""
    name = task if isinstance(task, str) else task.name
    return Path(root) / RUNS / name


def run_status(root: str | Path, task: SweepTask | str) -> str | None:
    """The status in a task's run.json (None when there is none or it cannot be read)."""
    try:
        return str(json.loads((run_dir(root, task) / "run.json").read_text())["status"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def needs_run(root: str | Path, task: SweepTask, *, retry_failed: bool) -> bool:
    """Whether a task must (still) be run: not finished, and not failed unless retrying."""
    status = run_status(root, task)
    if status in FINISHED:
        return False
    return retry_failed or status not in FAILED


def load_manifest(root: str | Path) -> dict[str, Any] | None:
    """A sweep folder's ``sweep.json`` (None if it has none).

    Raises
    ------
    SweepError
        If the file is there but cannot be read.
    """
    path = Path(root) / MANIFEST
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
        if not isinstance(doc, dict) or not isinstance(doc.get("tasks"), list):
            raise ValueError("no task list")
        manifest_tasks(doc)  # every task readable
        return doc
    except (OSError, ValueError, TypeError) as exc:
        raise SweepError(f"cannot read the sweep record: {exc}", file=path,
                         hint="Was it written by `semmap sweep`? Move it away to start over.") \
            from None


def save_manifest(root: str | Path, config: SweepConfig, tasks: list[SweepTask],
                  previous: dict[str, Any] | None,
                  spec: dict[str, Any] | None = None) -> dict[str, Any]:
    """Write ``DIR/sweep.json``: the config, every task ever planned in the folder and the
    specs that planned them (``spec``: this sweep's ``{worlds, seeds}``).

    Raises
    ------
    SweepError
        If ``previous`` (the folder's record) is of another graph or settings.
    """
    if previous is not None:
        old = previous.get("config", {})
        mine = config.identity()
        changed = [k for k in mine if old.get(k) != mine[k]]
        if changed:
            shown = [k for k in changed if k != "graph_sha256"]
            what = ", ".join(shown) if shown else "graph file content (it was edited)"
            raise SweepError(
                f"{root} holds a sweep with another {what}"
                + (f" ({'; '.join(f'{k}: {old.get(k)!r}' for k in shown)})" if shown else ""),
                field="--out", hint="Give a new --out folder, or the same graph file, --set, "
                                    "--steps and --record values to resume it.")
    known = {t["name"]: t for t in (previous or {}).get("tasks", [])}
    known.update({t.name: t.as_dict() for t in tasks})
    specs = list((previous or {}).get("specs", []))
    if spec is not None and spec not in specs:
        specs.append(spec)
    doc = {"config": config.identity(), "specs": specs, "tasks": list(known.values())}
    atomic_write_json(Path(root) / MANIFEST, doc)
    return doc


def manifest_tasks(doc: dict[str, Any]) -> list[SweepTask]:
    """The tasks recorded in a sweep.json document.

    Raises
    ------
    TypeError
        For a task entry that is not a SweepTask's fields.
    """
    return [SweepTask(**t) for t in doc["tasks"]]
