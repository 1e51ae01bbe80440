"""A graph's scores: which of its run.json metrics measure how well it did, and which
way is better.

A graph declares them under ``scores:``; ``semmap sweep`` summarises them
over many runs (median, tails, the worst runs by name), and every run records
them in run.json with the rest of the effective graph::

    scores:
      - {metric: world.collisions, better: lower}
      - {name: free coverage, metric: offline_map.free_coverage, better: higher}

``metric`` names a value in run.json: ``NODE.KEY`` (dotted further into
nested values) under ``metrics``, where ``NODE`` is a node of the graph, or
one of the run's own fields (:data:`RUN_FIELDS`).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Iterable

from .errors import GraphError
from .yamlsrc import line_of

__all__ = ["RUN_FIELDS", "Score", "parse_scores"]

#: run.json fields that are scores of the run itself, not of a node.
RUN_FIELDS = ("x_real_time", "wall_time_s", "sim_time_s", "ticks")
SCORE_KEYS = ("name", "metric", "better", "doc")
BETTER = ("higher", "lower")


@dataclass(frozen=True)
class Score:
    """One declared score.

    Attributes
    ----------
    name : str
        How tables name it (default: the metric).
    metric : str
        The metric's dotted name, as ``results.csv`` names its column.
    better : {'higher', 'lower'}
        Which way is better; the worst runs lie the other way.
    doc : str
        What it measures.
    """

    name: str
    metric: str
    better: str
    doc: str = ""

    def as_dict(self) -> dict[str, str]:
        return asdict(self)

    @classmethod
    def from_dict(cls, item: dict[str, Any]) -> "Score":
        return cls(**{k: str(item[k]) for k in SCORE_KEYS if k in item})


def parse_scores(raw: Any, node_paths: Iterable[str], *, file: str) -> list[Score]:
    """The ``scores:`` list of a graph file, checked against the graph's nodes.

    Parameters
    ----------
    raw : list of mappings, or None
        The parsed ``scores:`` value (with line numbers where the YAML had them).
    node_paths : iterable of str
        The flattened graph's node paths (``follower.loop``).
    file : str
        The graph file, for error messages.

    Returns
    -------
    list of Score

    Raises
    ------
    GraphError
        Naming the line and field of a malformed entry, an unknown direction,
        a repeated name, or a metric that names no node of the graph.
    """
    if raw is None:
        return []
    if not isinstance(raw, list):
        raise GraphError("scores must be a list of {metric, better} entries", file=file,
                         line=line_of(raw), field="scores",
                         hint="For example: scores: [{metric: world.collisions, better: lower}]")
    paths = list(node_paths)
    scores: list[Score] = []
    for item in raw:
        line = line_of(item) or line_of(raw)
        if not isinstance(item, dict):
            raise GraphError(f"a score must be a mapping, got {item!r}", file=file, line=line,
                             field="scores", hint="Write {metric: NODE.KEY, better: higher}.")
        unknown = [k for k in item if k not in SCORE_KEYS]
        if unknown:
            raise GraphError(f"unknown score field {unknown[0]!r}", file=file, line=line,
                             field="scores", hint=f"A score has {', '.join(SCORE_KEYS)}.")
        metric, better = item.get("metric"), item.get("better")
        if not isinstance(metric, str) or not metric:
            raise GraphError("a score needs a metric (NODE.KEY in run.json's metrics)",
                             file=file, line=line, field="scores.metric")
        if better not in BETTER:
            raise GraphError(f"score {metric!r}: better must be higher or lower, got "
                             f"{better!r}", file=file, line=line, field="scores.better")
        if metric not in RUN_FIELDS and not any(metric.startswith(p + ".") for p in paths):
            raise GraphError(f"score {metric!r} names no node of the graph", file=file,
                             line=line, field="scores.metric",
                             hint=f"Start it with a node's id (a block reports its metrics "
                                  f"under it), or use one of {', '.join(RUN_FIELDS)}.")
        score = Score(name=str(item.get("name") or metric), metric=metric, better=better,
                      doc=str(item.get("doc") or ""))
        if any(s.name == score.name for s in scores):
            raise GraphError(f"two scores are named {score.name!r}", file=file, line=line,
                             field="scores.name", hint="Give each score its own name.")
        scores.append(score)
    return scores
